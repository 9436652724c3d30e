//! The loop's own rule, proven after the loop (the parent's module docs, (6) and (7)): the
//! proof, the directions where the rule is short, and the choice between two rounds' results.

use nalgebra::DVector;

use super::result::CutsResult;
use super::settings::{CutsSettings, CutsStop};
use crate::error::SolveError;
use crate::fusion::bracket::{Bracket, UpperRule, BRACKET_CERTIFY_MAX_BLOCK, CLOSED_RTOL};
use crate::fusion::certify::{
    certification_blocks, certify_gain, certify_rule_short, Certificates, CertifiedResult,
    CertifySettings,
};
use crate::fusion::program::Deadline;
use crate::fusion::upper::trace_upper_bound;
use crate::fusion::FusionProblem;

/// Where the certified rule left the bracket of a three-state problem open (wider than
/// [`CLOSED_RTOL`], the proof's own target), the loop's own rule proven on cones of
/// directions (module docs, "Its own rule, proven"), kept when its proven trace is smaller,
/// and where that leaves it open, the gain's own certificate ([`prove_own_gain`]); at other
/// sizes, where the bracket is not closed to the loop's tolerance, the gain's own
/// certificate. Past the time limit, or where the solver fails on it, the result as it is.
///
/// Also returns, where the proof ran and left the bracket open wider than [`CLOSED_RTOL`],
/// the directions where the loop's rule is short (`certify_rule_short`).
pub(super) fn prove_own_rule(
    problem: &FusionProblem,
    mut result: CutsResult,
    settings: &CutsSettings,
    deadline: &Deadline,
) -> Result<(CutsResult, Vec<DVector<f64>>), SolveError> {
    let Some(upper) = result.certified_trace else {
        return Ok((result, Vec::new()));
    };
    // The time left, read once (a limit of zero would be refused as a setting).
    let left = deadline.remaining();
    if result.gap_closed || result.stop == CutsStop::TimeLimit || left <= 0.0 {
        return Ok((result, Vec::new()));
    }
    let certify_settings = CertifySettings {
        time_limit: settings.time_limit.map(|_| left),
        ..settings.certify_settings
    };
    if problem.dim() != 3 || settings.own_rule_cones == 0 {
        // Not closed to the loop's tolerance: the gain's own certificate.
        prove_own_gain(problem, &mut result, settings, &certify_settings)?;
        return Ok((result, Vec::new()));
    }
    if closed(result.lower_bound, upper) {
        return Ok((result, Vec::new()));
    }
    let (proven, short) = match certify_rule_short(
        problem,
        &result.fused,
        settings.own_rule_cones,
        proof_rtol(result.fused.P.trace(), result.lower_bound),
        &certify_settings,
    ) {
        Ok(Some(proven)) => proven,
        Ok(None)
        | Err(
            SolveError::TimeLimit { .. }
            | SolveError::SolverFailed { .. }
            | SolveError::NotProven { .. },
        ) => return Ok((result, Vec::new())),
        Err(e) => return Err(e),
    };
    adopt_if_tighter(&mut result, proven, settings);
    if still_open(&result) {
        // The cones left it open: the gain's own certificate, in the time left.
        let certify_settings = CertifySettings {
            time_limit: settings
                .time_limit
                .map(|_| deadline.remaining().max(f64::MIN_POSITIVE)),
            ..settings.certify_settings
        };
        if !deadline.passed() {
            prove_own_gain(problem, &mut result, settings, &certify_settings)?;
        }
    }
    let short = if still_open(&result) {
        short
    } else {
        Vec::new()
    };
    Ok((result, short))
}

/// The loop's gain `K` with its own certificate (`certify_gain`: the least `P̄ ⪰ K J Kᵀ` the
/// certificate family proves for that gain, every admissible `J`), kept as the result's
/// proven rule when its proven trace is smaller (module docs, (6)): the bracket's upper end
/// is then the least proven bound the loop holds, and the loop's stop and its rounds (7), (8)
/// are decided on it. Only where every block the gain couples has at most
/// [`BRACKET_CERTIFY_MAX_BLOCK`] states (the bracket's limit); past the time limit, or where
/// the solver fails on it, the result as it is.
fn prove_own_gain(
    problem: &FusionProblem,
    result: &mut CutsResult,
    settings: &CutsSettings,
    certify_settings: &CertifySettings,
) -> Result<(), SolveError> {
    let gain = &result.fused.K_a;
    if !certification_blocks(problem, Some(gain))
        .iter()
        .all(|b| b.len() <= BRACKET_CERTIFY_MAX_BLOCK)
    {
        return Ok(());
    }
    match certify_gain(problem, gain, certify_settings) {
        Ok(proven) => {
            adopt_if_tighter(result, proven, settings);
            Ok(())
        }
        Err(
            SolveError::TimeLimit { .. }
            | SolveError::SolverFailed { .. }
            | SolveError::NotProven { .. },
        ) => Ok(()),
        Err(e) => Err(e),
    }
}

/// `proven`, a bound proven for the loop's own gain, as the result's proven rule when its
/// rounded-up trace is below the one the result holds.
fn adopt_if_tighter(result: &mut CutsResult, proven: CertifiedResult, settings: &CutsSettings) {
    let trace = trace_upper_bound(&proven.fused.P);
    if result.certified_trace.is_none_or(|upper| trace < upper) {
        result.certified_trace = Some(trace);
        result.certificates = Some(Certificates::of(&proven));
        result.certified = Some(proven.fused);
        result.own_rule_proven = true;
        result.gap_closed = settings.closes(result.lower_bound, trace);
    }
}

/// The `rtol` the proof of a rule with `tr P̄ = trace` is run at, where the proven lower end
/// is `lower` (module docs, (6)): `4 · room / tr P̄`, where `room = CLOSED_RTOL · tr P̄ −
/// (tr P̄ − lower)` is what closing the bracket leaves the proof; never below [`CLOSED_RTOL`]
/// (and [`CLOSED_RTOL`] itself where there is no room), below 1.
///
/// Why: `certify_rule` cuts until each cone's `t` is at most `rtol · tr P̄ / (8n)` and then
/// proves every cone at `P̄ + τI`, `τ` the largest `t`, a trace of at most `tr P̄ + rtol ·
/// tr P̄ / 8 = tr P̄ + room / 2`. Each cone's `t` already includes its own repair, and a
/// certificate proven at `Q` holds at every `Q' ⪰ Q`, so that last step repairs nothing but
/// rounding; with it and the rounding up of the trace below the other half of the room, the
/// proven upper end `U` has `U − lower ≤ (tr P̄ − lower) + room = CLOSED_RTOL · tr P̄ ≤
/// CLOSED_RTOL · U`: closed. The bracket itself is what decides closed, never this
/// estimate. Where the cones miss the target, they are cut as with a smaller `rtol`, worst
/// `t` first; a looser target only stops the cutting sooner.
fn proof_rtol(trace: f64, lower: f64) -> f64 {
    let room = CLOSED_RTOL * trace - (trace - lower);
    if trace > 0.0 && room > 0.0 {
        (4.0 * room / trace).clamp(CLOSED_RTOL, 0.5)
    } else {
        CLOSED_RTOL
    }
}

/// Whether the proven bracket `[lower, upper]` is closed to [`CLOSED_RTOL`], as the bracket
/// reports it.
fn closed(lower: f64, upper: f64) -> bool {
    let upper_rule = UpperRule::Certified;
    Bracket {
        lower,
        upper,
        upper_rule,
    }
    .closed(CLOSED_RTOL)
}

/// Of two results of the loop on one problem, the one whose proven bracket is narrower, with
/// the larger of their proven lower ends (both bound the same robust optimum).
pub(super) fn tighter(a: CutsResult, b: CutsResult, settings: &CutsSettings) -> CutsResult {
    let lower = a.lower_bound.max(b.lower_bound);
    let upper = |r: &CutsResult| r.certified_trace.unwrap_or(f64::INFINITY);
    let mut kept = if upper(&a) < upper(&b) { a } else { b };
    kept.lower_bound = lower;
    if let Some(trace) = kept.certified_trace {
        kept.gap_closed |= settings.closes(lower, trace);
    }
    kept
}

/// Most rounds the proof's short directions restart the loop (module docs, (7)).
pub(super) const PROOF_ROUNDS: usize = 2;

/// The tolerance the loop goes on to where the proof of its rule left the bracket open
/// (module docs, (8)).
pub(super) const REFINED_TOLERANCE: f64 = 1e-10;

/// Whether a result's proven bracket is open: not closed to the loop's tolerance and wider
/// than [`CLOSED_RTOL`] (without a certified upper end there is no bracket to close: no).
pub(super) fn still_open(result: &CutsResult) -> bool {
    result
        .certified_trace
        .is_some_and(|t| !result.gap_closed && !closed(result.lower_bound, t))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The proof's `rtol` leaves it half the room the loop's gap leaves in `CLOSED_RTOL`, so
    /// a proof whose cones all meet their target (a trace of at most `tr P̄ · (1 + rtol / 8)`)
    /// closes the bracket with the other half to spare; without room, and never stricter than
    /// it, `CLOSED_RTOL`.
    #[test]
    fn the_proof_target_leaves_half_the_room_of_the_bracket() {
        for trace in [1e-3, 1.0, 7.5, 1e4] {
            for gap in [0.0, 1e-9, 1e-7, 5e-7, 7e-7] {
                let lower = trace * (1.0 - gap);
                let rtol = proof_rtol(trace, lower);
                let room = CLOSED_RTOL * trace - (trace - lower);
                assert!(
                    (rtol * trace / 8.0 - room / 2.0).abs() <= 1e-9 * room,
                    "{trace} {gap}"
                );
                let upper = trace * (1.0 + rtol / 8.0);
                assert!(upper - lower <= CLOSED_RTOL * upper - room / 2.0 * (1.0 - 1e-9));
            }
            // Too little room for a target above `CLOSED_RTOL`, and none at all.
            assert_eq!(proof_rtol(trace, trace * (1.0 - 0.9e-6)), CLOSED_RTOL);
            assert_eq!(proof_rtol(trace, trace * (1.0 - 2e-6)), CLOSED_RTOL);
        }
        assert_eq!(proof_rtol(0.0, 0.0), CLOSED_RTOL);
        assert_eq!(proof_rtol(-1.0, -1.0), CLOSED_RTOL);
    }
}
