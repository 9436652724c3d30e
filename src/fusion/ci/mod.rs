//! Covariance intersection with the exactly optimal weight.
//!
//! CI (paper eq. (CI)): `P⁻¹ = ω P_a⁻¹ + (1−ω) P_b⁻¹`, `P⁻¹x = ω P_a⁻¹x_a + (1−ω) P_b⁻¹x_b`,
//! `ω ∈ [0, 1]`. In a basis `W` that diagonalizes the pencil `(P_a, P_b)` (`P_b = W Wᵀ`,
//! `P_a = W diag(μ) Wᵀ`, one generalized symmetric eigenproblem) every candidate is diagonal:
//!
//! `P(ω) = W diag(1 / dᵢ(ω)) Wᵀ`, `dᵢ(ω) = (1 − ω) + ω λᵢ`, `λᵢ = 1/μᵢ`,
//!
//! so `tr P(ω) = Σ ‖wᵢ‖²/dᵢ(ω)` and `log det P(ω) = log det WWᵀ − Σ ln dᵢ(ω)`. Both are convex
//! in `ω`; the optimum is an endpoint when the derivative does not change sign on `[0, 1]`
//! (then `ω` is exactly `0` or `1` and `P` is exactly `P_b` or `P_a`; a derivative within
//! `1e-9` of the size of its terms counts as zero, so rounding noise on a flat criterion does
//! not decide; where it counts as zero at both ends — equal covariances, a criterion flat on
//! all of `[0, 1]`, every `ω` optimal — `ω = ½`, the middle of the optimal set, whose mean is
//! the average of the two), otherwise the root of the derivative, found by safeguarded Newton (exact
//! second derivative, bisection when a step leaves the bracket) until the derivative is zero
//! to within `4ε` of the size of its terms — its sign then no longer says where the root is —
//! or a step moves `ω` by less than `4ε` relative: at most 8 steps on 40 random problems
//! (tested).
//!
//! ## The balanced pencil (accuracy)
//!
//! The textbook reduction factors `P_b = L Lᵀ` and diagonalizes `L⁻¹ P_a L⁻ᵀ`, whose
//! eigenvalues are the `μᵢ`. A symmetric eigensolver returns them with an *absolute* error of a
//! few `ε max μ`, so the small ones lose their relative accuracy: with the ratios `μ` spanning
//! `s = μ_max/μ_min`, some `dᵢ` carry a relative error of about `ε s`. Each of `P_a`, `P_b` of
//! condition number `κ` lets `s` reach `κ²`, while a relative change of `ε` in the inputs
//! moves `P(ω)` by about `ε κ`; at large `κ` it even returns negative `μᵢ` for positive
//! definite inputs (docs/methods.md has the measurements).
//!
//! Here the pencil is balanced instead:
//!
//! - `S = P_a + t P_b = L Lᵀ`, with `t = 2ᵏ` from the diagonal ratios ([`balance`]), so
//!   `t P_b` is exact (unless an entry leaves the normal range) and `S` rounds once per entry.
//! - `L⁻¹ P_a L⁻ᵀ = V diag(ν) Vᵀ` and `L⁻¹ (t P_b) L⁻ᵀ = I − V diag(ν) Vᵀ`, so
//!   `νᵢ = μᵢ/(μᵢ + t)` and `ηᵢ = 1 − νᵢ = t/(μᵢ + t)` both lie in `(0, 1)`. Their absolute
//!   error of a few `ε` is a relative error of a few `ε` for every `νᵢ, ηᵢ ≥ ½`. `ηᵢ = 1 − νᵢ`
//!   is exact for `νᵢ ≥ ½` (Sterbenz) and rounds once below.
//! - An end below `2⁻¹⁰` is recomputed as a Rayleigh quotient of the original matrices at the
//!   generalized eigenvector `sᵢ = L⁻ᵀ vᵢ`: `νᵢ = sᵢᵀ P_a sᵢ`, `ηᵢ = t sᵢᵀ P_b sᵢ`. The
//!   quadratic form's rounding is relative to the matrix it is taken of, so a direction in which
//!   `P_b` is small keeps the accuracy of `P_b` there.
//! - Then `μᵢ = t νᵢ/ηᵢ`, `λᵢ = ηᵢ/(t νᵢ)` and `W = L V diag(√(ηᵢ/t))`. This is the
//!   representation above: `W Wᵀ = L (I − V diag(ν) Vᵀ) Lᵀ / t = P_b`, `W diag(μ) Wᵀ = P_a`.
//!   `dᵢ = (1 − ω) + ω λᵢ` is a sum of non-negative terms, so it keeps their accuracy.
//!
//! Accuracy is a tested statement, not a proven one: against 50-digit references of random
//! pairs of condition number `κ = 10²…10¹⁵` the relative error of `P` is within `4 ε κ` (the
//! Python tests), and on exact co-diagonal pairs of `κ = 2²⁰, 2⁴⁰` (ratios spanning `κ²`) within
//! `16 ε κ` of the exact answer (`tests/native/ci.rs`); ICI and EI, which use this basis, are
//! tested alike. CI's conservativeness holds to the same relative accuracy. Where a bound must
//! hold in floating point, the bracket recomputes CI's with enclosed rounding
//! ([`bracket`](super::bracket)). When a computed `νᵢ` or `ηᵢ` is still not positive, the pair
//! is beyond what floating point resolves and [`InputError::UnresolvedPair`] says so; when `S`
//! itself does not factor, [`InputError::Unfactored`] does (no input is named: each was
//! accepted).
//!
//! Filters that keep their estimates in blocks (the tracking study) use the in-place forms
//! `ci_in_place` / `nmci_in_place`: means and covariances only, endpoints decided from the
//! derivative at `ω = 0` and `1` before any eigenproblem, and blocks with equal covariances
//! in both estimates sharing one pencil.

mod omega;
mod pencil;
mod rule;
#[cfg(test)]
#[allow(non_snake_case)]
mod tests;

pub(in crate::fusion) use omega::{minimise_convex, Weighted};
pub(in crate::fusion) use pencil::Pencil;
pub(in crate::fusion) use rule::weighted;
pub use rule::{ci_covariance, covariance_intersection, covariance_intersection_blocks, CiResult};
pub(crate) use rule::{ci_in_place, nmci_in_place};
