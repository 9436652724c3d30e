// The "Tracking study" tab: runs the paper's 16-agent study in two Web Workers (wasm `Study`
// and `StudyRules`, each running half of the rules) and its exact COIN in two more (wasm
// `StudyCoin` and `StudyCoinPart`, half of the estimators each), side by side, and redraws the
// headline table and the four charts (drawn by the wasm module, as `nmci track` draws its SVG
// files) as their chunks come in. The network is
// picked (paper fit, the figure's reading, custom links) and drawn by the wasm module.
import { download, drawChart } from "./charts.js";
import { readWholeNumbers, workerTab } from "./worker-tab.js";
import init, { study_chart_svg, study_estimators, study_network, study_networks, study_series_csv } from "./pkg/nmci.js";

const $ = (s) => document.querySelector(s);
// The estimators in the series' order, with their labels: from the wasm module
// (`sim::Estimator`).
const ESTIMATORS = study_estimators();

// Tabs.
function showTab(name) {
  for (const [tab, panel] of [["explorer", $("#explorer")], ["study", $("#study")], ["fig2", $("#fig2")], ["nway", $("#nway")]]) {
    const on = tab === name;
    $(`#tab-${tab}`).setAttribute("aria-selected", String(on));
    panel.hidden = !on;
  }
  // The footer's timing is the explorer's.
  $("#timing").hidden = name !== "explorer";
}
$("#tab-explorer").addEventListener("click", () => showTab("explorer"));
$("#tab-study").addEventListener("click", () => showTab("study"));
$("#tab-fig2").addEventListener("click", () => showTab("fig2"));
$("#tab-nway").addEventListener("click", () => showTab("nway"));

// The network: a named one (from the wasm module, where the defaults live) or custom links
// between groups ("4-7 7-11 …"), drawn by the same Rust code as `nmci track`'s network.svg.
const networks = init().then(() => study_networks());
let named = null; // the named networks once the module is loaded
networks.then((n) => { named = n; drawNetwork(); }, (err) => { $("#err-study").textContent = `cannot load the wasm module: ${err.message || err}`; });

function parseLinks(text) {
  const links = [];
  for (const word of text.trim().split(/[\s,;]+/).filter(Boolean)) {
    const m = /^(\d+)\s*[-–]\s*(\d+)$/.exec(word);
    if (!m) throw new Error(`links: write pairs of agents like "4-7 7-11" (cannot read "${word}")`);
    links.push([Number(m[1]), Number(m[2])]);
  }
  return links;
}

/** The links between groups of the chosen network; throws an Error naming the problem. */
function readLinks() {
  if (!named) throw new Error("the wasm module is still loading");
  const choice = $("#study-network").value;
  $("#study-links-label").hidden = choice !== "custom";
  if (choice !== "custom") return named[choice];
  const input = $("#study-links");
  try {
    const links = parseLinks(input.value);
    input.classList.remove("bad");
    return links;
  } catch (err) {
    input.classList.add("bad");
    throw err;
  }
}

function drawNetwork() {
  const error = $("#err-study");
  error.textContent = "";
  try {
    const network = study_network({ scenario: { bridges: readLinks() } });
    $("#study-links").classList.remove("bad");
    $("#study-network-svg").innerHTML = network.svg;
    $("#study-network-caption").textContent = network.text_mismatch
      ? `Does not fit the paper's text: ${network.text_mismatch}.`
      : "Fits the paper's text: groups 1–2 reach agent 11 only through agent 7, and groups 3–4 reach agent 7 also without agent 11.";
  } catch (err) {
    const message = err.message || String(err);
    if ($("#study-network").value === "custom") $("#study-links").classList.add("bad");
    error.textContent = message;
    $("#study-network-svg").replaceChildren();
    $("#study-network-caption").textContent = "";
  }
}
$("#study-network").addEventListener("change", () => {
  if ($("#study-network").value === "custom" && !$("#study-links").value.trim() && named) {
    $("#study-links").value = named.paper.map(([a, b]) => `${a}-${b}`).join(" ");
  }
  drawNetwork();
});
$("#study-links").addEventListener("input", drawNetwork);

function readConfig() {
  const config = readWholeNumbers("study", [["runs", 1, 100], ["steps", 2, 2000], ["seed", 0, Number.MAX_SAFE_INTEGER]]);
  config.coin = $("#study-coin").checked;
  config.scenario = { bridges: readLinks() };
  return config;
}

const fmt = (v) => (!Number.isFinite(v) ? "—" : Math.abs(v) >= 1e5 ? v.toExponential(2) : v.toFixed(3));

// The latest messages of this start: the runs' worker's view and charts, and (with COIN) the
// COIN worker's view and chart; each message redraws what it changed.
let runs = null;
let coin = null;
let coinOn = false;

// The files `nmci track` writes, of the finished study: the per-step CSVs (wasm
// `study_series_csv`) and the charts as SVG (`study_chart_svg`), from the numbers the page shows.
function studyFile(name) {
  const view = runs.view;
  const [stem, ext] = name.split(".");
  if (ext === "csv") {
    const [series, steps] = stem === "coin" ? [coin.view.coin, coin.view.coin_len] : [view[stem], view.series_len];
    return study_series_csv(series, steps, view.dt);
  }
  return study_chart_svg(stem === "coin" ? coin.chart : runs.charts[stem]);
}
$("#study-export").addEventListener("click", () => {
  const name = $("#study-export-file").value;
  download(name, name.endsWith(".csv") ? "text/csv" : "image/svg+xml", studyFile(name));
});

function render() {
  if (!runs) return;
  const view = runs.view;
  const c = coin?.view;
  // Work: every run's steps and, side by side in its own worker, the exact COIN: one step
  // per estimator (5).
  const coinTotal = coinOn ? ESTIMATORS.length * view.steps : 0;
  const coinDone = c ? c.units_done : 0;
  // The runs advance together (the covariances they share computed once per step).
  const runsDone = view.runs_done >= view.runs;
  const runWork = view.runs * view.step;
  const total = view.runs * view.steps + coinTotal;
  $("#study-bar").style.width = `${(100 * (runWork + coinDone)) / total}%`;
  const runSeconds = view.run_ms.length ? ` · ${(view.run_ms.reduce((a, b) => a + b, 0) / view.run_ms.length / 1000).toFixed(2)} s per run` : "";
  const coinFinished = !coinOn || (c && c.finished);
  const elapsed = `${(Math.max(view.elapsed_ms, c ? c.elapsed_ms : 0) / 1000).toFixed(1)} s`;
  const coinText = coinOn ? (coinFinished ? "; exact COIN done" : `; exact COIN ${Math.floor((100 * coinDone) / coinTotal)}%: step ${c ? c.coin_len : 0} of ${view.steps}`) : "";
  // The files are of the finished study (coin.* only with the exact COIN).
  $("#study-export").disabled = !(runsDone && coinFinished);
  for (const option of $("#study-export-file").options) option.disabled = option.value.startsWith("coin") && !coinOn;
  if ($("#study-export-file").selectedOptions[0]?.disabled) $("#study-export-file").value = "nees.csv";
  $("#study-progress").textContent =
    runsDone && coinFinished
      ? `done: ${view.runs} run${view.runs === 1 ? "" : "s"} × ${view.steps} steps${coinOn ? " and the exact COIN" : ""} in ${elapsed}${runSeconds}`
      : runsDone
        ? `runs done${runSeconds}${coinText} · ${elapsed}`
        : `${view.runs} run${view.runs === 1 ? "" : "s"}, step ${view.step} of ${view.steps}${coinText} · ${elapsed}`;
  const coinOf = Object.fromEntries((c ? c.estimators : []).map((e) => [e.name, e]));
  const body = $("#study-table tbody");
  // The numbers behind the table, unrounded (JSON), for whoever reads the page's markup.
  $("#study-table").dataset.report = JSON.stringify(view.report);
  $("#study-table").dataset.coin = JSON.stringify(c ? c.estimators : []);
  body.replaceChildren();
  for (const { name, label } of ESTIMATORS) {
    const e = view.report[name];
    const k = coinOf[name] ?? {};
    const tr = document.createElement("tr");
    tr.dataset.estimator = name;
    const shown = (v) => (v === undefined || v === null ? (coinOn && !coinFinished ? "…" : "—") : fmt(v));
    if (k.coin_max > 1 + 1e-9) tr.classList.add("warn");
    const cells = [label, fmt(e.rmse_mean), fmt(e.two_sigma_mean), fmt(e.nees_mean), `${(100 * e.nees_frac_above_upper).toFixed(0)}%`, shown(k.coin_mean), shown(k.coin_max)];
    for (const text of cells) {
      const td = document.createElement("td");
      td.textContent = text;
      tr.append(td);
    }
    body.append(tr);
  }
  const w = view.report.omega_7_11;
  const gain = (a, b) => `${(100 * (a / b - 1)).toFixed(0)}%`;
  $("#study-omega").textContent =
    `nmCI vs CI: RMSE ${gain(view.report.nmci.rmse_mean, view.report.ci.rmse_mean)}, 2σ ${gain(view.report.nmci.two_sigma_mean, view.report.ci.two_sigma_mean)}. ` +
    `Steady ω (7←11): CI ${fmt(w.ci)}; nmCI ${w.nmci.map((v) => v.toFixed(2)).join(", ")} (G1x … G4y); ICI ${fmt(w.ici)}.` +
    (coinOf.nmci?.coin_mean !== undefined ? ` Mean COIN: CI ${fmt(coinOf.ci.coin_mean)}, nmCI ${fmt(coinOf.nmci.coin_mean)}, ICI ${fmt(coinOf.ici.coin_mean)} (closer to 1 = less conservative).` : "");
}

/** Draws the charts a message brought (`null` hides a chart). */
function drawCharts(charts) {
  const canvases = { nees: "#study-nees", rmse: "#study-rmse", omega: "#study-omega-plot", coin: "#study-coin-plot" };
  for (const [name, chart] of Object.entries(charts)) {
    const canvas = $(canvases[name]);
    canvas.hidden = !chart;
    if (chart) drawChart(canvas, chart);
  }
}

const tab = workerTab({
  name: "study",
  label: "study",
  // The runs, their rules shared between two workers (the second sends its steps straight
  // to the first, which shows them all), and beside them the exact COIN, which does not
  // depend on them, its estimators shared between two more workers the same way.
  urls: ["./study-worker.js", "./study-coin-worker.js", "./study-rules-worker.js", "./study-coin-part-worker.js"].map((u) => new URL(u, import.meta.url)),
  channels: [[0, 2], [1, 3]],
  readConfig,
  split: (config) => {
    runs = coin = null;
    $("#study-export").disabled = true;
    coinOn = config.coin;
    const runsOnly = { ...config, coin: false };
    return [runsOnly, coinOn ? config : null, runsOnly, coinOn ? config : null];
  },
  onProgress: (msg) => {
    if (msg.type === "coin") {
      coin = msg;
      drawCharts({ coin: msg.chart });
    } else {
      runs = msg;
      drawCharts(coinOn ? msg.charts : { ...msg.charts, coin: null });
    }
    render();
  },
});
for (const key of ["runs", "steps", "seed"]) {
  $(`#study-${key}`).addEventListener("keydown", (e) => { if (e.key === "Enter" && !tab.running()) tab.start(); });
}
