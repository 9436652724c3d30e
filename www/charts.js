// The study's and fig. 2's charts: drawn by the wasm module (`draw_chart`, src/chart/)
// onto canvases through web-sys — the code that writes the SVG files of `nmci track` and
// `nmci fig2`. This module only sizes the canvas and keeps the last chart for a redraw when
// the canvas changes size.
import { draw_chart } from "./pkg/nmci.js";
import "./rules.js"; // loads the wasm module first

const last = new Map(); // canvas → the chart drawn last

/** Draws `chart` (an object from the wasm module) onto `canvas` at its CSS size (560 × 300
 * while the canvas is hidden); records on the canvas, for tests, the points drawn per line
 * (`data-points`) and the lines' legend labels (`data-labels`). */
export function drawChart(canvas, chart) {
  last.set(canvas, chart);
  // The panel's placeholder gives way to the first chart drawn.
  canvas.hidden = false;
  canvas.closest(".study-plots")?.querySelector(".placeholder")?.setAttribute("hidden", "");
  if (!drawnWidth.has(canvas)) resized.observe(canvas);
  const width = Math.round(canvas.clientWidth) || 560;
  drawnWidth.set(canvas, Math.round(canvas.clientWidth));
  const height = Math.round(canvas.clientHeight) || 300;
  const points = draw_chart(canvas, chart, width, height);
  canvas.dataset.points = Array.from(points).join(",");
  canvas.dataset.labels = JSON.stringify(chart.lines.map((l) => l.label ?? null));
  return points;
}

/** Downloads `content` as the file `name` (the page's exports). */
export function download(name, type, content) {
  const a = document.createElement("a");
  a.href = URL.createObjectURL(new Blob([content], { type }));
  a.download = name;
  a.click();
  setTimeout(() => URL.revokeObjectURL(a.href), 1000);
}

// A chart is redrawn whenever its canvas changes size: a window resized, or its tab shown
// again after the window was resized while it was hidden (its width then read as 0).
const drawnWidth = new Map(); // canvas → the CSS width it was drawn at
const resized = new ResizeObserver((entries) => {
  for (const { target } of entries) {
    const chart = last.get(target);
    if (chart && target.clientWidth && Math.round(target.clientWidth) !== drawnWidth.get(target)) drawChart(target, chart);
  }
});
