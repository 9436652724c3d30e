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
