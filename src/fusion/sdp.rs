//! The sampled-SDP approximation of the optimal robust bound (paper eq. (sampled_sdp)).
//!
//! The robust problem (paper eq. (robust_sdp)) is
//! `min tr P̄  s.t.  K_a + K_b = I,  P̄ ⪰ K P' Kᵀ  ∀ admissible P'`, `K = [K_a, K_b]`.
//! Replacing "all admissible `P'`" by a sample set `{P'_1, …, P'_N}` gives a semidefinite
//! program whose optimum is a **lower bound** on the robust optimum (a relaxation), and whose
//! solution is only guaranteed conservative for the samples.
//!
//! ## Formulation
//! The paper writes each constraint as `[[P̄, K], [Kᵀ, P'_i⁻¹]] ⪰ 0`. Near the boundary of
//! the admissible set (correlations near ±1) `P'_i` is nearly singular, `P'_i⁻¹` explodes
//! and the interior-point solver stalls. With any factor `P'_i = L_i L_iᵀ` the congruent form
//! `[[P̄, K L_i], [(K L_i)ᵀ, I₂ₙ]] ⪰ 0` is the same constraint (Schur complement) and stays
//! bounded. This module uses that form in the basis where it is smallest:
//!
//! With `K_b = I − K_a` the fused error is `e_f = e_b + K_a d`, `d = e_a − e_b`. Factor the
//! covariance of `(d, e_b)`, `Z_i = [[S_i, C_iᵀ], [C_i, P_b]]` with `S_i = P_a + P_b − P_ab − P_abᵀ`
//! and `C_i = P_abᵀ − P_b`, as `Z_i = L_i L_iᵀ`, `L_i = [[L₁₁, 0], [L₂₁, L₂₂]]` lower
//! block-triangular. Then `e_f = (K_a L₁₁ + L₂₁) w₁ + L₂₂ w₂` with white `w`, so
//!
//! `P̄ ⪰ K P'_i Kᵀ`  ⇔  `[[P̄ − L₂₂L₂₂ᵀ, K_a L₁₁ + L₂₁], [(K_a L₁₁ + L₂₁)ᵀ, Iₙ]] ⪰ 0`,
//!
//! an LMI of size `2n` (not `3n`), affine in `K_a`, built from one Cholesky factorization and
//! no inverse (`L₂₂L₂₂ᵀ` is the known-correlation optimum `P*_i`). `Z_i` is positive definite
//! exactly when `P'_i` is; a sample too close to singular for Cholesky is factored through its
//! eigendecomposition and an LQ step. Decision variables: `K_a` (n²) and the upper triangle
//! of `P̄`.
//!
//! ## Independent blocks
//! When `P_a`, `P_b` and the pattern split the state into independent blocks (as for nmCI),
//! the sampled program splits too, exactly: for any feasible `(K, P̄)`, dropping the gains
//! between blocks and the off-block part of `P̄` stays feasible with the same trace, because
//! each diagonal block of `K P'_i Kᵀ` is its within-block part plus the PSD contribution of
//! the cross-block gains (the cross-block covariances of every admissible `P'_i` are zero).
//! So one small SDP per block, on the same samples restricted to the block, gives the same
//! optimum at a fraction of the cost.
//!
//! ## Working set
//! Only a few samples are active at the optimum. By default the program is solved on a small
//! working set; every other sample is then checked by `λ_min(P̄ − K P'_i Kᵀ)`, the most
//! violated are added, and the loop repeats until none of the `N` is violated (beyond a
//! tolerance). The final point is then feasible for all `N` constraints and optimal for a
//! subset of them, hence optimal for the full `N`-sample program.

use clarabel::algebra::CscMatrix;
use clarabel::solver::SupportedConeT;
use nalgebra::{DMatrix, SymmetricEigen};

use super::check::{lowest_margin, margin};
use super::lower::lower_bound;
pub use super::program::SdpStatus;
use super::program::{check_time_limit, solve_program, svec_index, Deadline, Kkt};
use super::sample::{sample_cross_covariances, AutoChoice, CrossSamples, SamplerSettings};
use super::scale::Pow2;
use super::{per_block, Fused, FusionProblem};
use crate::error::SolveError;
use crate::linalg::{cholesky_of, symmetrize};
use crate::structure::independent_blocks;

/// Settings of the sampled SDP, with defaults and [`SdpSettings::validate`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SdpSettings {
    /// Number of sampled cross-covariances `N` (default 200).
    pub samples: usize,
    /// Seed of the sampler's `ChaCha8Rng` (default 0).
    pub seed: u64,
    /// Rejection-sampler settings.
    pub sampler: SamplerSettings,
    /// Interior-point iteration limit per solve (default 200).
    pub max_iter: u32,
    /// Clarabel's gap and feasibility tolerances (default `1e-9`).
    pub tolerance: f64,
    /// Solve on a working set of samples (default `true`); `false` puts all `N` LMIs in one program.
    pub working_set: bool,
    /// Samples in the first working set (default 8).
    pub initial_working_set: usize,
    /// Most violated samples added per round (default 8).
    pub batch: usize,
    /// Round limit of the working-set loop (default 100).
    pub max_rounds: usize,
    /// Solve one SDP per independent block (default `true`; exact, see the module docs).
    pub split_blocks: bool,
    /// Wall-clock limit of the whole solve in seconds (default none): past it the solve
    /// ends with [`SolveError::TimeLimit`].
    pub time_limit: Option<f64>,
}

impl Default for SdpSettings {
    fn default() -> Self {
        Self {
            samples: 200,
            seed: 0,
            sampler: SamplerSettings::default(),
            max_iter: 200,
            tolerance: 1e-9,
            working_set: true,
            initial_working_set: 8,
            batch: 8,
            max_rounds: 100,
            split_blocks: true,
            time_limit: None,
        }
    }
}

impl SdpSettings {
    /// Checks every value.
    pub fn validate(&self) -> Result<(), SolveError> {
        let bad = |m: &str| Err(SolveError::InvalidSettings(m.into()));
        if self.samples == 0 {
            return bad("samples must be at least 1");
        }
        if self.max_iter == 0 {
            return bad("max_iter must be at least 1");
        }
        if !(self.tolerance > 0.0 && self.tolerance < 1.0) {
            return bad("tolerance must be in (0, 1)");
        }
        if self.initial_working_set == 0 || self.batch == 0 || self.max_rounds == 0 {
            return bad("initial_working_set, batch and max_rounds must be at least 1");
        }
        self.sampler.validate()?;
        check_time_limit(self.time_limit)
    }
}

/// The sampled-SDP bound with the solver's report.
#[derive(Debug, Clone, PartialEq)]
pub struct SdpResult {
    /// Fused estimate, bound `P̄` and gains.
    pub fused: Fused,
    /// How the last solve ended.
    pub status: SdpStatus,
    /// Interior-point iterations, summed over working-set rounds and blocks.
    pub iterations: u32,
    /// Working-set rounds, summed over blocks.
    pub rounds: usize,
    /// LMIs in the final programs, summed over blocks.
    pub lmis: usize,
    /// Samples `N` the bound was computed for.
    pub samples: usize,
    /// Sampler acceptance rate (1 when the samples were given).
    pub acceptance_rate: f64,
    /// With [`SamplerKind::Auto`](crate::sample::SamplerKind::Auto): the sampler chosen and why.
    pub sampler_choice: Option<AutoChoice>,
    /// Clarabel's dual objective of the final programs, summed over blocks: a lower bound on
    /// the `N`-sample optimum only up to the solver's tolerance (its dual point is feasible
    /// only to that tolerance); see `lower_bound` for a proven one.
    pub dual_objective: f64,
    /// A proven lower bound on the robust optimum (`fusion::bracket`: the solver's dual
    /// matrices checked in exact arithmetic), summed over blocks and rounded down.
    pub lower_bound: f64,
    /// Smallest `λ_min(P̄ − K P'_i Kᵀ)` over all `N` samples (≈ 0 up to solver tolerance).
    pub worst_sample_margin: f64,
    /// The independent blocks solved separately (one block = the whole state).
    pub blocks: Vec<Vec<usize>>,
}

/// Draws `settings.samples` admissible cross-covariances and solves the sampled SDP.
///
/// ```
/// use nalgebra::{DMatrix, DVector};
/// use nmci::{CrossPattern, FusionProblem, sdp::{SdpSettings, optimal_fusion}};
/// let d = |v: &[f64]| DMatrix::from_diagonal(&DVector::from_row_slice(v));
/// let p = FusionProblem::from_covariances(d(&[3.0, 1.0]), d(&[1.0, 4.0]),
///     CrossPattern::diagonal(2)).unwrap();
/// let opt = optimal_fusion(&p, &SdpSettings { samples: 100, ..Default::default() }).unwrap();
/// assert!((opt.fused.trace() - 2.0).abs() < 1e-6);
/// ```
pub fn optimal_fusion(
    problem: &FusionProblem,
    settings: &SdpSettings,
) -> Result<SdpResult, SolveError> {
    settings.validate()?;
    let deadline = Deadline::after(settings.time_limit);
    let samples =
        sample_cross_covariances(problem, settings.samples, settings.seed, settings.sampler)?;
    deadline.check("the sampled SDP (while sampling)")?;
    solve_samples(problem, &samples, settings, &deadline)
}

/// Solves the sampled SDP for a given sample set (`settings.samples` and `seed` are ignored).
#[allow(non_snake_case)]
pub fn optimal_fusion_for_samples(
    problem: &FusionProblem,
    samples: &CrossSamples,
    settings: &SdpSettings,
) -> Result<SdpResult, SolveError> {
    solve_samples(
        problem,
        samples,
        settings,
        &Deadline::after(settings.time_limit),
    )
}

#[allow(non_snake_case)]
pub(crate) fn solve_samples(
    problem: &FusionProblem,
    samples: &CrossSamples,
    settings: &SdpSettings,
    deadline: &Deadline,
) -> Result<SdpResult, SolveError> {
    let settings = SdpSettings {
        samples: samples.len().max(1),
        ..*settings
    };
    settings.validate()?;
    if samples.is_empty() {
        return Err(SolveError::InvalidSettings(
            "the sample set is empty".into(),
        ));
    }
    let blocks = if settings.split_blocks {
        independent_blocks(&problem.P_a, &problem.P_b, &problem.cross_pattern)
    } else {
        vec![(0..problem.dim()).collect()]
    };
    let (mut status, mut iterations, mut rounds, mut lmis, mut dual_objective) =
        (SdpStatus::Solved, 0, 0, 0, 0.0);
    let mut lower = 0.0;
    let fused = per_block(problem, &blocks, |block, sub| {
        let cross = if blocks.len() == 1 {
            samples.cross.clone()
        } else {
            let restrict = |m: &DMatrix<f64>| {
                DMatrix::from_fn(block.len(), block.len(), |i, j| m[(block[i], block[j])])
            };
            samples.cross.iter().map(restrict).collect()
        };
        let solved = solve_block(&sub, &cross, &settings, deadline)?;
        if solved.status == SdpStatus::AlmostSolved {
            status = SdpStatus::AlmostSolved;
        }
        iterations += solved.iterations;
        rounds += solved.rounds;
        lmis += solved.lmis;
        dual_objective += solved.dual_objective;
        lower += solved.lower_bound;
        Ok::<_, SolveError>((solved.fused.K_a, solved.fused.P))
    })?;
    let worst_sample_margin = lowest_margin(problem, &fused, &samples.cross);
    Ok(SdpResult {
        fused,
        status,
        iterations,
        rounds,
        lmis,
        samples: samples.len(),
        acceptance_rate: samples.acceptance_rate(),
        sampler_choice: samples.auto,
        dual_objective,
        // A sum of non-negative floats, each a proven bound for its block (module docs of
        // `fusion::bracket`: per-block bounds add up), rounded down.
        lower_bound: super::verify::down(lower, 2 * blocks.len() + 2),
        worst_sample_margin,
        blocks,
    })
}

/// One block's working-set solve.
struct BlockSolution {
    fused: Fused,
    status: SdpStatus,
    iterations: u32,
    rounds: usize,
    lmis: usize,
    dual_objective: f64,
    lower_bound: f64,
}

/// The working-set loop on one block, at unit scale (`fusion::scale`): a block whose largest
/// diagonal entry is outside `[2⁻⁴, 2⁴]` has its covariances and samples multiplied by the
/// power of two that brings that entry into `[1, 2)`, so the solver's absolute tolerances and the LMIs' identity blocks
/// meet data of order one whatever the units. `P̄` is mapped back (rounded: the sampled
/// optimum is not a proof). The proven lower bound is proven for the scaled block, which is
/// exactly the scale times the block as given (`Pow2::scaled_problem` checks it), and mapped
/// back rounded down: the robust optimum scales with the covariances.
#[allow(non_snake_case)]
fn solve_block(
    problem: &FusionProblem,
    cross: &[DMatrix<f64>],
    settings: &SdpSettings,
    deadline: &Deadline,
) -> Result<BlockSolution, SolveError> {
    let (scaled, scale) = Pow2::normalising(problem).scaled_problem(problem);
    let scaled_cross = scale.scale_all(cross);
    let factors: Vec<DMatrix<f64>> = scaled_cross
        .iter()
        .map(|p| difference_factor(&scaled, p))
        .collect();
    let n_all = factors.len();
    let mut active: Vec<usize> = if settings.working_set {
        (0..n_all.min(settings.initial_working_set)).collect()
    } else {
        (0..n_all).collect()
    };
    let mut iterations = 0;
    let mut rounds = 0;
    loop {
        rounds += 1;
        deadline.check("the sampled SDP")?;
        let solved = solve_lmis(&scaled, &factors, &active, settings, deadline)?;
        iterations += solved.iterations;
        // Check every sample outside the working set.
        let viol_tol = 10.0 * settings.tolerance * solved.fused.P.amax().max(1.0);
        let mut in_set = vec![false; n_all];
        for &i in &active {
            in_set[i] = true;
        }
        let mut violated: Vec<(f64, usize)> = (0..n_all)
            .filter(|&i| !in_set[i])
            .map(|i| (margin(&scaled, &solved.fused, &scaled_cross[i]), i))
            .filter(|(m, _)| *m < -viol_tol)
            .collect();
        if violated.is_empty() {
            let used: Vec<&DMatrix<f64>> = active.iter().map(|&i| &scaled_cross[i]).collect();
            let Solved {
                fused,
                status,
                iterations: _,
                dual_objective,
                duals,
            } = solved;
            return Ok(BlockSolution {
                fused: Fused {
                    P: scale.unscale(&fused.P),
                    ..fused
                },
                status,
                iterations,
                rounds,
                lmis: active.len(),
                dual_objective: scale.unscale_value(dual_objective),
                lower_bound: scale.unscale_down(lower_bound(&scaled, &used, &duals)),
            });
        }
        if rounds >= settings.max_rounds {
            let worst = violated.iter().map(|v| v.0).fold(f64::INFINITY, f64::min);
            return Err(SolveError::WorkingSetStalled {
                rounds,
                violated: violated.len(),
                worst: scale.unscale_value(worst),
            });
        }
        violated.sort_by(|a, b| a.0.total_cmp(&b.0));
        active.extend(violated.iter().take(settings.batch).map(|v| v.1));
        active.sort_unstable();
    }
}

/// The lower-triangular factor `L` of `Z = Cov(d, e_b)` (see the module docs) for the joint
/// covariance `P'`: Cholesky, or for numerically singular samples `V diag(√λ)` made
/// lower-triangular by an LQ step (`F = L Q`).
#[allow(non_snake_case)]
fn difference_factor(problem: &FusionProblem, P_ab: &DMatrix<f64>) -> DMatrix<f64> {
    let n = problem.dim();
    let P_ba = P_ab.transpose();
    let S = &problem.P_a + &problem.P_b - P_ab - &P_ba;
    let C = &P_ba - &problem.P_b;
    let mut Z = DMatrix::zeros(2 * n, 2 * n);
    Z.view_mut((0, 0), (n, n)).copy_from(&S);
    Z.view_mut((n, 0), (n, n)).copy_from(&C);
    Z.view_mut((0, n), (n, n)).copy_from(&C.transpose());
    Z.view_mut((n, n), (n, n)).copy_from(&problem.P_b);
    let Z = symmetrize(&Z);
    if let Some(c) = cholesky_of(Z.clone()) {
        return c.l();
    }
    let eig = SymmetricEigen::new(Z);
    let roots = eig.eigenvalues.map(|l| l.max(0.0).sqrt());
    let F = eig.eigenvectors * DMatrix::from_diagonal(&roots);
    // F = L Q  ⇔  Fᵀ = Qᵀ Lᵀ: the R of the QR of Fᵀ is Lᵀ.
    F.transpose().qr().r().transpose()
}

struct Solved {
    fused: Fused,
    status: SdpStatus,
    iterations: u32,
    dual_objective: f64,
    /// The dual matrix of each LMI's `P̄` block (`Λ_i`, `Σ Λ_i ≈ I`), in `active` order.
    duals: Vec<DMatrix<f64>>,
}

#[allow(non_snake_case)]
fn solve_lmis(
    problem: &FusionProblem,
    factors: &[DMatrix<f64>],
    active: &[usize],
    settings: &SdpSettings,
    deadline: &Deadline,
) -> Result<Solved, SolveError> {
    let n = problem.dim();
    let ka = |r: usize, k: usize| r + k * n;
    let pbar = |i: usize, j: usize| n * n + svec_index(i.min(j), i.max(j));
    let n_vars = n * n + n * (n + 1) / 2;
    let m = 2 * n;
    let cone_len = m * (m + 1) / 2;
    let sqrt2 = std::f64::consts::SQRT_2;

    let mut rows = Vec::new();
    let mut cols = Vec::new();
    let mut vals = Vec::new();
    let mut b = vec![0.0; cone_len * active.len()];
    for (slot, &i) in active.iter().enumerate() {
        let L = &factors[i];
        let L11 = L.view((0, 0), (n, n));
        let L21 = L.view((n, 0), (n, n));
        let L22 = L.view((n, n), (n, n));
        let P_star = L22 * L22.transpose();
        let offset = slot * cone_len;
        // P̄ − L₂₂L₂₂ᵀ block
        for c in 0..n {
            for r in 0..=c {
                let scale = if r == c { 1.0 } else { sqrt2 };
                let e = offset + svec_index(r, c);
                rows.push(e);
                cols.push(pbar(r, c));
                vals.push(-scale);
                b[e] = -scale * P_star[(r, c)];
            }
        }
        // K_a L₁₁ + L₂₁ block: rows r < n, columns n + q
        for q in 0..n {
            let c = n + q;
            for r in 0..n {
                let e = offset + svec_index(r, c);
                b[e] = sqrt2 * L21[(r, q)];
                for k in 0..n {
                    let d = L11[(k, q)];
                    if d != 0.0 {
                        rows.push(e);
                        cols.push(ka(r, k));
                        vals.push(-sqrt2 * d);
                    }
                }
            }
            // identity block
            b[offset + svec_index(c, c)] = 1.0;
        }
    }
    let A = CscMatrix::new_from_triplets(cone_len * active.len(), n_vars, rows, cols, vals);
    let P = CscMatrix::zeros((n_vars, n_vars));
    let mut q = vec![0.0; n_vars];
    for i in 0..n {
        q[pbar(i, i)] = 1.0;
    }
    let cones: Vec<SupportedConeT<f64>> = active
        .iter()
        .map(|_| SupportedConeT::PSDTriangleConeT(m))
        .collect();
    let (solver, status) = solve_program(
        &P,
        &q,
        &A,
        &b,
        &cones,
        Kkt::Platform,
        (settings.max_iter, settings.tolerance),
        deadline,
        "the sampled SDP",
    )?;
    let sol = &solver.solution;
    let K_a = DMatrix::from_fn(n, n, |r, k| sol.x[ka(r, k)]);
    let K_b = DMatrix::identity(n, n) - &K_a;
    let P_bar = DMatrix::from_fn(n, n, |i, j| sol.x[pbar(i, j)]);
    let x = &K_a * &problem.x_a + &K_b * &problem.x_b;
    // Clarabel's z in svec form: off-diagonal entries scaled by √2.
    let duals = (0..active.len())
        .map(|slot| {
            let offset = slot * cone_len;
            DMatrix::from_fn(n, n, |r, c| {
                let z = sol.z[offset + svec_index(r.min(c), r.max(c))];
                if r == c {
                    z
                } else {
                    z / sqrt2
                }
            })
        })
        .collect();
    Ok(Solved {
        fused: Fused {
            x,
            P: P_bar,
            K_a,
            K_b,
        },
        status,
        iterations: sol.iterations,
        dual_objective: sol.obj_val_dual,
        duals,
    })
}
