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
//! ## Sectors: two states, one certificate per cone of directions
//! The inequality `vᵀ K J Kᵀ v ≤ vᵀ Q v` is needed for every `v`, and it is even in `v`, so
//! it suffices on a set of cones covering a half-plane. For `n = 2` split the closed upper
//! half-plane by integer directions `d_0 = (64, 0), d_1, …, d_S = (−64, 0)`, `d_k ≈
//! 64 (cos πk/S, sin πk/S)` rounded, each turning counterclockwise from the one before
//! (checked exactly in integers, [`sector_multipliers`]). Sector `k` is
//! `{v : det(d_k, v) ≥ 0, det(v, d_{k+1}) ≥ 0}`, on which the quadratic form
//! `q_k(v) = det(d_k, v)·det(v, d_{k+1}) = vᵀ S_k v` is non-negative; the sectors and their
//! negatives cover the plane. Per sector take, besides the shared `Q` and `K`, a level-1
//! `C_k`, `G_k` as above, a PSD `C′_k` (`2n × 2n`) and a scalar `g′_k`, with
//!
//! 1′. `C_k − S_k ⊗ C′_k ⪰ w wᵀ` (`w` as in condition 1, `r = 1`) and `C′_k ⪰ 0`;
//! 2′. condition 2 for `C_k` (only `C_k` reaches `⟨J, Z⟩`);
//! 3′. `vᵀ Q v − ⟨J₀, Z_k(v)⟩ = vᵀ G_k v + g′_k q_k(v)` (equal coefficients), `G_k ⪰ 0`,
//!     `g′_k ≥ 0`.
//!
//! On sector `k`, `Z_k(v) = (v ⊗ I)ᵀ(C_k − S_k ⊗ C′_k)(v ⊗ I) + q_k(v) C′_k ⪰ Kᵀ v vᵀ K`
//! (1′, `q_k ≥ 0`), and `vᵀ Q v − ⟨J₀, Z_k(v)⟩ ≥ 0` (3′); with 2′ the chain of the level-`r`
//! proof gives `vᵀ K J Kᵀ v ≤ vᵀ Q v` there, hence everywhere: **`Q ⪰ K J Kᵀ`**. This is the
//! S-procedure with the sector's defining product as multiplier (a Positivstellensatz
//! certificate on each semialgebraic piece, as in Putinar's); `C′_k = 0`, `g′_k = 0` is the
//! level-1 certificate, so sectors are never looser than level 1 (up to solver tolerance);
//! finer sectors let the certificate follow the direction more closely, but no monotonicity
//! in `S` and no convergence to the robust optimum is claimed (the sweep in docs/methods.md measures
//! how far they close the brackets). The program: `min tr Q` with `S` copies of
//! the level-1 cone (size `2n² + 1 = 9` each), `S` cones of size `2n = 4` for the `C′_k`,
//! and `g′ ≥ 0`. The multipliers' coefficients are integers below `2¹⁴` times `2⁻¹²`,
//! exact floats, so the repair below treats `S_k ⊗ C′_k` exactly.
//!
//! **Three states** ([`CertifySettings::cones`], opt-in): the same argument with several
//! multipliers per piece. The pieces are `4`, `16` or `64` cones spanned by integer
//! generators `u₁, u₂, u₃` — the four octants of `v₃ ≥ 0`, split 0, 1 or 2 times into four at
//! the edges' midpoints (generators `u_i + u_j`), an exact subdivision, so the cones and their
//! negatives cover space (also checked exactly on an integer grid). With facet normals
//! `n_i = u_j × u_k`, every `v = Σ λ_i u_i` of the cone has `n_i·v = λ_i det U`, all of one
//! sign, so the three products `q_ij(v) = (n_i·v)(n_j·v) = vᵀ S_ij v`, `i < j`, are
//! non-negative on the cone and its negative. Each piece then takes `C − Σ_ij S_ij ⊗ C′_ij
//! ⪰ w wᵀ` with `C′_ij ⪰ 0`, and `vᵀQv − ⟨J₀, Z(v)⟩ = vᵀ G v + Σ_ij g′_ij q_ij(v)` with
//! `G ⪰ 0`, `g′_ij ≥ 0`: on the cone `Z(v) ⪰ Kᵀ v vᵀ K` and the residual is non-negative,
//! and the chain above gives `Q ⪰ K J Kᵀ`. The `S_ij` have dyadic entries (integers times a
//! power of two), so the repair forms `S ⊗ C′` exactly as for two states. This family
//! contains level 1 (zero multipliers); the sweep in docs/methods.md measures it against
//! the levels (it narrows the gaps at a cost of the order of level 3's, so it is not a
//! default).
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
//!   For a sector, `C′ ⪰ 0` is proven first (its diagonal shifted the same way if needed),
//!   then `C − S ⊗ C′ − W Wᵀ ⪰ 0` with `S ⊗ C′` formed in balls; a negative `g′` from the
//!   solver is set to 0 before step 3 (which then absorbs the difference).
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
//! certified trace is **never above the proven trace of CI's (on independent blocks nmCI's)
//! bound made a dominating float matrix**, whatever the solver's tolerance. How far that is
//! from CI's floating-point trace depends on how accurately CI's bound can be enclosed: within
//! `10⁻¹⁴` relative on the well-conditioned random problems of the tests, but 1.44 % above it on
//! a pair of condition number `2·10¹³` (`P_a = [[1, 1 − 10⁻¹³], …]`, `P_b` its mirror;
//! `tests/native/certify.rs`), where the enclosure's radius, added to the diagonal to make the
//! matrix dominate, is that large. It is not "never above CI's trace beyond rounding".
//!
//! **Wholly unknown blocks.** Where a block's cross block is wholly unknown (and the gain is
//! free), CI is the robust optimum (Reinhardt et al., above), so the program's optimum at any
//! level or number of sectors is CI's trace and no solve can do better than CI's proven bound
//! beyond rounding: that bound is taken without a solve (`levels` 1, `sectors` 0,
//! `ci_blocks` true, no iterations).
//!
//! When `P_a`, `P_b` and the pattern split the state into independent blocks, each block is
//! certified on its own (the joint covariance is block diagonal, so a block-diagonal gain's
//! `K J Kᵀ` is too). Blocks above [`CertifySettings::max_block_dim`] states, or whose cone
//! would exceed [`CertifySettings::max_cone`], are refused with a typed error.

use std::collections::{BTreeMap, HashMap};

use clarabel::algebra::CscMatrix;
use clarabel::solver::SupportedConeT;
use nalgebra::DMatrix;
use serde::{Deserialize, Serialize};

use super::ci::covariance_intersection;
use super::program::{check_time_limit, solve_program, svec_index, Deadline, Kkt, SdpStatus};
use super::scale::{largest_variance, Pow2};
use super::upper::{trace_upper_bound, young_bound, young_omega};
use super::verify::{is_psd, psd_shift, up, Ball, BallMatrix, Dot, U};
use super::{per_block, Criterion, Fused, FusionProblem};
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
    /// Blocks of two states: the number of sectors of the half-circle of directions, each
    /// with its own level-1 certificate (module docs, "Sectors"), in
    /// `2..=`[`MAX_SECTORS`]. `None` (default): [`DEFAULT_SECTORS`] unless `level` is set,
    /// which then applies to two-state blocks too (one certificate for every direction).
    pub sectors: Option<u32>,
    /// Blocks of three states: the number of cones of directions (4, 16 or 64), each with its
    /// own level-1 certificate (module docs, "Sectors"); `None` (default): one certificate of
    /// [`CertifySettings::level_for`].
    pub cones: Option<u32>,
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
            sectors: None,
            cones: None,
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
        if let Some(count) = self.sectors {
            if !(2..=MAX_SECTORS).contains(&count) {
                return Err(SolveError::InvalidSettings(format!(
                    "sectors must be in 2..={MAX_SECTORS} (got {count})"
                )));
            }
        }
        if let Some(count) = self.cones {
            cone_generators(count)?;
        }
        check_time_limit(self.time_limit)
    }

    /// The certificate of a block of `dim` states: sectors for two states (the setting, or
    /// [`DEFAULT_SECTORS`] when neither `sectors` nor `level` is set), cones for three states
    /// when `cones` is set, else one certificate of [`CertifySettings::level_for`].
    pub fn family_for(&self, dim: usize) -> Family {
        if let (3, Some(count)) = (dim, self.cones) {
            return Family::Cones(count);
        }
        match (dim, self.sectors, self.level) {
            (2, Some(_), _) | (2, None, None) => {
                Family::Sectors(self.sectors.unwrap_or(DEFAULT_SECTORS))
            }
            _ => Family::Global(self.level_for(dim)),
        }
    }

    /// The level used for a block of `dim` states: the setting, or by default the level
    /// chosen from the measured gap-and-time curves (docs/methods.md, `examples/certify_levels.rs`):
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

/// Most sectors accepted ([`CertifySettings::sectors`]).
pub const MAX_SECTORS: u32 = 64;

/// The default number of sectors of a two-state block, chosen from the measured
/// gap-and-time curves (docs/methods.md, `examples/certify_levels.rs`).
pub const DEFAULT_SECTORS: u32 = 24;

/// A block solved only `AlmostSolved` whose repair added more than this fraction of its trace
/// is certified again with the next lower family, and the smaller bound kept (a tenth of
/// [`crate::CLOSED_RTOL`]: below it the repair cannot keep a bracket open).
const RETRY_REPAIR_RTOL: f64 = 1e-7;

/// Sectors halve down to this count before a failed or reduced-accuracy sector certificate
/// falls back to a level (`Family::lower`).
const MIN_FALLBACK_SECTORS: u32 = 16;

/// Which certificate a block gets (module docs).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Family {
    /// One certificate of this level for every direction.
    Global(u32),
    /// Two states: a level-1 certificate on each of this many sectors of directions.
    Sectors(u32),
    /// Three states: a level-1 certificate on each of this many cones of directions (4, 16
    /// or 64: the octants of a half-space, subdivided 0, 1 or 2 times).
    Cones(u32),
}

impl Family {
    /// The family's level (1 for sectors).
    pub fn level(self) -> u32 {
        match self {
            Family::Global(level) => level,
            Family::Sectors(_) | Family::Cones(_) => 1,
        }
    }

    /// The number of sectors or cones (0 for one certificate for every direction).
    pub fn sectors(self) -> u32 {
        match self {
            Family::Global(_) => 0,
            Family::Sectors(count) | Family::Cones(count) => count,
        }
    }

    /// The family tried when this one breaks down numerically or solves to reduced accuracy
    /// only: sectors halve down to [`MIN_FALLBACK_SECTORS`], then fall back to the default
    /// level of a two-state block, a level to the one below; `None` after level 1.
    fn lower(self) -> Option<Family> {
        match self {
            Family::Sectors(count) if count / 2 >= MIN_FALLBACK_SECTORS => {
                Some(Family::Sectors(count / 2))
            }
            Family::Sectors(_) => Some(Family::Global(CertifySettings::auto_level(2))),
            Family::Cones(count) if count / 4 >= 4 => Some(Family::Cones(count / 4)),
            Family::Cones(_) => Some(Family::Global(CertifySettings::auto_level(3))),
            Family::Global(level) if level > 1 => Some(Family::Global(level - 1)),
            Family::Global(_) => None,
        }
    }
}

/// The sectors' multipliers: integer directions `d_k ≈ 2⁶ (cos πk/S, sin πk/S)`,
/// `k = 0..S`, with `d_S = −d_0`, and for each sector `q(v) = det(d_k, v)·det(v, d_{k+1})`
/// by its coefficients on `v₁², v₁v₂, v₂²` (integers below `2¹⁴` times `2⁻¹²`, exact). Consecutive directions are
/// checked to turn counterclockwise within the closed upper half-plane, exactly in
/// integers — the covering argument of the module docs needs nothing else.
pub(crate) fn sector_multipliers(count: u32) -> Result<Vec<[f64; 3]>, SolveError> {
    let radius = 64.0;
    let s = count as usize;
    let mut d: Vec<[i64; 2]> = (0..=s)
        .map(|k| {
            let t = std::f64::consts::PI * k as f64 / count as f64;
            [
                (radius * t.cos()).round() as i64,
                (radius * t.sin()).round() as i64,
            ]
        })
        .collect();
    d[0] = [64, 0];
    d[s] = [-64, 0];
    let turns = d
        .windows(2)
        .all(|w| w[0][1] >= 0 && w[1][1] >= 0 && w[0][0] * w[1][1] - w[0][1] * w[1][0] > 0);
    if count < 2 || !turns {
        return Err(SolveError::InvalidSettings(format!(
            "sectors must be in 2..={MAX_SECTORS} (got {count})"
        )));
    }
    Ok(d.windows(2)
        .map(|w| {
            let ([x0, y0], [x1, y1]) = (w[0], w[1]);
            // (x0 v₂ − y0 v₁)(y1 v₁ − x1 v₂) / 2¹²: integers below 2¹⁴ times a power of two,
            // exact, and of order one (the solver needs a well-scaled program).
            let scale = 1.0 / (radius * radius);
            [
                (-y0 * y1) as f64 * scale,
                (x0 * y1 + y0 * x1) as f64 * scale,
                (-x0 * x1) as f64 * scale,
            ]
        })
        .collect())
}

/// The multipliers of each piece of directions (module docs, "Sectors"): for two states one
/// per sector of [`sector_multipliers`]; for three states, `count` ∈ {4, 16, 64} cones
/// spanned by integer generators — the four octants of `v₃ ≥ 0`, each split 0, 1 or 2 times
/// into four at its edges' midpoints (the generators `u_i + u_j`), an exact subdivision of the
/// octant — with the three products `q_ij(v) = (n_i·v)(n_j·v)`, `i < j`, of the cone's facet
/// normals `n_i = u_j × u_k`: on the cone all `n_i·v` share a sign (`n_i·v = λ_i det U` for
/// `v = Σ λ_i u_i`), so every `q_ij ≥ 0` there and on its negative, and the octants and their
/// negatives cover space. Each matrix is scaled by a power of two to entries of order one
/// (exact).
#[allow(non_snake_case)]
pub(crate) fn cone_multipliers(n: usize, count: u32) -> Result<Vec<Vec<DMatrix<f64>>>, SolveError> {
    match n {
        2 => Ok(sector_multipliers(count)?
            .into_iter()
            .map(|sigma| {
                vec![DMatrix::from_row_slice(
                    2,
                    2,
                    &[sigma[0], 0.5 * sigma[1], 0.5 * sigma[1], sigma[2]],
                )]
            })
            .collect()),
        3 => Ok(cone_generators(count)?
            .iter()
            .map(|u| {
                let cross = |a: [i64; 3], b: [i64; 3]| {
                    [
                        a[1] * b[2] - a[2] * b[1],
                        a[2] * b[0] - a[0] * b[2],
                        a[0] * b[1] - a[1] * b[0],
                    ]
                };
                let normals = [cross(u[1], u[2]), cross(u[2], u[0]), cross(u[0], u[1])];
                [(0, 1), (0, 2), (1, 2)]
                    .iter()
                    .map(|&(i, j)| {
                        let (a, b) = (normals[i], normals[j]);
                        // 2 S = a bᵀ + b aᵀ in integers, then scaled by a power of two.
                        let twice: Vec<i64> = (0..9)
                            .map(|e| a[e / 3] * b[e % 3] + b[e / 3] * a[e % 3])
                            .collect();
                        let largest = twice.iter().map(|v| v.abs()).max().unwrap_or(1).max(1);
                        let scale = 0.5 / (largest as f64).log2().ceil().exp2();
                        DMatrix::from_iterator(3, 3, twice.iter().map(|&v| v as f64 * scale))
                    })
                    .collect()
            })
            .collect()),
        _ => Err(SolveError::InvalidSettings(format!(
            "cones of directions certify blocks of two or three states (got a block of {n})"
        ))),
    }
}

/// The integer generators of the cones of [`cone_multipliers`] for three states.
pub(crate) fn cone_generators(count: u32) -> Result<Vec<[[i64; 3]; 3]>, SolveError> {
    let splits = match count {
        4 => 0,
        16 => 1,
        64 => 2,
        _ => {
            return Err(SolveError::InvalidSettings(format!(
                "three-state blocks are certified on 4, 16 or 64 cones (got {count})"
            )))
        }
    };
    let mut cones: Vec<[[i64; 3]; 3]> = [(1, 1), (-1, 1), (-1, -1), (1, -1)]
        .iter()
        .map(|&(x, y)| [[x, 0, 0], [0, y, 0], [0, 0, 1]])
        .collect();
    let add = |a: [i64; 3], b: [i64; 3]| [a[0] + b[0], a[1] + b[1], a[2] + b[2]];
    for _ in 0..splits {
        cones = cones
            .iter()
            .flat_map(|&[u1, u2, u3]| {
                let (m12, m13, m23) = (add(u1, u2), add(u1, u3), add(u2, u3));
                [
                    [u1, m12, m13],
                    [u2, m12, m23],
                    [u3, m13, m23],
                    [m12, m23, m13],
                ]
            })
            .collect();
    }
    Ok(cones)
}

/// The certified rule's certificate on each independent block.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Certificates {
    /// The certificate level per block (JSON `levels`).
    pub levels: Vec<u32>,
    /// The number of sectors (two states) or cones (three states) per block, 0 for one
    /// certificate for every direction (JSON `sectors`).
    pub sectors: Vec<u32>,
}

impl Certificates {
    /// The certificates of a computed certified rule.
    pub fn of(cert: &CertifiedResult) -> Self {
        Certificates {
            levels: cert.levels.clone(),
            sectors: cert.sectors.clone(),
        }
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
    /// broke down numerically on it (1 on a block certified by sectors, and on a block whose
    /// cross block is wholly unknown: CI's certificate, no solve).
    pub levels: Vec<u32>,
    /// The number of sectors or cones used on each block (0: one certificate for every direction).
    pub sectors: Vec<u32>,
    /// Per block: whether CI's proven bound (for the block's CI gain, or for the given gain
    /// with its best `ω`) was taken — without a solve where the block's cross block is wholly
    /// unknown (CI is the robust optimum there), or because it was tighter than the solver's
    /// certificate: the solver can end looser than CI where CI is optimal (`AlmostSolved` at
    /// high levels), or fail at every level (then the block's `status` is `AlmostSolved`).
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
    certify(problem, None, settings, None)
}

/// [`certified_fusion`] with the blocks certified before taken from `memo` (and those
/// certified now added to it): the same result, bit for bit (see [`CertificateMemo`]).
///
/// ```
/// use nalgebra::{DMatrix, DVector};
/// use nmci::*;
/// let d = |v: &[f64]| DMatrix::from_diagonal(&DVector::from_row_slice(v));
/// let p = FusionProblem::from_covariances(d(&[3.0, 1.0]), d(&[1.0, 4.0]),
///     CrossPattern::diagonal(2)).unwrap();
/// let mut memo = CertificateMemo::new();
/// let settings = CertifySettings::default();
/// let first = certified_fusion_memo(&p, &settings, &mut memo).unwrap();
/// let again = certified_fusion_memo(&p, &settings, &mut memo).unwrap();
/// assert_eq!(first, again);
/// assert_eq!(first, certified_fusion(&p, &settings).unwrap());
/// assert_eq!(memo.hits(), 2); // two independent 1-state blocks, each certified once
/// ```
pub fn certified_fusion_memo(
    problem: &FusionProblem,
    settings: &CertifySettings,
    memo: &mut CertificateMemo,
) -> Result<CertifiedResult, SolveError> {
    certify(problem, None, settings, Some(memo))
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
    certify(problem, Some(K_a), settings, None)
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
    mut memo: Option<&mut CertificateMemo>,
) -> Result<CertifiedResult, SolveError> {
    settings.validate()?;
    let blocks = certification_blocks(problem, gain);
    for block in &blocks {
        if block.len() > settings.max_block_dim {
            return Err(SolveError::BlockTooLarge {
                dim: block.len(),
                limit: settings.max_block_dim,
            });
        }
        let level = settings.family_for(block.len()).level();
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
    let (mut status, mut iterations, mut repair) = (SdpStatus::Solved, 0, 0.0);
    let mut levels = Vec::with_capacity(blocks.len());
    let mut sectors = Vec::with_capacity(blocks.len());
    let mut ci_blocks = Vec::with_capacity(blocks.len());
    let fused = per_block(problem, &blocks, |block, sub| {
        let sub_gain = gain
            .map(|K| DMatrix::from_fn(block.len(), block.len(), |i, j| K[(block[i], block[j])]));
        let outcome = match (&mut memo, &sub_gain) {
            (Some(memo), None) => memo.get_or_certify(&sub, settings)?,
            _ => certify_one_block(&sub, sub_gain.as_ref(), settings)?,
        };
        if outcome.P.iter().any(|v| !v.is_finite()) {
            return Err(SolveError::Overflow {
                what: "certified bound".into(),
                largest: largest_variance(&sub),
            });
        }
        ci_blocks.push(outcome.ci_used);
        if outcome.status == SdpStatus::AlmostSolved {
            status = SdpStatus::AlmostSolved;
        }
        iterations += outcome.iterations;
        repair += outcome.repair;
        levels.push(outcome.level);
        sectors.push(outcome.sectors);
        Ok::<_, SolveError>((outcome.K_a, outcome.P))
    })?;
    Ok(CertifiedResult {
        fused,
        status,
        iterations,
        repair,
        blocks,
        levels,
        sectors,
        ci_blocks,
    })
}

/// What [`certify`] finds for one block: its gain and proven bound, and how they were found.
#[allow(non_snake_case)]
#[derive(Debug, Clone)]
struct BlockOutcome {
    K_a: DMatrix<f64>,
    P: DMatrix<f64>,
    status: SdpStatus,
    iterations: u32,
    repair: f64,
    level: u32,
    sectors: u32,
    ci_used: bool,
}

/// One block of [`certify`]: `sub` is the block's problem, `sub_gain` its part of a given gain.
///
/// Certified at unit scale (`fusion::scale`): a block whose largest diagonal entry is outside
/// `[2⁻⁴, 2⁴]` has its covariances multiplied by the power of two that brings that entry into
/// `[1, 2)` — exactly, or not at all —
/// so the solver's absolute tolerances meet data of order one whatever the units. The bound
/// proven for the scaled block is mapped back by the inverse power of two, exactly, or where an
/// entry would not map back exactly (near the bottom of the float range) to a matrix that
/// dominates it by a few subnormal units (`Pow2::unscale_dominating`), so the bound is always
/// proven for the block as given; the block is certified as given only when mapping back
/// overflows.
fn certify_one_block(
    sub: &FusionProblem,
    sub_gain: Option<&DMatrix<f64>>,
    settings: &CertifySettings,
) -> Result<BlockOutcome, SolveError> {
    let (scaled, scale) = Pow2::normalising(sub).scaled_problem(sub);
    if scale != Pow2::ONE {
        let outcome = certify_at_scale(&scaled, sub_gain, settings)?;
        if let Some(p) = scale.unscale_dominating(&outcome.P) {
            return Ok(BlockOutcome {
                P: p,
                repair: scale.unscale_value(outcome.repair),
                ..outcome
            });
        }
    }
    certify_at_scale(sub, sub_gain, settings)
}

/// [`certify_one_block`] on the block as given.
#[allow(non_snake_case)]
fn certify_at_scale(
    sub: &FusionProblem,
    sub_gain: Option<&DMatrix<f64>>,
    settings: &CertifySettings,
) -> Result<BlockOutcome, SolveError> {
    let n = sub.dim();
    // A block whose cross block is wholly unknown: CI is the robust optimum there (module
    // docs), so no certificate of any family is tighter than CI's own beyond rounding; its
    // proven bound is taken without a solve.
    if sub_gain.is_none() && sub.cross_pattern.unknown_count() == n * n {
        let ci = covariance_intersection(sub, Criterion::Trace)?;
        if let Some(bound) = young_bound(&sub.P_a, &sub.P_b, &ci.fused.K_a, ci.omega) {
            return Ok(BlockOutcome {
                K_a: ci.fused.K_a,
                P: bound.dominating(),
                status: SdpStatus::Solved,
                iterations: 0,
                repair: 0.0,
                level: 1,
                sectors: 0,
                ci_used: true,
            });
        }
    }
    // The requested family, or — where the solver breaks down numerically on it — the
    // next lower one that solves (`Family::lower`); CI's proven bound when none does.
    let mut family = settings.family_for(n);
    let mut solved = loop {
        match certify_block(sub, sub_gain, family, settings) {
            Ok(s) => break Some(s),
            Err(SolveError::SolverFailed { .. } | SolveError::NotProven { .. }) => {
                match family.lower() {
                    Some(lower) => family = lower,
                    None => break None,
                }
            }
            Err(e) => return Err(e),
        }
    };
    // Solved to reduced accuracy only and repaired by more than RETRY_REPAIR_RTOL of the
    // trace: the repair can cost more than a coarser family loses (degenerate optima,
    // e.g. one row of P_ab unknown). Both are proofs; keep the smaller trace of this
    // family's and the next lower one's.
    if let (Some(first), Some(lower)) = (&solved, family.lower()) {
        if first.status == SdpStatus::AlmostSolved
            && first.repair > RETRY_REPAIR_RTOL * first.P.trace().abs()
        {
            match certify_block(sub, sub_gain, lower, settings) {
                Ok(s) if trace_upper_bound(&s.P) < trace_upper_bound(&first.P) => {
                    solved = Some(s);
                    family = lower;
                }
                Ok(_) | Err(SolveError::SolverFailed { .. } | SolveError::NotProven { .. }) => {}
                Err(e) => return Err(e),
            }
        }
    }
    // CI's bound (Young's inequality, proven in exact arithmetic) is a level-1
    // certificate: keep it where the solver's certificate ended looser (module docs).
    let (ci_gain, omega) = match sub_gain {
        Some(K) => (K.clone(), young_omega(&sub.P_a, &sub.P_b, K)),
        None => {
            let ci = covariance_intersection(sub, Criterion::Trace)?;
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
    Ok(BlockOutcome {
        K_a: solved.K_a,
        P: solved.P,
        status: solved.status,
        iterations: solved.iterations,
        repair: solved.repair,
        level: family.level(),
        sectors: family.sectors(),
        ci_used,
    })
}

/// How many certified blocks a [`CertificateMemo`] keeps.
pub const MEMO_BLOCKS: usize = 8;

/// Certified blocks kept for reuse by [`certified_fusion_memo`]: the [`MEMO_BLOCKS`] blocks
/// used most recently, each under its exact inputs — the block's `P_a`, `P_b` (bit for bit)
/// and known-zero pattern, and the settings. A block certified before with the same inputs
/// gets the same gain, bound, status, iterations, repair, level and sector count as then,
/// which a fresh solve would give again (the program and its repair are deterministic), so
/// results are the same with and without the memo (tested); only the time differs. The
/// explorer keeps one per worker: an edit inside one block then solves that block alone.
/// Errors are not kept, and settings with a `time_limit` do not use the memo (a solve's
/// outcome then depends on the time it gets).
#[derive(Debug, Default)]
pub struct CertificateMemo {
    entries: std::collections::VecDeque<(BlockKey, BlockOutcome)>,
    hits: u64,
}

/// The exact inputs of one block's certificate (no given gain).
#[allow(non_snake_case)]
#[derive(Debug, PartialEq)]
struct BlockKey {
    P_a: Vec<u64>,
    P_b: Vec<u64>,
    unknown: Vec<bool>,
    settings: CertifySettings,
}

impl BlockKey {
    fn of(sub: &FusionProblem, settings: &CertifySettings) -> Self {
        let n = sub.dim();
        let bits = |m: &DMatrix<f64>| m.iter().map(|v| v.to_bits()).collect();
        BlockKey {
            P_a: bits(&sub.P_a),
            P_b: bits(&sub.P_b),
            unknown: (0..n)
                .flat_map(|i| (0..n).map(move |j| (i, j)))
                .map(|(i, j)| sub.cross_pattern.is_unknown(i, j))
                .collect(),
            settings: *settings,
        }
    }
}

impl CertificateMemo {
    /// An empty memo.
    pub fn new() -> Self {
        Self::default()
    }

    /// How many blocks were taken from the memo instead of certified.
    pub fn hits(&self) -> u64 {
        self.hits
    }

    /// How many blocks it holds (at most [`MEMO_BLOCKS`]).
    pub fn len(&self) -> usize {
        self.entries.len()
    }

    /// Whether it holds no block.
    pub fn is_empty(&self) -> bool {
        self.entries.is_empty()
    }

    fn get_or_certify(
        &mut self,
        sub: &FusionProblem,
        settings: &CertifySettings,
    ) -> Result<BlockOutcome, SolveError> {
        // A solve with a time limit may end differently with other timing: never kept or
        // reused.
        if settings.time_limit.is_some() {
            return certify_one_block(sub, None, settings);
        }
        let key = BlockKey::of(sub, settings);
        if let Some(at) = self.entries.iter().position(|(k, _)| *k == key) {
            self.hits += 1;
            // The most recently used last: the first is evicted next.
            let entry = self.entries.remove(at).expect("found above");
            let outcome = entry.1.clone();
            self.entries.push_back(entry);
            return Ok(outcome);
        }
        let outcome = certify_one_block(sub, None, settings)?;
        if self.entries.len() == MEMO_BLOCKS {
            self.entries.pop_front();
        }
        self.entries.push_back((key, outcome.clone()));
        Ok(outcome)
    }
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

    /// A multiplier's coefficient on the monomial of index `g` in `products` (level 1):
    /// `q(v) = vᵀ S v` has `S_kk` on `v_k²` and `2 S_kl` on `v_k v_l` (exact: `S` holds
    /// multiples of a power of two with room to spare).
    #[allow(non_snake_case)]
    fn multiplier_coefficient(&self, S: &DMatrix<f64>, g: usize) -> f64 {
        let e = self
            .products
            .iter()
            .find(|(_, &i)| i == g)
            .map(|(e, _)| e)
            .expect("a degree-2 monomial");
        let ones: Vec<usize> = (0..self.n).filter(|&k| e[k] > 0).collect();
        match ones.as_slice() {
            [k] => S[(*k, *k)],
            [k, l] => 2.0 * S[(*k, *l)],
            _ => unreachable!("a degree-2 monomial has one or two variables"),
        }
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

/// One piece of a block's certificate: its conditions hold for every direction (no
/// multipliers), or only on a cone of directions and its negative, through multipliers
/// `q_j(v) = vᵀ S_j v ≥ 0` there (level 1; module docs, "Sectors").
#[allow(non_snake_case)]
struct Piece {
    multipliers: Vec<DMatrix<f64>>,
}

#[allow(non_snake_case)]
fn certify_block(
    problem: &FusionProblem,
    gain: Option<&DMatrix<f64>>,
    family: Family,
    settings: &CertifySettings,
) -> Result<BlockCertificate, SolveError> {
    let n = problem.dim();
    let (level, pieces) = match family {
        Family::Global(level) => (
            level,
            vec![Piece {
                multipliers: Vec::new(),
            }],
        ),
        Family::Sectors(count) | Family::Cones(count) => {
            let pieces = cone_multipliers(n, count)?
                .into_iter()
                .map(|multipliers| Piece { multipliers })
                .collect::<Vec<_>>();
            (1, pieces)
        }
    };
    let lay = Layout::new(n, level as usize);
    let (m, s, N) = (lay.m, lay.mons.len(), lay.big());
    let nb = lay.lower.len();
    let J0 = |p: usize, q: usize| match (p < n, q < n) {
        (true, true) => problem.P_a[(p, q)],
        (false, false) => problem.P_b[(p - n, q - n)],
        _ => 0.0,
    };
    // Variables: Q (svec of n), K_a (n², when free), then per piece C (svec of N), G (svec of
    // s) and, per multiplier of the piece, C' (svec of m) and g' (one).
    let var_q = |k: usize, l: usize| svec_index(k.min(l), k.max(l));
    let off_k = n * (n + 1) / 2;
    let var_k = |k: usize, i: usize| off_k + k + i * n;
    let mut next = off_k + if gain.is_none() { n * n } else { 0 };
    struct Offsets {
        c: usize,
        g: usize,
        /// Per multiplier: the offsets of its C' and of its g'.
        mult: Vec<(usize, usize)>,
    }
    let offsets: Vec<Offsets> = pieces
        .iter()
        .map(|piece| {
            let c = next;
            let g = c + N * (N + 1) / 2;
            next = g + s * (s + 1) / 2;
            let mult = piece
                .multipliers
                .iter()
                .map(|_| {
                    let cp = next;
                    next = cp + m * (m + 1) / 2 + 1;
                    (cp, cp + m * (m + 1) / 2)
                })
                .collect();
            Offsets { c, g, mult }
        })
        .collect();
    let total_vars = next;
    let var_c = |o: &Offsets, x: usize, y: usize| o.c + svec_index(x.min(y), x.max(y));
    let var_g = |o: &Offsets, a: usize, b: usize| o.g + svec_index(a.min(b), a.max(b));
    let var_cp = |cp: usize, x: usize, y: usize| cp + svec_index(x.min(y), x.max(y));

    // Condition 2: per piece, one group of C entries per (γ, unknown (i, j)) that must sum to
    // zero.
    let mut groups: Vec<Vec<usize>> = Vec::new();
    // Condition 3, per piece one row per degree-2r monomial γ.
    let mut sos: Vec<BTreeMap<usize, f64>> = Vec::new();
    for (piece, o) in pieces.iter().zip(&offsets) {
        let mut by_key: BTreeMap<(usize, usize, usize), Vec<usize>> = BTreeMap::new();
        for a in 0..s {
            for b in 0..s {
                let g = lay.sum[a][b];
                for i in 0..n {
                    for j in 0..n {
                        if problem.cross_pattern.is_unknown(i, j) {
                            by_key.entry((g, i, j)).or_default().push(var_c(
                                o,
                                a * m + i,
                                b * m + n + j,
                            ));
                        }
                    }
                }
            }
        }
        groups.extend(by_key.into_values());
        let mut rows = vec![BTreeMap::new(); lay.products.len()];
        for (beta, c) in &lay.lower {
            for k in 0..n {
                for l in 0..n {
                    *rows[lay.quad(beta, k, l)].entry(var_q(k, l)).or_default() += c;
                }
            }
        }
        for a in 0..s {
            for b in 0..s {
                let row = &mut rows[lay.sum[a][b]];
                for p in 0..m {
                    for q in 0..m {
                        let j = J0(p, q);
                        if j != 0.0 {
                            *row.entry(var_c(o, a * m + p, b * m + q)).or_default() -= j;
                        }
                    }
                }
                *row.entry(var_g(o, a, b)).or_default() -= 1.0;
            }
        }
        for (S, &(_, gp)) in piece.multipliers.iter().zip(&o.mult) {
            for (g, row) in rows.iter_mut().enumerate() {
                let sg = lay.multiplier_coefficient(S, g);
                if sg != 0.0 {
                    *row.entry(gp).or_default() -= sg;
                }
            }
        }
        sos.extend(rows);
    }
    let sqrt2 = std::f64::consts::SQRT_2;
    let zeros = groups.len() + sos.len();
    let cone = N + nb;
    let multipliers: usize = pieces.iter().map(|p| p.multipliers.len()).sum();
    let piece_rows = |piece: &Piece| {
        cone * (cone + 1) / 2 + s * (s + 1) / 2 + piece.multipliers.len() * m * (m + 1) / 2
    };
    let rows_total = zeros + pieces.iter().map(piece_rows).sum::<usize>() + multipliers;
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
    let mut base = zeros;
    let mut cones = vec![SupportedConeT::ZeroConeT(zeros)];
    let psd = |rows: &mut Vec<usize>,
               cols: &mut Vec<usize>,
               vals: &mut Vec<f64>,
               base: usize,
               size: usize,
               var: &dyn Fn(usize, usize) -> usize| {
        for c in 0..size {
            for r in 0..=c {
                rows.push(base + svec_index(r, c));
                cols.push(var(r, c));
                vals.push(if r == c { -1.0 } else { -sqrt2 });
            }
        }
    };
    // Per piece: condition 1 as [[C, W D^{1/2}], [·, I]] ⪰ 0, condition 4 (G ⪰ 0) and, per
    // multiplier, C' ⪰ 0.
    let mut schur_bases = Vec::with_capacity(pieces.len());
    for (piece, o) in pieces.iter().zip(&offsets) {
        psd(&mut rows, &mut cols, &mut vals, base, N, &|x, y| {
            var_c(o, x, y)
        });
        // The top left block is C − Σ_j S_j ⊗ C'_j (S_j the matrix of q_j):
        // (S ⊗ C')[(a,p),(b,q)] = S_ab C'_pq.
        let mut coef: BTreeMap<(usize, usize), f64> = BTreeMap::new();
        for (S, &(cp, _)) in piece.multipliers.iter().zip(&o.mult) {
            for c in 0..N {
                for r in 0..=c {
                    let (a, p, bb, q) = (r / m, r % m, c / m, c % m);
                    let w = if r == c { 1.0 } else { sqrt2 };
                    if S[(a, bb)] != 0.0 {
                        *coef
                            .entry((base + svec_index(r, c), var_cp(cp, p, q)))
                            .or_default() += w * S[(a, bb)];
                    }
                }
            }
        }
        for ((row, var), c) in coef {
            rows.push(row);
            cols.push(var);
            vals.push(c);
        }
        schur_bases.push(base);
        base += cone * (cone + 1) / 2;
        cones.push(SupportedConeT::PSDTriangleConeT(cone));
        psd(&mut rows, &mut cols, &mut vals, base, s, &|x, y| {
            var_g(o, x, y)
        });
        base += s * (s + 1) / 2;
        cones.push(SupportedConeT::PSDTriangleConeT(s));
        for &(cp, _) in &o.mult {
            psd(&mut rows, &mut cols, &mut vals, base, m, &|x, y| {
                var_cp(cp, x, y)
            });
            base += m * (m + 1) / 2;
            cones.push(SupportedConeT::PSDTriangleConeT(m));
        }
    }
    // g' ≥ 0 for each multiplier.
    for o in &offsets {
        for &(_, gp) in &o.mult {
            rows.push(base);
            cols.push(gp);
            vals.push(-1.0);
            base += 1;
        }
    }
    if multipliers > 0 {
        cones.push(SupportedConeT::NonnegativeConeT(multipliers));
    }
    debug_assert_eq!(base, rows_total);
    for &schur in &schur_bases {
        for (t, (beta, cb)) in lay.lower.iter().enumerate() {
            let scale = sqrt2 * cb.sqrt();
            for alpha in 0..s {
                let Some(k) = lay.step(alpha, beta) else {
                    continue;
                };
                for p in 0..m {
                    let e = schur + svec_index(alpha * m + p, N + t);
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
            b[schur + svec_index(N + t, N + t)] = 1.0;
        }
    }
    let mut q = vec![0.0; total_vars];
    for k in 0..n {
        q[var_q(k, k)] = 1.0;
    }
    let A = CscMatrix::new_from_triplets(rows_total, total_vars, rows, cols, vals);
    let P_quad = CscMatrix::zeros((total_vars, total_vars));
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
        let terms: Vec<f64> = group.iter().map(|&v| x[v]).collect();
        if !sums_to_zero(&terms) {
            return Err(repair_failed("the zero-sum groups"));
        }
    }
    let mut Q = DMatrix::from_fn(n, n, |k, l| x[var_q(k, l)]);
    let trace_solver = Q.trace();
    for (piece, o) in pieces.iter().zip(&offsets) {
        let C = DMatrix::from_fn(N, N, |r, c| x[var_c(o, r, c)]);
        let G = DMatrix::from_fn(s, s, |a, b| x[var_g(o, a, b)]);
        let parts = piece
            .multipliers
            .iter()
            .zip(&o.mult)
            .map(|(S, &(cp, gp))| MultiplierPart {
                S: S.clone(),
                Cp: DMatrix::from_fn(m, m, |r, c| x[var_cp(cp, r, c)]),
                gp: x[gp].max(0.0),
            })
            .collect();
        repair(problem, &lay, &K_a, C, &mut Q, &G, parts)?;
    }
    let repair = (Q.trace() - trace_solver).max(0.0);
    Ok(BlockCertificate {
        K_a,
        P: Q,
        status,
        iterations: sol.iterations,
        repair,
    })
}

/// Whether floats sum to exactly zero, decided exactly: Shewchuk's GROW-EXPANSION (Discrete
/// Comput. Geom. 18, 1997, Thm. 10) keeps the running sum as a nonoverlapping expansion,
/// which is zero exactly when all its components are.
fn sums_to_zero(terms: &[f64]) -> bool {
    let mut expansion: Vec<f64> = Vec::with_capacity(terms.len());
    for &t in terms {
        if !t.is_finite() {
            return false;
        }
        let mut q = t;
        for h in expansion.iter_mut() {
            // TwoSum(q, h): s + e = q + h exactly (no overflow below 2^1023).
            let s = q + *h;
            let bv = s - q;
            let e = (q - (s - bv)) + (*h - bv);
            *h = e;
            q = s;
        }
        expansion.push(q);
        if !q.is_finite() {
            return false;
        }
    }
    expansion.iter().all(|&h| h == 0.0)
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

/// One multiplier of a piece (module docs, "Sectors"): its matrix `S` (`q(v) = vᵀ S v`,
/// exact), `C'` and `g' ≥ 0`.
#[allow(non_snake_case)]
struct MultiplierPart {
    S: DMatrix<f64>,
    Cp: DMatrix<f64>,
    gp: f64,
}

/// The verified repair of one piece (module docs): `C ← C + δI` until `C − Σ S ⊗ C' − W D Wᵀ
/// ⪰ 0` is proven (each multiplier's `C' ← C' + δ'I` until `C' ⪰ 0` is, first), then `Q ← Q + ηI` until
/// `G + E ⪰ 0` is proven. `Q` only grows (by multiples of `I`), so a piece proven before
/// stays proven.
#[allow(non_snake_case)]
fn repair(
    problem: &FusionProblem,
    lay: &Layout,
    K_a: &DMatrix<f64>,
    C: DMatrix<f64>,
    Q: &mut DMatrix<f64>,
    G: &DMatrix<f64>,
    parts: Vec<MultiplierPart>,
) -> Result<(), SolveError> {
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
    // Each multiplier's C' ⪰ 0 proven first (its diagonal shifted if needed: the diagonal
    // holds no cross entry, and C enters only through C − Σ S ⊗ C', proven next).
    let zero = DMatrix::zeros(m, m);
    let parts = parts
        .into_iter()
        .map(|MultiplierPart { S, Cp, gp }| {
            let first = BallMatrix::exact(&Cp);
            let Cp = shift_until_proven(Cp, &first, "C' ⪰ 0", |shifted| is_psd(shifted, &zero))?;
            Ok(MultiplierPart { S, Cp, gp })
        })
        .collect::<Result<Vec<_>, SolveError>>()?;
    let margin = |C: &DMatrix<f64>| {
        BallMatrix::from_fn(N, N, |x, y| {
            let mut d = Dot::new();
            d.add(Ball::exact(C[(x, y)]));
            for part in &parts {
                // − (S ⊗ C')[(a,p),(b,q)] = − S_ab C'_pq (level 1: x = a m + p).
                d.add_prod(
                    Ball::exact(-part.S[(x / m, y / m)]),
                    Ball::exact(part.Cp[(x % m, y % m)]),
                );
            }
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
    let C = shift_until_proven(C, &first, "C − W D Wᵀ", |shifted| {
        let b = margin(shifted).symmetrized();
        is_psd(&b.mid, &b.rad)
    })?;
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
        for part in &parts {
            for (g, d) in coef.iter_mut().enumerate() {
                let c = lay.multiplier_coefficient(&part.S, g);
                if c != 0.0 {
                    d.add_exact_prod(-c, part.gp);
                }
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
            return Ok(());
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

/// `M` itself when `first` (the enclosure of what must be PSD, formed from `M`) is proven
/// PSD, else `M + δI` with the smallest `δ` of a doubling sequence (from `psd_shift(first)`)
/// for which `proves` succeeds; `NotProven { what }` when none of 60 does.
#[allow(non_snake_case)]
fn shift_until_proven(
    M: DMatrix<f64>,
    first: &BallMatrix,
    what: &str,
    proves: impl Fn(&DMatrix<f64>) -> bool,
) -> Result<DMatrix<f64>, SolveError> {
    if is_psd(&first.mid, &first.rad) {
        return Ok(M);
    }
    let mut delta = psd_shift(first).ok_or_else(|| repair_failed(what))?;
    let scale = M.amax().max(f64::MIN_POSITIVE);
    for _ in 0..60 {
        let mut shifted = M.clone();
        for i in 0..shifted.nrows() {
            shifted[(i, i)] += delta;
        }
        if proves(&shifted) {
            return Ok(shifted);
        }
        delta = 2.0 * delta + 1e-16 * scale;
    }
    Err(repair_failed(what))
}

fn repair_failed(what: &str) -> SolveError {
    SolveError::NotProven { what: what.into() }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::CrossPattern;
    use rand::{Rng, SeedableRng};

    #[test]
    fn the_memo_keeps_the_last_blocks_used_and_changes_no_number() {
        // `n` one-state blocks with distinct variances (each cross block wholly unknown: CI's
        // bound, so cheap); `shift` moves every variance.
        let problem = |n: usize, shift: f64| {
            let d = |f: fn(usize) -> f64| {
                DMatrix::from_fn(n, n, |i, j| if i == j { f(i) + shift } else { 0.0 })
            };
            FusionProblem::from_covariances(
                d(|i| 1.0 + i as f64),
                d(|i| 3.0 + 0.5 * i as f64),
                CrossPattern::diagonal(n),
            )
            .unwrap()
        };
        let settings = CertifySettings::default();
        let run = |memo: &mut CertificateMemo, p: &FusionProblem| {
            let got = certified_fusion_memo(p, &settings, memo).unwrap();
            assert_eq!(got, certified_fusion(p, &settings).unwrap());
            (memo.hits(), memo.len())
        };
        let mut memo = CertificateMemo::new();
        assert!(memo.is_empty());
        // Four blocks, twice: all four kept, then all four reused.
        assert_eq!(run(&mut memo, &problem(4, 0.0)), (0, 4));
        assert!(!memo.is_empty());
        assert_eq!(run(&mut memo, &problem(4, 0.0)), (4, 4));
        // MEMO_BLOCKS + 2 new blocks: the memo holds the last MEMO_BLOCKS of them.
        let big = problem(MEMO_BLOCKS + 2, 10.0);
        assert_eq!(run(&mut memo, &big), (4, MEMO_BLOCKS));
        // The first two were evicted first (least recently used); the cyclic order then
        // evicts each block before it comes round again: no hit, the same result.
        assert_eq!(run(&mut memo, &big), (4, MEMO_BLOCKS));
        // The blocks used last are kept: the last MEMO_BLOCKS of `big` again.
        let tail = FusionProblem::from_covariances(
            big.P_a
                .view((2, 2), (MEMO_BLOCKS, MEMO_BLOCKS))
                .into_owned(),
            big.P_b
                .view((2, 2), (MEMO_BLOCKS, MEMO_BLOCKS))
                .into_owned(),
            CrossPattern::diagonal(MEMO_BLOCKS),
        )
        .unwrap();
        assert_eq!(run(&mut memo, &tail), (4 + MEMO_BLOCKS as u64, MEMO_BLOCKS));
        // With a time limit the memo is neither read nor written.
        let limited = CertifySettings {
            time_limit: Some(60.0),
            ..settings
        };
        let mut fresh = CertificateMemo::new();
        for _ in 0..2 {
            certified_fusion_memo(&tail, &limited, &mut fresh).unwrap();
        }
        assert_eq!((fresh.hits(), fresh.len()), (0, 0));
    }

    #[test]
    #[allow(non_snake_case)]
    fn cones_cover_space_exactly_and_their_multipliers_are_the_normals_products() {
        // The proof needs: every v ≠ 0 lies in some cone or its negative, where each q_ij is
        // ≥ 0. Checked exactly in integers over every direction of a 17³ grid (the cones'
        // generators have entries up to 4, so the grid meets every cone's interior and
        // boundary), and each multiplier matrix, evaluated exactly (dyadic entries, small
        // integer v), equals the product of its two normals' forms up to its power-of-two
        // scale.
        for count in [4u32, 16, 64] {
            let cones = cone_generators(count).unwrap();
            let mults = cone_multipliers(3, count).unwrap();
            assert_eq!(cones.len(), count as usize);
            let cross = |a: [i64; 3], b: [i64; 3]| {
                [
                    a[1] * b[2] - a[2] * b[1],
                    a[2] * b[0] - a[0] * b[2],
                    a[0] * b[1] - a[1] * b[0],
                ]
            };
            let dot = |a: [i64; 3], b: [i64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
            let normals: Vec<[[i64; 3]; 3]> = cones
                .iter()
                .map(|u| [cross(u[1], u[2]), cross(u[2], u[0]), cross(u[0], u[1])])
                .collect();
            for x in -8i64..=8 {
                for y in -8i64..=8 {
                    for z in -8i64..=8 {
                        let v = [x, y, z];
                        if v == [0, 0, 0] {
                            continue;
                        }
                        let inside = normals.iter().position(|nn| {
                            let d = nn.map(|n| dot(n, v));
                            d.iter().all(|&t| t >= 0) || d.iter().all(|&t| t <= 0)
                        });
                        let k = inside.unwrap_or_else(|| panic!("{count} cones miss {v:?}"));
                        let d = normals[k].map(|n| dot(n, v));
                        for (S, (i, j)) in mults[k].iter().zip([(0, 1), (0, 2), (1, 2)]) {
                            let vf = v.map(|t| t as f64);
                            let mut q = 0.0;
                            for a in 0..3 {
                                for b in 0..3 {
                                    q += vf[a] * S[(a, b)] * vf[b];
                                }
                            }
                            let exact = (d[i] * d[j]) as f64;
                            assert!(q >= 0.0, "{count} cones: q < 0 at {v:?}");
                            // q = exact · 2^-e for the matrix's scale: the ratio is a power of
                            // two (or both are zero).
                            if exact == 0.0 {
                                assert_eq!(q, 0.0);
                            } else {
                                let ratio = q / exact;
                                assert_eq!(ratio, ratio.log2().round().exp2(), "{v:?}");
                            }
                        }
                    }
                }
            }
        }
        assert!(cone_generators(8).is_err());
        assert!(cone_multipliers(4, 4).is_err());
    }

    #[test]
    fn sector_multipliers_cover_the_plane_exactly() {
        // The proof needs only: every v ≠ 0 has some sector with q_k(v) ≥ 0. Checked exactly
        // (coefficients · 2¹² are integers, products in i128) on every integer direction of a
        // fine grid — a missing or inverted sector leaves an arc of π/S ≥ π/64 uncovered,
        // which holds many of them — and each q_k is positive inside its own sector's arc
        // and negative just outside both of its ends.
        for count in 2..=MAX_SECTORS {
            let q: Vec<[i128; 3]> = sector_multipliers(count)
                .unwrap()
                .iter()
                .map(|c| {
                    c.map(|x| {
                        let i = x * 4096.0;
                        assert_eq!(i, i.round(), "not an integer times 2⁻¹²");
                        i as i128
                    })
                })
                .collect();
            assert_eq!(q.len(), count as usize);
            let eval = |c: &[i128; 3], x: i128, y: i128| c[0] * x * x + c[1] * x * y + c[2] * y * y;
            for x in -300i128..=300 {
                for y in -300i128..=300 {
                    if (x, y) != (0, 0) {
                        assert!(
                            q.iter().any(|c| eval(c, x, y) >= 0),
                            "{count} sectors miss ({x}, {y})"
                        );
                    }
                }
            }
            for (k, c) in q.iter().enumerate() {
                let t = |f: f64| std::f64::consts::PI * (k as f64 + f) / count as f64;
                let at = |t: f64| ((1e6 * t.cos()) as i128, (1e6 * t.sin()) as i128);
                let (xm, ym) = at(t(0.5));
                assert!(eval(c, xm, ym) > 0, "{count}: sector {k} mid");
                for outside in [t(-0.3), t(1.3)] {
                    let (x, y) = at(outside);
                    assert!(eval(c, x, y) < 0, "{count}: sector {k} outside");
                }
            }
        }
        assert!(sector_multipliers(1).is_err());
    }

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
                assert!(sums_to_zero(&x));
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
