// The JSON contract of `fuse` (docs/contract.md in the repository): the same object `nmci fuse`
// reads and prints. The field lists are checked against the Rust crate's own (`contract_fields()`)
// by the package test, so a field added in Rust and not here fails it.

/** A fusion rule: its name in the contract (`rules()` lists each with its guarantee and options). */
export type Method = "ci" | "nmci" | "certified" | "sdp" | "sdp_cuts" | "ici" | "ei" | "naive";

/** What a response's bound is guaranteed for. */
export type Guarantee = "conservative" | "relaxation" | "common_information" | "none";

/** Row-major nested rows of a matrix. */
export type Rows = number[][];

/** One estimate of an N-way request. */
export interface NwayEstimate {
  x?: number[];
  p: Rows;
}

/** The pattern of one pair's cross-covariance in an N-way request (pairs not listed: fully unknown). */
export interface NwayPair {
  i: number;
  j: number;
  pab_unknown: boolean[][];
}

/** A fusion request: two estimates (`pa`, `pb`, …) or, for N-way `ci` and `nmci`, `estimates`. */
export interface FuseRequest {
  /** `P_a` (required unless `estimates` is given). */
  pa?: Rows;
  /** `P_b` (required unless `estimates` is given). */
  pb?: Rows;
  /** `x_a` (default zeros). */
  xa?: number[];
  /** `x_b` (default zeros). */
  xb?: number[];
  /** `true` = `P_ab[i][j]` may be non-zero, `false` = known zero (default all `true`). */
  pab_unknown?: boolean[][];
  /** A declared partition of the states into blocks with independent errors. */
  blocks?: number[][];
  /** Relative size up to which an entry between blocks is absorbed (default 1e-9; 0: exact zeros only). */
  coupling_tol?: number;
  method: Method;
  criterion?: "trace" | "logdet";
  /** The sampled SDP's number of cross-covariances. */
  samples?: number;
  seed?: number;
  max_trials?: number;
  sampler?: "rejection" | "hit_and_run" | "auto";
  /** Wall-clock limit in seconds. */
  time_limit?: number;
  /** The certified rule's level. */
  level?: number;
  /** Two-state blocks certified on this many sectors of directions. */
  sectors?: number;
  /** Three-state blocks certified on this many cones of directions (4, 16 or 64). */
  cones?: number;
  /** Three-state blocks certified on at most this many cones, cut where the bound is tight (4–256; not with `cones`). */
  max_cones?: number;
  /** `sdp_cuts`: stop when the worst violation found is below this times max(tr P̄, 1) (positive; default 1e-7); where the proof of its own rule leaves a three-state bracket open, the loop goes on once to 1e-10. */
  cuts_tolerance?: number;
  /** N-way fusion: k ≥ 2 estimates. */
  estimates?: NwayEstimate[];
  /** N-way: the patterns of the pairs' cross-covariances. */
  patterns?: NwayPair[];
}

/** What `sampler: "auto"` chose, and the pilot it chose by. */
export interface AutoChoice {
  kind: "rejection" | "hit_and_run";
  pilot_trials: number;
  pilot_accepted: number;
  fell_back: boolean;
}

/** One absorbed coupling: an entry of `P_a` or `P_b` between two blocks. */
export interface Coupling {
  matrix: string;
  blocks: [number, number];
  row: number;
  col: number;
  value: number;
  relative: number;
  norm_bound: number;
  trace_added: number;
}

/** How the problem's blocks were found, when that is worth saying. */
export interface StructureDetails {
  blocks: number[][];
  exact_blocks: number;
  coupling_tol: number;
  absorbed: boolean;
  couplings: Coupling[];
  trace_added: number;
  nmci_trace_cost?: number;
  note?: string;
}

/** A fusion response: each optional field is present exactly where its method reports it. */
export interface FuseResponse {
  method: Method;
  criterion: "trace" | "logdet";
  /** The fused estimate. */
  x: number[];
  /** The covariance bound. */
  p: Rows;
  ka?: Rows;
  kb?: Rows;
  /** N-way: one gain per estimate. */
  gains?: Rows[];
  /** N-way: per block, the weight of each estimate. */
  weights?: number[][];
  trace: number;
  det: number;
  /** CI and ICI: `[ω]`; nmCI: one ω per block. */
  omega?: number[];
  blocks?: number[][];
  samples?: number;
  status?: "Solved" | "AlmostSolved";
  iterations?: number;
  acceptance_rate?: number;
  sampler_choice?: AutoChoice;
  lmis?: number;
  worst_sample_margin?: number;
  /** Proven lower end of the bracket on the robust optimum. */
  lower_bound?: number;
  /** Proven upper end of the bracket. */
  upper_bound?: number;
  upper_bound_rule?: Method;
  gap?: number;
  gap_relative?: number;
  repair?: number;
  gain_certified_trace?: number;
  /** `sdp`, `sdp_cuts`: a bound proven for the method's own gain and every admissible `P_ab` (rounding included); `x` with it is a conservative estimate, where `x` with `p` (the relaxation's) is not. `gain_certified_trace` is its trace rounded up. */
  gain_certified_p?: number[][];
  levels?: number[];
  sectors?: number[];
  stop?: "tolerance" | "gap_closed" | "max_iterations" | "time_limit";
  violation?: number;
  converged?: boolean;
  gap_closed?: boolean;
  /** `sdp_cuts`: the certified upper end is the loop's own rule proven on cones of directions. */
  own_rule_proven?: boolean;
  /** `sdp_cuts`: rounds in which the own rule's proof found cuts the search had missed and the loop went on (at most 2). */
  proof_rounds?: number;
  guarantee: Guarantee;
  structure?: StructureDetails;
}

/** The `Error` `fuse` throws: its message, and in `field` the request field at fault, when one is. */
export interface FuseError extends Error {
  field?: string;
}
