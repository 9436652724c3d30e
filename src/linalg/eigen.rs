//! The symmetric eigendecomposition behind CI's pencil (and so ICI's and EI's): nalgebra's
//! `SymmetricEigen`, compiled with AVX2 where the CPU has it.
//!
//! The algorithm is nalgebra 0.34's (Apache-2.0), step for step: the matrix divided by its
//! largest entry, Householder reduction to tridiagonal form `A = Q T Qᵀ`
//! (`SymmetricTridiagonal::new`, `Q` assembled from the reflectors), then the implicit
//! symmetric QR iteration with Wilkinson's shift on `T`, each Givens rotation applied to `Q`,
//! 2 × 2 blocks in closed form (Golub and Van Loan, *Matrix Computations*, 4th ed., §§ 8.3.1,
//! 8.3.5). It calls nalgebra's own building blocks (`reflection_axis_mut`, `dotc`, `axpy`,
//! `GivensRotation`, `wilkinson_shift`, `Matrix2::eigenvalues`; `hegemv`,
//! `Reflection::reflect_with_sign` and the reduction's three `hegerc` rank-one updates written
//! out from their source, the last fused into one pass over the lower triangle in which each
//! entry gets the same three operations in the same order) on the same values, so it performs
//! the same IEEE operations. It is written here so that those generic, inlined blocks are
//! compiled inside a function that [`wide!`] also builds with AVX2 (nalgebra's own copy is
//! compiled once, for the baseline), and so that the rank-one updates read and write the
//! matrix once instead of three times. The result is bitwise that of
//! `SymmetricEigen::try_new(m, eps, 0)` on either copy (tested on twelve kinds of matrices —
//! random, indefinite, diagonal, zero, identity, clustered, graded, rank one, split, equal
//! diagonals, couplings on either deflation threshold — of sizes 1–20, 28, 56, 112 and 120).

use nalgebra::linalg::givens::GivensRotation;
use nalgebra::linalg::householder::reflection_axis_mut;
use nalgebra::linalg::wilkinson_shift;
use nalgebra::{DMatrix, DVector, Matrix2, Vector2};

wide! {
/// `(λ, V)` with `A = V diag(λ) Vᵀ` for a symmetric `A` (only its lower triangle is read):
/// exactly `SymmetricEigen::try_new(a, eps, 0)`'s eigenvalues and eigenvectors. No iteration
/// limit, as that call has none: the QR iteration with Wilkinson's shift converges globally
/// (Parlett, *The Symmetric Eigenvalue Problem*, § 8.10). `None` for an empty or non-square
/// `a`, or a 2 × 2 block without real eigenvalues (which a symmetric one cannot be: its
/// discriminant is a sum of squares; nalgebra would panic there).
pub(crate) fn symmetric_eigen(a: DMatrix<f64>, eps: f64) -> Option<(DVector<f64>, DMatrix<f64>)> = symmetric_eigen_kernel;
}

/// The body of [`symmetric_eigen`], compiled into each of its copies.
#[inline(always)]
#[allow(non_snake_case)]
fn symmetric_eigen_kernel(a: DMatrix<f64>, eps: f64) -> Option<(DVector<f64>, DMatrix<f64>)> {
    let dim = a.nrows();
    if dim == 0 || a.ncols() != dim {
        return None;
    }
    let mut matrix = a;
    let m_amax = matrix.camax();
    if m_amax != 0.0 {
        matrix.unscale_mut(m_amax);
    }
    let (mut q, mut diag, mut off_diag) = tridiagonal(matrix);
    if dim == 1 {
        diag.scale_mut(m_amax);
        return Some((diag, q));
    }
    let (mut start, mut end) = delimit_subproblem(&diag, &mut off_diag, dim - 1, eps);
    while end != start {
        let subdim = end - start + 1;
        if subdim > 2 {
            let m = end - 1;
            let n = end;
            let mut vec = Vector2::new(
                diag[start] - wilkinson_shift(diag[m], diag[n], off_diag[m]),
                off_diag[start],
            );
            for i in start..n {
                let j = i + 1;
                let Some((rot, norm)) = GivensRotation::cancel_y(&vec) else {
                    break;
                };
                if i > start {
                    off_diag[i - 1] = norm;
                }
                let (mii, mjj, mij) = (diag[i], diag[j], off_diag[i]);
                let cc = rot.c() * rot.c();
                let ss = rot.s() * rot.s();
                let cs = rot.c() * rot.s();
                let b = cs * 2.0 * mij;
                diag[i] = (cc * mii + ss * mjj) - b;
                diag[j] = (ss * mii + cc * mjj) + b;
                off_diag[i] = cs * (mii - mjj) + mij * (cc - ss);
                if i != n - 1 {
                    vec.x = off_diag[i];
                    vec.y = -rot.s() * off_diag[i + 1];
                    off_diag[i + 1] *= rot.c();
                }
                let rot = GivensRotation::new_unchecked(rot.c(), rot.s());
                rot.inverse().rotate_rows(&mut q.fixed_columns_mut::<2>(i));
            }
            if off_diag[m].abs() <= eps * (diag[m].abs() + diag[n].abs()) {
                end -= 1;
            }
        } else if subdim == 2 {
            let m = Matrix2::new(
                diag[start],
                off_diag[start],
                off_diag[start],
                diag[start + 1],
            );
            let eigvals = m.eigenvalues()?;
            // The basis least likely to cancel.
            let basis = if (eigvals.x - diag[start + 1]).abs() > (eigvals.x - diag[start]).abs() {
                Vector2::new(eigvals.x - diag[start + 1], off_diag[start])
            } else {
                Vector2::new(off_diag[start], eigvals.x - diag[start])
            };
            diag[start] = eigvals[0];
            diag[start + 1] = eigvals[1];
            if let Some((rot, _)) = GivensRotation::try_new(basis.x, basis.y, eps) {
                let rot = GivensRotation::new_unchecked(rot.c(), rot.s());
                rot.rotate_rows(&mut q.fixed_columns_mut::<2>(start));
            }
            end -= 1;
        }
        let sub = delimit_subproblem(&diag, &mut off_diag, end, eps);
        start = sub.0;
        end = sub.1;
    }
    diag.scale_mut(m_amax);
    Some((diag, q))
}

/// `SymmetricTridiagonal::new(m).unpack()`: `(Q, diagonal, |off-diagonal|)` with
/// `m = Q T Qᵀ` (Householder reflectors stored below the subdiagonal, then `Q` assembled
/// from them as `householder::assemble_q` does). `m` is not empty.
#[inline(always)]
fn tridiagonal(mut m: DMatrix<f64>) -> (DMatrix<f64>, DVector<f64>, DVector<f64>) {
    let dim = m.nrows();
    let mut off_diagonal = DVector::<f64>::zeros(dim - 1);
    let mut p = DVector::<f64>::zeros(dim - 1);
    for i in 0..dim - 1 {
        let mut m = m.rows_range_mut(i + 1..);
        let (mut axis, mut m) = m.columns_range_pair_mut(i, i + 1..);
        let (norm, not_zero) = reflection_axis_mut(&mut axis);
        off_diagonal[i] = norm;
        if not_zero {
            let mut p = p.rows_range_mut(i..);
            // p = 2 m axis from m's lower triangle: `p.hegemv(2.0, &m, &axis, 0.0)` written
            // out (nalgebra passes its dot product as a closure, which is not inlined).
            let alpha = 2.0;
            p.axpy(alpha * axis[0], &m.column(0), 0.0);
            p[0] += alpha * m.view_range(1.., 0).dotc(&axis.rows_range(1..));
            for j in 1..m.nrows() {
                let col = m.column(j);
                let dot = col.rows_range(j..).dotc(&axis.rows_range(j..));
                p[j] += alpha * dot;
                p.rows_range_mut(j + 1..)
                    .axpy(alpha * axis[j], &col.rows_range(j + 1..), 1.0);
            }
            let dot = axis.dotc(&p);
            // nalgebra's three rank-one updates of the lower triangle, `m.hegerc(-1.0, &p,
            // &axis, 1.0)`, `m.hegerc(-1.0, &axis, &p, 1.0)` and `m.hegerc(dot * 2.0, &axis,
            // &axis, 1.0)`, in one pass: each entry gets the same three `a·xᵢ·1 + 1·mᵢⱼ`
            // (the products by one exact) in the same order; `(−1)·y` is exactly `−y`.
            for j in 0..m.ncols() {
                let (c1, c2, c3) = (-axis[j], -p[j], dot * 2.0 * axis[j]);
                let mut col = m.column_mut(j);
                let mut col = col.rows_range_mut(j..);
                let (p, axis) = (p.rows_range(j..), axis.rows_range(j..));
                for ((m_ij, &p_i), &a_i) in col
                    .as_mut_slice()
                    .iter_mut()
                    .zip(p.as_slice())
                    .zip(axis.as_slice())
                {
                    let m1 = c1 * p_i + *m_ij;
                    let m2 = c2 * a_i + m1;
                    *m_ij = c3 * a_i + m2;
                }
            }
        }
    }
    let diag = m.diagonal();
    let mut q = DMatrix::<f64>::identity(dim, dim);
    for i in (0..dim - 1).rev() {
        // The reflection by the unit axis below the subdiagonal, signed:
        // `Reflection::new(axis, 0).reflect_with_sign(rows, sign)` written out.
        let axis = m.view_range(i + 1.., i);
        let sign = off_diagonal[i].signum();
        let m_two = sign * -2.0;
        let mut rows = q.view_range_mut(i + 1.., i..);
        for c in 0..rows.ncols() {
            let factor = (axis.dotc(&rows.column(c)) - 0.0) * m_two;
            rows.column_mut(c).axpy(factor, &axis, sign);
        }
    }
    (q, diag, off_diagonal.map(f64::abs))
}

/// nalgebra's `SymmetricEigen::delimit_subproblem`: the last unreduced block ending at or
/// before `end`, setting the negligible coupling above it to zero.
#[inline(always)]
fn delimit_subproblem(
    diag: &DVector<f64>,
    off_diag: &mut DVector<f64>,
    end: usize,
    eps: f64,
) -> (usize, usize) {
    let mut n = end;
    while n > 0 {
        let m = n - 1;
        if off_diag[m].abs() > eps * (diag[n].abs() + diag[m].abs()) {
            break;
        }
        n -= 1;
    }
    if n == 0 {
        return (0, 0);
    }
    let mut new_start = n - 1;
    while new_start > 0 {
        let m = new_start - 1;
        if off_diag[m] == 0.0 || off_diag[m].abs() <= eps * (diag[new_start].abs() + diag[m].abs())
        {
            off_diag[m] = 0.0;
            break;
        }
        new_start -= 1;
    }
    (new_start, n)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::linalg::{on_baseline, test_spd};

    /// The bits of eigenvalues and eigenvectors.
    fn bits(values: &DVector<f64>, vectors: &DMatrix<f64>) -> Vec<u64> {
        values
            .iter()
            .chain(vectors.iter())
            .map(|v| v.to_bits())
            .collect()
    }

    /// Matrices of every kind the QR iteration branches on: random SPD and indefinite,
    /// diagonal (no reflection, immediate deflation) with repeated entries, zero, identity,
    /// a cluster `I + 1e-12 E`, graded scales `10^{±k}` (deflation by the relative test),
    /// rank one, a split tridiagonal (an exact zero coupling in the middle), a tridiagonal
    /// Toeplitz one (equal diagonals: the 2 × 2 step's tie), and couplings exactly on the
    /// deflation threshold of either tolerance.
    fn cases(n: usize, seed: &mut u64) -> Vec<DMatrix<f64>> {
        let spd = test_spd(n, seed, 0.1);
        let indefinite = test_spd(n, seed, 0.0) - DMatrix::identity(n, n) * (n as f64 / 12.0);
        let diagonal =
            DMatrix::from_fn(n, n, |i, j| if i == j { (i % 3) as f64 + 1.0 } else { 0.0 });
        let e = test_spd(n, seed, 0.0);
        let cluster = DMatrix::identity(n, n) + e * 1e-12;
        let g = DMatrix::from_fn(n, n, |i, j| 10f64.powi((i + j) as i32 - n as i32));
        let graded = &g * g.transpose()
            + DMatrix::from_fn(
                n,
                n,
                |i, j| if i == j { 10f64.powi(-(i as i32)) } else { 0.0 },
            );
        let v = DMatrix::from_fn(n, 1, |i, _| i as f64 + 1.0);
        let rank_one = &v * v.transpose();
        let split = DMatrix::from_fn(n, n, |i, j| match i.abs_diff(j) {
            0 => 2.0 + i as f64,
            1 if i.min(j) != n / 2 => 1.0,
            _ => 0.0,
        });
        // Equal diagonals: the 2 × 2 step's two candidate bases tie exactly (for n = 2 the
        // whole matrix; the reduction makes the coupling positive, and then they coincide).
        let tie = DMatrix::from_fn(n, n, |i, j| match i.abs_diff(j) {
            0 => 2.0,
            1 => -1.0,
            _ => 0.0,
        });
        // Couplings exactly on the deflation threshold `eps (|dᵢ| + |dᵢ₊₁|)` for each tolerance
        // the tests use (the reduction keeps the diagonal and the couplings' magnitudes
        // exactly, so the test sees equality): deflated, as nalgebra's strict `>` says, not
        // iterated on (`>=` there fails the bit-for-bit test).
        let threshold = |eps: f64| {
            DMatrix::from_fn(n, n, |i, j| match i.abs_diff(j) {
                0 => 1.0,
                1 => 2.0 * eps,
                _ => 0.0,
            })
        };
        vec![
            spd,
            indefinite,
            diagonal,
            DMatrix::zeros(n, n),
            DMatrix::identity(n, n),
            cluster,
            graded,
            rank_one,
            split,
            tie,
            threshold(f64::EPSILON),
            threshold(4.0 * f64::EPSILON),
        ]
    }

    /// Bit for bit nalgebra's `SymmetricEigen::try_new(a, eps, 0)`, from the dispatched copy
    /// (AVX2 on a CPU that has it) and from the baseline one, for sizes 1–20 and the
    /// sizes the project uses (28, 56, 112, 120), at the tolerances it uses (ε, 4ε).
    #[test]
    fn same_bits_as_nalgebra_on_both_copies() {
        let mut seed = 3;
        let mut checked = 0;
        for n in (1..=20).chain([28, 56, 112, 120]) {
            for a in cases(n, &mut seed) {
                for eps in [f64::EPSILON, 4.0 * f64::EPSILON] {
                    let reference = nalgebra::SymmetricEigen::try_new(a.clone(), eps, 0).unwrap();
                    let expected = bits(&reference.eigenvalues, &reference.eigenvectors);
                    let (values, vectors) = symmetric_eigen(a.clone(), eps).unwrap();
                    assert_eq!(bits(&values, &vectors), expected, "n {n} eps {eps:e}\n{a}");
                    let (values, vectors) =
                        on_baseline(|| symmetric_eigen(a.clone(), eps)).unwrap();
                    assert_eq!(bits(&values, &vectors), expected, "baseline, n {n}\n{a}");
                    checked += 1;
                }
            }
        }
        assert_eq!(checked, 24 * 12 * 2);
    }

    /// A decomposition, not only a copy: `A V = V Λ` and `VᵀV = I` to rounding (so a test
    /// that compared two wrong copies would still fail here).
    #[test]
    fn decomposes() {
        let mut seed = 5;
        for n in [1, 2, 3, 14, 112] {
            for a in cases(n, &mut seed) {
                let (values, vectors) = symmetric_eigen(a.clone(), 4.0 * f64::EPSILON).unwrap();
                let scale = a.amax().max(f64::MIN_POSITIVE);
                let residual = &a * &vectors - &vectors * DMatrix::from_diagonal(&values);
                assert!(
                    residual.amax() <= 1e-13 * scale * n as f64,
                    "n {n} {}",
                    residual.amax()
                );
                let gram = vectors.transpose() * &vectors - DMatrix::identity(n, n);
                assert!(gram.amax() <= 1e-14 * n as f64, "n {n} {}", gram.amax());
            }
        }
    }

    #[test]
    fn empty_is_none() {
        assert!(symmetric_eigen(DMatrix::zeros(0, 0), f64::EPSILON).is_none());
    }
}
