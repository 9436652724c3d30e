//! Fusion with a *known* cross-covariance: the best linear unbiased fusion (Bar-Shalom–Campo).
//!
//! With `x_f = x_b + K_a (x_a − x_b)`, `S = P_a + P_b − P_ab − P_abᵀ = Cov(e_a − e_b)` and
//! `Cov(e_b, e_a − e_b) = P_abᵀ − P_b`, the optimal gain is `K_a = (P_b − P_abᵀ) S⁻¹` and
//! `P* = P_b − K_a (P_b − P_ab)`. For every admissible `P_ab`, `P*` is the smallest fused
//! covariance any linear unbiased rule can reach; the set of these `P*` over the admissible set
//! is the "region of possible true fused covariances" of the paper's fig. 1.

use nalgebra::{DMatrix, DVector, SymmetricEigen};

use super::{covariance_twins, validate_square, BlockMean, Fused, FusionProblem, MeanPlan};
use crate::error::InputError;
use crate::linalg::{
    cholesky_of, solve_lower_in_place, solve_lower_rows, symmetrize, symmetrize_in_place,
};

/// The optimal fusion when the cross-covariance is known to be `P_ab`.
///
/// ```
/// use nalgebra::{DMatrix, DVector};
/// use nmci::prelude::*;
/// use nmci::rules::known_correlation_fusion;
/// // Independent estimates of equal covariance: the average, with half the covariance.
/// let I = DMatrix::<f64>::identity(2, 2);
/// let p = FusionProblem::from_covariances(I.clone() * 2.0, I.clone() * 2.0,
///     CrossPattern::independent(2)).unwrap();
/// let f = known_correlation_fusion(&p, &DMatrix::zeros(2, 2)).unwrap();
/// assert!((f.P - I.clone()).amax() < 1e-12);
/// assert!((f.K_a - I * 0.5).amax() < 1e-12);
/// ```
///
/// `P_ab` must be `n × n` and finite (an error names it otherwise). Whether it is admissible
/// (the joint covariance positive semidefinite) is the caller's to know: the formulas give the
/// best linear unbiased fusion only then.
#[allow(non_snake_case)]
pub fn known_correlation_fusion(
    problem: &FusionProblem,
    P_ab: &DMatrix<f64>,
) -> Result<Fused, InputError> {
    validate_square("P_ab", P_ab, problem.dim())?;
    Ok(known_fusion(problem, P_ab))
}

/// [`known_correlation_fusion`] without the check, for the sampled `P_ab` of the region and
/// naive fusion's zero.
#[allow(non_snake_case)]
pub(crate) fn known_fusion(problem: &FusionProblem, P_ab: &DMatrix<f64>) -> Fused {
    let n = problem.dim();
    let P_ba = P_ab.transpose();
    let S = symmetrize(&(&problem.P_a + &problem.P_b - P_ab - &P_ba));
    let B = &problem.P_b - &P_ba; // K_a = B S⁻¹  ⇔  K_aᵀ = S⁻¹ Bᵀ
    let K_a = match cholesky_of(S.clone()) {
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
/// use nmci::prelude::*;
/// use nmci::rules::naive_fusion;
/// let I = DMatrix::<f64>::identity(2, 2);
/// let p = FusionProblem::from_covariances(I.clone() * 2.0, I.clone() * 2.0,
///     CrossPattern::fully_unknown(2)).unwrap();
/// assert!((naive_fusion(&p).P - I).amax() < 1e-12); // half of either, whatever P_ab really is
/// ```
pub fn naive_fusion(problem: &FusionProblem) -> Fused {
    known_fusion(problem, &DMatrix::zeros(problem.dim(), problem.dim()))
}

/// Naive fusion of block-stored estimates in place (`P_a[k] ← naive(P_a[k], P_b[k])`), and
/// the plan that fuses the means ([`MeanPlan`]): with `S = P_a + P_b = L Lᵀ`,
/// `x = x_b + P_b S⁻¹ (x_a − x_b)` ([`naive_mean`]) and
/// `P = P_b − P_b S⁻¹ P_b = P_b − (L⁻¹P_b)ᵀ(L⁻¹P_b)` — [`naive_fusion`]'s formulas without the
/// gains. Twin blocks ([`covariance_twins`]) share the factorization and the covariance. A
/// block whose `S` is numerically singular falls back to [`naive_fusion`] (pseudo-inverse)
/// and its gains.
#[allow(non_snake_case)]
pub(crate) fn naive_in_place(P_a: &mut [DMatrix<f64>], P_b: &[DMatrix<f64>]) -> MeanPlan {
    let twins = covariance_twins(P_a, P_b);
    let mut plan = MeanPlan::with_blocks(P_a.len());
    // The plan's factor of each block (None: the fallback).
    let mut slots: Vec<Option<usize>> = Vec::with_capacity(P_a.len());
    for k in 0..P_a.len() {
        let shared = twins[k].and_then(|t| slots[t].map(|slot| (slot, P_a[t].clone())));
        let (slot, P) = match shared {
            Some(done) => done,
            None => match cholesky_of(&P_a[k] + &P_b[k]) {
                Some(c) => {
                    let L = c.unpack();
                    // P_b symmetric: the row solve leaves Z = L⁻¹P_b row-major, i.e. Zᵀ
                    // column-major; P_b S⁻¹ P_b = Zᵀ Z.
                    let mut Zt = P_b[k].clone();
                    solve_lower_rows(&L, Zt.as_mut_slice());
                    let Z = Zt.transpose();
                    let mut P = P_b[k].clone();
                    P.gemm_tr(-1.0, &Z, &Z, 1.0);
                    symmetrize_in_place(&mut P);
                    plan.factors.push((L, P_b[k].clone()));
                    (plan.factors.len() - 1, P)
                }
                None => {
                    let n = P_a[k].nrows();
                    let problem = FusionProblem::new_trusted(
                        DVector::zeros(n),
                        P_a[k].clone(),
                        DVector::zeros(n),
                        P_b[k].clone(),
                        crate::structure::CrossPattern::fully_unknown(n),
                    );
                    let f = naive_fusion(&problem);
                    P_a[k] = f.P;
                    plan.gains.push((f.K_a, f.K_b));
                    plan.blocks.push(BlockMean::Gains {
                        gains: plan.gains.len() - 1,
                    });
                    slots.push(None);
                    continue;
                }
            },
        };
        P_a[k] = P;
        plan.blocks.push(BlockMean::Naive { factor: slot });
        slots.push(Some(slot));
    }
    plan
}

/// Naive fusion's mean `x_b + P_b S⁻¹ (x_a − x_b)` with `S = P_a + P_b = L Lᵀ`.
#[allow(non_snake_case)]
pub(super) fn naive_mean(
    L: &DMatrix<f64>,
    P_b: &DMatrix<f64>,
    x_a: &DVector<f64>,
    x_b: &DVector<f64>,
) -> DVector<f64> {
    // y = S⁻¹ (x_a − x_b) = L⁻ᵀ L⁻¹ (x_a − x_b)
    let mut y = x_a - x_b;
    solve_lower_in_place(L, y.as_mut_slice());
    L.tr_solve_lower_triangular_mut(&mut y);
    x_b + P_b * y
}

#[cfg(test)]
#[allow(non_snake_case)]
mod tests {
    use super::*;
    use crate::fusion::{fuse_estimates, Estimate};
    use crate::structure::CrossPattern;

    #[test]
    fn naive_in_place_matches_naive_fusion_and_shares_twins() {
        let P_a = DMatrix::from_row_slice(3, 3, &[4.0, 1.0, 0.5, 1.0, 3.0, 0.2, 0.5, 0.2, 2.0]);
        let P_b = DMatrix::from_row_slice(3, 3, &[2.0, -0.3, 0.1, -0.3, 5.0, 1.0, 0.1, 1.0, 1.5]);
        let mean = |v: [f64; 3]| DVector::from_row_slice(&v);
        let a = vec![
            Estimate {
                x: mean([1.0, 2.0, 3.0]),
                P: P_a.clone(),
            },
            Estimate {
                x: mean([-1.0, 0.5, 0.0]),
                P: P_a.clone(),
            },
        ];
        let b = vec![
            Estimate {
                x: mean([0.0, 1.0, -2.0]),
                P: P_b.clone(),
            },
            Estimate {
                x: mean([2.0, 2.0, 2.0]),
                P: P_b.clone(),
            },
        ];
        // A third pair whose P_a − P_b is positive definite too (so a factorization of the
        // wrong combination would not fall back to `naive_fusion` unnoticed).
        let a = [
            a,
            vec![Estimate {
                x: mean([0.5, 0.5, 0.5]),
                P: &P_b * 10.0,
            }],
        ]
        .concat();
        let b = [
            b,
            vec![Estimate {
                x: mean([1.0, -1.0, 0.0]),
                P: P_b.clone(),
            }],
        ]
        .concat();
        let mut fused = a.clone();
        fuse_estimates(&mut fused, &b, |a, b| Ok(((), naive_in_place(a, b)))).unwrap();
        for k in 0..3 {
            let p = FusionProblem::new_trusted(
                a[k].x.clone(),
                a[k].P.clone(),
                b[k].x.clone(),
                b[k].P.clone(),
                CrossPattern::fully_unknown(3),
            );
            let r = naive_fusion(&p);
            assert!((&fused[k].P - &r.P).amax() < 1e-12);
            assert!((&fused[k].x - &r.x).amax() < 1e-12);
        }
    }
}
