//! The worst-case search of the cutting-plane loop (the parent's module docs): for a rule
//! `(K, P̄)` and a direction, the admissible cross-covariance that most violates
//! `P̄ ⪰ K P' Kᵀ`, alternated with the top eigenvector of the violation, and the extra starting
//! directions used when the proven bracket is open.

use clarabel::algebra::CscMatrix;
use clarabel::solver::SupportedConeT;
use nalgebra::{DMatrix, DVector, SymmetricEigen};

use super::settings::CutsSettings;
use crate::error::SolveError;
use crate::fusion::check::{error_covariance, margin};
use crate::fusion::program::{solve_program, svec_index, Deadline, Kkt};
use crate::fusion::sample::{sample_cross_covariances, SamplerSettings};
use crate::fusion::{Fused, FusionProblem};
use crate::linalg::symmetrize;

/// A cut found on the boundary of the admissible set is pulled inside by this factor
/// (`P_ab ← (1 − CUT_SHRINK) P_ab`; the set is convex and contains `P_ab = 0`), so that its
/// joint covariance stays positive definite and its LMI well conditioned: exact boundary
/// cuts made Clarabel stop with `NumericalError` on 6-D cases. The constraint moves by at
/// most `CUT_SHRINK` times its cross term, below the loop's tolerance.
pub(super) const CUT_SHRINK: f64 = 1e-7;

/// Admissible cross-covariances drawn at random (hit-and-run, [`RANDOM_SEARCH_SAMPLES`]):
/// the top eigenvectors of the violations of the most violated ones, the starting directions
/// of the worst-case search (at most `restarts`; empty when none is violated beyond
/// `threshold`).
#[allow(non_snake_case)]
pub(super) fn random_starts(
    problem: &FusionProblem,
    fused: &Fused,
    settings: &CutsSettings,
    round: u64,
    threshold: f64,
) -> Result<Vec<DVector<f64>>, SolveError> {
    let drawn = sample_cross_covariances(
        problem,
        RANDOM_SEARCH_SAMPLES,
        settings.seed ^ (0xC0FFEE + round),
        SamplerSettings::hit_and_run(),
    )?;
    let mut scored: Vec<(f64, usize)> = drawn
        .cross
        .iter()
        .enumerate()
        .map(|(i, P_ab)| (-margin(problem, fused, P_ab), i))
        .filter(|(v, _)| *v > threshold)
        .collect();
    scored.sort_by(|a, b| b.0.total_cmp(&a.0));
    Ok(scored
        .iter()
        .take(settings.restarts)
        .map(|&(_, i)| top_eigen(&violation_matrix(problem, fused, &drawn.cross[i])).1)
        .collect())
}

/// [`GRID_DIRECTIONS`] directions spread evenly over the half circle (`n = 2`) or the half
/// sphere (`n = 3`, a Fibonacci lattice); none for larger `n`. Extra starting directions of the
/// worst-case search when the bracket is open: random ones can all miss a narrow violation
/// (a 2-D case left open by 1.8e-6 in `examples/certify_levels.rs` until these were added).
pub(super) fn direction_grid(n: usize) -> Vec<DVector<f64>> {
    let count = GRID_DIRECTIONS;
    match n {
        2 => (0..count)
            .map(|k| {
                let t = std::f64::consts::PI * k as f64 / count as f64;
                DVector::from_vec(vec![t.cos(), t.sin()])
            })
            .collect(),
        3 => (0..count)
            .map(|k| {
                // z in (0, 1]: the upper half sphere (−v gives the same constraint).
                let z = (k as f64 + 0.5) / count as f64;
                let r = (1.0 - z * z).sqrt();
                let t = k as f64 * std::f64::consts::PI * (3.0 - 5f64.sqrt());
                DVector::from_vec(vec![r * t.cos(), r * t.sin(), z])
            })
            .collect(),
        _ => Vec::new(),
    }
}

/// The number of directions of [`direction_grid`].
const GRID_DIRECTIONS: usize = 64;

/// Extra random starting directions (times `restarts`) of the worst-case search when the
/// local search finds no violation but the proven bracket is open.
pub(super) const OPEN_BRACKET_STARTS: usize = 4;

/// Random admissible points tried when the local search finds no violation but the proven
/// bracket is open.
const RANDOM_SEARCH_SAMPLES: usize = 2000;

/// `K P' Kᵀ − P̄` for one cross-covariance.
#[allow(non_snake_case)]
pub(super) fn violation_matrix(
    problem: &FusionProblem,
    fused: &Fused,
    P_ab: &DMatrix<f64>,
) -> DMatrix<f64> {
    symmetrize(&(error_covariance(problem, &fused.K_a, &fused.K_b, P_ab) - &fused.P))
}

/// Largest eigenvalue and its unit eigenvector.
pub(super) fn top_eigen(m: &DMatrix<f64>) -> (f64, DVector<f64>) {
    let eig = SymmetricEigen::new(m.clone());
    let k = eig.eigenvalues.imax();
    (eig.eigenvalues[k], eig.eigenvectors.column(k).into_owned())
}

/// Alternates the direction SDP with the top eigenvector until the violation stops growing.
#[allow(non_snake_case)]
pub(super) fn worst_case_search(
    problem: &FusionProblem,
    fused: &Fused,
    mut v: DVector<f64>,
    settings: &CutsSettings,
    deadline: &Deadline,
) -> Result<(f64, DMatrix<f64>), SolveError> {
    let mut best = (
        f64::NEG_INFINITY,
        DMatrix::zeros(problem.dim(), problem.dim()),
    );
    for _ in 0..10 {
        let P_ab = worst_cross_for_direction(problem, fused, &v, settings, deadline)?;
        let (violation, next) = top_eigen(&violation_matrix(problem, fused, &P_ab));
        let improved = violation > best.0 + 1e-12 * violation.abs().max(1.0);
        if violation > best.0 {
            best = (violation, P_ab);
        }
        if !improved || next.dot(&v).abs() > 1.0 - 1e-12 {
            break;
        }
        v = next;
    }
    Ok(best)
}

/// `argmax_{P_ab} 2 (K_aᵀv)ᵀ P_ab (K_bᵀv)` over `[[P_a, P_ab], [P_abᵀ, P_b]] ⪰ 0` with the
/// known zeros: one PSD cone of size `2n` over the free entries of `P_ab`.
#[allow(non_snake_case)]
pub(super) fn worst_cross_for_direction(
    problem: &FusionProblem,
    fused: &Fused,
    v: &DVector<f64>,
    settings: &CutsSettings,
    deadline: &Deadline,
) -> Result<DMatrix<f64>, SolveError> {
    let n = problem.dim();
    let (u_a, u_b) = (fused.K_a.tr_mul(v), fused.K_b.tr_mul(v));
    let free: Vec<(usize, usize)> = (0..n)
        .flat_map(|i| (0..n).map(move |j| (i, j)))
        .filter(|&(i, j)| problem.cross_pattern.is_unknown(i, j))
        .collect();
    if free.is_empty() {
        return Ok(DMatrix::zeros(n, n));
    }
    let m = 2 * n;
    let svec = |r: usize, c: usize| svec_index(r.min(c), r.max(c));
    let sqrt2 = std::f64::consts::SQRT_2;
    // s = b − A y = svec(joint(y)) ∈ PSD cone.
    let mut b = vec![0.0; m * (m + 1) / 2];
    for c in 0..n {
        for r in 0..=c {
            let scale = if r == c { 1.0 } else { sqrt2 };
            b[svec(r, c)] = scale * problem.P_a[(r, c)];
            b[svec(n + r, n + c)] = scale * problem.P_b[(r, c)];
        }
    }
    let (mut rows, mut cols, mut vals) = (Vec::new(), Vec::new(), Vec::new());
    let mut q = vec![0.0; free.len()];
    for (k, &(i, j)) in free.iter().enumerate() {
        rows.push(svec(i, n + j));
        cols.push(k);
        vals.push(-sqrt2);
        q[k] = -2.0 * u_a[i] * u_b[j]; // minimise the negated objective
    }
    let A = CscMatrix::new_from_triplets(b.len(), free.len(), rows, cols, vals);
    let P = CscMatrix::zeros((free.len(), free.len()));
    let cones = [SupportedConeT::PSDTriangleConeT(m)];
    let (solver, _) = solve_program(
        &P,
        &q,
        &A,
        &b,
        &cones,
        Kkt::Qdldl,
        (settings.sdp.max_iter, settings.sdp.tolerance),
        deadline,
        "the cutting planes' worst-case search",
    )?;
    let sol = &solver.solution;
    let mut P_ab = DMatrix::zeros(n, n);
    for (k, &(i, j)) in free.iter().enumerate() {
        P_ab[(i, j)] = sol.x[k];
    }
    Ok(P_ab * (1.0 - CUT_SHRINK))
}
