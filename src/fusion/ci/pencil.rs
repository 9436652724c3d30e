//! CI's pencil `(P_a, P_b)` diagonalised once, balanced and factored (the parent's module docs,
//! "The balanced pencil"), and the fused covariance and mean at any `ω` from it.

use nalgebra::{DMatrix, DVector};

use crate::error::InputError;
use crate::fusion::scale::two_to;
use crate::fusion::{definiteness_error, BlockMean, Criterion};
use crate::linalg::{
    cholesky, cholesky_of, solve_lower_in_place, solve_lower_rows, solve_lower_transposed_rows,
    symmetric_eigen, symmetrize_in_place,
};

/// `P_a + t P_b` (positive definite in exact arithmetic for accepted `P_a`, `P_b`) or the
/// pencil matrix formed from its factor could not be factored (module docs).
pub(super) fn unfactored(matrix: &str) -> InputError {
    InputError::Unfactored {
        matrix: matrix.into(),
        inputs: "P_a and P_b".into(),
    }
}

/// `X = L⁻¹ A` for lower-triangular `L` and symmetric `A`, returned as its transpose `Xᵀ`:
/// `A`'s column-major buffer is also row-major, so the row solve leaves `X` row by row, i.e.
/// the column-major buffer holds `Xᵀ`.
#[allow(non_snake_case)]
pub(super) fn left_solve(L: &DMatrix<f64>, A: &DMatrix<f64>) -> DMatrix<f64> {
    let mut Xt = A.clone();
    solve_lower_rows(L, Xt.as_mut_slice());
    Xt
}

/// `L⁻¹ A L⁻ᵀ = L⁻¹ Xᵀ` (symmetrized) from [`left_solve`]'s `Xᵀ`, in its storage: the
/// column-major transpose of `Xᵀ` is `Xᵀ` in row-major order, so one more row solve.
#[allow(non_snake_case)]
pub(super) fn congruence(L: &DMatrix<f64>, mut Xt: DMatrix<f64>) -> DMatrix<f64> {
    Xt.transpose_mut();
    solve_lower_rows(L, Xt.as_mut_slice());
    symmetrize_in_place(&mut Xt);
    Xt
}

/// `P_b = L Lᵀ` and `X = L⁻¹ P_a`: what the derivative of the criterion at `ω = 1` needs, so
/// that an endpoint optimum is found without the pencil's eigenproblem.
#[allow(non_snake_case)]
pub(super) struct HalfPencil {
    pub(super) L: DMatrix<f64>,
    /// `Xᵀ` (the row solve's output layout; only `‖X‖_F` and `L⁻¹Xᵀ` are used).
    pub(super) Xt: DMatrix<f64>,
}

#[allow(non_snake_case)]
impl HalfPencil {
    pub(super) fn new(P_a: &DMatrix<f64>, P_b: &DMatrix<f64>) -> Result<Self, InputError> {
        let L = cholesky(P_b)
            .ok_or_else(|| definiteness_error("P_b", P_b))?
            .unpack();
        let Xt = left_solve(&L, P_a);
        Ok(Self { L, Xt })
    }

    /// `M = L⁻¹ P_a L⁻ᵀ = L⁻¹ Xᵀ` (symmetrized).
    pub(super) fn pencil_matrix(&self) -> DMatrix<f64> {
        congruence(&self.L, self.Xt.clone())
    }

    /// The criterion's derivative at `ω = 1` (where `P = P_a`): `−tr P_a + tr(P_a P_b⁻¹ P_a)`
    /// for the trace, `−n + tr(P_b⁻¹ P_a)` for log-det. Returns the derivative and the size of
    /// its terms, as [`derivatives`] does.
    pub(super) fn derivative_at_one(&self, P_a: &DMatrix<f64>, criterion: Criterion) -> (f64, f64) {
        let (plus, minus) = match criterion {
            Criterion::Trace => (self.Xt.norm_squared(), P_a.trace()),
            // tr(P_b⁻¹ P_a) = tr(L⁻ᵀ L⁻¹ P_a) = tr(L⁻¹ P_a L⁻ᵀ) = tr M
            Criterion::Logdet => (self.pencil_matrix().trace(), P_a.nrows() as f64),
        };
        (plus - minus, plus + minus)
    }

    /// The criterion's derivative at `ω = 0` (where `P = P_b`): `tr P_b − tr(P_b P_a⁻¹ P_b)`
    /// for the trace, `n − tr(P_a⁻¹ P_b)` for log-det (one Cholesky factorization of `P_a`).
    pub(super) fn derivative_at_zero(
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
pub(in crate::fusion) struct Pencil {
    /// Cholesky factor `L` of `S = P_a + t P_b`.
    pub(super) L: DMatrix<f64>,
    /// Eigenvectors `V` of `L⁻¹ P_a L⁻ᵀ`.
    pub(super) V: DMatrix<f64>,
    /// `√(ηᵢ/t)`: `W = L V diag(√(ηᵢ/t))`.
    pub(super) scales: Vec<f64>,
    /// `W`, with `P_b = W Wᵀ`.
    pub(in crate::fusion) basis: DMatrix<f64>,
    /// `‖wᵢ‖²`.
    pub(in crate::fusion) weights: Vec<f64>,
    /// `λᵢ = 1/μᵢ = ηᵢ/(t νᵢ)`, the generalized eigenvalues of `(P_a⁻¹, P_b⁻¹)`.
    pub(super) lambda: Vec<f64>,
    /// `λᵢ − 1`, the derivative of `dᵢ(ω)`.
    pub(super) slopes: Vec<f64>,
    /// `μᵢ = t νᵢ/ηᵢ` (`P_a = W diag(μ) Wᵀ`).
    pub(in crate::fusion) mu: Vec<f64>,
}

/// The balancing power of two `t = 2ᵏ` of the pencil `(P_a, P_a + t P_b)`: `k` the rounded
/// mean of the extreme `log₂` ratios of the diagonals, `log₂(P_a[i,i]/P_b[i,i])`. These are
/// Rayleigh quotients of the pencil, so `t` is within a factor `√2` (the rounding of `k`) of
/// `[μ_min, μ_max]`, near its middle on a log scale when the diagonal ratios span it (module
/// docs).
#[allow(non_snake_case)]
pub(super) fn balance(P_a: &DMatrix<f64>, P_b: &DMatrix<f64>) -> f64 {
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
pub(super) const RAYLEIGH_BELOW: f64 = 1.0 / 1024.0;

/// `sᵀ A s`.
pub(super) fn quadratic_form(a: &DMatrix<f64>, s: &[f64]) -> f64 {
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
    pub(in crate::fusion) fn new(
        P_a: &DMatrix<f64>,
        P_b: &DMatrix<f64>,
    ) -> Result<Self, InputError> {
        let t = balance(P_a, P_b);
        // t P_b is exact (a power of two) unless an entry leaves the normal range; S rounds
        // once per entry.
        let S = P_a.zip_map(P_b, |a, b| a + b * t);
        let L = cholesky_of(S)
            .ok_or_else(|| unfactored("P_a + t P_b"))?
            .unpack();
        let M = congruence(&L, left_solve(&L, P_a));
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
    pub(super) fn d(&self, i: usize, omega: f64) -> f64 {
        (1.0 - omega) + omega * self.lambda[i]
    }

    /// `W⁻¹ x = diag(√(t/ηᵢ)) Vᵀ L⁻¹ x`: a vector's coordinates in the basis (`O(n²)`, no
    /// inverse formed).
    pub(in crate::fusion) fn coordinates(&self, x: &DVector<f64>) -> DVector<f64> {
        let mut y = x.clone();
        solve_lower_in_place(&self.L, y.as_mut_slice());
        let mut c = self.V.tr_mul(&y);
        for (c, s) in c.iter_mut().zip(&self.scales) {
            *c /= s;
        }
        c
    }

    /// `W⁻¹ = diag(√(t/ηᵢ)) Vᵀ L⁻¹`.
    pub(in crate::fusion) fn basis_inv(&self) -> DMatrix<f64> {
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
    pub(in crate::fusion) fn scaled_product(
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
    pub(super) fn covariance(&self, omega: f64) -> DMatrix<f64> {
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
    pub(super) fn gain_b(&self, omega: f64) -> DMatrix<f64> {
        let s = (0..self.lambda.len()).map(|i| (1.0 - omega) / self.d(i, omega));
        self.scaled_product(s, &self.basis_inv())
    }

    /// The fused mean without the gains: with `P_a⁻¹ = W⁻ᵀ diag(λ) W⁻¹` and
    /// `P_b⁻¹ = W⁻ᵀ W⁻¹`, `x = P (ω P_a⁻¹ x_a + (1−ω) P_b⁻¹ x_b)
    /// = W diag(1/dᵢ) (ω λ ∘ W⁻¹x_a + (1−ω) W⁻¹x_b)`.
    pub(in crate::fusion) fn fused_mean(
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
    pub(super) fn fuse_covariance_into(
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
    pub(super) fn ci(omega: f64, pencil: usize) -> Self {
        if omega == 1.0 {
            BlockMean::Keep
        } else if omega == 0.0 {
            BlockMean::Take
        } else {
            BlockMean::Ci { pencil, omega }
        }
    }
}
