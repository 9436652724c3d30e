//! The optimal `ω`: the criterion's derivatives summed over pencils, and a safeguarded Newton
//! search on the convex criterion (shared with ICI).

use crate::fusion::Criterion;

use super::pencil::Pencil;

/// Relative size below which a derivative at an endpoint counts as zero (a tie): then the
/// endpoint is optimal to within rounding, and taking it exactly keeps `ω` reproducible
/// between mathematically equal computations (identical estimates give `g ≡ 0`, whose sign is
/// rounding noise). CI's and ICI's (shared through [`minimise_convex`]).
pub(in crate::fusion) const ENDPOINT_TIE: f64 = 1e-9;

/// `ω` where the criterion is flat on all of `[0, 1]` (both endpoints optimal within
/// [`ENDPOINT_TIE`]: equal covariances): the midpoint of the optimal set, which gives the
/// average of the two means (a tie taken at an endpoint would drop one of them).
pub(in crate::fusion) const FLAT_OMEGA: f64 = 0.5;

/// The pencils of the blocks that share one `ω`, each with its multiplicity: the blocks of a
/// block-diagonal problem each count in the criterion, and blocks with equal covariances in
/// both estimates ([`covariance_twins`]) share one pencil counted as often as they occur. CI
/// and ICI take their blocks in this one form.
pub(in crate::fusion) type Weighted<'a> = [(&'a Pencil, f64)];

/// First and second derivative at `ω` of the criterion summed over `pencils` (with their
/// multiplicities), and the size of the terms the first derivative sums (its rounding scale).
pub(super) fn derivatives(pencils: &Weighted, criterion: Criterion, omega: f64) -> (f64, f64, f64) {
    let (mut d1, mut d2, mut size) = (0.0, 0.0, 0.0);
    for &(pencil, count) in pencils {
        let (mut p1, mut p2, mut psize) = (0.0, 0.0, 0.0);
        for (i, (c, s)) in pencil.weights.iter().zip(&pencil.slopes).enumerate() {
            let d = pencil.d(i, omega);
            match criterion {
                Criterion::Trace => {
                    p1 -= c * s / (d * d);
                    p2 += 2.0 * c * s * s / (d * d * d);
                    psize += c * (1.0 + s.abs()) / (d * d);
                }
                Criterion::Logdet => {
                    p1 -= s / d;
                    p2 += s * s / (d * d);
                    psize += (1.0 + s.abs()) / d;
                }
            }
        }
        d1 += count * p1;
        d2 += count * p2;
        size += count * psize;
    }
    (d1, d2, size)
}

/// The minimiser over `[0, 1]` of CI's (convex) criterion summed over `pencils`. An endpoint
/// is returned exactly when the derivative there does not point inwards (within
/// [`ENDPOINT_TIE`]); where both do, [`FLAT_OMEGA`].
pub(super) fn optimal_omega(pencils: &Weighted, criterion: Criterion) -> f64 {
    solve_omega(pencils, criterion).0
}

/// [`optimal_omega`] and the number of derivative evaluations inside `(0, 1)` it took.
pub(super) fn solve_omega(pencils: &Weighted, criterion: Criterion) -> (f64, usize) {
    minimise_convex(|omega| derivatives(pencils, criterion, omega))
}

/// The one minimiser of a convex criterion of `ω` over `[0, 1]` (CI's and ICI's), given its
/// derivative, second derivative and the size of the terms the derivative sums at `ω`:
/// [`FLAT_OMEGA`] when the derivative points inwards at neither end (within [`ENDPOINT_TIE`]
/// of its size: the criterion is flat); an endpoint, exactly, when it does not at that end;
/// otherwise safeguarded Newton from `½` —
/// bisection when a step leaves the bracket — until the derivative is zero to within `4ε` of
/// its size (its sign then no longer says where the root is) or a step moves `ω` by less than
/// `4ε` relative. Returns `ω` and the number of interior evaluations.
pub(in crate::fusion) fn minimise_convex(
    derivatives: impl Fn(f64) -> (f64, f64, f64),
) -> (f64, usize) {
    let (g0, _, size0) = derivatives(0.0);
    let (g1, _, size1) = derivatives(1.0);
    let (zero_optimal, one_optimal) = (g0 >= -ENDPOINT_TIE * size0, g1 <= ENDPOINT_TIE * size1);
    if zero_optimal && one_optimal {
        // Both ends optimal: a convex criterion with zero slope at both ends is flat on
        // [0, 1] (equal covariances), so every ω is optimal; the midpoint averages the means.
        return (FLAT_OMEGA, 0);
    }
    if zero_optimal {
        return (0.0, 0);
    }
    if one_optimal {
        return (1.0, 0);
    }
    // g is increasing (convex criterion), g(lo) < 0 < g(hi).
    let (mut lo, mut hi) = (0.0_f64, 1.0_f64);
    let mut omega = 0.5;
    for step in 1..=200 {
        let (g, h, size) = derivatives(omega);
        // Zero to within the rounding of its terms: the sign of g no longer tells which side
        // the root is on (bisecting further on noise took up to 50 steps).
        if g.abs() <= 4.0 * f64::EPSILON * size {
            return (omega, step);
        }
        if g < 0.0 {
            lo = omega;
        } else {
            hi = omega;
        }
        let newton = omega - g / h;
        let next = if h > 0.0 && newton > lo && newton < hi {
            newton
        } else {
            0.5 * (lo + hi)
        };
        if (next - omega).abs() <= 4.0 * f64::EPSILON * omega.max(1e-300) || hi - lo <= 0.0 {
            return (next, step);
        }
        omega = next;
    }
    (omega, 200)
}
