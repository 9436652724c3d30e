//! The LAPACK drivers against hand-computed values and identities they must satisfy, for
//! f64 and f32, including the workspace queries Clarabel makes.

use nalgebra::DMatrix;

struct Lcg(u64);
impl Lcg {
    fn next(&mut self) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((self.0 >> 11) as f64 / (1u64 << 53) as f64) * 2.0 - 1.0
    }
    fn matrix(&mut self, r: usize, c: usize) -> DMatrix<f64> {
        DMatrix::from_fn(r, c, |_, _| self.next())
    }
    fn spd(&mut self, n: usize) -> DMatrix<f64> {
        let g = self.matrix(n, n);
        &g * g.transpose() + DMatrix::identity(n, n) * 0.5
    }
}

#[allow(clippy::type_complexity)]
fn syevr(a: &DMatrix<f64>, jobz: u8, uplo: u8) -> (i32, Vec<f64>, DMatrix<f64>) {
    let n = a.nrows();
    let mut data = a.as_slice().to_vec();
    let (mut w, mut z) = (vec![0.0; n], vec![0.0; n * n]);
    let mut isuppz = vec![0; 2 * n];
    let (mut work, mut iwork) = (vec![0.0; 1], vec![0; 1]);
    let (mut m, mut info) = (0, 0);
    // Workspace query, as Clarabel does it (lwork = liwork = -1, then read back work[0], iwork[0]).
    unsafe {
        lapack::dsyevr(
            jobz,
            b'A',
            uplo,
            n as i32,
            &mut data,
            n as i32,
            0.0,
            0.0,
            0,
            0,
            -1.0,
            &mut m,
            &mut w,
            &mut z,
            n as i32,
            &mut isuppz,
            &mut work,
            -1,
            &mut iwork,
            -1,
            &mut info,
        )
    };
    assert_eq!(info, 0);
    assert!(work[0] >= 1.0 && iwork[0] >= 1);
    work.resize(work[0] as usize, 0.0);
    iwork.resize(iwork[0] as usize, 0);
    let (lw, liw) = (work.len() as i32, iwork.len() as i32);
    unsafe {
        lapack::dsyevr(
            jobz,
            b'A',
            uplo,
            n as i32,
            &mut data,
            n as i32,
            0.0,
            0.0,
            0,
            0,
            -1.0,
            &mut m,
            &mut w,
            &mut z,
            n as i32,
            &mut isuppz,
            &mut work,
            lw,
            &mut iwork,
            liw,
            &mut info,
        )
    };
    assert_eq!(m, n as i32);
    (info, w, DMatrix::from_column_slice(n, n, &z))
}

#[test]
fn dsyevr_hand_computed_and_reconstruction() {
    // [[2, 1], [1, 2]] has eigenvalues 1 and 3 (ascending) with vectors (1, -1)/√2, (1, 1)/√2.
    let a = DMatrix::from_row_slice(2, 2, &[2.0, 1.0, 1.0, 2.0]);
    let (info, w, z) = syevr(&a, b'V', b'U');
    assert_eq!(info, 0);
    assert!((w[0] - 1.0).abs() < 1e-14 && (w[1] - 3.0).abs() < 1e-14);
    assert!((z[(0, 1)].abs() - 0.5f64.sqrt()).abs() < 1e-14);
    assert!((z[(0, 0)] + z[(1, 0)]).abs() < 1e-14);

    // Clarabel's own test matrix (4×4, to avoid special cases), and random symmetric ones;
    // only the named triangle may be read.
    let mut g = Lcg(9);
    let clarabel = DMatrix::from_row_slice(
        4,
        4,
        &[
            3., 2., 4., 0., 2., 0., 2., 0., 4., 2., 3., 0., 0., 0., 0., 9.,
        ],
    );
    for a in [clarabel, {
        let m = g.matrix(6, 6);
        &m + m.transpose()
    }] {
        for &uplo in b"UL" {
            let mut poisoned = a.clone();
            for j in 0..a.ncols() {
                for i in 0..a.nrows() {
                    if (uplo == b'U' && i > j) || (uplo == b'L' && i < j) {
                        poisoned[(i, j)] = f64::NAN;
                    }
                }
            }
            let (info, w, z) = syevr(&poisoned, b'V', uplo);
            assert_eq!(info, 0);
            assert!(w.windows(2).all(|p| p[0] <= p[1]), "ascending");
            let rec = &z
                * DMatrix::from_diagonal(&nalgebra::DVector::from_vec(w.clone()))
                * z.transpose();
            assert!((rec - &a).amax() < 1e-12);
            assert!((z.transpose() * &z - DMatrix::identity(a.nrows(), a.nrows())).amax() < 1e-12);
            let (_, w_only, _) = syevr(&poisoned, b'N', uplo);
            assert!(w_only.iter().zip(&w).all(|(p, q)| (p - q).abs() < 1e-12));
        }
    }
    // Clarabel's reference eigenvalues for its 4×4 test matrix: -1, -1, 8, 9.
    let c = DMatrix::from_row_slice(
        4,
        4,
        &[
            3., 2., 4., 0., 2., 0., 2., 0., 4., 2., 3., 0., 0., 0., 0., 9.,
        ],
    );
    let (_, w, _) = syevr(&c, b'N', b'U');
    for (got, want) in w.iter().zip([-1.0, -1.0, 8.0, 9.0]) {
        assert!((got - want).abs() < 1e-12, "{w:?}");
    }
}

/// `jobz = N` computes the eigenvalues alone, and they are those of `jobz = V` bit for bit
/// (the same reduction and QR iteration; only the rotations of `Q` are skipped): the SDP's
/// step lengths do not depend on which one Clarabel asks for. Random, graded, clustered,
/// diagonal, rank-one and split matrices of sizes 1–12.
#[test]
fn dsyevr_values_alone_are_the_full_decompositions_bit_for_bit() {
    let mut g = Lcg(11);
    let mut cases = Vec::new();
    for n in 1..=12 {
        let m = g.matrix(n, n);
        cases.push(&m + m.transpose());
        cases.push(g.spd(n));
        let graded = DMatrix::from_fn(n, n, |i, j| {
            10f64.powi(-((i + j) as i32)) * (1.0 + (i * j) as f64)
        });
        cases.push(graded);
        let v = g.matrix(n, 1);
        cases.push(&v * v.transpose());
        cases.push(DMatrix::identity(n, n) * 2.0 + DMatrix::from_element(n, n, 1e-9));
        cases.push(DMatrix::from_fn(
            n,
            n,
            |i, j| if i == j { i as f64 } else { 0.0 },
        ));
        cases.push(DMatrix::from_fn(n, n, |i, j| {
            if i.abs_diff(j) == 1 && i.min(j) != n / 2 {
                0.5
            } else if i == j {
                1.0
            } else {
                0.0
            }
        }));
    }
    for (c, a) in cases.iter().enumerate() {
        for &uplo in b"UL" {
            let (info_v, w_v, _) = syevr(a, b'V', uplo);
            let (info_n, w_n, _) = syevr(a, b'N', uplo);
            assert_eq!((info_v, info_n), (0, 0));
            let bits = |w: &[f64]| w.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
            assert_eq!(
                bits(&w_n),
                bits(&w_v),
                "case {c} ({}×{}), uplo {}",
                a.nrows(),
                a.ncols(),
                uplo as char
            );
        }
    }
}

#[test]
fn dsyevr_rejects_unsupported_range() {
    let mut a = vec![1.0];
    let (mut w, mut z, mut isuppz, mut work, mut iwork) =
        (vec![0.0], vec![0.0], vec![0; 2], vec![0.0; 30], vec![0; 10]);
    let (mut m, mut info) = (0, 0);
    unsafe {
        lapack::dsyevr(
            b'V',
            b'I',
            b'U',
            1,
            &mut a,
            1,
            0.0,
            0.0,
            1,
            1,
            -1.0,
            &mut m,
            &mut w,
            &mut z,
            1,
            &mut isuppz,
            &mut work,
            30,
            &mut iwork,
            10,
            &mut info,
        )
    };
    assert_eq!(info, -2);
}

#[test]
fn dpotrf_dpotrs_hand_computed_and_random() {
    // [[4, 2], [2, 3]] = L Lᵀ with L = [[2, 0], [1, √2]].
    let mut a = vec![4.0, 2.0, 2.0, 3.0];
    let mut info = 0;
    unsafe { lapack::dpotrf(b'L', 2, &mut a, 2, &mut info) };
    assert_eq!(info, 0);
    assert_eq!((a[0], a[1]), (2.0, 1.0));
    assert!((a[3] - 2f64.sqrt()).abs() < 1e-15);
    assert_eq!(a[2], 2.0, "upper triangle untouched");
    // Solve [[4,2],[2,3]] x = [2, 1] → x = [0.5, 0].
    let mut b = vec![2.0, 1.0];
    unsafe { lapack::dpotrs(b'L', 2, 1, &a, 2, &mut b, 2, &mut info) };
    assert!((b[0] - 0.5).abs() < 1e-15 && b[1].abs() < 1e-15);

    let mut g = Lcg(4);
    for &uplo in b"LU" {
        let s = g.spd(5);
        let mut f = s.as_slice().to_vec();
        unsafe { lapack::dpotrf(uplo, 5, &mut f, 5, &mut info) };
        assert_eq!(info, 0);
        let rhs = g.matrix(5, 2);
        let mut x = rhs.as_slice().to_vec();
        unsafe { lapack::dpotrs(uplo, 5, 2, &f, 5, &mut x, 5, &mut info) };
        assert!((&s * DMatrix::from_column_slice(5, 2, &x) - rhs).amax() < 1e-12);
    }
    // Not positive definite: info names the failing leading minor (1-based).
    let mut bad = vec![1.0, 2.0, 2.0, 1.0];
    unsafe { lapack::dpotrf(b'L', 2, &mut bad, 2, &mut info) };
    assert_eq!(info, 2);
}

#[test]
fn dgesdd_and_dgesvd_thin_svd() {
    // diag(3, 2) with a swapped column order: singular values descending [3, 2].
    let mut g = Lcg(5);
    for (m, n) in [(2usize, 2usize), (5, 3), (3, 5)] {
        let a = if (m, n) == (2, 2) {
            DMatrix::from_row_slice(2, 2, &[0.0, 2.0, 3.0, 0.0])
        } else {
            g.matrix(m, n)
        };
        let k = m.min(n);
        for driver in ["gesdd", "gesvd"] {
            let mut data = a.as_slice().to_vec();
            let (mut s, mut u, mut vt) = (vec![0.0; k], vec![0.0; m * k], vec![0.0; k * n]);
            let mut work = vec![0.0; 1];
            let mut iwork = vec![0; 8 * k];
            let mut info = 0;
            for pass in 0..2 {
                let lwork = if pass == 0 { -1 } else { work.len() as i32 };
                unsafe {
                    if driver == "gesdd" {
                        lapack::dgesdd(
                            b'S', m as i32, n as i32, &mut data, m as i32, &mut s, &mut u,
                            m as i32, &mut vt, k as i32, &mut work, lwork, &mut iwork, &mut info,
                        )
                    } else {
                        lapack::dgesvd(
                            b'S', b'S', m as i32, n as i32, &mut data, m as i32, &mut s, &mut u,
                            m as i32, &mut vt, k as i32, &mut work, lwork, &mut info,
                        )
                    }
                }
                assert_eq!(info, 0);
                if pass == 0 {
                    assert!(work[0] >= 1.0);
                    work.resize(work[0] as usize, 0.0);
                }
            }
            assert!(s.windows(2).all(|p| p[0] >= p[1]), "descending");
            let (u, vt) = (
                DMatrix::from_column_slice(m, k, &u),
                DMatrix::from_column_slice(k, n, &vt),
            );
            let rec = &u * DMatrix::from_diagonal(&nalgebra::DVector::from_vec(s.clone())) * &vt;
            assert!((rec - &a).amax() < 1e-12, "{driver} {m}×{n}");
            if (m, n) == (2, 2) {
                assert!((s[0] - 3.0).abs() < 1e-14 && (s[1] - 2.0).abs() < 1e-14);
            }
        }
    }
}

#[test]
fn dgesv_solves_with_pivoting() {
    // [[0, 1], [2, 0]] needs a row swap; x = [1, 2] for b = [2, 2].
    let mut a = vec![0.0, 2.0, 1.0, 0.0];
    let mut b = vec![2.0, 2.0];
    let mut ipiv = vec![0; 2];
    let mut info = 0;
    unsafe { lapack::dgesv(2, 1, &mut a, 2, &mut ipiv, &mut b, 2, &mut info) };
    assert_eq!(info, 0);
    assert_eq!(ipiv[0], 2);
    assert!((b[0] - 1.0).abs() < 1e-15 && (b[1] - 2.0).abs() < 1e-15);
    let mut sing = vec![1.0, 2.0, 2.0, 4.0];
    let mut b = vec![1.0, 1.0];
    unsafe { lapack::dgesv(2, 1, &mut sing, 2, &mut ipiv, &mut b, 2, &mut info) };
    assert_eq!(info, 2);
}

#[test]
fn single_precision_variants() {
    let mut a = vec![2.0f32, 1.0, 1.0, 2.0];
    let (mut w, mut z, mut isuppz) = (vec![0.0f32; 2], vec![0.0f32; 4], vec![0; 4]);
    let (mut work, mut iwork) = (vec![0.0f32; 52], vec![0; 20]);
    let (mut m, mut info) = (0, 0);
    unsafe {
        lapack::ssyevr(
            b'V',
            b'A',
            b'U',
            2,
            &mut a,
            2,
            0.0,
            0.0,
            0,
            0,
            -1.0,
            &mut m,
            &mut w,
            &mut z,
            2,
            &mut isuppz,
            &mut work,
            52,
            &mut iwork,
            20,
            &mut info,
        )
    };
    assert_eq!(info, 0);
    assert!((w[0] - 1.0).abs() < 1e-6 && (w[1] - 3.0).abs() < 1e-6);
    let mut c = vec![4.0f32, 2.0, 2.0, 3.0];
    unsafe { lapack::spotrf(b'U', 2, &mut c, 2, &mut info) };
    assert_eq!(info, 0);
    assert_eq!((c[0], c[2]), (2.0, 1.0));
}

#[test]
fn dsyevr_non_finite_input_gives_nan_without_panicking() {
    // A solver that produced NaN gets NaN back (as from LAPACK), not a panic or a hang.
    let mut a = DMatrix::from_row_slice(
        4,
        4,
        &[
            4., 1., 0., 0., 1., 3., 0., 0., 0., 0., 2., 0., 0., 0., 0., 1.,
        ],
    );
    a[(0, 2)] = f64::NAN;
    a[(2, 0)] = f64::NAN;
    let (info, w, _) = syevr(&a, b'N', b'U');
    assert_eq!(info, 0);
    assert!(w.iter().all(|x| x.is_nan()), "{w:?}");
}
