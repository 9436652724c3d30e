//! Small dense linear-algebra helpers shared by the fusion rules.
//!
//! ## Wider vectors, the same numbers
//! The kernels that carry the dense work — the triangular solves, the Cholesky factorizations
//! (this module's and the verified test's in `fusion::verify`) — are compiled twice on x86-64 by [`wide!`]: for the
//! portable baseline (SSE2) and with AVX2 enabled, the copy picked at run time when the CPU
//! has AVX2. Rust compiles floating point strictly: no fused multiply-add contraction and no
//! reassociation, so wider vectors can only be used for operations that are already
//! independent (elements of an axpy or a rotation), never to reorder a sum. The two copies
//! therefore perform the same IEEE operations in the same order and give bitwise identical
//! results (tested), as the wasm32 build (SIMD128) does.

use nalgebra::{Cholesky, DMatrix, DVector, Dyn};

/// `wide! { /// docs  fn name(args) -> ret = kernel; }` defines `name`, which calls the
/// `#[inline(always)]` function `kernel` compiled twice on x86-64 — inlined into the baseline
/// code and into a copy with AVX2 enabled — and picks the copy at run time
/// (`is_x86_feature_detected!` caches its answer); elsewhere it is a plain call. The kernel
/// is ordinary code (formatted, linted and mutated like any other); the module docs say why
/// both copies give the same bits.
macro_rules! wide {
    ($(#[$m:meta])* $vis:vis fn $name:ident($($arg:ident: $ty:ty),* $(,)?) $(-> $ret:ty)? = $kernel:ident;) => {
        $(#[$m])*
        $vis fn $name($($arg: $ty),*) $(-> $ret)? {
            #[cfg(target_arch = "x86_64")]
            {
                #[target_feature(enable = "avx2")]
                #[allow(non_snake_case)]
                unsafe fn avx2($($arg: $ty),*) $(-> $ret)? {
                    $kernel($($arg),*)
                }
                if !$crate::linalg::baseline_forced() && std::is_x86_feature_detected!("avx2") {
                    // SAFETY: the CPU supports AVX2, the only requirement of `avx2`.
                    return unsafe { avx2($($arg),*) };
                }
            }
            $kernel($($arg),*)
        }
    };
}

/// `(λ, V)` with `A = V diag(λ) Vᵀ` for a symmetric `A` (only its lower triangle is read):
/// nalgebra's `SymmetricEigen::try_new(a, eps, 0)` — Householder reduction to tridiagonal form,
/// then the implicit symmetric QR iteration with Wilkinson's shift (Golub and Van Loan,
/// *Matrix Computations*, 4th ed., §§ 8.3.1, 8.3.5). No iteration limit, as that call has
/// none: the iteration converges globally (Parlett, *The Symmetric Eigenvalue Problem*,
/// § 8.10). `None` for an empty, non-square or non-finite `a`, where nalgebra would panic (a
/// 2 × 2 block without real eigenvalues) or not end.
///
/// Sizes 2–4 run the same generic code on fixed-size matrices (no heap work inside, the same
/// bits: tested), the sizes of most tracking states' blocks.
pub(crate) fn symmetric_eigen(a: DMatrix<f64>, eps: f64) -> Option<(DVector<f64>, DMatrix<f64>)> {
    if a.is_empty() || !a.is_square() || first_non_finite(&a).is_some() {
        return None;
    }
    match a.nrows() {
        2 => symmetric_eigen_fixed!(a, eps, 2),
        3 => symmetric_eigen_fixed!(a, eps, 3),
        4 => symmetric_eigen_fixed!(a, eps, 4),
        _ => symmetric_eigen_dynamic(a, eps),
    }
}

/// `det a` of a square `a`: nalgebra's (closed forms up to 3 × 3, LU with partial pivoting
/// above); 4 × 4 on stack storage, the same code and bits (tested).
pub(crate) fn determinant(a: &DMatrix<f64>) -> f64 {
    if a.nrows() == 4 && a.ncols() == 4 {
        nalgebra::Matrix4::from_column_slice(a.as_slice()).determinant()
    } else {
        a.determinant()
    }
}

/// [`symmetric_eigen`] on heap storage, any size.
fn symmetric_eigen_dynamic(a: DMatrix<f64>, eps: f64) -> Option<(DVector<f64>, DMatrix<f64>)> {
    let e = nalgebra::SymmetricEigen::try_new(a, eps, 0)?;
    Some((e.eigenvalues, e.eigenvectors))
}

/// [`symmetric_eigen`] of an `N × N` `a` on stack storage (`N` of 2, 3, 4: nalgebra's
/// decomposition needs a type-level size).
macro_rules! symmetric_eigen_fixed {
    ($a:expr, $eps:expr, $n:literal) => {{
        let m = nalgebra::SMatrix::<f64, $n, $n>::from_column_slice($a.as_slice());
        nalgebra::SymmetricEigen::try_new(m, $eps, 0).map(|e| {
            (
                DVector::from_column_slice(e.eigenvalues.as_slice()),
                DMatrix::from_column_slice($n, $n, e.eigenvectors.as_slice()),
            )
        })
    }};
}
use symmetric_eigen_fixed;

#[cfg(test)]
thread_local! {
    /// Unit tests only: run the baseline copies of [`wide!`] functions on this thread.
    static FORCE_BASELINE: std::cell::Cell<bool> = const { std::cell::Cell::new(false) };
}

/// Whether this thread runs the baseline copies (only ever in unit tests; only x86-64 has
/// another copy).
#[inline(always)]
#[cfg_attr(not(target_arch = "x86_64"), allow(dead_code))]
pub(crate) fn baseline_forced() -> bool {
    #[cfg(test)]
    {
        FORCE_BASELINE.with(|f| f.get())
    }
    #[cfg(not(test))]
    {
        false
    }
}

/// Unit tests: `f` run on the baseline copies of the [`wide!`] functions (on this thread).
#[cfg(test)]
pub(crate) fn on_baseline<R>(f: impl FnOnce() -> R) -> R {
    FORCE_BASELINE.with(|b| b.set(true));
    let r = f();
    FORCE_BASELINE.with(|b| b.set(false));
    r
}

/// `maxᵢⱼ |aᵢⱼ|`: nalgebra's `amax` bit for bit, the same fold in the same order (from the
/// first entry's `|a|`, then `if m ≥ |x| { m } else { |x| }`, so NaN entries give what they
/// give there; 0 for an empty matrix), over the contiguous storage rather than through
/// nalgebra's strided iterator (tested).
pub(crate) fn largest_abs(a: &DMatrix<f64>) -> f64 {
    let mut entries = a.as_slice().iter();
    let first = entries.next().map_or(0.0, |x| x.abs());
    entries.fold(first, |m, x| if m >= x.abs() { m } else { x.abs() })
}

/// The first non-finite entry of `a`, as `(row, column)`.
pub(crate) fn first_non_finite(a: &DMatrix<f64>) -> Option<(usize, usize)> {
    let k = a.as_slice().iter().position(|x| !x.is_finite())?;
    Some((k % a.nrows(), k / a.nrows()))
}

/// Relative tolerance of the symmetry check on inputs.
pub(crate) const SYMMETRY_RTOL: f64 = 1e-9;

/// `(A + Aᵀ) / 2`, each entry `(a_ij + a_ji) · 0.5` (the diagonal `(a_ii + a_ii) · 0.5`, which
/// overflows where `a_ii` is above half the largest float, as the sum does).
pub(crate) fn symmetrize(a: &DMatrix<f64>) -> DMatrix<f64> {
    let mut s = a.clone();
    let n = s.nrows();
    for j in 0..n {
        s[(j, j)] = (a[(j, j)] + a[(j, j)]) * 0.5;
        for i in j + 1..n {
            let m = (a[(i, j)] + a[(j, i)]) * 0.5;
            s[(i, j)] = m;
            s[(j, i)] = m;
        }
    }
    s
}

/// `P ← (P + Pᵀ) / 2` in place.
#[allow(non_snake_case)]
pub(crate) fn symmetrize_in_place(P: &mut DMatrix<f64>) {
    let n = P.nrows();
    for j in 0..n {
        for i in j + 1..n {
            let m = 0.5 * (P[(i, j)] + P[(j, i)]);
            P[(i, j)] = m;
            P[(j, i)] = m;
        }
    }
}

/// Smallest eigenvalue of a symmetric matrix (`+∞` for an empty one): sizes 1 and 2 in closed
/// form, larger ones by nalgebra's symmetric QR iteration (eigenvalues only).
pub fn min_eigenvalue(a: &DMatrix<f64>) -> f64 {
    extremes(a).map_or(f64::INFINITY, |e| e.0)
}

/// Largest eigenvalue of a symmetric matrix (`−∞` for an empty one), as [`min_eigenvalue`].
pub fn max_eigenvalue(a: &DMatrix<f64>) -> f64 {
    extremes(a).map_or(f64::NEG_INFINITY, |e| e.1)
}

/// `(λ_min, λ_max)` of the symmetric part of `a` (`None` when empty): sizes 1 and 2 in closed
/// form ([`eigenvalues_2x2`]), larger ones by nalgebra's symmetric QR iteration without
/// accumulating eigenvectors (the same iteration as with them, so the same values, at a
/// fraction of the cost).
fn extremes(a: &DMatrix<f64>) -> Option<(f64, f64)> {
    match a.nrows() {
        0 => None,
        1 => Some((a[(0, 0)], a[(0, 0)])),
        2 => Some(eigenvalues_2x2(a)),
        _ => {
            let e = symmetrize(a).symmetric_eigenvalues();
            Some((e.min(), e.max()))
        }
    }
}

/// The eigenvalues `(λ_min, λ_max)` of the symmetric part of a 2 × 2 matrix:
/// `m ± r` with `m = (a + c)/2`, `r = hypot((a − c)/2, b)`, `b` the mean of the off-diagonal
/// entries. Each is within a few ulps of `max(|a|, |b|, |c|)` of the exact value (the same
/// absolute accuracy as a QR iteration; `hypot` cannot overflow); NaN in, NaN out.
fn eigenvalues_2x2(a: &DMatrix<f64>) -> (f64, f64) {
    let (p, c) = (a[(0, 0)], a[(1, 1)]);
    let b = 0.5 * (a[(0, 1)] + a[(1, 0)]);
    let m = 0.5 * p + 0.5 * c;
    let r = (0.5 * p - 0.5 * c).hypot(b);
    (m - r, m + r)
}

/// Cholesky factor, or `None` when the matrix is not (numerically) positive definite:
/// `Cholesky::new(a.clone())`, bit for bit (tested), compiled as a [`wide!`] kernel.
pub(crate) fn cholesky(a: &DMatrix<f64>) -> Option<Cholesky<f64, Dyn>> {
    cholesky_of(a.clone())
}

/// [`cholesky`] of a matrix the caller gives up: `Cholesky::new(a)`, bit for bit. The crate
/// factors through these two, never through nalgebra's copy (compiled for the baseline only).
pub(crate) fn cholesky_of(a: DMatrix<f64>) -> Option<Cholesky<f64, Dyn>> {
    cholesky_in_place(a).map(Cholesky::pack_dirty)
}

wide! {
/// nalgebra 0.34's `Cholesky::new_internal` without a substitute, written out so that it is
/// compiled as a [`wide!`] kernel: column `j` minus `l_jk` times column `k` (`axpy`) for
/// `k < j`, then the square root of the pivot and the column below it divided by it; `None`
/// for a zero, negative or NaN pivot. The strict upper triangle keeps `a`'s entries, as
/// nalgebra's does ("dirty").
fn cholesky_in_place(a: DMatrix<f64>) -> Option<DMatrix<f64>> = cholesky_in_place_kernel;
}

/// The body of [`cholesky_in_place`], compiled into each of its copies.
#[inline(always)]
#[allow(non_snake_case)]
fn cholesky_in_place_kernel(a: DMatrix<f64>) -> Option<DMatrix<f64>> {
    let mut matrix = a;
    let n = matrix.nrows();
    if matrix.ncols() != n {
        return None;
    }
    for j in 0..n {
        for k in 0..j {
            let factor = -matrix[(j, k)];
            let (mut col_j, col_k) = matrix.columns_range_pair_mut(j, k);
            let mut col_j = col_j.rows_range_mut(j..);
            col_j.axpy(factor, &col_k.rows_range(j..), 1.0);
        }
        let diag = matrix[(j, j)];
        if diag == 0.0 || diag.is_nan() || diag < 0.0 {
            return None;
        }
        let denom = diag.sqrt();
        matrix[(j, j)] = denom;
        let mut col = matrix.view_range_mut(j + 1.., j);
        col /= denom;
    }
    Some(matrix)
}

/// `log det A` from a Cholesky factor.
pub(crate) fn logdet_from_cholesky(c: &Cholesky<f64, Dyn>) -> f64 {
    2.0 * c.l_dirty().diagonal().iter().map(|d| d.ln()).sum::<f64>()
}

/// `log det A` of a symmetric positive definite matrix (`-∞`/NaN are impossible for validated inputs;
/// a matrix that is not PD gives `NaN`).
pub fn logdet_spd(a: &DMatrix<f64>) -> f64 {
    cholesky(&symmetrize(a))
        .map(|c| logdet_from_cholesky(&c))
        .unwrap_or(f64::NAN)
}

/// Rows of a nested array as a matrix; `Err((row, len))` names the first ragged row.
pub(crate) fn matrix_from_rows(rows: &[Vec<f64>]) -> Result<DMatrix<f64>, (usize, usize)> {
    let n = rows.len();
    let cols = rows.first().map_or(0, Vec::len);
    if let Some((i, r)) = rows.iter().enumerate().find(|(_, r)| r.len() != cols) {
        return Err((i, r.len()));
    }
    Ok(DMatrix::from_fn(n, cols, |i, j| rows[i][j]))
}

/// A matrix as nested rows.
pub(crate) fn matrix_to_rows(a: &DMatrix<f64>) -> Vec<Vec<f64>> {
    (0..a.nrows())
        .map(|i| (0..a.ncols()).map(|j| a[(i, j)]).collect())
        .collect()
}

wide! {
/// `B ← L⁻¹ B` for a lower-triangular `L` (only its lower triangle is read); `b` holds the
/// columns of `B` one after the other (`DMatrix::as_mut_slice`, or a `DVector`'s). Column-
/// oriented forward substitution on contiguous slices: nalgebra's `solve_lower_triangular_mut`
/// goes one right-hand side at a time through strided views and dominated the tracking study.
/// `L` must have a non-zero diagonal (a Cholesky factor has a positive one).
#[allow(non_snake_case)]
pub(crate) fn solve_lower_in_place(L: &DMatrix<f64>, b: &mut [f64]) = solve_lower_in_place_kernel;
}

/// The body of [`solve_lower_in_place`], compiled into each of its copies.
#[inline(always)]
#[allow(non_snake_case)]
fn solve_lower_in_place_kernel(L: &DMatrix<f64>, b: &mut [f64]) {
    let n = L.nrows();
    debug_assert_eq!(b.len() % n.max(1), 0);
    let l = L.as_slice();
    for col in b.chunks_exact_mut(n) {
        for k in 0..n {
            let l_col = &l[k * n..(k + 1) * n];
            let xk = col[k] / l_col[k];
            col[k] = xk;
            for (c, &lik) in col[k + 1..].iter_mut().zip(&l_col[k + 1..]) {
                *c -= lik * xk;
            }
        }
    }
}

wide! {
/// `C ← L⁻¹ C` where `c` holds the `n × m` matrix `C` **row by row** (row-major), `L` lower
/// triangular (only its lower triangle is read) with a non-zero diagonal. Row-oriented forward
/// substitution: the inner loop is an axpy over a whole contiguous row of `m` entries, which
/// vectorizes (the column-oriented [`solve_lower_in_place`] has inner loops of `n − k`).
///
/// A symmetric `P` stored column-major is also its own row-major storage, so
/// `solve_lower_rows(L, P.as_mut_slice())` leaves `L⁻¹P` in row-major order, i.e. `(L⁻¹P)ᵀ` in
/// the column-major matrix.
#[allow(non_snake_case)]
pub(crate) fn solve_lower_rows(L: &DMatrix<f64>, c: &mut [f64]) = solve_lower_rows_kernel;
}

/// The body of [`solve_lower_rows`], compiled into each of its copies.
#[inline(always)]
#[allow(non_snake_case)]
fn solve_lower_rows_kernel(L: &DMatrix<f64>, c: &mut [f64]) {
    let n = L.nrows();
    if n == 0 {
        return;
    }
    let m = c.len() / n;
    debug_assert_eq!(c.len(), n * m);
    // Lᵀ column-major = L row-major: row k of L is contiguous.
    let Lt = L.transpose();
    for (k, l_row) in Lt.as_slice().chunks_exact(n).enumerate() {
        let (done, rest) = c.split_at_mut(k * m);
        let row_k = &mut rest[..m];
        for (row_j, &l_kj) in done.chunks_exact(m).zip(&l_row[..k]) {
            for (r, &x) in row_k.iter_mut().zip(row_j) {
                *r -= l_kj * x;
            }
        }
        let inv = 1.0 / l_row[k];
        for r in row_k.iter_mut() {
            *r *= inv;
        }
    }
}

wide! {
/// `C ← L⁻ᵀ C` where `c` holds the `n × m` matrix `C` row by row (row-major), `L` lower
/// triangular (only its lower triangle is read) with a non-zero diagonal: backward
/// substitution with `Lᵀ`, row-oriented as [`solve_lower_rows`] (column `k` of `L` below the
/// diagonal is row `k` of `Lᵀ` right of it, contiguous in column-major storage).
///
/// With `c` the column-major buffer of `Bᵀ` (the row-major storage of `B`), the buffer ends
/// up holding `(L⁻ᵀB)ᵀ = Bᵀ L⁻¹` in column-major order.
#[allow(non_snake_case)]
pub(crate) fn solve_lower_transposed_rows(L: &DMatrix<f64>, c: &mut [f64]) = solve_lower_transposed_rows_kernel;
}

/// The body of [`solve_lower_transposed_rows`], compiled into each of its copies.
#[inline(always)]
#[allow(non_snake_case)]
fn solve_lower_transposed_rows_kernel(L: &DMatrix<f64>, c: &mut [f64]) {
    let n = L.nrows();
    if n == 0 {
        return;
    }
    let m = c.len() / n;
    debug_assert_eq!(c.len(), n * m);
    let l = L.as_slice();
    for k in (0..n).rev() {
        let l_col = &l[k * n..(k + 1) * n];
        let (head, done) = c.split_at_mut((k + 1) * m);
        let row_k = &mut head[k * m..];
        for (row_j, &l_jk) in done.chunks_exact(m).zip(&l_col[k + 1..]) {
            for (r, &x) in row_k.iter_mut().zip(row_j) {
                *r -= l_jk * x;
            }
        }
        let inv = 1.0 / l_col[k];
        for r in row_k.iter_mut() {
            *r *= inv;
        }
    }
}

/// A random SPD matrix `A Aᵀ + δI` from a small LCG (no RNG dependency in unit tests): the
/// unit tests' problem generator.
#[cfg(test)]
#[allow(non_snake_case)]
pub(crate) fn test_spd(n: usize, seed: &mut u64, shift: f64) -> DMatrix<f64> {
    let mut next = || {
        *seed = seed
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((*seed >> 11) as f64 / (1u64 << 53) as f64) - 0.5
    };
    let A = DMatrix::from_fn(n, n, |_, _| next());
    &A * A.transpose() + DMatrix::identity(n, n) * shift
}

#[cfg(test)]
#[allow(non_snake_case)]
mod tests {
    use super::*;

    /// The eigensolver refuses what nalgebra's would panic or loop on, and decomposes the rest:
    /// `V diag(λ) Vᵀ` gives back the matrix.
    #[test]
    fn symmetric_eigen_refuses_bad_input_and_decomposes_the_rest() {
        assert!(symmetric_eigen(DMatrix::zeros(0, 0), f64::EPSILON).is_none());
        assert!(symmetric_eigen(DMatrix::zeros(2, 3), f64::EPSILON).is_none());
        for bad in [f64::NAN, f64::INFINITY] {
            let m = DMatrix::from_row_slice(2, 2, &[1.0, bad, bad, 2.0]);
            assert!(symmetric_eigen(m, f64::EPSILON).is_none());
        }
        let mut seed = 3;
        for n in [1, 2, 5, 14] {
            let a = test_spd(n, &mut seed, 0.1);
            let (values, vectors) = symmetric_eigen(a.clone(), f64::EPSILON).unwrap();
            let back = &vectors * DMatrix::from_diagonal(&values) * vectors.transpose();
            assert!((back - &a).amax() <= 1e-13 * a.amax(), "n = {n}");
        }
    }

    /// Sizes 2–4 on fixed-size storage give the bits of the heap-storage code, on random
    /// symmetric matrices (lower triangle read), positive definite ones, and ones with a
    /// repeated eigenvalue.
    #[test]
    fn fixed_size_eigen_gives_the_bits_of_the_dynamic_one() {
        let mut seed = 11;
        for n in 2..=4 {
            for case in 0..200 {
                let mut a = test_spd(n, &mut seed, 0.01);
                match case % 3 {
                    0 => a[(n - 1, 0)] -= 2.0 * a[(n - 1, 0)] + 0.3, // indefinite, asymmetric
                    1 => a = DMatrix::identity(n, n) * 0.25 + DMatrix::from_element(n, n, 1.0),
                    _ => {}
                }
                for eps in [f64::EPSILON, 4.0 * f64::EPSILON] {
                    let fixed = symmetric_eigen(a.clone(), eps).unwrap();
                    let dynamic = symmetric_eigen_dynamic(a.clone(), eps).unwrap();
                    assert_eq!(fixed, dynamic, "n = {n}, case {case}");
                }
            }
        }
    }

    /// The 4 × 4 determinant on stack storage gives the heap-storage bits.
    #[test]
    fn largest_abs_is_amax_bit_for_bit() {
        let nan = f64::NAN;
        for v in [
            vec![],
            vec![-3.0, 2.0, 1.0, -0.5],
            vec![nan, -2.0, 1.0, 0.5],
            vec![1.0, nan, -7.0, nan],
            vec![nan, nan, nan, nan],
            vec![f64::NEG_INFINITY, 1.0, 2.0, 3.0],
            vec![-0.0, 0.0, -0.0, 0.0],
        ] {
            let n = if v.is_empty() { 0 } else { 2 };
            let m = DMatrix::from_vec(n, n, v);
            assert_eq!(largest_abs(&m).to_bits(), m.amax().to_bits(), "{m}");
        }
    }

    #[test]
    fn fixed_size_determinant_gives_the_bits_of_the_dynamic_one() {
        let mut seed = 5;
        for case in 0..300 {
            let mut a = test_spd(4, &mut seed, 0.01);
            if case % 2 == 0 {
                a[(0, 3)] = -a[(0, 3)] * 3.0; // asymmetric, maybe indefinite
            }
            assert_eq!(determinant(&a), a.determinant(), "case {case}");
        }
        let b = test_spd(5, &mut seed, 0.1);
        assert_eq!(determinant(&b), b.determinant());
    }

    /// The closed forms against nalgebra's QR iteration with eigenvectors (another
    /// algorithm) at sizes 1–3, over scales 1e−150…1e150 (no overflow in `hypot`), with
    /// repeated eigenvalues and asymmetric input (its symmetric part); NaN stays NaN.
    #[test]
    fn extreme_eigenvalues_match_the_qr_iteration() {
        let mut k = 0u64;
        let mut next = || {
            k = k
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (k >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        for n in 1..=3 {
            for scale in [1e-150, 1e-8, 1.0, 1e8, 1e150] {
                for case in 0..50 {
                    let mut A = DMatrix::from_fn(n, n, |_, _| next() * scale);
                    if case == 0 {
                        A = DMatrix::identity(n, n) * scale; // repeated eigenvalue
                    }
                    let exact = qr(&symmetrize(&A));
                    let tol = 1e-14 * A.amax();
                    assert!((min_eigenvalue(&A) - exact.0).abs() <= tol, "n {n} {A}");
                    assert!((max_eigenvalue(&A) - exact.1).abs() <= tol, "n {n} {A}");
                }
            }
        }
        let nan = DMatrix::from_row_slice(2, 2, &[1.0, f64::NAN, f64::NAN, 1.0]);
        assert!(min_eigenvalue(&nan).is_nan() && max_eigenvalue(&nan).is_nan());
        assert_eq!(min_eigenvalue(&DMatrix::zeros(0, 0)), f64::INFINITY);
        assert_eq!(max_eigenvalue(&DMatrix::zeros(0, 0)), f64::NEG_INFINITY);
    }

    /// nalgebra's full decomposition: `(λ_min, λ_max)`.
    fn qr(a: &DMatrix<f64>) -> (f64, f64) {
        let e = nalgebra::SymmetricEigen::new(a.clone()).eigenvalues;
        (e.min(), e.max())
    }

    #[test]
    fn triangular_solves_match_nalgebra() {
        let n = 6;
        let A = DMatrix::from_fn(n, n, |i, j| ((i * 7 + j * 3) % 11) as f64 / 5.0 - 1.0);
        let S = &A * A.transpose() + DMatrix::identity(n, n);
        let L = Cholesky::new(S.clone()).unwrap().unpack();
        let expected = L.solve_lower_triangular(&S).unwrap();
        let mut by_columns = S.clone();
        solve_lower_in_place(&L, by_columns.as_mut_slice());
        assert!((&by_columns - &expected).amax() < 1e-12);
        // S symmetric: its storage is row-major too; the result is (L⁻¹S)ᵀ column-major.
        let mut by_rows = S.clone();
        solve_lower_rows(&L, by_rows.as_mut_slice());
        assert!((by_rows.transpose() - &expected).amax() < 1e-12);
        // A non-square right-hand side, row-major: 6 × 2.
        let B = DMatrix::from_fn(n, 2, |i, j| (i + 2 * j) as f64);
        let mut rows: Vec<f64> = (0..n).flat_map(|i| [B[(i, 0)], B[(i, 1)]]).collect();
        solve_lower_rows(&L, &mut rows);
        let X = L.solve_lower_triangular(&B).unwrap();
        for i in 0..n {
            for j in 0..2 {
                assert!((rows[2 * i + j] - X[(i, j)]).abs() < 1e-12);
            }
        }
        // L⁻ᵀ B, row-major, against nalgebra's transposed solve (a different algorithm).
        let mut rows: Vec<f64> = (0..n).flat_map(|i| [B[(i, 0)], B[(i, 1)]]).collect();
        solve_lower_transposed_rows(&L, &mut rows);
        let Y = L.tr_solve_lower_triangular(&B).unwrap();
        for i in 0..n {
            for j in 0..2 {
                assert!((rows[2 * i + j] - Y[(i, j)]).abs() < 1e-12);
            }
        }
        // A non-symmetric square B given through the buffer of Bᵀ: the buffer ends up holding
        // Bᵀ L⁻¹ column-major.
        let mut Z = A.transpose();
        solve_lower_transposed_rows(&L, Z.as_mut_slice());
        let expected = A.transpose() * L.clone().try_inverse().unwrap();
        assert!((&Z - &expected).amax() < 1e-12, "{Z} {expected}");
    }

    /// The two copies of each triangular solve give the same bits (on a CPU with AVX2 the
    /// dispatched copy is the AVX2 one; without, this compares the baseline with itself),
    /// on sizes that leave every remainder of the vector loops.
    #[test]
    fn triangular_solves_same_bits_on_both_copies() {
        let mut seed = 11;
        for n in [1, 2, 3, 5, 8, 13, 14, 31, 112] {
            let L = cholesky(&test_spd(n, &mut seed, 0.5)).unwrap().unpack();
            for m in [1, 3, 7, n] {
                let b = test_spd(n.max(m), &mut seed, 0.0);
                let c: Vec<f64> = b.as_slice()[..n * m].to_vec();
                let run = |f: fn(&DMatrix<f64>, &mut [f64])| {
                    let (mut wide, mut base) = (c.clone(), c.clone());
                    f(&L, &mut wide);
                    on_baseline(|| f(&L, &mut base));
                    let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
                    assert_eq!(bits(&wide), bits(&base), "n {n} m {m}");
                    assert_ne!(wide, c, "the solve changed nothing");
                };
                run(solve_lower_rows);
                run(solve_lower_transposed_rows);
                run(solve_lower_in_place);
            }
        }
    }

    /// [`cholesky`] is nalgebra's factorization bit for bit (dirty upper triangle included),
    /// on both copies, and refuses what nalgebra refuses (singular, indefinite, NaN).
    #[test]
    fn cholesky_same_bits_as_nalgebra_on_both_copies() {
        let mut seed = 17;
        for n in [1, 2, 3, 7, 14, 31, 112] {
            let mut cases = vec![test_spd(n, &mut seed, 0.1), test_spd(n, &mut seed, 1e-9)];
            let mut indefinite = test_spd(n, &mut seed, 0.0);
            indefinite[(n - 1, n - 1)] = -1.0;
            cases.push(indefinite);
            cases.push(DMatrix::zeros(n, n));
            let mut nan = test_spd(n, &mut seed, 0.1);
            nan[(n / 2, n / 2)] = f64::NAN;
            cases.push(nan);
            for a in cases {
                let reference = Cholesky::new(a.clone()).map(|c| c.unpack_dirty());
                let bits = |m: &Option<DMatrix<f64>>| {
                    m.as_ref()
                        .map(|m| m.iter().map(|v| v.to_bits()).collect::<Vec<_>>())
                };
                let wide = cholesky(&a).map(|c| c.unpack_dirty());
                let base = on_baseline(|| cholesky(&a)).map(|c| c.unpack_dirty());
                assert_eq!(bits(&wide), bits(&reference), "n {n}\n{a}");
                assert_eq!(bits(&base), bits(&reference), "baseline, n {n}");
            }
        }
    }
}
