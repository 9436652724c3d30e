//! Proven upper bounds on the robust optimum `V*` (`fusion::bracket` composes them with the
//! lower end of `fusion::lower`).
//!
//! Each conservative rule gives a `P̄` that dominates `K J Kᵀ` for every admissible `J`, so
//! its trace bounds `V*` from above. To be a bound in floating point too, the trace is
//! recomputed in exact arithmetic with rounding enclosed:
//! - CI with weight `ω ∈ (0, 1)` and any gain `K_a`: for every `J ⪰ 0` with diagonal blocks
//!   `P_a`, `P_b`, `K J Kᵀ ⪯ ω⁻¹ K_a P_a K_aᵀ + (1−ω)⁻¹ K_b P_b K_bᵀ` (Young's inequality;
//!   `ω ∈ {0, 1}` needs `K_a = 0`, resp. `K_a = I`), so the upper end is the rounded-up
//!   trace of the right side for the rule's own `ω` and gain; nmCI sums it over its blocks.
//! - The certified rule: its `P̄` is proven (`fusion::certify`); its trace is rounded up.

use nalgebra::DMatrix;

use super::ci::CiResult;
use super::nmci::NmciResult;
use super::verify::{up, Ball, BallMatrix, Dot, U};
use super::FusionProblem;

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
