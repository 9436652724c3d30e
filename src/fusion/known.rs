//! Fusion with a *known* cross-covariance: the best linear unbiased fusion (Bar-Shalom–Campo).
//!
//! With `x_f = x_b + K_a (x_a − x_b)`, `S = P_a + P_b − P_ab − P_abᵀ = Cov(e_a − e_b)` and
//! `Cov(e_b, e_a − e_b) = P_abᵀ − P_b`, the optimal gain is `K_a = (P_b − P_abᵀ) S⁻¹` and
//! `P* = P_b − K_a (P_b − P_ab)`. For every admissible `P_ab`, `P*` is the smallest fused
//! covariance any linear unbiased rule can reach; the set of these `P*` over the admissible set
//! is the "region of possible true fused covariances" of the paper's fig. 1.

use nalgebra::{DMatrix, SymmetricEigen};

use super::{Fused, FusionProblem};
use crate::linalg::symmetrize;

/// The optimal fusion when the cross-covariance is known to be `P_ab`.
///
/// ```
/// use nalgebra::{DMatrix, DVector};
/// use nmci::*;
/// // Independent estimates of equal covariance: the average, with half the covariance.
/// let I = DMatrix::<f64>::identity(2, 2);
/// let p = FusionProblem::from_covariances(I.clone() * 2.0, I.clone() * 2.0,
///     CrossPattern::independent(2)).unwrap();
/// let f = known_correlation_fusion(&p, &DMatrix::zeros(2, 2));
/// assert!((f.P - I.clone()).amax() < 1e-12);
/// assert!((f.K_a - I * 0.5).amax() < 1e-12);
/// ```
#[allow(non_snake_case)]
pub fn known_correlation_fusion(problem: &FusionProblem, P_ab: &DMatrix<f64>) -> Fused {
    let n = problem.dim();
    let P_ba = P_ab.transpose();
    let S = symmetrize(&(&problem.P_a + &problem.P_b - P_ab - &P_ba));
    let B = &problem.P_b - &P_ba; // K_a = B S⁻¹  ⇔  K_aᵀ = S⁻¹ Bᵀ
    let K_a = match nalgebra::Cholesky::new(S.clone()) {
        Some(c) => c.solve(&B.transpose()).transpose(),
        None => {
            // S is PD for every admissible P_ab; at the boundary use the pseudo-inverse.
            let eig = SymmetricEigen::new(S);
            let tol = eig.eigenvalues.amax() * 1e-12;
            let inv = eig.eigenvalues.map(|l| if l > tol { 1.0 / l } else { 0.0 });
            &B * &eig.eigenvectors * DMatrix::from_diagonal(&inv) * eig.eigenvectors.transpose()
        }
    };
    let P = symmetrize(&(&problem.P_b - &K_a * (&problem.P_b - P_ab)));
    let K_b = DMatrix::identity(n, n) - &K_a;
    let x = &K_a * &problem.x_a + &K_b * &problem.x_b;
    Fused { x, P, K_a, K_b }
}

/// Naive fusion: the estimates treated as independent (`P_ab = 0`),
/// `P = (P_a⁻¹ + P_b⁻¹)⁻¹`, `x = P (P_a⁻¹ x_a + P_b⁻¹ x_b)`. **Not conservative** when the
/// estimates share information: it is what double counting looks like.
///
/// ```
/// use nalgebra::DMatrix;
/// use nmci::*;
/// let I = DMatrix::<f64>::identity(2, 2);
/// let p = FusionProblem::from_covariances(I.clone() * 2.0, I.clone() * 2.0,
///     CrossPattern::fully_unknown(2)).unwrap();
/// assert!((naive_fusion(&p).P - I).amax() < 1e-12); // half of either, whatever P_ab really is
/// ```
pub fn naive_fusion(problem: &FusionProblem) -> Fused {
    known_correlation_fusion(problem, &DMatrix::zeros(problem.dim(), problem.dim()))
}
