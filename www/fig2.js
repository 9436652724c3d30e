// The "Fig. 2" tab: the paper's sample-size study (wasm `fig2_run`, one run at a time in a
// Web Worker), redrawn after every run as a table and two band charts.
import { bandChart } from "./chart.js";

const $ = (s) => document.querySelector(s);
let worker = null;
let running = false;
let total = 0;

function readConfig() {
  const config = {};
  for (const [key, min, max] of [["runs", 1, 1000], ["seed", 0, Number.MAX_SAFE_INTEGER]]) {
    const input = $(`#fig2-${key}`);
    const raw = input.value.trim();
    const v = Number(raw);
    if (raw === "" || !Number.isInteger(v) || v < min || v > max) {
      input.classList.add("bad");
      throw new Error(`${key} must be a whole number in ${min}…${max === Number.MAX_SAFE_INTEGER ? "2⁵³" : max} (got "${raw}")`);
    }
    input.classList.remove("bad");
    config[key] = v;
  }
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

function setRunning(on) {
  running = on;
  $("#fig2-start").disabled = on;
  $("#fig2-stop").disabled = !on;
}

const fmt = (v) => (v === null || v === undefined || !Number.isFinite(v) ? "—" : v.toExponential(2));

function render(rows, runsDone, elapsedMs) {
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
  const sizes = rows.map((r) => r.samples);
  const pick = (key, i) => rows.map((r) => (r[key][i] === null ? NaN : r[key][i]));
  const band = (key, label, color) => ({ label, color, median: pick(key, 0), min: pick(key, 1), max: pick(key, 2) });
  bandChart($("#fig2-dev"), { sizes, yLog: true, yLabel: "‖P_nmCI − P_opt‖₂", series: [band("dev", "sampled SDP vs nmCI", "#9467bd")] });
  bandChart($("#fig2-eig"), {
    sizes, zero: true, yLabel: "λ_min",
    series: [band("eig_opt", "sampled SDP", "#9467bd"), band("eig_nmci", "nmCI", "#d62728")],
  });
}

function start() {
  $("#err-fig2").textContent = "";
  let config;
  try {
    config = readConfig();
  } catch (err) {
    $("#err-fig2").textContent = err.message;
    return;
  }
  total = config.runs;
  if (!worker) {
    worker = new Worker(new URL("./fig2-worker.js", import.meta.url), { type: "module" });
    worker.onmessage = (event) => {
      const msg = event.data;
      if (msg.type === "rows") render(msg.rows, msg.runsDone, msg.elapsedMs);
      else if (msg.type === "error") {
        $("#err-fig2").textContent = msg.error;
        setRunning(false);
        document.body.dataset.fig2 = "error";
      } else {
        setRunning(false);
        document.body.dataset.fig2 = msg.type;
      }
    };
    worker.onerror = (event) => {
      $("#err-fig2").textContent = `the fig. 2 worker failed: ${event.message || "unknown error"}`;
      setRunning(false);
    };
  }
  document.body.dataset.fig2 = "running";
  setRunning(true);
  worker.postMessage({ type: "start", config });
}

$("#fig2-start").addEventListener("click", start);
$("#fig2-stop").addEventListener("click", () => worker && worker.postMessage({ type: "stop" }));
