//! Small dense linear-algebra helpers shared by the fusion rules.

use nalgebra::{Cholesky, DMatrix, Dyn, SymmetricEigen};

/// Relative tolerance of the symmetry check on inputs.
pub(crate) const SYMMETRY_RTOL: f64 = 1e-9;

/// `(A + Aᵀ) / 2`.
pub(crate) fn symmetrize(a: &DMatrix<f64>) -> DMatrix<f64> {
    (a + a.transpose()) * 0.5
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
