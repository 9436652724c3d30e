// The explorer's UI: inputs, the Web Worker round trip, drawing and the numbers panel.
import { LAYERS, preset, patternPreset, resize, encodeHash, decodeHash } from "./state.js";
import { el, marginal, axes, fromAxes, ellipsePath, frame } from "./plot.js";
import { EXPLORER_RULES, RULE } from "./rules.js";

const $ = (id) => document.getElementById(id);
// Labels and colours: the region and the two estimates here, every rule from the registry.
const STYLE = {
  region: { label: "possible true fused P (known P_ab)", color: "#888" },
  pa: { label: "P_a", color: "#1f77b4" },
  pb: { label: "P_b", color: "#e07b00" },
  ...Object.fromEntries(EXPLORER_RULES.map((r) => [r.name, { label: r.legend, color: r.colour }])),
};
// How a rule's ellipse is stroked follows its guarantee: the conservative rules solid, each
// thinner than the one before so coinciding bounds stay visible (CI under nmCI under the
// certified rule); relaxations dashed; the unguaranteed rules dotted.
const STROKE = (() => {
  const stroke = { pa: { width: 2, dash: "none" }, pb: { width: 2, dash: "none" } };
  let k = 0;
  for (const r of EXPLORER_RULES) {
    stroke[r.name] = r.guarantee === "conservative" ? { width: Math.max(1.2, 2.6 - 0.6 * k++), dash: "none" }
      : r.guarantee === "relaxation" ? { width: 2, dash: "7 4" }
      : { width: 1.8, dash: "2 3" };
  }
  return stroke;
})();

let state = preset("paper");
let text = null; // the grids' raw text, so an invalid entry stays visible
let last = null; // the last valid analysis (the picture stays when an input is invalid)
let analysedState = null;
const timings = [];
window.nmciStats = {
  timings,
  median() {
    if (timings.length === 0) return NaN;
    const s = [...timings].sort((a, b) => a - b);
    return s[Math.floor(s.length / 2)];
  },
  runs: 0,
  abandoned: 0,
};

// ---------- worker round trip: latest state wins, one request in flight ----------
// A solve still running ABANDON_MS after a newer edit arrived is stale: the worker is
// terminated (wasm cannot be interrupted from outside) and a fresh one takes the newest state.
const ABANDON_MS = 300;
function makeWorker() {
  const w = new Worker(new URL("./worker.js", import.meta.url), { type: "module" });
  w.onmessage = onWorkerMessage;
  w.onerror = (e) => showGeneral(`the worker failed: ${e.message}`);
  return w;
}
let worker = null;
let staleTimer = null;
let nextId = 1;
let inFlight = null; // { id, t0, state }
let queued = null;

function request(s) {
  return {
    pa: s.pa, pb: s.pb, pab_unknown: s.pattern, criterion: s.criterion,
    samples: s.samples, seed: s.seed, region_samples: s.region, sampler: s.sampler,
  };
}

function submit() {
  const snapshot = structuredClone(state);
  if (inFlight) {
    queued = snapshot;
    if (!staleTimer) {
      const stale = inFlight.id;
      const wait = Math.max(0, ABANDON_MS - (performance.now() - inFlight.t0));
      staleTimer = setTimeout(() => {
        staleTimer = null;
        if (!inFlight || inFlight.id !== stale || !queued) return;
        worker.terminate();
        worker = makeWorker();
        window.nmciStats.abandoned++;
        inFlight = null;
        const q = queued;
        queued = null;
        send(q);
      }, wait);
    }
    return;
  }
  send(snapshot);
}

function send(s) {
  inFlight = { id: nextId++, t0: performance.now(), state: s };
  $("busy").hidden = false;
  document.body.dataset.ready = "false";
  worker.postMessage({ id: inFlight.id, request: request(s) });
}

function onWorkerMessage(event) {
  const { id, ok, result, error, field } = event.data;
  if (!inFlight || id !== inFlight.id) return;
  if (staleTimer) {
    clearTimeout(staleTimer);
    staleTimer = null;
  }
  const done = inFlight;
  inFlight = null;
  if (ok) {
    last = result;
    analysedState = done.state;
    clearErrors();
    render();
    timings.push(performance.now() - done.t0);
    if (timings.length > 200) timings.shift();
    window.nmciStats.runs++;
  } else {
    showInputError(error, field);
  }
  $("timing").textContent = timings.length
    ? `recompute (all rules + region, worker round trip): median ${window.nmciStats.median().toFixed(1)} ms over ${timings.length}`
    : "";
  if (queued) {
    const q = queued;
    queued = null;
    send(q);
  } else {
    $("busy").hidden = true;
    document.body.dataset.ready = "true";
  }
}
worker = makeWorker();

// ---------- errors shown inline ----------
function clearErrors() {
  for (const id of ["err-pa", "err-pb", "err-pattern", "err-settings", "err-general"]) $(id).textContent = "";
}
function showGeneral(msg) {
  $("err-general").textContent = msg;
}
/** Why the URL's state was not used (kept until a readable link is loaded: the page's own
 * errors and results clear `err-general`, not this). */
function showLinkError(msg) {
  $("err-link").textContent = msg;
}
// Where a request field's errors are shown (the field comes with the error: `Error.field`).
const ERROR_SLOT = {
  pa: "err-pa", xa: "err-pa", pb: "err-pb", xb: "err-pb", pab_unknown: "err-pattern",
  criterion: "err-settings", samples: "err-settings", seed: "err-settings", max_trials: "err-settings",
  region_samples: "err-settings", sampler: "err-settings",
};
function showInputError(msg, field) {
  clearErrors();
  markBadCells();
  $(ERROR_SLOT[field] ?? "err-general").textContent = msg + (last ? " — showing the last valid result." : "");
}

// ---------- inputs ----------
function fmtInput(v) {
  return String(+v.toPrecision(10));
}

function buildGrids() {
  const n = state.n;
  text = { pa: state.pa.map((r) => r.map(fmtInput)), pb: state.pb.map((r) => r.map(fmtInput)) };
  for (const key of ["pa", "pb"]) {
    const grid = $(`grid-${key}`);
    grid.replaceChildren();
    grid.style.gridTemplateColumns = `repeat(${n}, 1fr)`;
    for (let i = 0; i < n; i++) {
      for (let j = 0; j < n; j++) {
        const input = document.createElement("input");
        input.setAttribute("aria-label", `${key === "pa" ? "P_a" : "P_b"}[${i + 1},${j + 1}]`);
        input.dataset.i = i;
        input.dataset.j = j;
        input.inputMode = "decimal";
        input.value = text[key][i][j];
        if (i === j) input.classList.add("diag");
        input.addEventListener("input", () => onCell(key, i, j, input.value));
        grid.appendChild(input);
      }
    }
  }
  const pg = $("grid-pattern");
  pg.replaceChildren();
  pg.style.gridTemplateColumns = `repeat(${n}, 2.3em)`;
  for (let i = 0; i < n; i++) {
    for (let j = 0; j < n; j++) {
      const b = document.createElement("button");
      b.dataset.i = i;
      b.dataset.j = j;
      b.title = `P_ab[${i + 1},${j + 1}]: click to toggle unknown / known zero`;
      b.setAttribute("aria-label", `P_ab[${i + 1},${j + 1}]`);
      if (i === j) b.classList.add("diagcell");
      b.addEventListener("click", () => {
        state.pattern[i][j] = !state.pattern[i][j];
        state.preset = "custom";
        syncPattern();
        changed();
      });
      pg.appendChild(b);
    }
  }
  syncPattern();
}

function syncPattern() {
  for (const b of $("grid-pattern").children) {
    const on = state.pattern[+b.dataset.i][+b.dataset.j];
    b.classList.toggle("on", on);
    b.setAttribute("aria-pressed", String(on));
  }
}

function syncGridValues(key) {
  for (const input of $(`grid-${key}`).children) {
    const [i, j] = [+input.dataset.i, +input.dataset.j];
    if (document.activeElement !== input) input.value = text[key][i][j];
  }
}

function parseCell(s) {
  const t = s.trim();
  if (t === "" || !/^[-+]?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?$/.test(t)) return NaN;
  return Number(t);
}

function markBadCells() {
  for (const key of ["pa", "pb"]) {
    for (const input of $(`grid-${key}`).children) {
      const v = parseCell(text[key][+input.dataset.i][+input.dataset.j]);
      input.classList.toggle("bad", !Number.isFinite(v));
    }
  }
}

function onCell(key, i, j, value) {
  text[key][i][j] = value;
  text[key][j][i] = value; // symmetric entries stay tied
  syncGridValues(key);
  markBadCells();
  const v = parseCell(value);
  const name = key === "pa" ? "P_a" : "P_b";
  if (!Number.isFinite(v)) {
    $(`err-${key}`).textContent = `${name}[${i + 1},${j + 1}]: "${value}" is not a number` + (last ? " — showing the last valid result." : "");
    return;
  }
  // Another cell may still be bad.
  for (let a = 0; a < state.n; a++) for (let b = 0; b < state.n; b++) {
    if (!Number.isFinite(parseCell(text[key][a][b]))) {
      $(`err-${key}`).textContent = `${name}[${a + 1},${b + 1}]: "${text[key][a][b]}" is not a number`;
      return;
    }
  }
  state[key][i][j] = v;
  state[key][j][i] = v;
  state.preset = "custom";
  $(`err-${key}`).textContent = "";
  changed();
}

function allCellsValid() {
  return ["pa", "pb"].every((k) => text[k].every((r) => r.every((s) => Number.isFinite(parseCell(s)))));
}

function settingInput(id, key, lo, hi) {
  const input = $(id);
  input.addEventListener("input", () => {
    const v = Number(input.value);
    if (!Number.isInteger(v) || v < lo || v > hi) {
      input.classList.add("bad");
      $("err-settings").textContent = `${key === "region" ? "region samples" : key}: "${input.value}" must be a whole number from ${lo} to ${hi}`;
      return;
    }
    input.classList.remove("bad");
    $("err-settings").textContent = "";
    state[key] = v;
    changed();
  });
}

function syncControls() {
  $("preset").value = PRESETS.includes(state.preset) ? state.preset : "custom";
  $("dim").value = state.n;
  $("criterion").value = state.criterion;
  $("sampler").value = state.sampler;
  $("samples").value = state.samples;
  $("seed").value = state.seed;
  $("region").value = state.region;
  for (const id of ["view-i", "view-j"]) {
    const s = $(id);
    s.replaceChildren(...Array.from({ length: state.n }, (_, k) => new Option(`x${k + 1}`, k)));
  }
  $("view-i").value = state.view[0];
  $("view-j").value = state.view[1];
  for (const l of LAYERS) {
    const box = document.querySelector(`#legend input[data-layer=${l}]`);
    if (box) box.checked = state.layers[l];
  }
}

const PRESETS = ["paper", "correlated", "twoblock", "six"];

function changed() {
  $("preset").value = PRESETS.includes(state.preset) ? state.preset : "custom";
  history.replaceState(null, "", encodeHash(state));
  if (!allCellsValid()) return;
  submit();
}

function load(s) {
  state = s;
  buildGrids();
  syncControls();
  clearErrors();
  changed();
}

// ---------- drawing ----------
let drag = null; // { key, which, axes } while a handle is dragged
let currentFromPx = null; // pixel → data map of the current frame

function render() {
  if (!last || !analysedState) return;
  const s = analysedState;
  const [i, j] = state.view;
  const svg = $("plot");
  svg.replaceChildren();
  const mats = {
    pa: state.n === s.n ? state.pa : s.pa,
    pb: state.n === s.n ? state.pb : s.pb,
    ...Object.fromEntries(last.rules.map((r) => [r.method, r.response ? r.response.p : null])),
  };
  const n = last.n;
  const region = [];
  for (let k = 0; k < last.region_count; k++) {
    const o = k * n * n;
    region.push([[last.region[o + i * n + i], last.region[o + i * n + j]], [last.region[o + j * n + i], last.region[o + j * n + j]]]);
  }
  const extent = Math.max(...["pa", "pb"].flatMap((k) => [mats[k][i][i], mats[k][j][j]]).map(Math.sqrt), 1e-9) * 1.15;
  const { toPx, fromPx } = frame(svg, extent, [`x${i + 1}`, `x${j + 1}`]);
  currentFromPx = fromPx;
  const clip = el("clipPath", { id: "clip" }, el("defs", {}, svg));
  el("rect", { x: 46, y: 46, width: 428, height: 428 }, clip);
  const g = el("g", { "clip-path": "url(#clip)" }, svg);
  if (state.layers.region && region.length) {
    const rg = el("g", { opacity: 0.32, id: "layer-region" }, g);
    for (const m of region) el("path", { d: ellipsePath(m, toPx, 40), fill: STYLE.region.color, stroke: "none" }, rg);
  }
  for (const k of LAYERS.filter((l) => l !== "region")) {
    if (!state.layers[k] || !mats[k]) continue;
    el("path", {
      id: `layer-${k}`, d: ellipsePath(marginal(mats[k], i, j), toPx), fill: "none",
      stroke: STYLE[k].color, "stroke-width": STROKE[k].width, "stroke-dasharray": STROKE[k].dash,
    }, g);
  }
  for (const k of ["pa", "pb"]) {
    if (!state.layers[k]) continue;
    const a = axes(marginal(mats[k], i, j));
    const ends = [
      ["major", a.major, a.theta],
      ["minor", a.minor, a.theta + Math.PI / 2],
    ];
    for (const [which, r, t] of ends) {
      const [x, y] = toPx(r * Math.cos(t), r * Math.sin(t));
      const h = el("circle", { cx: x, cy: y, r: 6.5, fill: STYLE[k].color, stroke: "#fff", "stroke-width": 1.5, cursor: "grab", class: "handle", "data-key": k, "data-axis": which }, svg);
      h.addEventListener("pointerdown", (e) => {
        drag = { key: k, which, axes: a };
        svg.setPointerCapture(e.pointerId);
        e.preventDefault();
      });
    }
  }
  renderNumbers();
}

function onDrag(e) {
  if (!drag || !currentFromPx) return;
  const svg = $("plot");
  const pt = svg.createSVGPoint();
  pt.x = e.clientX;
  pt.y = e.clientY;
  const p = pt.matrixTransform(svg.getScreenCTM().inverse());
  const [x, y] = currentFromPx(p.x, p.y);
  const r = Math.max(Math.hypot(x, y), 1e-3);
  const angle = Math.atan2(y, x);
  let { major, minor, theta } = drag.axes;
  if (drag.which === "major") {
    major = r;
    theta = angle;
  } else {
    minor = r;
    theta = angle - Math.PI / 2;
  }
  drag.axes = { major, minor, theta };
  const m = fromAxes(major, minor, theta);
  const [i, j] = state.view;
  const round = (v) => +v.toFixed(4);
  const key = drag.key;
  state[key][i][i] = round(m[0][0]);
  state[key][j][j] = round(m[1][1]);
  state[key][i][j] = state[key][j][i] = round(m[0][1]);
  for (const [a, b] of [[i, i], [j, j], [i, j], [j, i]]) text[key][a][b] = fmtInput(state[key][a][b]);
  syncGridValues(key);
  state.preset = "custom";
  $("preset").value = "custom";
  // Redraw the dragged ellipse immediately; the rest follows from the worker.
  changed();
}

const f3 = (v) => (v === undefined || v === null ? "—" : Number(v).toFixed(3));
const fe = (v) => (Math.abs(v) < 1e-3 && v !== 0 ? v.toExponential(2) : v.toFixed(4));

function renderNumbers() {
  const a = last;
  const s = analysedState;
  const det2 = (m) => {
    // det of a small dense matrix by Gaussian elimination.
    const A = m.map((r) => [...r]);
    let d = 1;
    for (let c = 0; c < A.length; c++) {
      let p = c;
      for (let r = c + 1; r < A.length; r++) if (Math.abs(A[r][c]) > Math.abs(A[p][c])) p = r;
      if (A[p][c] === 0) return 0;
      if (p !== c) { [A[p], A[c]] = [A[c], A[p]]; d = -d; }
      d *= A[c][c];
      for (let r = c + 1; r < A.length; r++) {
        const f = A[r][c] / A[c][c];
        for (let k = c; k < A.length; k++) A[r][k] -= f * A[c][k];
      }
    }
    return d;
  };
  const tr = (m) => m.reduce((t, r, k) => t + r[k], 0);
  // Negative = not conservative for some drawn P' (red). Within 1e-8·max(1, tr P) of zero it is
  // solver round-off of a bound that touches the region (the SDP's optimum does by design).
  const margin = (v, scale) => {
    if (v === undefined || v === null) return ["—", ""];
    const tol = 1e-8 * Math.max(1, scale);
    return [fe(v), v < -tol ? "neg" : v < 0 ? "tol" : ""];
  };
  // COIN over the drawn P' (worst, median): > 1 = not conservative for some drawn P' (red),
  // within 1e-8 of 1 = touching (the SDP's optimum does by design).
  const coin = (c) => {
    if (!c) return ["—", ""];
    return [`${f3(c.max)} (${f3(c.median)})`, c.max > 1 + 1e-8 ? "neg" : c.max > 1 ? "tol" : ""];
  };
  const omega = (r) => (r.omega ? r.omega.map(f3).join(", ") : "—");
  const body = document.querySelector("#table tbody");
  body.replaceChildren();
  // One row per estimate and per rule of the analysis; cells filled as text, never as HTML.
  const row = (key, color, label, note) => {
    const tr_ = document.createElement("tr");
    tr_.id = `row-${key}`;
    const name = document.createElement("td");
    const swatch = document.createElement("span");
    swatch.className = "swatch";
    swatch.style.borderColor = color;
    name.append(swatch, ` ${label}`);
    if (note) {
      const small = document.createElement("small");
      small.textContent = ` (${note})`;
      name.append(small);
    }
    tr_.append(name);
    body.appendChild(tr_);
    return tr_;
  };
  const cells = (tr_, values) => {
    for (const [cls, text] of values) {
      const td = document.createElement("td");
      td.className = cls;
      td.textContent = text;
      tr_.append(td);
    }
  };
  for (const key of ["pa", "pb"]) {
    cells(row(key, STYLE[key].color, STYLE[key].label), [["trace", f3(tr(s[key]))], ["det", f3(det2(s[key]))], ["omega", ""], ["margin", "—"], ["coin", "—"]]);
  }
  for (const report of a.rules) {
    const rule = RULE[report.method];
    const tr_ = row(rule.name, rule.colour, rule.label, rule.phrase);
    if (rule.unguaranteed) tr_.className = "unguaranteed";
    const r = report.response;
    if (!r) {
      cells(tr_, [["na", `not available: ${report.error}`]]);
      tr_.lastChild.colSpan = 5;
      continue;
    }
    const [mt, cls] = margin(report.margin, r.trace);
    const [ct, ccls] = coin(report.coin);
    cells(tr_, [["trace", f3(r.trace)], ["det", f3(r.det)], ["omega", omega(r)], [`margin ${cls}`, mt], [`coin ${ccls}`, ct]]);
  }

  const response = (m) => a.rules.find((r) => r.method === m)?.response;
  const [nmci, ci, sdp, certified] = ["nmci", "ci", "sdp", "certified"].map(response);
  const blocks = nmci.blocks.map((b, k) => `{${b.map((x) => "x" + (x + 1)).join(", ")}}: ω = ${f3(nmci.omega[k])}`).join(" · ");
  const d = $("details");
  const parts = [];
  parts.push(`<div id="blocks"><span class="k">nmCI blocks (${nmci.blocks.length}):</span> ${blocks}</div>`);
  if (sdp) {
    parts.push(`<div id="sdp-status"><span class="k">SDP:</span> status <b>${sdp.status}</b>, ${sdp.iterations} iterations, ${sdp.lmis} LMIs in the final working set of ${sdp.samples} samples, ${state.sampler === "hit_and_run" ? "hit-and-run sampler (no rejections)" : `sampler acceptance ${(sdp.acceptance_rate * 100).toPrecision(3)} %`}</div>`);
  }
  if (a.gap) {
    const upperName = `the ${RULE[a.gap.upper_rule].label} bound`;
    const level = a.gap.levels ? ` (certificate level${a.gap.levels.length > 1 ? "s" : ""} ${a.gap.levels.join(", ")})` : "";
    const verdict = a.gap.closed
      ? `<span id="gap-verdict" class="ok">proven optimal to 10⁻⁶ (relative): ${upperName}${a.gap.upper_rule === "certified" ? level : ""} is within 10⁻⁶ of the robust optimum</span>`
      : `<span id="gap-verdict" class="open">open: the robust optimum lies between the ends${level}</span>`;
    parts.push(`<div id="gap"><span class="k">robust optimum of tr P̄ lies in</span> [${a.gap.lower.toFixed(6)}, ${a.gap.upper.toFixed(6)}] <span class="k">(both ends proven, every rounding accounted for: a Lagrangian bound from the SDP's duals below, ${upperName} above): gap</span> ${a.gap.absolute.toExponential(2)} <span class="k">absolute,</span> ${(a.gap.relative * 100).toPrecision(3)} % <span class="k">relative —</span> ${verdict}</div>`);
  }
  if (certified) {
    const best = Math.min(ci.trace, nmci.trace);
    parts.push(`<div id="certified-status"><span class="k">certified rule:</span> tr P̄ ${certified.trace.toFixed(6)}${s.criterion !== "trace" ? " (minimises the trace; CI and nmCI above minimise log det)" : certified.trace < best - 1e-9 ? ` — ${((1 - certified.trace / best) * 100).toPrecision(3)} % below the best of CI and nmCI` : " — no tighter than nmCI here"}, proven to dominate K P' Kᵀ for every admissible P' (level ${(certified.levels || []).join(", ")}, status ${certified.status}, ${certified.iterations} iterations, repair ${certified.repair.toExponential(1)})</div>`);
  }
  if (a.region_error) {
    parts.push(`<div class="err" id="region-status">region: ${a.region_error}</div>`);
  } else if (a.region_count) {
    parts.push(`<div id="region-status"><span class="k">region and worst λ<sub>min</sub>:</span> ${a.region_count} admissible P<sub>ab</sub> drawn (${state.sampler === "hit_and_run" ? "hit-and-run" : `acceptance ${(a.region_acceptance_rate * 100).toPrecision(3)} %`}), independent of the SDP's samples</div>`);
  }
  d.innerHTML = parts.join("");
}

// ---------- wiring ----------
function buildLegend() {
  const legend = $("legend");
  for (const l of LAYERS) {
    const lab = document.createElement("label");
    const box = document.createElement("input");
    box.type = "checkbox";
    box.dataset.layer = l;
    box.checked = state.layers[l];
    box.addEventListener("change", () => {
      state.layers[l] = box.checked;
      history.replaceState(null, "", encodeHash(state));
      render();
    });
    const sw = document.createElement("span");
    sw.className = l === "region" ? "swatch fill" : "swatch";
    sw.style[l === "region" ? "background" : "borderColor"] = STYLE[l].color;
    lab.append(box, sw, document.createTextNode(STYLE[l].label));
    legend.appendChild(lab);
  }
}

function download(name, type, content) {
  const a = document.createElement("a");
  a.href = URL.createObjectURL(new Blob([content], { type }));
  a.download = name;
  a.click();
  setTimeout(() => URL.revokeObjectURL(a.href), 1000);
}

function init() {
  $("dim").replaceChildren(...[2, 3, 4, 5, 6].map((k) => new Option(String(k), k)));
  buildLegend();
  $("plot").addEventListener("pointermove", onDrag);
  for (const ev of ["pointerup", "pointercancel"]) $("plot").addEventListener(ev, () => (drag = null));
  $("preset").addEventListener("change", (e) => e.target.value !== "custom" && load(preset(e.target.value)));
  $("dim").addEventListener("change", (e) => load(resize(state, Number(e.target.value))));
  $("criterion").addEventListener("change", (e) => {
    state.criterion = e.target.value;
    changed();
  });
  $("sampler").addEventListener("change", (e) => {
    state.sampler = e.target.value;
    changed();
  });
  settingInput("samples", "samples", 1, 5000);
  settingInput("seed", "seed", 0, Number.MAX_SAFE_INTEGER);
  settingInput("region", "region", 0, 5000);
  for (const [id, k] of [["view-i", 0], ["view-j", 1]]) {
    $(id).addEventListener("change", (e) => {
      const v = Number(e.target.value);
      const other = state.view[1 - k];
      if (v === other) state.view[1 - k] = state.view[k];
      state.view[k] = v;
      syncControls();
      history.replaceState(null, "", encodeHash(state));
      render();
    });
  }
  for (const b of document.querySelectorAll("[data-pattern]")) {
    b.addEventListener("click", () => {
      state.pattern = patternPreset(b.dataset.pattern, state.n, state.pa, state.pb);
      state.preset = "custom";
      syncPattern();
      changed();
    });
  }
  $("export-svg").addEventListener("click", () => {
    const svg = $("plot").cloneNode(true);
    svg.querySelectorAll(".handle").forEach((h) => h.remove());
    download("nmci-view.svg", "image/svg+xml", new XMLSerializer().serializeToString(svg));
  });
  $("export-json").addEventListener("click", () => {
    if (!last) return;
    const { region, ...numbers } = last;
    download("nmci-numbers.json", "application/json", JSON.stringify({ state, ...numbers }, null, 2));
  });
  $("share").addEventListener("click", () => navigator.clipboard?.writeText(location.href));
  window.addEventListener("hashchange", () => {
    if (location.hash === encodeHash(state)) return;
    const { state: s, error } = decodeHash(location.hash);
    if (s) {
      showLinkError(error ?? "");
      load(s);
    } else if (error) showLinkError(error);
  });
  const { state: fromHash, error } = decodeHash(location.hash);
  load(fromHash ?? preset("paper"));
  if (error) showLinkError(error);
}

init();
