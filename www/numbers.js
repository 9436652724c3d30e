// The explorer's numbers panel: one row per estimate and per rule of an analysis (trace,
// determinant, ω, worst margin and COIN over the region), then each rule's own details (nmCI's
// blocks, the SDP's status, the proven bracket, the certified rule, the region).
import { EXPLORER_RULES, RULE } from "./rules.js";
import { PROVE_SECONDS } from "./prove-client.js";

const $ = (id) => document.getElementById(id);
// Labels and colours: the region and the two estimates here, every rule from the registry.
export const STYLE = {
  region: { label: "possible true fused P (known P_ab)", color: "#888" },
  pa: { label: "P_a", color: "#1f77b4" },
  pb: { label: "P_b", color: "#e07b00" },
  ...Object.fromEntries(EXPLORER_RULES.map((r) => [r.name, { label: r.legend, color: r.colour }])),
  // The second stage's rule: the cutting planes' gain, in their registry colour.
  proven: { label: "cutting planes, proven bound", color: RULE.sdp_cuts.colour },
};

const f3 = (v) => (v === undefined || v === null ? "—" : Number(v).toFixed(3));
const fe = (v) => (Math.abs(v) < 1e-3 && v !== 0 ? v.toExponential(2) : v.toFixed(4));

const percent = (rate) => `${(rate * 100).toPrecision(3)} %`;

/** Which sampler drew `count` samples and, for `auto`, why (its `choice`: `kind`,
 * `pilot_trials`, `pilot_accepted`, `fell_back`). */
// Which certificate proved each block's bound: a level-r certificate for every direction, or
// (two-state blocks) level 1 on each of k sectors of directions (`sectors[i] > 0`).
function certificateText(levels, sectors) {
  const one = (level, i) => (sectors && sectors[i] > 0 ? `level ${level} on ${sectors[i]} sectors` : `level ${level}`);
  return `certificate${levels.length > 1 ? "s" : ""} ${levels.map(one).join(", ")}`;
}

function samplerText(requested, choice, acceptance, count) {
  const kind = choice ? choice.kind : requested;
  const drawn = kind === "hit_and_run" ? "hit-and-run sampler (no rejections)" : `rejection sampler, acceptance ${percent(acceptance)}`;
  if (!choice) return drawn;
  const pilot = `the rejection sampler's pilot accepted ${choice.pilot_accepted} of ${choice.pilot_trials} proposals`;
  if (kind === "rejection") return `auto: ${drawn} (${pilot})`;
  if (choice.fell_back) return `auto: ${drawn} — ${pilot}, but the rejection sampler then ran out of its budget`;
  return `auto: ${drawn} — ${pilot} (${percent(choice.pilot_accepted / choice.pilot_trials)}), too few for ${count} samples within its budget`;
}

/** Fills the numbers table and the details under it from an analysis `a` of the explorer
 * state `s`. */
export function renderNumbersPanel(a, s, second = null) {
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
  // The estimates' trace and det come from wasm, computed as the rules' are.
  for (const e of a.estimates) {
    cells(row(e.name, STYLE[e.name].color, STYLE[e.name].label), [["trace", f3(e.trace)], ["det", f3(e.det)], ["omega", ""], ["margin", "—"], ["coin", "—"]]);
  }
  for (const report of a.rules) {
    const rule = RULE[report.method];
    const r = report.response;
    const [mt, cls] = r ? margin(report.margin, r.trace) : [];
    const [ct, ccls] = r ? coin(report.coin) : [];
    // The guarantee in words where it is not "conservative"; on hover for every rule. A
    // relaxation flagged red says why that can happen.
    const flagged = rule.guarantee === "relaxation" && (cls === "neg" || ccls === "neg");
    const note = rule.guarantee === "conservative" ? "" : flagged ? `${rule.phrase}: bounds only the P_ab it sampled, and a drawn one exceeds it` : rule.phrase;
    const tr_ = row(rule.name, rule.colour, rule.label, note);
    tr_.title = `${rule.label}: ${rule.phrase}`;
    if (rule.unguaranteed) tr_.className = "unguaranteed";
    if (!r) {
      cells(tr_, [["na", `not available: ${report.error}`]]);
      tr_.lastChild.colSpan = 5;
      continue;
    }
    cells(tr_, [["trace", f3(r.trace)], ["det", f3(r.det)], ["omega", omega(r)], [`margin ${cls}`, mt], [`coin ${ccls}`, ct]]);
  }

  // The second stage's proven rule (the cutting planes' gains with the bound proven for them):
  // a row of its own once it has finished.
  const proven = second?.proof?.rule;
  if (proven) {
    const tr_ = row("proven", STYLE.proven.color, STYLE.proven.label, "second stage, conservative");
    tr_.title = "the cutting planes' gains with the bound proven for them, every rounding enclosed (its gains and P̄ are in the JSON export)";
    cells(tr_, [["trace", f3(proven.trace)], ["det", "—"], ["omega", "—"], ["margin", "—"], ["coin", "—"]]);
  }

  const response = (m) => a.rules.find((r) => r.method === m)?.response;
  const [nmci, ci, sdp, certified] = ["nmci", "ci", "sdp", "certified"].map(response);
  const blocks = nmci.blocks.map((b, k) => `{${b.map((x) => "x" + (x + 1)).join(", ")}}: ω = ${f3(nmci.omega[k])}`).join(" · ");
  // Built as DOM nodes: every number and message is text, never parsed as HTML.
  const key = (...children) => el("span", { class: "k" }, ...children);
  const parts = [];
  parts.push(el("div", { id: "blocks" }, key(`nmCI blocks (${nmci.blocks.length}):`), ` ${blocks}`));
  // How the blocks were found, when that is worth saying (couplings absorbed, or a weak one
  // keeping blocks merged): the library's sentence, and what the absorption cost nmCI.
  if (a.structure?.note) {
    const cost = a.structure.nmci_trace_cost;
    parts.push(el("div", { id: "structure-note" }, key("structure:"), ` ${a.structure.note}`,
      cost === undefined ? "" : `; nmCI's trace is ${cost.toExponential(2)} above the same covariances with the couplings set to zero`));
  }
  if (sdp) {
    parts.push(el("div", { id: "sdp-status" }, key("SDP:"), " status ", el("b", {}, sdp.status),
      `, ${sdp.iterations} iterations, ${sdp.lmis} LMIs in the final working set of ${sdp.samples} samples, ${samplerText(s.sampler, sdp.sampler_choice, sdp.acceptance_rate, sdp.samples)}`));
  }
  if (a.gap) {
    // The second stage's bracket (www/prove-client.js) where it is narrower: both are proven.
    const proof = second?.proof && second.proof.relative < a.gap.relative ? second.proof : null;
    const g = proof ?? a.gap;
    const level = g.levels ? ` (${certificateText(g.levels, g.sectors)})` : "";
    const upperName = proof?.own_rule_proven
      ? `the cutting planes' own rule (proven on ${proof.sectors[0]} cones of directions)`
      : `the ${RULE[g.upper_rule].label} bound`;
    const withLevel = `${upperName}${g.upper_rule === "certified" && !proof?.own_rule_proven ? level : ""}`;
    const verdict = g.closed
      ? el("span", { id: "gap-verdict", class: "ok" }, `proven optimal to 10⁻⁶ (relative): ${withLevel} is within 10⁻⁶ of the robust optimum`)
      : el("span", { id: "gap-verdict", class: "open" }, `open: the robust optimum lies between the ends${proof?.own_rule_proven ? "" : level}`);
    const lowerName = proof ? "a Lagrangian bound from the cutting planes' duals" : "a Lagrangian bound from the SDP's duals";
    parts.push(el("div", { id: "gap" }, key("robust optimum of tr P̄ lies in"), ` [${g.lower.toFixed(6)}, ${g.upper.toFixed(6)}] `,
      key(`(both ends proven, every rounding accounted for: ${lowerName} below, ${upperName} above): gap`),
      ` ${g.absolute.toExponential(2)} `, key("absolute,"), ` ${g.relative < 1e-4 ? g.relative.toExponential(2) : `${(g.relative * 100).toPrecision(3)} %`} `, key("relative —"), " ", verdict));
    if (second) parts.push(secondStage(second, a.gap));
  }
  if (certified) {
    const best = Math.min(ci.trace, nmci.trace);
    const comparison = s.criterion !== "trace"
      ? " (minimises the trace; CI and nmCI above minimise log det)"
      : certified.trace < best - 1e-9 ? ` — ${((1 - certified.trace / best) * 100).toPrecision(3)} % below the best of CI and nmCI` : " — no tighter than nmCI here";
    parts.push(el("div", { id: "certified-status" }, key("certified rule:"),
      ` tr P̄ ${certified.trace.toFixed(6)}${comparison}, proven to dominate K P' Kᵀ for every admissible P' (${certificateText(certified.levels || [], certified.sectors)}, status ${certified.status}, ${certified.iterations} iterations, repair ${certified.repair.toExponential(1)})`));
  }
  if (a.region_error) {
    parts.push(el("div", { class: "err", id: "region-status" }, `region: ${a.region_error}`));
  } else if (a.region_count) {
    parts.push(el("div", { id: "region-status" }, key("region and worst λ", el("sub", {}, "min"), ":"),
      ` ${a.region_count} admissible P`, el("sub", {}, "ab"),
      ` drawn (${samplerText(s.sampler, a.region_sampler_choice, a.region_acceptance_rate, a.region_count)}), independent of the SDP's samples`));
  }
  $("details").replaceChildren(...parts);
}

/** The second stage's line: running, its outcome, or why it failed. */
function secondStage(second, first) {
  const key = (...children) => el("span", { class: "k" }, ...children);
  if (second.running) {
    return el("div", { id: "proof-status" }, key("second stage:"), ` the cutting planes are closing the bracket (up to ${PROVE_SECONDS} s)…`);
  }
  if (second.error !== undefined) {
    return el("div", { id: "proof-status", class: "err" }, `second stage: ${second.error}`);
  }
  const p = second.proof;
  if (!p) return el("div", { id: "proof-status" }, key("second stage:"), " the cutting planes gave no bracket");
  const stop = { tolerance: "converged", gap_closed: "the bracket closed", time_limit: `the time limit (${PROVE_SECONDS} s)`, max_iterations: "the iteration limit" }[p.stop] ?? p.stop;
  const narrower = p.relative < first.relative
    ? `narrowed the bracket ${(first.relative / Math.max(p.relative, Number.MIN_VALUE)).toPrecision(2)} times`
    : "did not narrow the bracket";
  const pointed = p.proof_rounds > 0
    ? `; the proof pointed them to cuts their search had missed (${p.proof_rounds === 1 ? "once" : "twice"})`
    : "";
  // The loop's gain with the bound proven for it: the rule a filter can carry on.
  const rule = p.rule ? `; their gains with the bound proven for them (tr P̄ ${p.rule.trace.toFixed(6)}, drawn in the picture) are in the JSON export` : "";
  return el("div", { id: "proof-status" }, key("second stage:"), ` the cutting planes (${p.iterations} iterations, stopped by ${stop}) ${narrower}${pointed}${rule}`);
}

/** An element with attributes and children (strings become text nodes). */
function el(tag, attrs, ...children) {
  const node = document.createElement(tag);
  for (const [name, value] of Object.entries(attrs)) node.setAttribute(name, value);
  node.append(...children);
  return node;
}
