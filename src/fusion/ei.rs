//! Ellipsoidal intersection (EI; Sijs & Lazar 2012). **Not guaranteed conservative.**
//!
//! EI assumes the correlation comes from a common part `(γ, Γ)` of both estimates and takes
//! `Γ` as large as both allow: with the CI pencil's basis (`P_b = W Wᵀ`,
//! `P_a = W diag(μ) Wᵀ`), `Γ = W diag(max(μᵢ, 1)) Wᵀ` and
//! `P = (P_a⁻¹ + P_b⁻¹ − Γ⁻¹)⁻¹ = W diag(min(μᵢ, 1)) Wᵀ`: along each common principal axis
//! the smaller of the two variances. The mean `x = P (P_a⁻¹ x_a + P_b⁻¹ x_b − Γ⁻¹ γ)` with
//! the paper's `γ` reduces in the same basis to taking, per axis, the coordinate of the
//! estimate with the smaller variance (the average of both where they are equal within
//! `1e-9`, the paper's `η` regularisation): `K_a = W diag(kᵢ) W⁻¹`, `kᵢ ∈ {1, ½, 0}`.
//! When the estimates are in fact correlated in other ways, `P` can be too small — EI is a
//! point of comparison, not a bound.

use nalgebra::{DMatrix, DVector};

use super::ci::Pencil;
use super::{Fused, FusionProblem};
use crate::error::InputError;
use crate::linalg::symmetrize_in_place;

/// Variance ratios within this relative distance of 1 count as equal (EI's `η`).
const EQUAL: f64 = 1e-9;

/// Ellipsoidal intersection (see the module docs).
///
/// ```
/// use nalgebra::{DMatrix, DVector};
/// use nmci::prelude::*;
/// use nmci::rules::ellipsoidal_intersection;
/// let d = |v: &[f64]| DMatrix::from_diagonal(&DVector::from_row_slice(v));
/// let p = FusionProblem::new(DVector::from_vec(vec![1.0, 2.0]), d(&[3.0, 1.0]),
///     DVector::from_vec(vec![5.0, 6.0]), d(&[1.0, 4.0]), CrossPattern::fully_unknown(2)).unwrap();
/// let ei = ellipsoidal_intersection(&p).unwrap();
/// assert!((&ei.P - d(&[1.0, 1.0])).amax() < 1e-12); // the smaller variance per axis
/// assert!((ei.x[0] - 5.0).abs() < 1e-12 && (ei.x[1] - 2.0).abs() < 1e-12);
/// ```
#[allow(non_snake_case)]
pub fn ellipsoidal_intersection(problem: &FusionProblem) -> Result<Fused, InputError> {
    let n = problem.dim();
    let pencil = Pencil::new(&problem.P_a, &problem.P_b)?;
    let p = pencil.mu.iter().map(|&mu| mu.min(1.0));
    let k = pencil.mu.iter().map(|&mu| {
        if (mu - 1.0).abs() <= EQUAL {
            0.5
        } else if mu < 1.0 {
            1.0
        } else {
            0.0
        }
    });
    let mut P = pencil.scaled_product(p, &pencil.basis.transpose());
    symmetrize_in_place(&mut P);
    let K_a = pencil.scaled_product(k, &pencil.basis_inv());
    let K_b = DMatrix::identity(n, n) - &K_a;
    let x: DVector<f64> = &K_a * &problem.x_a + &K_b * &problem.x_b;
    Ok(Fused { x, P, K_a, K_b })
}
