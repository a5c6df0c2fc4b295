// A trend plot of one offset over time, in SVG and nothing else: a point per session with a value,
// its error bar +-3 sigma (the band a check or verification is judged by), the sessions whose
// offset was withheld as a hollow mark on the time axis (no value drawn), and the controller's
// applies and rollbacks as vertical lines at their time.

const SVG = "http://www.w3.org/2000/svg";
// In the SVG's own units; it is drawn about this wide on a tablet's column and on a phone, so
// that its text stays readable on both.
const WIDTH = 360, HEIGHT = 190;
const LEFT = 50, RIGHT = 10, TOP = 10, BOTTOM = 30;
export const BAR_SIGMAS = 3;

function node(name, attributes, text) {
  const n = document.createElementNS(SVG, name);
  for (const [k, v] of Object.entries(attributes)) n.setAttribute(k, String(v));
  if (text !== undefined) n.textContent = text;
  return n;
}

// Round steps (1, 2, 5 times a power of ten) covering [lo, hi] with about `count` ticks.
export function ticks(lo, hi, count = 4) {
  if (!(hi > lo)) return [lo];
  const raw = (hi - lo) / count;
  const power = 10 ** Math.floor(Math.log10(raw));
  const step = [1, 2, 5, 10].map((m) => m * power).find((s) => s >= raw * (1 - 1e-9));
  const out = [];
  for (let v = Math.ceil(lo / step) * step; v <= hi + step * 1e-9; v += step) out.push(+v.toPrecision(12));
  return out;
}

function dateLabel(t) {
  return new Date(t * 1000).toISOString().slice(0, 16).replace("T", " ");  // UTC, to the minute
}

// points: [{t (s since the epoch), value (deg) or null when withheld, sigma, kind, session}];
// events: [{t, kind, outcome}]. Replaces the SVG's content.
export function drawTrend(svg, points, events = []) {
  svg.replaceChildren();
  svg.setAttribute("viewBox", `0 0 ${WIDTH} ${HEIGHT}`);
  const valued = points.filter((p) => typeof p.value === "number");
  const times = [...points.map((p) => p.t), ...events.map((e) => e.t)].filter((t) => typeof t === "number");
  let t0 = Math.min(...times), t1 = Math.max(...times);
  if (!times.length) t0 = t1 = 0;
  if (t1 - t0 < 60) { t0 -= 30; t1 += 30; }  // one session, or a few within a minute
  const bar = (p) => BAR_SIGMAS * (p.sigma || 0);
  let lo = Math.min(...valued.map((p) => p.value - bar(p))), hi = Math.max(...valued.map((p) => p.value + bar(p)));
  if (!valued.length) { lo = -0.01; hi = 0.01; }
  const pad = Math.max((hi - lo) * 0.08, 0.001);
  lo -= pad; hi += pad;
  const x = (t) => LEFT + ((t - t0) / (t1 - t0)) * (WIDTH - LEFT - RIGHT);
  const y = (v) => TOP + ((hi - v) / (hi - lo)) * (HEIGHT - TOP - BOTTOM);
  const bottom = HEIGHT - BOTTOM;

  svg.append(node("rect", { class: "frame", x: LEFT, y: TOP, width: WIDTH - LEFT - RIGHT, height: bottom - TOP }));
  const marks = ticks(lo, hi);
  // As many decimals as the step needs: 0.5, or 0.0005.
  const step = marks.length > 1 ? marks[1] - marks[0] : Math.abs(hi - lo) || 1;
  const decimals = Math.min(6, Math.max(0, -Math.floor(Math.log10(step) + 1e-9)));
  for (const v of marks) {
    svg.append(node("line", { class: "grid", x1: LEFT, x2: WIDTH - RIGHT, y1: y(v), y2: y(v) }));
    const label = (Math.abs(v) < step * 1e-6 ? 0 : v).toFixed(decimals);
    svg.append(node("text", { class: "tick", x: LEFT - 4, y: y(v) + 4, "text-anchor": "end" }, label));
  }
  if (lo < 0 && hi > 0) svg.append(node("line", { class: "zero", x1: LEFT, x2: WIDTH - RIGHT, y1: y(0), y2: y(0) }));
  svg.append(node("text", { class: "tick", x: LEFT, y: HEIGHT - 10 }, dateLabel(t0)));
  svg.append(node("text", { class: "tick", x: WIDTH - RIGHT, y: HEIGHT - 10, "text-anchor": "end" }, dateLabel(t1)));

  for (const e of events) {
    if (typeof e.t !== "number") continue;
    const line = node("line", { class: `event ${e.kind}`, x1: x(e.t), x2: x(e.t), y1: TOP, y2: bottom });
    line.append(node("title", {}, `${e.kind} ${e.outcome} ${dateLabel(e.t)}`));
    svg.append(line);
  }
  for (const p of points) {
    if (typeof p.t !== "number") continue;
    if (typeof p.value !== "number") {
      const mark = node("circle", { class: "withheld", cx: x(p.t), cy: bottom, r: 4, "data-session": p.session });
      mark.append(node("title", {}, `${p.session} ${p.kind}: withheld`));
      svg.append(mark);
      continue;
    }
    const g = node("g", { class: `sample ${p.kind}` });
    g.append(node("line", { class: "bar", x1: x(p.t), x2: x(p.t), y1: y(p.value - bar(p)), y2: y(p.value + bar(p)) }));
    const point = node("circle", { class: "point", cx: x(p.t), cy: y(p.value), r: 4, "data-session": p.session });
    point.append(node("title", {}, `${p.session} ${p.kind}: ${p.value.toFixed(4)} ± ${bar(p).toFixed(4)} deg (3 sigma)`));
    g.append(point);
    svg.append(g);
  }
}
