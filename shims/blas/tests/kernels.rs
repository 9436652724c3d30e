//! The BLAS kernels against hand-computed values and against nalgebra on random
//! column-major data with padded leading dimensions, for f64 and f32.

use nalgebra::DMatrix;

/// Deterministic pseudo-random numbers in [-1, 1).
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
}

/// Column-major storage with leading dimension `ld ≥ rows`, padding filled with NaN.
fn store(m: &DMatrix<f64>, ld: usize) -> Vec<f64> {
    let mut v = vec![f64::NAN; ld * m.ncols().max(1)];
    for j in 0..m.ncols() {
        for i in 0..m.nrows() {
            v[i + j * ld] = m[(i, j)];
        }
    }
    v
}

fn load(v: &[f64], r: usize, c: usize, ld: usize) -> DMatrix<f64> {
    DMatrix::from_fn(r, c, |i, j| v[i + j * ld])
}

#[test]
fn dgemm_hand_computed() {
    // A = [1 2; 3 4], B = [5 6; 7 8]: A B = [19 22; 43 50]; Aᵀ B = [26 30; 38 44].
    let a = [1.0, 3.0, 2.0, 4.0];
    let b = [5.0, 7.0, 6.0, 8.0];
    let mut c = [0.0; 4];
    unsafe { blas::dgemm(b'N', b'N', 2, 2, 2, 1.0, &a, 2, &b, 2, 0.0, &mut c, 2) };
    assert_eq!(c, [19.0, 43.0, 22.0, 50.0]);
    unsafe { blas::dgemm(b'T', b'N', 2, 2, 2, 1.0, &a, 2, &b, 2, 0.0, &mut c, 2) };
    assert_eq!(c, [26.0, 38.0, 30.0, 44.0]);
    // β = 1 accumulates, α scales.
    unsafe { blas::dgemm(b'T', b'N', 2, 2, 2, 2.0, &a, 2, &b, 2, 1.0, &mut c, 2) };
    assert_eq!(c, [78.0, 114.0, 90.0, 132.0]);
}

#[test]
fn dgemm_every_transpose_against_nalgebra() {
    let mut g = Lcg(1);
    let (m, n, k) = (5, 4, 3);
    for &ta in b"NTC" {
        for &tb in b"NTC" {
            let opa = g.matrix(m, k);
            let opb = g.matrix(k, n);
            let c0 = g.matrix(m, n);
            let (a, lda) = if ta == b'N' {
                (store(&opa, m + 2), m + 2)
            } else {
                (store(&opa.transpose(), k + 1), k + 1)
            };
            let (b, ldb) = if tb == b'N' {
                (store(&opb, k + 3), k + 3)
            } else {
                (store(&opb.transpose(), n + 1), n + 1)
            };
            let mut c = store(&c0, m + 1);
            unsafe {
                blas::dgemm(
                    ta,
                    tb,
                    m as i32,
                    n as i32,
                    k as i32,
                    0.7,
                    &a,
                    lda as i32,
                    &b,
                    ldb as i32,
                    -0.3,
                    &mut c,
                    (m + 1) as i32,
                )
            };
            let expected = &opa * &opb * 0.7 + &c0 * -0.3;
            assert!((load(&c, m, n, m + 1) - expected).amax() < 1e-14);
            assert!(c[m].is_nan(), "padding untouched");
        }
    }
}

/// `dgemm` sums each entry's products in the order of `l`, from `0`, then scales (the
/// textbook triple loop): the same bits on every target and for every loop order the kernel
/// picks, so a change of its loops cannot move a number of the SDP. Sizes from 1 to 40 rows,
/// `k = 0`, `β = 0` over NaN, padded leading dimensions, and every transpose.
#[test]
fn dgemm_is_the_triple_loop_bit_for_bit() {
    let mut g = Lcg(7);
    for &(m, n, k) in &[
        (1, 1, 1),
        (4, 4, 4),
        (6, 3, 10),
        (10, 10, 4),
        (33, 5, 7),
        (40, 2, 0),
    ] {
        for &ta in b"NTC" {
            for &tb in b"NTC" {
                for beta in [0.0, -0.3] {
                    let (ra, ca) = if ta == b'N' { (m, k) } else { (k, m) };
                    let (rb, cb) = if tb == b'N' { (k, n) } else { (n, k) };
                    let (lda, ldb, ldc) = (ra + 1, rb + 2, m + 3);
                    let a = store(&g.matrix(ra, ca), lda);
                    let b = store(&g.matrix(rb, cb), ldb);
                    let c0 = if beta == 0.0 {
                        vec![f64::NAN; ldc * n]
                    } else {
                        store(&g.matrix(m, n), ldc)
                    };
                    let mut c = c0.clone();
                    let alpha = 0.7;
                    unsafe {
                        blas::dgemm(
                            ta, tb, m as i32, n as i32, k as i32, alpha, &a, lda as i32, &b,
                            ldb as i32, beta, &mut c, ldc as i32,
                        )
                    };
                    for j in 0..n {
                        for i in 0..m {
                            let mut acc = 0.0;
                            for l in 0..k {
                                let av = if ta == b'N' {
                                    a[i + l * lda]
                                } else {
                                    a[l + i * lda]
                                };
                                let bv = if tb == b'N' {
                                    b[l + j * ldb]
                                } else {
                                    b[j + l * ldb]
                                };
                                acc += av * bv;
                            }
                            let want = if beta == 0.0 {
                                alpha * acc
                            } else {
                                alpha * acc + beta * c0[i + j * ldc]
                            };
                            assert_eq!(
                                c[i + j * ldc].to_bits(),
                                want.to_bits(),
                                "{}{} m {m} n {n} k {k} β {beta}: ({i}, {j})",
                                ta as char,
                                tb as char
                            );
                        }
                        for i in m..ldc {
                            assert_eq!(
                                c[i + j * ldc].to_bits(),
                                c0[i + j * ldc].to_bits(),
                                "padding"
                            );
                        }
                    }
                }
            }
        }
    }
}

/// With `k = 0` reference BLAS reads neither `A` nor `B` (they may be empty): `C ← β C`, or
/// `α·0` when `β = 0`; no panic for any transpose.
#[test]
fn dgemm_with_k_zero_reads_no_operand() {
    for &ta in b"NT" {
        for &tb in b"NT" {
            let mut c = [1.0, 2.0, 3.0, 4.0, 5.0, 6.0];
            unsafe { blas::dgemm(ta, tb, 3, 2, 0, 0.7, &[], 1, &[], 1, 0.5, &mut c, 3) };
            assert_eq!(c, [0.5, 1.0, 1.5, 2.0, 2.5, 3.0]);
            let mut c = [f64::NAN; 6];
            unsafe { blas::dgemm(ta, tb, 3, 2, 0, 0.7, &[], 1, &[], 1, 0.0, &mut c, 3) };
            assert_eq!(c, [0.0; 6]);
        }
    }
}

#[test]
fn beta_zero_ignores_nan_output() {
    let a = [1.0, 2.0];
    let mut y = [f64::NAN, f64::NAN];
    unsafe { blas::dgemv(b'N', 2, 1, 1.0, &a, 2, &[3.0], 1, 0.0, &mut y, 1) };
    assert_eq!(y, [3.0, 6.0]);
}

#[test]
fn dgemv_and_dsymv_against_nalgebra() {
    let mut g = Lcg(2);
    let a = g.matrix(4, 3);
    let x3 = g.matrix(3, 1);
    let x4 = g.matrix(4, 1);
    let y0 = g.matrix(4, 1);
    let mut y = y0.as_slice().to_vec();
    unsafe {
        blas::dgemv(
            b'N',
            4,
            3,
            2.0,
            &store(&a, 5),
            5,
            x3.as_slice(),
            1,
            0.5,
            &mut y,
            1,
        )
    };
    assert!((DMatrix::from_column_slice(4, 1, &y) - (&a * &x3 * 2.0 + &y0 * 0.5)).amax() < 1e-14);
    let mut y = vec![0.0; 3];
    unsafe {
        blas::dgemv(
            b'T',
            4,
            3,
            1.0,
            &store(&a, 4),
            4,
            x4.as_slice(),
            1,
            0.0,
            &mut y,
            1,
        )
    };
    assert!((DMatrix::from_column_slice(3, 1, &y) - a.transpose() * &x4).amax() < 1e-14);
    // Strided x (incx = 2).
    let xs: Vec<f64> = x3.iter().flat_map(|v| [*v, f64::NAN]).collect();
    let mut y = vec![0.0; 4];
    unsafe { blas::dgemv(b'N', 4, 3, 1.0, &store(&a, 4), 4, &xs, 2, 0.0, &mut y, 1) };
    assert!((DMatrix::from_column_slice(4, 1, &y) - &a * &x3).amax() < 1e-14);

    let s = {
        let m = g.matrix(4, 4);
        &m + m.transpose()
    };
    for &uplo in b"UL" {
        // Only the named triangle is read: poison the other one.
        let mut st = store(&s, 4);
        for j in 0..4 {
            for i in 0..4 {
                if (uplo == b'U' && i > j) || (uplo == b'L' && i < j) {
                    st[i + 4 * j] = f64::NAN;
                }
            }
        }
        let mut y = y0.as_slice().to_vec();
        unsafe { blas::dsymv(uplo, 4, 1.5, &st, 4, x4.as_slice(), 1, 1.0, &mut y, 1) };
        assert!((DMatrix::from_column_slice(4, 1, &y) - (&s * &x4 * 1.5 + &y0)).amax() < 1e-14);
    }
}

#[test]
fn dsyrk_and_dsyr2k_update_one_triangle() {
    let mut g = Lcg(3);
    let (n, k) = (4, 3);
    for &trans in b"NT" {
        for &uplo in b"UL" {
            let a = if trans == b'N' {
                g.matrix(n, k)
            } else {
                g.matrix(k, n)
            };
            let b = if trans == b'N' {
                g.matrix(n, k)
            } else {
                g.matrix(k, n)
            };
            let c0 = {
                let m = g.matrix(n, n);
                &m + m.transpose()
            };
            let (opa, opb) = if trans == b'N' {
                (a.clone(), b.clone())
            } else {
                (a.transpose(), b.transpose())
            };
            let lda = a.nrows() + 1;
            let mut c = store(&c0, n);
            unsafe {
                blas::dsyrk(
                    uplo,
                    trans,
                    n as i32,
                    k as i32,
                    0.5,
                    &store(&a, lda),
                    lda as i32,
                    2.0,
                    &mut c,
                    n as i32,
                )
            };
            let expected = &opa * opa.transpose() * 0.5 + &c0 * 2.0;
            let mut c2 = store(&c0, n);
            unsafe {
                blas::dsyr2k(
                    uplo,
                    trans,
                    n as i32,
                    k as i32,
                    1.0,
                    &store(&a, lda),
                    lda as i32,
                    &store(&b, lda),
                    lda as i32,
                    0.0,
                    &mut c2,
                    n as i32,
                )
            };
            let expected2 = &opa * opb.transpose() + &opb * opa.transpose();
            let got = load(&c, n, n, n);
            let got2 = load(&c2, n, n, n);
            for j in 0..n {
                for i in 0..n {
                    let in_tri = if uplo == b'U' { i <= j } else { i >= j };
                    if in_tri {
                        assert!((got[(i, j)] - expected[(i, j)]).abs() < 1e-14);
                        assert!((got2[(i, j)] - expected2[(i, j)]).abs() < 1e-14);
                    } else {
                        assert_eq!(got[(i, j)], c0[(i, j)], "other triangle untouched");
                        assert_eq!(got2[(i, j)], c0[(i, j)]);
                    }
                }
            }
        }
    }
}

#[test]
fn single_precision_variants() {
    let a = [1.0f32, 3.0, 2.0, 4.0];
    let b = [5.0f32, 7.0, 6.0, 8.0];
    let mut c = [0.0f32; 4];
    unsafe { blas::sgemm(b'N', b'N', 2, 2, 2, 1.0, &a, 2, &b, 2, 0.0, &mut c, 2) };
    assert_eq!(c, [19.0, 43.0, 22.0, 50.0]);
    let mut c = [0.0f32; 4];
    unsafe { blas::ssyrk(b'U', b'N', 2, 2, 1.0, &a, 2, 0.0, &mut c, 2) };
    // A Aᵀ = [5 11; 11 25]
    assert_eq!((c[0], c[2], c[3]), (5.0, 11.0, 25.0));
    let mut y = [0.0f32; 2];
    unsafe {
        blas::ssymv(
            b'L',
            2,
            1.0,
            &[2.0, 1.0, f32::NAN, 3.0],
            2,
            &[1.0, 1.0],
            1,
            0.0,
            &mut y,
            1,
        )
    };
    assert_eq!(y, [3.0, 4.0]);
}
