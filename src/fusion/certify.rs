//! A bound *proven* to dominate `K P' Kᵀ` over the whole admissible set, by a hierarchy of
//! sum-of-squares certificates: the certified rule.
//!
//! ## The certificate of level `r`
//! Let `K = [K_a, K_b]` (`n × 2n`, `K_b = I − K_a`), `J₀ = blkdiag(P_a, P_b)`, and let `J` be
//! any admissible joint covariance: `J ⪰ 0`, diagonal blocks `P_a`, `P_b`, cross block
//! `P_ab` zero on the known-zero set `I`. For `r ≥ 1` let `m_r(v)` be the vector of the
//! `s = C(n + r − 1, r)` monomials `v^α` of degree `r` in `v ∈ ℝⁿ`, and `c_β = (r−1)!/β!`
//! the multinomial coefficients of `‖v‖^{2(r−1)} = Σ_{|β| = r−1} c_β v^{2β}`. Take
//!
//! - a symmetric `C` of size `2n·s`, in `2n × 2n` blocks `C_{αβ}`, and
//!   `Z(v) = (m_r(v) ⊗ I₂ₙ)ᵀ C (m_r(v) ⊗ I₂ₙ) = Σ_{α,β} v^α v^β C_{αβ}` (a matrix form of
//!   degree `2r`),
//! - a symmetric `Q` (`n × n`) and a symmetric `G` (`s × s`),
//!
//! such that
//!
//! 1. `C ⪰ Σ_β c_β w_β w_βᵀ`, where `w_β[(α, p)] = K[k, p]` if `α = β + e_k`, else 0
//!    (so `(m_r ⊗ I)ᵀ w_β = v^β Kᵀ v` and condition 1 gives
//!    `Z(v) ⪰ ‖v‖^{2(r−1)} Kᵀ v vᵀ K`);
//! 2. the cross entries of `Z(v)` vanish where `P_ab` may be non-zero: for every monomial
//!    `γ` of degree `2r` and every unknown `(i, j)`, `Σ_{α+β=γ} C[(α,i),(β,n+j)] = 0`;
//! 3. `‖v‖^{2(r−1)} vᵀ Q v − ⟨J₀, Z(v)⟩ = m_r(v)ᵀ G m_r(v)` (equal coefficients), and
//! 4. `G ⪰ 0`.
//!
//! Then for every admissible `J` and every `v ≠ 0`
//!
//! `‖v‖^{2(r−1)} vᵀ K J Kᵀ v = ⟨J, ‖v‖^{2(r−1)} Kᵀ v vᵀ K⟩ ≤ ⟨J, Z(v)⟩ = ⟨J₀, Z(v)⟩ ≤ ‖v‖^{2(r−1)} vᵀ Q v`
//!
//! (1 and `J ⪰ 0`; 2, since `J − J₀` lives on the unknown cross entries; 3 and 4), so
//! **`Q ⪰ K J Kᵀ` for every admissible `J`**: `(K, Q)` is a conservative fusion rule,
//! whoever produced `C`, `Q` and `G`. This is weak duality of the inner problem
//! `max_J ⟨J, Kᵀ v vᵀ K⟩` with a dual certificate polynomial in `v`, and conditions 1 and 4
//! are sum-of-squares proofs (the Positivstellensatz with the multiplier `‖v‖^{2(r−1)}`,
//! as in Reznick's and Parrilo's hierarchies): a relaxation at every level. Multiplying a
//! level-`r` certificate by `‖v‖²` gives one of level `r + 1`, so the bound never grows
//! with the level (up to solver tolerance) and may fall.
//!
//! Level 1 is the quadratic certificate (`Z(v) = Σ_kl v_k v_l C_kl`, `G = Q − (⟨J₀, C_kl⟩)`).
//! CI with weight `ω` and its gain is the level-1 certificate
//! `C = ω⁻¹ w_a w_aᵀ + (1−ω)⁻¹ w_b w_bᵀ` (`w_a`, `w_b`: `w` with its `b`-, resp.
//! `a`-entries zeroed; `C − wwᵀ ⪰ 0` because `(ω⁻¹ − 1)((1−ω)⁻¹ − 1) = 1`); nmCI is the
//! block-wise one, so the program's optimum is never above CI's or nmCI's trace (and the
//! reported bound is not either beyond rounding, see below). This is a statement about
//! traces, not the Loewner order: the certified `P̄` may be larger than CI's along some
//! direction (tested). Where `P_ab` is fully unknown CI is the robust optimum (Reinhardt,
//! Noack, Arambel, Hanebeck, "Minimum covariance bounds for the fusion under unknown
//! correlations", IEEE SPL 22(9), 2015), and so is nmCI where every independent block has a
//! fully unknown cross block (the per-block problems are then such CI problems); there the
//! certified bound equals them up to rounding (it is proven, so it cannot be below the
//! optimum). On other patterns it is tighter on many problems and equal where CI or nmCI
//! already is the robust optimum.
//!
//! ## The program
//! `min tr Q` over `C`, `Q`, `G` and, for [`certified_fusion`], the gain `K_a`, subject to
//! 2 and 3 (equalities), 4 (a PSD cone of size `s`) and 1 as `[[C, W D^{1/2}], [·, I]] ⪰ 0`
//! (Schur complement, linear in `K`; `W = [w_β]`, `D = diag(c_β)`): one PSD cone of size
//! `2n·s + C(n + r − 2, r − 1)` (Clarabel). [`certify_gain`] keeps `K` fixed — e.g. the
//! sampled SDP's — and gives the tightest bound of the level for that gain.
//!
//! ## Exact in floating point, whatever the solver's accuracy
//! The solver's point satisfies 1–4 only to its tolerance. The reported bound is made to
//! satisfy them exactly, for the reported floats `K_a`, `P̄ = Q` and `K_b = I − K_a` taken
//! exactly (the stored `K_b` is that difference rounded), by three steps whose arithmetic is
//! accounted for in `fusion::verify`:
//!
//! - **Condition 2 exactly.** Each group of entries that must sum to zero is rounded to a
//!   grid `g = 2^{e−b}` (`2^e` bounds the group, `b` leaves room for the group's length
//!   within 53 bits), and its last entry is set to minus the sum of the others: sums of
//!   grid multiples below `2⁵³ g` are exact in floating point, so the group sums to exactly 0.
//! - **Condition 1 proven.** `C ← C + δ I` (no cross entries: condition 2 still holds) with
//!   `δ` the smallest of a doubling sequence for which `fusion::verify::is_psd` proves
//!   `C − W D Wᵀ ⪰ 0`, every rounding of forming it (including `K_b = I − K_a`) in the radius.
//! - **Conditions 3–4 proven.** With `C` fixed, the coefficients of
//!   `p(v) = ‖v‖^{2(r−1)} vᵀQv − ⟨J₀, Z(v)⟩ − m_rᵀ G m_r` are enclosed in balls and written
//!   as a Gram matrix `E` (each coefficient on one entry pair), so `p + m_rᵀGm_r = m_rᵀ(G + E)m_r`
//!   exactly; `Q ← Q + η I` (which adds `η (r!/α!) ≥ η` to the diagonal of `G + E`) with the
//!   smallest `η` of a doubling sequence for which `G + E ⪰ 0` is proven.
//!
//! So the proof of `P̄ ⪰ K J Kᵀ` rests on the floating-point model of `fusion::verify`
//! (IEEE binary64, round to nearest, no overflow), not on the solver. `repair` reports the
//! trace these steps added to the solver's `tr Q`.
//!
//! ## Never looser than CI in trace
//! CI's certificate is in every level's family, but the solver finds the optimum only to its
//! tolerance, and at high levels it can end `AlmostSolved` a little above CI where CI is
//! optimal. So each block also evaluates CI's bound `ω⁻¹ K_a P_a K_aᵀ + (1−ω)⁻¹ K_b P_b K_bᵀ`
//! (for the block's CI gain; for a given gain, with its best `ω`) in exact arithmetic
//! (`fusion::bracket`), rounded up to a dominating float matrix, and keeps it where its
//! proven trace is smaller (`ci_blocks`). On independent blocks this is nmCI. Hence the
//! certified trace is **never above nmCI's or CI's beyond rounding** (relative `10⁻¹⁴`,
//! tested), whatever the solver's tolerance.
//!
//! When `P_a`, `P_b` and the pattern split the state into independent blocks, each block is
//! certified on its own (the joint covariance is block diagonal, so a block-diagonal gain's
//! `K J Kᵀ` is too). Blocks above [`CertifySettings::max_block_dim`] states, or whose cone
//! would exceed [`CertifySettings::max_cone`], are refused with a typed error.

use std::collections::{BTreeMap, HashMap};

use clarabel::algebra::CscMatrix;
use clarabel::solver::SupportedConeT;
use nalgebra::DMatrix;

use super::bracket::{trace_upper_bound, young_bound, young_omega};
use super::ci::covariance_intersection;
use super::sdp::{solve_program, svec_index, Deadline, Kkt, SdpStatus};
use super::verify::{is_psd, psd_shift, up, Ball, BallMatrix, Dot, U};
use super::{scatter_block, Criterion, Fused, FusionProblem};
use crate::error::SolveError;
use crate::structure::independent_blocks;

/// The default of [`CertifySettings::max_block_dim`], and the certified rule's block limit in
/// the request contract ([`crate::RULES`]).
pub const MAX_BLOCK_DIM: usize = 6;

/// Settings of the certified bound, with defaults and [`CertifySettings::validate`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CertifySettings {
    /// Interior-point iteration limit (default 200).
    pub max_iter: u32,
    /// Clarabel's gap and feasibility tolerances (default `1e-10`: the repair then adds
    /// `~1e-9` relative instead of `~1e-7` at `1e-9`; they affect how tight the bound is,
    /// never whether it is proven).
    pub tolerance: f64,
    /// Largest independent block certified (default 6).
    pub max_block_dim: usize,
    /// The certificate's level `r ≥ 1` (module docs); `None` (default) chooses per block:
    /// [`CertifySettings::auto_level`].
    pub level: Option<u32>,
    /// Largest PSD cone accepted (default 90 rows: the level-1 cone of a 6-state block is 73,
    /// level 3 of a 3-state block 66, level 2 of a 4-state block 84). The interior-point
    /// solver holds a dense block of `(m(m+1)/2)²` numbers for a cone of `m` rows: 134 MB at
    /// 90 rows, 1.7 GB at 170 (a level-3 4-state block, minutes per iteration).
    pub max_cone: usize,
    /// Wall-clock limit of each block's solve in seconds (default none); past it the solve
    /// ends with [`SolveError::TimeLimit`].
    pub time_limit: Option<f64>,
}

impl Default for CertifySettings {
    fn default() -> Self {
        Self {
            max_iter: 200,
            tolerance: 1e-10,
            max_block_dim: MAX_BLOCK_DIM,
            level: None,
            max_cone: 90,
            time_limit: None,
        }
    }
}

impl CertifySettings {
    /// Checks every value.
    pub fn validate(&self) -> Result<(), SolveError> {
        if self.max_iter == 0 || self.max_block_dim == 0 || self.max_cone == 0 {
            return Err(SolveError::InvalidSettings(
                "max_iter, max_block_dim and max_cone must be at least 1".into(),
            ));
        }
        if !(self.tolerance > 0.0 && self.tolerance < 1.0) {
            return Err(SolveError::InvalidSettings(format!(
                "tolerance must be in (0, 1) (got {})",
                self.tolerance
            )));
        }
        if let Some(level) = self.level {
            if !(1..=MAX_LEVEL).contains(&level) {
                return Err(SolveError::InvalidSettings(format!(
                    "level must be in 1..={MAX_LEVEL} (got {level})"
                )));
            }
        }
        check_time_limit(self.time_limit)
    }

    /// The level used for a block of `dim` states: the setting, or by default the level
    /// chosen from the measured gap-and-time curves (README, `examples/certify_levels.rs`):
    /// 5 for blocks of at most 2 states (level 4 left a few measured brackets open by up to
    /// `10⁻⁴`), 2 for 3 states (the highest level below a second), 1 above.
    pub fn level_for(&self, dim: usize) -> u32 {
        self.level.unwrap_or_else(|| Self::auto_level(dim))
    }

    /// The default level for a block of `dim` states (see [`CertifySettings::level_for`]).
    pub fn auto_level(dim: usize) -> u32 {
        match dim {
            0..=2 => 5,
            3 => 2,
            _ => 1,
        }
    }

    /// Rows of the level-`level` PSD cone for a block of `dim` states.
    pub fn cone_size(dim: usize, level: u32) -> usize {
        let r = level as usize;
        2 * dim * binomial(dim + r - 1, r) + binomial(dim + r - 2, r - 1)
    }
}

/// Highest certificate level accepted.
pub const MAX_LEVEL: u32 = 6;

/// Checks an optional wall-clock limit (positive and finite).
pub(crate) fn check_time_limit(limit: Option<f64>) -> Result<(), SolveError> {
    match limit {
        Some(t) if !(t > 0.0 && t.is_finite()) => Err(SolveError::InvalidSettings(format!(
            "time_limit must be a positive number of seconds (got {t})"
        ))),
        _ => Ok(()),
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
    /// Trace added by the floating-point repair (≥ 0, summed over blocks).
    pub repair: f64,
    /// The independent blocks certified separately.
    pub blocks: Vec<Vec<usize>>,
    /// The level used on each block: the requested one, or a lower one where the solver
    /// broke down numerically on it.
    pub levels: Vec<u32>,
    /// Per block: whether CI's proven bound (for the block's CI gain, or for the given gain
    /// with its best `ω`) was tighter than the solver's certificate and was taken instead —
    /// the solver can end looser than CI where CI is optimal (`AlmostSolved` at high levels),
    /// or fail at every level (then the block's `status` is `AlmostSolved`).
    pub ci_blocks: Vec<bool>,
}

/// The tightest certified bound over gain and certificate: a conservative fusion rule never
/// looser than CI or nmCI in trace (up to solver tolerance).
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
    for block in &blocks {
        if block.len() > settings.max_block_dim {
            return Err(SolveError::BlockTooLarge {
                dim: block.len(),
                limit: settings.max_block_dim,
            });
        }
        let level = settings.level_for(block.len());
        let cone = CertifySettings::cone_size(block.len(), level);
        if cone > settings.max_cone {
            return Err(SolveError::ConeTooLarge {
                dim: block.len(),
                level,
                cone,
                limit: settings.max_cone,
            });
        }
    }
    let mut K_a = DMatrix::zeros(n, n);
    let mut P = DMatrix::zeros(n, n);
    let (mut status, mut iterations, mut repair) = (SdpStatus::Solved, 0, 0.0);
    let mut levels = Vec::with_capacity(blocks.len());
    let mut ci_blocks = Vec::with_capacity(blocks.len());
    for block in &blocks {
        let sub = problem.restrict(block);
        let sub_gain = gain
            .map(|K| DMatrix::from_fn(block.len(), block.len(), |i, j| K[(block[i], block[j])]));
        // The requested level, or — where the solver breaks down numerically on it — the
        // highest lower level that solves; CI's proven bound when none does.
        let mut level = settings.level_for(block.len());
        let mut solved = loop {
            match certify_block(&sub, sub_gain.as_ref(), level, settings) {
                Ok(s) => break Some(s),
                Err(SolveError::SolverFailed { .. } | SolveError::NotProven { .. })
                    if level > 1 =>
                {
                    level -= 1
                }
                Err(SolveError::SolverFailed { .. } | SolveError::NotProven { .. }) => break None,
                Err(e) => return Err(e),
            }
        };
        // CI's bound (Young's inequality, proven in exact arithmetic) is a level-1
        // certificate: keep it where the solver's certificate ended looser (module docs).
        let (ci_gain, omega) = match &sub_gain {
            Some(K) => (K.clone(), young_omega(&sub.P_a, &sub.P_b, K)),
            None => {
                let ci = covariance_intersection(&sub, Criterion::Trace)?;
                (ci.fused.K_a, ci.omega)
            }
        };
        let mut ci_used = false;
        if let Some(bound) = young_bound(&sub.P_a, &sub.P_b, &ci_gain, omega) {
            let P_ci = bound.dominating();
            let looser = match &solved {
                Some(s) => trace_upper_bound(&P_ci) < trace_upper_bound(&s.P),
                None => true,
            };
            if looser {
                let s = solved.get_or_insert_with(|| BlockCertificate {
                    K_a: ci_gain.clone(),
                    P: P_ci.clone(),
                    status: SdpStatus::AlmostSolved,
                    iterations: 0,
                    repair: 0.0,
                });
                s.P = P_ci;
                s.K_a = ci_gain;
                ci_used = true;
            }
        }
        let solved = solved.ok_or_else(|| repair_failed("CI's bound"))?;
        ci_blocks.push(ci_used);
        if solved.status == SdpStatus::AlmostSolved {
            status = SdpStatus::AlmostSolved;
        }
        iterations += solved.iterations;
        repair += solved.repair;
        levels.push(level);
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
        levels,
        ci_blocks,
    })
}

fn binomial(n: usize, k: usize) -> usize {
    (0..k).fold(1, |acc, i| acc * (n - i) / (i + 1))
}

/// The exponent vectors of degree `d` in `n` variables (graded, lexicographic).
fn monomials(n: usize, d: usize) -> Vec<Vec<usize>> {
    fn rec(n: usize, d: usize, prefix: &mut Vec<usize>, out: &mut Vec<Vec<usize>>) {
        if prefix.len() == n - 1 {
            prefix.push(d);
            out.push(prefix.clone());
            prefix.pop();
            return;
        }
        for e in (0..=d).rev() {
            prefix.push(e);
            rec(n, d - e, prefix, out);
            prefix.pop();
        }
    }
    let mut out = Vec::new();
    rec(n, d, &mut Vec::with_capacity(n), &mut out);
    out
}

/// `d! / β!` for an exponent vector `β` of degree `d`.
fn multinomial(beta: &[usize]) -> f64 {
    let mut num = 1.0;
    let mut k = 0;
    for &b in beta {
        for i in 1..=b {
            k += 1;
            num = num * k as f64 / i as f64;
        }
    }
    num.round()
}

/// The index layout of one block's level-`r` program.
struct Layout {
    n: usize,
    /// Rows of `Kᵀ`: `2n`.
    m: usize,
    /// Degree-`r` monomials (`s` of them).
    mons: Vec<Vec<usize>>,
    /// Degree-`(r − 1)` monomials and their multinomial coefficients.
    lower: Vec<(Vec<usize>, f64)>,
    /// Degree-`2r` monomials, by exponent.
    products: HashMap<Vec<usize>, usize>,
    /// `α + β` as an index of `products`, for `α`, `β` indices of `mons`.
    sum: Vec<Vec<usize>>,
}

impl Layout {
    fn new(n: usize, r: usize) -> Self {
        let mons = monomials(n, r);
        let lower = monomials(n, r - 1)
            .into_iter()
            .map(|b| {
                let c = multinomial(&b);
                (b, c)
            })
            .collect();
        let products: HashMap<Vec<usize>, usize> = monomials(n, 2 * r)
            .into_iter()
            .enumerate()
            .map(|(i, g)| (g, i))
            .collect();
        let add =
            |a: &[usize], b: &[usize]| a.iter().zip(b).map(|(x, y)| x + y).collect::<Vec<_>>();
        let sum = mons
            .iter()
            .map(|a| mons.iter().map(|b| products[&add(a, b)]).collect())
            .collect();
        Self {
            n,
            m: 2 * n,
            mons,
            lower,
            products,
            sum,
        }
    }

    /// Size of `C`.
    fn big(&self) -> usize {
        self.m * self.mons.len()
    }

    /// The monomial index `k` with `α = β + e_k`, if any.
    fn step(&self, alpha: usize, beta: &[usize]) -> Option<usize> {
        let a = &self.mons[alpha];
        let mut k = None;
        for i in 0..self.n {
            match a[i] as isize - beta[i] as isize {
                0 => {}
                1 if k.is_none() => k = Some(i),
                _ => return None,
            }
        }
        k
    }

    /// Index in `products` of `2β + e_k + e_l`.
    fn quad(&self, beta: &[usize], k: usize, l: usize) -> usize {
        let mut g: Vec<usize> = beta.iter().map(|b| 2 * b).collect();
        g[k] += 1;
        g[l] += 1;
        self.products[&g]
    }
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
    level: u32,
    settings: &CertifySettings,
) -> Result<BlockCertificate, SolveError> {
    let n = problem.dim();
    let lay = Layout::new(n, level as usize);
    let (m, s, N) = (lay.m, lay.mons.len(), lay.big());
    let nb = lay.lower.len();
    let J0 = |p: usize, q: usize| match (p < n, q < n) {
        (true, true) => problem.P_a[(p, q)],
        (false, false) => problem.P_b[(p - n, q - n)],
        _ => 0.0,
    };
    // Variables: C (svec of N), Q (svec of n), G (svec of s), then K_a (n², when free).
    let var_c = |x: usize, y: usize| svec_index(x.min(y), x.max(y));
    let off_q = N * (N + 1) / 2;
    let var_q = |k: usize, l: usize| off_q + svec_index(k.min(l), k.max(l));
    let off_g = off_q + n * (n + 1) / 2;
    let var_g = |a: usize, b: usize| off_g + svec_index(a.min(b), a.max(b));
    let off_k = off_g + s * (s + 1) / 2;
    let var_k = |k: usize, i: usize| off_k + k + i * n;
    let total_vars = off_k + if gain.is_none() { n * n } else { 0 };

    // Condition 2: one group of C entries per (γ, unknown (i, j)) that must sum to zero.
    let mut groups: BTreeMap<(usize, usize, usize), Vec<usize>> = BTreeMap::new();
    for a in 0..s {
        for b in 0..s {
            let g = lay.sum[a][b];
            for i in 0..n {
                for j in 0..n {
                    if problem.cross_pattern.is_unknown(i, j) {
                        groups
                            .entry((g, i, j))
                            .or_default()
                            .push(var_c(a * m + i, b * m + n + j));
                    }
                }
            }
        }
    }
    let groups: Vec<Vec<usize>> = groups.into_values().collect();
    // Condition 3, one row per degree-2r monomial γ.
    let mut sos: Vec<BTreeMap<usize, f64>> = vec![BTreeMap::new(); lay.products.len()];
    for (beta, c) in &lay.lower {
        for k in 0..n {
            for l in 0..n {
                *sos[lay.quad(beta, k, l)].entry(var_q(k, l)).or_default() += c;
            }
        }
    }
    for a in 0..s {
        for b in 0..s {
            let row = &mut sos[lay.sum[a][b]];
            for p in 0..m {
                for q in 0..m {
                    let j = J0(p, q);
                    if j != 0.0 {
                        *row.entry(var_c(a * m + p, b * m + q)).or_default() -= j;
                    }
                }
            }
            *row.entry(var_g(a, b)).or_default() -= 1.0;
        }
    }
    let sqrt2 = std::f64::consts::SQRT_2;
    let zeros = groups.len() + sos.len();
    let cone = N + nb;
    let rows_total = zeros + cone * (cone + 1) / 2 + s * (s + 1) / 2;
    let mut b = vec![0.0; rows_total];
    let (mut rows, mut cols, mut vals) = (Vec::new(), Vec::new(), Vec::new());
    for (e, group) in groups.iter().enumerate() {
        let mut coef: BTreeMap<usize, f64> = BTreeMap::new();
        for &v in group {
            *coef.entry(v).or_default() += 1.0;
        }
        for (v, c) in coef {
            rows.push(e);
            cols.push(v);
            vals.push(c);
        }
    }
    for (g, row) in sos.iter().enumerate() {
        for (&v, &c) in row {
            if c != 0.0 {
                rows.push(groups.len() + g);
                cols.push(v);
                vals.push(c);
            }
        }
    }
    // Condition 1: [[C, W D^{1/2}], [·, I]] ⪰ 0.
    let base = zeros;
    for c in 0..N {
        for r in 0..=c {
            rows.push(base + svec_index(r, c));
            cols.push(var_c(r, c));
            vals.push(if r == c { -1.0 } else { -sqrt2 });
        }
    }
    for (t, (beta, cb)) in lay.lower.iter().enumerate() {
        let scale = sqrt2 * cb.sqrt();
        for alpha in 0..s {
            let Some(k) = lay.step(alpha, beta) else {
                continue;
            };
            for p in 0..m {
                let e = base + svec_index(alpha * m + p, N + t);
                // K[k, p] = K_a[k, p] (p < n), δ_{k, p−n} − K_a[k, p−n] (p ≥ n).
                let (constant, coefficient, column) = if p < n {
                    (0.0, 1.0, p)
                } else {
                    (if k == p - n { 1.0 } else { 0.0 }, -1.0, p - n)
                };
                match gain {
                    Some(K_a) => b[e] = scale * (constant + coefficient * K_a[(k, column)]),
                    None => {
                        b[e] = scale * constant;
                        rows.push(e);
                        cols.push(var_k(k, column));
                        vals.push(-scale * coefficient);
                    }
                }
            }
        }
        b[base + svec_index(N + t, N + t)] = 1.0;
    }
    // Condition 4: G ⪰ 0.
    let base_g = base + cone * (cone + 1) / 2;
    for c in 0..s {
        for r in 0..=c {
            rows.push(base_g + svec_index(r, c));
            cols.push(var_g(r, c));
            vals.push(if r == c { -1.0 } else { -sqrt2 });
        }
    }
    let mut q = vec![0.0; total_vars];
    for k in 0..n {
        q[var_q(k, k)] = 1.0;
    }
    let A = CscMatrix::new_from_triplets(rows_total, total_vars, rows, cols, vals);
    let P_quad = CscMatrix::zeros((total_vars, total_vars));
    let mut cones = vec![
        SupportedConeT::ZeroConeT(zeros),
        SupportedConeT::PSDTriangleConeT(cone),
    ];
    cones.push(SupportedConeT::PSDTriangleConeT(s));
    let (solver, status) = solve_program(
        &P_quad,
        &q,
        &A,
        &b,
        &cones,
        Kkt::Platform,
        (settings.max_iter, settings.tolerance),
        &Deadline::after(settings.time_limit),
        "the certified bound's SDP",
    )?;
    let sol = &solver.solution;
    let K_a = match gain {
        Some(K_a) => K_a.clone(),
        None => DMatrix::from_fn(n, n, |k, i| sol.x[var_k(k, i)]),
    };
    let mut x = sol.x.clone();
    for group in &groups {
        exact_zero_sum(&mut x, group);
    }
    let C = DMatrix::from_fn(N, N, |r, c| x[var_c(r, c)]);
    let Q = DMatrix::from_fn(n, n, |k, l| x[var_q(k, l)]);
    let G = DMatrix::from_fn(s, s, |a, b| x[var_g(a, b)]);
    let (P, repair) = repair(problem, &lay, &K_a, C, Q, &G)?;
    Ok(BlockCertificate {
        K_a,
        P,
        status,
        iterations: sol.iterations,
        repair,
    })
}

/// Makes the entries `group` of `x` sum to exactly zero (module docs: a grid, then the last
/// entry minus the sum of the others).
fn exact_zero_sum(x: &mut [f64], group: &[usize]) {
    // Distinct variables only (a group never repeats one, but be safe).
    let mut vars: Vec<usize> = group.to_vec();
    vars.sort_unstable();
    vars.dedup();
    let bound = vars.iter().map(|&v| x[v].abs()).fold(0.0, f64::max);
    if vars.len() == 1 || bound == 0.0 || !bound.is_finite() {
        for &v in &vars {
            x[v] = 0.0;
        }
        return;
    }
    let mut e = bound.log2().ceil() as i32;
    while 2f64.powi(e) < bound {
        e += 1;
    }
    // len · 2^e < 2^(e + room) ≤ 2^(53) · g with g = 2^(e − bits).
    let room = (usize::BITS - vars.len().leading_zeros()) as i32 + 1;
    let bits = 52 - room;
    let g = 2f64.powi(e - bits);
    let mut sum = 0.0;
    let (last, rest) = vars.split_last().expect("two or more");
    for &v in rest {
        x[v] = (x[v] / g).round() * g;
        sum += x[v];
    }
    x[*last] = -sum;
}

/// The verified repair (module docs): `C ← C + δI` until `C − W D Wᵀ ⪰ 0` is proven, then
/// `Q ← Q + ηI` until `G + E ⪰ 0` is proven. Returns `P̄ = Q` and the trace added.
#[allow(non_snake_case)]
fn repair(
    problem: &FusionProblem,
    lay: &Layout,
    K_a: &DMatrix<f64>,
    mut C: DMatrix<f64>,
    mut Q: DMatrix<f64>,
    G: &DMatrix<f64>,
) -> Result<(DMatrix<f64>, f64), SolveError> {
    let n = lay.n;
    let (m, s, N) = (lay.m, lay.mons.len(), lay.big());
    let K_b = BallMatrix::identity_minus(K_a);
    let k_entry = |k: usize, p: usize| {
        if p < n {
            Ball::exact(K_a[(k, p)])
        } else {
            K_b.at(k, p - n)
        }
    };
    // W (N × nb) as balls, with each column scaled by c_β (exact integers) on one side.
    let nb = lay.lower.len();
    let W = BallMatrix::from_fn(N, nb, |row, t| {
        let (alpha, p) = (row / m, row % m);
        match lay.step(alpha, &lay.lower[t].0) {
            Some(k) => k_entry(k, p),
            None => Ball::exact(0.0),
        }
    });
    let WD = BallMatrix::from_fn(N, nb, |row, t| {
        let c = lay.lower[t].1;
        let w = W.at(row, t);
        let mid = c * w.mid;
        Ball {
            mid,
            rad: up(c * w.rad + U * mid.abs(), 3),
        }
    });
    let margin = |C: &DMatrix<f64>| {
        BallMatrix::from_fn(N, N, |x, y| {
            let mut d = Dot::new();
            d.add(Ball::exact(C[(x, y)]));
            for t in 0..nb {
                let w = WD.at(y, t);
                d.add_prod(
                    W.at(x, t),
                    Ball {
                        mid: -w.mid,
                        rad: w.rad,
                    },
                );
            }
            d.ball()
        })
    };
    let first = margin(&C).symmetrized();
    if !is_psd(&first.mid, &first.rad) {
        let mut delta = psd_shift(&first).ok_or_else(|| repair_failed("C − W D Wᵀ"))?;
        let scale = C.amax().max(f64::MIN_POSITIVE);
        let mut proven = false;
        for _ in 0..60 {
            let mut Cd = C.clone();
            for i in 0..N {
                Cd[(i, i)] += delta;
            }
            let b = margin(&Cd).symmetrized();
            if is_psd(&b.mid, &b.rad) {
                C = Cd;
                proven = true;
                break;
            }
            delta = 2.0 * delta + 1e-16 * scale;
        }
        if !proven {
            return Err(repair_failed("C − W D Wᵀ"));
        }
    }
    // T_αβ = ⟨J₀, C_αβ⟩ as balls.
    let J0 = |p: usize, q: usize| match (p < n, q < n) {
        (true, true) => problem.P_a[(p, q)],
        (false, false) => problem.P_b[(p - n, q - n)],
        _ => 0.0,
    };
    let T = BallMatrix::from_fn(s, s, |a, b| {
        let mut d = Dot::new();
        for p in 0..m {
            for q in 0..m {
                let j = J0(p, q);
                if j != 0.0 {
                    d.add_exact_prod(j, C[(a * m + p, b * m + q)]);
                }
            }
        }
        d.ball()
    });
    // Where each degree-2r coefficient goes in the Gram matrix E: (α, α) when γ = 2α, else
    // half on (α, β) and half on (β, α) for the first α < β with α + β = γ.
    let mut place: Vec<Option<(usize, usize)>> = vec![None; lay.products.len()];
    for a in 0..s {
        place[lay.sum[a][a]] = Some((a, a));
    }
    for a in 0..s {
        for b in a + 1..s {
            let g = lay.sum[a][b];
            if place[g].is_none() {
                place[g] = Some((a, b));
            }
        }
    }
    let trace_solver = Q.trace();
    let mut eta = 0.0;
    for _ in 0..60 {
        // e_γ = coef_γ(‖v‖^{2(r−1)} vᵀQv) − Σ_{α+β=γ} (T_αβ + G_αβ), as balls.
        let mut coef = vec![Dot::new(); lay.products.len()];
        for (beta, c) in &lay.lower {
            for k in 0..n {
                for l in 0..n {
                    coef[lay.quad(beta, k, l)].add_exact_prod(*c, Q[(k, l)]);
                }
            }
        }
        for a in 0..s {
            for b in 0..s {
                let t = T.at(a, b);
                let d = &mut coef[lay.sum[a][b]];
                d.add(Ball {
                    mid: -t.mid,
                    rad: t.rad,
                });
                d.add(Ball::exact(-G[(a, b)]));
            }
        }
        let mut Y = BallMatrix::exact(G);
        for (g, d) in coef.iter().enumerate() {
            let e = d.ball();
            let (a, b) = place[g].expect("every degree-2r monomial splits");
            if a == b {
                let mid = Y.mid[(a, a)] + e.mid;
                Y.rad[(a, a)] = up(e.rad + U * mid.abs(), 3);
                Y.mid[(a, a)] = mid;
            } else {
                for (x, y) in [(a, b), (b, a)] {
                    let mid = Y.mid[(x, y)] + 0.5 * e.mid;
                    Y.rad[(x, y)] = up(0.5 * e.rad + U * mid.abs(), 3);
                    Y.mid[(x, y)] = mid;
                }
            }
        }
        if is_psd(&Y.mid, &Y.rad) {
            return Ok((Q.clone(), (Q.trace() - trace_solver).max(0.0)));
        }
        let shift = psd_shift(&Y).ok_or_else(|| repair_failed("G + E"))?;
        let step = if eta == 0.0 { shift } else { shift.max(eta) };
        let step = step + 1e-16 * Q.amax().max(f64::MIN_POSITIVE);
        for k in 0..n {
            Q[(k, k)] += step;
        }
        eta += step;
    }
    Err(repair_failed("G + E"))
}

fn repair_failed(what: &str) -> SolveError {
    SolveError::NotProven { what: what.into() }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    #[test]
    fn zero_groups_sum_to_exactly_zero() {
        // Every entry ends a multiple of the group's grid g, so the sum is checked exactly in
        // integers (i128 multiples of g), not in floating point.
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1);
        for len in [2usize, 3, 5, 17, 100] {
            for scale in [1e-12, 1.0, 3e7] {
                let mut x: Vec<f64> = (0..len)
                    .map(|_| scale * rng.random_range(-1.0..1.0))
                    .collect();
                let before = x.clone();
                let group: Vec<usize> = (0..len).collect();
                exact_zero_sum(&mut x, &group);
                let bound = before.iter().fold(0.0f64, |m, v| m.max(v.abs()));
                let g = x
                    .iter()
                    .filter(|v| **v != 0.0)
                    .map(|v| v.abs())
                    .fold(f64::INFINITY, f64::min);
                let ints: i128 = x
                    .iter()
                    .map(|v| {
                        // exact multiples of the smallest power of two dividing the entries
                        let e = (g.log2().floor() as i32) - 60;
                        let q = v / 2f64.powi(e);
                        assert_eq!(q, q.round(), "not on a grid");
                        q as i128
                    })
                    .sum();
                assert_eq!(ints, 0, "len {len} scale {scale}");
                let moved = x
                    .iter()
                    .zip(&before)
                    .map(|(a, b)| (a - b).abs())
                    .fold(0.0f64, f64::max);
                let sum: f64 = before.iter().sum();
                assert!(moved <= sum.abs() + 1e-12 * bound, "moved {moved}");
            }
        }
    }

    #[test]
    fn cone_sizes_and_monomials() {
        assert_eq!(CertifySettings::cone_size(2, 1), 9);
        assert_eq!(CertifySettings::cone_size(3, 3), 66);
        assert_eq!(CertifySettings::cone_size(4, 2), 84);
        assert_eq!(monomials(3, 2).len(), 6);
        assert_eq!(multinomial(&[2, 1]), 3.0);
    }
}
