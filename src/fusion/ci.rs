//! Covariance intersection with the exactly optimal weight.
//!
//! CI (paper eq. (CI)): `P⁻¹ = ω P_a⁻¹ + (1−ω) P_b⁻¹`, `P⁻¹x = ω P_a⁻¹x_a + (1−ω) P_b⁻¹x_b`,
//! `ω ∈ [0, 1]`. In a basis `W` that diagonalizes the pencil `(P_a, P_b)` (`P_b = W Wᵀ`,
//! `P_a = W diag(μ) Wᵀ`, one generalized symmetric eigenproblem) every candidate is diagonal:
//!
//! `P(ω) = W diag(1 / dᵢ(ω)) Wᵀ`, `dᵢ(ω) = (1 − ω) + ω λᵢ`, `λᵢ = 1/μᵢ`,
//!
//! so `tr P(ω) = Σ ‖wᵢ‖²/dᵢ(ω)` and `log det P(ω) = log det WWᵀ − Σ ln dᵢ(ω)`. Both are convex
//! in `ω`; the optimum is an endpoint when the derivative does not change sign on `[0, 1]`
//! (then `ω` is exactly `0` or `1` and `P` is exactly `P_b` or `P_a`; a derivative within
//! `1e-9` of the size of its terms counts as zero, so rounding noise on a flat criterion does
//! not decide), otherwise the root of the derivative, found by safeguarded Newton (exact
//! second derivative, bisection when a step leaves the bracket) until the derivative is zero
//! to within `4ε` of the size of its terms — its sign then no longer says where the root is —
//! or a step moves `ω` by less than `4ε` relative: at most 8 steps on 40 random problems
//! (tested).
//!
//! ## The balanced pencil (accuracy)
//!
//! The textbook reduction factors `P_b = L Lᵀ` and diagonalizes `L⁻¹ P_a L⁻ᵀ`, whose
//! eigenvalues are the `μᵢ`. A symmetric eigensolver returns them with an *absolute* error of a
//! few `ε max μ`, so the small ones lose their relative accuracy: with the ratios `μ` spanning
//! `s = μ_max/μ_min`, some `dᵢ` carry a relative error of about `ε s`. Each of `P_a`, `P_b` of
//! condition number `κ` lets `s` reach `κ²`, while a relative change of `ε` in the inputs
//! moves `P(ω)` by about `ε κ`; at large `κ` it even returns negative `μᵢ` for positive
//! definite inputs (docs/methods.md has the measurements).
//!
//! Here the pencil is balanced instead:
//!
//! - `S = P_a + t P_b = L Lᵀ`, with `t = 2ᵏ` from the diagonal ratios ([`balance`]), so
//!   `t P_b` is exact (unless an entry leaves the normal range) and `S` rounds once per entry.
//! - `L⁻¹ P_a L⁻ᵀ = V diag(ν) Vᵀ` and `L⁻¹ (t P_b) L⁻ᵀ = I − V diag(ν) Vᵀ`, so
//!   `νᵢ = μᵢ/(μᵢ + t)` and `ηᵢ = 1 − νᵢ = t/(μᵢ + t)` both lie in `(0, 1)`. Their absolute
//!   error of a few `ε` is a relative error of a few `ε` for every `νᵢ, ηᵢ ≥ ½`. `ηᵢ = 1 − νᵢ`
//!   is exact for `νᵢ ≥ ½` (Sterbenz) and rounds once below.
//! - An end below `2⁻¹⁰` is recomputed as a Rayleigh quotient of the original matrices at the
//!   generalized eigenvector `sᵢ = L⁻ᵀ vᵢ`: `νᵢ = sᵢᵀ P_a sᵢ`, `ηᵢ = t sᵢᵀ P_b sᵢ`. The
//!   quadratic form's rounding is relative to the matrix it is taken of, so a direction in which
//!   `P_b` is small keeps the accuracy of `P_b` there.
//! - Then `μᵢ = t νᵢ/ηᵢ`, `λᵢ = ηᵢ/(t νᵢ)` and `W = L V diag(√(ηᵢ/t))`. This is the
//!   representation above: `W Wᵀ = L (I − V diag(ν) Vᵀ) Lᵀ / t = P_b`, `W diag(μ) Wᵀ = P_a`.
//!   `dᵢ = (1 − ω) + ω λᵢ` is a sum of non-negative terms, so it keeps their accuracy.
//!
//! Accuracy is a tested statement, not a proven one: against 50-digit references of random
//! pairs of condition number `κ = 10²…10¹⁵` the relative error of `P` is within `4 ε κ` (the
//! Python tests), and on exact co-diagonal pairs of `κ = 2²⁰, 2⁴⁰` (ratios spanning `κ²`) within
//! `16 ε κ` of the exact answer (`tests/native/ci.rs`); ICI and EI, which use this basis, are
//! tested alike. CI's conservativeness holds to the same relative accuracy. Where a bound must
//! hold in floating point, the bracket recomputes CI's with enclosed rounding
//! ([`bracket`](super::bracket)). When a computed `νᵢ` or `ηᵢ` is still not positive, the pair
//! is beyond what floating point resolves and [`InputError::UnresolvedPair`] says so; when `S`
//! itself does not factor, [`InputError::Unfactored`] does (no input is named: each was
//! accepted).
//!
//! Filters that keep their estimates in blocks (the tracking study) use the in-place forms
//! `ci_in_place` / `nmci_in_place`: means and covariances only, endpoints decided from the
//! derivative at `ω = 0` and `1` before any eigenproblem, and blocks with equal covariances
//! in both estimates sharing one pencil.

use nalgebra::{DMatrix, DVector};

use super::scale::two_to;
use super::{
    covariance_twins, definiteness_error, scatter_block, BlockMean, Criterion, Fused,
    FusionProblem, MeanPlan,
};
use crate::error::InputError;
use crate::linalg::{
    cholesky, solve_lower_in_place, solve_lower_rows, solve_lower_transposed_rows, symmetric_eigen,
    symmetrize, symmetrize_in_place,
};

/// CI result: the fused estimate and the optimal weight `ω` on estimate `a`.
#[derive(Debug, Clone, PartialEq)]
pub struct CiResult {
    /// Fused estimate, bound and gains.
    pub fused: Fused,
    /// Weight on `P_a⁻¹` (`0` = take `b`, `1` = take `a`).
    pub omega: f64,
}

/// `P_a + t P_b` (positive definite in exact arithmetic for accepted `P_a`, `P_b`) or the
/// pencil matrix formed from its factor could not be factored (module docs).
fn unfactored(matrix: &str) -> InputError {
    InputError::Unfactored {
        matrix: matrix.into(),
        inputs: "P_a and P_b".into(),
    }
}

/// `X = L⁻¹ A` for lower-triangular `L` and symmetric `A`, returned as its transpose `Xᵀ`:
/// `A`'s column-major buffer is also row-major, so the row solve leaves `X` row by row, i.e.
/// the column-major buffer holds `Xᵀ`.
#[allow(non_snake_case)]
fn left_solve(L: &DMatrix<f64>, A: &DMatrix<f64>) -> DMatrix<f64> {
    let mut Xt = A.clone();
    solve_lower_rows(L, Xt.as_mut_slice());
    Xt
}

/// `L⁻¹ A L⁻ᵀ = L⁻¹ Xᵀ` (symmetrized) from [`left_solve`]'s `Xᵀ`: the column-major transpose
/// of `Xᵀ` is `Xᵀ` in row-major order, so one more row solve.
#[allow(non_snake_case)]
fn congruence(L: &DMatrix<f64>, Xt: &DMatrix<f64>) -> DMatrix<f64> {
    let mut M = Xt.transpose();
    solve_lower_rows(L, M.as_mut_slice());
    symmetrize(&M)
}

/// `P_b = L Lᵀ` and `X = L⁻¹ P_a`: what the derivative of the criterion at `ω = 1` needs, so
/// that an endpoint optimum is found without the pencil's eigenproblem.
#[allow(non_snake_case)]
struct HalfPencil {
    L: DMatrix<f64>,
    /// `Xᵀ` (the row solve's output layout; only `‖X‖_F` and `L⁻¹Xᵀ` are used).
    Xt: DMatrix<f64>,
}

#[allow(non_snake_case)]
impl HalfPencil {
    fn new(P_a: &DMatrix<f64>, P_b: &DMatrix<f64>) -> Result<Self, InputError> {
        let L = cholesky(P_b)
            .ok_or_else(|| definiteness_error("P_b", P_b))?
            .unpack();
        let Xt = left_solve(&L, P_a);
        Ok(Self { L, Xt })
    }

    /// `M = L⁻¹ P_a L⁻ᵀ = L⁻¹ Xᵀ` (symmetrized).
    fn pencil_matrix(&self) -> DMatrix<f64> {
        congruence(&self.L, &self.Xt)
    }

    /// The criterion's derivative at `ω = 1` (where `P = P_a`): `−tr P_a + tr(P_a P_b⁻¹ P_a)`
    /// for the trace, `−n + tr(P_b⁻¹ P_a)` for log-det. Returns the derivative and the size of
    /// its terms, as [`derivatives`] does.
    fn derivative_at_one(&self, P_a: &DMatrix<f64>, criterion: Criterion) -> (f64, f64) {
        let (plus, minus) = match criterion {
            Criterion::Trace => (self.Xt.norm_squared(), P_a.trace()),
            // tr(P_b⁻¹ P_a) = tr(L⁻ᵀ L⁻¹ P_a) = tr(L⁻¹ P_a L⁻ᵀ) = tr M
            Criterion::Logdet => (self.pencil_matrix().trace(), P_a.nrows() as f64),
        };
        (plus - minus, plus + minus)
    }

    /// The criterion's derivative at `ω = 0` (where `P = P_b`): `tr P_b − tr(P_b P_a⁻¹ P_b)`
    /// for the trace, `n − tr(P_a⁻¹ P_b)` for log-det (one Cholesky factorization of `P_a`).
    fn derivative_at_zero(
        &self,
        P_a: &DMatrix<f64>,
        P_b: &DMatrix<f64>,
        criterion: Criterion,
    ) -> Result<(f64, f64), InputError> {
        let L_a = cholesky(P_a)
            .ok_or_else(|| definiteness_error("P_a", P_a))?
            .unpack();
        let (plus, minus) = match criterion {
            Criterion::Trace => {
                let mut Y = P_b.clone();
                solve_lower_rows(&L_a, Y.as_mut_slice()); // (L_a⁻¹ P_b)ᵀ: same norm
                (P_b.trace(), Y.norm_squared())
            }
            Criterion::Logdet => {
                let mut Y = self.L.clone();
                solve_lower_in_place(&L_a, Y.as_mut_slice());
                (P_a.nrows() as f64, Y.norm_squared())
            }
        };
        Ok((plus - minus, plus + minus))
    }
}

/// The CI family of one problem in its diagonalizing basis (shared with ICI and EI, which are
/// diagonal in the same basis: `P_b = W Wᵀ`, `P_a = W diag(μ) Wᵀ`), computed through the
/// balanced pencil of the module docs (`S = P_a + t P_b = L Lᵀ`).
#[allow(non_snake_case)]
pub(super) struct Pencil {
    /// Cholesky factor `L` of `S = P_a + t P_b`.
    L: DMatrix<f64>,
    /// Eigenvectors `V` of `L⁻¹ P_a L⁻ᵀ`.
    V: DMatrix<f64>,
    /// `√(ηᵢ/t)`: `W = L V diag(√(ηᵢ/t))`.
    scales: Vec<f64>,
    /// `W`, with `P_b = W Wᵀ`.
    pub(super) basis: DMatrix<f64>,
    /// `‖wᵢ‖²`.
    pub(super) weights: Vec<f64>,
    /// `λᵢ = 1/μᵢ = ηᵢ/(t νᵢ)`, the generalized eigenvalues of `(P_a⁻¹, P_b⁻¹)`.
    lambda: Vec<f64>,
    /// `λᵢ − 1`, the derivative of `dᵢ(ω)`.
    slopes: Vec<f64>,
    /// `μᵢ = t νᵢ/ηᵢ` (`P_a = W diag(μ) Wᵀ`).
    pub(super) mu: Vec<f64>,
}

/// The balancing power of two `t = 2ᵏ` of the pencil `(P_a, P_a + t P_b)`: `k` the rounded
/// mean of the extreme `log₂` ratios of the diagonals, `log₂(P_a[i,i]/P_b[i,i])`. These are
/// Rayleigh quotients of the pencil, so `t` is within a factor `√2` (the rounding of `k`) of
/// `[μ_min, μ_max]`, near its middle on a log scale when the diagonal ratios span it (module
/// docs).
#[allow(non_snake_case)]
fn balance(P_a: &DMatrix<f64>, P_b: &DMatrix<f64>) -> f64 {
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for i in 0..P_a.nrows() {
        let r = P_a[(i, i)].log2() - P_b[(i, i)].log2();
        lo = lo.min(r);
        hi = hi.max(r);
    }
    let k = (0.5 * (lo + hi)).round();
    // Positive definite inputs have positive finite diagonals; anything else is balanced by 1.
    if k.is_finite() {
        two_to(k.clamp(-1000.0, 1000.0) as i32)
    } else {
        1.0
    }
}

/// Below this, an eigenvalue `νᵢ` of the balanced pencil (or its complement `ηᵢ = 1 − νᵢ`)
/// is recomputed as a Rayleigh quotient: its absolute error of a few `ε` would be more than
/// about `10³ ε` relative (module docs).
const RAYLEIGH_BELOW: f64 = 1.0 / 1024.0;

/// `sᵀ A s`.
fn quadratic_form(a: &DMatrix<f64>, s: &[f64]) -> f64 {
    let n = s.len();
    let mut sum = 0.0;
    for (j, col) in a.as_slice().chunks_exact(n).enumerate() {
        let dot: f64 = col.iter().zip(s).map(|(x, y)| x * y).sum();
        sum += s[j] * dot;
    }
    sum
}

#[allow(non_snake_case)]
impl Pencil {
    pub(super) fn new(P_a: &DMatrix<f64>, P_b: &DMatrix<f64>) -> Result<Self, InputError> {
        let t = balance(P_a, P_b);
        // t P_b is exact (a power of two) unless an entry leaves the normal range; S rounds
        // once per entry.
        let S = P_a + P_b * t;
        let L = cholesky(&S)
            .ok_or_else(|| unfactored("P_a + t P_b"))?
            .unpack();
        let M = congruence(&L, &left_solve(&L, P_a));
        // Off-diagonal entries below 4ε relative to their diagonal neighbours count as zero
        // (nalgebra's default is ε): eigenvalues still accurate to ~1e-15 ‖M‖ ≤ 1e-15, ~15 %
        // fewer QR sweeps. nalgebra's `SymmetricEigen` without an iteration limit, bit for bit
        // (`linalg::symmetric_eigen`, whose docs say why it ends).
        let (nu, V) =
            symmetric_eigen(M, 4.0 * f64::EPSILON).ok_or_else(|| unfactored("L⁻¹ P_a L⁻ᵀ"))?;
        // νᵢ and ηᵢ = 1 − νᵢ (exact for νᵢ ≥ ½, one rounding below), then the end that is small
        // enough to have lost relative accuracy recomputed as a Rayleigh quotient (module docs).
        let mut ends: Vec<(f64, f64)> = nu.iter().map(|&nu| (nu, 1.0 - nu)).collect();
        for (i, (nu, eta)) in ends.iter_mut().enumerate() {
            if *nu < RAYLEIGH_BELOW || *eta < RAYLEIGH_BELOW {
                // sᵢ = L⁻ᵀ vᵢ, the generalized eigenvector (one row for the row solve).
                let mut s = V.column(i).as_slice().to_vec();
                solve_lower_transposed_rows(&L, &mut s);
                if *nu < RAYLEIGH_BELOW {
                    *nu = quadratic_form(P_a, &s);
                }
                if *eta < RAYLEIGH_BELOW {
                    *eta = t * quadratic_form(P_b, &s);
                }
            }
        }
        // Both are positive for positive definite P_a, P_b; a non-positive or non-finite one
        // is beyond what the computation resolves.
        if !ends
            .iter()
            .all(|&(nu, eta)| nu > 0.0 && eta > 0.0 && nu.is_finite() && eta.is_finite())
        {
            let ratios = ends.iter().map(|&(nu, eta)| t * nu / eta);
            let lo = ratios.clone().fold(f64::INFINITY, f64::min);
            let hi = ratios.fold(f64::NEG_INFINITY, f64::max);
            return Err(InputError::UnresolvedPair {
                min_ratio: lo,
                max_ratio: hi,
            });
        }
        let scales: Vec<f64> = ends.iter().map(|&(_, eta)| (eta / t).sqrt()).collect();
        let lambda: Vec<f64> = ends.iter().map(|&(nu, eta)| eta / (t * nu)).collect();
        let slopes = lambda.iter().map(|l| l - 1.0).collect();
        let mu = ends.iter().map(|&(nu, eta)| t * nu / eta).collect();
        let mut basis = &L * &V;
        for (mut col, s) in basis.column_iter_mut().zip(&scales) {
            col *= *s;
        }
        let weights = basis.column_iter().map(|c| c.norm_squared()).collect();
        Ok(Self {
            L,
            V,
            scales,
            basis,
            weights,
            lambda,
            slopes,
            mu,
        })
    }

    /// `dᵢ(ω) = (1 − ω) + ω λᵢ`: `P(ω)⁻¹ = W⁻ᵀ diag(dᵢ) W⁻¹`; a sum of two non-negative terms,
    /// so it keeps its relative accuracy for every `λᵢ`.
    fn d(&self, i: usize, omega: f64) -> f64 {
        (1.0 - omega) + omega * self.lambda[i]
    }

    /// `W⁻¹ x = diag(√(t/ηᵢ)) Vᵀ L⁻¹ x`: a vector's coordinates in the basis (`O(n²)`, no
    /// inverse formed).
    pub(super) fn coordinates(&self, x: &DVector<f64>) -> DVector<f64> {
        let mut y = x.clone();
        solve_lower_in_place(&self.L, y.as_mut_slice());
        let mut c = self.V.tr_mul(&y);
        for (c, s) in c.iter_mut().zip(&self.scales) {
            *c /= s;
        }
        c
    }

    /// `W⁻¹ = diag(√(t/ηᵢ)) Vᵀ L⁻¹`.
    pub(super) fn basis_inv(&self) -> DMatrix<f64> {
        // The column-major buffer of Vᵀ is V row by row; the row solve leaves (L⁻ᵀV)ᵀ = Vᵀ L⁻¹
        // in it, column-major.
        let mut Z = self.V.transpose();
        solve_lower_transposed_rows(&self.L, Z.as_mut_slice());
        for (mut row, s) in Z.row_iter_mut().zip(&self.scales) {
            row /= *s;
        }
        Z
    }

    /// `W diag(s) R`.
    pub(super) fn scaled_product(
        &self,
        scales: impl Iterator<Item = f64>,
        right: &DMatrix<f64>,
    ) -> DMatrix<f64> {
        let mut scaled = self.basis.clone();
        for (mut col, s) in scaled.column_iter_mut().zip(scales) {
            col *= s;
        }
        scaled * right
    }

    /// `P(ω) = W diag(1/dᵢ) Wᵀ`.
    fn covariance(&self, omega: f64) -> DMatrix<f64> {
        // P = U Uᵀ with U = W diag(1/√dᵢ) (dᵢ > 0 on [0, 1]).
        let mut U = self.basis.clone();
        for (i, mut col) in U.column_iter_mut().enumerate() {
            col /= self.d(i, omega).sqrt();
        }
        let mut P = &U * U.transpose();
        symmetrize_in_place(&mut P);
        P
    }

    /// `K_b = (1−ω) P P_b⁻¹ = W diag((1−ω)/dᵢ) W⁻¹` (since `P_b⁻¹ = W⁻ᵀ W⁻¹`).
    fn gain_b(&self, omega: f64) -> DMatrix<f64> {
        let s = (0..self.lambda.len()).map(|i| (1.0 - omega) / self.d(i, omega));
        self.scaled_product(s, &self.basis_inv())
    }

    /// The fused mean without the gains: with `P_a⁻¹ = W⁻ᵀ diag(λ) W⁻¹` and
    /// `P_b⁻¹ = W⁻ᵀ W⁻¹`, `x = P (ω P_a⁻¹ x_a + (1−ω) P_b⁻¹ x_b)
    /// = W diag(1/dᵢ) (ω λ ∘ W⁻¹x_a + (1−ω) W⁻¹x_b)`.
    pub(super) fn fused_mean(
        &self,
        x_a: &DVector<f64>,
        x_b: &DVector<f64>,
        omega: f64,
    ) -> DVector<f64> {
        let (u_a, u_b) = (self.coordinates(x_a), self.coordinates(x_b));
        let coords = DVector::from_fn(u_a.len(), |i, _| {
            (omega * self.lambda[i] * u_a[i] + (1.0 - omega) * u_b[i]) / self.d(i, omega)
        });
        &self.basis * coords
    }

    /// Overwrites the covariance `P_a` with that of the fusion with `P_b` at `ω` (exact at the
    /// endpoints); `shared` is the fused covariance when a twin block already computed it. The
    /// mean is [`BlockMean::ci`]'s.
    #[allow(non_snake_case)]
    fn fuse_covariance_into(
        &self,
        P_a: &mut DMatrix<f64>,
        P_b: &DMatrix<f64>,
        omega: f64,
        shared: Option<&DMatrix<f64>>,
    ) {
        if omega == 1.0 {
            return;
        }
        if omega == 0.0 {
            P_a.clone_from(P_b);
            return;
        }
        *P_a = shared.cloned().unwrap_or_else(|| self.covariance(omega));
    }
}

impl BlockMean {
    /// CI's mean at `ω` with pencil `pencil` of the plan: `x_a` at `ω = 1`, `x_b` at `ω = 0`
    /// (exactly), otherwise [`Pencil::fused_mean`].
    fn ci(omega: f64, pencil: usize) -> Self {
        if omega == 1.0 {
            BlockMean::Keep
        } else if omega == 0.0 {
            BlockMean::Take
        } else {
            BlockMean::Ci { pencil, omega }
        }
    }
}

/// Relative size below which a derivative at an endpoint counts as zero (a tie): then the
/// endpoint is optimal to within rounding, and taking it exactly keeps `ω` reproducible
/// between mathematically equal computations (identical estimates give `g ≡ 0`, whose sign is
/// rounding noise). CI's and ICI's (shared through [`minimise_convex`]).
pub(super) const ENDPOINT_TIE: f64 = 1e-9;

/// The pencils of the blocks that share one `ω`, each with its multiplicity: the blocks of a
/// block-diagonal problem each count in the criterion, and blocks with equal covariances in
/// both estimates ([`covariance_twins`]) share one pencil counted as often as they occur. CI
/// and ICI take their blocks in this one form.
pub(super) type Weighted<'a> = [(&'a Pencil, f64)];

/// First and second derivative at `ω` of the criterion summed over `pencils` (with their
/// multiplicities), and the size of the terms the first derivative sums (its rounding scale).
fn derivatives(pencils: &Weighted, criterion: Criterion, omega: f64) -> (f64, f64, f64) {
    let (mut d1, mut d2, mut size) = (0.0, 0.0, 0.0);
    for &(pencil, count) in pencils {
        let (mut p1, mut p2, mut psize) = (0.0, 0.0, 0.0);
        for (i, (c, s)) in pencil.weights.iter().zip(&pencil.slopes).enumerate() {
            let d = pencil.d(i, omega);
            match criterion {
                Criterion::Trace => {
                    p1 -= c * s / (d * d);
                    p2 += 2.0 * c * s * s / (d * d * d);
                    psize += c * (1.0 + s.abs()) / (d * d);
                }
                Criterion::Logdet => {
                    p1 -= s / d;
                    p2 += s * s / (d * d);
                    psize += (1.0 + s.abs()) / d;
                }
            }
        }
        d1 += count * p1;
        d2 += count * p2;
        size += count * psize;
    }
    (d1, d2, size)
}

/// The minimiser over `[0, 1]` of CI's (convex) criterion summed over `pencils`. An endpoint
/// is returned exactly when the derivative there does not point inwards (ties within
/// [`ENDPOINT_TIE`] go to the endpoint, `ω = 0` first).
fn optimal_omega(pencils: &Weighted, criterion: Criterion) -> f64 {
    solve_omega(pencils, criterion).0
}

/// [`optimal_omega`] and the number of derivative evaluations inside `(0, 1)` it took.
fn solve_omega(pencils: &Weighted, criterion: Criterion) -> (f64, usize) {
    minimise_convex(|omega| derivatives(pencils, criterion, omega))
}

/// The one minimiser of a convex criterion of `ω` over `[0, 1]` (CI's and ICI's), given its
/// derivative, second derivative and the size of the terms the derivative sums at `ω`:
/// an endpoint, exactly, when the derivative there does not point inwards (within
/// [`ENDPOINT_TIE`] of its size; `ω = 0` first); otherwise safeguarded Newton from `½` —
/// bisection when a step leaves the bracket — until the derivative is zero to within `4ε` of
/// its size (its sign then no longer says where the root is) or a step moves `ω` by less than
/// `4ε` relative. Returns `ω` and the number of interior evaluations.
pub(super) fn minimise_convex(derivatives: impl Fn(f64) -> (f64, f64, f64)) -> (f64, usize) {
    let (g0, _, size0) = derivatives(0.0);
    if g0 >= -ENDPOINT_TIE * size0 {
        return (0.0, 0);
    }
    let (g1, _, size1) = derivatives(1.0);
    if g1 <= ENDPOINT_TIE * size1 {
        return (1.0, 0);
    }
    // g is increasing (convex criterion), g(lo) < 0 < g(hi).
    let (mut lo, mut hi) = (0.0_f64, 1.0_f64);
    let mut omega = 0.5;
    for step in 1..=200 {
        let (g, h, size) = derivatives(omega);
        // Zero to within the rounding of its terms: the sign of g no longer tells which side
        // the root is on (bisecting further on noise took up to 50 steps).
        if g.abs() <= 4.0 * f64::EPSILON * size {
            return (omega, step);
        }
        if g < 0.0 {
            lo = omega;
        } else {
            hi = omega;
        }
        let newton = omega - g / h;
        let next = if h > 0.0 && newton > lo && newton < hi {
            newton
        } else {
            0.5 * (lo + hi)
        };
        if (next - omega).abs() <= 4.0 * f64::EPSILON * omega.max(1e-300) || hi - lo <= 0.0 {
            return (next, step);
        }
        omega = next;
    }
    (omega, 200)
}

/// `(P, K_a, K_b)` of one pencil at `ω`, exact at the endpoints.
#[allow(non_snake_case)]
fn fuse_at(
    pencil: &Pencil,
    P_a: &DMatrix<f64>,
    P_b: &DMatrix<f64>,
    omega: f64,
) -> (DMatrix<f64>, DMatrix<f64>, DMatrix<f64>) {
    let n = P_a.nrows();
    let (P, K_a) = if omega == 0.0 {
        (P_b.clone(), DMatrix::zeros(n, n))
    } else if omega == 1.0 {
        (P_a.clone(), DMatrix::identity(n, n))
    } else {
        let P = pencil.covariance(omega);
        let K_a = DMatrix::identity(n, n) - pencil.gain_b(omega);
        (P, K_a)
    };
    let K_b = DMatrix::identity(n, n) - &K_a;
    (P, K_a, K_b)
}

/// The CI covariance `P(ω) = (ω P_a⁻¹ + (1−ω) P_b⁻¹)⁻¹` for a given weight `ω ∈ [0, 1]`
/// (`ω = 0` gives `P_b` and `ω = 1` gives `P_a`, exactly; any other `ω`, NaN included, is
/// [`InputError::WeightOutOfRange`]).
#[allow(non_snake_case)]
pub fn ci_covariance(problem: &FusionProblem, omega: f64) -> Result<DMatrix<f64>, InputError> {
    if !(0.0..=1.0).contains(&omega) {
        return Err(InputError::WeightOutOfRange {
            name: "omega".into(),
            value: omega,
        });
    }
    if omega == 0.0 {
        return Ok(problem.P_b.clone());
    }
    if omega == 1.0 {
        return Ok(problem.P_a.clone());
    }
    Ok(Pencil::new(&problem.P_a, &problem.P_b)?.covariance(omega))
}

/// Covariance intersection with the weight that exactly minimises `criterion`.
///
/// ```
/// use nalgebra::{DMatrix, DVector};
/// use nmci::{Criterion, CrossPattern, FusionProblem, rules::covariance_intersection};
/// let d = |v: &[f64]| DMatrix::from_diagonal(&DVector::from_row_slice(v));
/// let p = FusionProblem::from_covariances(d(&[3.0, 1.0]), d(&[1.0, 4.0]),
///     CrossPattern::fully_unknown(2)).unwrap();
/// let ci = covariance_intersection(&p, Criterion::Trace).unwrap();
/// assert!(ci.omega > 0.0 && ci.omega < 1.0);
/// assert!(ci.fused.trace() > 2.0); // nmCI reaches 2 on this example
/// ```
#[allow(non_snake_case)]
pub fn covariance_intersection(
    problem: &FusionProblem,
    criterion: Criterion,
) -> Result<CiResult, InputError> {
    let pencil = Pencil::new(&problem.P_a, &problem.P_b)?;
    let omega = optimal_omega(&[(&pencil, 1.0)], criterion);
    let (P, K_a, K_b) = fuse_at(&pencil, &problem.P_a, &problem.P_b, omega);
    let x = &K_a * &problem.x_a + &K_b * &problem.x_b;
    Ok(CiResult {
        fused: Fused { x, P, K_a, K_b },
        omega,
    })
}

/// Monolithic CI (one `ω` for the whole state) on a problem whose covariances are
/// block-diagonal in `blocks` (each a list of state indices, together a partition of the
/// state): the pencil of the whole problem is the union of the blocks' pencils, so one small
/// eigenproblem per block gives the same exact `ω` and bound as [`covariance_intersection`] on
/// the dense matrices, at a fraction of the cost (8 blocks of 14 instead of one 112×112).
///
/// Entries of `P_a`, `P_b` outside the blocks must be exactly zero.
///
/// ```
/// use nalgebra::{DMatrix, DVector};
/// use nmci::prelude::*;
/// use nmci::rules::covariance_intersection_blocks;
/// let d = |v: &[f64]| DMatrix::from_diagonal(&DVector::from_row_slice(v));
/// let p = FusionProblem::from_covariances(d(&[3.0, 1.0]), d(&[1.0, 4.0]),
///     CrossPattern::fully_unknown(2)).unwrap();
/// let blocks = covariance_intersection_blocks(&p, &[vec![0], vec![1]], Criterion::Trace).unwrap();
/// let dense = covariance_intersection(&p, Criterion::Trace).unwrap();
/// assert!((blocks.omega - dense.omega).abs() < 1e-12);
/// ```
#[allow(non_snake_case)]
pub fn covariance_intersection_blocks(
    problem: &FusionProblem,
    blocks: &[Vec<usize>],
    criterion: Criterion,
) -> Result<CiResult, InputError> {
    let n = problem.dim();
    crate::structure::check_partition(n, blocks)?;
    let mut block_of = vec![0; n];
    for (b, block) in blocks.iter().enumerate() {
        for &i in block {
            block_of[i] = b;
        }
    }
    for i in 0..n {
        for j in 0..n {
            if block_of[i] != block_of[j] {
                for (name, m) in [("P_a", &problem.P_a), ("P_b", &problem.P_b)] {
                    if m[(i, j)] != 0.0 {
                        return Err(InputError::NotBlockDiagonal {
                            name: name.into(),
                            row: i,
                            col: j,
                            value: m[(i, j)],
                        });
                    }
                }
            }
        }
    }
    let subs: Vec<FusionProblem> = blocks.iter().map(|b| problem.restrict(b)).collect();
    let (parts, omega) = covariance_intersection_independent(&subs, criterion)?;
    let mut P = DMatrix::zeros(n, n);
    let mut K_a = DMatrix::zeros(n, n);
    for (block, part) in blocks.iter().zip(&parts) {
        scatter_block(&mut P, block, &part.P);
        scatter_block(&mut K_a, block, &part.K_a);
    }
    let K_b = DMatrix::identity(n, n) - &K_a;
    let x = &K_a * &problem.x_a + &K_b * &problem.x_b;
    Ok(CiResult {
        fused: Fused { x, P, K_a, K_b },
        omega,
    })
}

/// Monolithic CI (one `ω`) over independent sub-problems stored separately — the blocks of a
/// block-diagonal problem kept in block storage (as a tracking filter does). Returns each
/// block's fused result and the common weight; identical to [`covariance_intersection`] on
/// the assembled dense problem.
#[allow(non_snake_case)]
pub fn covariance_intersection_independent(
    blocks: &[FusionProblem],
    criterion: Criterion,
) -> Result<(Vec<Fused>, f64), InputError> {
    let pencils = blocks
        .iter()
        .map(|s| Pencil::new(&s.P_a, &s.P_b))
        .collect::<Result<Vec<_>, _>>()?;
    let refs: Vec<(&Pencil, f64)> = pencils.iter().map(|p| (p, 1.0)).collect();
    let omega = optimal_omega(&refs, criterion);
    let fused = blocks
        .iter()
        .zip(&pencils)
        .map(|(sub, pencil)| {
            let (P, K_a, K_b) = fuse_at(pencil, &sub.P_a, &sub.P_b, omega);
            let x = &K_a * &sub.x_a + &K_b * &sub.x_b;
            Fused { x, P, K_a, K_b }
        })
        .collect();
    Ok((fused, omega))
}

/// Each distinct pencil of block-stored estimates once, counted as often as its block occurs
/// (`pencils[k]` is `None` for a twin of an earlier block, `twins` from [`covariance_twins`]):
/// the one form in which CI and ICI sum their criterion over blocks.
pub(super) fn weighted<'a>(
    pencils: &'a [Option<Pencil>],
    twins: &[Option<usize>],
) -> Vec<(&'a Pencil, f64)> {
    let mut counts = vec![0.0; pencils.len()];
    for (k, twin) in twins.iter().enumerate() {
        counts[twin.unwrap_or(k)] += 1.0;
    }
    pencils
        .iter()
        .zip(&counts)
        .filter_map(|(p, &c)| p.as_ref().map(|p| (p, c)))
        .collect()
}

/// Monolithic CI of block-stored estimates, in place: `P_a[k] ← CI(P_a[k], P_b[k])` with one
/// common `ω` (the blocks are independent parts of one state), and the plan that fuses the
/// means ([`MeanPlan`]). For filters that keep their estimates in blocks (the tracking study);
/// no gains. Same `ω` and numbers as [`covariance_intersection_independent`] up to rounding.
/// Blocks whose covariances equal an earlier block's in both estimates ([`covariance_twins`])
/// share its pencil and fused covariance.
#[allow(non_snake_case)]
pub(crate) fn ci_in_place(
    P_a: &mut [DMatrix<f64>],
    P_b: &[DMatrix<f64>],
    criterion: Criterion,
) -> Result<(f64, MeanPlan), InputError> {
    let twins = covariance_twins(P_a, P_b);
    let mut pencils = Vec::with_capacity(P_a.len());
    for (k, twin) in twins.iter().enumerate() {
        pencils.push(match twin {
            Some(_) => None,
            None => Some(Pencil::new(&P_a[k], &P_b[k])?),
        });
    }
    let source = |k: usize| twins[k].unwrap_or(k);
    let omega = optimal_omega(&weighted(&pencils, &twins), criterion);
    for k in 0..P_a.len() {
        if let Some(pencil) = &pencils[source(k)] {
            // A twin's source t < k is fused already: its covariance is the twin's.
            let (done, rest) = P_a.split_at_mut(k);
            let shared = twins[k].map(|t| &done[t]);
            pencil.fuse_covariance_into(&mut rest[0], &P_b[k], omega, shared);
        }
    }
    let mut plan = MeanPlan::with_blocks(P_a.len());
    let slots: Vec<Option<usize>> = pencils
        .into_iter()
        .map(|p| p.map(|p| plan.push_pencil(p)))
        .collect();
    for k in 0..P_a.len() {
        // Every source has its pencil (only twins have none).
        plan.blocks.push(match slots[source(k)] {
            Some(slot) => BlockMean::ci(omega, slot),
            None => BlockMean::Keep,
        });
    }
    Ok((omega, plan))
}

/// nmCI of block-stored estimates in place: each block fused by CI with its own `ω`, returned
/// in block order with the plan that fuses the means ([`MeanPlan`]). The endpoints are tested
/// first from the criterion's derivative at `ω = 1` and `ω = 0` (one Cholesky factorization
/// each); only an interior optimum needs the eigendecomposition of the pencil. In a fusion
/// network most blocks of most fusions sit at an endpoint (one agent knows strictly more about
/// that part of the state), so nmCI in block storage is mostly factorizations. Twin blocks
/// ([`covariance_twins`]) share the work.
#[allow(non_snake_case)]
pub(crate) fn nmci_in_place(
    P_a: &mut [DMatrix<f64>],
    P_b: &[DMatrix<f64>],
    criterion: Criterion,
) -> Result<(Vec<f64>, MeanPlan), InputError> {
    let twins = covariance_twins(P_a, P_b);
    let mut plan = MeanPlan::with_blocks(P_a.len());
    // The plan's pencil of each block, when its ω is interior.
    let mut slots: Vec<Option<usize>> = Vec::with_capacity(P_a.len());
    let mut omegas: Vec<f64> = Vec::with_capacity(P_a.len());
    for (k, twin) in twins.iter().enumerate() {
        let (omega, slot) = match *twin {
            Some(t) => {
                let omega = omegas[t];
                match slots[t] {
                    Some(slot) => {
                        let (done, rest) = P_a.split_at_mut(k);
                        plan.pencils[slot].fuse_covariance_into(
                            &mut rest[0],
                            &P_b[k],
                            omega,
                            Some(&done[t]),
                        );
                    }
                    None if omega == 0.0 => P_a[k].clone_from(&P_b[k]),
                    None => {} // ω = 1: keep a
                }
                (omega, slots[t])
            }
            None => {
                let (omega, pencil) = ci_block_in_place(&mut P_a[k], &P_b[k], criterion)?;
                (omega, pencil.map(|p| plan.push_pencil(p)))
            }
        };
        plan.blocks.push(match slot {
            Some(slot) => BlockMean::ci(omega, slot),
            None if omega == 0.0 => BlockMean::Take,
            None => BlockMean::Keep,
        });
        omegas.push(omega);
        slots.push(slot);
    }
    Ok((omegas, plan))
}

/// CI of one block's covariance in place (`P_a ← CI(P_a, P_b)`): `ω`, and the pencil when `ω`
/// is interior.
#[allow(non_snake_case)]
fn ci_block_in_place(
    P_a: &mut DMatrix<f64>,
    P_b: &DMatrix<f64>,
    criterion: Criterion,
) -> Result<(f64, Option<Pencil>), InputError> {
    let half = HalfPencil::new(P_a, P_b)?;
    // g is non-decreasing (convex criterion): a clearly negative g(1) settles ω = 1 without
    // g(0); otherwise g(0) decides between ω = 0 (ties included, as in `optimal_omega`),
    // ω = 1 (a tie at 1) and an interior optimum.
    let (g1, size1) = half.derivative_at_one(P_a, criterion);
    if g1 < -ENDPOINT_TIE * size1 {
        return Ok((1.0, None));
    }
    let (g0, size0) = half.derivative_at_zero(P_a, P_b, criterion)?;
    if g0 >= -ENDPOINT_TIE * size0 {
        P_a.clone_from(P_b);
        return Ok((0.0, None));
    }
    if g1 <= ENDPOINT_TIE * size1 {
        return Ok((1.0, None));
    }
    let pencil = Pencil::new(P_a, P_b)?;
    let omega = optimal_omega(&[(&pencil, 1.0)], criterion);
    pencil.fuse_covariance_into(P_a, P_b, omega, None);
    Ok((omega, Some(pencil)))
}

#[cfg(test)]
#[allow(non_snake_case)]
mod tests {
    use super::*;
    use crate::fusion::{fuse_estimates, Estimate};
    use crate::structure::CrossPattern;

    use crate::linalg::test_spd as spd;

    fn gaussian(n: usize, seed: &mut u64, shift: f64) -> Estimate {
        let P = spd(n, seed, shift);
        let x = spd(n, seed, 0.0).column(0).into_owned();
        Estimate { x, P }
    }

    fn problem(a: &Estimate, b: &Estimate) -> FusionProblem {
        FusionProblem::new_trusted(
            a.x.clone(),
            a.P.clone(),
            b.x.clone(),
            b.P.clone(),
            CrossPattern::fully_unknown(a.x.len()),
        )
    }

    fn covs(e: &[Estimate]) -> Vec<DMatrix<f64>> {
        e.iter().map(|e| e.P.clone()).collect()
    }

    fn close(a: &DMatrix<f64>, b: &DMatrix<f64>) -> bool {
        (a - b).amax() <= 1e-10 * b.amax().max(1.0)
    }

    /// Blocks: interior optimum, `b` much better (ω = 0), `a` much better (ω = 1), a twin of
    /// block 0 (same covariances, other means) and identical estimates (a tie).
    fn blocks(criterion_seed: u64) -> (Vec<Estimate>, Vec<Estimate>) {
        let mut seed = criterion_seed;
        let n = 5;
        let (a0, b0) = (gaussian(n, &mut seed, 0.5), gaussian(n, &mut seed, 0.5));
        let (a1, b1) = (gaussian(n, &mut seed, 9.0), gaussian(n, &mut seed, 0.01));
        let (a2, b2) = (gaussian(n, &mut seed, 0.01), gaussian(n, &mut seed, 9.0));
        let mut a3 = gaussian(n, &mut seed, 1.0);
        let mut b3 = gaussian(n, &mut seed, 1.0);
        a3.P = a0.P.clone();
        b3.P = b0.P.clone();
        let a4 = gaussian(n, &mut seed, 1.0);
        let b4 = a4.clone();
        (vec![a0, a1, a2, a3, a4], vec![b0, b1, b2, b3, b4])
    }

    /// The balancing power of two is the rounded middle of the extreme diagonal log-ratios.
    /// `P_a + t P_b` that does not factor is `InputError::Unfactored`, naming the matrix and
    /// the pair (reached here with matrices the input checks would refuse: `P_a = −P_b`).
    #[test]
    fn a_pencil_that_does_not_factor_names_the_matrix() {
        let I = DMatrix::<f64>::identity(2, 2);
        let e = Pencil::new(&(-&I), &I).err().unwrap();
        assert!(matches!(e, InputError::Unfactored { .. }), "{e}");
        assert!(
            e.to_string()
                .starts_with("P_a + t P_b, formed from P_a and P_b and positive definite in exact arithmetic when they are"),
            "{e}"
        );
    }

    /// The endpoint test's factorizations of `P_b` and `P_a` (the study's filter covariances,
    /// not checked per step) name a failure as the input checks do: not positive definite only
    /// when proven. `P_b` below is positive definite as floats (smallest eigenvalue 1.1044);
    /// it was called "P_b is not positive definite (smallest eigenvalue 0)" before.
    #[test]
    fn the_endpoint_test_calls_a_covariance_indefinite_only_when_proven() {
        let I = DMatrix::<f64>::identity(2, 2);
        let undecidable = DMatrix::from_row_slice(
            2,
            2,
            &[
                1.5547804921864044e16,
                -2.2527755614633864e16,
                -2.2527755614633864e16,
                3.264124907555265e16,
            ],
        );
        let indefinite = DMatrix::from_row_slice(2, 2, &[1.0, 2.0, 2.0, 1.0]);
        let e = HalfPencil::new(&I, &undecidable).err().unwrap();
        assert!(matches!(e, InputError::Singular { .. }), "{e}");
        assert!(e.to_string().starts_with("P_b is singular"), "{e}");
        let e = HalfPencil::new(&I, &indefinite).err().unwrap();
        assert!(matches!(e, InputError::NotPositiveDefinite { .. }), "{e}");
        let half = HalfPencil::new(&I, &I).unwrap();
        let e = half
            .derivative_at_zero(&undecidable, &I, Criterion::Trace)
            .unwrap_err();
        assert!(e.to_string().starts_with("P_a is singular"), "{e}");
    }

    #[test]
    fn the_balance_is_the_power_of_two_between_the_diagonal_ratios() {
        let d = |v: &[f64]| DMatrix::from_diagonal(&DVector::from_row_slice(v));
        // log₂ ratios 2 and −6: the middle −2.
        assert_eq!(balance(&d(&[4.0, 1.0]), &d(&[1.0, 64.0])), 0.25);
        // Scaling P_b by 2¹⁰⁰ moves it by 2⁻¹⁰⁰, exactly.
        assert_eq!(
            balance(&d(&[4.0, 1.0]), &d(&[2f64.powi(100), 2f64.powi(106)])),
            2f64.powi(-102)
        );
        // log₂ ratios 0 and 1: the middle ½ rounds away from zero, to 2¹.
        assert_eq!(balance(&d(&[1.0, 2.0]), &d(&[1.0, 1.0])), 2.0);
        // Equal diagonals: 1.
        assert_eq!(balance(&d(&[3.0, 5.0]), &d(&[3.0, 5.0])), 1.0);
    }

    #[test]
    fn block_nmci_in_place_matches_per_block_ci() {
        for criterion in [Criterion::Trace, Criterion::Logdet] {
            let (mut a, b) = blocks(7);
            let reference: Vec<CiResult> = a
                .iter()
                .zip(&b)
                .map(|(a, b)| covariance_intersection(&problem(a, b), criterion).unwrap())
                .collect();
            let omegas = fuse_estimates(&mut a, &b, |a, b| nmci_in_place(a, b, criterion)).unwrap();
            assert_eq!(omegas[1], 0.0);
            assert_eq!(omegas[2], 1.0);
            assert_eq!(omegas[3], omegas[0]);
            assert!(omegas[0] > 0.0 && omegas[0] < 1.0);
            assert_eq!(omegas[4], 0.0, "a tie goes to ω = 0");
            for (k, r) in reference.iter().enumerate() {
                assert!((omegas[k] - r.omega).abs() < 1e-9, "{criterion:?} {k}");
                assert!(close(&a[k].P, &r.fused.P), "{criterion:?} block {k}");
                let x = DMatrix::from_column_slice(5, 1, a[k].x.as_slice());
                let rx = DMatrix::from_column_slice(5, 1, r.fused.x.as_slice());
                assert!(close(&x, &rx), "{criterion:?} mean {k}");
            }
        }
    }

    #[test]
    fn block_ci_in_place_matches_independent_ci() {
        for criterion in [Criterion::Trace, Criterion::Logdet] {
            let (mut a, b) = blocks(11);
            let problems: Vec<FusionProblem> =
                a.iter().zip(&b).map(|(a, b)| problem(a, b)).collect();
            let (fused, omega_ref) =
                covariance_intersection_independent(&problems, criterion).unwrap();
            let omega = fuse_estimates(&mut a, &b, |a, b| ci_in_place(a, b, criterion)).unwrap();
            assert!((omega - omega_ref).abs() < 1e-12);
            for (k, f) in fused.iter().enumerate() {
                assert!(close(&a[k].P, &f.P), "{criterion:?} block {k}");
                assert!((&a[k].x - &f.x).amax() < 1e-10, "{criterion:?} mean {k}");
            }
        }
    }

    /// Pairs whose CI optimum is interior: `P_a`, `P_b` random with comparable scales.
    fn interior_pairs(count: usize) -> Vec<(DMatrix<f64>, DMatrix<f64>)> {
        let mut seed = 5;
        let mut pairs = Vec::new();
        while pairs.len() < count {
            let n = 2 + pairs.len() % 4;
            let (a, b) = (spd(n, &mut seed, 0.1), spd(n, &mut seed, 0.1));
            let pencil = Pencil::new(&a, &b).unwrap();
            let w = optimal_omega(&[(&pencil, 1.0)], Criterion::Trace);
            if w > 0.0 && w < 1.0 && optimal_omega(&[(&pencil, 1.0)], Criterion::Logdet) > 0.0 {
                pairs.push((a, b));
            }
        }
        pairs
    }

    #[test]
    fn the_weight_is_found_by_newton_in_a_few_steps() {
        // The safeguard (bisection) alone needs ~50 steps to reach 4ε; Newton with the exact
        // second derivative converges quadratically: a wrong `d2` shows as many more steps.
        let mut most = 0;
        for (a, b) in interior_pairs(40) {
            let pencil = Pencil::new(&a, &b).unwrap();
            for criterion in [Criterion::Trace, Criterion::Logdet] {
                let (w, steps) = solve_omega(&[(&pencil, 1.0)], criterion);
                if w > 0.0 && w < 1.0 {
                    // The derivative vanishes there (to rounding of its terms).
                    let (g, _, size) = derivatives(&[(&pencil, 1.0)], criterion, w);
                    assert!(g.abs() <= 1e-12 * size, "{criterion:?}: g = {g:e}");
                    most = most.max(steps);
                }
            }
        }
        assert!(most <= 8, "Newton took up to {most} steps");
    }

    #[test]
    fn the_weight_does_not_depend_on_the_scale() {
        // CI's ω is invariant under P_a, P_b → c P_a, c P_b (both criteria change by a
        // constant): the endpoint tests and the stopping rule must be relative to the scale.
        for (a, b) in interior_pairs(10) {
            for criterion in [Criterion::Trace, Criterion::Logdet] {
                let at = |c: f64| {
                    let pencil = Pencil::new(&(&a * c), &(&b * c)).unwrap();
                    let w = optimal_omega(&[(&pencil, 1.0)], criterion);
                    // The in-place rule decides the endpoints its own way: the same ω.
                    let (w_in_place, _) =
                        ci_block_in_place(&mut (&a * c), &(&b * c), criterion).unwrap();
                    assert_eq!(w_in_place, w);
                    w
                };
                let w = at(1.0);
                for k in [-12, -8, -4, 4, 8, 12] {
                    let wk = at(10f64.powi(k));
                    assert!((wk - w).abs() <= 1e-12, "{criterion:?} 1e{k}: {wk} vs {w}");
                }
            }
        }
    }

    #[test]
    fn a_tie_goes_to_omega_zero_at_every_scale() {
        // Identical estimates: g ≡ 0, computed as rounding noise of either sign; the tie
        // tolerance scales with the terms, so the answer is ω = 0 at every scale and size.
        let mut seed = 13;
        for k in -8..=8 {
            for n in 1..=5 {
                let P = spd(n, &mut seed, 0.1) * 10f64.powi(k);
                let g = Estimate {
                    x: DVector::zeros(n),
                    P: P.clone(),
                };
                let p = problem(&g, &g);
                for criterion in [Criterion::Trace, Criterion::Logdet] {
                    let ci = covariance_intersection(&p, criterion).unwrap();
                    assert_eq!(ci.omega, 0.0, "CI 1e{k}, n = {n}, {criterion:?}");
                    let mut a = g.P.clone();
                    let (w, pencil) = ci_block_in_place(&mut a, &g.P, criterion).unwrap();
                    assert_eq!(w, 0.0, "in place 1e{k}, n = {n}, {criterion:?}");
                    assert!(pencil.is_none());
                }
            }
        }
    }

    #[test]
    fn endpoints_in_place_need_no_eigendecomposition() {
        // The in-place rule decides ω = 0 and ω = 1 from the derivatives at the endpoints
        // (Cholesky factorizations); only an interior optimum builds the pencil.
        let (a, b) = blocks(7);
        for criterion in [Criterion::Trace, Criterion::Logdet] {
            for (k, expected) in [(1, Some(0.0)), (2, Some(1.0)), (0, None)] {
                let mut fused = a[k].P.clone();
                let (w, pencil) = ci_block_in_place(&mut fused, &b[k].P, criterion).unwrap();
                match expected {
                    Some(endpoint) => {
                        assert_eq!(w, endpoint, "{criterion:?} block {k}");
                        assert!(pencil.is_none(), "{criterion:?} block {k}");
                    }
                    None => assert!(w > 0.0 && w < 1.0 && pencil.is_some()),
                }
            }
        }
    }

    #[test]
    fn twins_of_endpoint_blocks_take_the_endpoint() {
        // A twin (same covariances in both estimates, other means) of a block at ω = 0 takes
        // b's estimate, of a block at ω = 1 keeps a's: as CI of the twin alone would.
        let (a0, b0) = blocks(19);
        for criterion in [Criterion::Trace, Criterion::Logdet] {
            for k in [1, 2] {
                let mut seed = 40 + k as u64;
                let twin_a = Estimate {
                    x: gaussian(5, &mut seed, 1.0).x,
                    P: a0[k].P.clone(),
                };
                let twin_b = Estimate {
                    x: gaussian(5, &mut seed, 1.0).x,
                    P: b0[k].P.clone(),
                };
                let reference = covariance_intersection(&problem(&twin_a, &twin_b), criterion)
                    .unwrap()
                    .fused;
                let mut a = vec![a0[k].clone(), twin_a];
                let b = vec![b0[k].clone(), twin_b.clone()];
                assert_eq!(covariance_twins(&covs(&a), &covs(&b)), vec![None, Some(0)]);
                let omegas =
                    fuse_estimates(&mut a, &b, |a, b| nmci_in_place(a, b, criterion)).unwrap();
                assert_eq!(omegas, vec![if k == 1 { 0.0 } else { 1.0 }; 2]);
                assert_eq!(a[1].x, reference.x, "{criterion:?} block {k}");
                assert_eq!(a[1].P, reference.P, "{criterion:?} block {k}");
            }
        }
    }

    #[test]
    fn twins_are_exactly_equal_covariances_in_both() {
        let (a, b) = blocks(3);
        assert_eq!(
            covariance_twins(&covs(&a), &covs(&b)),
            vec![None, None, None, Some(0), None]
        );
    }
}
