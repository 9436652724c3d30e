//! A proven lower bound on the robust optimum `V*` (`fusion::bracket` composes it with the
//! upper ends of `fusion::upper`).
//!
//! ## A Lagrangian bound checked in exact arithmetic
//! Let `J_1, …, J_M` be admissible (each `J_i ⪰ 0` with the diagonal blocks `P_a`, `P_b` and
//! the known zeros) and `Λ_1, …, Λ_M ⪰ 0` (`n × n`) with `Σ Λ_i ⪯ σ I`. For every robust-
//! feasible `(K, P̄)`, `P̄ ⪰ K J_i Kᵀ` and `P̄ ⪰ 0`, so
//!
//! `σ tr P̄ ≥ ⟨Σ Λ_i, P̄⟩ ≥ Σ ⟨Λ_i, K J_i Kᵀ⟩ = f(K_a) ≥ min_{K_a} f`,
//!
//! and `V* ≥ min f / σ`. With `e_f = e_b + K_a d`, `d = e_a − e_b`, each term is
//! `⟨Λ_i, K_a S_i K_aᵀ⟩ + 2⟨Λ_i C_i, K_a⟩ + ⟨Λ_i, P_b⟩` (`S_i = P_a + P_b − X_i − X_iᵀ`,
//! `C_i = X_iᵀ − P_b`, `X_i` the cross block of `J_i`), so with `v = vec K_a`,
//! `f(v) = vᵀ H v + 2 gᵀ v + c₀`, `H = Σ S_i ⊗ Λ_i ⪰ 0`. For any `v̂` and `μ ≤ λ_min(H)`,
//! `μ > 0`: `f(v) ≥ f(v̂) + 2 rᵀ(v − v̂) + μ ‖v − v̂‖² ≥ f(v̂) − ‖r‖²/μ`, `r = H v̂ + g`.
//!
//! The `J_i` and `Λ_i` come from the relaxation the caller solved (the sampled SDP's or the
//! cutting planes' constraints and the solver's dual matrices; any choice is valid, a good
//! one is tight), `v̂` solves `H v̂ = −g` approximately. Everything is then *checked*, not
//! trusted: each `J_i` is proven PSD by `fusion::verify::is_psd` (pulled towards `P_ab = 0`,
//! which keeps it admissible, if needed; dropped if that fails — dropping a term keeps the
//! bound valid); each `Λ_i` is shifted until proven PSD; `σ = 1 + ‖Σ Λ_i − I‖_F` rounded
//! up; `μ` is proven by the same test on `H − μ I`; `f(v̂)` and `‖r‖²` are enclosed in
//! balls. So **`lower_bound ≤ V*` holds in exact arithmetic for the problem's floats** (the
//! inputs as symmetrised, `(A + Aᵀ)/2`: `FusionProblem` stores them so), on
//! the floating-point model of `fusion::verify`, whatever the solver's accuracy (a loose
//! solve only makes the bound weaker). This is the approach of Jansson, Chaykin and Keil,
//! "Rigorous error bounds for the optimal value in semidefinite programming", SIAM J.
//! Numer. Anal. 46(1), 2007, specialised to this program (the gain is eliminated exactly
//! instead of bounded a priori).
//!
//! **Independent blocks.** When `P_a`, `P_b` and the pattern split the state into
//! independent blocks, every admissible `J` is block diagonal (in the blocks' order), and the
//! bound is computed per block `B` with `J_i` built on that block (and `P_a`, `P_b`'s blocks
//! elsewhere). For any robust-feasible `(K, P̄)`, the diagonal block
//! `(K J Kᵀ)_BB = Σ_C K_BC J_CC K_BCᵀ ⪰ K_BB J_BB K_BBᵀ`, and `K_BB` is itself unbiased
//! (`(K_a)_BB + (K_b)_BB = I`), so `tr P̄_BB` is at least block `B`'s bound, and the sum of
//! the per-block bounds (rounded down) is a lower bound on `V*`.
//!

use nalgebra::{DMatrix, DVector, SymmetricEigen};

use super::verify::{down, is_psd, norm2_up, psd_shift, up, Ball, BallMatrix, Dot, U};
use super::FusionProblem;
use crate::linalg::cholesky_of;

/// A proven lower bound on the robust optimum `V*` of `problem` from admissible cross blocks
/// `cross[i]` and dual matrices `duals[i]` (module docs); `0` when nothing can be proven.
///
/// The steps of the module docs' argument: the terms `(X_i, Λ_i)` checked ([`terms`]), `σ`
/// ([`sigma`]), `f`'s coefficients `H`, `g`, `c₀` as balls ([`quadratic`]), `μ ≤ λ_min(H)`
/// proven ([`proven_mu`]), `v̂ ≈ −H⁻¹ g` ([`minimiser`]), and `f(v̂) − ‖r‖²/μ` rounded down
/// ([`f_lower`]), divided by `σ`.
#[allow(non_snake_case)]
pub fn lower_bound(
    problem: &FusionProblem,
    cross: &[&DMatrix<f64>],
    duals: &[DMatrix<f64>],
) -> f64 {
    let terms = terms(problem, cross, duals);
    if terms.is_empty() {
        return 0.0;
    }
    let sigma = sigma(&terms, problem.dim());
    let f = quadratic(problem, &terms);
    let Some(mu) = proven_mu(&f.H) else {
        return 0.0;
    };
    let Some(v) = minimiser(&f) else {
        return 0.0;
    };
    match f_lower(&f, &v, mu) {
        Some(numerator) => down(numerator / sigma, 2),
        None => 0.0,
    }
}

/// The terms `(X_i, Λ_i)` that can be checked: each `J_i` proven PSD (pulled towards
/// `P_ab = 0` if needed, `admissible`), each `Λ_i` shifted until proven PSD; a term of the
/// wrong size, with a non-finite entry, or that cannot be proven is dropped (dropping a term
/// keeps the bound valid).
#[allow(non_snake_case)]
fn terms(
    problem: &FusionProblem,
    cross: &[&DMatrix<f64>],
    duals: &[DMatrix<f64>],
) -> Vec<(DMatrix<f64>, DMatrix<f64>)> {
    let n = problem.dim();
    let mut terms = Vec::new();
    for (X, L) in cross.iter().zip(duals) {
        if X.shape() != (n, n)
            || L.shape() != (n, n)
            || X.iter().chain(L.iter()).any(|x| !x.is_finite())
        {
            continue;
        }
        let Some(X) = admissible(problem, X) else {
            continue;
        };
        let Some(L) = proven_psd(&symmetric_floats(L)) else {
            continue;
        };
        terms.push((X, L));
    }
    terms
}

/// `σ = 1 + ‖Σ Λ_i − I‖_F` rounded up: `σ ≥ λ_max(Σ Λ_i)`.
#[allow(non_snake_case)]
fn sigma(terms: &[(DMatrix<f64>, DMatrix<f64>)], n: usize) -> f64 {
    let sum_minus_i = BallMatrix::from_fn(n, n, |r, c| {
        let mut d = Dot::new();
        for (_, L) in terms {
            d.add(Ball::exact(L[(r, c)]));
        }
        if r == c {
            d.add(Ball::exact(-1.0));
        }
        d.ball()
    });
    let fro = norm2_up(
        sum_minus_i
            .mid
            .iter()
            .zip(sum_minus_i.rad.iter())
            .map(|(m, r)| m.abs() + r),
        3 * n * n + 6,
    );
    up(1.0 + fro, 2)
}

/// `f(v) = vᵀ H v + 2 gᵀ v + c₀` as balls (module docs).
#[allow(non_snake_case)]
struct Quadratic {
    H: BallMatrix,
    g: Vec<Ball>,
    c0: Ball,
}

/// `S_i = P_a + P_b − X_i − X_iᵀ`, `C_i = X_iᵀ − P_b` as balls; `H = Σ S_i ⊗ Λ_i`,
/// `g = vec Σ Λ_i C_i`, `c₀ = Σ ⟨Λ_i, P_b⟩`.
#[allow(non_snake_case)]
fn quadratic(problem: &FusionProblem, terms: &[(DMatrix<f64>, DMatrix<f64>)]) -> Quadratic {
    let n = problem.dim();
    let sc: Vec<(BallMatrix, BallMatrix)> = terms
        .iter()
        .map(|(X, _)| {
            let S = BallMatrix::from_fn(n, n, |k, l| {
                let mut d = Dot::new();
                for v in [
                    problem.P_a[(k, l)],
                    problem.P_b[(k, l)],
                    -X[(k, l)],
                    -X[(l, k)],
                ] {
                    d.add(Ball::exact(v));
                }
                d.ball()
            });
            let C = BallMatrix::from_fn(n, n, |k, l| {
                let mut d = Dot::new();
                d.add(Ball::exact(X[(l, k)]));
                d.add(Ball::exact(-problem.P_b[(k, l)]));
                d.ball()
            });
            (S.symmetrized(), C)
        })
        .collect();
    let nn = n * n;
    let H = BallMatrix::from_fn(nn, nn, |a, b| {
        let (k, r) = (a / n, a % n);
        let (l, s) = (b / n, b % n);
        let mut d = Dot::new();
        for ((_, L), (S, _)) in terms.iter().zip(&sc) {
            d.add_prod(S.at(k, l), Ball::exact(L[(r, s)]));
        }
        d.ball()
    })
    .symmetrized();
    let g: Vec<Ball> = (0..nn)
        .map(|a| {
            let (k, r) = (a / n, a % n);
            let mut d = Dot::new();
            for ((_, L), (_, C)) in terms.iter().zip(&sc) {
                for t in 0..n {
                    d.add_prod(Ball::exact(L[(r, t)]), C.at(t, k));
                }
            }
            d.ball()
        })
        .collect();
    let mut c0 = Dot::new();
    for (_, L) in terms {
        for r in 0..n {
            for c in 0..n {
                c0.add_exact_prod(L[(r, c)], problem.P_b[(r, c)]);
            }
        }
    }
    Quadratic {
        H,
        g,
        c0: c0.ball(),
    }
}

/// `μ > 0` with `H − μ I` proven PSD: half the estimated `λ_min(H)`, halved up to 20 times;
/// `None` if the estimate is not positive or no `μ` is proven.
#[allow(non_snake_case)]
fn proven_mu(H: &BallMatrix) -> Option<f64> {
    let estimate = SymmetricEigen::new(H.mid.clone()).eigenvalues.min();
    if estimate.is_nan() || estimate <= 0.0 {
        return None;
    }
    let nn = H.mid.nrows();
    let mut mu = 0.5 * estimate;
    for _ in 0..20 {
        let mut shifted = H.clone();
        for i in 0..nn {
            let m = shifted.mid[(i, i)] - mu;
            shifted.rad[(i, i)] = up(shifted.rad[(i, i)] + U * m.abs(), 3);
            shifted.mid[(i, i)] = m;
        }
        if is_psd(&shifted.mid, &shifted.rad) {
            return Some(mu);
        }
        mu *= 0.5;
    }
    None
}

/// `v̂ ≈ −H⁻¹ g` (any `v̂` is valid; zero where `H`'s midpoint has no Cholesky factor);
/// `None` if not finite.
fn minimiser(f: &Quadratic) -> Option<DVector<f64>> {
    let nn = f.g.len();
    let g_mid = DVector::from_iterator(nn, f.g.iter().map(|b| b.mid));
    let v = match cholesky_of(f.H.mid.clone()) {
        Some(ch) => -ch.solve(&g_mid),
        None => DVector::zeros(nn),
    };
    v.iter().all(|x| x.is_finite()).then_some(v)
}

/// `f(v̂) − ‖r‖²/μ` rounded down, `r = H v̂ + g` (module docs): a lower bound on `min f`;
/// `None` unless positive.
fn f_lower(f: &Quadratic, v: &DVector<f64>, mu: f64) -> Option<f64> {
    let nn = f.g.len();
    let mut fv = Dot::new();
    let mut r_sq = 0.0;
    for a in 0..nn {
        let mut ra = Dot::new();
        for b in 0..nn {
            let w = v[a] * v[b];
            fv.add_prod(
                f.H.at(a, b),
                Ball {
                    mid: w,
                    rad: up(U * w.abs(), 1),
                },
            );
            ra.add_prod(f.H.at(a, b), Ball::exact(v[b]));
        }
        ra.add(f.g[a]);
        let ra = ra.ball();
        let mag = ra.mid.abs() + ra.rad;
        r_sq += mag * mag;
        fv.add_prod(f.g[a], Ball::exact(2.0 * v[a]));
    }
    fv.add(f.c0);
    let f_low = fv.ball().lower();
    let penalty = up(up(r_sq, 2 * nn + 2) / mu, 2);
    let numerator = Ball {
        mid: f_low - penalty,
        rad: 0.0,
    }
    .lower();
    (!numerator.is_nan() && numerator > 0.0).then_some(numerator)
}

/// The admissible joint covariance nearest to `X` on the segment to `P_ab = 0` that can be
/// proven PSD (known zeros forced): `X` itself or `(1 − 2⁻ᵏ) X`; `None` if none is proven.
#[allow(non_snake_case)]
fn admissible(problem: &FusionProblem, X: &DMatrix<f64>) -> Option<DMatrix<f64>> {
    let n = problem.dim();
    let X = DMatrix::from_fn(n, n, |i, j| {
        if problem.cross_pattern.is_unknown(i, j) {
            X[(i, j)]
        } else {
            0.0
        }
    });
    for t in [
        1.0,
        1.0 - 2f64.powi(-40),
        1.0 - 2f64.powi(-26),
        1.0 - 2f64.powi(-14),
        0.99,
        0.9,
    ] {
        let Xt = &X * t;
        let J = problem.joint_covariance(&Xt);
        // joint_covariance copies P_a, P_b, Xt and Xtᵀ: exactly symmetric.
        if is_psd(&J, &DMatrix::zeros(2 * n, 2 * n)) {
            return Some(Xt);
        }
    }
    None
}

/// `(M + Mᵀ)/2` in floats (exactly symmetric).
fn symmetric_floats(m: &DMatrix<f64>) -> DMatrix<f64> {
    DMatrix::from_fn(m.nrows(), m.ncols(), |i, j| 0.5 * (m[(i, j)] + m[(j, i)]))
}

/// `M + t I` (floats) proven PSD for the smallest `t` of a doubling sequence.
fn proven_psd(m: &DMatrix<f64>) -> Option<DMatrix<f64>> {
    let n = m.nrows();
    if is_psd(m, &DMatrix::zeros(n, n)) {
        return Some(m.clone());
    }
    let mut t = psd_shift(&BallMatrix::exact(m))?;
    for _ in 0..40 {
        let mut s = m.clone();
        for i in 0..n {
            s[(i, i)] += t;
        }
        if is_psd(&s, &DMatrix::zeros(n, n)) {
            return Some(s);
        }
        t *= 2.0;
    }
    None
}
