//! The bracket `[lower_bound, upper_bound]` around the robust optimum, with both ends proven
//! in floating point.
//!
//! The robust optimum is `V* = min tr P̄` over `K_a` (`K_b = I − K_a`) and `P̄` with
//! `P̄ ⪰ K J Kᵀ` for every admissible joint covariance `J` (paper eq. (robust_sdp)).
//!
//! ## The lower end: a Lagrangian bound checked in exact arithmetic
//! Let `J_1, …, J_M` be admissible (each `J_i ⪰ 0` with the diagonal blocks `P_a`, `P_b` and
//! the known zeros) and `Λ_1, …, Λ_M ⪰ 0` (`n × n`) with `Σ Λ_i ⪯ σ I`. For every robust-
//! feasible `(K, P̄)`, `P̄ ⪰ K J_i Kᵀ` and `P̄ ⪰ 0`, so
//!
//! `σ tr P̄ ≥ ⟨Σ Λ_i, P̄⟩ ≥ Σ ⟨Λ_i, K J_i Kᵀ⟩ = f(K_a) ≥ min_{K_a} f`,
//!
//! and `V* ≥ min f / σ`. With `e_f = e_b + K_a d`, `d = e_a − e_b`, each term is
//! `⟨Λ_i, K_a S_i K_aᵀ⟩ + 2⟨Λ_i C_i, K_a⟩ + ⟨Λ_i, P_b⟩` (`S_i = P_a + P_b − X_i − X_iᵀ`,
//! `C_i = X_iᵀ − P_b`, `X_i` the cross block of `J_i`), so with `v = vec K_a`,
//! `f(v) = vᵀ H v + 2 gᵀ v + c₀`, `H = Σ S_i ⊗ Λ_i ⪰ 0`. For any `v̂` and `μ ≤ λ_min(H)`,
//! `μ > 0`: `f(v) ≥ f(v̂) + 2 rᵀ(v − v̂) + μ ‖v − v̂‖² ≥ f(v̂) − ‖r‖²/μ`, `r = H v̂ + g`.
//!
//! The `J_i` and `Λ_i` come from the relaxation the caller solved (the sampled SDP's or the
//! cutting planes' constraints and the solver's dual matrices; any choice is valid, a good
//! one is tight), `v̂` solves `H v̂ = −g` approximately. Everything is then *checked*, not
//! trusted: each `J_i` is proven PSD by `fusion::verify::is_psd` (pulled towards `P_ab = 0`,
//! which keeps it admissible, if needed; dropped if that fails — dropping a term keeps the
//! bound valid); each `Λ_i` is shifted until proven PSD; `σ = 1 + ‖Σ Λ_i − I‖_F` rounded
//! up; `μ` is proven by the same test on `H − μ I`; `f(v̂)` and `‖r‖²` are enclosed in
//! balls. So **`lower_bound ≤ V*` holds in exact arithmetic for the problem's floats** (the
//! inputs as symmetrised, `(A + Aᵀ)/2`: `FusionProblem` stores them so), on
//! the floating-point model of `fusion::verify`, whatever the solver's accuracy (a loose
//! solve only makes the bound weaker). This is the approach of Jansson, Chaykin and Keil,
//! "Rigorous error bounds for the optimal value in semidefinite programming", SIAM J.
//! Numer. Anal. 46(1), 2007, specialised to this program (the gain is eliminated exactly
//! instead of bounded a priori).
//!
//! **Independent blocks.** When `P_a`, `P_b` and the pattern split the state into
//! independent blocks, every admissible `J` is block diagonal (in the blocks' order), and the
//! bound is computed per block `B` with `J_i` built on that block (and `P_a`, `P_b`'s blocks
//! elsewhere). For any robust-feasible `(K, P̄)`, the diagonal block
//! `(K J Kᵀ)_BB = Σ_C K_BC J_CC K_BCᵀ ⪰ K_BB J_BB K_BBᵀ`, and `K_BB` is itself unbiased
//! (`(K_a)_BB + (K_b)_BB = I`), so `tr P̄_BB` is at least block `B`'s bound, and the sum of
//! the per-block bounds (rounded down) is a lower bound on `V*`.
//!
//! ## The upper end
//! Each conservative rule gives a `P̄` that dominates `K J Kᵀ` for every admissible `J`, so
//! its trace bounds `V*` from above. To be a bound in floating point too, the trace is
//! recomputed in exact arithmetic with rounding enclosed:
//! - CI with weight `ω ∈ (0, 1)` and any gain `K_a`: for every `J ⪰ 0` with diagonal blocks
//!   `P_a`, `P_b`, `K J Kᵀ ⪯ ω⁻¹ K_a P_a K_aᵀ + (1−ω)⁻¹ K_b P_b K_bᵀ` (Young's inequality;
//!   `ω ∈ {0, 1}` needs `K_a = 0`, resp. `K_a = I`), so the upper end is the rounded-up
//!   trace of the right side for the rule's own `ω` and gain; nmCI sums it over its blocks.
//! - The certified rule: its `P̄` is proven (`fusion::certify`); its trace is rounded up.
//!
//! `upper_bound` is the smallest of these, `lower_bound ≤ V* ≤ upper_bound` holds
//! rigorously, and `gap = upper_bound − lower_bound ≥ 0` (rounded up).
//!
//! ## Which certificate joins the bracket (policy, shared by `fuse` and the explorer)
//! CI (one pencil) and nmCI (one pencil per block) always join. The certified rule joins when every
//! independent block has at most [`BRACKET_CERTIFY_MAX_BLOCK`] states
//! ([`bracket_certificate`]; its level-1 program grows as `(2n² + 1)²`); the same limit
//! applies to certifying an optimal-fusion method's own gain ([`gain_certified_trace`]).
//! Method `"certified"` itself takes larger blocks.
//!
//! ## A given gain's bound, carried over from the certified rule
//! `gain_certified_trace` reports a proven upper bound on what an optimal-fusion method's own
//! gain `K₁` (`K_b = I − K_a`) costs when the bound must hold for every admissible `J`. Besides
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
//! evaluated in balls and rounded up ([`carried_trace`]); when `K₁ = K₀` it is `t₀`.
//!
//! When that carried-over bound `t` is within the bracket's closing tolerance of the proven
//! lower end (`t − lower_bound ≤ CLOSED_RTOL · t`), no bound for this gain can be smaller by
//! more than that — with `K₁`, every valid bound `P̄` is a feasible point of the robust
//! problem, so `tr P̄ ≥ V* ≥ lower_bound` — and the gain's own certificate is not solved.
//! Otherwise it is (within
//! the block limit above), and the smaller of the two is reported. Where the method's gain is
//! close to the certified rule's (as on the paper's example with one known zero, the unit
//! test) the carried-over bound exceeds the certified rule's trace by only `2√(t₀ d) + d`, and
//! the second solve is saved (`docs/development.md` has the timings).

use nalgebra::{DMatrix, DVector, SymmetricEigen};

use super::certify::{
    certification_blocks, certified_fusion, certified_fusion_memo, certify_gain, CertificateMemo,
    CertifiedResult, CertifySettings,
};
use super::ci::{covariance_intersection, CiResult};
use super::nmci::{non_monolithic_ci, NmciResult};
use super::rules::Method;
use super::verify::{down, is_psd, norm2_up, psd_shift, up, Ball, BallMatrix, Dot, U};
use super::Criterion;
use super::{Fused, FusionProblem};
use crate::error::{InputError, SolveError};
use crate::linalg::cholesky_of;

/// The relative gap below which a bracket counts as closed: the robust optimum is then
/// proven to that relative accuracy (`gap ≤ 10⁻⁶ · upper`).
pub const CLOSED_RTOL: f64 = 1e-6;

/// The certified rule joins the `sdp` / `sdp_cuts` bracket's upper bound when every
/// independent block has at most this many states (the level-1 program grows as
/// `(2n² + 1)²`; timings in docs/development.md). Method `"certified"` itself goes to
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

/// A proven upper bound on the worst-case trace of an optimal-fusion method's own gain `K_a`
/// (module docs, "A given gain's bound"): the certified rule's `certified` bound carried over
/// to `K_a`, without a solve when that is within [`CLOSED_RTOL`] of the proven `lower` end;
/// otherwise the smaller of it and the gain's own certificate (`certify_gain`, only for
/// blocks of at most [`BRACKET_CERTIFY_MAX_BLOCK`] states). `None` when neither exists.
#[allow(non_snake_case)]
pub(crate) fn gain_certified_trace(
    problem: &FusionProblem,
    K_a: &DMatrix<f64>,
    settings: &CertifySettings,
    certified: Option<&Fused>,
    lower: f64,
) -> Result<Option<f64>, SolveError> {
    let carried = certified.and_then(|c| carried_trace(problem, K_a, c));
    if let Some(t) = carried {
        if t - lower <= CLOSED_RTOL * t {
            return Ok(Some(t));
        }
    }
    let own = if small_enough(problem, Some(K_a)) {
        Some(trace_upper_bound(
            &certify_gain(problem, K_a, settings)?.fused.P,
        ))
    } else {
        None
    };
    Ok(match (own, carried) {
        (Some(own), Some(carried)) => Some(own.min(carried)),
        (own, carried) => own.or(carried),
    })
}

/// `(1 + ε) t₀ + (1 + 1/ε) d` rounded up, with `t₀ ≥ tr P̄₀` of the conservative pair
/// `certified = (K₀, P̄₀)` and `d ≥ 2 tr(ΔK_a (P_a + P_b) ΔK_aᵀ)`, `ΔK_a = K_a − K₀`, both
/// enclosed in balls: a proven upper bound on the trace of a bound that dominates
/// `K J Kᵀ` (`K_b = I − K_a`) for every admissible `J` (module docs). `None` when the sizes
/// differ or a number is not finite.
#[allow(non_snake_case)]
pub(crate) fn carried_trace(
    problem: &FusionProblem,
    K_a: &DMatrix<f64>,
    certified: &Fused,
) -> Option<f64> {
    let n = problem.dim();
    let K_0 = &certified.K_a;
    if K_a.shape() != (n, n) || K_0.shape() != (n, n) || certified.P.shape() != (n, n) {
        return None;
    }
    let t0 = trace_upper_bound(&certified.P);
    if !(t0.is_finite() && t0 > 0.0) || K_a.iter().any(|k| !k.is_finite()) {
        return None;
    }
    if K_a == K_0 {
        return Some(t0);
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
    let d = 2.0 * delta.mul(&sum).mul(&delta.transpose()).trace().upper(); // exact doubling
    if !d.is_finite() {
        return None;
    }
    // Any ε > 0 gives a valid bound; this one makes it (√t₀ + √d)² up to rounding.
    let epsilon = (d / t0).sqrt().max(1e-150);
    let one_plus = |x: Ball| {
        let mut s = Dot::new();
        s.add(Ball::exact(1.0));
        s.add(x);
        s.ball()
    };
    let mut total = Dot::new();
    total.add_prod(one_plus(Ball::exact(epsilon)), Ball::exact(t0));
    total.add_prod(one_plus(Ball::exact(epsilon).recip()?), Ball::exact(d));
    let t = total.ball().upper();
    t.is_finite().then_some(t)
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
    pub upper_rule: Method,
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
    /// dominate `problem`'s with the same pattern (`crate::absorb_couplings`): an upper bound
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
    pub fn best(&self) -> Option<(f64, Method)> {
        let mut best: Option<(f64, Method)> = None;
        for (v, rule) in [(self.nmci, Method::Nmci), (self.ci, Method::Ci)] {
            if let Some(v) = v {
                if best.is_none_or(|(b, _)| v < b) {
                    best = Some((v, rule));
                }
            }
        }
        if let Some(c) = self.certified {
            if best.is_none_or(|(b, _)| c < b * (1.0 - 1e-12)) {
                best = Some((c, Method::Certified));
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
}

/// `tr P` rounded up.
pub fn trace_upper_bound(p: &DMatrix<f64>) -> f64 {
    BallMatrix::exact(p).trace().upper()
}

/// The rounded-up trace of `ω⁻¹ K_a P_a K_aᵀ + (1−ω)⁻¹ K_b P_b K_bᵀ` (`K_b = I − K_a`
/// exactly) for CI's weight and gain: a proven upper bound on `V*` (module docs).
pub fn ci_upper_bound(problem: &FusionProblem, ci: &CiResult) -> Option<f64> {
    weighted_upper(&problem.P_a, &problem.P_b, &ci.fused.K_a, ci.omega)
}

/// nmCI's bound: [`ci_upper_bound`] summed over its blocks (its gain must be block diagonal).
pub fn nmci_upper_bound(problem: &FusionProblem, nm: &NmciResult) -> Option<f64> {
    let n = problem.dim();
    let mut block_of = vec![usize::MAX; n];
    for (b, block) in nm.blocks.iter().enumerate() {
        for &i in block {
            block_of[i] = b;
        }
    }
    let mixes =
        (0..n).any(|i| (0..n).any(|j| block_of[i] != block_of[j] && nm.fused.K_a[(i, j)] != 0.0));
    if mixes || block_of.contains(&usize::MAX) {
        return None;
    }
    let mut total = Dot::new();
    for (block, &omega) in nm.blocks.iter().zip(&nm.omega) {
        let pick = |m: &DMatrix<f64>| {
            DMatrix::from_fn(block.len(), block.len(), |i, j| m[(block[i], block[j])])
        };
        let b = weighted_upper(
            &pick(&problem.P_a),
            &pick(&problem.P_b),
            &pick(&nm.fused.K_a),
            omega,
        )?;
        total.add(Ball::exact(b));
    }
    Some(total.ball().upper())
}

#[allow(non_snake_case)]
fn weighted_upper(
    P_a: &DMatrix<f64>,
    P_b: &DMatrix<f64>,
    K_a: &DMatrix<f64>,
    omega: f64,
) -> Option<f64> {
    // The rule's own ω; where it does not fit the gain exactly (an endpoint with a gain that
    // is not exactly 0 or I), ω = 1/2, for which Young's inequality holds for any gain.
    young_bound(P_a, P_b, K_a, omega)
        .or_else(|| young_bound(P_a, P_b, K_a, 0.5))
        .map(|m| m.trace().upper())
}

/// `ω⁻¹ K_a P_a K_aᵀ + (1−ω)⁻¹ K_b P_b K_bᵀ` (`K_b = I − K_a` exactly) as a ball matrix: for
/// every `J ⪰ 0` with diagonal blocks `P_a`, `P_b` it dominates `K J Kᵀ` (Young's inequality,
/// module docs). `ω ∈ {0, 1}` only with `K_a = 0`, resp. `K_a = I` (then `K J Kᵀ` is the one
/// term); `None` otherwise or for `ω ∉ [0, 1]`.
#[allow(non_snake_case)]
pub(crate) fn young_bound(
    P_a: &DMatrix<f64>,
    P_b: &DMatrix<f64>,
    K_a: &DMatrix<f64>,
    omega: f64,
) -> Option<BallMatrix> {
    let n = P_a.nrows();
    let K_b = BallMatrix::identity_minus(K_a);
    let Ka = BallMatrix::exact(K_a);
    let a = Ka.mul(&BallMatrix::exact(P_a)).mul(&Ka.transpose());
    let b = K_b.mul(&BallMatrix::exact(P_b)).mul(&K_b.transpose());
    if omega == 0.0 {
        return K_a.iter().all(|&k| k == 0.0).then_some(b);
    }
    if omega == 1.0 {
        let identity =
            (0..n).all(|i| (0..n).all(|j| K_a[(i, j)] == if i == j { 1.0 } else { 0.0 }));
        return identity.then_some(a);
    }
    if !(omega > 0.0 && omega < 1.0) {
        return None;
    }
    let wa = Ball::exact(omega).recip()?;
    let one_minus = 1.0 - omega;
    let wb = Ball {
        mid: one_minus,
        rad: up(U * one_minus, 1),
    }
    .recip()?;
    Some(BallMatrix::from_fn(n, n, |i, j| {
        let mut d = Dot::new();
        d.add_prod(wa, a.at(i, j));
        d.add_prod(wb, b.at(i, j));
        d.ball()
    }))
}

/// The `ω` minimising `tr` of [`young_bound`] for a fixed gain: `√A / (√A + √B)` with
/// `A = tr K_a P_a K_aᵀ`, `B = tr K_b P_b K_bᵀ` (any `ω` gives a valid bound).
#[allow(non_snake_case)]
pub(crate) fn young_omega(P_a: &DMatrix<f64>, P_b: &DMatrix<f64>, K_a: &DMatrix<f64>) -> f64 {
    let n = P_a.nrows();
    let K_b = DMatrix::identity(n, n) - K_a;
    let a = (K_a * P_a * K_a.transpose()).trace().max(0.0).sqrt();
    let b = (&K_b * P_b * K_b.transpose()).trace().max(0.0).sqrt();
    if a == 0.0 {
        0.0
    } else if b == 0.0 {
        1.0
    } else {
        a / (a + b)
    }
}

/// A proven lower bound on the robust optimum `V*` of `problem` from admissible cross blocks
/// `cross[i]` and dual matrices `duals[i]` (module docs); `0` when nothing can be proven.
#[allow(non_snake_case)]
pub fn lower_bound(
    problem: &FusionProblem,
    cross: &[&DMatrix<f64>],
    duals: &[DMatrix<f64>],
) -> f64 {
    let n = problem.dim();
    let mut terms: Vec<(DMatrix<f64>, DMatrix<f64>)> = Vec::new(); // (X_i, Λ_i)
    for (X, L) in cross.iter().zip(duals) {
        if X.shape() != (n, n)
            || L.shape() != (n, n)
            || X.iter().chain(L.iter()).any(|x| !x.is_finite())
        {
            continue;
        }
        let Some(X) = admissible(problem, X) else {
            continue;
        };
        let Some(L) = proven_psd(&symmetric_floats(L)) else {
            continue;
        };
        terms.push((X, L));
    }
    if terms.is_empty() {
        return 0.0;
    }
    // σ ≥ λ_max(Σ Λ_i): 1 + ‖Σ Λ_i − I‖_F.
    let sum_minus_i = BallMatrix::from_fn(n, n, |r, c| {
        let mut d = Dot::new();
        for (_, L) in &terms {
            d.add(Ball::exact(L[(r, c)]));
        }
        if r == c {
            d.add(Ball::exact(-1.0));
        }
        d.ball()
    });
    let fro = norm2_up(
        sum_minus_i
            .mid
            .iter()
            .zip(sum_minus_i.rad.iter())
            .map(|(m, r)| m.abs() + r),
        3 * n * n + 6,
    );
    let sigma = up(1.0 + fro, 2);
    // S_i, C_i as balls; H = Σ S_i ⊗ Λ_i, g = vec Σ Λ_i C_i, c₀ = Σ ⟨Λ_i, P_b⟩.
    let sc: Vec<(BallMatrix, BallMatrix)> = terms
        .iter()
        .map(|(X, _)| {
            let S = BallMatrix::from_fn(n, n, |k, l| {
                let mut d = Dot::new();
                for v in [
                    problem.P_a[(k, l)],
                    problem.P_b[(k, l)],
                    -X[(k, l)],
                    -X[(l, k)],
                ] {
                    d.add(Ball::exact(v));
                }
                d.ball()
            });
            let C = BallMatrix::from_fn(n, n, |k, l| {
                let mut d = Dot::new();
                d.add(Ball::exact(X[(l, k)]));
                d.add(Ball::exact(-problem.P_b[(k, l)]));
                d.ball()
            });
            (S.symmetrized(), C)
        })
        .collect();
    let nn = n * n;
    let H = BallMatrix::from_fn(nn, nn, |a, b| {
        let (k, r) = (a / n, a % n);
        let (l, s) = (b / n, b % n);
        let mut d = Dot::new();
        for ((_, L), (S, _)) in terms.iter().zip(&sc) {
            d.add_prod(S.at(k, l), Ball::exact(L[(r, s)]));
        }
        d.ball()
    })
    .symmetrized();
    let g: Vec<Ball> = (0..nn)
        .map(|a| {
            let (k, r) = (a / n, a % n);
            let mut d = Dot::new();
            for ((_, L), (_, C)) in terms.iter().zip(&sc) {
                for t in 0..n {
                    d.add_prod(Ball::exact(L[(r, t)]), C.at(t, k));
                }
            }
            d.ball()
        })
        .collect();
    let mut c0 = Dot::new();
    for (_, L) in &terms {
        for r in 0..n {
            for c in 0..n {
                c0.add_exact_prod(L[(r, c)], problem.P_b[(r, c)]);
            }
        }
    }
    let c0 = c0.ball();
    // μ ≤ λ_min(H), proven.
    let estimate = SymmetricEigen::new(H.mid.clone()).eigenvalues.min();
    if estimate.is_nan() || estimate <= 0.0 {
        return 0.0;
    }
    let mut mu = 0.5 * estimate;
    let mut proven_mu = None;
    for _ in 0..20 {
        let mut shifted = H.clone();
        for i in 0..nn {
            let m = shifted.mid[(i, i)] - mu;
            shifted.rad[(i, i)] = up(shifted.rad[(i, i)] + U * m.abs(), 3);
            shifted.mid[(i, i)] = m;
        }
        if is_psd(&shifted.mid, &shifted.rad) {
            proven_mu = Some(mu);
            break;
        }
        mu *= 0.5;
    }
    let Some(mu) = proven_mu else {
        return 0.0;
    };
    // v̂ ≈ −H⁻¹ g.
    let g_mid = DVector::from_iterator(nn, g.iter().map(|b| b.mid));
    let v = match cholesky_of(H.mid.clone()) {
        Some(ch) => -ch.solve(&g_mid),
        None => DVector::zeros(nn),
    };
    if v.iter().any(|x| !x.is_finite()) {
        return 0.0;
    }
    // f(v̂) and r = H v̂ + g as balls.
    let mut f = Dot::new();
    let mut r_sq = 0.0;
    for a in 0..nn {
        let mut ra = Dot::new();
        for b in 0..nn {
            let w = v[a] * v[b];
            f.add_prod(
                H.at(a, b),
                Ball {
                    mid: w,
                    rad: up(U * w.abs(), 1),
                },
            );
            ra.add_prod(H.at(a, b), Ball::exact(v[b]));
        }
        ra.add(g[a]);
        let ra = ra.ball();
        let mag = ra.mid.abs() + ra.rad;
        r_sq += mag * mag;
        f.add_prod(g[a], Ball::exact(2.0 * v[a]));
    }
    f.add(c0);
    let f_low = f.ball().lower();
    let penalty = up(up(r_sq, 2 * nn + 2) / mu, 2);
    let numerator = Ball {
        mid: f_low - penalty,
        rad: 0.0,
    }
    .lower();
    if numerator.is_nan() || numerator <= 0.0 {
        return 0.0;
    }
    down(numerator / sigma, 2)
}

/// The admissible joint covariance nearest to `X` on the segment to `P_ab = 0` that can be
/// proven PSD (known zeros forced): `X` itself or `(1 − 2⁻ᵏ) X`; `None` if none is proven.
#[allow(non_snake_case)]
fn admissible(problem: &FusionProblem, X: &DMatrix<f64>) -> Option<DMatrix<f64>> {
    let n = problem.dim();
    let X = DMatrix::from_fn(n, n, |i, j| {
        if problem.cross_pattern.is_unknown(i, j) {
            X[(i, j)]
        } else {
            0.0
        }
    });
    for t in [
        1.0,
        1.0 - 2f64.powi(-40),
        1.0 - 2f64.powi(-26),
        1.0 - 2f64.powi(-14),
        0.99,
        0.9,
    ] {
        let Xt = &X * t;
        let J = problem.joint_covariance(&Xt);
        // joint_covariance copies P_a, P_b, Xt and Xtᵀ: exactly symmetric.
        if is_psd(&J, &DMatrix::zeros(2 * n, 2 * n)) {
            return Some(Xt);
        }
    }
    None
}

/// `(M + Mᵀ)/2` in floats (exactly symmetric).
fn symmetric_floats(m: &DMatrix<f64>) -> DMatrix<f64> {
    DMatrix::from_fn(m.nrows(), m.ncols(), |i, j| 0.5 * (m[(i, j)] + m[(j, i)]))
}

/// `M + t I` (floats) proven PSD for the smallest `t` of a doubling sequence.
fn proven_psd(m: &DMatrix<f64>) -> Option<DMatrix<f64>> {
    let n = m.nrows();
    if is_psd(m, &DMatrix::zeros(n, n)) {
        return Some(m.clone());
    }
    let mut t = psd_shift(&BallMatrix::exact(m))?;
    for _ in 0..40 {
        let mut s = m.clone();
        for i in 0..n {
            s[(i, i)] += t;
        }
        if is_psd(&s, &DMatrix::zeros(n, n)) {
            return Some(s);
        }
        t *= 2.0;
    }
    None
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

    /// `max tr(K J Kᵀ)` over admissible joint covariances drawn by hit-and-run, `K_b = I − K_a`:
    /// a lower estimate of the gain's worst case, which every valid bound's trace exceeds.
    #[allow(non_snake_case)]
    fn sampled_worst_trace(problem: &FusionProblem, K_a: &DMatrix<f64>) -> f64 {
        let n = problem.dim();
        let K_b = DMatrix::identity(n, n) - K_a;
        let drawn =
            sample_cross_covariances(problem, 2000, 3, SamplerSettings::hit_and_run()).unwrap();
        drawn
            .cross
            .iter()
            .map(|P_ab| {
                let cross = K_a * P_ab * K_b.transpose();
                (K_a * &problem.P_a * K_a.transpose()
                    + &K_b * &problem.P_b * K_b.transpose()
                    + &cross
                    + cross.transpose())
                .trace()
            })
            .fold(f64::NEG_INFINITY, f64::max)
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
        let mut exceeded = false;
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
        }
        assert!(
            exceeded,
            "no gain's sampled worst case exceeded t₀: the test proves little"
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
        let carried = carried_trace(&problem, K, &cert.fused).unwrap();
        assert!(carried - sdp.lower_bound <= CLOSED_RTOL * carried);
        let closed =
            gain_certified_trace(&problem, K, &settings, Some(&cert.fused), sdp.lower_bound);
        assert_eq!(closed.unwrap(), Some(carried));
        let own = trace_upper_bound(&certify_gain(&problem, K, &settings).unwrap().fused.P);
        assert_ne!(
            own, carried,
            "the two bounds must differ for this test to tell them apart"
        );
        // The threshold is relative to the bound: just inside it the carried bound, just
        // outside the solve.
        let at = |gap: f64| {
            let lower = carried * (1.0 - gap * CLOSED_RTOL);
            gain_certified_trace(&problem, K, &settings, Some(&cert.fused), lower).unwrap()
        };
        assert_eq!(at(0.9), Some(carried));
        assert_eq!(at(1.1), Some(own.min(carried)));
        let open = gain_certified_trace(&problem, K, &settings, Some(&cert.fused), 0.0);
        assert_eq!(open.unwrap(), Some(own.min(carried)));
        let alone = gain_certified_trace(&problem, K, &settings, None, sdp.lower_bound);
        assert_eq!(alone.unwrap(), Some(own));
    }

    /// The cutting planes hand their certified rule on (`CutsResult::certified`, the pair whose
    /// trace is `certified_trace`), and method `sdp_cuts` reports the bound carried over from
    /// it to the loop's gain where that closes the gain's bracket.
    #[test]
    fn the_cutting_planes_carry_their_certified_rule_to_their_gain() {
        let problem = one_known_zero();
        let cuts = crate::optimal_fusion_cuts(&problem, &Default::default()).unwrap();
        let cert = cuts
            .certified
            .as_ref()
            .expect("the loop certifies a two-state block");
        assert_eq!(Some(trace_upper_bound(&cert.P)), cuts.certified_trace);
        let carried = carried_trace(&problem, &cuts.fused.K_a, cert).unwrap();
        assert!(carried - cuts.lower_bound <= CLOSED_RTOL * carried);
        let request: crate::FuseRequest = serde_json::from_str(
            r#"{"pa": [[3, 0], [0, 1]], "pb": [[1, 0], [0, 4]],
                "pab_unknown": [[true, true], [false, true]], "method": "sdp_cuts"}"#,
        )
        .unwrap();
        match crate::fuse(&request).unwrap().details {
            crate::Details::SdpCuts(d) => assert_eq!(d.gain_certified_trace, Some(carried)),
            other => panic!("{other:?}"),
        }
    }
}
