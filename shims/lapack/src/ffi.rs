//! The Fortran symbols (`dsyevr_`, …) of the drivers above, for a crate that depends on nmci
//! outside its workspace: as `blas::ffi` (the shim's) does for BLAS, so a dependent links with
//! no system LAPACK (natively; on `wasm32` the real `lapack` crate does not compile and the
//! workspace's patch stays necessary).
//!
//! Each array is read as a slice of exactly the elements LAPACK's contract lets the driver
//! touch: matrices by [`span`], `w`/`s` by the order, workspaces by their length (one element
//! for a workspace query, `lwork = −1`).
#![allow(clippy::too_many_arguments, non_snake_case)]

use std::os::raw::{c_char, c_int};

use blas::ffi::{span, view, view_mut};

/// A workspace of `len` entries, or the one entry a query (`len = −1`) writes.
fn workspace(len: c_int) -> usize {
    len.max(1) as usize
}

fn jobs(job: c_char, rows: c_int, cols: c_int, ld: c_int) -> usize {
    if matches!(job as u8, b'N' | b'n') {
        0
    } else {
        span(rows, cols, ld)
    }
}

macro_rules! lapack_ffi {
    ($T:ty, $syevr:ident => $syevr_:ident, $potrf:ident => $potrf_:ident, $potrs:ident => $potrs_:ident,
     $gesdd:ident => $gesdd_:ident, $gesvd:ident => $gesvd_:ident, $gesv:ident => $gesv_:ident) => {
        /// LAPACK's Fortran symbol over the driver of the same name.
        ///
        /// # Safety
        /// The Fortran LAPACK contract: every pointer valid for the sizes its arguments give.
        #[no_mangle]
        pub unsafe extern "C" fn $syevr_(
            jobz: *const c_char,
            range: *const c_char,
            uplo: *const c_char,
            n: *const c_int,
            A: *mut $T,
            lda: *const c_int,
            vl: *const $T,
            vu: *const $T,
            il: *const c_int,
            iu: *const c_int,
            abstol: *const $T,
            m: *mut c_int,
            W: *mut $T,
            Z: *mut $T,
            ldz: *const c_int,
            ISUPPZ: *mut c_int,
            work: *mut $T,
            lwork: *const c_int,
            iwork: *mut c_int,
            liwork: *const c_int,
            info: *mut c_int,
        ) {
            let n = *n;
            crate::$syevr(
                *jobz as u8,
                *range as u8,
                *uplo as u8,
                n,
                view_mut(A, span(n, n, *lda)),
                *lda,
                *vl,
                *vu,
                *il,
                *iu,
                *abstol,
                &mut *m,
                view_mut(W, n.max(0) as usize),
                view_mut(Z, jobs(*jobz, n, n, *ldz)),
                *ldz,
                view_mut(ISUPPZ, jobs(*jobz, 2, n, 2)),
                view_mut(work, workspace(*lwork)),
                *lwork,
                view_mut(iwork, workspace(*liwork)),
                *liwork,
                &mut *info,
            )
        }

        /// LAPACK's Fortran symbol over the driver of the same name.
        ///
        /// # Safety
        /// The Fortran LAPACK contract: every pointer valid for the sizes its arguments give.
        #[no_mangle]
        pub unsafe extern "C" fn $potrf_(
            uplo: *const c_char,
            n: *const c_int,
            A: *mut $T,
            lda: *const c_int,
            info: *mut c_int,
        ) {
            crate::$potrf(
                *uplo as u8,
                *n,
                view_mut(A, span(*n, *n, *lda)),
                *lda,
                &mut *info,
            )
        }

        /// LAPACK's Fortran symbol over the driver of the same name.
        ///
        /// # Safety
        /// The Fortran LAPACK contract: every pointer valid for the sizes its arguments give.
        #[no_mangle]
        pub unsafe extern "C" fn $potrs_(
            uplo: *const c_char,
            n: *const c_int,
            nrhs: *const c_int,
            A: *const $T,
            lda: *const c_int,
            B: *mut $T,
            ldb: *const c_int,
            info: *mut c_int,
        ) {
            let (n, nrhs) = (*n, *nrhs);
            crate::$potrs(
                *uplo as u8,
                n,
                nrhs,
                view(A, span(n, n, *lda)),
                *lda,
                view_mut(B, span(n, nrhs, *ldb)),
                *ldb,
                &mut *info,
            )
        }

        /// LAPACK's Fortran symbol over the driver of the same name.
        ///
        /// # Safety
        /// The Fortran LAPACK contract: every pointer valid for the sizes its arguments give.
        #[no_mangle]
        pub unsafe extern "C" fn $gesdd_(
            jobz: *const c_char,
            m: *const c_int,
            n: *const c_int,
            A: *mut $T,
            lda: *const c_int,
            S: *mut $T,
            U: *mut $T,
            ldu: *const c_int,
            VT: *mut $T,
            ldvt: *const c_int,
            work: *mut $T,
            lwork: *const c_int,
            iwork: *mut c_int,
            info: *mut c_int,
        ) {
            let (m, n) = (*m, *n);
            let k = m.min(n);
            // `A` (all columns of U, all rows of Vᵀ) is taken only for square matrices, where
            // it is `S`.
            crate::$gesdd(
                *jobz as u8,
                m,
                n,
                view_mut(A, span(m, n, *lda)),
                *lda,
                view_mut(S, k.max(0) as usize),
                view_mut(U, jobs(*jobz, m, k, *ldu)),
                *ldu,
                view_mut(VT, jobs(*jobz, k, n, *ldvt)),
                *ldvt,
                view_mut(work, workspace(*lwork)),
                *lwork,
                view_mut(iwork, 8 * k.max(0) as usize),
                &mut *info,
            )
        }

        /// LAPACK's Fortran symbol over the driver of the same name.
        ///
        /// # Safety
        /// The Fortran LAPACK contract: every pointer valid for the sizes its arguments give.
        #[no_mangle]
        pub unsafe extern "C" fn $gesvd_(
            jobu: *const c_char,
            jobvt: *const c_char,
            m: *const c_int,
            n: *const c_int,
            A: *mut $T,
            lda: *const c_int,
            S: *mut $T,
            U: *mut $T,
            ldu: *const c_int,
            VT: *mut $T,
            ldvt: *const c_int,
            work: *mut $T,
            lwork: *const c_int,
            info: *mut c_int,
        ) {
            let (m, n) = (*m, *n);
            let k = m.min(n);
            crate::$gesvd(
                *jobu as u8,
                *jobvt as u8,
                m,
                n,
                view_mut(A, span(m, n, *lda)),
                *lda,
                view_mut(S, k.max(0) as usize),
                view_mut(U, jobs(*jobu, m, k, *ldu)),
                *ldu,
                view_mut(VT, jobs(*jobvt, k, n, *ldvt)),
                *ldvt,
                view_mut(work, workspace(*lwork)),
                *lwork,
                &mut *info,
            )
        }

        /// LAPACK's Fortran symbol over the driver of the same name.
        ///
        /// # Safety
        /// The Fortran LAPACK contract: every pointer valid for the sizes its arguments give.
        #[no_mangle]
        pub unsafe extern "C" fn $gesv_(
            n: *const c_int,
            nrhs: *const c_int,
            A: *mut $T,
            lda: *const c_int,
            ipiv: *mut c_int,
            B: *mut $T,
            ldb: *const c_int,
            info: *mut c_int,
        ) {
            let (n, nrhs) = (*n, *nrhs);
            crate::$gesv(
                n,
                nrhs,
                view_mut(A, span(n, n, *lda)),
                *lda,
                view_mut(ipiv, n.max(0) as usize),
                view_mut(B, span(n, nrhs, *ldb)),
                *ldb,
                &mut *info,
            )
        }
    };
}

lapack_ffi!(f64, dsyevr => dsyevr_, dpotrf => dpotrf_, dpotrs => dpotrs_, dgesdd => dgesdd_,
    dgesvd => dgesvd_, dgesv => dgesv_);
lapack_ffi!(f32, ssyevr => ssyevr_, spotrf => spotrf_, spotrs => spotrs_, sgesdd => sgesdd_,
    sgesvd => sgesvd_, sgesv => sgesv_);
