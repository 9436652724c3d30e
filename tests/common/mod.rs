//! Shared helpers of the native tests: seeded random SPD matrices and patterns.
#![allow(dead_code, non_snake_case)]

use nalgebra::{DMatrix, DVector};
use nmci::{CrossPattern, FusionProblem};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

pub mod fuzz;
pub mod memo;
pub mod worst;

/// A matrix as the contract's nested rows.
pub fn rows(m: &DMatrix<f64>) -> Vec<Vec<f64>> {
    m.row_iter().map(|r| r.iter().copied().collect()).collect()
}

pub fn rng(seed: u64) -> ChaCha8Rng {
    ChaCha8Rng::seed_from_u64(seed)
}

/// A random SPD matrix with eigenvalues in [0.2, 5] and a random orientation.
pub fn random_spd(n: usize, rng: &mut ChaCha8Rng) -> DMatrix<f64> {
    let g = DMatrix::from_fn(n, n, |_, _| rng.random_range(-1.0..1.0));
    let q = g.qr().q();
    let d = DVector::from_fn(n, |_, _| rng.random_range(0.2..5.0));
    let m = &q * DMatrix::from_diagonal(&d) * q.transpose();
    (&m + m.transpose()) * 0.5
}

/// A random pattern with each entry unknown with probability `p`.
pub fn random_pattern(n: usize, p: f64, rng: &mut ChaCha8Rng) -> CrossPattern {
    CrossPattern::from_matrix(DMatrix::from_fn(n, n, |_, _| rng.random_bool(p))).unwrap()
}

pub fn diag(v: &[f64]) -> DMatrix<f64> {
    DMatrix::from_diagonal(&DVector::from_row_slice(v))
}

/// The paper's example: P_a = diag(3, 1), P_b = diag(1, 4), P_ab diagonal.
pub fn paper_example() -> FusionProblem {
    FusionProblem::from_covariances(
        diag(&[3.0, 1.0]),
        diag(&[1.0, 4.0]),
        CrossPattern::diagonal(2),
    )
    .unwrap()
}

/// A random problem with random means.
pub fn random_problem(n: usize, pattern: CrossPattern, rng: &mut ChaCha8Rng) -> FusionProblem {
    let P_a = random_spd(n, rng);
    let P_b = random_spd(n, rng);
    let x_a = DVector::from_fn(n, |_, _| rng.random_range(-3.0..3.0));
    let x_b = DVector::from_fn(n, |_, _| rng.random_range(-3.0..3.0));
    FusionProblem::new(x_a, P_a, x_b, P_b, pattern).unwrap()
}

/// Block-diagonal SPD matrix with random blocks on the given state groups.
pub fn block_spd(n: usize, groups: &[Vec<usize>], rng: &mut ChaCha8Rng) -> DMatrix<f64> {
    let mut m = DMatrix::zeros(n, n);
    for g in groups {
        let b = random_spd(g.len(), rng);
        for (i, &gi) in g.iter().enumerate() {
            for (j, &gj) in g.iter().enumerate() {
                m[(gi, gj)] = b[(i, j)];
            }
        }
    }
    m
}

/// `min λ_min(P̄ − K P' Kᵀ)` over the cross-covariances `cross`, with
/// `P' = [[P_a, X], [Xᵀ, P_b]]` and the product written out (not the library's check).
pub fn margin_by_hand(
    p: &FusionProblem,
    K_a: &DMatrix<f64>,
    K_b: &DMatrix<f64>,
    P: &DMatrix<f64>,
    cross: &[DMatrix<f64>],
) -> f64 {
    cross
        .iter()
        .map(|X| {
            let KPK = K_a * &p.P_a * K_a.transpose()
                + K_a * X * K_b.transpose()
                + K_b * X.transpose() * K_a.transpose()
                + K_b * &p.P_b * K_b.transpose();
            let D = P - KPK;
            nalgebra::SymmetricEigen::new((&D + D.transpose()) * 0.5)
                .eigenvalues
                .min()
        })
        .fold(f64::INFINITY, f64::min)
}
