// The explorer's UI: inputs, drawing and wiring; the worker round trip is www/explore-client.js,
// the numbers panel www/numbers.js, the state and its URL www/state.js.
import { LAYERS, SAMPLERS, preset, patternPreset, resize, encodeHash, decodeHash, parseBlocks, formatBlocks } from "./state.js";
import { el, marginal, axes, fromAxes, ellipsePath, frame } from "./plot.js";
import { EXPLORER_RULES } from "./rules.js";
import { createExploreClient } from "./explore-client.js";
import { renderNumbersPanel, STYLE } from "./numbers.js";
import { createProveClient, worthProving } from "./prove-client.js";
import { download } from "./charts.js";
import { watchTables } from "./tables.js";

const $ = (id) => document.getElementById(id);
// How a rule's ellipse is stroked follows its guarantee: the conservative rules solid, each
// thinner than the one before (CI under the certified rule); relaxations dashed; the
// unguaranteed rules dotted. nmCI, which often coincides with the certified rule and the
// SDP (the paper's example), is drawn last and long-dashed, so the lines beneath show in its
// gaps and its own colour stays visible.
const STROKE = (() => {
  const stroke = { pa: { width: 2, dash: "none" }, pb: { width: 2, dash: "none" } };
  let k = 0;
  for (const r of EXPLORER_RULES) {
    stroke[r.name] = r.guarantee === "conservative" ? { width: Math.max(1.2, 2.6 - 0.6 * k++), dash: "none" }
      : r.guarantee === "relaxation" ? { width: 2, dash: "7 4" }
      : { width: 1.8, dash: "2 3" };
  }
  stroke.proven = { width: 1.6, dash: "none" }; // a proven bound: solid
  stroke.nmci = { ...stroke.nmci, dash: "9 5" };
  return stroke;
})();

let state = preset("paper");
let text = null; // the grids' raw text, so an invalid entry stays visible
let last = null; // the last valid analysis (the picture stays when an input is invalid)
let analysedState = null;
// The second stage of the analysed state (www/prove-client.js): `{ running }`, `{ proof }` or
// `{ error }`; null when there is none.
let second = null;
// One explore request in flight, the latest state wins (www/explore-client.js).
const client = createExploreClient({
  url: new URL("./worker.js", import.meta.url),
  onBusy: (busy) => {
    $("busy").hidden = !busy;
    if (!busy) writeHash();
    document.body.dataset.ready = String(!busy);
  },
  onResult: (result, analysed) => {
    last = result;
    analysedState = analysed;
    second = null;
    if (worthProving(result)) {
      second = { running: true };
      prover.start(analysed);
    }
    clearErrors();
    document.body.dataset.stale = "false";
    render();
  },
  onError: (error, field) => showInputError(error, field),
  onWorkerError: (message) => showGeneral(`${message}; the numbers shown are of the last state computed`),
  onTimings: (median, count) => {
    $("timing").textContent = count ? `recompute (all rules + region, worker round trip): median ${median.toFixed(1)} ms over ${count}` : "";
  },
});
// The second stage of the analysed state; an edit abandons it.
const prover = createProveClient({
  url: new URL("./prove-worker.js", import.meta.url),
  onProving: (running) => {
    document.body.dataset.proving = String(running);
  },
  onProof: (proof, of) => {
    if (of !== analysedState) return;
    second = { proof };
    render(); // the proven rule's ellipse, and the numbers
  },
  onProofError: (error, of) => {
    if (of !== analysedState) return;
    second = { error };
    renderNumbers();
  },
});
const submit = () => {
  if (second?.running) {
    prover.cancel();
    second = null;
    renderNumbers();
  }
  client.submit(structuredClone(state));
};

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
  region_samples: "err-settings", sampler: "err-settings", coupling_tol: "err-settings", blocks: "err-pattern",
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
  $("coupling-tol").value = state.couplingTol ?? "";
  $("declared-blocks").value = formatBlocks(state.blocks);
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

const PRESETS = ["paper", "correlated", "twoblock", "six", "roundoff"];

// The URL's hash holds the state (a link reproduces the view). After an edit that starts an
// analysis it is written once the worker is idle, not at the edit: each `replaceState` costs the
// browser process several milliseconds, which on a machine with few cores ran alongside the
// worker's analysis and lengthened it. A link copied before then is
// written first (`share`).
let hashPending = false;
function writeHash() {
  if (!hashPending) return;
  hashPending = false;
  const hash = encodeHash(state);
  if (location.hash !== hash) history.replaceState(null, "", hash);
}

function changed() {
  $("preset").value = PRESETS.includes(state.preset) ? state.preset : "custom";
  hashPending = true;
  if (!allCellsValid()) return writeHash();
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
    proven: second?.proof?.rule?.p ?? null,
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
    // One path of one closed subpath per ellipse: all drawn in the same direction, so the
    // nonzero fill paints their union once — the look of one path each under the group's
    // opacity, with one DOM node instead of hundreds.
    const rg = el("g", { opacity: 0.32, id: "layer-region" }, g);
    el("path", { d: region.map((m) => ellipsePath(m, toPx)).join(""), fill: STYLE.region.color, stroke: "none" }, rg);
  }
  const onTop = ["nmci"]; // drawn last (STROKE)
  for (const k of [...LAYERS.filter((l) => l !== "region" && !onTop.includes(l)), ...onTop.filter((l) => LAYERS.includes(l))]) {
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

function renderNumbers() {
  if (!last || !analysedState) return;
  renderNumbersPanel(last, analysedState, second);
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
    if (STROKE[l] && STROKE[l].dash !== "none") sw.style.borderTopStyle = STROKE[l].dash.startsWith("2 ") ? "dotted" : "dashed";
    lab.append(box, sw, document.createTextNode(STYLE[l].label));
    legend.appendChild(lab);
  }
}

/** The picture as a file: a title naming the matrices and the states shown, the plot, and a
 * legend of the layers drawn (each line in its own stroke), without the drag handles. */
function exportedSvg() {
  const NS = "http://www.w3.org/2000/svg";
  const node = (tag, attrs, parent, text) => {
    const e = document.createElementNS(NS, tag);
    for (const [k, v] of Object.entries(attrs)) e.setAttribute(k, v);
    if (text !== undefined) e.textContent = text;
    parent.appendChild(e);
    return e;
  };
  const s = analysedState ?? state;
  const rows = (m) => `[${m.map((r) => `[${r.map((v) => +v.toPrecision(6)).join(", ")}]`).join(", ")}]`;
  const pattern = s.pattern.map((r) => r.map((b) => (b ? "1" : "0")).join("")).join(" ");
  const [i, j] = s.view;
  const shown = LAYERS.filter((l) => s.layers[l] && $(`layer-${l}`));
  const top = 44, rowH = 18, width = 520, height = top + 520 + 12 + shown.length * rowH;
  const root = document.createElementNS(NS, "svg");
  root.setAttribute("xmlns", NS);
  root.setAttribute("viewBox", `0 0 ${width} ${height}`);
  root.setAttribute("width", width);
  root.setAttribute("height", height);
  node("rect", { width, height, fill: "#fff" }, root);
  node("title", {}, root, `nmci: ${shown.map((l) => STYLE[l].label).join(", ")}`);
  node("text", { x: 10, y: 18, "font-size": 13, "font-weight": 600, fill: "#111" }, root,
    `P_a = ${rows(s.pa)}, P_b = ${rows(s.pb)}`);
  node("text", { x: 10, y: 36, "font-size": 11, fill: "#444" }, root,
    `P_ab pattern ${pattern} (1 = unknown, 0 = known zero); 1σ marginals of x${i + 1}, x${j + 1}; ${s.criterion}, ${s.samples} SDP samples, seed ${s.seed}`);
  const plot = $("plot").cloneNode(true);
  plot.querySelectorAll(".handle").forEach((h) => h.remove());
  const g = node("g", { transform: `translate(0, ${top})` }, root);
  for (const child of [...plot.childNodes]) g.appendChild(child);
  shown.forEach((l, k) => {
    const y = top + 520 + 12 + k * rowH + rowH / 2;
    const line = { x1: 14, x2: 44, y1: y, y2: y, stroke: STYLE[l].color, "stroke-width": l === "region" ? 8 : STROKE[l].width };
    if (l === "region") line.opacity = 0.35;
    else if (STROKE[l].dash !== "none") line["stroke-dasharray"] = STROKE[l].dash;
    node("line", line, root);
    node("text", { x: 52, y: y + 4, "font-size": 12, fill: "#111" }, root, STYLE[l].label);
  });
  return root;
}


// Stale: while an input error is shown, the numbers and the picture are those of the last
// valid input (style.css greys them and shows #stale-note).
function watchStale() {
  const slots = ["err-pa", "err-pb", "err-pattern", "err-settings"].map($);
  const update = () => {
    document.body.dataset.stale = String(Boolean(last) && slots.some((e) => e.textContent !== ""));
  };
  const observer = new MutationObserver(update);
  for (const e of slots) observer.observe(e, { childList: true, characterData: true, subtree: true });
  update();
}

function init() {
  watchStale();
  watchTables();
  $("dim").replaceChildren(...[2, 3, 4, 5, 6].map((k) => new Option(String(k), k)));
  $("sampler").replaceChildren(...Object.entries(SAMPLERS).map(([value, label]) => new Option(label, value)));
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
  // The coupling tolerance: empty = the library's default; the range is checked by the library
  // (its error comes back naming `coupling_tol` and is shown under the settings).
  $("coupling-tol").addEventListener("input", (e) => {
    const t = e.target.value.trim();
    const v = Number(t);
    if (t !== "" && !Number.isFinite(v)) {
      e.target.classList.add("bad");
      $("err-settings").textContent = `coupling tol: "${e.target.value}" is not a number`;
      return;
    }
    e.target.classList.remove("bad");
    $("err-settings").textContent = "";
    state.couplingTol = t === "" ? undefined : v;
    changed();
  });
  // Declared blocks: parsed here, checked by the library (a partition of the states that
  // agrees with P_a, P_b and the pattern; its errors name `blocks`, `pa`, `pb` or
  // `pab_unknown` and are shown beside that input).
  $("declared-blocks").addEventListener("input", (e) => {
    const { blocks, error } = parseBlocks(e.target.value);
    if (error) {
      e.target.classList.add("bad");
      $("err-pattern").textContent = error;
      return;
    }
    e.target.classList.remove("bad");
    $("err-pattern").textContent = "";
    state.blocks = blocks;
    changed();
  });
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
    download("nmci-view.svg", "image/svg+xml", new XMLSerializer().serializeToString(exportedSvg()));
  });
  $("export-json").addEventListener("click", () => {
    if (!last) return;
    const { region, ...numbers } = last;
    // The second stage's proof (its bracket, and the cutting planes' gains with their proven
    // bound) when it has finished.
    const proof = second?.proof ? { second_stage: second.proof } : {};
    download("nmci-numbers.json", "application/json", JSON.stringify({ state, ...numbers, ...proof }, null, 2));
  });
  $("share").addEventListener("click", () => {
    writeHash();
    // The clipboard needs a secure context and the browser's permission: when it is refused
    // the page says so (the link is the address bar's).
    const refused = () => showGeneral("the link could not be copied (the browser refused the clipboard): copy it from the address bar");
    if (!navigator.clipboard) return refused();
    navigator.clipboard.writeText(location.href).catch(refused);
  });
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
