// Minimal SVG line charts for the study tab: axes with ticks, optional horizontal band,
// solid or dashed series, a legend row. No dependencies.

const NS = "http://www.w3.org/2000/svg";

function el(name, attrs = {}, text) {
  const e = document.createElementNS(NS, name);
  for (const [k, v] of Object.entries(attrs)) e.setAttribute(k, v);
  if (text !== undefined) e.textContent = text;
  return e;
}

/** "Nice" tick values covering [lo, hi]. */
function ticks(lo, hi, count = 5) {
  const span = hi - lo || 1;
  const step0 = span / count;
  const mag = 10 ** Math.floor(Math.log10(step0));
  const step = [1, 2, 5, 10].map((m) => m * mag).find((s) => s >= step0);
  const out = [];
  for (let v = Math.ceil(lo / step) * step; v <= hi + 1e-12 * span; v += step) out.push(Number(v.toPrecision(12)));
  return out;
}

/**
 * Draws `series` ([{ label, values, color, dash }]) against time (step k at (k+1)·dt) into
 * `svg` (viewBox 560 × 250). `band` = [lo, hi] shades a horizontal band; `yRange` fixes the
 * y axis, otherwise it covers the finite values of every series (and the band).
 */
export function lineChart(svg, { series, dt, steps, band, yRange, yLabel }) {
  svg.replaceChildren();
  const W = 560, H = 250, left = 48, right = 10, top = 22, bottom = 28;
  const finite = series.flatMap((s) => Array.from(s.values).filter(Number.isFinite));
  let [lo, hi] = yRange || [Math.min(...finite, ...(band || [])), Math.max(...finite, ...(band || []))];
  if (!Number.isFinite(lo) || !Number.isFinite(hi)) [lo, hi] = [0, 1];
  if (hi - lo < 1e-12) { lo -= 0.5; hi += 0.5; }
  if (!yRange) { const pad = 0.05 * (hi - lo); lo -= pad; hi += pad; }
  const tMax = Math.max(steps, 1) * dt;
  const X = (t) => left + ((W - left - right) * t) / tMax;
  const Y = (v) => top + ((H - top - bottom) * (hi - v)) / (hi - lo);
  for (const v of ticks(lo, hi)) {
    svg.append(el("line", { class: "gridline", x1: left, x2: W - right, y1: Y(v), y2: Y(v) }));
    svg.append(el("text", { x: left - 4, y: Y(v) + 3, "text-anchor": "end" }, String(v)));
  }
  for (const t of ticks(0, tMax)) {
    svg.append(el("text", { x: X(t), y: H - bottom + 13, "text-anchor": "middle" }, String(t)));
  }
  svg.append(el("text", { x: W - right, y: H - 4, "text-anchor": "end" }, "time [s]"));
  if (yLabel) svg.append(el("text", { x: 4, y: 12 }, yLabel));
  if (band) {
    svg.append(el("rect", { x: left, width: W - left - right, y: Y(band[1]), height: Math.max(0, Y(band[0]) - Y(band[1])), fill: "#2a9d3f", opacity: 0.15 }));
  }
  svg.append(el("rect", { class: "axis", x: left, y: top, width: W - left - right, height: H - top - bottom }));
  const clipId = `clip-${svg.id}`;
  const clip = el("clipPath", { id: clipId });
  clip.append(el("rect", { x: left, y: top, width: W - left - right, height: H - top - bottom }));
  svg.append(clip);
  let legendX = left + 4;
  for (const s of series) {
    let d = "";
    let pen = false;
    Array.from(s.values).forEach((v, k) => {
      if (!Number.isFinite(v)) { pen = false; return; }
      d += `${pen ? "L" : "M"}${X((k + 1) * dt).toFixed(1)},${Y(Math.max(Math.min(v, hi + (hi - lo)), lo - (hi - lo))).toFixed(1)}`;
      pen = true;
    });
    svg.append(el("path", { d, fill: "none", stroke: s.color, "stroke-width": 1.6, "stroke-dasharray": s.dash ? "5 3" : "none", "clip-path": `url(#${clipId})`, "data-label": s.label }));
    svg.append(el("line", { x1: legendX, x2: legendX + 14, y1: 12, y2: 12, stroke: s.color, "stroke-width": 2, "stroke-dasharray": s.dash ? "4 2" : "none" }));
    const text = el("text", { x: legendX + 17, y: 15 }, s.label);
    svg.append(text);
    legendX += 24 + 6 * s.label.length;
  }
}

/**
 * Fig. 2-style chart against the sample-set size on a log x axis: for each series a shaded
 * min–max band and a median line with dots. `yLog` uses a log y axis (values ≤ 0 are drawn
 * at the floor `yFloor`); `zero` draws the y = 0 line (non-conservative below it).
 */
export function bandChart(svg, { sizes, series, yLog, yFloor = 1e-12, zero, yLabel }) {
  svg.replaceChildren();
  const W = 560, H = 250, left = 58, right = 10, top = 22, bottom = 28;
  const f = (v) => (yLog ? Math.log10(Math.max(v, yFloor)) : v);
  const all = series.flatMap((s) => [...s.min, ...s.max]).filter(Number.isFinite).map(f);
  let lo = Math.min(...all, ...(zero ? [0] : [])), hi = Math.max(...all, ...(zero ? [0] : []));
  if (!Number.isFinite(lo) || !Number.isFinite(hi)) [lo, hi] = [0, 1];
  if (hi - lo < 1e-12) { lo -= 0.5; hi += 0.5; }
  const pad = 0.05 * (hi - lo); lo -= pad; hi += pad;
  const xs = sizes.map((s) => Math.log10(s));
  const x0 = Math.min(...xs), x1 = Math.max(...xs, x0 + 1);
  const X = (s) => left + ((W - left - right) * (Math.log10(s) - x0)) / (x1 - x0);
  const Y = (v) => top + ((H - top - bottom) * (hi - f(v))) / (hi - lo);
  const Yraw = (u) => top + ((H - top - bottom) * (hi - u)) / (hi - lo);
  for (const u of yLog ? ticks(Math.ceil(lo), Math.floor(hi)).filter(Number.isInteger) : ticks(lo, hi)) {
    svg.append(el("line", { class: "gridline", x1: left, x2: W - right, y1: Yraw(u), y2: Yraw(u) }));
    svg.append(el("text", { x: left - 4, y: Yraw(u) + 3, "text-anchor": "end" }, yLog ? `1e${u}` : String(u)));
  }
  for (const s of sizes) svg.append(el("text", { x: X(s), y: H - bottom + 13, "text-anchor": "middle" }, String(s)));
  svg.append(el("text", { x: W - right, y: H - 4, "text-anchor": "end" }, "samples N"));
  svg.append(el("rect", { class: "axis", x: left, y: top, width: W - left - right, height: H - top - bottom }));
  if (zero) svg.append(el("line", { x1: left, x2: W - right, y1: Yraw(0), y2: Yraw(0), stroke: "#000", "stroke-dasharray": "3 3" }));
  let legendX = 4;
  if (yLabel) {
    svg.append(el("text", { x: 4, y: 15 }, yLabel));
    legendX += 16 + 6 * yLabel.length;
  }
  for (const s of series) {
    const ok = sizes.map((_, k) => Number.isFinite(s.min[k]) && Number.isFinite(s.max[k]));
    const upper = sizes.map((n, k) => (ok[k] ? `${X(n).toFixed(1)},${Y(s.max[k]).toFixed(1)}` : null)).filter(Boolean);
    const lower = sizes.map((n, k) => (ok[k] ? `${X(n).toFixed(1)},${Y(s.min[k]).toFixed(1)}` : null)).filter(Boolean).reverse();
    if (upper.length) svg.append(el("polygon", { points: [...upper, ...lower].join(" "), fill: s.color, opacity: 0.18 }));
    let d = "";
    sizes.forEach((n, k) => {
      if (!Number.isFinite(s.median[k])) return;
      d += `${d ? "L" : "M"}${X(n).toFixed(1)},${Y(s.median[k]).toFixed(1)}`;
      svg.append(el("circle", { cx: X(n), cy: Y(s.median[k]), r: 2.5, fill: s.color }));
    });
    svg.append(el("path", { d, fill: "none", stroke: s.color, "stroke-width": 1.6, "data-label": s.label }));
    svg.append(el("line", { x1: legendX, x2: legendX + 14, y1: 12, y2: 12, stroke: s.color, "stroke-width": 2 }));
    svg.append(el("text", { x: legendX + 17, y: 15 }, s.label));
    legendX += 24 + 6 * s.label.length;
  }
}
