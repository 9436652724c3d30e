//! Pure-Rust stand-in for the [`lapack`](https://crates.io/crates/lapack) 0.19 wrapper crate.
//!
//! Clarabel's SDP cones call a few LAPACK drivers through the `lapack` crate, whose FFI
//! declarations need a system LAPACK and `libc` types that do not exist on
//! `wasm32-unknown-unknown`. This crate is patched in for `lapack` and provides the same
//! signatures, implemented with [`nalgebra`] and plain loops, for `f32` and `f64`:
//!
//! | driver | supported arguments |
//! |---|---|
//! | `?syevr` | `jobz` `N` (the eigenvalues alone: the same bits as with `V`) / `V`, `range` `A` (others: `info = -2`), `uplo` `U`/`L`, workspace queries (`lwork = -1` or `liwork = -1`) |
//! | `?potrf` | `uplo` `U`/`L`; `info = k > 0` when the leading minor of order `k` is not positive definite |
//! | `?potrs` | `uplo` `U`/`L`, any `nrhs` |
//! | `?gesdd` | `jobz` `N`/`S`, and `A` when `m = n` (then the same as `S`); workspace query |
//! | `?gesvd` | `jobu`, `jobvt` each `N`/`S` (and `A` when it equals `S`, i.e. square); workspace query |
//! | `?gesv` | LU with partial pivoting, 1-based `ipiv`, `info = k > 0` on an exactly zero pivot |
//!
//! Eigenvalues come out ascending and singular values descending, as LAPACK returns them.
//! Unsupported arguments set `info` to minus the argument's position, as LAPACK does; they
//! never panic.
#![deny(missing_docs)]
#![allow(
    clippy::too_many_arguments,
    clippy::missing_safety_doc,
    clippy::needless_range_loop
)]

use nalgebra::{DMatrix, RealField, SymmetricEigen, SVD};

#[cfg(not(target_arch = "wasm32"))]
pub mod ffi;

fn is_upper(uplo: u8) -> bool {
    matches!(uplo, b'U' | b'u')
}

fn is_char(c: u8, want: u8) -> bool {
    c.eq_ignore_ascii_case(&want)
}

fn cast<T: RealField + Copy>(v: f64) -> T {
    nalgebra::convert::<f64, T>(v)
}

fn syevr<T: RealField + Copy>(
    jobz: u8,
    range: u8,
    uplo: u8,
    n: i32,
    a: &mut [T],
    lda: i32,
    m: &mut i32,
    w: &mut [T],
    z: &mut [T],
    ldz: i32,
    isuppz: &mut [i32],
    work: &mut [T],
    lwork: i32,
    iwork: &mut [i32],
    liwork: i32,
    info: &mut i32,
) {
    *info = 0;
    let vectors = if is_char(jobz, b'V') {
        true
    } else if is_char(jobz, b'N') {
        false
    } else {
        *info = -1;
        return;
    };
    if !is_char(range, b'A') {
        *info = -2;
        return;
    }
    if n < 0 {
        *info = -4;
        return;
    }
    let nu = n as usize;
    if lwork == -1 || liwork == -1 {
        if let Some(w0) = work.first_mut() {
            *w0 = cast((26 * nu).max(1) as f64);
        }
        if let Some(i0) = iwork.first_mut() {
            *i0 = (10 * n).max(1);
        }
        return;
    }
    let lda = lda as usize;
    let up = is_upper(uplo);
    let full = DMatrix::<T>::from_fn(nu, nu, |i, j| {
        let (r, c) = if (i <= j) == up { (i, j) } else { (j, i) };
        a[r + c * lda]
    });
    if full.iter().any(|x| !x.is_finite()) {
        // What LAPACK gives for an invalid input: NaN (no error code), without iterating.
        *m = n;
        let nan = T::zero() / T::zero();
        w.iter_mut().take(nu).for_each(|x| *x = nan);
        if vectors {
            z.iter_mut().for_each(|x| *x = nan);
        }
        return;
    }
    // Without vectors, nalgebra's eigenvalues alone: the same reduction and QR iteration on
    // the same numbers (the rotations are only not applied to `Q`), so the same bits as the
    // values of the full decomposition (tested), at a fraction of the cost.
    let (values, vecs) = if vectors {
        let Some(eig) = SymmetricEigen::try_new(full, T::default_epsilon(), 0) else {
            *info = 1;
            return;
        };
        (eig.eigenvalues, Some(eig.eigenvectors))
    } else {
        (full.symmetric_eigenvalues(), None)
    };
    let mut order: Vec<usize> = (0..nu).collect();
    // A total order even with NaN (sorted last, as an invalid input gives; LAPACK returns
    // NaN too): `partial_cmp(..).unwrap_or(Equal)` is not one, and the standard sort panics
    // on such comparators — a panic inside the solver would kill a wasm module.
    order.sort_by(|&p, &q| {
        let (a, b) = (values[p], values[q]);
        let nan = |x: T| x.partial_cmp(&x).is_none();
        match (nan(a), nan(b)) {
            (true, true) => core::cmp::Ordering::Equal,
            (true, false) => core::cmp::Ordering::Greater,
            (false, true) => core::cmp::Ordering::Less,
            (false, false) => a.partial_cmp(&b).unwrap_or(core::cmp::Ordering::Equal),
        }
    });
    *m = n;
    for (k, &p) in order.iter().enumerate() {
        w[k] = values[p];
        if let Some(v) = &vecs {
            for i in 0..nu {
                z[i + k * ldz as usize] = v[(i, p)];
            }
        }
    }
    for (k, s) in isuppz.iter_mut().take(2 * nu).enumerate() {
        *s = if k % 2 == 0 { 1 } else { n };
    }
}

fn potrf<T: RealField + Copy>(uplo: u8, n: i32, a: &mut [T], lda: i32, info: &mut i32) {
    *info = 0;
    if n < 0 {
        *info = -2;
        return;
    }
    let (n, lda) = (n as usize, lda as usize);
    let up = is_upper(uplo);
    // Work on the lower factor L (A = L Lᵀ); for 'U' the transposed index gives U = Lᵀ.
    let idx = |i: usize, j: usize| if up { j + i * lda } else { i + j * lda };
    let zero = nalgebra::zero::<T>();
    for j in 0..n {
        let mut d = a[idx(j, j)];
        for k in 0..j {
            d -= a[idx(j, k)] * a[idx(j, k)];
        }
        if d <= zero || !d.is_finite() {
            a[idx(j, j)] = d;
            *info = j as i32 + 1;
            return;
        }
        let d = d.sqrt();
        a[idx(j, j)] = d;
        for i in j + 1..n {
            let mut s = a[idx(i, j)];
            for k in 0..j {
                s -= a[idx(i, k)] * a[idx(j, k)];
            }
            a[idx(i, j)] = s / d;
        }
    }
}

fn potrs<T: RealField + Copy>(
    uplo: u8,
    n: i32,
    nrhs: i32,
    a: &[T],
    lda: i32,
    b: &mut [T],
    ldb: i32,
    info: &mut i32,
) {
    *info = 0;
    if n < 0 {
        *info = -2;
        return;
    }
    if nrhs < 0 {
        *info = -3;
        return;
    }
    let (n, lda, ldb) = (n as usize, lda as usize, ldb as usize);
    let up = is_upper(uplo);
    let l = |i: usize, j: usize| if up { a[j + i * lda] } else { a[i + j * lda] };
    for c in 0..nrhs as usize {
        let col = &mut b[c * ldb..c * ldb + n];
        // L y = b
        for i in 0..n {
            let mut s = col[i];
            for k in 0..i {
                s -= l(i, k) * col[k];
            }
            col[i] = s / l(i, i);
        }
        // Lᵀ x = y
        for i in (0..n).rev() {
            let mut s = col[i];
            for k in i + 1..n {
                s -= l(k, i) * col[k];
            }
            col[i] = s / l(i, i);
        }
    }
}

/// Thin SVD `A = U diag(s) Vᵀ` with singular values sorted descending; writes the requested
/// factors. Returns `info`.
fn svd_into<T: RealField + Copy>(
    want_u: bool,
    want_vt: bool,
    m: usize,
    n: usize,
    a: &[T],
    lda: usize,
    s: &mut [T],
    u: &mut [T],
    ldu: usize,
    vt: &mut [T],
    ldvt: usize,
) -> i32 {
    let k = m.min(n);
    if k == 0 {
        return 0;
    }
    let full = DMatrix::<T>::from_fn(m, n, |i, j| a[i + j * lda]);
    let Some(svd) = SVD::try_new(full, true, true, T::default_epsilon(), 0) else {
        return 1;
    };
    let (Some(uu), Some(vv)) = (svd.u.as_ref(), svd.v_t.as_ref()) else {
        return 1;
    };
    let mut order: Vec<usize> = (0..k).collect();
    order.sort_by(|&p, &q| {
        svd.singular_values[q]
            .partial_cmp(&svd.singular_values[p])
            .unwrap_or(core::cmp::Ordering::Equal)
    });
    for (c, &p) in order.iter().enumerate() {
        s[c] = svd.singular_values[p];
        if want_u {
            for i in 0..m {
                u[i + c * ldu] = uu[(i, p)];
            }
        }
        if want_vt {
            for j in 0..n {
                vt[c + j * ldvt] = vv[(p, j)];
            }
        }
    }
    0
}

fn gesdd<T: RealField + Copy>(
    jobz: u8,
    m: i32,
    n: i32,
    a: &mut [T],
    lda: i32,
    s: &mut [T],
    u: &mut [T],
    ldu: i32,
    vt: &mut [T],
    ldvt: i32,
    work: &mut [T],
    lwork: i32,
    info: &mut i32,
) {
    *info = 0;
    let want = if is_char(jobz, b'S') || (is_char(jobz, b'A') && m == n) {
        true
    } else if is_char(jobz, b'N') {
        false
    } else {
        *info = -1;
        return;
    };
    if m < 0 || n < 0 {
        *info = if m < 0 { -2 } else { -3 };
        return;
    }
    if lwork == -1 {
        if let Some(w0) = work.first_mut() {
            let k = m.min(n).max(1) as f64;
            *w0 = cast((3.0 * k * k + 4.0 * k + f64::from(m.max(n))).max(1.0));
        }
        return;
    }
    *info = svd_into(
        want,
        want,
        m as usize,
        n as usize,
        a,
        lda as usize,
        s,
        u,
        ldu as usize,
        vt,
        ldvt as usize,
    );
}

fn gesvd<T: RealField + Copy>(
    jobu: u8,
    jobvt: u8,
    m: i32,
    n: i32,
    a: &mut [T],
    lda: i32,
    s: &mut [T],
    u: &mut [T],
    ldu: i32,
    vt: &mut [T],
    ldvt: i32,
    work: &mut [T],
    lwork: i32,
    info: &mut i32,
) {
    *info = 0;
    let parse = |c: u8| -> Option<bool> {
        if is_char(c, b'S') || (is_char(c, b'A') && m == n) {
            Some(true)
        } else if is_char(c, b'N') {
            Some(false)
        } else {
            None
        }
    };
    let Some(want_u) = parse(jobu) else {
        *info = -1;
        return;
    };
    let Some(want_vt) = parse(jobvt) else {
        *info = -2;
        return;
    };
    if m < 0 || n < 0 {
        *info = if m < 0 { -3 } else { -4 };
        return;
    }
    if lwork == -1 {
        if let Some(w0) = work.first_mut() {
            *w0 = cast((5 * m.min(n) + m.max(n)).max(1) as f64);
        }
        return;
    }
    *info = svd_into(
        want_u,
        want_vt,
        m as usize,
        n as usize,
        a,
        lda as usize,
        s,
        u,
        ldu as usize,
        vt,
        ldvt as usize,
    );
}

fn gesv<T: RealField + Copy>(
    n: i32,
    nrhs: i32,
    a: &mut [T],
    lda: i32,
    ipiv: &mut [i32],
    b: &mut [T],
    ldb: i32,
    info: &mut i32,
) {
    *info = 0;
    if n < 0 {
        *info = -1;
        return;
    }
    if nrhs < 0 {
        *info = -2;
        return;
    }
    let (n, lda, ldb, nrhs) = (n as usize, lda as usize, ldb as usize, nrhs as usize);
    let zero = nalgebra::zero::<T>();
    for k in 0..n {
        let mut p = k;
        for i in k + 1..n {
            if a[i + k * lda].abs() > a[p + k * lda].abs() {
                p = i;
            }
        }
        ipiv[k] = p as i32 + 1;
        if p != k {
            for j in 0..n {
                a.swap(k + j * lda, p + j * lda);
            }
            for j in 0..nrhs {
                b.swap(k + j * ldb, p + j * ldb);
            }
        }
        let piv = a[k + k * lda];
        if piv == zero {
            if *info == 0 {
                *info = k as i32 + 1;
            }
            continue;
        }
        for i in k + 1..n {
            let f = a[i + k * lda] / piv;
            a[i + k * lda] = f;
            for j in k + 1..n {
                let akj = a[k + j * lda];
                a[i + j * lda] -= f * akj;
            }
        }
    }
    if *info != 0 {
        return;
    }
    for c in 0..nrhs {
        let col = &mut b[c * ldb..c * ldb + n];
        for i in 0..n {
            for k in 0..i {
                let v = a[i + k * lda] * col[k];
                col[i] -= v;
            }
        }
        for i in (0..n).rev() {
            for k in i + 1..n {
                let v = a[i + k * lda] * col[k];
                col[i] -= v;
            }
            col[i] /= a[i + i * lda];
        }
    }
}

macro_rules! lapack_fns {
    ($T:ty, $syevr:ident, $potrf:ident, $potrs:ident, $gesdd:ident, $gesvd:ident, $gesv:ident) => {
        /// Symmetric eigendecomposition (all eigenvalues ascending, optionally eigenvectors).
        /// `vl`, `vu`, `il`, `iu` and `abstol` are accepted for signature compatibility and
        /// unused (only `range = 'A'` is supported).
        pub unsafe fn $syevr(
            jobz: u8,
            range: u8,
            uplo: u8,
            n: i32,
            a: &mut [$T],
            lda: i32,
            _vl: $T,
            _vu: $T,
            _il: i32,
            _iu: i32,
            _abstol: $T,
            m: &mut i32,
            w: &mut [$T],
            z: &mut [$T],
            ldz: i32,
            isuppz: &mut [i32],
            work: &mut [$T],
            lwork: i32,
            iwork: &mut [i32],
            liwork: i32,
            info: &mut i32,
        ) {
            syevr(
                jobz, range, uplo, n, a, lda, m, w, z, ldz, isuppz, work, lwork, iwork, liwork,
                info,
            )
        }

        /// Cholesky factorization of a symmetric positive definite matrix, in place.
        pub unsafe fn $potrf(uplo: u8, n: i32, a: &mut [$T], lda: i32, info: &mut i32) {
            potrf(uplo, n, a, lda, info)
        }

        /// Solves `A X = B` with the Cholesky factor computed by `?potrf`.
        pub unsafe fn $potrs(
            uplo: u8,
            n: i32,
            nrhs: i32,
            a: &[$T],
            lda: i32,
            b: &mut [$T],
            ldb: i32,
            info: &mut i32,
        ) {
            potrs(uplo, n, nrhs, a, lda, b, ldb, info)
        }

        /// Singular value decomposition (the "divide and conquer" driver's interface).
        pub unsafe fn $gesdd(
            jobz: u8,
            m: i32,
            n: i32,
            a: &mut [$T],
            lda: i32,
            s: &mut [$T],
            u: &mut [$T],
            ldu: i32,
            vt: &mut [$T],
            ldvt: i32,
            work: &mut [$T],
            lwork: i32,
            _iwork: &mut [i32],
            info: &mut i32,
        ) {
            gesdd(jobz, m, n, a, lda, s, u, ldu, vt, ldvt, work, lwork, info)
        }

        /// Singular value decomposition (the QR driver's interface).
        pub unsafe fn $gesvd(
            jobu: u8,
            jobvt: u8,
            m: i32,
            n: i32,
            a: &mut [$T],
            lda: i32,
            s: &mut [$T],
            u: &mut [$T],
            ldu: i32,
            vt: &mut [$T],
            ldvt: i32,
            work: &mut [$T],
            lwork: i32,
            info: &mut i32,
        ) {
            gesvd(
                jobu, jobvt, m, n, a, lda, s, u, ldu, vt, ldvt, work, lwork, info,
            )
        }

        /// Solves `A X = B` by LU factorization with partial pivoting.
        pub unsafe fn $gesv(
            n: i32,
            nrhs: i32,
            a: &mut [$T],
            lda: i32,
            ipiv: &mut [i32],
            b: &mut [$T],
            ldb: i32,
            info: &mut i32,
        ) {
            gesv(n, nrhs, a, lda, ipiv, b, ldb, info)
        }
    };
}

lapack_fns!(f64, dsyevr, dpotrf, dpotrs, dgesdd, dgesvd, dgesv);
lapack_fns!(f32, ssyevr, spotrf, spotrs, sgesdd, sgesvd, sgesv);
