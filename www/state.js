// The explorer's state: presets, resizing, and the URL hash that makes a view shareable.

import { EXPLORER_RULES } from "./rules.js";

// The region, the two estimates, every rule the explorer computes (from the registry), then
// the second stage's proven rule (the cutting planes' gain with its proven bound, when a proof
// has one).
export const LAYERS = ["region", "pa", "pb", ...EXPLORER_RULES.map((r) => r.name), "proven"];
// Drawn by default: all but the rules guaranteed for chosen correlations only or not at all
// (`unguaranteed` in the registry); they are a click away.
const DEFAULT_OFF = EXPLORER_RULES.filter((r) => r.unguaranteed).map((r) => r.name);

// The samplers of admissible P_ab (`SamplerKind` in Rust) with the select's labels; the first is
// the default.
export const SAMPLERS = {
  auto: "auto (rejection where it works)",
  rejection: "rejection (paper)",
  hit_and_run: "hit-and-run",
};

const diag = (v) => v.map((x, i) => v.map((_, j) => (i === j ? x : 0)));
const blockDiag = (blocks) => {
  const n = blocks.reduce((s, b) => s + b.length, 0);
  const m = Array.from({ length: n }, () => Array(n).fill(0));
  let o = 0;
  for (const b of blocks) {
    b.forEach((row, i) => row.forEach((v, j) => (m[o + i][o + j] = v)));
    o += b.length;
  }
  return m;
};

export function patternPreset(kind, n, pa, pb) {
  const grid = (f) => Array.from({ length: n }, (_, i) => Array.from({ length: n }, (_, j) => f(i, j)));
  switch (kind) {
    case "full":
      return grid(() => true);
    case "diagonal":
      return grid((i, j) => i === j);
    case "block": {
      // The blocks P_a and P_b already have (their non-zero structure), or pairs of states.
      const comp = components(n, (i, j) => (pa && pa[i][j] !== 0) || (pb && pb[i][j] !== 0));
      const single = new Set(comp).size === 1 || new Set(comp).size === n;
      return grid((i, j) => (single ? Math.floor(i / 2) === Math.floor(j / 2) : comp[i] === comp[j]));
    }
    case "chain":
      // diagonal + super-diagonal: links every state, so nmCI = CI; only the optimum gains.
      return grid((i, j) => i === j || j === i + 1);
    default:
      throw new Error(`unknown pattern preset ${kind}`);
  }
}

function components(n, linked) {
  const parent = Array.from({ length: n }, (_, i) => i);
  const find = (i) => (parent[i] === i ? i : (parent[i] = find(parent[i])));
  for (let i = 0; i < n; i++) for (let j = i + 1; j < n; j++) if (linked(i, j)) parent[find(i)] = find(j);
  return parent.map((_, i) => find(i));
}

export function preset(name) {
  const base = { samples: 200, seed: 0, region: 300, criterion: "trace", sampler: Object.keys(SAMPLERS)[0], view: [0, 1], layers: Object.fromEntries(LAYERS.map((l) => [l, !DEFAULT_OFF.includes(l)])), preset: name };
  switch (name) {
    case "paper":
      return { ...base, n: 2, pa: diag([3, 1]), pb: diag([1, 4]), pattern: [[true, false], [false, true]] };
    case "correlated":
      return { ...base, n: 2, pa: [[3, 1.2], [1.2, 2]], pb: [[2, -0.9], [-0.9, 3]], pattern: [[true, false], [false, true]] };
    case "twoblock": {
      const pa = blockDiag([[[3, 0.5], [0.5, 1]], [[1, 0.2], [0.2, 2]]]);
      const pb = blockDiag([[[1, -0.3], [-0.3, 2]], [[4, 1], [1, 2]]]);
      return { ...base, n: 4, pa, pb, pattern: patternPreset("block", 4, pa, pb), view: [0, 2] };
    }
    case "six": {
      const pa = blockDiag([[[3, 0.4], [0.4, 1]], [[1, 0], [0, 2]], [[2, -0.5], [-0.5, 1.5]]]);
      const pb = blockDiag([[[1, 0.2], [0.2, 3]], [[2.5, 0.6], [0.6, 1]], [[1, 0.3], [0.3, 2.5]]]);
      return { ...base, n: 6, pa, pb, pattern: patternPreset("diagonal", 6), view: [0, 1] };
    }
    case "roundoff": {
      // Two axes with independent errors whose covariances carry a filter's round-off
      // (1e-13) across them: exact-zero detection finds one block, the coupling tolerance
      // keeps two at a proven inflation.
      const pa = blockDiag([[[3, 0.5], [0.5, 1]], [[1, 0.2], [0.2, 2]]]);
      const pb = blockDiag([[[1, -0.3], [-0.3, 2]], [[4, 1], [1, 2]]]);
      for (const [i, j, v] of [[0, 2, 1e-13], [1, 3, -2e-13]]) {
        pa[i][j] = pa[j][i] = v;
        pb[i][j] = pb[j][i] = -v;
      }
      return { ...base, n: 4, pa, pb, pattern: patternPreset("block", 4, pa, pb), view: [0, 2] };
    }
    default:
      throw new Error(`unknown preset ${name}`);
  }
}

/** Resizes a state to n states: keeps the top-left block, extends with identity / diagonal pattern. */
export function resize(state, n) {
  const grow = (m, fill) => Array.from({ length: n }, (_, i) => Array.from({ length: n }, (_, j) => (i < m.length && j < m.length ? m[i][j] : fill(i, j))));
  const eye = (i, j) => (i === j ? 1 : 0);
  const view = state.view.map((v) => Math.min(v, n - 1));
  if (view[0] === view[1]) view[1] = view[0] === 0 ? 1 : 0;
  return { ...state, n, pa: grow(state.pa, eye), pb: grow(state.pb, eye), pattern: grow(state.pattern, (i, j) => i === j), view, preset: "custom" };
}

/** Declared blocks as typed ("0 1 | 2 3") → `[[0, 1], [2, 3]]`, `undefined` for none, or an
 * error naming the first token that is not a state index (whether the blocks are a partition of
 * the states is the library's check, whose message the page shows). */
export function parseBlocks(text) {
  const t = text.trim();
  if (t === "") return { blocks: undefined };
  const blocks = t.split("|").map((group) => group.trim().split(/[\s,]+/).filter((x) => x !== ""));
  for (const group of blocks) {
    const bad = group.find((x) => !/^\d+$/.test(x));
    if (bad !== undefined) return { error: `declared blocks: "${bad}" is not a state index (0-based)` };
  }
  return { blocks: blocks.map((g) => g.map(Number)) };
}

export const formatBlocks = (blocks) => (blocks ? blocks.map((b) => b.join(" ")).join(" | ") : "");

export function encodeHash(state) {
  const compact = {
    n: state.n, pa: state.pa, pb: state.pb,
    pattern: state.pattern.map((r) => r.map((b) => (b ? 1 : 0)).join("")),
    samples: state.samples, seed: state.seed, region: state.region, criterion: state.criterion,
    sampler: state.sampler, view: state.view, layers: LAYERS.filter((l) => state.layers[l]), preset: state.preset,
    ...(state.couplingTol === undefined ? {} : { coupling_tol: state.couplingTol }),
    ...(state.blocks === undefined ? {} : { blocks: state.blocks }),
  };
  return "#" + encodeURIComponent(JSON.stringify(compact));
}

/** Parses a hash; returns null (and a reason) when it is not a valid state. */
export function decodeHash(hash) {
  if (!hash || hash.length < 2) return { state: null };
  let c;
  try {
    c = JSON.parse(decodeURIComponent(hash.slice(1)));
  } catch {
    return { state: null, error: "the link's state could not be read" };
  }
  const n = c.n;
  const square = (m) => Array.isArray(m) && m.length === n && m.every((r) => Array.isArray(r) && r.length === n && r.every((v) => typeof v === "number" && Number.isFinite(v)));
  const okPattern = Array.isArray(c.pattern) && c.pattern.length === n && c.pattern.every((r) => typeof r === "string" && /^[01]+$/.test(r) && r.length === n);
  if (!Number.isInteger(n) || n < 2 || n > 6 || !square(c.pa) || !square(c.pb) || !okPattern) {
    return { state: null, error: "the link's state is incomplete or out of range" };
  }
  const base = preset("paper");
  // Optional settings: absent → the default; present but invalid → the default, and named in
  // the returned error (never replaced silently).
  const ignored = [];
  const pick = (key, ok, value, fallback) => {
    if (c[key] === undefined) return fallback;
    if (ok) return value;
    ignored.push(key);
    return fallback;
  };
  const view = pick("view", Array.isArray(c.view) && c.view.length === 2 && c.view.every((v) => Number.isInteger(v) && v >= 0 && v < n) && c.view[0] !== c.view[1], c.view, [0, 1]);
  const int = (key, d, lo, hi) => pick(key, Number.isInteger(c[key]) && c[key] >= lo && c[key] <= hi, c[key], d);
  const state = {
    ...base, n, pa: c.pa, pb: c.pb,
    pattern: c.pattern.map((r) => [...r].map((ch) => ch === "1")),
    samples: int("samples", base.samples, 1, 5000), seed: int("seed", base.seed, 0, Number.MAX_SAFE_INTEGER), region: int("region", base.region, 0, 5000),
    criterion: pick("criterion", c.criterion === "trace" || c.criterion === "logdet", c.criterion, base.criterion), view,
    sampler: pick("sampler", Object.hasOwn(SAMPLERS, c.sampler), c.sampler, base.sampler),
    layers: pick("layers", Array.isArray(c.layers), Array.isArray(c.layers) && Object.fromEntries(LAYERS.map((l) => [l, c.layers.includes(l)])), base.layers),
    preset: pick("preset", typeof c.preset === "string", c.preset, "custom"),
    couplingTol: pick("coupling_tol", typeof c.coupling_tol === "number" && Number.isFinite(c.coupling_tol), c.coupling_tol, undefined),
    blocks: pick("blocks", Array.isArray(c.blocks) && c.blocks.every((b) => Array.isArray(b) && b.every(Number.isInteger)), c.blocks, undefined),
  };
  return ignored.length
    ? { state, error: `the link's ${ignored.join(", ")} ${ignored.length === 1 ? "was" : "were"} out of range; the default${ignored.length === 1 ? " is" : "s are"} used` }
    : { state };
}
