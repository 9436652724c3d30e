//! The cutting-plane loop's result ([`CutsResult`]).

use nalgebra::DMatrix;

use super::settings::CutsStop;
use crate::fusion::certify::Certificates;
use crate::fusion::program::SdpStatus;
use crate::fusion::Fused;

/// The cutting-plane result.
#[derive(Debug, Clone, PartialEq)]
pub struct CutsResult {
    /// Fused estimate, bound `P̄` and gains of the last program.
    pub fused: Fused,
    /// Status of the last solve.
    pub status: SdpStatus,
    /// Outer iterations run.
    pub iterations: usize,
    /// Constraints (cross-covariances) in the last program: after convergence the active
    /// ones only (see [`CutsResult::constraints_generated`]).
    pub constraints: usize,
    /// Constraints generated over the run: the starting samples and every cut.
    pub constraints_generated: usize,
    /// The worst `λ_max(K P' Kᵀ − P̄)` the search found at the end (≤ the stopping threshold
    /// when `converged`).
    pub violation: f64,
    /// Whether the loop stopped on the tolerance or a closed gap (otherwise on
    /// `max_iterations` or `time_limit`).
    pub converged: bool,
    /// Why the loop stopped.
    pub stop: CutsStop,
    /// `tr P̄` of `certified` rounded up (a proven upper bound on the robust optimum), when
    /// computed.
    pub certified_trace: Option<f64>,
    /// The certificate of `certified` on each block, when computed.
    pub certificates: Option<Certificates>,
    /// A proven rule (gain and bound), when computed: the certified rule, or where
    /// `own_rule_proven` the loop's own gain with a proven bound.
    pub certified: Option<Fused>,
    /// Whether `certified` is the loop's own rule proven on cones of directions (module docs,
    /// "Its own rule, proven"): its gain is `fused`'s, its bound proven and tighter than the
    /// certified rule's.
    pub own_rule_proven: bool,
    /// Whether `lower_bound` reached `certified_trace` within the tolerance: the optimum is
    /// then proven to that relative accuracy, and `certified` attains it to that accuracy.
    /// The loop stops there (`stop: GapClosed`), or the own rule proven after the loop
    /// closed it.
    pub gap_closed: bool,
    /// Clarabel's dual objective of the last program (a lower bound only up to the solver's
    /// tolerance).
    pub dual_objective: f64,
    /// A proven lower bound on the robust optimum: the best over the programs solved
    /// (`fusion::bracket`).
    pub lower_bound: f64,
    /// The cross-covariances of the last program.
    pub cross: Vec<DMatrix<f64>>,
    /// Rounds in which the proof's short directions found violations and restarted the loop
    /// (module docs, (7); at most 2).
    pub proof_rounds: usize,
}
