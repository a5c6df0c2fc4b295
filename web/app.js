// The shop-floor terminal (docs/web.md): one page per step of the work, chosen by the session's
// state while a session runs and by the technician otherwise. Everything the daemon refuses is
// shown as the daemon words it (error.message), never rephrased.
import { Connection, logIn, loggedIn, logOut } from "./connection.js";
import { drawSpot } from "./detector.js";
import { SessionsPage } from "./sessions.js";
import { HistoryPage } from "./history.js";

const $ = (id) => document.getElementById(id);
const OFFSETS = ["delta2_deg", "delta3_deg", "delta4_deg", "delta5_deg"];
const POSE_STATES = new Set(["connecting", "moving", "servoing", "recording", "solving"]);
const WAIT_STATES = new Set(["awaiting_placement", "awaiting_counter"]);

let status = null;   // the latest status object
let chosen = "cell"; // the page the technician chose, when no session decides
let applySession = "";
let psdPending = false;

const connection = new Connection({
  onOpen: async () => {
    setLink("connected", "connected");
    try {
      // An operator's login checks and aborts only (docs/protocol.md, "Roles"): say whose it is.
      const hello = await connection.call("hello");
      document.body.dataset.role = hello.role === "operator" ? "operator" : "engineer";
      if (hello.role === "operator") setLink("connected", "connected (operator: checks and abort)");
      const subscribed = await connection.call("subscribe");
      if (subscribed.ok) update(subscribed.status);
      const robots = await connection.call("robots");
      showIdentity(robots.ok ? robots.robots : []);
    } catch (e) {
      setLink("lost", e.message);
    }
  },
  onClose: async () => {
    setLink("lost", "connection lost: reconnecting");
    // A WebSocket refused for want of a login closes like a dropped one: ask which it was.
    if ((await loggedIn()) === "no") {
      connection.close();
      show("login");
    }
  },
  onEvent: (event) => {
    if (event.event === "status") return update(event.status);
    if (event.event === "state") {
      update({ ...(status || {}), ...pick(event, ["state", "pose", "pose_count", "recorded", "message"]),
        active: !["idle", "done", "aborted", "faulted"].includes(event.state) });
      refreshStatus();  // the whole object (placement, servo zone, time) with the change
      return;
    }
    if (event.event === "apply_progress") $("apply-progress").textContent = event.message;
    if (event.event === "apply") {
      $("apply-outcome").textContent = `${event.outcome}: ${event.message}`;
      $("apply-outcome").className = "verdict " + (["verified", "pass"].includes(event.outcome) ? "usable" : "not-usable");
    }
    if (event.event === "result") refreshStatus();
  },
});

function pick(object, keys) {
  const out = {};
  for (const k of keys) if (k in object) out[k] = object[k];
  return out;
}

function setLink(state, text) {
  $("link").dataset.state = state;
  $("link").textContent = text;
}

async function refreshStatus() {
  try {
    const r = await connection.call("status");
    if (r.ok) update(r.status);
  } catch { /* the reconnect shows it */ }
}

function showIdentity(robots) {
  const robot = robots.length ? robots[robots.length - 1] : null;
  const text = robot ? `${robot.robot_type} ${robot.serial}` : "robot not yet identified";
  $("cell-robot").textContent = text;
  $("identity").textContent = "zerocal · " + text;
}

// -- pages -----------------------------------------------------------------------------------

function show(page) {
  for (const section of document.querySelectorAll(".page"))
    section.hidden = section.id !== "page-" + page;
  document.body.dataset.page = page;
}

function pageFor(s) {
  if (!s) return chosen;
  if (s.state === "applying" || (s.state === "awaiting_counter")) return "apply";
  if (WAIT_STATES.has(s.state)) return "wait";
  if (POSE_STATES.has(s.state)) return "progress";
  return chosen;
}

function update(next) {
  const before = status;
  status = next;
  // A session that ends shows its outcome: the verdict when done, the cell (with why) otherwise.
  // An apply's outcome stays on the apply page, where it was asked for.
  if (before && before.active && !next.active && chosen !== "apply") {
    if (next.state === "done") openResult();
    else chosen = "cell";
  }
  render();
}

function render() {
  const s = status || {};
  $("abort").hidden = !s.active;
  $("cell-backend").textContent = s.backend === "sim" ? "simulated cell" : s.backend || "–";
  $("cell-state").textContent = s.state || "–";
  $("cell-state").classList.toggle("attention", ["aborted", "faulted", "unrecovered"].includes(s.state));
  $("cell-session").textContent = s.session || "none yet";
  $("cell-message").textContent = s.message || s.apply || "";
  $("cell-suggestion").textContent = s.suggestion || "";
  $("to-result").disabled = !s.session;
  $("to-start").disabled = !!s.active;
  renderProgress(s);
  renderWait(s);
  $("status-line").textContent = s.state ? `${s.state} · session ${s.session || "–"}` : "";
  if (document.body.dataset.page !== "login") show(pageFor(status));
}

function renderProgress(s) {
  const count = s.pose_count || 0, recorded = s.recorded || 0;
  $("progress-title").textContent = s.state === "solving" ? "Solving" : "Measuring";
  $("progress-pose").textContent = `pose ${Math.min(s.pose || 0, count)} of ${count}`;
  const percent = count ? Math.round((100 * recorded) / count) : 0;
  $("progress-fill").style.width = percent + "%";
  $("progress-bar").setAttribute("aria-valuenow", String(percent));
  $("progress-state").textContent = s.state || "–";
  const elapsed = s.cell_time_s || 0;
  $("progress-left").textContent = recorded > 0 && elapsed > 0 && recorded < count
      ? `about ${Math.ceil((elapsed / recorded) * (count - recorded))} s` : "–";
  const live = s.live_servo_error_um;
  $("progress-servo").textContent = typeof live === "number" ? `${live.toFixed(0)} µm (live)`
      : s.last_servo_error_um ? `${s.last_servo_error_um.toFixed(1)} µm at the last pose` : "–";
  $("progress-time").textContent = `${elapsed.toFixed(0)} s`;
  if (["moving", "servoing", "recording"].includes(s.state)) pollPsd();
}

async function pollPsd() {
  if (psdPending) return;
  psdPending = true;
  try {
    const r = await connection.call("psd");
    drawSpot($("detector"), r.ok ? r.reading : null);
    $("detector-caption").textContent = r.ok && r.reading.spot_present
        ? `spot at u ${r.reading.u_mm.toFixed(2)} mm, v ${r.reading.v_mm.toFixed(2)} mm`
        : "no spot on the detector";
  } catch { /* shown by the link state */ }
  psdPending = false;
}

function renderWait(s) {
  $("wait-message").textContent = s.message || "";
  $("wait-centre").textContent = Array.isArray(s.next_centre_mm)
      ? `placement ${s.next_placement} planned at ${s.next_centre_mm.map((x) => x.toFixed(0)).join(", ")} mm (robot base)` : "";
}

// -- actions ------------------------------------------------------------------------------------

function refusal(r) {
  return r.ok ? "" : `${r.error.message} (${r.error.code})`;
}

async function loadPlan() {
  const kind = document.querySelector("input[name=kind]:checked")?.value;
  $("start-confirm").disabled = true;
  $("plan-description").textContent = "planning…";
  $("start-error").textContent = "";
  const body = $("plan-table").querySelector("tbody");
  body.replaceChildren();
  const r = await connection.call("plan", kind ? { kind } : {}).catch((e) => ({ ok: false, error: { code: "link", message: e.message } }));
  if (!r.ok) {
    $("plan-description").textContent = "";
    $("start-error").textContent = refusal(r);
    $("start-confirm").disabled = false;  // start may still go (a check re-measures the reference)
    return;
  }
  const plan = r.plan;
  $("plan-description").textContent = plan.description;
  for (const name of OFFSETS) {
    const p = plan.predicted?.[name];
    const row = document.createElement("tr");
    row.innerHTML = "<td></td><td></td>";
    row.cells[0].textContent = name.replace("_deg", "");
    row.cells[1].textContent = p && p.identifiable ? `${p.sigma.toFixed(4)} deg` : "not identifiable";
    body.append(row);
  }
  $("plan-poses").textContent = `${plan.poses.length} poses; required accuracy ${plan.required_accuracy_deg} deg`;
  const time = plan.predicted_cell_time;
  $("plan-time").textContent = time
      ? `about ${time.seconds.toFixed(0)} s of cell time (${time.per_pose_s.toFixed(1)} s a pose in the daemon's latest ${time.from_sessions} session${time.from_sessions === 1 ? "" : "s"})`
        + ((plan.placements || 1) > 1 ? ", and the PSD moved by hand between its placements" : "")
      : "cell time not predicted: the daemon has no finished session to go by";
  $("start-confirm").disabled = false;
}

async function openResult() {
  chosen = "result";
  $("result-error").textContent = "";
  const r = await connection.call("result").catch((e) => ({ ok: false, error: { code: "link", message: e.message } }));
  if (!r.ok) {
    $("verdict").textContent = "–";
    $("result-error").textContent = refusal(r);
    render();
    return;
  }
  const result = r.result;
  applySession = result.session || "";
  const usable = result.verdict ? result.verdict.usable : result.converged;
  $("verdict").textContent = usable ? "USABLE" : "NOT USABLE";
  $("verdict").className = "verdict " + (usable ? "usable" : "not-usable");
  $("verdict-reasons").replaceChildren(...(result.verdict?.reasons || []).map((reason) => {
    const li = document.createElement("li");
    li.textContent = reason;
    return li;
  }));
  $("result-kind").textContent = `${result.kind} ${result.session}` +
      (result.reference ? `: the change of each zero since reference ${result.reference}` : "");
  const body = $("result-table").querySelector("tbody");
  body.replaceChildren();
  for (const name of OFFSETS) {
    const p = result.parameters?.[name];
    const row = document.createElement("tr");
    row.innerHTML = "<td></td><td></td><td></td>";
    row.cells[0].textContent = name.replace("_deg", "");
    row.cells[1].textContent = p && p.identifiable ? p.value.toFixed(4) : "withheld";
    row.cells[2].textContent = p && p.identifiable ? p.sigma.toFixed(4) : p?.reason || "";
    body.append(row);
  }
  let todo;
  if (result.check) todo = result.check.summary;
  else if (!usable) todo = "Do not write these values into the controller.";
  else if (result.kind === "reference") todo = "Nothing to write: the reference is kept for later checks and restores.";
  else todo = "Apply them to the controller (with verification and rollback), or write the cal_offset values on the FlexPendant (docs/apply.md).";
  if (r.apply) todo += ` Applied: ${r.apply.outcome || ""}.`;
  $("result-todo").textContent = todo;
  $("to-apply").disabled = !usable || result.kind === "reference" || !!result.check;
  render();
}

// A call whose failure to reach the daemon is answered like a refusal, in the same shape.
function ask(cmd, members) {
  return connection.call(cmd, members).catch((e) => ({ ok: false, error: { code: "link", message: e.message } }));
}

const sessionsPage = new SessionsPage({
  call: ask, table: $("sessions-table"), summary: $("sessions-summary"), error: $("sessions-error"),
  newer: $("sessions-newer"), older: $("sessions-older"),
});

const historyPage = new HistoryPage({
  call: ask, robotSelect: $("history-robot"), robotLine: $("history-robot-line"),
  table: $("history-table"), plots: $("history-plots"), caption: $("history-trend"),
  error: $("history-error"),
});

async function call(cmd, members, errorId) {
  $(errorId).textContent = "";
  const r = await connection.call(cmd, members).catch((e) => ({ ok: false, error: { code: "link", message: e.message } }));
  $(errorId).textContent = refusal(r);
  return r;
}

$("login-form").addEventListener("submit", async (e) => {
  e.preventDefault();
  $("login-error").textContent = "";
  $("login").disabled = true;
  try {
    const r = await logIn($("token").value);
    if (r.ok) {
      $("token").value = "";
      chosen = "cell";
      show("cell");
      connection.open();
    } else {
      $("login-error").textContent = refusal(r);
    }
  } catch (err) {
    $("login-error").textContent = "the cell does not answer: " + err.message;
  }
  $("login").disabled = false;
});

$("abort").addEventListener("click", () => connection.call("abort").catch(() => {}));
$("to-start").addEventListener("click", () => {
  chosen = "start";
  const suggested = status?.suggested_kind;
  const radio = document.querySelector(`input[name=kind][value="${suggested || "reference"}"]`);
  if (radio) radio.checked = true;
  // A kind this login may not start is not offered: the first it may is chosen instead.
  const offered = [...document.querySelectorAll("input[name=kind]")].filter((r) => r.offsetParent);
  if (offered.length && !offered.some((r) => r.checked)) offered[0].checked = true;
  render();
  loadPlan();
});
$("kinds").addEventListener("change", loadPlan);
$("start-cancel").addEventListener("click", () => { chosen = "cell"; render(); });
$("start-confirm").addEventListener("click", async () => {
  const kind = document.querySelector("input[name=kind]:checked")?.value;
  $("start-confirm").disabled = true;
  const r = await call("start", kind ? { kind } : {}, "start-error");
  $("start-confirm").disabled = false;
  if (r.ok) { chosen = "cell"; refreshStatus(); }
});
$("to-result").addEventListener("click", openResult);
$("to-sessions").addEventListener("click", () => {
  chosen = "sessions";
  render();
  sessionsPage.open();
});
$("sessions-back").addEventListener("click", () => { chosen = "cell"; render(); });
$("to-history").addEventListener("click", () => {
  chosen = "history";
  render();
  historyPage.open();
});
$("history-back").addEventListener("click", () => { chosen = "cell"; render(); });
$("result-back").addEventListener("click", () => { chosen = "cell"; render(); });
$("to-apply").addEventListener("click", () => {
  chosen = "apply";
  $("apply-session").textContent = applySession;
  $("apply-confirm-box").checked = false;  // every apply is confirmed anew
  $("apply-progress").textContent = $("apply-outcome").textContent = $("apply-error").textContent = "";
  render();
  $("apply-cancel").focus();
});
$("apply-cancel").addEventListener("click", () => { chosen = "result"; render(); });
$("apply-go").addEventListener("click", () =>
  call("apply", { session: applySession, confirm: $("apply-confirm-box").checked }, "apply-error"));
$("verify-go").addEventListener("click", () => call("verify", { session: applySession }, "apply-error"));
$("wait-continue").addEventListener("click", () => call("continue", {}, "wait-error"));
$("logout").addEventListener("click", async () => {
  connection.close();
  await logOut();
  delete document.body.dataset.role;  // the next login says its own
  show("login");
});

// At load: straight to the cell when this browser is logged in already.
(async () => {
  const state = await loggedIn();
  if (state === "yes") {
    show("cell");
    connection.open();
  } else {
    show("login");
    if (state === "unreachable") $("login-error").textContent = "the cell does not answer";
  }
  // The first page can be used from here on (docs/web.md, "Load and latency" measures it).
  performance.mark("zerocal-usable");
})();
