//! Worst-case constraints instead of random ones: the robust SDP by cutting planes.
//!
//! The sampled SDP (paper eq. (sampled_sdp)) keeps `P̄ ⪰ K P' Kᵀ` for random admissible `P'`
//! only. Here the constraints are chosen adversarially: solve the program on the current set,
//! then search the admissible set for the `P'` that most violates the constraint at the new
//! `(K, P̄)`, add it, and repeat. For a direction `v` the inner problem
//!
//! `max vᵀ K P' Kᵀ v = vᵀK_aP_aK_aᵀv + vᵀK_bP_bK_bᵀv + 2 (K_aᵀv)ᵀ P_ab (K_bᵀv)`
//!
//! over the admissible set (the joint covariance `⪰ 0` — the closure of the admissible set —
//! and the known zeros) is linear in `P_ab` with one PSD constraint of size `2n`: a small SDP
//! (Clarabel). The search alternates it with the top eigenvector of `K P' Kᵀ − P̄`, from
//! several starting directions, and stops when the violation no longer grows. The loop ends
//! when the worst violation found is below `tolerance · max(tr P̄, 1)` or at `max_iterations`
//! (reported, never hidden). Every program solved is a relaxation of the robust one, so its
//! dual objective stays a lower bound on the robust optimum. A cut lies on the boundary of the
//! admissible set (its joint covariance is singular, to solver tolerance); the SDP uses it
//! through its positive semidefinite projection.
//!
//! Convergence is that of a cutting-plane method: fast where few constraints are active
//! (the paper's example, fully unknown `P_ab`: a handful of cuts), slower in general. Each
//! iteration adds the cut of every start that found a violation; since every cut is a worst
//! case, nearly all are active and each program is solved with all of them at once (no
//! working set). Measured (release, `tests`' random problems, each entry of `P_ab` unknown
//! with probability 0.6, tolerance `1e-7`): 2-D and 3-D in 6–17 iterations (24–58
//! constraints, ≤ 0.3 s); 4-D in 36–39 (105–107, 6 s); 5-D in 39–46 (127–143, 16–21 s);
//! 6-D in 6–11 (24–41, 2–5 s), but other 6-D cases (e.g. the `random_spd` of the
//! benchmarks, `P_ab` unknown on a band or at random) were still at a violation of
//! `5e-6`–`1e-5` after 60 iterations (≈ 170 constraints, 60 s): the tail of a cutting-plane
//! method is slow. The search is local (the worst case over `(v, P')` is not a
//! convex problem), so "converged" means no violation was *found*; the fresh-sample checks in
//! the tests are the independent evidence. `converged: false` reports an iteration limit;
//! a solver failure is returned as an error.

use clarabel::algebra::CscMatrix;
use clarabel::solver::{DefaultSettings, DefaultSolver, IPSolver, SolverStatus, SupportedConeT};
use nalgebra::{DMatrix, DVector, SymmetricEigen};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use super::certify::{certification_blocks, certified_fusion, CertifySettings};
use super::check::fused_error_covariance;
use super::sample::{sample_cross_covariances, CrossSamples, SamplerSettings};
use super::sdp::{optimal_fusion_for_samples, SdpSettings, SdpStatus};
use super::{Fused, FusionProblem};
use crate::error::SolveError;
use crate::linalg::symmetrize;

/// A cut found on the boundary of the admissible set is pulled inside by this factor
/// (`P_ab ← (1 − CUT_SHRINK) P_ab`; the set is convex and contains `P_ab = 0`), so that its
/// joint covariance stays positive definite and its LMI well conditioned: exact boundary
/// cuts made Clarabel stop with `NumericalError` on 6-D cases. The constraint moves by at
/// most `CUT_SHRINK` times its cross term, below the loop's tolerance.
const CUT_SHRINK: f64 = 1e-7;

/// Settings of the cutting-plane loop.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CutsSettings {
    /// Random admissible cross-covariances to start from (default 4, hit-and-run).
    pub initial_samples: usize,
    /// Seed of the starting samples and of the random search directions (default 0).
    pub seed: u64,
    /// Outer iterations (one solve and one search each; default 60).
    pub max_iterations: usize,
    /// Starting directions of the worst-case search per iteration (default 4).
    pub restarts: usize,
    /// Stop when the worst violation is below `tolerance · max(tr P̄, 1)` (default `1e-7`).
    pub tolerance: f64,
    /// Settings of each SDP solve (its sample and working-set fields are ignored).
    pub sdp: SdpSettings,
    /// Guide the loop with the certified rule (default `true`; blocks of at most
    /// [`CertifySettings::max_block_dim`] states): seed it with the worst cases at the
    /// certified bound, and stop as soon as the lower bound reaches the certified upper bound
    /// within `tolerance` — a proven optimum.
    pub certify: bool,
}

impl Default for CutsSettings {
    fn default() -> Self {
        Self {
            initial_samples: 4,
            seed: 0,
            max_iterations: 60,
            restarts: 4,
            tolerance: 1e-7,
            sdp: SdpSettings::default(),
            certify: true,
        }
    }
}

impl CutsSettings {
    /// Checks the settings.
    pub fn validate(&self) -> Result<(), SolveError> {
        if self.initial_samples == 0 || self.max_iterations == 0 || self.restarts == 0 {
            return Err(SolveError::InvalidSettings(
                "sdp_cuts needs initial_samples, max_iterations and restarts of at least 1".into(),
            ));
        }
        if !(self.tolerance > 0.0 && self.tolerance.is_finite()) {
            return Err(SolveError::InvalidSettings(format!(
                "tolerance must be positive and finite (got {})",
                self.tolerance
            )));
        }
        Ok(())
    }
}

/// The cutting-plane result.
#[derive(Debug, Clone, PartialEq)]
pub struct CutsResult {
    /// Fused estimate, bound `P̄` and gains of the last program.
    pub fused: Fused,
    /// Status of the last solve.
    pub status: SdpStatus,
    /// Outer iterations run.
    pub iterations: usize,
    /// Constraints (cross-covariances) in the last program: the starting samples and the cuts.
    pub constraints: usize,
    /// The worst `λ_max(K P' Kᵀ − P̄)` the search found at the end (≤ the stopping threshold
    /// when `converged`).
    pub violation: f64,
    /// Whether the loop stopped on the tolerance or a closed gap (otherwise on
    /// `max_iterations`).
    pub converged: bool,
    /// The certified rule's `tr P̄` (an upper bound on the robust optimum), when computed.
    pub certified_trace: Option<f64>,
    /// Whether the loop stopped because `dual_objective` reached `certified_trace` within
    /// the tolerance: the optimum is then proven, and the certified rule attains it.
    pub gap_closed: bool,
    /// Dual objective of the last program: a lower bound on the robust optimum.
    pub dual_objective: f64,
    /// The cross-covariances of the last program.
    pub cross: Vec<DMatrix<f64>>,
}

/// The robust-optimal bound by cutting planes (see the module docs).
///
/// ```
/// use nalgebra::{DMatrix, DVector};
/// use nmci::*;
/// let d = |v: &[f64]| DMatrix::from_diagonal(&DVector::from_row_slice(v));
/// let p = FusionProblem::from_covariances(d(&[3.0, 1.0]), d(&[1.0, 4.0]),
///     CrossPattern::diagonal(2)).unwrap();
/// let cuts = optimal_fusion_cuts(&p, &CutsSettings::default()).unwrap();
/// assert!(cuts.converged && (cuts.fused.trace() - 2.0).abs() < 1e-6);
/// ```
#[allow(non_snake_case)]
pub fn optimal_fusion_cuts(
    problem: &FusionProblem,
    settings: &CutsSettings,
) -> Result<CutsResult, SolveError> {
    settings.validate()?;
    let n = problem.dim();
    let mut cross = sample_cross_covariances(
        problem,
        settings.initial_samples,
        settings.seed,
        SamplerSettings::hit_and_run(),
    )?
    .cross;
    let mut rng = ChaCha8Rng::seed_from_u64(settings.seed ^ 0x5EED_C075);
    let certify_settings = CertifySettings::default();
    let certified = if settings.certify
        && certification_blocks(problem, None)
            .iter()
            .all(|b| b.len() <= certify_settings.max_block_dim)
    {
        Some(certified_fusion(problem, &certify_settings)?)
    } else {
        None
    };
    // The worst cases at the certified bound are where it is tight: the likely active
    // constraints of the robust optimum.
    if let Some(cert) = &certified {
        let eig = SymmetricEigen::new(cert.fused.P.clone());
        for k in 0..settings.restarts.max(n) {
            let v = if k < n {
                eig.eigenvectors.column(k).into_owned()
            } else {
                DVector::from_fn(n, |_, _| rng.random_range(-1.0..1.0)).normalize()
            };
            let (_, P_ab) = worst_case_search(problem, &cert.fused, v, settings)?;
            if !cross.iter().any(|c| (c - &P_ab).amax() <= 1e-12 * P_ab.amax().max(1.0)) {
                cross.push(P_ab);
            }
        }
    }
    // Every constraint here is a worst case, so nearly all are active: one program with all
    // of them beats the sampled SDP's working-set loop (which re-solves to add 8 at a time).
    let sdp = SdpSettings {
        working_set: false,
        ..settings.sdp
    };
    let mut iterations = 0;
    loop {
        iterations += 1;
        let set = CrossSamples {
            cross: cross.clone(),
            trials: 0,
        };
        let opt = optimal_fusion_for_samples(problem, &set, &sdp)?;
        let threshold = settings.tolerance * opt.fused.trace().max(1.0);
        // Worst-case search from the top eigenvector of the worst current constraint and
        // from random directions.
        let mut starts: Vec<DVector<f64>> = Vec::with_capacity(settings.restarts);
        if let Some((_, v)) = cross
            .iter()
            .map(|P_ab| top_eigen(&violation_matrix(problem, &opt.fused, P_ab)))
            .max_by(|a, b| a.0.total_cmp(&b.0))
        {
            starts.push(v);
        }
        while starts.len() < settings.restarts {
            let v = DVector::from_fn(n, |_, _| rng.random_range(-1.0..1.0));
            starts.push(v.normalize());
        }
        // Every start that finds a violation contributes its cut (distinct directions cut off
        // different parts of the current relaxation); the worst decides convergence.
        let mut found: Vec<(f64, DMatrix<f64>)> = Vec::with_capacity(starts.len());
        for start in starts {
            found.push(worst_case_search(problem, &opt.fused, start, settings)?);
        }
        let violation = found.iter().map(|f| f.0).fold(f64::NEG_INFINITY, f64::max);
        let certified_trace = certified.as_ref().map(|c| c.fused.trace());
        let gap_closed = certified_trace.is_some_and(|upper| {
            opt.dual_objective >= upper - settings.tolerance * upper.max(1.0)
        });
        let converged = violation <= threshold || gap_closed;
        if converged || iterations >= settings.max_iterations {
            return Ok(CutsResult {
                fused: opt.fused,
                status: opt.status,
                iterations,
                constraints: cross.len(),
                violation,
                converged,
                certified_trace,
                gap_closed,
                dual_objective: opt.dual_objective,
                cross,
            });
        }
        for (v, P_ab) in found {
            let duplicate = cross
                .iter()
                .any(|c| (c - &P_ab).amax() <= 1e-12 * P_ab.amax().max(1.0));
            if v > threshold && !duplicate {
                cross.push(P_ab);
            }
        }
    }
}

/// `K P' Kᵀ − P̄` for one cross-covariance.
#[allow(non_snake_case)]
fn violation_matrix(problem: &FusionProblem, fused: &Fused, P_ab: &DMatrix<f64>) -> DMatrix<f64> {
    symmetrize(&(fused_error_covariance(problem, &fused.K_a, &fused.K_b, P_ab) - &fused.P))
}

/// Largest eigenvalue and its unit eigenvector.
fn top_eigen(m: &DMatrix<f64>) -> (f64, DVector<f64>) {
    let eig = SymmetricEigen::new(m.clone());
    let k = eig.eigenvalues.imax();
    (eig.eigenvalues[k], eig.eigenvectors.column(k).into_owned())
}

/// Alternates the direction SDP with the top eigenvector until the violation stops growing.
#[allow(non_snake_case)]
fn worst_case_search(
    problem: &FusionProblem,
    fused: &Fused,
    mut v: DVector<f64>,
    settings: &CutsSettings,
) -> Result<(f64, DMatrix<f64>), SolveError> {
    let mut best = (
        f64::NEG_INFINITY,
        DMatrix::zeros(problem.dim(), problem.dim()),
    );
    for _ in 0..10 {
        let P_ab = worst_cross_for_direction(problem, fused, &v, settings)?;
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
fn worst_cross_for_direction(
    problem: &FusionProblem,
    fused: &Fused,
    v: &DVector<f64>,
    settings: &CutsSettings,
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
    let svec = |r: usize, c: usize| {
        let (r, c) = (r.min(c), r.max(c));
        c * (c + 1) / 2 + r
    };
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
    let clarabel_settings = DefaultSettings {
        verbose: false,
        max_iter: settings.sdp.max_iter,
        tol_gap_abs: settings.sdp.tolerance,
        tol_gap_rel: settings.sdp.tolerance,
        tol_feas: settings.sdp.tolerance,
        ..DefaultSettings::default()
    };
    let mut solver = DefaultSolver::new(&P, &q, &A, &b, &cones, clarabel_settings)
        .map_err(|e| SolveError::Setup(e.to_string()))?;
    solver.solve();
    let sol = &solver.solution;
    match sol.status {
        SolverStatus::Solved | SolverStatus::AlmostSolved => {}
        other => {
            return Err(SolveError::SolverFailed {
                status: format!("{other:?}"),
                iterations: sol.iterations,
            })
        }
    }
    let mut P_ab = DMatrix::zeros(n, n);
    for (k, &(i, j)) in free.iter().enumerate() {
        P_ab[(i, j)] = sol.x[k];
    }
    Ok(P_ab * (1.0 - CUT_SHRINK))
}
