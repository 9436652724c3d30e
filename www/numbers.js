// The explorer's numbers panel: one row per estimate and per rule of an analysis (trace,
// determinant, ω, worst margin and COIN over the region), then each rule's own details (nmCI's
// blocks, the SDP's status, the proven bracket, the certified rule, the region).
import { EXPLORER_RULES, RULE } from "./rules.js";

const $ = (id) => document.getElementById(id);
// Labels and colours: the region and the two estimates here, every rule from the registry.
export const STYLE = {
  region: { label: "possible true fused P (known P_ab)", color: "#888" },
  pa: { label: "P_a", color: "#1f77b4" },
  pb: { label: "P_b", color: "#e07b00" },
  ...Object.fromEntries(EXPLORER_RULES.map((r) => [r.name, { label: r.legend, color: r.colour }])),
};

const f3 = (v) => (v === undefined || v === null ? "—" : Number(v).toFixed(3));
const fe = (v) => (Math.abs(v) < 1e-3 && v !== 0 ? v.toExponential(2) : v.toFixed(4));

const percent = (rate) => `${(rate * 100).toPrecision(3)} %`;

/** Which sampler drew `count` samples and, for `auto`, why (its `choice`: `kind`,
 * `pilot_trials`, `pilot_accepted`, `fell_back`). */
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
export function renderNumbersPanel(a, s) {
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
    // The guarantee in words where it is not "conservative"; on hover for every rule.
    const tr_ = row(rule.name, rule.colour, rule.label, rule.guarantee === "conservative" ? "" : rule.phrase);
    tr_.title = `${rule.label}: ${rule.phrase}`;
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
    parts.push(`<div id="sdp-status"><span class="k">SDP:</span> status <b>${sdp.status}</b>, ${sdp.iterations} iterations, ${sdp.lmis} LMIs in the final working set of ${sdp.samples} samples, ${samplerText(s.sampler, sdp.sampler_choice, sdp.acceptance_rate, sdp.samples)}</div>`);
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
    parts.push(`<div id="region-status"><span class="k">region and worst λ<sub>min</sub>:</span> ${a.region_count} admissible P<sub>ab</sub> drawn (${samplerText(s.sampler, a.region_sampler_choice, a.region_acceptance_rate, a.region_count)}), independent of the SDP's samples</div>`);
  }
  d.innerHTML = parts.join("");
}
