//! Floating-point arithmetic with proven error bounds: what every "proven" number of nmci
//! stands on (the certified rule's repair, the rigorous ends of the bracket).
//!
//! ## The model
//! IEEE 754 binary64 with round to nearest, as Rust's `f64` does on every target nmci builds
//! for. For finite operands and a finite result, each `+ − × ÷ √` satisfies
//! `fl(a ∘ b) = (a ∘ b)(1 + δ) + η`, `|δ| ≤ u = 2⁻⁵³`, `|η| ≤ 2⁻¹⁰⁷⁵` (η only on underflow)
//! (Higham, *Accuracy and Stability of Numerical Algorithms*, 2nd ed. 2002, §2.2). We write
//! `γ_k = k u / (1 − k u)`. Nothing here assumes a particular summation order.
//!
//! ## Balls
//! A [`Ball`] `⟨m, r⟩` stands for an exact real number `x` with `|x − m| ≤ r`; `m`, `r` are
//! floats. A sum of `k` products of balls, `Σ a_i b_i`, computed by [`Dot`] as
//! `s = fl(Σ m(a_i) m(b_i))`, satisfies (Higham eq. (3.5) for the rounding, the triangle
//! inequality for the radii)
//!
//! `|Σ a_i b_i − s| ≤ γ_k Σ |m(a_i) m(b_i)| + Σ (|m(a_i)| r(b_i) + r(a_i)(|m(b_i)| + r(b_i)))`,
//!
//! a non-negative expression that is itself evaluated in floating point and then passed
//! through [`up`], which returns a float no smaller than the exact value of such an
//! expression of at most `k` rounded operations: `x̂ (1 + 2γ_{k+2}) + (k + 2)·2⁻¹⁰⁰⁰` (the
//! relative factor covers `x ≤ x̂ / (1 − γ_k)` and the rounding of the product itself; the
//! absolute term covers underflow). [`Dot`] charges `2k + 8` operations, more than it uses.
//!
//! ## Proving a matrix positive semidefinite
//! [`is_psd`] proves that **every** symmetric `X` with `|X − M| ≤ R` entrywise is positive
//! semidefinite (`M` symmetric floats, `R ≥ 0`): with `e ≥ ‖R‖_F ≥ ‖X − M‖₂`,
//! `t = Σ |M_ii|`, `d = max |M_ii|`, `a = γ_{N+1} / (1 − γ_{N+1})` and the shift
//! `s = 2 (e + a t + u d) + 64 (N + 2)(2N + d) 2⁻¹⁰²²`, it runs a floating-point Cholesky
//! factorization of `B = fl(M − s I)`. If it completes with positive pivots, then
//! `R̃ᵀR̃ = B + ΔB` with `|ΔB| ≤ γ_{N+1} |R̃ᵀ||R̃|` (Demmel 1989; Higham Thm. 10.3), so
//! `‖ΔB‖₂ ≤ γ_{N+1} ‖R̃‖_F² ≤ a · Σ|B_ii|` (take the trace of `R̃ᵀR̃ = B + ΔB`), and
//! `B ⪰ −a Σ|B_ii| I`. With `|B_ii − (M_ii − s)| ≤ u |B_ii|` and `Σ |B_ii| ≤ (t + N s)(1 + u)`:
//!
//! `X ⪰ M − e I = B + s I + (M − s I − B) − e I ⪰ (s − e − a (t + N s)(1 + u) − u (d + s)(1 + u)) I ⪰ 0`,
//!
//! because `a N ≤ 10⁻²` for every size used here, so the bracket is at least
//! `0.98 s − 1.01 (e + a t + u d) > 0`. The last term of `s` covers underflow, as in Rump,
//! "Verification of positive definiteness", BIT 46 (2006), whose criterion this is (with
//! the interval radius `R` added through Weyl's inequality). The test can fail on a matrix
//! that is positive semidefinite but too close to singular; callers then enlarge a margin
//! and try again. It never succeeds on one that is not.

use nalgebra::DMatrix;

/// Unit roundoff of `f64` (round to nearest).
pub(crate) const U: f64 = f64::EPSILON / 2.0;

/// `2⁻¹⁰⁰⁰`: the absolute slack per operation that covers underflow (any underflow error is
/// at most `2⁻¹⁰⁷⁵`).
const TINY: f64 = 9.332636185032189e-302;

/// `γ_k = k u / (1 − k u)`.
pub(crate) fn gamma(k: usize) -> f64 {
    let ku = k as f64 * U;
    ku / (1.0 - ku)
}

/// A float no smaller than the exact value `x ≥ 0` of an expression of at most `k` rounded
/// operations on non-negative numbers whose computed value is `x_hat` (module docs).
pub(crate) fn up(x_hat: f64, k: usize) -> f64 {
    x_hat.max(0.0) * (1.0 + 2.0 * gamma(k + 2)) + (k as f64 + 2.0) * TINY
}

/// A float no smaller than `√(Σ vᵢ²)` for the non-negative floats `values`, each computed by
/// at most a few rounded operations, `k` counting them all (as for [`up`]).
///
/// [`up`]'s absolute term covers underflow in a sum, but not through a square root: a sum of
/// squares that underflows to `s ≈ 0` has `√s` far below the true `√(Σ vᵢ²)`. So when the
/// largest value `m` is at least `2⁻⁴⁰⁰`, the sum of squares is at least `m² ≥ 2⁻⁸⁰⁰`, the
/// squares that underflow lose at most `k·2⁻¹⁰⁷⁵ ≤ k·2⁻²⁷⁵ · Σ vᵢ²` (a relative error far below
/// one `γ_k`, which `up`'s relative factor covers, the root halving it), and the rounded-up
/// root of the sum of squares is returned; below `2⁻⁴⁰⁰`, the rounded-up plain sum
/// `Σ vᵢ ≥ √(Σ vᵢ²)`, with no square to underflow. Overflow gives `+∞`, which bounds anything.
pub(crate) fn norm2_up(values: impl Iterator<Item = f64> + Clone, k: usize) -> f64 {
    let largest = values.clone().fold(0.0f64, |m, v| m.max(v.abs()));
    if largest >= 2f64.powi(-400) {
        up(values.map(|v| v * v).sum::<f64>().sqrt(), k)
    } else {
        up(values.map(f64::abs).sum::<f64>(), k)
    }
}

/// A float no larger than the exact value `x ≥ 0` of such an expression (never negative).
pub(crate) fn down(x_hat: f64, k: usize) -> f64 {
    (x_hat * (1.0 - 2.0 * gamma(k + 2)) - (k as f64 + 2.0) * TINY).max(0.0)
}

/// An exact real number `x` known only to lie in `[mid − rad, mid + rad]`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Ball {
    /// The float the number is computed as.
    pub mid: f64,
    /// A proven bound on the distance to the exact number.
    pub rad: f64,
}

impl Ball {
    /// A float, exactly.
    pub(crate) fn exact(x: f64) -> Self {
        Self { mid: x, rad: 0.0 }
    }

    /// A float no smaller than the number.
    pub(crate) fn upper(self) -> f64 {
        // mid + rad rounded to nearest can fall below by u|s|; 4u|s| more, rounded, cannot.
        let s = self.mid + self.rad;
        s + up(4.0 * U * s.abs(), 1)
    }

    /// A float no larger than the number.
    pub(crate) fn lower(self) -> f64 {
        let s = self.mid - self.rad;
        s - up(4.0 * U * s.abs(), 1)
    }

    /// `1 / x`, when the ball lies in `(0, ∞)`.
    pub(crate) fn recip(self) -> Option<Self> {
        let lo = self.lower();
        if lo.is_nan() || lo <= 0.0 || !self.mid.is_finite() {
            return None;
        }
        // |1/x − 1/m| = |m − x| / (x m) ≤ r / (lo m); fl(1/m) adds u/m.
        let mid = 1.0 / self.mid;
        let rad = up(self.rad / (lo * self.mid) + U * mid.abs(), 6);
        Some(Self { mid, rad })
    }
}

/// `Σ a_i b_i` over balls with a proven radius (module docs).
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct Dot {
    sum: f64,
    abs: f64,
    rad: f64,
    terms: usize,
}

impl Dot {
    pub(crate) fn new() -> Self {
        Self::default()
    }

    /// Adds `a·b`.
    pub(crate) fn add_prod(&mut self, a: Ball, b: Ball) {
        let p = a.mid * b.mid;
        self.sum += p;
        self.abs += p.abs();
        self.rad += a.mid.abs() * b.rad + a.rad * (b.mid.abs() + b.rad);
        self.terms += 1;
    }

    /// Adds `a·b` for two floats.
    pub(crate) fn add_exact_prod(&mut self, a: f64, b: f64) {
        let p = a * b;
        self.sum += p;
        self.abs += p.abs();
        self.terms += 1;
    }

    /// Adds `a`.
    pub(crate) fn add(&mut self, a: Ball) {
        self.sum += a.mid;
        self.abs += a.mid.abs();
        self.rad += a.rad;
        self.terms += 1;
    }

    /// The sum with its proven radius.
    pub(crate) fn ball(&self) -> Ball {
        let k = self.terms + 1;
        Ball {
            mid: self.sum,
            rad: up(gamma(k) * self.abs + self.rad, 2 * k + 8),
        }
    }
}

/// A matrix of balls: the exact matrix `X` satisfies `|X − mid| ≤ rad` entrywise.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct BallMatrix {
    pub mid: DMatrix<f64>,
    pub rad: DMatrix<f64>,
}

impl BallMatrix {
    /// A float matrix, exactly.
    pub(crate) fn exact(m: &DMatrix<f64>) -> Self {
        Self {
            mid: m.clone(),
            rad: DMatrix::zeros(m.nrows(), m.ncols()),
        }
    }

    /// Builds a matrix entry by entry.
    pub(crate) fn from_fn(
        rows: usize,
        cols: usize,
        mut f: impl FnMut(usize, usize) -> Ball,
    ) -> Self {
        let mut mid = DMatrix::zeros(rows, cols);
        let mut rad = DMatrix::zeros(rows, cols);
        for c in 0..cols {
            for r in 0..rows {
                let b = f(r, c);
                mid[(r, c)] = b.mid;
                rad[(r, c)] = b.rad;
            }
        }
        Self { mid, rad }
    }

    /// Entry `(r, c)`.
    pub(crate) fn at(&self, r: usize, c: usize) -> Ball {
        Ball {
            mid: self.mid[(r, c)],
            rad: self.rad[(r, c)],
        }
    }

    /// `I − M` for a float matrix `M` (the gain `K_b = I − K_a`, exactly as a ball).
    pub(crate) fn identity_minus(m: &DMatrix<f64>) -> Self {
        Self::from_fn(m.nrows(), m.ncols(), |r, c| {
            if r == c {
                let d = 1.0 - m[(r, c)];
                Ball {
                    mid: d,
                    rad: up(U * d.abs(), 1),
                }
            } else {
                Ball::exact(-m[(r, c)])
            }
        })
    }

    /// `A B`.
    pub(crate) fn mul(&self, other: &BallMatrix) -> Self {
        Self::from_fn(self.mid.nrows(), other.mid.ncols(), |r, c| {
            let mut d = Dot::new();
            for k in 0..self.mid.ncols() {
                d.add_prod(self.at(r, k), other.at(k, c));
            }
            d.ball()
        })
    }

    /// `Aᵀ`.
    pub(crate) fn transpose(&self) -> Self {
        Self {
            mid: self.mid.transpose(),
            rad: self.rad.transpose(),
        }
    }

    /// A symmetric float matrix `P` with `P ⪰ X` for every symmetric `X` of the ball: the
    /// symmetrized `mid` plus `ρ ≥ ‖rad‖_F` (and the rounding of the addition) on the
    /// diagonal, so `P − X ⪰ (ρ − ‖X − mid‖₂) I ⪰ 0`.
    pub(crate) fn dominating(&self) -> DMatrix<f64> {
        let s = self.symmetrized();
        let n = s.mid.nrows();
        let rho = norm2_up(s.rad.iter().copied(), n * n + 4);
        let mut p = s.mid.clone();
        for i in 0..n {
            let add = up(rho + 2.0 * U * (p[(i, i)].abs() + rho), 4);
            p[(i, i)] += add;
        }
        p
    }

    /// The same matrices with an exactly symmetric `mid`: `(M + Mᵀ)/2`, the difference and
    /// the rounding added to the radius (for a ball matrix that stands for a symmetric
    /// matrix but was computed entry by entry in different orders).
    pub(crate) fn symmetrized(&self) -> Self {
        let k = self.mid.nrows();
        Self::from_fn(k, k, |x, y| {
            let (a, c) = (self.mid[(x, y)], self.mid[(y, x)]);
            let mid = 0.5 * (a + c);
            Ball {
                mid,
                rad: up(
                    self.rad[(x, y)].max(self.rad[(y, x)]) + 0.5 * (a - c).abs() + U * mid.abs(),
                    4,
                ),
            }
        })
    }

    /// `tr A`.
    pub(crate) fn trace(&self) -> Ball {
        let mut d = Dot::new();
        for i in 0..self.mid.nrows().min(self.mid.ncols()) {
            d.add(self.at(i, i));
        }
        d.ball()
    }
}

/// Proves that every symmetric `X` with `|X − mid| ≤ rad` is positive semidefinite (module
/// docs); `false` means "not proven", not "indefinite". `mid` must be exactly symmetric.
pub(crate) fn is_psd(mid: &DMatrix<f64>, rad: &DMatrix<f64>) -> bool {
    let n = mid.nrows();
    if n == 0 {
        return true;
    }
    if rad.shape() != mid.shape() || rad.iter().any(|x| !x.is_finite()) {
        return false;
    }
    let e = norm2_up(rad.iter().copied(), n * n + 4);
    psd_within(mid, e)
}

/// [`is_psd`] for the matrices within spectral distance `e ≥ ‖X − mid‖₂` of `mid` (`e` a
/// float no smaller than the exact bound).
fn psd_within(mid: &DMatrix<f64>, e: f64) -> bool {
    let n = mid.nrows();
    if mid.ncols() != n
        || crate::linalg::first_non_finite(mid).is_some()
        || (0..n).any(|j| (j + 1..n).any(|i| mid[(i, j)] != mid[(j, i)]))
    {
        return false;
    }
    let t = up((0..n).map(|i| mid[(i, i)].abs()).sum::<f64>(), n + 2);
    let d = (0..n).map(|i| mid[(i, i)].abs()).fold(0.0, f64::max);
    let g = gamma(n + 1);
    let a = up(g / (1.0 - g), 4);
    if a * n as f64 > 1e-2 {
        return false;
    }
    let underflow = 64.0 * (n as f64 + 2.0) * (2.0 * n as f64 + d) * f64::MIN_POSITIVE;
    let s = up(2.0 * (e + a * t + U * d) + underflow, 8);
    let mut b = mid.clone();
    for i in 0..n {
        b[(i, i)] -= s;
    }
    cholesky_succeeds(&mut b)
}

/// Proves that the symmetric float matrix `m` is positive definite: [`is_psd`] with radius 0,
/// whose shift `s` is then positive (its underflow term alone is), so the proven bound
/// `m ⪰ (0.98 s − 1.01 (a t + u d)) I` of the module docs is strictly positive. `false` means
/// "not proven" (indefinite, or too close to singular for the proof).
pub(crate) fn is_positive_definite(m: &DMatrix<f64>) -> bool {
    m.nrows() == 0 || psd_within(m, 0.0)
}

/// Proves that the symmetric float matrix `m` is **not** positive definite: a vector `v ≠ 0`
/// (the computed eigenvector of its smallest eigenvalue) whose quadratic form `vᵀ m v`,
/// enclosed in a [`Ball`] by [`Dot`] (`w = m v` entry by entry as balls, then `Σ vᵢ wᵢ`), has
/// an upper end `≤ 0`, or that is exactly `0` (`m` zero on the support of `v`). `false` means
/// "not proven" (positive definite, or within rounding of singular); it never returns `true`
/// for a positive definite `m`.
pub(crate) fn is_not_positive_definite(m: &DMatrix<f64>) -> bool {
    let n = m.nrows();
    if n == 0 {
        return false;
    }
    let Some((values, vectors)) = crate::linalg::symmetric_eigen(m.clone(), f64::EPSILON) else {
        return false;
    };
    let k = values.imin();
    let v = vectors.column(k);
    if v.iter().all(|&x| x == 0.0) || !v.iter().all(|x| x.is_finite()) {
        return false;
    }
    // vᵀ m v = 0 exactly when m vanishes wherever both factors are non-zero (the enclosure
    // below keeps an underflow slack and cannot show that).
    let support: Vec<usize> = (0..n).filter(|&i| v[i] != 0.0).collect();
    if support
        .iter()
        .all(|&i| support.iter().all(|&j| m[(i, j)] == 0.0))
    {
        return true;
    }
    let mut form = Dot::new();
    for i in 0..n {
        let mut w = Dot::new();
        for j in 0..n {
            w.add_exact_prod(m[(i, j)], v[j]);
        }
        form.add_prod(Ball::exact(v[i]), w.ball());
    }
    let ball = form.ball();
    ball.mid.is_finite() && ball.rad.is_finite() && ball.upper() <= 0.0
}

wide! {
/// Plain floating-point Cholesky `B = R̃ᵀR̃`, in `b`'s storage (which it leaves undefined);
/// whether every pivot is positive (and finite). Left-looking on the columns of the lower
/// factor `R̃ᵀ`: each entry is `b` minus its products summed in the order `k = 0, 1, …`,
/// then divided by (or, on the diagonal, the square root of) the pivot — the factorization
/// the error bound of the module docs is for (it holds for any summation order); the updates
/// run along contiguous columns, so they vectorize — with AVX2 where the CPU has it
/// ([`wide!`](crate::linalg), the same operations in the same order, so the same bits).
fn cholesky_succeeds(b: &mut DMatrix<f64>) -> bool = cholesky_succeeds_kernel;
}

/// The body of [`cholesky_succeeds`], compiled into each of its copies.
#[inline(always)]
#[allow(non_snake_case)]
fn cholesky_succeeds_kernel(b: &mut DMatrix<f64>) -> bool {
    let n = b.nrows();
    let data = b.as_mut_slice();
    for j in 0..n {
        let (done, rest) = data.split_at_mut(j * n);
        let col = &mut rest[j..n];
        for k in 0..j {
            let column_k = &done[k * n..(k + 1) * n];
            let l_jk = column_k[j];
            for (c, &l_ik) in col.iter_mut().zip(&column_k[j..]) {
                *c -= l_ik * l_jk;
            }
        }
        let pivot = col[0];
        if pivot.is_nan() || pivot <= 0.0 || !pivot.is_finite() {
            return false;
        }
        let r = pivot.sqrt();
        col[0] = r;
        for c in col[1..].iter_mut() {
            *c /= r;
        }
    }
    true
}

/// A float `s ≥ 0` with `λ_min(X) ≥ −s` proven for every `X` of the ball matrix (symmetric
/// `mid`): the smallest of `0, s₀, 2s₀, 4s₀, …` (from an eigenvalue estimate) for which
/// [`is_psd`] proves `X + s I ⪰ 0`, with `mid + s I` formed in floating point and its
/// rounding added to the radius. `None` if no shift up to `2⁴⁰` times the estimate works.
pub(crate) fn psd_shift(m: &BallMatrix) -> Option<f64> {
    let n = m.mid.nrows();
    if is_psd(&m.mid, &m.rad) {
        return Some(0.0);
    }
    let estimate = -nalgebra::SymmetricEigen::new(m.mid.clone())
        .eigenvalues
        .min();
    let scale = m.mid.amax().max(m.rad.amax()).max(f64::MIN_POSITIVE);
    let mut shift = up(estimate.max(0.0) + 1e-15 * scale, 2);
    for _ in 0..40 {
        let mut mid = m.mid.clone();
        let mut rad = m.rad.clone();
        for i in 0..n {
            mid[(i, i)] += shift;
            rad[(i, i)] = up(rad[(i, i)] + U * mid[(i, i)].abs(), 3);
        }
        if is_psd(&mid, &rad) {
            return Some(shift);
        }
        shift *= 2.0;
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The bound on a 2-norm holds where the squares underflow (radii of `10⁻²⁰⁰`, whose
    /// squares are 0 in floating point: `up(√0)` gave about `10⁻²⁹⁹`), and stays the rounded-up
    /// root of the sum of squares at ordinary sizes.
    #[test]
    fn the_norm_bound_survives_underflowing_squares() {
        for v in [1e-200, 1e-170, 1e-121, 3e-308] {
            let values = [v; 4];
            let bound = norm2_up(values.iter().copied(), 8);
            assert!(bound >= 2.0 * v, "{v:e}: {bound:e}");
            assert!(
                bound <= 4.0 * v * (1.0 + 1e-12) + 1e-298,
                "{v:e}: {bound:e}"
            );
        }
        let bound = norm2_up([3.0, 4.0].into_iter(), 4);
        assert!((5.0..=5.0 * (1.0 + 1e-14)).contains(&bound), "{bound}");
        assert_eq!(norm2_up([f64::MAX, f64::MAX].into_iter(), 4), f64::INFINITY);
        // `dominating` of the zero matrix with radii of 1e-200 must dominate every matrix of
        // the ball, e.g. the one of all 1e-200, whose largest eigenvalue is 2e-200.
        let ball = BallMatrix {
            mid: DMatrix::zeros(2, 2),
            rad: DMatrix::from_element(2, 2, 1e-200),
        };
        let p = ball.dominating();
        assert!(p[(0, 0)] >= 2e-200 && p[(1, 1)] >= 2e-200, "{p}");
    }

    /// The witness of indefiniteness never fires on a matrix proven positive definite (random
    /// ones, and ones shifted to a smallest eigenvalue of 1e-12 relative), and fires on clearly
    /// indefinite ones and on exactly singular ones.
    #[test]
    fn the_witness_of_indefiniteness_is_never_found_for_a_positive_definite_matrix() {
        let mut seed = 41;
        let (mut proven_pd, mut indefinite) = (0, 0);
        for n in [1, 2, 3, 6, 14] {
            for shift in [1e-12, 1e-6, -1e-9, -1e-3] {
                let a = crate::linalg::test_spd(n, &mut seed, 0.0);
                let eig = nalgebra::SymmetricEigen::new(a.clone()).eigenvalues;
                let (lmin, lmax) = (eig.min(), eig.max());
                let mut b = a.clone();
                for i in 0..n {
                    b[(i, i)] += shift * lmax - lmin;
                }
                if is_positive_definite(&b) {
                    proven_pd += 1;
                    assert!(!is_not_positive_definite(&b), "n {n} shift {shift}");
                }
                if shift < 0.0 {
                    indefinite += 1;
                    assert!(is_not_positive_definite(&b), "n {n} shift {shift}");
                }
            }
        }
        assert!(
            proven_pd >= 8 && indefinite == 10,
            "{proven_pd} {indefinite}"
        );
        assert!(is_not_positive_definite(&DMatrix::from_row_slice(
            2,
            2,
            &[1.0, 0.0, 0.0, 0.0]
        )));
        assert!(is_not_positive_definite(&DMatrix::zeros(3, 3)));
        assert!(!is_not_positive_definite(&DMatrix::identity(3, 3)));
    }

    /// The verified test decides the same on both copies of `cholesky_succeeds` ([`wide!`]):
    /// matrices shifted across their smallest eigenvalue in steps of 1e−14 relative, where
    /// the last pivot decides.
    #[test]
    fn both_copies_decide_alike_at_the_boundary() {
        let mut seed = 23;
        let mut decided = [0, 0];
        for n in [2, 5, 14, 33] {
            let a = crate::linalg::test_spd(n, &mut seed, 0.0);
            let lmin = nalgebra::SymmetricEigen::new(a.clone()).eigenvalues.min();
            for k in -20..=20 {
                let mut b = a.clone();
                for i in 0..n {
                    b[(i, i)] += -lmin + k as f64 * 1e-14 * a.amax();
                }
                let wide = cholesky_succeeds(&mut b.clone());
                let base = crate::linalg::on_baseline(|| cholesky_succeeds(&mut b.clone()));
                assert_eq!(wide, base, "n {n} k {k}");
                decided[usize::from(wide)] += 1;
            }
        }
        assert!(
            decided[0] > 0 && decided[1] > 0,
            "{decided:?}: both answers occur"
        );
    }

    #[test]
    fn positive_definite_is_proven_with_a_margin_and_never_without() {
        let d = |v: &[f64]| DMatrix::from_diagonal(&nalgebra::DVector::from_row_slice(v));
        assert!(is_positive_definite(&d(&[1.0, 1e-6])));
        assert!(is_positive_definite(&DMatrix::identity(40, 40)));
        // Singular, indefinite, or positive definite below the proof's margin (~1e-15):
        // never proven.
        for m in [d(&[1.0, 0.0]), d(&[1.0, -1e-300]), d(&[1.0, 1e-17])] {
            assert!(!is_positive_definite(&m), "{m}");
        }
        let s = DMatrix::from_row_slice(2, 2, &[1.0, 1.0, 1.0, 1.0]);
        assert!(!is_positive_definite(&s));
        let s = DMatrix::from_row_slice(2, 2, &[1.0, 1.0, 1.0, 1.0 - 1e-12]);
        assert!(!is_positive_definite(&s));
        // Dense (every factor entry updated): Q diag(λ) Qᵀ with λ_min = ±1e-3, the rest 1–4.
        let q = nalgebra::linalg::QR::new(DMatrix::from_fn(5, 5, |i, j| {
            ((3 * i + 5 * j) % 7) as f64 - 3.0 + if i == j { 6.0 } else { 0.0 }
        }))
        .q();
        let with_smallest = |l: f64| {
            let m = &q * d(&[1.0, l, 2.0, 3.0, 4.0]) * q.transpose();
            (&m + m.transpose()) * 0.5
        };
        assert!(is_positive_definite(&with_smallest(1e-3)));
        assert!(!is_positive_definite(&with_smallest(-1e-3)));
    }

    #[test]
    fn identity_is_proven_and_a_negative_eigenvalue_never_is() {
        assert!(is_psd(&DMatrix::identity(5, 5), &DMatrix::zeros(5, 5)));
        // [[1, 1], [1, 1 − 1e-12]] has λ_min ≈ −5e-13: not PSD, must not be proven.
        let m = DMatrix::from_row_slice(2, 2, &[1.0, 1.0, 1.0, 1.0 - 1e-12]);
        assert!(!is_psd(&m, &DMatrix::zeros(2, 2)));
        // Singular PSD [[1, 1], [1, 1]]: not provable (a margin is needed), never claimed.
        let s = DMatrix::from_row_slice(2, 2, &[1.0, 1.0, 1.0, 1.0]);
        assert!(!is_psd(&s, &DMatrix::zeros(2, 2)));
        // A radius larger than the smallest eigenvalue: not proven.
        let d = DMatrix::from_diagonal(&nalgebra::DVector::from_vec(vec![1.0, 1e-3]));
        assert!(is_psd(&d, &DMatrix::from_element(2, 2, 1e-5)));
        assert!(!is_psd(&d, &DMatrix::from_element(2, 2, 2e-3)));
    }

    #[test]
    fn shift_brackets_the_smallest_eigenvalue() {
        let m = DMatrix::from_row_slice(2, 2, &[2.0, 1.0, 1.0, -1.0]);
        let lmin = nalgebra::SymmetricEigen::new(m.clone()).eigenvalues.min();
        let s = psd_shift(&BallMatrix::exact(&m)).unwrap();
        assert!(s >= -lmin && s <= -2.0 * lmin + 1e-12, "{s} vs {lmin}");
    }

    #[test]
    fn dot_radius_covers_cancellation() {
        // 1e16 + 1 − 1e16 computed in floats is 0 or 2; the exact value is 1.
        let mut d = Dot::new();
        d.add(Ball::exact(1e16));
        d.add(Ball::exact(1.0));
        d.add(Ball::exact(-1e16));
        let b = d.ball();
        assert!((b.mid - 1.0).abs() <= b.rad, "{b:?}");
        assert!(b.lower() <= 1.0 && b.upper() >= 1.0);
        let inv = Ball::exact(3.0).recip().unwrap();
        assert!(inv.lower() <= 1.0 / 3.0 && inv.upper() >= 1.0 / 3.0);
    }
}
