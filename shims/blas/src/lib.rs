//! Pure-Rust stand-in for the [`blas`](https://crates.io/crates/blas) 0.22 wrapper crate.
//!
//! Clarabel's SDP cones call a handful of BLAS kernels through the `blas` crate, whose
//! FFI declarations need a system BLAS and `libc` types that do not exist on
//! `wasm32-unknown-unknown`. This crate is patched in for `blas` (see the workspace's
//! `[patch.crates-io]`) and provides the same function signatures, implemented in plain
//! Rust, for `f32` and `f64`:
//!
//! | kernel | operation |
//! |---|---|
//! | `?gemm` | `C ← α op(A) op(B) + β C`, every combination of `N`/`T`/`C` |
//! | `?gemv` | `y ← α op(A) x + β y` |
//! | `?symv` | `y ← α A x + β y`, `A` symmetric, one triangle referenced |
//! | `?syrk` | `C ← α A Aᵀ + β C` (`N`) or `α Aᵀ A + β C` (`T`), one triangle updated |
//! | `?syr2k` | `C ← α (A Bᵀ + B Aᵀ) + β C` (`N`) or `α (Aᵀ B + Bᵀ A) + β C` (`T`) |
//!
//! All matrices are column-major with the usual leading dimensions. As in reference BLAS,
//! when `β = 0` the output is not read, so it may hold NaN on entry. The functions keep the
//! `unsafe` signature of the crate they replace; they perform no unchecked access.
#![deny(missing_docs)]
#![allow(clippy::too_many_arguments, clippy::missing_safety_doc)]

use nalgebra::RealField;

#[cfg(not(target_arch = "wasm32"))]
pub mod ffi;

fn is_trans(t: u8) -> bool {
    matches!(t, b'T' | b't' | b'C' | b'c')
}

fn is_upper(uplo: u8) -> bool {
    matches!(uplo, b'U' | b'u')
}

/// Index of the `i`-th element of a strided BLAS vector of length `len`.
fn vidx(i: usize, len: usize, inc: i32) -> usize {
    if inc >= 0 {
        i * inc as usize
    } else {
        (len - 1 - i) * (-inc) as usize
    }
}

fn gemm<T: RealField + Copy>(
    transa: u8,
    transb: u8,
    m: i32,
    n: i32,
    k: i32,
    alpha: T,
    a: &[T],
    lda: i32,
    b: &[T],
    ldb: i32,
    beta: T,
    c: &mut [T],
    ldc: i32,
) {
    let (m, n, k) = (m as usize, n as usize, k as usize);
    let (lda, ldb, ldc) = (lda as usize, ldb as usize, ldc as usize);
    let ta = is_trans(transa);
    let tb = is_trans(transb);
    let zero = nalgebra::zero::<T>();
    // Each entry is `α (((0 + a₁b₁) + a₂b₂) + … + a_kb_k) (+ β c)`, its products summed in
    // the order of `l` in one accumulator: the reference loop's arithmetic (tested bit for
    // bit), with the operands read through slices so that the bounds are checked once per
    // row or column rather than at every product.
    for j in 0..n {
        let ccol = &mut c[j * ldc..j * ldc + m];
        for (i, cij) in ccol.iter_mut().enumerate() {
            let mut acc = zero;
            if k > 0 {
                match (ta, tb) {
                    (true, false) => {
                        for (&x, &y) in a[i * lda..i * lda + k].iter().zip(&b[j * ldb..j * ldb + k])
                        {
                            acc += x * y;
                        }
                    }
                    (true, true) => {
                        for (l, &x) in a[i * lda..i * lda + k].iter().enumerate() {
                            acc += x * b[j + l * ldb];
                        }
                    }
                    (false, false) => {
                        for (l, &y) in b[j * ldb..j * ldb + k].iter().enumerate() {
                            acc += a[i + l * lda] * y;
                        }
                    }
                    (false, true) => {
                        for l in 0..k {
                            acc += a[i + l * lda] * b[j + l * ldb];
                        }
                    }
                }
            }
            *cij = if beta == zero {
                alpha * acc
            } else {
                alpha * acc + beta * *cij
            };
        }
    }
}

fn gemv<T: RealField + Copy>(
    trans: u8,
    m: i32,
    n: i32,
    alpha: T,
    a: &[T],
    lda: i32,
    x: &[T],
    incx: i32,
    beta: T,
    y: &mut [T],
    incy: i32,
) {
    let (m, n, lda) = (m as usize, n as usize, lda as usize);
    let t = is_trans(trans);
    let (ylen, xlen) = if t { (n, m) } else { (m, n) };
    let zero = nalgebra::zero::<T>();
    for i in 0..ylen {
        let mut acc = zero;
        for l in 0..xlen {
            let aval = if t { a[l + i * lda] } else { a[i + l * lda] };
            acc += aval * x[vidx(l, xlen, incx)];
        }
        let yi = &mut y[vidx(i, ylen, incy)];
        *yi = if beta == zero {
            alpha * acc
        } else {
            alpha * acc + beta * *yi
        };
    }
}

fn symv<T: RealField + Copy>(
    uplo: u8,
    n: i32,
    alpha: T,
    a: &[T],
    lda: i32,
    x: &[T],
    incx: i32,
    beta: T,
    y: &mut [T],
    incy: i32,
) {
    let (n, lda) = (n as usize, lda as usize);
    let up = is_upper(uplo);
    let zero = nalgebra::zero::<T>();
    for i in 0..n {
        let mut acc = zero;
        for l in 0..n {
            let (r, c) = if (l >= i) == up { (i, l) } else { (l, i) };
            acc += a[r + c * lda] * x[vidx(l, n, incx)];
        }
        let yi = &mut y[vidx(i, n, incy)];
        *yi = if beta == zero {
            alpha * acc
        } else {
            alpha * acc + beta * *yi
        };
    }
}

/// Entry `(i, l)` of `op(A)` where `op(A)` is `n × k` (`N`: `A` stored `n × k`; `T`: `A` stored `k × n`).
fn opa<T: Copy>(a: &[T], lda: usize, trans: bool, i: usize, l: usize) -> T {
    if trans {
        a[l + i * lda]
    } else {
        a[i + l * lda]
    }
}

fn syr2k_impl<T: RealField + Copy>(
    uplo: u8,
    trans: u8,
    n: i32,
    k: i32,
    alpha: T,
    a: &[T],
    lda: i32,
    b: Option<(&[T], i32)>,
    beta: T,
    c: &mut [T],
    ldc: i32,
) {
    let (n, k, lda, ldc) = (n as usize, k as usize, lda as usize, ldc as usize);
    let t = is_trans(trans);
    let up = is_upper(uplo);
    let zero = nalgebra::zero::<T>();
    for j in 0..n {
        let rows = if up { 0..j + 1 } else { j..n };
        for i in rows {
            let mut acc = zero;
            for l in 0..k {
                match b {
                    None => acc += opa(a, lda, t, i, l) * opa(a, lda, t, j, l),
                    Some((b, ldb)) => {
                        let ldb = ldb as usize;
                        acc += opa(a, lda, t, i, l) * opa(b, ldb, t, j, l)
                            + opa(b, ldb, t, i, l) * opa(a, lda, t, j, l);
                    }
                }
            }
            let cij = &mut c[i + j * ldc];
            *cij = if beta == zero {
                alpha * acc
            } else {
                alpha * acc + beta * *cij
            };
        }
    }
}

macro_rules! blas_fns {
    ($T:ty, $gemm:ident, $gemv:ident, $symv:ident, $syrk:ident, $syr2k:ident) => {
        /// General matrix-matrix product `C ← α op(A) op(B) + β C` (reference BLAS semantics).
        pub unsafe fn $gemm(
            transa: u8,
            transb: u8,
            m: i32,
            n: i32,
            k: i32,
            alpha: $T,
            a: &[$T],
            lda: i32,
            b: &[$T],
            ldb: i32,
            beta: $T,
            c: &mut [$T],
            ldc: i32,
        ) {
            gemm(transa, transb, m, n, k, alpha, a, lda, b, ldb, beta, c, ldc)
        }

        /// General matrix-vector product `y ← α op(A) x + β y` (reference BLAS semantics).
        pub unsafe fn $gemv(
            trans: u8,
            m: i32,
            n: i32,
            alpha: $T,
            a: &[$T],
            lda: i32,
            x: &[$T],
            incx: i32,
            beta: $T,
            y: &mut [$T],
            incy: i32,
        ) {
            gemv(trans, m, n, alpha, a, lda, x, incx, beta, y, incy)
        }

        /// Symmetric matrix-vector product `y ← α A x + β y`, reading only the `uplo` triangle of `A`.
        pub unsafe fn $symv(
            uplo: u8,
            n: i32,
            alpha: $T,
            a: &[$T],
            lda: i32,
            x: &[$T],
            incx: i32,
            beta: $T,
            y: &mut [$T],
            incy: i32,
        ) {
            symv(uplo, n, alpha, a, lda, x, incx, beta, y, incy)
        }

        /// Symmetric rank-k update of the `uplo` triangle of `C`.
        pub unsafe fn $syrk(
            uplo: u8,
            trans: u8,
            n: i32,
            k: i32,
            alpha: $T,
            a: &[$T],
            lda: i32,
            beta: $T,
            c: &mut [$T],
            ldc: i32,
        ) {
            syr2k_impl(uplo, trans, n, k, alpha, a, lda, None, beta, c, ldc)
        }

        /// Symmetric rank-2k update of the `uplo` triangle of `C`.
        pub unsafe fn $syr2k(
            uplo: u8,
            trans: u8,
            n: i32,
            k: i32,
            alpha: $T,
            a: &[$T],
            lda: i32,
            b: &[$T],
            ldb: i32,
            beta: $T,
            c: &mut [$T],
            ldc: i32,
        ) {
            syr2k_impl(
                uplo,
                trans,
                n,
                k,
                alpha,
                a,
                lda,
                Some((b, ldb)),
                beta,
                c,
                ldc,
            )
        }
    };
}

blas_fns!(f64, dgemm, dgemv, dsymv, dsyrk, dsyr2k);
blas_fns!(f32, sgemm, sgemv, ssymv, ssyrk, ssyr2k);
