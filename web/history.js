// The History page (docs/web.md): the robot's record (the `robots` and `history` commands), its
// sessions newest first with their offsets and the controller's events, and a trend plot per
// offset (trend.js) over time, oldest on the left.
import { drawTrend } from "./trend.js";

export const OFFSETS = ["delta2_deg", "delta3_deg", "delta4_deg", "delta5_deg"];
const LABELS = ["when", "session", "kind", "verdict", "delta2", "delta3", "delta4", "delta5", "events"];

function when(session) {
  return session.finished_unix_s ?? session.started_unix_s ?? null;
}

function offsetText(o) {
  return o ? `${o.value.toFixed(4)} ± ${o.sigma.toFixed(4)}` : "withheld";
}

function verdictText(s) {
  if (s.usable === null || s.usable === undefined) return s.converged ? "converged" : "not converged";
  return s.usable ? "USABLE" : "NOT USABLE";
}

// What the trend plots show: a change since a reference and a zero's offset are not on one scale
// (hundredths of a degree against a degree), so the plots show one of them, as the session
// report's do. With a check, a restore or a verification recorded: the changes since the
// reference the latest of them compared with; otherwise the references' and calibrations' offsets.
export function trendOf(history) {
  const compared = history.filter((s) => s.reference);
  if (compared.length) {
    const reference = compared[compared.length - 1].reference;
    return { sessions: history.filter((s) => s.reference === reference),
      caption: `Each zero's change since reference ${reference}, as each check, restore and verification against it found it (deg).` };
  }
  return { sessions: history.filter((s) => s.kind === "reference" || s.kind === "calibration"),
    caption: "Each zero's offset as each reference and calibration found it (deg)." };
}

export function eventText(e) {
  return `${e.kind} ${e.outcome}` + (e.verification ? ` (verified by ${e.verification})` : "");
}

export class HistoryPage {
  constructor({ call, robotSelect, robotLine, table, plots, caption, error }) {
    Object.assign(this, { call, robotSelect, robotLine, table, plots, caption, error });
    this.robots = [];
    robotSelect.addEventListener("change", () => this.load());
  }

  async open() {
    this.error.textContent = "";
    const r = await this.call("robots");
    if (!r.ok) return this.fail(r);
    this.robots = r.robots;
    this.robotSelect.replaceChildren(...this.robots.map((robot, i) => {
      const option = document.createElement("option");
      option.value = String(i);
      option.textContent = `${robot.robot_type} ${robot.serial} (${robot.sessions} sessions)`;
      return option;
    }));
    this.robotSelect.value = String(this.robots.length - 1);
    this.robotSelect.hidden = this.robots.length < 2;
    if (!this.robots.length) {
      this.robotLine.textContent = "The record knows no robot yet: it has one once a session finishes.";
      this.show([]);
      return;
    }
    await this.load();
  }

  async load() {
    const robot = this.robots[Number(this.robotSelect.value)];
    this.error.textContent = "";
    const r = await this.call("history", { serial: robot.serial, robot_type: robot.robot_type });
    if (!r.ok) return this.fail(r);
    this.robotLine.textContent = `${r.robot.robot_type} ${r.robot.serial}: ${r.history.length} sessions recorded`;
    this.show(r.history);
  }

  fail(r) {
    this.error.textContent = `${r.error.message} (${r.error.code})`;
    this.show([]);
  }

  show(history) {
    const body = this.table.querySelector("tbody");
    body.replaceChildren(...[...history].reverse().map((s) => this.row(s)));
    const events = history.flatMap((s) => s.events || []).filter((e) => e.kind === "apply" || e.kind === "rollback")
        .map((e) => ({ t: e.time_unix_s, kind: e.kind, outcome: e.outcome }));
    const trend = trendOf(history);
    this.caption.textContent = history.length ? trend.caption : "";
    for (const name of OFFSETS) {
      const svg = this.plots.querySelector(`svg[data-offset="${name}"]`);
      const points = trend.sessions.map((s) => ({
        t: when(s), value: s.offsets?.[name]?.value ?? null, sigma: s.offsets?.[name]?.sigma ?? null,
        kind: s.kind, session: s.session,
      }));
      drawTrend(svg, points, events);
    }
  }

  row(s) {
    const tr = document.createElement("tr");
    tr.dataset.session = s.session;
    const t = when(s);
    const cells = [
      [t === null ? "–" : new Date(t * 1000).toISOString().slice(0, 16).replace("T", " "), "when"],
      [s.session, "id"], [s.kind, "kind"],
      [verdictText(s), "verdict-cell " + (s.usable ? "usable" : s.usable === false ? "not-usable" : "")],
      ...OFFSETS.map((name) => [offsetText(s.offsets?.[name]), "offset " + (s.offsets?.[name] ? "" : "withheld")]),
      [(s.events || []).map(eventText).join("; ") || "–", "events"],
    ];
    for (const [text, cls] of cells) {
      const td = document.createElement("td");
      td.textContent = text;
      td.className = cls;
      td.dataset.label = LABELS[tr.cells.length];  // the header's, for the phone's cards
      tr.append(td);
    }
    tr.cells[2].title = s.verifies ? `the verification of ${s.verifies}'s apply` : "";
    return tr;
  }
}
