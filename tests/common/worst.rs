//! The worst admissible cross-covariance in one direction, written for the tests independently
//! of the crate: `max 2 u_aᵀ P_ab u_b` over the unknown entries of `P_ab` with
//! `[[P_a, P_ab], [P_abᵀ, P_b]] ⪰ 0` and the known zeros kept, solved by Clarabel directly.
//! For a gain `K = [K_a, K_b]` and a direction `v`, `u = Kᵀ v` makes this the worst
//! `vᵀ K J Kᵀ v` over admissible joints `J`.

use clarabel::algebra::CscMatrix;
use clarabel::solver::{DefaultSettings, DefaultSolver, IPSolver, SolverStatus, SupportedConeT};
use nalgebra::{DMatrix, DVector};
use nmci::FusionProblem;

/// The maximising `P_ab` (zero where the pattern has known zeros), to the solver's
/// tolerance (`10⁻¹¹`); panics (a test failure) unless the solver reports solved.
pub fn worst_cross(
    problem: &FusionProblem,
    u_a: &DVector<f64>,
    u_b: &DVector<f64>,
) -> DMatrix<f64> {
    let n = problem.dim();
    let free: Vec<(usize, usize)> = (0..n)
        .flat_map(|i| (0..n).map(move |j| (i, j)))
        .filter(|&(i, j)| problem.cross_pattern.is_unknown(i, j))
        .collect();
    let mut P_ab = DMatrix::zeros(n, n);
    if free.is_empty() {
        return P_ab;
    }
    // Rows of the joint's upper triangle, column by column, off-diagonals scaled by √2
    // (Clarabel's `PSDTriangleConeT` convention).
    let m = 2 * n;
    let at = |r: usize, c: usize| {
        let (r, c) = (r.min(c), r.max(c));
        c * (c + 1) / 2 + r
    };
    let s2 = std::f64::consts::SQRT_2;
    let mut b = vec![0.0; m * (m + 1) / 2];
    for c in 0..n {
        for r in 0..=c {
            let s = if r == c { 1.0 } else { s2 };
            b[at(r, c)] = s * problem.P_a[(r, c)];
            b[at(n + r, n + c)] = s * problem.P_b[(r, c)];
        }
    }
    let (mut rows, mut cols, mut vals, mut q) = (vec![], vec![], vec![], vec![]);
    for (k, &(i, j)) in free.iter().enumerate() {
        rows.push(at(i, n + j));
        cols.push(k);
        vals.push(-s2);
        q.push(-2.0 * u_a[i] * u_b[j]);
    }
    let A = CscMatrix::new_from_triplets(b.len(), free.len(), rows, cols, vals);
    let zero = CscMatrix::zeros((free.len(), free.len()));
    let settings = DefaultSettings {
        verbose: false,
        tol_gap_abs: 1e-11,
        tol_gap_rel: 1e-11,
        tol_feas: 1e-11,
        ..DefaultSettings::default()
    };
    let cones = [SupportedConeT::PSDTriangleConeT(m)];
    let mut solver = DefaultSolver::new(&zero, &q, &A, &b, &cones, settings).unwrap();
    solver.solve();
    assert!(
        matches!(
            solver.solution.status,
            SolverStatus::Solved | SolverStatus::AlmostSolved
        ),
        "{:?}",
        solver.solution.status
    );
    for (k, &(i, j)) in free.iter().enumerate() {
        P_ab[(i, j)] = solver.solution.x[k];
    }
    P_ab
}
