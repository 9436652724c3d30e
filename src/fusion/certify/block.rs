//! One block certified: at unit scale, through the families' fallbacks, beside CI's own bound (the
//! parent's module docs, "Never looser than CI in trace").

use nalgebra::DMatrix;

use crate::error::SolveError;
use crate::fusion::ci::covariance_intersection;
use crate::fusion::program::SdpStatus;
use crate::fusion::scale::Pow2;
use crate::fusion::upper::{trace_upper_bound, young_bound, young_omega};
use crate::fusion::{Criterion, FusionProblem};

use super::assemble::Piece;
use super::geometry::cone_multipliers;
use super::refine::certify_adaptive;
use super::repair::repair_failed;
use super::settings::{CertifySettings, Family, RETRY_REPAIR_RTOL};
use super::sos::{certify_pieces, BlockCertificate};

/// What [`certify`] finds for one block: its gain and proven bound, and how they were found.
#[allow(non_snake_case)]
#[derive(Debug, Clone)]
pub(super) struct BlockOutcome {
    pub(super) K_a: DMatrix<f64>,
    pub(super) P: DMatrix<f64>,
    pub(super) status: SdpStatus,
    pub(super) iterations: u32,
    pub(super) repair: f64,
    pub(super) level: u32,
    pub(super) sectors: u32,
    pub(super) ci_used: bool,
}

/// One block of [`certify`]: `sub` is the block's problem, `sub_gain` its part of a given gain.
///
/// Certified at unit scale (`fusion::scale`): a block whose largest diagonal entry is outside
/// `[2⁻⁴, 2⁴]` has its covariances multiplied by the power of two that brings that entry into
/// `[1, 2)` — exactly, or not at all —
/// so the solver's absolute tolerances meet data of order one whatever the units. The bound
/// proven for the scaled block is mapped back by the inverse power of two, exactly, or where an
/// entry would not map back exactly (near the bottom of the float range) to a matrix that
/// dominates it by a few subnormal units (`Pow2::unscale_dominating`), so the bound is always
/// proven for the block as given; the block is certified as given only when mapping back
/// overflows.
pub(super) fn certify_one_block(
    sub: &FusionProblem,
    sub_gain: Option<&DMatrix<f64>>,
    settings: &CertifySettings,
) -> Result<BlockOutcome, SolveError> {
    let (scaled, scale) = Pow2::normalising(sub).scaled_problem(sub);
    if scale != Pow2::ONE {
        let outcome = certify_at_scale(&scaled, sub_gain, settings)?;
        if let Some(p) = scale.unscale_dominating(&outcome.P) {
            return Ok(BlockOutcome {
                P: p,
                repair: scale.unscale_value(outcome.repair),
                ..outcome
            });
        }
    }
    certify_at_scale(sub, sub_gain, settings)
}

/// [`certify_one_block`] on the block as given.
#[allow(non_snake_case)]
pub(super) fn certify_at_scale(
    sub: &FusionProblem,
    sub_gain: Option<&DMatrix<f64>>,
    settings: &CertifySettings,
) -> Result<BlockOutcome, SolveError> {
    let n = sub.dim();
    // A block whose cross block is wholly unknown: CI is the robust optimum there (module
    // docs), so no certificate of any family is tighter than CI's own beyond rounding; its
    // proven bound is taken without a solve.
    if sub_gain.is_none() && sub.cross_pattern.unknown_count() == n * n {
        let ci = covariance_intersection(sub, Criterion::Trace)?;
        if let Some(bound) = young_bound(&sub.P_a, &sub.P_b, &ci.fused.K_a, ci.omega) {
            return Ok(BlockOutcome {
                K_a: ci.fused.K_a,
                P: bound.dominating(),
                status: SdpStatus::Solved,
                iterations: 0,
                repair: 0.0,
                level: 1,
                sectors: 0,
                ci_used: true,
            });
        }
    }
    // The requested family, or — where the solver breaks down numerically on it — the
    // next lower one that solves (`Family::lower`); CI's proven bound when none does.
    let mut family = settings.family_for(n);
    let mut solved = loop {
        match certify_block(sub, sub_gain, family, settings) {
            Ok(s) => break Some(s),
            Err(SolveError::SolverFailed { .. } | SolveError::NotProven { .. }) => {
                match family.lower() {
                    Some(lower) => family = lower,
                    None => break None,
                }
            }
            Err(e) => return Err(e),
        }
    };
    // Solved to reduced accuracy only and repaired by more than RETRY_REPAIR_RTOL of the
    // trace: the repair can cost more than a coarser family loses (degenerate optima,
    // e.g. one row of P_ab unknown). Both are proofs; keep the smaller trace of this
    // family's and the next lower one's.
    if let (Some(first), Some(lower)) = (&solved, family.lower()) {
        if first.status == SdpStatus::AlmostSolved
            && first.repair > RETRY_REPAIR_RTOL * first.P.trace().abs()
        {
            match certify_block(sub, sub_gain, lower, settings) {
                Ok(s) if trace_upper_bound(&s.P) < trace_upper_bound(&first.P) => {
                    solved = Some(s);
                    family = lower;
                }
                Ok(_) | Err(SolveError::SolverFailed { .. } | SolveError::NotProven { .. }) => {}
                Err(e) => return Err(e),
            }
        }
    }
    // CI's bound (Young's inequality, proven in exact arithmetic) is a level-1
    // certificate: keep it where the solver's certificate ended looser (module docs).
    let (ci_gain, omega) = match sub_gain {
        Some(K) => (K.clone(), young_omega(&sub.P_a, &sub.P_b, K)),
        None => {
            let ci = covariance_intersection(sub, Criterion::Trace)?;
            (ci.fused.K_a, ci.omega)
        }
    };
    let mut ci_used = false;
    if let Some(bound) = young_bound(&sub.P_a, &sub.P_b, &ci_gain, omega) {
        let P_ci = bound.dominating();
        let looser = match &solved {
            Some(s) => trace_upper_bound(&P_ci) < trace_upper_bound(&s.P),
            None => true,
        };
        if looser {
            let s = solved.get_or_insert_with(|| BlockCertificate {
                K_a: ci_gain.clone(),
                P: P_ci.clone(),
                status: SdpStatus::AlmostSolved,
                iterations: 0,
                repair: 0.0,
                pieces: 0,
            });
            s.P = P_ci;
            s.K_a = ci_gain;
            ci_used = true;
        }
    }
    let solved = solved.ok_or_else(|| repair_failed("CI's bound"))?;
    Ok(BlockOutcome {
        K_a: solved.K_a,
        P: solved.P,
        status: solved.status,
        iterations: solved.iterations,
        repair: solved.repair,
        level: family.level(),
        sectors: solved.pieces,
        ci_used,
    })
}

/// The certificate of `family` for one block, at `gain` when given.
pub(super) fn certify_block(
    problem: &FusionProblem,
    gain: Option<&DMatrix<f64>>,
    family: Family,
    settings: &CertifySettings,
) -> Result<BlockCertificate, SolveError> {
    match family {
        Family::Global(level) => {
            let whole = [Piece {
                multipliers: Vec::new(),
            }];
            Ok(certify_pieces(problem, gain, level, &whole, settings)?.0)
        }
        Family::Sectors(count) | Family::Cones(count) => {
            let pieces = cone_multipliers(problem.dim(), count)?
                .into_iter()
                .map(|multipliers| Piece { multipliers })
                .collect::<Vec<_>>();
            Ok(certify_pieces(problem, gain, 1, &pieces, settings)?.0)
        }
        Family::Adaptive(budget) => certify_adaptive(problem, gain, budget, settings),
    }
}
