// The Sessions page (docs/web.md): the daemon's sessions, newest first, a page at a time (the
// `sessions` command and its cursor), each with its kind and verdict where it has a result (the
// `result` command) and links to the report and summary the daemon serves under /sessions/ID/.

export const PAGE_SIZE = 20;
const LABELS = ["session", "kind", "verdict", "poses"];

// What one session's row says, from its `sessions` entry and, when finished, its `result`.
export function describe(entry, result) {
  const row = {
    id: entry.id,
    kind: result?.kind || entry.kind || "–",
    verdict: "",
    verdictClass: "",
    poses: `${entry.recorded_poses} of ${entry.planned_poses}`,
    reports: !!entry.finished,
  };
  if (entry.damaged) row.verdict = "damaged: " + entry.damaged;
  else if (entry.closed) row.verdict = "closed: " + entry.closed;
  else if (!entry.finished) row.verdict = "not finished";
  else if (!result) row.verdict = "result unreadable";
  else {
    const usable = result.verdict ? result.verdict.usable : result.converged;
    row.verdict = usable ? "USABLE" : "NOT USABLE";
    row.verdictClass = usable ? "usable" : "not-usable";
  }
  return row;
}

export class SessionsPage {
  // `call(cmd, members)` resolves with the daemon's response; `table`'s tbody gets the rows.
  constructor({ call, table, summary, error, newer, older }) {
    Object.assign(this, { call, table, summary, error, newer, older });
    this.cursors = [""];  // the cursor of each page shown so far; the last is this page's
    this.next = null;
    newer.addEventListener("click", () => { this.cursors.pop(); this.load(); });
    older.addEventListener("click", () => { this.cursors.push(this.next); this.load(); });
  }

  // From the newest again.
  open() {
    this.cursors = [""];
    return this.load();
  }

  async load() {
    this.error.textContent = "";
    const cursor = this.cursors[this.cursors.length - 1];
    const r = await this.call("sessions", cursor ? { limit: PAGE_SIZE, cursor } : { limit: PAGE_SIZE });
    if (!r.ok) {
      this.error.textContent = `${r.error.message} (${r.error.code})`;
      return;
    }
    const results = await Promise.all(r.sessions.map((s) =>
      s.finished ? this.call("result", { session: s.id }).then((x) => (x.ok ? x.result : null))
                 : Promise.resolve(null)));
    const body = this.table.querySelector("tbody");
    body.replaceChildren(...r.sessions.map((s, i) => this.row(describe(s, results[i]))));
    const first = (this.cursors.length - 1) * PAGE_SIZE;
    this.summary.textContent = r.total === 0 ? "no sessions yet"
        : `sessions ${first + 1}–${first + r.sessions.length} of ${r.total}, newest first`;
    this.next = r.next || null;
    this.older.disabled = !this.next;
    this.newer.disabled = this.cursors.length <= 1;
  }

  row(d) {
    const tr = document.createElement("tr");
    tr.dataset.session = d.id;
    for (const [text, cls] of [[d.id, "id"], [d.kind, "kind"], [d.verdict, "verdict-cell " + d.verdictClass], [d.poses, "poses"]]) {
      const td = document.createElement("td");
      td.textContent = text;
      td.className = cls;
      td.dataset.label = LABELS[tr.cells.length];  // the header's, for the phone's cards
      tr.append(td);
    }
    const links = document.createElement("td");
    links.className = "reports";
    if (d.reports) {
      for (const [file, label] of [["report.html", "report"], ["summary.txt", "summary"]]) {
        const a = document.createElement("a");
        a.href = `/sessions/${encodeURIComponent(d.id)}/${file}`;
        a.target = "_blank";
        a.rel = "noopener";
        a.textContent = label;
        links.append(a);
      }
    }
    tr.append(links);
    return tr;
  }
}
