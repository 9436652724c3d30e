//! Worst-case constraints instead of random ones: the robust SDP by cutting planes.
//!
//! The sampled SDP (paper eq. (sampled_sdp)) keeps `P̄ ⪰ K P' Kᵀ` for random admissible `P'`
//! only. Here the constraints are chosen adversarially: solve the program on the current set,
//! then search the admissible set for the `P'` that most violates the constraint at the new
//! `(K, P̄)`, add it, and repeat. For a direction `v` the inner problem
//!
//! `max vᵀ K P' Kᵀ v = vᵀK_aP_aK_aᵀv + vᵀK_bP_bK_bᵀv + 2 (K_aᵀv)ᵀ P_ab (K_bᵀv)`
//!
//! over the admissible set (the joint covariance `⪰ 0` — the closure of the admissible set —
//! and the known zeros) is linear in `P_ab` with one PSD constraint of size `2n`: a small SDP
//! (Clarabel). The search alternates it with the top eigenvector of `K P' Kᵀ − P̄`, from
//! several starting directions, and stops when the violation no longer grows. The loop ends
//! when the worst violation found is below `tolerance · max(tr P̄, 1)` or at `max_iterations`
//! (reported, never hidden). Every program solved is a relaxation of the robust one; its
//! constraints and the solver's dual matrices give a proven lower bound on the robust
//! optimum (`fusion::bracket`; the best over the programs solved is reported). A cut lies on the boundary of the
//! admissible set (its joint covariance is singular, to solver tolerance); the SDP uses it
//! through its positive semidefinite projection.
//!
//! Convergence is that of a cutting-plane method: fast where few constraints are active
//! (the paper's example, fully unknown `P_ab`: a handful of cuts), slower in general. Each
//! iteration adds the cut of every start that found a violation; since every cut is a worst
//! case, nearly all are active and each program is solved with all of them at once (no
//! working set). The search is local (the worst case over `(v, P')` is not a convex
//! problem), so on its own "converged" means no violation was *found*.
//!
//! ## Guided by the certified rule, cut in-out
//! The certified rule (`fusion::certify`) is a proven upper bound on the robust optimum.
//! With `certify` (default) the loop (1) starts from the worst cases at the certified bound —
//! where it is tight, i.e. the likely active constraints — found by the same search from the
//! eigenvectors of its `P̄`, (2) also stops when the proven lower bound reaches the certified
//! rule's proven trace within the tolerance (`gap_closed`): the optimum is then proven to
//! that relative accuracy, not just "no violation found" — or, with `bracket_rtol` (the
//! explorer's second stage), as soon as the proven bracket is closed to that, whatever the
//! violation at the loop's `P̄` — and (3) does not stop on "no
//! violation found" while the proven bracket is open until a wider search — 2000 random
//! admissible points (hit-and-run), four times as many random starting directions and, for
//! `n ≤ 3`, 64 directions spread evenly over the half circle or sphere — has also found none.
//! (4) In-out separation (Ben-Ameur & Neto): cuts taken at the relaxation's optimum
//! oscillate in the tail; the search also runs at the point `α` of the way from a feasible
//! point (the certified rule, else nmCI) to the optimum, whose cuts are deeper; when it finds
//! no violation that point becomes the new feasible one.
//!
//! (5) In-out cuts are not all active at the end: after convergence the program is solved
//! again on the active cuts alone (margin `≤ 10⁻⁶ max(tr P̄, 1)`), and that program is kept
//! when its optimum is no lower, every dropped cut holds at its solution and the worst-case
//! search from the eigenvectors of its `P̄` finds nothing new (all beyond the tolerance).
//! `constraints` counts the final program, `constraints_generated` the whole run.
//!
//! (6) Its own rule, proven. The certified rule is the loop's guide and its upper end. Where
//! that leaves the bracket open wider than `CLOSED_RTOL` (`10⁻⁶`, the proof's own target; a
//! bracket closed to that is not proven again where the loop's tolerance is stricter, as at
//! the default `10⁻⁷`) on a problem of one block of three states, the loop's own
//! final rule `(K, P̄)` — a relaxation's, with a trace near the lower end — is proven after
//! the loop (`certify_rule`; module docs of `fusion::certify`, "At a given rule") on at most
//! `own_rule_cones` cones of directions in the time left. The cones are cut until what they
//! add to the trace fits in half of what the loop's own gap leaves of `CLOSED_RTOL · tr P̄`
//! (`own_rule::proof_rtol`, with the argument that the bracket then closes); cutting further
//! would only narrow a bracket already closed. Its bound replaces the certified
//! rule's as `certified` when its proven trace is smaller (`own_rule_proven`); the gain is
//! the loop's, so `sdp_cuts`' own gain is then proven to the bracket's upper end. Where the
//! cones leave the bracket open, and on problems of other sizes wherever the bracket is not
//! closed to the loop's tolerance, the gain's own certificate (`certify_gain`, blocks of up to
//! `BRACKET_CERTIFY_MAX_BLOCK` states) is tried the same way: the least bound proven for the
//! loop's gain is its upper end, and the loop's stop and (7), (8) are decided on it. A proof
//! the solver fails on, or that runs out of time, leaves the result as it was. `certify_rule`
//! also proves four-state rules, but on 64 cones of ℝ⁴ it takes several times the loop's own
//! time and closes few more brackets than the default certificate (docs/methods.md, "Four
//! states", measures both), so the loop runs it at three states only.
//!
//! (7) The proof finds what the search missed. The search is local, so the loop can stop on
//! "no violation found" with `P̄` short of a bound in a narrow set of directions; the proof
//! then needs a large `t` on the cones there, and cutting them does not lower it (module docs
//! of `fusion::certify`, "At a given rule"). A cone's `t` bounds the violation of `P̄` on it
//! from above, so where the proof leaves the bracket open (wider than `CLOSED_RTOL`) the
//! search runs again from the centres of the cones with the largest `t` (at most 8). If it
//! finds violations above the tolerance, they are added as cuts and the loop goes on (at most
//! twice); the result with the narrower proven bracket is returned, with the larger of the
//! proven lower ends (both bound the same optimum). Past the time limit the earlier round's
//! result stands.
//!
//! (8) Still open, a finer loop. How tight the proof can be is set by `P̄`: where `P̄` is short
//! of a bound by up to the loop's tolerance (times `tr P̄`) in the directions it stopped at,
//! the proof has to add that back. So where the proof leaves the bracket open (wider than
//! `CLOSED_RTOL`) and (7) finds no cuts to go on with, the loop goes on once from the
//! round's cuts to `REFINED_TOLERANCE` (`10⁻¹⁰`) and the proof runs again at its end; the
//! narrower bracket is kept as in (7). Brackets that close at the loop's own tolerance never
//! pay for it.
//!
//! `converged: false` reports an iteration or time limit (`stop` says which); a solver
//! failure is returned as an error. Measurements: docs/benchmarks.md ("The cutting planes",
//! `examples/cuts_probe.rs`).

mod own_rule;
mod result;
mod run;
mod search;
mod settings;

pub use result::CutsResult;
pub use settings::{CutsSettings, CutsStop};

use run::cuts_at_scale;

use super::scale::Pow2;
use super::{Fused, FusionProblem};
use crate::error::SolveError;

/// The robust-optimal bound by cutting planes (see the module docs).
///
/// ```
/// use nalgebra::{DMatrix, DVector};
/// use nmci::prelude::*;
/// let d = |v: &[f64]| DMatrix::from_diagonal(&DVector::from_row_slice(v));
/// let p = FusionProblem::from_covariances(d(&[3.0, 1.0]), d(&[1.0, 4.0]),
///     CrossPattern::diagonal(2)).unwrap();
/// let cuts = optimal_fusion_cuts(&p, &CutsSettings::default()).unwrap();
/// assert!(cuts.converged && (cuts.fused.trace() - 2.0).abs() < 1e-6);
/// ```
///
/// Run at unit scale (`fusion::scale`): a problem whose covariances are far from order one is
/// solved scaled by a power of two, exactly, and mapped back — the proven lower bound rounded
/// down, the certified trace rounded up, the certified bound only where every entry maps back
/// exactly (otherwise the problem is solved as given).
pub fn optimal_fusion_cuts(
    problem: &FusionProblem,
    settings: &CutsSettings,
) -> Result<CutsResult, SolveError> {
    settings.validate()?;
    let (scaled, scale) = Pow2::normalising(problem).scaled_problem(problem);
    if scale != Pow2::ONE {
        let r = cuts_at_scale(&scaled, settings)?;
        let certified = match r.certified {
            Some(c) => match scale.unscale_exact(&c.P) {
                Some(p) => Some(Fused { P: p, ..c }),
                None => return cuts_at_scale(problem, settings),
            },
            None => None,
        };
        return Ok(CutsResult {
            fused: Fused {
                P: scale.unscale(&r.fused.P),
                ..r.fused
            },
            violation: scale.unscale_value(r.violation),
            certified_trace: r.certified_trace.map(|t| scale.unscale_up(t)),
            certified,
            dual_objective: scale.unscale_value(r.dual_objective),
            lower_bound: scale.unscale_down(r.lower_bound),
            cross: r.cross.iter().map(|c| scale.unscale(c)).collect(),
            ..r
        });
    }
    cuts_at_scale(problem, settings)
}

#[cfg(test)]
#[allow(non_snake_case)]
mod tests {
    use nalgebra::{DMatrix, DVector};

    use super::own_rule::{prove_own_rule, tighter};
    use super::search::worst_case_search;
    use super::*;
    use crate::fusion::ci::covariance_intersection;
    use crate::fusion::program::Deadline;
    use crate::fusion::Criterion;
    use crate::structure::CrossPattern;

    fn problem() -> FusionProblem {
        let P_a = DMatrix::from_row_slice(3, 3, &[4.0, 1.0, 0.5, 1.0, 3.0, 0.2, 0.5, 0.2, 2.0]);
        let P_b = DMatrix::from_row_slice(3, 3, &[2.0, -0.3, 0.1, -0.3, 5.0, 1.0, 0.1, 1.0, 1.5]);
        FusionProblem::from_covariances(P_a, P_b, CrossPattern::fully_unknown(3)).unwrap()
    }

    /// The worst-case search's programs share the solve's deadline: past it, the search ends
    /// in the time-limit error (which the loop turns into `CutsStop::TimeLimit`), instead of
    /// running its programs to the end.
    #[test]
    fn the_worst_case_search_stops_at_the_deadline() {
        let p = problem();
        let ci = covariance_intersection(&p, Criterion::Trace).unwrap().fused;
        let v = DVector::from_row_slice(&[1.0, 0.0, 0.0]);
        let settings = CutsSettings::default();
        // Without a deadline: a worst case (CI is conservative: no violation beyond rounding).
        let (violation, _) =
            worst_case_search(&p, &ci, v.clone(), &settings, &Deadline::after(None)).unwrap();
        assert!(violation.is_finite() && violation <= 1e-7, "{violation}");
        let passed = Deadline::after(Some(1e-9));
        std::thread::sleep(std::time::Duration::from_millis(2));
        assert!(passed.passed());
        let err = worst_case_search(&p, &ci, v, &settings, &passed).unwrap_err();
        assert!(matches!(err, SolveError::TimeLimit { .. }), "{err}");
        assert!(err.to_string().contains("worst-case search"), "{err}");
    }

    /// A result of the loop on a small two-state problem (`CrossPattern::diagonal`): the base
    /// the tests below vary.
    fn a_result() -> CutsResult {
        let d = |v: &[f64]| DMatrix::from_diagonal(&DVector::from_row_slice(v));
        let p = FusionProblem::from_covariances(
            d(&[3.0, 1.0]),
            d(&[1.0, 4.0]),
            CrossPattern::diagonal(2),
        )
        .unwrap();
        optimal_fusion_cuts(&p, &CutsSettings::default()).unwrap()
    }

    /// Of two rounds' results, the one with the smaller proven upper end is kept, whichever
    /// came first, with the larger of the two lower ends; the closed flag follows the kept
    /// bracket.
    #[test]
    fn of_two_rounds_the_narrower_bracket_is_kept_with_the_larger_lower_end() {
        let base = a_result();
        let with = |lower: f64, upper: Option<f64>, iterations: usize| CutsResult {
            lower_bound: lower,
            certified_trace: upper,
            gap_closed: false,
            iterations,
            ..base.clone()
        };
        for swap in [false, true] {
            let (a, b) = (with(1.0, Some(1.2), 1), with(1.1, Some(1.3), 2));
            let kept = if swap {
                tighter(b, a, &CutsSettings::default())
            } else {
                tighter(a, b, &CutsSettings::default())
            };
            assert_eq!(kept.iterations, 1);
            assert_eq!((kept.lower_bound, kept.certified_trace), (1.1, Some(1.2)));
            assert!(!kept.gap_closed);
        }
        // The later round's lower end reaches the earlier one's upper end: closed.
        let kept = tighter(
            with(1.0, Some(1.2), 1),
            with(1.2, None, 2),
            &CutsSettings::default(),
        );
        assert_eq!((kept.iterations, kept.lower_bound), (1, 1.2));
        assert!(kept.gap_closed);
    }

    /// The own rule's proof runs where the bracket is open wider than `CLOSED_RTOL`, and not
    /// where it is closed to that, even when the loop's tolerance is stricter (module docs,
    /// (6)). Seen through a rule the proof refuses: a two-state rule on a three-state problem
    /// is an error from the proof, and returned as one, only where the proof runs.
    #[test]
    fn the_own_rule_is_proven_only_where_the_bracket_is_open_wider_than_closed_rtol() {
        let d = |v: &[f64]| DMatrix::from_diagonal(&DVector::from_row_slice(v));
        let three = FusionProblem::from_covariances(
            d(&[3.0, 1.0, 2.0]),
            d(&[1.0, 4.0, 2.0]),
            CrossPattern::from_fn(3, |i, j| i + j != 2),
        )
        .unwrap();
        let base = a_result();
        let settings = CutsSettings {
            tolerance: 1e-10,
            ..CutsSettings::default()
        };
        let at = |rtol: f64| CutsResult {
            lower_bound: 5.0 * (1.0 - rtol),
            certified_trace: Some(5.0),
            gap_closed: false,
            stop: CutsStop::Tolerance,
            ..base.clone()
        };
        let deadline = Deadline::after(None);
        let err = prove_own_rule(&three, at(1e-5), &settings, &deadline).unwrap_err();
        assert!(err.to_string().contains("3×3"), "{err}");
        let (kept, short) = prove_own_rule(&three, at(5e-7), &settings, &deadline).unwrap();
        assert_eq!(kept, at(5e-7));
        assert!(short.is_empty());
    }
}
