// The "Fig. 2" tab: the paper's sample-size study (wasm `fig2_run`, one run at a time in a
// Web Worker), redrawn as the runs come in as a table and the two charts of `nmci fig2`'s
// fig2.svg (wasm `fig2_charts`, drawn by `draw_chart`).
import { download, drawChart } from "./charts.js";
import { fig2_charts, fig2_file } from "./pkg/nmci.js";
import { readWholeNumbers, workerTab } from "./worker-tab.js";

const $ = (s) => document.querySelector(s);
let total = 0;

function readConfig() {
  const config = readWholeNumbers("fig2", [["runs", 1, 1000], ["seed", 0, Number.MAX_SAFE_INTEGER]]);
  const input = $("#fig2-sizes");
  const parts = input.value.split(",").map((p) => p.trim());
  const sizes = parts.map(Number);
  if (!parts.length || parts.some((p) => p === "") || sizes.some((v) => !Number.isInteger(v) || v < 1 || v > 5000)) {
    input.classList.add("bad");
    throw new Error(`sizes must be a comma-separated list of whole numbers in 1…5000 (got "${input.value}")`);
  }
  input.classList.remove("bad");
  config.sizes = sizes;
  return config;
}

const fmt = (v) => (v === null || v === undefined || !Number.isFinite(v) ? "—" : v.toExponential(2));

// The last rows and the runs they summarise: the files `nmci fig2` writes (wasm `fig2_file`),
// once every run is in.
let last = null;
$("#fig2-export").addEventListener("click", () => {
  const name = $("#fig2-export-file").value;
  download(name, name.endsWith(".csv") ? "text/csv" : "image/svg+xml", fig2_file(name, last.rows, last.runsDone));
});

function render(rows, runsDone, elapsedMs) {
  last = { rows, runsDone };
  $("#fig2-export").disabled = runsDone < total;
  $("#fig2-bar").style.width = `${(100 * runsDone) / total}%`;
  $("#fig2-progress").textContent = `${runsDone} of ${total} runs · ${(elapsedMs / 1000).toFixed(1)} s`;
  const body = $("#fig2-table tbody");
  body.replaceChildren();
  for (const r of rows) {
    const tr = document.createElement("tr");
    tr.dataset.samples = r.samples;
    const coin = (v) => (v === null || v === undefined || !Number.isFinite(v) ? "—" : v.toFixed(5));
    for (const c of [String(r.samples), fmt(r.dev[0]), fmt(r.eig_opt[1]), fmt(r.eig_nmci[1]), coin(r.coin_opt[2]), coin(r.coin_nmci[2]), String(r.failures)]) {
      const td = document.createElement("td");
      td.textContent = c;
      tr.append(td);
    }
    if (r.eig_opt[1] < -1e-6) tr.classList.add("warn");
    body.append(tr);
  }
  const [dev, eig] = fig2_charts(rows, runsDone);
  drawChart($("#fig2-dev"), dev);
  drawChart($("#fig2-eig"), eig);
}

workerTab({
  name: "fig2",
  label: "fig. 2",
  url: new URL("./fig2-worker.js", import.meta.url),
  readConfig: () => {
    const config = readConfig();
    total = config.runs;
    $("#fig2-export").disabled = true;
    return config;
  },
  onProgress: (msg) => render(msg.rows, msg.runsDone, msg.elapsedMs),
});
