//! A bound *proven* to dominate `K P' Kᵀ` over the whole admissible set: the certified upper
//! bound of issue 5, tighter than nmCI where the pattern of `P_ab` is not separable.
//!
//! ## The certificate
//! Let `K = [K_a, K_b]` (`n × 2n`), `J₀ = blkdiag(P_a, P_b)` and let `J` be any admissible
//! joint covariance: `J ⪰ 0`, diagonal blocks `P_a`, `P_b`, cross block `X = P_ab` zero on the
//! known-zero set `I`. Take a symmetric matrix `C` of size `2n² × 2n²`, partitioned into
//! `n × n` blocks `C_kl ∈ ℝ^{2n×2n}`, and let `w ∈ ℝ^{2n²}` stack the columns of `Kᵀ`
//! (`w_(k,p) = K_{kp}`). Suppose
//!
//! 1. `C ⪰ w wᵀ`, and
//! 2. `C[(k,i),(l,n+j)] + C[(l,i),(k,n+j)] = 0` for all `k, l` wherever `(i, j)` is **not**
//!    in `I` (where `P_ab` may be non-zero),
//!
//! indexing `C` by `(k, p)`, `k < n`, `p < 2n`. For `v ∈ ℝⁿ` put
//! `Y(v) = (v ⊗ I₂ₙ)ᵀ C (v ⊗ I₂ₙ) = Σ_kl v_k v_l C_kl`; condition 2 says exactly that the
//! cross block of `Y(v)` vanishes off `I`, for every `v`. Since
//! `(v ⊗ I₂ₙ)ᵀ w = Kᵀ v`, condition 1 gives `Y(v) ⪰ Kᵀ v vᵀ K`, and with `J ⪰ 0`
//!
//! `vᵀ K J Kᵀ v = ⟨J, Kᵀ v vᵀ K⟩ ≤ ⟨J, Y(v)⟩ = ⟨J₀, Y(v)⟩ = vᵀ Q v`,
//!
//! where the middle equality is condition 2 (`Y(v)`'s cross block vanishes wherever `X` can
//! be non-zero, and `X` vanishes on `I`) and `Q_kl = ⟨J₀, C_kl⟩`. As `v` is arbitrary,
//! **`Q ⪰ K J Kᵀ` for every admissible `J`**: `(K, Q)` is a conservative fusion rule, whatever
//! solver produced `C`. (This is weak SDP duality of the inner problem `max_J ⟨J, KᵀvvᵀK⟩`,
//! with a dual certificate `Y(v)` quadratic in `v`; `C ⪰ wwᵀ` is a sum-of-squares proof that
//! the biquadratic form `uᵀ(Y(v) − Kᵀ v vᵀ K)u` is nonnegative — a relaxation: a tighter
//! certificate may exist where this family has none.)
//!
//! CI with weight `ω` and its gain is the certificate `C = ω⁻¹ w_a w_aᵀ + (1−ω)⁻¹ w_b w_bᵀ`
//! (`w_a`, `w_b`: `w` with its `b`-, resp. `a`-entries zeroed; `C − wwᵀ ⪰ 0` because
//! `(ω⁻¹ − 1)((1−ω)⁻¹ − 1) = 1`), giving `Q = ω⁻¹K_aP_aK_aᵀ + (1−ω)⁻¹K_bP_bK_bᵀ`; nmCI is the
//! block-wise one. So the best certificate is never looser than either; with a fully unknown
//! `P_ab` it equals CI (optimal there), on separable patterns nmCI (the paper's theorem).
//!
//! ## The program
//! `min tr Q = Σ_k ⟨J₀, C_kk⟩` over `C` and, for [`certified_fusion`], the gain `K_a`
//! (`K_b = I − K_a`), subject to condition 2 (equalities) and `[[C, w], [wᵀ, 1]] ⪰ 0`
//! (condition 1 by a Schur complement, linear in `K`): one PSD cone of size `2n² + 1`
//! (Clarabel). [`certify_gain`] keeps `K` fixed — e.g. the sampled
//! SDP's — and gives the tightest certified `P̄` for that gain.
//!
//! ## Exact in floating point, whatever the solver's accuracy
//! The solver's `C` satisfies both conditions only to its tolerance. After the solve, each
//! pair `(a, b)` of condition 2 is replaced by `((a − b)/2, (b − a)/2)`, whose sum is exactly
//! zero in floating point; then `μ = λ_min(C − wwᵀ)` is computed and `C` is replaced by
//! `C + δ I` with `δ = max(0, −μ) + 10⁻¹² ‖C‖_F` (the second term covers the rounding of the
//! eigenvalue and of `Q`); `δ I` has no cross part, so condition 2 still holds, and `Q` grows
//! by `δ tr(J₀) I`. So the reported bound rests on one eigenvalue computation, not on the
//! solver; `repair` reports how much trace this added.
//!
//! When `P_a`, `P_b` and the pattern split the state into independent blocks, each block is
//! certified on its own (the joint covariance is block diagonal, so a block-diagonal gain's
//! `K J Kᵀ` is too). The cone grows as `2n²` per block: blocks above
//! [`CertifySettings::max_block_dim`] states are refused with a typed error.

use clarabel::algebra::CscMatrix;
use clarabel::solver::{DefaultSettings, SolverStatus, SupportedConeT};
use nalgebra::{DMatrix, SymmetricEigen};

use super::sdp::{solve_program, svec_index, SdpStatus};
use super::{scatter_block, Fused, FusionProblem};
use crate::error::SolveError;
use crate::linalg::symmetrize;
use crate::structure::independent_blocks;

/// Settings of the certified bound, with defaults and [`CertifySettings::validate`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CertifySettings {
    /// Interior-point iteration limit (default 200).
    pub max_iter: u32,
    /// Clarabel's gap and feasibility tolerances (default `1e-9`; they affect how tight the
    /// bound is, never whether it is certified).
    pub tolerance: f64,
    /// Largest independent block certified (default 6: one cone of size 73, 6–9 s natively).
    pub max_block_dim: usize,
}

impl Default for CertifySettings {
    fn default() -> Self {
        Self {
            max_iter: 200,
            tolerance: 1e-9,
            max_block_dim: 6,
        }
    }
}

impl CertifySettings {
    /// Checks every value.
    pub fn validate(&self) -> Result<(), SolveError> {
        if self.max_iter == 0 || self.max_block_dim == 0 {
            return Err(SolveError::InvalidSettings(
                "max_iter and max_block_dim must be at least 1".into(),
            ));
        }
        if !(self.tolerance > 0.0 && self.tolerance < 1.0) {
            return Err(SolveError::InvalidSettings(format!(
                "tolerance must be in (0, 1) (got {})",
                self.tolerance
            )));
        }
        Ok(())
    }
}

/// A certified conservative bound (see the module docs).
#[derive(Debug, Clone, PartialEq)]
pub struct CertifiedResult {
    /// Fused estimate, the certified bound `P̄ = Q` and the gains.
    pub fused: Fused,
    /// How the (last) solve ended; `AlmostSolved` if any block's did.
    pub status: SdpStatus,
    /// Interior-point iterations, summed over blocks.
    pub iterations: u32,
    /// Trace added by the floating-point repair `C ← C + δ I` (≥ 0, summed over blocks).
    pub repair: f64,
    /// The independent blocks certified separately.
    pub blocks: Vec<Vec<usize>>,
}

/// The tightest certified bound over gain and certificate: a conservative fusion rule never
/// looser than CI or nmCI.
///
/// ```
/// use nalgebra::{DMatrix, DVector};
/// use nmci::*;
/// let d = |v: &[f64]| DMatrix::from_diagonal(&DVector::from_row_slice(v));
/// let p = FusionProblem::from_covariances(d(&[3.0, 1.0]), d(&[1.0, 4.0]),
///     CrossPattern::diagonal(2)).unwrap();
/// let cert = certified_fusion(&p, &CertifySettings::default()).unwrap();
/// assert!((cert.fused.trace() - 2.0).abs() < 1e-6); // nmCI's diag(1, 1), proven
/// ```
pub fn certified_fusion(
    problem: &FusionProblem,
    settings: &CertifySettings,
) -> Result<CertifiedResult, SolveError> {
    certify(problem, None, settings)
}

/// The tightest certified bound for a given gain `K_a` (`K_b = I − K_a`), e.g. the sampled
/// SDP's: `P̄` with `P̄ ⪰ K P' Kᵀ` proven for every admissible `P'`.
///
/// ```
/// use nalgebra::{DMatrix, DVector};
/// use nmci::*;
/// let d = |v: &[f64]| DMatrix::from_diagonal(&DVector::from_row_slice(v));
/// let p = FusionProblem::from_covariances(d(&[3.0, 1.0]), d(&[1.0, 4.0]),
///     CrossPattern::diagonal(2)).unwrap();
/// // The gain of nmCI with ω = [0, 1]: x_b's first state, x_a's second.
/// let cert = certify_gain(&p, &d(&[0.0, 1.0]), &CertifySettings::default()).unwrap();
/// assert!((&cert.fused.P - d(&[1.0, 1.0])).amax() < 1e-6);
/// ```
#[allow(non_snake_case)]
pub fn certify_gain(
    problem: &FusionProblem,
    K_a: &DMatrix<f64>,
    settings: &CertifySettings,
) -> Result<CertifiedResult, SolveError> {
    let n = problem.dim();
    if K_a.nrows() != n || K_a.ncols() != n || K_a.iter().any(|k| !k.is_finite()) {
        return Err(SolveError::InvalidSettings(format!(
            "the gain must be a finite {n}×{n} matrix (got {}×{})",
            K_a.nrows(),
            K_a.ncols()
        )));
    }
    certify(problem, Some(K_a), settings)
}

/// The blocks a certificate is computed on: the independent blocks, or the whole state when
/// a given gain mixes them.
#[allow(non_snake_case)]
pub(crate) fn certification_blocks(
    problem: &FusionProblem,
    gain: Option<&DMatrix<f64>>,
) -> Vec<Vec<usize>> {
    let n = problem.dim();
    let blocks = independent_blocks(&problem.P_a, &problem.P_b, &problem.cross_pattern);
    if let Some(K_a) = gain {
        let mut block_of = vec![0; n];
        for (b, block) in blocks.iter().enumerate() {
            for &i in block {
                block_of[i] = b;
            }
        }
        let mixes =
            (0..n).any(|i| (0..n).any(|j| block_of[i] != block_of[j] && K_a[(i, j)] != 0.0));
        if mixes {
            return vec![(0..n).collect()];
        }
    }
    blocks
}

#[allow(non_snake_case)]
fn certify(
    problem: &FusionProblem,
    gain: Option<&DMatrix<f64>>,
    settings: &CertifySettings,
) -> Result<CertifiedResult, SolveError> {
    settings.validate()?;
    let n = problem.dim();
    let blocks = certification_blocks(problem, gain);
    let mut K_a = DMatrix::zeros(n, n);
    let mut P = DMatrix::zeros(n, n);
    let (mut status, mut iterations, mut repair) = (SdpStatus::Solved, 0, 0.0);
    for block in &blocks {
        if block.len() > settings.max_block_dim {
            return Err(SolveError::BlockTooLarge {
                dim: block.len(),
                limit: settings.max_block_dim,
            });
        }
        let sub = problem.restrict(block);
        let sub_gain = gain
            .map(|K| DMatrix::from_fn(block.len(), block.len(), |i, j| K[(block[i], block[j])]));
        let solved = certify_block(&sub, sub_gain.as_ref(), settings)?;
        if solved.status == SdpStatus::AlmostSolved {
            status = SdpStatus::AlmostSolved;
        }
        iterations += solved.iterations;
        repair += solved.repair;
        scatter_block(&mut K_a, block, &solved.K_a);
        scatter_block(&mut P, block, &solved.P);
    }
    let K_b = DMatrix::identity(n, n) - &K_a;
    let x = &K_a * &problem.x_a + &K_b * &problem.x_b;
    Ok(CertifiedResult {
        fused: Fused { x, P, K_a, K_b },
        status,
        iterations,
        repair,
        blocks,
    })
}

#[allow(non_snake_case)]
struct BlockCertificate {
    K_a: DMatrix<f64>,
    P: DMatrix<f64>,
    status: SdpStatus,
    iterations: u32,
    repair: f64,
}

#[allow(non_snake_case)]
fn certify_block(
    problem: &FusionProblem,
    gain: Option<&DMatrix<f64>>,
    settings: &CertifySettings,
) -> Result<BlockCertificate, SolveError> {
    let n = problem.dim();
    let m = 2 * n; // rows of Kᵀ
    let N = n * m; // size of C; index (k, p) ↦ k·m + p
    let J0 = |p: usize, q: usize| match (p < n, q < n) {
        (true, true) => problem.P_a[(p, q)],
        (false, false) => problem.P_b[(p - n, q - n)],
        _ => 0.0,
    };
    // Condition 2: Y(v)'s cross entry (i, n+j) vanishes for every v where P_ab may be
    // non-zero: C[(k,i),(l,n+j)] + C[(l,i),(k,n+j)] = 0 for all k ≤ l (module docs).
    let var = |r: usize, c: usize| svec_index(r.min(c), r.max(c));
    let mut pairs: Vec<(usize, usize)> = Vec::new();
    for k in 0..n {
        for l in k..n {
            for i in 0..n {
                for j in 0..n {
                    if problem.cross_pattern.is_unknown(i, j) {
                        pairs.push((var(k * m + i, l * m + n + j), var(l * m + i, k * m + n + j)));
                    }
                }
            }
        }
    }
    let n_vars = N * (N + 1) / 2; // C's upper triangle, in svec order
    let gain_var = |k: usize, i: usize| n_vars + k + i * n; // K_a[(k, i)]
    let total_vars = n_vars + if gain.is_none() { n * n } else { 0 };
    let sqrt2 = std::f64::consts::SQRT_2;
    let cone = N + 1;
    let zeros = pairs.len();
    let mut b = vec![0.0; zeros + cone * (cone + 1) / 2];
    let (mut rows, mut cols, mut vals) = (Vec::new(), Vec::new(), Vec::new());
    for (e, &(u, v)) in pairs.iter().enumerate() {
        if u == v {
            // k = l: the entry itself, 2·C = 0 (one triplet: no duplicate entries)
            rows.push(e);
            cols.push(u);
            vals.push(2.0);
        } else {
            rows.extend([e, e]);
            cols.extend([u, v]);
            vals.extend([1.0, 1.0]);
        }
    }
    let mut q = vec![0.0; total_vars];
    for c in 0..N {
        for r in 0..=c {
            let v = svec_index(r, c);
            let scale = if r == c { 1.0 } else { sqrt2 };
            rows.push(zeros + svec_index(r, c));
            cols.push(v);
            vals.push(-scale);
            if r / m == c / m {
                let weight = J0(r % m, c % m);
                q[v] = if r == c { weight } else { 2.0 * weight };
            }
        }
    }
    // The border w: w_(k,p) = K_a[k, p] (p < n), δ_{k, p−n} − K_a[k, p−n] (p ≥ n).
    for r in 0..N {
        let (k, p) = (r / m, r % m);
        let e = zeros + svec_index(r, N);
        let (constant, coefficient, column) = if p < n {
            (0.0, 1.0, p)
        } else {
            (if k == p - n { 1.0 } else { 0.0 }, -1.0, p - n)
        };
        match gain {
            Some(K_a) => b[e] = sqrt2 * (constant + coefficient * K_a[(k, column)]),
            None => {
                b[e] = sqrt2 * constant;
                rows.push(e);
                cols.push(gain_var(k, column));
                vals.push(-sqrt2 * coefficient);
            }
        }
    }
    b[zeros + svec_index(N, N)] = 1.0;
    let A = CscMatrix::new_from_triplets(b.len(), total_vars, rows, cols, vals);
    let P_quad = CscMatrix::zeros((total_vars, total_vars));
    let mut cones = Vec::with_capacity(2);
    if zeros > 0 {
        cones.push(SupportedConeT::ZeroConeT(zeros));
    }
    cones.push(SupportedConeT::PSDTriangleConeT(cone));
    let clarabel_settings = DefaultSettings {
        verbose: false,
        max_threads: 1,
        max_iter: settings.max_iter,
        tol_gap_abs: settings.tolerance,
        tol_gap_rel: settings.tolerance,
        tol_feas: settings.tolerance,
        ..DefaultSettings::default()
    };
    let solver = solve_program(&P_quad, &q, &A, &b, &cones, clarabel_settings)?;
    let sol = &solver.solution;
    let status = match sol.status {
        SolverStatus::Solved => SdpStatus::Solved,
        SolverStatus::AlmostSolved => SdpStatus::AlmostSolved,
        other => {
            return Err(SolveError::SolverFailed {
                status: format!("{other:?}"),
                iterations: sol.iterations,
            })
        }
    };
    let K_a = match gain {
        Some(K_a) => K_a.clone(),
        None => DMatrix::from_fn(n, n, |k, i| sol.x[gain_var(k, i)]),
    };
    let mut svec_C = sol.x[..n_vars].to_vec();
    // Condition 2 exactly: each pair (a, b) becomes ((a − b)/2, (b − a)/2), whose sum is 0
    // in floating point (fl(b − a) = −fl(a − b), halving is exact).
    for &(u, v) in &pairs {
        let half = 0.5 * (svec_C[u] - svec_C[v]);
        svec_C[u] = half;
        svec_C[v] = -half; // u = v: half = 0
    }
    let C = DMatrix::from_fn(N, N, |r, c| svec_C[var(r, c)]);
    let w = nalgebra::DVector::from_fn(N, |r, _| {
        let (k, p) = (r / m, r % m);
        if p < n {
            K_a[(k, p)]
        } else {
            (if k == p - n { 1.0 } else { 0.0 }) - K_a[(k, p - n)]
        }
    });
    // Repair: C ← C + δI with C − wwᵀ ⪰ 0 beyond rounding (module docs).
    let mut R = C.clone();
    R.ger(-1.0, &w, &w, 1.0);
    let mu = SymmetricEigen::new(R).eigenvalues.min();
    let delta = (-mu).max(0.0) + 1e-12 * C.norm();
    let trace_J0 = problem.P_a.trace() + problem.P_b.trace();
    let Q = DMatrix::from_fn(n, n, |k, l| {
        let mut s = 0.0;
        for p in 0..m {
            for qq in 0..m {
                s += J0(p, qq) * C[(k * m + p, l * m + qq)];
            }
        }
        s + if k == l { delta * trace_J0 } else { 0.0 }
    });
    Ok(BlockCertificate {
        K_a,
        P: symmetrize(&Q),
        status,
        iterations: sol.iterations,
        repair: n as f64 * delta * trace_J0,
    })
}
