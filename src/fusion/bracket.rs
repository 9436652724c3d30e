//! The bracket `[lower_bound, upper_bound]` around the robust optimum, with both ends proven
//! in floating point.
//!
//! The robust optimum is `V* = min tr P̄` over `K_a` (`K_b = I − K_a`) and `P̄` with
//! `P̄ ⪰ K J Kᵀ` for every admissible joint covariance `J` (paper eq. (robust_sdp)).
//!
//! The lower end is `fusion::lower` ([`lower_bound`], a Lagrangian bound checked in exact
//! arithmetic), the upper ends `fusion::upper` (each conservative rule's trace, recomputed
//! with rounding enclosed). This module composes them:
//! `upper_bound` is the smallest of these, `lower_bound ≤ V* ≤ upper_bound` holds
//! rigorously, and `gap = upper_bound − lower_bound ≥ 0` (rounded up).
//!
//! ## Which certificate joins the bracket (policy, shared by `fuse` and the explorer)
//! CI (one pencil) and nmCI (one pencil per block) always join. The certified rule joins when every
//! independent block has at most [`BRACKET_CERTIFY_MAX_BLOCK`] states
//! ([`bracket_certificate`]; its level-1 program grows as `(2n² + 1)²`); the same limit
//! applies to certifying an optimal-fusion method's own gain ([`gain_certified`]).
//! Method `"certified"` itself takes larger blocks.
//!
//! ## A given gain's bound, carried over from the certified rule
//! [`gain_certified`] gives a proven bound `P̄₁ ⪰ K₁ J K₁ᵀ` for every admissible `J` for an
//! optimal-fusion method's own gain `K₁` (`K_b = I − K_a`): what that gain costs when the bound
//! must hold for all of them (responses carry it as `gain_certified_p`, its trace rounded up as
//! `gain_certified_trace`). Besides
//! the gain's own certificate (`certify_gain`, a solve), the certified rule's pair `(K₀, P̄₀)`
//! gives one without a solve. With `Δ = K₁ − K₀ = [ΔK_a, −ΔK_a]` and any `ε > 0`, for every
//! `J ⪰ 0` (Young's inequality, as above)
//!
//! `K₁ J K₁ᵀ ⪯ (1 + ε) K₀ J K₀ᵀ + (1 + 1/ε) Δ J Δᵀ`,
//!
//! and `Δ J Δᵀ = ΔK_a Cov(e_a − e_b) ΔK_aᵀ ⪯ 2 ΔK_a (P_a + P_b) ΔK_aᵀ`, since
//! `(vᵀe_a − vᵀe_b)² ≤ 2(vᵀe_a)² + 2(vᵀe_b)²` — a fixed matrix, whatever `P_ab` is. So
//! `P̄₁ = (1 + ε) P̄₀ + 2(1 + 1/ε) ΔK_a (P_a + P_b) ΔK_aᵀ` dominates `K₁ J K₁ᵀ` for every
//! admissible `J`, and its trace `(1 + ε) t₀ + (1 + 1/ε) d`, `t₀ = tr P̄₀`,
//! `d = 2 tr(ΔK_a (P_a + P_b) ΔK_aᵀ)`, is smallest at `ε = √(d / t₀)`: `(√t₀ + √d)²`. It is
//! evaluated in balls and returned as a float matrix that dominates the ball
//! ([`carried_bound`]); its trace, rounded up, is never below the exact `(√tr P̄₀ + √d)²` and
//! above it by rounding only (the unit test); when `K₁ = K₀` it is `P̄₀`.
//!
//! When that carried-over bound `t` is within the bracket's closing tolerance of the proven
//! lower end (`t − lower_bound ≤ CLOSED_RTOL · t`), no bound for this gain can be smaller by
//! more than that — with `K₁`, every valid bound `P̄` is a feasible point of the robust
//! problem, so `tr P̄ ≥ V* ≥ lower_bound` — and the gain's own certificate is not solved.
//! Otherwise it is (within the block limit above), and the one of the two with the smaller
//! trace is reported. Where the method's gain is close to the certified rule's (as on the paper's example with one known zero, the unit
//! test) the carried-over bound exceeds the certified rule's trace by only `2√(t₀ d) + d`, and
//! the second solve is saved (`docs/benchmarks.md` has the timings).

use nalgebra::DMatrix;

use super::certify::{
    certification_blocks, certified_fusion, certified_fusion_memo, certify_gain, CertificateMemo,
    CertifiedResult, CertifySettings,
};
use super::ci::covariance_intersection;
pub use super::lower::lower_bound;
use super::nmci::non_monolithic_ci;
pub use super::upper::{ci_upper_bound, nmci_upper_bound, trace_upper_bound};
use super::verify::{Ball, BallMatrix, Dot};
use super::Criterion;
use super::{Fused, FusionProblem};
use crate::error::{InputError, SolveError};

/// The relative gap below which a bracket counts as closed: the robust optimum is then
/// proven to that relative accuracy (`gap ≤ 10⁻⁶ · upper`).
pub const CLOSED_RTOL: f64 = 1e-6;

/// The certified rule joins the `sdp` / `sdp_cuts` bracket's upper bound when every
/// independent block has at most this many states (the level-1 program grows as
/// `(2n² + 1)²`; timings in docs/benchmarks.md). Method `"certified"` itself goes to
/// [`CertifySettings::max_block_dim`](super::certify::CertifySettings::max_block_dim).
pub const BRACKET_CERTIFY_MAX_BLOCK: usize = 4;

/// The certified rule for the bracket: `None` when a block exceeds
/// [`BRACKET_CERTIFY_MAX_BLOCK`] states (too slow for every SDP request). Blocks certified
/// before are taken from `memo` when one is given (the same result, see [`CertificateMemo`]).
pub(crate) fn bracket_certificate(
    problem: &FusionProblem,
    settings: &CertifySettings,
    memo: Option<&mut CertificateMemo>,
) -> Result<Option<CertifiedResult>, SolveError> {
    if !small_enough(problem, None) {
        return Ok(None);
    }
    match memo {
        Some(memo) => certified_fusion_memo(problem, settings, memo).map(Some),
        None => certified_fusion(problem, settings).map(Some),
    }
}

/// Whether every block a certificate would be computed on has at most
/// [`BRACKET_CERTIFY_MAX_BLOCK`] states.
fn small_enough(problem: &FusionProblem, gain: Option<&DMatrix<f64>>) -> bool {
    certification_blocks(problem, gain)
        .iter()
        .all(|b| b.len() <= BRACKET_CERTIFY_MAX_BLOCK)
}

/// A proven bound for an optimal-fusion method's own gain `K_a` (module docs, "A given gain's
/// bound"): a symmetric `P̄` with `P̄ ⪰ K J Kᵀ` (`K_b = I − K_a`) for every admissible `J`.
/// It is the certified rule's `certified` bound carried over to `K_a`, without a solve when its
/// trace is within [`CLOSED_RTOL`] of the proven `lower` end; otherwise the one of smaller
/// rounded-up trace of it and the gain's own certificate (`certify_gain`, only for blocks of
/// at most [`BRACKET_CERTIFY_MAX_BLOCK`] states). `None` when neither exists.
#[allow(non_snake_case)]
pub(crate) fn gain_certified(
    problem: &FusionProblem,
    K_a: &DMatrix<f64>,
    settings: &CertifySettings,
    certified: Option<&Fused>,
    lower: f64,
) -> Result<Option<DMatrix<f64>>, SolveError> {
    let carried = certified.and_then(|c| carried_bound(problem, K_a, c));
    if let Some(P) = &carried {
        let t = trace_upper_bound(P);
        if t - lower <= CLOSED_RTOL * t {
            return Ok(carried);
        }
    }
    let own = if small_enough(problem, Some(K_a)) {
        Some(certify_gain(problem, K_a, settings)?.fused.P)
    } else {
        None
    };
    Ok(match (own, carried) {
        (Some(own), Some(carried)) => {
            Some(if trace_upper_bound(&own) <= trace_upper_bound(&carried) {
                own
            } else {
                carried
            })
        }
        (own, carried) => own.or(carried),
    })
}

/// `P̄₁ = (1 + ε) P̄₀ + 2(1 + 1/ε) ΔK_a (P_a + P_b) ΔK_aᵀ` (module docs) for the conservative
/// pair `certified = (K₀, P̄₀)`, `ΔK_a = K_a − K₀` and `ε = √(d / t₀)`: evaluated in balls and
/// returned as a float matrix that dominates every matrix of the ball
/// (`BallMatrix::dominating`), so it dominates `K J Kᵀ` (`K_b = I − K_a`) for every admissible
/// `J`. `P̄₀` itself when `K_a = K₀`. `None` when the sizes differ or a number is not finite.
#[allow(non_snake_case)]
pub(crate) fn carried_bound(
    problem: &FusionProblem,
    K_a: &DMatrix<f64>,
    certified: &Fused,
) -> Option<DMatrix<f64>> {
    let n = problem.dim();
    let (K_0, P_0) = (&certified.K_a, &certified.P);
    if K_a.shape() != (n, n) || K_0.shape() != (n, n) || P_0.shape() != (n, n) {
        return None;
    }
    let t0 = trace_upper_bound(P_0);
    if !(t0.is_finite() && t0 > 0.0) || K_a.iter().any(|k| !k.is_finite()) {
        return None;
    }
    if K_a == K_0 {
        return Some(P_0.clone());
    }
    let delta = BallMatrix::from_fn(n, n, |i, j| {
        let mut d = Dot::new();
        d.add(Ball::exact(K_a[(i, j)]));
        d.add(Ball::exact(-K_0[(i, j)]));
        d.ball()
    });
    let sum = BallMatrix::from_fn(n, n, |i, j| {
        let mut d = Dot::new();
        d.add(Ball::exact(problem.P_a[(i, j)]));
        d.add(Ball::exact(problem.P_b[(i, j)]));
        d.ball()
    });
    // `ΔK_a (P_a + P_b) ΔK_aᵀ`; `d` its trace doubled (exactly), rounded up.
    let spread = delta.mul(&sum).mul(&delta.transpose());
    let d = 2.0 * spread.trace().upper();
    if !d.is_finite() {
        return None;
    }
    // Any ε > 0 gives a valid bound; this one makes its trace (√t₀ + √d)² up to rounding.
    let epsilon = Ball::exact((d / t0).sqrt().max(1e-150));
    let one_plus = |x: Ball| {
        let mut s = Dot::new();
        s.add(Ball::exact(1.0));
        s.add(x);
        s.ball()
    };
    let (a, b) = (one_plus(epsilon), one_plus(epsilon.recip()?));
    let b = Ball {
        mid: 2.0 * b.mid,
        rad: 2.0 * b.rad,
    }; // exact doubling
    let bound = BallMatrix::from_fn(n, n, |i, j| {
        let mut s = Dot::new();
        s.add_prod(a, Ball::exact(P_0[(i, j)]));
        s.add_prod(b, spread.at(i, j));
        s.ball()
    })
    .dominating();
    bound.iter().all(|v| v.is_finite()).then_some(bound)
}

/// The rounded-up trace of [`carried_bound`].
#[cfg(test)]
#[allow(non_snake_case)]
fn carried_trace(problem: &FusionProblem, K_a: &DMatrix<f64>, certified: &Fused) -> Option<f64> {
    carried_bound(problem, K_a, certified).map(|P| trace_upper_bound(&P))
}

/// The proven upper bounds of a problem: CI, nmCI and (for small blocks) the certified rule.
#[allow(non_snake_case)]
pub(crate) fn upper_bounds(
    problem: &FusionProblem,
    certified_P: Option<&DMatrix<f64>>,
) -> Result<UpperBounds, InputError> {
    UpperBounds::of(problem, certified_P.map(trace_upper_bound))
}

/// `[lower, upper] ∋ V*`, both ends proven (module docs).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Bracket {
    /// A proven lower bound on the robust optimum of `tr P̄`.
    pub lower: f64,
    /// A proven upper bound: the smallest rigorous trace of the conservative rules computed.
    pub upper: f64,
    /// The rule that gives `upper`.
    pub upper_rule: UpperRule,
}

/// A rule whose proven trace can be a bracket's upper end (`fusion::upper`); its
/// request-level name is the registry's (`Method::from`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum UpperRule {
    /// CI (trace criterion).
    Ci,
    /// Non-monolithic CI (trace criterion).
    Nmci,
    /// The certified rule.
    Certified,
    /// The sampled SDP's own gain, its bound proven (`gain_certified_p`).
    Sdp,
    /// The cutting planes' own gain, its bound proven (the own rule proven, or
    /// `gain_certified_p`).
    SdpCuts,
}

impl Bracket {
    /// `upper − lower`, rounded up (never negative: both ends are proven).
    pub fn gap(&self) -> f64 {
        Ball {
            mid: self.upper - self.lower,
            rad: 0.0,
        }
        .upper()
        .max(0.0)
    }

    /// `gap / upper` (0 when `upper` is 0).
    pub fn gap_relative(&self) -> f64 {
        if self.upper > 0.0 {
            self.gap() / self.upper
        } else {
            0.0
        }
    }

    /// Whether the gap is at most `rtol · upper`: the robust optimum is then proven to that
    /// relative accuracy.
    pub fn closed(&self, rtol: f64) -> bool {
        self.gap() <= rtol * self.upper
    }
}

/// The rigorous upper bounds of the rules at hand, and the best of them.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct UpperBounds {
    /// CI's (trace criterion), rounded up.
    pub ci: Option<f64>,
    /// nmCI's (trace criterion), rounded up.
    pub nmci: Option<f64>,
    /// The certified rule's, rounded up.
    pub certified: Option<f64>,
}

impl UpperBounds {
    /// The bounds of trace-optimal CI and nmCI (computed here; both always present for finite
    /// data) and a certified rule's rounded-up trace ([`trace_upper_bound`]).
    pub fn of(problem: &FusionProblem, certified: Option<f64>) -> Result<Self, InputError> {
        Self::of_absorbed(problem, problem, certified)
    }

    /// [`UpperBounds::of`] with nmCI's bound taken on `absorbed`, a problem whose covariances
    /// dominate `problem`'s with the same pattern (`crate::structure::absorb_couplings`): an upper bound
    /// on its robust optimum is one on `problem`'s, which is never larger (module docs of
    /// `structure::absorb`). CI does not use the blocks and takes `problem` as given.
    pub fn of_absorbed(
        problem: &FusionProblem,
        absorbed: &FusionProblem,
        certified: Option<f64>,
    ) -> Result<Self, InputError> {
        let ci = covariance_intersection(problem, Criterion::Trace)?;
        let nm = non_monolithic_ci(absorbed, Criterion::Trace)?;
        Ok(Self {
            ci: ci_upper_bound(problem, &ci),
            nmci: nmci_upper_bound(absorbed, &nm),
            certified,
        })
    }

    /// The smallest bound and its rule. Ties go to nmCI, then CI (the closed-form rules); the
    /// certified rule is named only when it is smaller by more than `10⁻¹²` relative (where
    /// it takes CI's bound per block, the two differ by rounding only).
    pub fn best(&self) -> Option<(f64, UpperRule)> {
        let mut best: Option<(f64, UpperRule)> = None;
        for (v, rule) in [(self.nmci, UpperRule::Nmci), (self.ci, UpperRule::Ci)] {
            if let Some(v) = v {
                if best.is_none_or(|(b, _)| v < b) {
                    best = Some((v, rule));
                }
            }
        }
        if let Some(c) = self.certified {
            if best.is_none_or(|(b, _)| c < b * (1.0 - 1e-12)) {
                best = Some((c, UpperRule::Certified));
            }
        }
        best
    }

    /// The bracket with a proven lower bound.
    pub fn bracket(&self, lower: f64) -> Option<Bracket> {
        self.best().map(|(upper, upper_rule)| Bracket {
            lower,
            upper,
            upper_rule,
        })
    }

    /// The bracket with a proven lower bound, its upper end the least of these bounds and
    /// `own`, the rounded-up trace of a bound proven for the method's own gain
    /// (`gain_certified_p`), which `rule` names: every proven upper bound a response holds.
    /// `own` is named only when it is smaller than the others (as the certified rule is, by
    /// more than `10⁻¹²` relative: where it is the certified rule's bound carried over
    /// unchanged the two are equal).
    pub fn bracket_with_own(
        &self,
        lower: f64,
        own: Option<f64>,
        rule: UpperRule,
    ) -> Option<Bracket> {
        let best = match (self.best(), own) {
            (Some((b, r)), Some(o)) => Some(if o < b * (1.0 - 1e-12) {
                (o, rule)
            } else {
                (b, r)
            }),
            (best, None) => best,
            (None, Some(o)) => Some((o, rule)),
        };
        best.map(|(upper, upper_rule)| Bracket {
            lower,
            upper,
            upper_rule,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fusion::sample::{sample_cross_covariances, SamplerSettings};
    use crate::fusion::sdp::{optimal_fusion, SdpSettings};
    use crate::structure::CrossPattern;
    use nalgebra::DVector;

    /// The paper's example with one known zero (`P_ab[1][0] = 0`): a two-state block of the
    /// sector family, whose bracket closes.
    fn one_known_zero() -> FusionProblem {
        let d = |v: &[f64]| DMatrix::from_diagonal(&DVector::from_row_slice(v));
        FusionProblem::from_covariances(
            d(&[3.0, 1.0]),
            d(&[1.0, 4.0]),
            CrossPattern::from_fn(2, |i, j| !(i == 1 && j == 0)),
        )
        .unwrap()
    }

    /// `K J Kᵀ` (`K_b = I − K_a`) for 2000 admissible joint covariances `J` drawn by
    /// hit-and-run: every valid bound for the gain dominates each of them.
    #[allow(non_snake_case)]
    fn sampled_errors(problem: &FusionProblem, K_a: &DMatrix<f64>) -> Vec<DMatrix<f64>> {
        let n = problem.dim();
        let K_b = DMatrix::identity(n, n) - K_a;
        let drawn =
            sample_cross_covariances(problem, 2000, 3, SamplerSettings::hit_and_run()).unwrap();
        drawn
            .cross
            .iter()
            .map(|P_ab| {
                let cross = K_a * P_ab * K_b.transpose();
                K_a * &problem.P_a * K_a.transpose()
                    + &K_b * &problem.P_b * K_b.transpose()
                    + &cross
                    + cross.transpose()
            })
            .collect()
    }

    /// The largest `tr K J Kᵀ` over those `J`: a lower estimate of the gain's worst case,
    /// which every valid bound's trace exceeds.
    #[allow(non_snake_case)]
    fn sampled_worst_trace(problem: &FusionProblem, K_a: &DMatrix<f64>) -> f64 {
        sampled_errors(problem, K_a)
            .iter()
            .map(|e| e.trace())
            .fold(f64::NEG_INFINITY, f64::max)
    }

    /// The smallest `λ_min(P − K J Kᵀ)` over the same `J`.
    #[allow(non_snake_case)]
    fn sampled_worst_margin(problem: &FusionProblem, K_a: &DMatrix<f64>, P: &DMatrix<f64>) -> f64 {
        sampled_errors(problem, K_a)
            .iter()
            .map(|e| (P - e).symmetric_eigenvalues().min())
            .fold(f64::INFINITY, f64::min)
    }

    /// The carried-over bound: `t₀` itself for the certified gain, `(√t₀ + √d)²` to rounding
    /// (never below it) for another, and above every sampled worst case of that gain — also
    /// for gains far enough from the certified one that `t₀` alone is exceeded (so a bound that
    /// dropped the `d` term would fail here).
    #[test]
    #[allow(non_snake_case)]
    fn carried_bound_is_the_closed_form_and_dominates_the_gains_worst_cases() {
        let problem = one_known_zero();
        let cert = certified_fusion(&problem, &CertifySettings::default()).unwrap();
        let t0 = trace_upper_bound(&cert.fused.P);
        assert_eq!(
            carried_trace(&problem, &cert.fused.K_a, &cert.fused),
            Some(t0)
        );
        let direction = DMatrix::from_row_slice(2, 2, &[0.7, -0.4, 0.5, -0.9]);
        let (mut exceeded, mut short) = (false, false);
        for step in [1e-9, 1e-4, 0.05, 0.3] {
            let K_a = &cert.fused.K_a + &direction * step;
            let t = carried_trace(&problem, &K_a, &cert.fused).unwrap();
            let delta = &K_a - &cert.fused.K_a;
            let d = 2.0 * (&delta * (&problem.P_a + &problem.P_b) * delta.transpose()).trace();
            let closed = (t0.sqrt() + d.sqrt()).powi(2);
            assert!(
                t >= closed && t <= closed * (1.0 + 1e-12),
                "{step}: {t} vs {closed}"
            );
            let worst = sampled_worst_trace(&problem, &K_a);
            assert!(
                t >= worst,
                "{step}: bound {t} below a sampled worst case {worst}"
            );
            exceeded |= worst > t0;
            // The matrix itself dominates every sampled error (to the eigensolver's
            // rounding), where `P̄₀` alone does not (below).
            let P = carried_bound(&problem, &K_a, &cert.fused).unwrap();
            assert_eq!(P, P.transpose());
            // It is the module docs' `P̄₁` (in floats, to rounding), never below it.
            let epsilon = (d / t0).sqrt();
            let formula = &cert.fused.P * (1.0 + epsilon)
                + &delta
                    * (&problem.P_a + &problem.P_b)
                    * delta.transpose()
                    * (2.0 * (1.0 + 1.0 / epsilon));
            let off = (&P - &formula).abs().max();
            assert!(off <= 1e-12 * t, "{step}: {off}");
            let above = (&P - &formula).symmetric_eigenvalues().min();
            assert!(above >= -1e-14 * t, "{step}: {above}");
            let margin = sampled_worst_margin(&problem, &K_a, &P);
            assert!(margin >= -1e-12, "{step}: margin {margin}");
            short |= sampled_worst_margin(&problem, &K_a, &cert.fused.P) < -1e-6;
        }
        assert!(
            exceeded && short,
            "no gain's sampled worst case exceeded P̄₀: the test proves little"
        );
        // Sizes that do not fit, and non-finite gains: no bound.
        assert_eq!(
            carried_trace(&problem, &DMatrix::zeros(3, 3), &cert.fused),
            None
        );
        let nan = DMatrix::from_element(2, 2, f64::NAN);
        assert_eq!(carried_trace(&problem, &nan, &cert.fused), None);
        // A pair that cannot be a certificate — wrong sizes, a bound of negative or infinite trace,
        // infinite gains (equal to the given one) — gives no bound either.
        let pair = |K_a: DMatrix<f64>, P: DMatrix<f64>| Fused {
            x: DVector::zeros(K_a.nrows()),
            K_b: DMatrix::identity(K_a.nrows(), K_a.nrows()) - &K_a,
            K_a,
            P,
        };
        let (I2, I3) = (DMatrix::identity(2, 2), DMatrix::identity(3, 3));
        let K = &cert.fused.K_a;
        assert!(carried_trace(&problem, K, &pair(K.clone(), I2.clone())).is_some());
        assert_eq!(
            carried_trace(&problem, K, &pair(I3.clone(), I2.clone())),
            None
        );
        assert_eq!(carried_trace(&problem, K, &pair(K.clone(), I3)), None);
        assert_eq!(carried_trace(&problem, K, &pair(K.clone(), -&I2)), None);
        assert_eq!(
            carried_trace(&problem, K, &pair(K.clone(), &I2 * f64::INFINITY)),
            None
        );
        let infinite = DMatrix::from_row_slice(2, 2, &[f64::INFINITY, 0.0, 0.0, 1.0]);
        assert_eq!(
            carried_trace(&problem, &infinite, &pair(infinite.clone(), I2)),
            None
        );
    }

    /// Where the carried-over bound closes the gain's bracket it is reported without the
    /// gain's own solve (bit for bit the carried bound); with a lower end that leaves it open,
    /// the smaller of the gain's own certificate and the carried bound.
    #[test]
    #[allow(non_snake_case)]
    fn the_gains_own_certificate_is_solved_only_where_the_carried_bound_leaves_a_gap() {
        let problem = one_known_zero();
        let settings = CertifySettings::default();
        let cert = certified_fusion(&problem, &settings).unwrap();
        let sdp = optimal_fusion(
            &problem,
            &SdpSettings {
                samples: 1000,
                ..Default::default()
            },
        )
        .unwrap();
        let K = &sdp.fused.K_a;
        let gain_trace = |certified: Option<&Fused>, lower: f64| {
            gain_certified(&problem, K, &settings, certified, lower)
                .unwrap()
                .map(|P| trace_upper_bound(&P))
        };
        let carried = carried_trace(&problem, K, &cert.fused).unwrap();
        assert!(carried - sdp.lower_bound <= CLOSED_RTOL * carried);
        let closed = gain_certified(&problem, K, &settings, Some(&cert.fused), sdp.lower_bound);
        assert_eq!(
            closed.unwrap(),
            carried_bound(&problem, K, &cert.fused),
            "the carried matrix itself"
        );
        let own = trace_upper_bound(&certify_gain(&problem, K, &settings).unwrap().fused.P);
        assert_ne!(
            own, carried,
            "the two bounds must differ for this test to tell them apart"
        );
        // The threshold is relative to the bound: just inside it the carried bound, just
        // outside the solve.
        let at = |gap: f64| gain_trace(Some(&cert.fused), carried * (1.0 - gap * CLOSED_RTOL));
        assert_eq!(at(0.9), Some(carried));
        assert_eq!(at(1.1), Some(own.min(carried)));
        assert_eq!(gain_trace(Some(&cert.fused), 0.0), Some(own.min(carried)));
        assert_eq!(gain_trace(None, sdp.lower_bound), Some(own));
    }

    /// The cutting planes hand their certified rule on (`CutsResult::certified`, the pair whose
    /// trace is `certified_trace`), and method `sdp_cuts` reports the bound carried over from
    /// it to the loop's gain where that closes the gain's bracket.
    #[test]
    #[allow(non_snake_case)]
    fn the_cutting_planes_carry_their_certified_rule_to_their_gain() {
        let problem = one_known_zero();
        let cuts = crate::sdp::optimal_fusion_cuts(&problem, &Default::default()).unwrap();
        let cert = cuts
            .certified
            .as_ref()
            .expect("the loop certifies a two-state block");
        assert_eq!(Some(trace_upper_bound(&cert.P)), cuts.certified_trace);
        let carried = carried_trace(&problem, &cuts.fused.K_a, cert).unwrap();
        assert!(carried - cuts.lower_bound <= CLOSED_RTOL * carried);
        let request: crate::contract::FuseRequest = serde_json::from_str(
            r#"{"pa": [[3, 0], [0, 1]], "pb": [[1, 0], [0, 4]],
                "pab_unknown": [[true, true], [false, true]], "method": "sdp_cuts"}"#,
        )
        .unwrap();
        match crate::contract::fuse(&request).unwrap().details {
            crate::contract::Details::SdpCuts(d) => {
                assert_eq!(d.gain_certified_trace, Some(carried));
                let P = carried_bound(&problem, &cuts.fused.K_a, cert).unwrap();
                assert_eq!(d.gain_certified_p, Some(crate::linalg::matrix_to_rows(&P)));
            }
            other => panic!("{other:?}"),
        }
    }
}
