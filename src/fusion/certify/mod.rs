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
//! **Adaptive cones** ([`CertifySettings::max_cones`], opt-in; `fusion::certify::refine`).
//! Uniform cones spend most of the program on directions where the bound has slack. The
//! adaptive family starts from the four octants, solves, and cuts in two the cones that
//! carry the most of the solver's dual: for piece `k` the dual of its condition-3 rows is a
//! moment matrix `M_k ⪰ 0` (the measure of worst directions the optimum rests on), and
//! stationarity in `Q` gives `Σ_k M_k = I`, so `tr M_k` is the piece's share of the
//! objective — zero where its certificate has slack. A cone is cut at the midpoint of its
//! widest edge (`u_i + u_j`), an exact subdivision (`bisect`), so every round's cones and
//! their negatives cover space and every round's certificate is a proof by the argument
//! above; the generators stay below `2¹²`, so the multipliers stay exact. Rounds continue
//! until the proven trace falls by less than `10⁻⁸` of itself, `max_cones` is reached or the
//! time limit passes (a round stopped by it leaves the best proof found); the smallest proven
//! trace is kept. The first round is the 4-cone program, so the result is never above the
//! 4-cone certificate (exactly; tested). The choice of cones decides only how tight the bound
//! is, never whether it is proven. docs/methods.md measures how far it closes the brackets.
//!
//! **At a given rule** ([`certify_rule`], three or four states; `fusion::certify::point`). The
//! families above choose the gain and the bound together. The cutting planes
//! (`fusion::cuts`) end with a rule `(K, P̄)` whose trace is within their tolerance of the
//! proven lower end, but `P̄ ⪰ K J Kᵀ` is known there only for the cuts they found.
//! `certify_rule` proves a bound for that `K` near `P̄`. With `K` fixed the pieces' conditions
//! share only `Q`, so each cone is certified on its own at `Q = P̄ + t_k I`, with the
//! smallest `t_k` (of either sign) of the cone's level-1 program with its three multipliers
//! — one PSD cone of 19 rows, not one program over every cone. From the four octants (for four
//! states the eight orthants, below), the cone
//! with the largest `t_k` above the target is cut in two ([`bisect`](geometry), an exact
//! subdivision, so the cones and their negatives always cover space) and both halves are
//! certified; a cone the solver fails on (an octant or a half) is cut in two in its place,
//! three times at most, and a cut whose parts would pass the budget or still fail leaves its
//! cone whole and uncut from then on. This goes on until every `t_k` is within the target (`rtol · tr P̄ / (8n)`),
//! the cone budget is spent or, under a time limit, the time left would no longer hold a cut
//! and the two passes proving every cone below (timed from the cones so far; the joint
//! program below then runs only where the time left, less a pass, holds twice what its cones
//! took alone, and is given that less once: the limit is kept by these estimates, not
//! overrun by the last steps). A cone whose larger half keeps 99 % of
//! its `t_k` four cuts in a row is not cut again: `P̄` itself is short there, and cutting
//! cannot help. The cones within the target hold at `P̄ + τI`, `τ` the largest of their
//! `t_k`. The others are certified together in one program with `Q ⪰ P̄` in place of
//! `Q = P̄ + tI`, so `Q − P̄` follows the directions where `P̄` is short; call its `Q`
//! `Q_open`. The bound is `Q = Q_open + max(τ, 0) I`, and every cone's certificate is repaired
//! against this one `Q` ("Exact in floating point" below). The proof is then the argument of
//! "Three states" above, with `K` given and each cone's `C`, `G`, `C′`, `g′` from its own
//! program. It rests on the exact cover and the repair, not on the solver's accuracy, and
//! holds whatever `P̄` is. What `P̄` decides is how small the repair and `Q − P̄` are: a
//! certificate found at `Q′` holds at every `Q ⪰ Q′` (its residual gains `vᵀ(Q − Q′)v ≥ 0`),
//! so the repair is of the solver's tolerance, and `Q − P̄` is about the largest
//! `λ_max(K J Kᵀ − P̄)` over the admissible `J`, where `P̄` is short of dominating. For the
//! cutting planes' `P̄` that is their stopping tolerance, plus the shrink of their cuts
//! (`CUT_SHRINK`). docs/methods.md measures how often this closes the brackets.
//!
//! *Four states* (`geometry`, generic in the dimension `N`): the cover starts from the eight
//! orthants of `v₄ ≥ 0`, spanned by `±e₁, ±e₂, ±e₃, e₄`; they and their negatives cover ℝ⁴.
//! A cone spanned by the rows `u_1, …, u_4` of an integer `U` has the facet normals
//! `n_i[c] = det U` with row `i` replaced by `e_c`, so `n_i·v = det U` with row `i` replaced by
//! `v`, which for `v = Σ_k λ_k u_k` is `λ_i det U` (for three states `n_i = u_j × u_k`). On the
//! cone and its negative all `n_i·v` share a sign, so the six products `q_ij = (n_i·v)(n_j·v)`
//! are non-negative there, and the argument of "Three states" holds with six multipliers per
//! cone. `bisect` is the same exact subdivision at the widest edge. The multipliers stay exact
//! while the generators' entries stay below `2⁷` (the normals, `3 × 3` minors, below `2²⁴`;
//! `2 S` below `2⁴⁹`), where `bisect` stops cutting. The cover, the subdivisions and the
//! multipliers are checked exactly in integers (unit tests, with a determinant written apart).
//! The cone budget counts the eight orthants, so it is at least 8 cones. `sdp_cuts` does not
//! run this proof at four states (`fusion::cuts`, "Its own rule, proven", says why).
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

mod assemble;
mod block;
mod geometry;
mod layout;
mod memo;
mod point;
mod refine;
mod repair;
mod rule;
mod settings;
mod sos;
#[cfg(test)]
mod tests;

pub use geometry::MAX_SECTORS;
pub use memo::{CertificateMemo, MEMO_BLOCKS};
pub use point::certify_rule;
pub(crate) use point::certify_rule_short;
pub(crate) use rule::certification_blocks;
pub use rule::{
    certified_fusion, certified_fusion_memo, certify_gain, Certificates, CertifiedResult,
};
pub use settings::{CertifySettings, Family, DEFAULT_SECTORS, MAX_BLOCK_DIM, MAX_CONES, MAX_LEVEL};
