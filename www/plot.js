// SVG drawing: 1σ ellipses of 2×2 marginals, equal-aspect axes with ticks.
const NS = "http://www.w3.org/2000/svg";

export function el(name, attrs = {}, parent) {
  const e = document.createElementNS(NS, name);
  for (const [k, v] of Object.entries(attrs)) e.setAttribute(k, String(v));
  if (parent) parent.appendChild(e);
  return e;
}

/** The 2×2 marginal of an n×n row-major matrix (nested rows) on states i, j. */
export function marginal(m, i, j) {
  return [[m[i][i], m[i][j]], [m[j][i], m[j][j]]];
}

/** Eigen-decomposition of a symmetric 2×2: semi-axes (1σ) and angle of the major axis. */
export function axes(m) {
  const [a, b, c] = [m[0][0], (m[0][1] + m[1][0]) / 2, m[1][1]];
  const mean = (a + c) / 2;
  const r = Math.hypot((a - c) / 2, b);
  const l1 = mean + r;
  const l2 = mean - r;
  const theta = 0.5 * Math.atan2(2 * b, a - c);
  return { major: Math.sqrt(Math.max(l1, 0)), minor: Math.sqrt(Math.max(l2, 0)), theta };
}

/** From semi-axes and angle back to a 2×2 covariance. */
export function fromAxes(major, minor, theta) {
  const [c, s] = [Math.cos(theta), Math.sin(theta)];
  const [l1, l2] = [major * major, minor * minor];
  return [[c * c * l1 + s * s * l2, c * s * (l1 - l2)], [c * s * (l1 - l2), s * s * l1 + c * c * l2]];
}

/** Two decimals (what `toFixed(2)` keeps, without its trailing zeros), as a path number. */
const r2 = (v) => Math.round(v * 100) / 100;

/**
 * The closed SVG path of the 1σ ellipse of the 2×2 covariance `m`, placed by `toPx` (a
 * similarity: the page's frames scale both axes alike): two elliptical arcs between the ends of
 * the major axis, so the curve is an ellipse, not a polygon (its ends, radii and angle rounded
 * to 0.01 px and 0.01°), and the path is a few dozen characters instead of a polygon's hundreds. Every ellipse is drawn in the same direction (sweep flag 1),
 * so one path of many ellipses fills their union under the nonzero rule.
 */
export function ellipsePath(m, toPx) {
  const { major, minor, theta } = axes(m);
  const [c, s] = [Math.cos(theta), Math.sin(theta)];
  const [x0, y0] = toPx(0, 0);
  const [x1, y1] = toPx(major * c, major * s);
  const [x2, y2] = toPx(-major * c, -major * s);
  const [xm, ym] = toPx(-minor * s, minor * c);
  const rx = Math.hypot(x1 - x0, y1 - y0);
  const ry = Math.hypot(xm - x0, ym - y0);
  const angle = (Math.atan2(y1 - y0, x1 - x0) * 180) / Math.PI;
  const arc = `A${r2(rx)},${r2(ry)},${r2(angle)},0,1,`;
  return `M${r2(x1)},${r2(y1)}${arc}${r2(x2)},${r2(y2)}${arc}${r2(x1)},${r2(y1)}Z`;
}

export function niceStep(range, target = 6) {
  const raw = range / target;
  const p = Math.pow(10, Math.floor(Math.log10(raw)));
  const f = raw / p;
  return (f < 1.5 ? 1 : f < 3.5 ? 2 : f < 7.5 ? 5 : 10) * p;
}

/** A square frame with equal scales on both axes covering [-half, half]². */
export function frame(svg, half, labels) {
  const size = 520, pad = 46;
  const inner = size - 2 * pad;
  const scale = inner / (2 * half);
  const toPx = (x, y) => [pad + (x + half) * scale, pad + (half - y) * scale];
  const fromPx = (px, py) => [(px - pad) / scale - half, half - (py - pad) / scale];
  const g = el("g", { "font-family": "system-ui, sans-serif", "font-size": 11, fill: "#444" }, svg);
  el("rect", { x: pad, y: pad, width: inner, height: inner, fill: "#fff", stroke: "#bbb" }, g);
  const step = niceStep(2 * half);
  for (let t = Math.ceil(-half / step) * step; t <= half + 1e-12; t += step) {
    const v = Math.abs(t) < step * 1e-9 ? 0 : t;
    const [x] = toPx(v, 0);
    const [, y] = toPx(0, v);
    el("line", { x1: x, y1: pad, x2: x, y2: pad + inner, stroke: v === 0 ? "#bbb" : "#eee" }, g);
    el("line", { x1: pad, y1: y, x2: pad + inner, y2: y, stroke: v === 0 ? "#bbb" : "#eee" }, g);
    el("line", { x1: x, y1: pad + inner, x2: x, y2: pad + inner + 5, stroke: "#666" }, g);
    el("line", { x1: pad - 5, y1: y, x2: pad, y2: y, stroke: "#666" }, g);
    const label = +v.toPrecision(6);
    el("text", { x, y: pad + inner + 17, "text-anchor": "middle" }, g).textContent = label;
    el("text", { x: pad - 8, y: y + 4, "text-anchor": "end" }, g).textContent = label;
  }
  el("text", { x: pad + inner / 2, y: size - 6, "text-anchor": "middle", "font-size": 12 }, g).textContent = labels[0];
  const yl = el("text", { x: 12, y: pad + inner / 2, "text-anchor": "middle", "font-size": 12, transform: `rotate(-90 12 ${pad + inner / 2})` }, g);
  yl.textContent = labels[1];
  return { toPx, fromPx, scale };
}
