//! The Fortran symbols (`src/ffi.rs`) give the kernels' results bit for bit, on padded
//! leading dimensions and both transposes: the spans they read are exactly the elements the
//! kernels index (a short span panics on an index, a long one would read past the buffers
//! Miri or the sanitizers watch). Native only, as the symbols are.
#![cfg(not(target_arch = "wasm32"))]

use blas::ffi::*;

fn data(len: usize, seed: u64) -> Vec<f64> {
    let mut s = seed;
    (0..len)
        .map(|_| {
            s = s
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((s >> 11) as f64 / (1u64 << 53) as f64) * 2.0 - 1.0
        })
        .collect()
}

#[test]
fn the_fortran_symbols_are_the_kernels() {
    let (m, n, k) = (3i32, 4i32, 2i32);
    for (ta, tb) in [(b'N', b'N'), (b'T', b'N'), (b'N', b'T'), (b'T', b'T')] {
        let (ar, ac) = if ta == b'T' { (k, m) } else { (m, k) };
        let (br, bc) = if tb == b'T' { (n, k) } else { (k, n) };
        let (lda, ldb, ldc) = (ar + 2, br + 1, m + 3);
        let a = data(span(ar, ac, lda), 1);
        let b = data(span(br, bc, ldb), 2);
        let mut c1 = data(span(m, n, ldc), 3);
        let mut c2 = c1.clone();
        let (alpha, beta) = (0.7, -0.3);
        unsafe {
            blas::dgemm(ta, tb, m, n, k, alpha, &a, lda, &b, ldb, beta, &mut c1, ldc);
            dgemm_(
                &(ta as _),
                &(tb as _),
                &m,
                &n,
                &k,
                &alpha,
                a.as_ptr(),
                &lda,
                b.as_ptr(),
                &ldb,
                &beta,
                c2.as_mut_ptr(),
                &ldc,
            );
        }
        assert_eq!(c1, c2, "gemm {ta} {tb}");
    }
    for t in [b'N', b'T'] {
        let (m, n, lda) = (3i32, 2i32, 5i32);
        let (lx, ly) = if t == b'T' { (m, n) } else { (n, m) };
        let a = data(span(m, n, lda), 4);
        let x = data(vspan(lx, 2), 5);
        let mut y1 = data(vspan(ly, 3), 6);
        let mut y2 = y1.clone();
        unsafe {
            blas::dgemv(t, m, n, 1.5, &a, lda, &x, 2, 0.5, &mut y1, 3);
            dgemv_(
                &(t as _),
                &m,
                &n,
                &1.5,
                a.as_ptr(),
                &lda,
                x.as_ptr(),
                &2,
                &0.5,
                y2.as_mut_ptr(),
                &3,
            );
        }
        assert_eq!(y1, y2, "gemv {t}");
    }
    for uplo in [b'U', b'L'] {
        let (n, lda) = (3i32, 4i32);
        let a = data(span(n, n, lda), 7);
        let x = data(vspan(n, 1), 8);
        let mut y1 = data(vspan(n, 1), 9);
        let mut y2 = y1.clone();
        unsafe {
            blas::dsymv(uplo, n, 2.0, &a, lda, &x, 1, 1.0, &mut y1, 1);
            dsymv_(
                &(uplo as _),
                &n,
                &2.0,
                a.as_ptr(),
                &lda,
                x.as_ptr(),
                &1,
                &1.0,
                y2.as_mut_ptr(),
                &1,
            );
        }
        assert_eq!(y1, y2, "symv {uplo}");
        for t in [b'N', b'T'] {
            let k = 2i32;
            let (r, c) = if t == b'T' { (k, n) } else { (n, k) };
            let (lda, ldb, ldc) = (r + 1, r + 2, n + 1);
            let a = data(span(r, c, lda), 10);
            let b = data(span(r, c, ldb), 11);
            let mut c1 = data(span(n, n, ldc), 12);
            let mut c2 = c1.clone();
            let mut d1 = c1.clone();
            let mut d2 = c1.clone();
            unsafe {
                blas::dsyrk(uplo, t, n, k, 0.9, &a, lda, 0.1, &mut c1, ldc);
                dsyrk_(
                    &(uplo as _),
                    &(t as _),
                    &n,
                    &k,
                    &0.9,
                    a.as_ptr(),
                    &lda,
                    &0.1,
                    c2.as_mut_ptr(),
                    &ldc,
                );
                blas::dsyr2k(uplo, t, n, k, 0.9, &a, lda, &b, ldb, 0.1, &mut d1, ldc);
                dsyr2k_(
                    &(uplo as _),
                    &(t as _),
                    &n,
                    &k,
                    &0.9,
                    a.as_ptr(),
                    &lda,
                    b.as_ptr(),
                    &ldb,
                    &0.1,
                    d2.as_mut_ptr(),
                    &ldc,
                );
            }
            assert_eq!(c1, c2, "syrk {uplo} {t}");
            assert_eq!(d1, d2, "syr2k {uplo} {t}");
        }
    }
    // Single precision: the same symbols' `s` twins.
    let a = [1.0f32, 3.0, 2.0, 4.0];
    let mut c = [0.0f32; 4];
    unsafe {
        sgemm_(
            &(b'N' as _),
            &(b'N' as _),
            &2,
            &2,
            &2,
            &1.0,
            a.as_ptr(),
            &2,
            a.as_ptr(),
            &2,
            &0.0,
            c.as_mut_ptr(),
            &2,
        )
    };
    assert_eq!(c, [7.0, 15.0, 10.0, 22.0]);
}
