//! Small dense linear-algebra helpers shared by the fusion rules.

use nalgebra::{Cholesky, DMatrix, Dyn, SymmetricEigen};

/// Relative tolerance of the symmetry check on inputs.
pub(crate) const SYMMETRY_RTOL: f64 = 1e-9;

/// `(A + Aᵀ) / 2`.
pub(crate) fn symmetrize(a: &DMatrix<f64>) -> DMatrix<f64> {
    (a + a.transpose()) * 0.5
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

/// Smallest eigenvalue of a symmetric matrix (`+∞` for an empty one).
pub fn min_eigenvalue(a: &DMatrix<f64>) -> f64 {
    if a.nrows() == 0 {
        return f64::INFINITY;
    }
    SymmetricEigen::new(symmetrize(a)).eigenvalues.min()
}

/// Cholesky factor, or `None` when the matrix is not (numerically) positive definite.
pub(crate) fn cholesky(a: &DMatrix<f64>) -> Option<Cholesky<f64, Dyn>> {
    Cholesky::new(a.clone())
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

/// `B ← L⁻¹ B` for a lower-triangular `L` (only its lower triangle is read); `b` holds the
/// columns of `B` one after the other (`DMatrix::as_mut_slice`, or a `DVector`'s). Column-
/// oriented forward substitution on contiguous slices: nalgebra's `solve_lower_triangular_mut`
/// goes one right-hand side at a time through strided views and dominated the tracking study.
/// `L` must have a non-zero diagonal (a Cholesky factor has a positive one).
#[allow(non_snake_case)]
pub(crate) fn solve_lower_in_place(L: &DMatrix<f64>, b: &mut [f64]) {
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

/// `C ← L⁻¹ C` where `c` holds the `n × m` matrix `C` **row by row** (row-major), `L` lower
/// triangular (only its lower triangle is read) with a non-zero diagonal. Row-oriented forward
/// substitution: the inner loop is an axpy over a whole contiguous row of `m` entries, which
/// vectorizes (the column-oriented [`solve_lower_in_place`] has inner loops of `n − k`).
///
/// A symmetric `P` stored column-major is also its own row-major storage, so
/// `solve_lower_rows(L, P.as_mut_slice())` leaves `L⁻¹P` in row-major order, i.e. `(L⁻¹P)ᵀ` in
/// the column-major matrix.
#[allow(non_snake_case)]
pub(crate) fn solve_lower_rows(L: &DMatrix<f64>, c: &mut [f64]) {
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

#[cfg(test)]
#[allow(non_snake_case)]
mod tests {
    use super::*;

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
    }
}
