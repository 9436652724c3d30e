//! The Fortran symbols (`dgemm_`, …) of the kernels above, for a crate that depends on nmci
//! outside its workspace.
//!
//! Clarabel calls BLAS through the `blas` crate. Inside nmci's workspace `[patch.crates-io]`
//! replaces that crate by this one; a crate depending on nmci does not see the workspace's
//! patches, gets the real `blas` crate, and its `blas-sys` declares `extern "C"` symbols that a
//! system BLAS would define. These definitions are those symbols, over this crate's kernels, so
//! such a crate links with no system BLAS (natively; on `wasm32` the real crate does not
//! compile and the patch stays necessary: docs/rust.md).
//!
//! Each pointer is read as a slice of exactly the elements reference BLAS may touch (column
//! `j` of an `r × c` matrix with leading dimension `ld` spans `ld·(c − 1) + r` elements), so
//! the kernels' bounds-checked indexing stays inside the caller's arrays.
#![allow(clippy::too_many_arguments)]

use std::os::raw::{c_char, c_int};

/// The elements an `rows × cols` column-major matrix with leading dimension `ld` spans (the
/// kernels index `i + j·ld`, so an invalid `ld < rows` still stays inside).
pub fn span(rows: c_int, cols: c_int, ld: c_int) -> usize {
    if rows <= 0 || cols <= 0 {
        0
    } else {
        ld.max(1) as usize * (cols as usize - 1) + rows as usize
    }
}

/// The elements a strided vector of `n` entries with increment `inc` spans.
pub fn vspan(n: c_int, inc: c_int) -> usize {
    if n <= 0 {
        0
    } else {
        1 + (n as usize - 1) * inc.unsigned_abs() as usize
    }
}

/// `len` elements at `p` (a dangling, empty slice for `len = 0`).
///
/// # Safety
/// `p` points to at least `len` initialised elements (any pointer when `len = 0`).
pub unsafe fn view<'a, T>(p: *const T, len: usize) -> &'a [T] {
    if len == 0 || p.is_null() {
        &[]
    } else {
        std::slice::from_raw_parts(p, len)
    }
}

/// [`view`], mutable.
///
/// # Safety
/// As [`view`], and nothing else reads or writes those elements meanwhile.
pub unsafe fn view_mut<'a, T>(p: *mut T, len: usize) -> &'a mut [T] {
    if len == 0 || p.is_null() {
        &mut []
    } else {
        std::slice::from_raw_parts_mut(p, len)
    }
}

fn trans(t: c_char) -> bool {
    matches!(t as u8, b'T' | b't' | b'C' | b'c')
}

macro_rules! blas_ffi {
    ($T:ty, $gemm:ident => $gemm_:ident, $gemv:ident => $gemv_:ident, $symv:ident => $symv_:ident,
     $syrk:ident => $syrk_:ident, $syr2k:ident => $syr2k_:ident) => {
        /// Reference BLAS's Fortran symbol over the kernel of the same name.
        ///
        /// # Safety
        /// The Fortran BLAS contract: every pointer valid for the sizes its arguments give.
        #[no_mangle]
        pub unsafe extern "C" fn $gemm_(
            transa: *const c_char,
            transb: *const c_char,
            m: *const c_int,
            n: *const c_int,
            k: *const c_int,
            alpha: *const $T,
            a: *const $T,
            lda: *const c_int,
            b: *const $T,
            ldb: *const c_int,
            beta: *const $T,
            c: *mut $T,
            ldc: *const c_int,
        ) {
            let (ta, tb, m, n, k) = (*transa, *transb, *m, *n, *k);
            let (ar, ac) = if trans(ta) { (k, m) } else { (m, k) };
            let (br, bc) = if trans(tb) { (n, k) } else { (k, n) };
            crate::$gemm(
                ta as u8,
                tb as u8,
                m,
                n,
                k,
                *alpha,
                view(a, span(ar, ac, *lda)),
                *lda,
                view(b, span(br, bc, *ldb)),
                *ldb,
                *beta,
                view_mut(c, span(m, n, *ldc)),
                *ldc,
            )
        }

        /// Reference BLAS's Fortran symbol over the kernel of the same name.
        ///
        /// # Safety
        /// The Fortran BLAS contract: every pointer valid for the sizes its arguments give.
        #[no_mangle]
        pub unsafe extern "C" fn $gemv_(
            t: *const c_char,
            m: *const c_int,
            n: *const c_int,
            alpha: *const $T,
            a: *const $T,
            lda: *const c_int,
            x: *const $T,
            incx: *const c_int,
            beta: *const $T,
            y: *mut $T,
            incy: *const c_int,
        ) {
            let (t, m, n) = (*t, *m, *n);
            let (lx, ly) = if trans(t) { (m, n) } else { (n, m) };
            crate::$gemv(
                t as u8,
                m,
                n,
                *alpha,
                view(a, span(m, n, *lda)),
                *lda,
                view(x, vspan(lx, *incx)),
                *incx,
                *beta,
                view_mut(y, vspan(ly, *incy)),
                *incy,
            )
        }

        /// Reference BLAS's Fortran symbol over the kernel of the same name.
        ///
        /// # Safety
        /// The Fortran BLAS contract: every pointer valid for the sizes its arguments give.
        #[no_mangle]
        pub unsafe extern "C" fn $symv_(
            uplo: *const c_char,
            n: *const c_int,
            alpha: *const $T,
            a: *const $T,
            lda: *const c_int,
            x: *const $T,
            incx: *const c_int,
            beta: *const $T,
            y: *mut $T,
            incy: *const c_int,
        ) {
            let n = *n;
            crate::$symv(
                *uplo as u8,
                n,
                *alpha,
                view(a, span(n, n, *lda)),
                *lda,
                view(x, vspan(n, *incx)),
                *incx,
                *beta,
                view_mut(y, vspan(n, *incy)),
                *incy,
            )
        }

        /// Reference BLAS's Fortran symbol over the kernel of the same name.
        ///
        /// # Safety
        /// The Fortran BLAS contract: every pointer valid for the sizes its arguments give.
        #[no_mangle]
        pub unsafe extern "C" fn $syrk_(
            uplo: *const c_char,
            t: *const c_char,
            n: *const c_int,
            k: *const c_int,
            alpha: *const $T,
            a: *const $T,
            lda: *const c_int,
            beta: *const $T,
            c: *mut $T,
            ldc: *const c_int,
        ) {
            let (t, n, k) = (*t, *n, *k);
            let (ar, ac) = if trans(t) { (k, n) } else { (n, k) };
            crate::$syrk(
                *uplo as u8,
                t as u8,
                n,
                k,
                *alpha,
                view(a, span(ar, ac, *lda)),
                *lda,
                *beta,
                view_mut(c, span(n, n, *ldc)),
                *ldc,
            )
        }

        /// Reference BLAS's Fortran symbol over the kernel of the same name.
        ///
        /// # Safety
        /// The Fortran BLAS contract: every pointer valid for the sizes its arguments give.
        #[no_mangle]
        pub unsafe extern "C" fn $syr2k_(
            uplo: *const c_char,
            t: *const c_char,
            n: *const c_int,
            k: *const c_int,
            alpha: *const $T,
            a: *const $T,
            lda: *const c_int,
            b: *const $T,
            ldb: *const c_int,
            beta: *const $T,
            c: *mut $T,
            ldc: *const c_int,
        ) {
            let (t, n, k) = (*t, *n, *k);
            let (r, cols) = if trans(t) { (k, n) } else { (n, k) };
            crate::$syr2k(
                *uplo as u8,
                t as u8,
                n,
                k,
                *alpha,
                view(a, span(r, cols, *lda)),
                *lda,
                view(b, span(r, cols, *ldb)),
                *ldb,
                *beta,
                view_mut(c, span(n, n, *ldc)),
                *ldc,
            )
        }
    };
}

blas_ffi!(f64, dgemm => dgemm_, dgemv => dgemv_, dsymv => dsymv_, dsyrk => dsyrk_, dsyr2k => dsyr2k_);
blas_ffi!(f32, sgemm => sgemm_, sgemv => sgemv_, ssymv => ssymv_, ssyrk => ssyrk_, ssyr2k => ssyr2k_);
