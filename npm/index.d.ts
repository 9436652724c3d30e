// The package's types: `fuse`, `rules`, `contract_fields`, `explore`, `prove` and `version`,
// each typed here (the request and response by the contract, contract.d.ts). wasm-bindgen's
// own declarations (nmci.d.ts) give the module's initialisation; the page's own exports
// (its workers' study and fig. 2, chart drawing) and test hooks are not declared: they are
// not the package's API (src/wasm.rs).
import type { AutoChoice, FuseRequest, FuseResponse, Guarantee, Method, Rows, StructureDetails } from "./contract.js";

export { default, initSync } from "./nmci.js";
export type { InitInput, InitOutput, SyncInitInput } from "./nmci.js";
export type * from "./contract.js";

/**
 * Runs a fusion request and returns its response; throws an `Error` (`FuseError`) naming the
 * problem and, in `field`, the request field at fault.
 */
export function fuse(request: FuseRequest): FuseResponse;
/** A list of requests: the list of their responses; the first that fails throws, naming its index. */
export function fuse(requests: FuseRequest[]): FuseResponse[];

/** The contract's field names, from the Rust crate. */
export function contract_fields(): { request: string[]; response: string[] };

/** One rule of the registry (`nmci::rules::RULES`). */
export interface RuleInfo {
  /** The rule (the contract's `method`). */
  method: Method;
  /** Its name in the contract, on the CLI and in file columns. */
  name: Method;
  /** Its label in tables and charts (`"nmCI"`). */
  label: string;
  /** Its label in legends (the label with what it is guaranteed for, where that is not "conservative"). */
  legend: string;
  /** What its bound is guaranteed for. */
  guarantee: Guarantee;
  /** The guarantee in words (`"a relaxation"`). */
  phrase: string;
  /** Whether it guarantees nothing (EI, naive fusion). */
  unguaranteed: boolean;
  /** Its colour, `#rrggbb`. */
  colour: string;
  /** Which criteria it minimises. */
  criteria: "both" | "trace_only" | "no_weight";
  /** The request fields it takes beyond the estimates and `criterion`. */
  options: string[];
  /** Whether it fuses `k ≥ 2` estimates (`estimates`). */
  nway: boolean;
  /** Whether the explorer shows it. */
  explorer: boolean;
  /** The largest state dimension and independent block it takes. */
  limits: { max_dim: number; max_block: number };
}

/** Every rule with its guarantee, criteria and options. */
export function rules(): RuleInfo[];

/** The explorer's request: a two-estimate fusion request without `method` (every rule runs), and the region's size. */
export interface ExploreRequest extends Omit<FuseRequest, "method" | "estimates" | "patterns"> {
  /** Admissible cross-covariances drawn for the region and the margins (default 300; 0 = none). */
  region_samples?: number;
}

/** An estimate's trace and determinant. */
export interface CovarianceSummary {
  name: string;
  trace: number;
  det: number;
}

/** One rule's report in an exploration. */
export interface RuleReport {
  method: Method;
  /** Its response, or `error` saying why there is none. */
  response?: FuseResponse;
  error?: string;
  /** The worst `λ_min(P̄ − K P' Kᵀ)` over the region's drawn cross-covariances (negative: not conservative there). */
  margin?: number;
  /** The conservativeness index over the region: worst and median (above 1: not conservative there). */
  coin?: { max: number; median: number };
}

/** A proven bracket `[lower, upper]` on the robust optimum (both ends with every rounding enclosed). */
export interface Gap {
  lower: number;
  upper: number;
  /** The rule whose proven bound is the upper end. */
  upper_rule: Method;
  absolute: number;
  relative: number;
  /** Closed to 10⁻⁶ (relative). */
  closed: boolean;
  /** The certified rule's certificate level per block, when it is the upper end. */
  levels?: number[];
  /** Per block: the sectors (two states) or cones (three) of its certificate, 0 for one certificate. */
  sectors?: number[];
}

/** The explorer's analysis of one state: every rule, the proven bracket, the region. */
export interface Exploration {
  n: number;
  estimates: [CovarianceSummary, CovarianceSummary];
  rules: RuleReport[];
  gap?: Gap;
  region_count: number;
  region_acceptance_rate?: number;
  region_sampler_choice?: AutoChoice;
  region_error?: string;
  structure?: StructureDetails;
  /** The region: for each drawn cross-covariance the fused covariance it would give if known, `region_count` row-major `n × n` matrices back to back. */
  region: Float64Array;
}

/** The explorer's analysis of `request` (throws like `fuse`). */
export function explore(request: ExploreRequest): Exploration;

/** The cutting planes' gains with the bound proven for them (every rounding enclosed). */
export interface ProvenGain {
  ka: Rows;
  kb: Rows;
  p: Rows;
  trace: number;
}

/** The explorer's second stage: the cutting planes' proven bracket. */
export interface Proof extends Gap {
  /** The upper end is the loop's own rule, proven on cones of directions. */
  own_rule_proven: boolean;
  stop: "tolerance" | "gap_closed" | "time_limit" | "max_iterations";
  iterations: number;
  proof_rounds: number;
  rule?: ProvenGain;
}

/** The second stage on `request`: `undefined` when the loop has no bracket (throws like `fuse`). */
export function prove(request: ExploreRequest): Proof | undefined;

/** The crate's version. */
export function version(): string;
