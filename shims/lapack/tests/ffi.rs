//! The Fortran symbols (`src/ffi.rs`) give the drivers' results bit for bit, padded leading
//! dimensions and workspace queries included. Native only, as the symbols are.
#![cfg(not(target_arch = "wasm32"))]

use blas::ffi::span;
use lapack::ffi::*;

fn spd(n: i32, ld: i32) -> Vec<f64> {
    let mut a = vec![f64::NAN; span(n, n, ld)];
    for j in 0..n {
        for i in 0..n {
            let v = 1.0 / (1.0 + (i - j).abs() as f64) + if i == j { n as f64 } else { 0.0 };
            a[(i + j * ld) as usize] = v;
        }
    }
    a
}

#[test]
fn the_fortran_symbols_are_the_drivers() {
    let (n, lda) = (4i32, 6i32);
    for jobz in [b'V', b'N'] {
        let (mut a1, mut a2) = (spd(n, lda), spd(n, lda));
        let (mut m1, mut m2, mut i1, mut i2) = (0, 0, 0, 0);
        let (mut w1, mut w2) = (vec![0.0; 4], vec![0.0; 4]);
        let ldz = 5;
        let (mut z1, mut z2) = (vec![0.0; span(n, n, ldz)], vec![0.0; span(n, n, ldz)]);
        let (mut s1, mut s2) = (vec![0; 8], vec![0; 8]);
        let (mut work1, mut work2) = (vec![0.0; 200], vec![0.0; 200]);
        let (mut iw1, mut iw2) = (vec![0; 50], vec![0; 50]);
        unsafe {
            lapack::dsyevr(
                jobz, b'A', b'U', n, &mut a1, lda, 0.0, 0.0, 0, 0, 0.0, &mut m1, &mut w1, &mut z1,
                ldz, &mut s1, &mut work1, 200, &mut iw1, 50, &mut i1,
            );
            dsyevr_(
                &(jobz as _),
                &(b'A' as _),
                &(b'U' as _),
                &n,
                a2.as_mut_ptr(),
                &lda,
                &0.0,
                &0.0,
                &0,
                &0,
                &0.0,
                &mut m2,
                w2.as_mut_ptr(),
                z2.as_mut_ptr(),
                &ldz,
                s2.as_mut_ptr(),
                work2.as_mut_ptr(),
                &200,
                iw2.as_mut_ptr(),
                &50,
                &mut i2,
            );
        }
        assert_eq!((i1, m1, &w1), (i2, m2, &w2), "syevr {jobz}");
        if jobz == b'V' {
            assert_eq!(z1, z2);
        }
        // A workspace query writes one entry.
        let (mut q, mut iq, mut info) = (0.0, 0, 0);
        unsafe {
            dsyevr_(
                &(jobz as _),
                &(b'A' as _),
                &(b'L' as _),
                &n,
                a2.as_mut_ptr(),
                &lda,
                &0.0,
                &0.0,
                &0,
                &0,
                &0.0,
                &mut m2,
                w2.as_mut_ptr(),
                z2.as_mut_ptr(),
                &ldz,
                s2.as_mut_ptr(),
                &mut q,
                &-1,
                &mut iq,
                &-1,
                &mut info,
            );
        }
        assert!(q >= 1.0 && iq >= 1 && info == 0);
    }
    // Cholesky and its solve.
    let (mut a1, mut a2) = (spd(n, lda), spd(n, lda));
    let (mut i1, mut i2) = (0, 0);
    unsafe {
        lapack::dpotrf(b'L', n, &mut a1, lda, &mut i1);
        dpotrf_(&(b'L' as _), &n, a2.as_mut_ptr(), &lda, &mut i2);
    }
    let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    assert_eq!((bits(&a1), i1), (bits(&a2), i2), "potrf (NaN padding kept)");
    let ldb = 5;
    let mut b1: Vec<f64> = (0..span(n, 2, ldb)).map(|i| i as f64).collect();
    let mut b2 = b1.clone();
    unsafe {
        lapack::dpotrs(b'L', n, 2, &a1, lda, &mut b1, ldb, &mut i1);
        dpotrs_(
            &(b'L' as _),
            &n,
            &2,
            a2.as_ptr(),
            &lda,
            b2.as_mut_ptr(),
            &ldb,
            &mut i2,
        );
    }
    assert_eq!((b1.clone(), i1), (b2.clone(), i2));
    // LU solve.
    let (mut a1, mut a2) = (spd(n, lda), spd(n, lda));
    let (mut p1, mut p2) = (vec![0; 4], vec![0; 4]);
    let (mut c1, mut c2) = (b1.clone(), b1);
    unsafe {
        lapack::dgesv(n, 2, &mut a1, lda, &mut p1, &mut c1, ldb, &mut i1);
        dgesv_(
            &n,
            &2,
            a2.as_mut_ptr(),
            &lda,
            p2.as_mut_ptr(),
            c2.as_mut_ptr(),
            &ldb,
            &mut i2,
        );
    }
    assert_eq!((c1, p1, i1), (c2, p2, i2));
    // Thin SVDs of a 4 × 3 matrix.
    let (m, k) = (4i32, 3i32);
    let a: Vec<f64> = (0..span(m, k, lda))
        .map(|i| ((i * 7 % 11) as f64) - 5.0)
        .collect();
    let (ldu, ldvt) = (5, 4);
    let run = |ffi: bool, sdd: bool| {
        let mut a = a.clone();
        let (mut s, mut u, mut vt) = (
            vec![0.0; 3],
            vec![0.0; span(m, k, ldu)],
            vec![0.0; span(k, k, ldvt)],
        );
        let (mut work, mut iw, mut info) = (vec![0.0; 300], vec![0; 24], 0);
        unsafe {
            match (ffi, sdd) {
                (false, true) => lapack::dgesdd(
                    b'S', m, k, &mut a, lda, &mut s, &mut u, ldu, &mut vt, ldvt, &mut work, 300,
                    &mut iw, &mut info,
                ),
                (true, true) => dgesdd_(
                    &(b'S' as _),
                    &m,
                    &k,
                    a.as_mut_ptr(),
                    &lda,
                    s.as_mut_ptr(),
                    u.as_mut_ptr(),
                    &ldu,
                    vt.as_mut_ptr(),
                    &ldvt,
                    work.as_mut_ptr(),
                    &300,
                    iw.as_mut_ptr(),
                    &mut info,
                ),
                (false, false) => lapack::dgesvd(
                    b'S', b'S', m, k, &mut a, lda, &mut s, &mut u, ldu, &mut vt, ldvt, &mut work,
                    300, &mut info,
                ),
                (true, false) => dgesvd_(
                    &(b'S' as _),
                    &(b'S' as _),
                    &m,
                    &k,
                    a.as_mut_ptr(),
                    &lda,
                    s.as_mut_ptr(),
                    u.as_mut_ptr(),
                    &ldu,
                    vt.as_mut_ptr(),
                    &ldvt,
                    work.as_mut_ptr(),
                    &300,
                    &mut info,
                ),
            }
        }
        (s, u, vt, info)
    };
    assert_eq!(run(false, true), run(true, true), "gesdd");
    assert_eq!(run(false, false), run(true, false), "gesvd");
    // Single precision: the `s` twins.
    let mut a = [4.0f32, 2.0, 2.0, 3.0];
    let mut info = 0;
    unsafe { spotrf_(&(b'U' as _), &2, a.as_mut_ptr(), &2, &mut info) };
    assert_eq!((a[0], info), (2.0, 0));
}
