// The "N-way fusion" tab: k ≥ 2 two-dimensional estimates fused at once by N-way CI and
// nmCI through the wasm `fuse` (the same JSON contract as `nmci fuse` with `estimates`),
// on the main thread (a fusion takes well under a millisecond). Invalid input is shown inline.
import init, { fuse } from "./pkg/nmci.js";
import { el, ellipsePath, frame } from "./plot.js";
import { RULES } from "./rules.js";

const $ = (s) => document.querySelector(s);
const COLORS = ["#1f77b4", "#e07b00", "#2ca02c", "#9467bd", "#8c564b", "#e377c2", "#17becf", "#bcbd22"];
// The rules that fuse k ≥ 2 estimates (`nway` in the registry), each drawn thinner than the
// one before so coinciding bounds stay visible.
// Each thinner than the one before; nmCI, drawn last, long-dashed so CI shows in its gaps
// where the two coincide.
const NWAY = RULES.filter((r) => r.nway).map((r, k) => ({ ...r, width: Math.max(1.4, 3 - 0.8 * k), dash: r.name === "nmci" ? "9 5" : "none" }));
const MAX = 8;
const FIELDS = ["x1", "x2", "p11", "p12", "p22"];
// Three estimates, each good along one direction: nmCI takes x₁ from the first and x₂ from
// the second when the pairs' cross-covariances are diagonal.
let rows = [
  { x1: "1", x2: "0", p11: "1", p12: "0", p22: "9" },
  { x1: "0", x2: "1", p11: "9", p12: "0", p22: "1" },
  { x1: "0", x2: "0", p11: "4", p12: "0", p22: "4" },
];
const ready = init();

function buildInputs() {
  const body = $("#nway-inputs tbody");
  body.replaceChildren();
  rows.forEach((row, k) => {
    const tr = document.createElement("tr");
    const name = document.createElement("td");
    const swatch = document.createElement("span");
    swatch.className = "swatch";
    swatch.style.borderColor = COLORS[k];
    name.append(swatch, ` e${k + 1}`);
    tr.append(name);
    for (const f of FIELDS) {
      const td = document.createElement("td");
      const input = document.createElement("input");
      input.value = row[f];
      input.setAttribute("aria-label", `e${k + 1} ${f}`);
      input.addEventListener("input", () => {
        row[f] = input.value;
        update();
      });
      td.append(input);
      tr.append(td);
    }
    const td = document.createElement("td");
    const remove = document.createElement("button");
    remove.textContent = "remove";
    remove.disabled = rows.length <= 2;
    remove.addEventListener("click", () => {
      rows.splice(k, 1);
      buildInputs();
      update();
    });
    td.append(remove);
    tr.append(td);
    body.append(tr);
  });
  $("#nway-add").disabled = rows.length >= MAX;
}

/** The estimates as numbers; marks and names the first entry that is not a number. */
function readEstimates() {
  const inputs = [...document.querySelectorAll("#nway-inputs input")];
  inputs.forEach((i) => i.classList.remove("bad"));
  return rows.map((row, k) => {
    const v = {};
    for (const [f, input] of FIELDS.map((f, j) => [f, inputs[k * FIELDS.length + j]])) {
      const raw = row[f].trim();
      v[f] = Number(raw);
      if (raw === "" || !Number.isFinite(v[f])) {
        input.classList.add("bad");
        throw new Error(`e${k + 1} ${f}: "${row[f]}" is not a number`);
      }
    }
    return { x: [v.x1, v.x2], p: [[v.p11, v.p12], [v.p12, v.p22]] };
  });
}

function request(method, estimates) {
  const criterion = $("#nway-criterion").value;
  const req = { estimates, method, criterion };
  if (method === "nmci" && $("#nway-pattern").value === "diagonal") {
    req.patterns = [];
    for (let i = 0; i < estimates.length; i++) {
      for (let j = i + 1; j < estimates.length; j++) req.patterns.push({ i, j, pab_unknown: [[true, false], [false, true]] });
    }
  }
  return req;
}

const f3 = (v) => (Math.abs(v) >= 1e4 || (Math.abs(v) < 1e-3 && v !== 0) ? v.toExponential(2) : v.toFixed(3));

async function update() {
  await ready;
  $("#err-nway").textContent = "";
  let estimates, results;
  try {
    estimates = readEstimates();
    results = Object.fromEntries(NWAY.map((r) => [r.name, fuse(request(r.name, estimates))]));
  } catch (err) {
    $("#err-nway").textContent = err && err.message ? err.message : String(err);
    document.body.dataset.nway = "error";
    return;
  }
  const body = $("#nway-table tbody");
  body.replaceChildren();
  for (const rule of NWAY) {
    const r = results[rule.name];
    const tr = document.createElement("tr");
    tr.id = `nway-row-${rule.name}`;
    const weights = r.weights.map((w, b) => `{${r.blocks[b].map((s) => "x" + (s + 1)).join(", ")}}: [${w.map(f3).join(", ")}]`).join(" · ");
    const name = document.createElement("td");
    const swatch = document.createElement("span");
    swatch.className = "swatch";
    swatch.style.borderColor = rule.colour;
    name.append(swatch, ` N-way ${rule.label}`);
    tr.append(name);
    for (const [cls, text] of [["trace", f3(r.trace)], ["det", f3(r.det)], ["x", `(${r.x.map(f3).join(", ")})`], ["weights", weights]]) {
      const td = document.createElement("td");
      td.className = cls;
      td.textContent = text;
      tr.append(td);
    }
    body.append(tr);
  }
  draw(estimates, results);
  document.body.dataset.nway = "ready";
}

function draw(estimates, results) {
  const svg = $("#nway-plot");
  svg.replaceChildren();
  const all = [...estimates, ...Object.values(results)];
  const extent = Math.max(...all.flatMap((e) => [Math.abs(e.x[0]) + Math.sqrt(e.p[0][0]), Math.abs(e.x[1]) + Math.sqrt(e.p[1][1])]), 1e-9) * 1.1;
  const { toPx } = frame(svg, extent, ["x₁", "x₂"]);
  const at = (x) => (u, v) => toPx(x[0] + u, x[1] + v);
  estimates.forEach((e, k) => {
    el("path", { d: ellipsePath(e.p, at(e.x)), fill: "none", stroke: COLORS[k], "stroke-width": 1.5, class: "nway-estimate" }, svg);
  });
  for (const rule of NWAY) {
    const r = results[rule.name];
    el("path", { id: `nway-layer-${rule.name}`, d: ellipsePath(r.p, at(r.x)), fill: "none", stroke: rule.colour, "stroke-width": rule.width, "stroke-dasharray": rule.dash }, svg);
  }
  // The legend: each estimate's colour, then the rules' (nmCI long-dashed, drawn over CI where
  // they coincide).
  const item = (colour, label, { width = 1.5, dash = "none" } = {}) => {
    const span = document.createElement("span");
    const swatch = document.createElement("span");
    swatch.className = "swatch";
    swatch.style.borderColor = colour;
    swatch.style.borderTopWidth = `${width}px`;
    if (dash !== "none") swatch.style.borderTopStyle = "dashed";
    span.append(swatch, ` ${label}`);
    return span;
  };
  $("#nway-legend").replaceChildren(
    ...estimates.map((e, k) => item(COLORS[k], `e${k + 1}`)),
    ...NWAY.map((rule) => item(rule.colour, `N-way ${rule.label}`, rule)),
  );
}

$("#nway-add").addEventListener("click", () => {
  rows.push({ x1: "0", x2: "0", p11: "2", p12: "0", p22: "2" });
  buildInputs();
  update();
});
$("#nway-pattern").addEventListener("change", update);
$("#nway-criterion").addEventListener("change", update);
buildInputs();
update();
