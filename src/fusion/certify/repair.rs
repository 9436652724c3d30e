//! The repair of a solved certificate into one proven with every rounding accounted for (the
//! parent's module docs, "Exact in floating point").

use nalgebra::DMatrix;

use crate::error::SolveError;
use crate::fusion::verify::{is_psd, psd_shift, up, Ball, BallMatrix, Dot, U};
use crate::fusion::FusionProblem;

use super::layout::Layout;

/// Whether floats sum to exactly zero, decided exactly: Shewchuk's GROW-EXPANSION (Discrete
/// Comput. Geom. 18, 1997, Thm. 10) keeps the running sum as a nonoverlapping expansion,
/// which is zero exactly when all its components are.
pub(super) fn sums_to_zero(terms: &[f64]) -> bool {
    let mut expansion: Vec<f64> = Vec::with_capacity(terms.len());
    for &t in terms {
        if !t.is_finite() {
            return false;
        }
        let mut q = t;
        for h in expansion.iter_mut() {
            // TwoSum(q, h): s + e = q + h exactly (no overflow below 2^1023).
            let s = q + *h;
            let bv = s - q;
            let e = (q - (s - bv)) + (*h - bv);
            *h = e;
            q = s;
        }
        expansion.push(q);
        if !q.is_finite() {
            return false;
        }
    }
    expansion.iter().all(|&h| h == 0.0)
}

/// Makes the entries `group` of `x` sum to exactly zero (module docs: a grid, then the last
/// entry minus the sum of the others).
pub(super) fn exact_zero_sum(x: &mut [f64], group: &[usize]) {
    // Distinct variables only (a group never repeats one, but be safe).
    let mut vars: Vec<usize> = group.to_vec();
    vars.sort_unstable();
    vars.dedup();
    let bound = vars.iter().map(|&v| x[v].abs()).fold(0.0, f64::max);
    if vars.len() == 1 || bound == 0.0 || !bound.is_finite() {
        for &v in &vars {
            x[v] = 0.0;
        }
        return;
    }
    let mut e = bound.log2().ceil() as i32;
    while 2f64.powi(e) < bound {
        e += 1;
    }
    // len · 2^e < 2^(e + room) ≤ 2^(53) · g with g = 2^(e − bits).
    let room = (usize::BITS - vars.len().leading_zeros()) as i32 + 1;
    let bits = 52 - room;
    let g = 2f64.powi(e - bits);
    let mut sum = 0.0;
    let (last, rest) = vars.split_last().expect("two or more");
    for &v in rest {
        x[v] = (x[v] / g).round() * g;
        sum += x[v];
    }
    x[*last] = -sum;
}

/// One multiplier of a piece (module docs, "Sectors"): its matrix `S` (`q(v) = vᵀ S v`,
/// exact), `C'` and `g' ≥ 0`.
#[allow(non_snake_case)]
pub(super) struct MultiplierPart {
    pub(super) S: DMatrix<f64>,
    pub(super) Cp: DMatrix<f64>,
    pub(super) gp: f64,
}

/// The verified repair of one piece (module docs): `C ← C + δI` until `C − Σ S ⊗ C' − W D Wᵀ
/// ⪰ 0` is proven (each multiplier's `C' ← C' + δ'I` until `C' ⪰ 0` is, first), then `Q ← Q + ηI` until
/// `G + E ⪰ 0` is proven. `Q` only grows (by multiples of `I`), so a piece proven before
/// stays proven.
///
/// In steps: the multipliers ([`proven_multipliers`]), condition 1 ([`proven_condition_one`]),
/// `T_αβ = ⟨J₀, C_αβ⟩` ([`exposure`]), then `Q` shifted until the Gram matrix `G + E`
/// ([`gram_residual`]) is proven PSD, at most 60 times.
#[allow(non_snake_case)]
pub(super) fn repair(
    problem: &FusionProblem,
    lay: &Layout,
    K_a: &DMatrix<f64>,
    C: DMatrix<f64>,
    Q: &mut DMatrix<f64>,
    G: &DMatrix<f64>,
    parts: Vec<MultiplierPart>,
) -> Result<(), SolveError> {
    let parts = proven_multipliers(parts, lay.m)?;
    let C = proven_condition_one(lay, K_a, C, &parts)?;
    let T = exposure(problem, lay, &C);
    let place = gram_places(lay);
    let mut eta = 0.0;
    for _ in 0..60 {
        let Y = gram_residual(lay, Q, &T, G, &parts, &place);
        if is_psd(&Y.mid, &Y.rad) {
            return Ok(());
        }
        let shift = psd_shift(&Y).ok_or_else(|| repair_failed("G + E"))?;
        let step = if eta == 0.0 { shift } else { shift.max(eta) };
        let step = step + 1e-16 * Q.amax().max(f64::MIN_POSITIVE);
        for k in 0..lay.n {
            Q[(k, k)] += step;
        }
        eta += step;
    }
    Err(repair_failed("G + E"))
}

/// Each multiplier's `C' ⪰ 0` proven, its diagonal shifted if needed (the diagonal holds no
/// cross entry, and `C` enters only through `C − Σ S ⊗ C'`, proven next).
#[allow(non_snake_case)]
fn proven_multipliers(
    parts: Vec<MultiplierPart>,
    m: usize,
) -> Result<Vec<MultiplierPart>, SolveError> {
    let zero = DMatrix::zeros(m, m);
    parts
        .into_iter()
        .map(|MultiplierPart { S, Cp, gp }| {
            let first = BallMatrix::exact(&Cp);
            let Cp = shift_until_proven(Cp, &first, "C' ⪰ 0", |shifted| is_psd(shifted, &zero))?;
            Ok(MultiplierPart { S, Cp, gp })
        })
        .collect()
}

/// Condition 1 proven: `C` (shifted by `δI` if needed) with `C − Σ S ⊗ C' − W D Wᵀ ⪰ 0`, `W`
/// (`N × nb`) the gain's entries by monomial as balls, `D` the multinomial weights `c_β`
/// (exact integers).
#[allow(non_snake_case)]
fn proven_condition_one(
    lay: &Layout,
    K_a: &DMatrix<f64>,
    C: DMatrix<f64>,
    parts: &[MultiplierPart],
) -> Result<DMatrix<f64>, SolveError> {
    let n = lay.n;
    let (m, N) = (lay.m, lay.big());
    let K_b = BallMatrix::identity_minus(K_a);
    let k_entry = |k: usize, p: usize| {
        if p < n {
            Ball::exact(K_a[(k, p)])
        } else {
            K_b.at(k, p - n)
        }
    };
    let nb = lay.lower.len();
    let W = BallMatrix::from_fn(N, nb, |row, t| {
        let (alpha, p) = (row / m, row % m);
        match lay.step(alpha, &lay.lower[t].0) {
            Some(k) => k_entry(k, p),
            None => Ball::exact(0.0),
        }
    });
    let WD = BallMatrix::from_fn(N, nb, |row, t| {
        let c = lay.lower[t].1;
        let w = W.at(row, t);
        let mid = c * w.mid;
        Ball {
            mid,
            rad: up(c * w.rad + U * mid.abs(), 3),
        }
    });
    let margin = |C: &DMatrix<f64>| {
        BallMatrix::from_fn(N, N, |x, y| {
            let mut d = Dot::new();
            d.add(Ball::exact(C[(x, y)]));
            for part in parts {
                // − (S ⊗ C')[(a,p),(b,q)] = − S_ab C'_pq (level 1: x = a m + p).
                d.add_prod(
                    Ball::exact(-part.S[(x / m, y / m)]),
                    Ball::exact(part.Cp[(x % m, y % m)]),
                );
            }
            for t in 0..nb {
                let w = WD.at(y, t);
                d.add_prod(
                    W.at(x, t),
                    Ball {
                        mid: -w.mid,
                        rad: w.rad,
                    },
                );
            }
            d.ball()
        })
    };
    let first = margin(&C).symmetrized();
    shift_until_proven(C, &first, "C − W D Wᵀ", |shifted| {
        let b = margin(shifted).symmetrized();
        is_psd(&b.mid, &b.rad)
    })
}

/// `T_αβ = ⟨J₀, C_αβ⟩` as balls (`J₀` the joint covariance with zero cross blocks).
#[allow(non_snake_case)]
fn exposure(problem: &FusionProblem, lay: &Layout, C: &DMatrix<f64>) -> BallMatrix {
    let (n, m, s) = (lay.n, lay.m, lay.mons.len());
    let J0 = |p: usize, q: usize| match (p < n, q < n) {
        (true, true) => problem.P_a[(p, q)],
        (false, false) => problem.P_b[(p - n, q - n)],
        _ => 0.0,
    };
    BallMatrix::from_fn(s, s, |a, b| {
        let mut d = Dot::new();
        for p in 0..m {
            for q in 0..m {
                let j = J0(p, q);
                if j != 0.0 {
                    d.add_exact_prod(j, C[(a * m + p, b * m + q)]);
                }
            }
        }
        d.ball()
    })
}

/// Where each degree-`2r` coefficient goes in the Gram matrix `E`: `(α, α)` when `γ = 2α`,
/// else half on `(α, β)` and half on `(β, α)` for the first `α < β` with `α + β = γ`.
fn gram_places(lay: &Layout) -> Vec<(usize, usize)> {
    let s = lay.mons.len();
    let mut place: Vec<Option<(usize, usize)>> = vec![None; lay.products.len()];
    for a in 0..s {
        place[lay.sum[a][a]] = Some((a, a));
    }
    for a in 0..s {
        for b in a + 1..s {
            let g = lay.sum[a][b];
            if place[g].is_none() {
                place[g] = Some((a, b));
            }
        }
    }
    place
        .into_iter()
        .map(|p| p.expect("every degree-2r monomial splits"))
        .collect()
}

/// `G + E` as balls, `E` the Gram matrix (placed by `place`) of the residual
/// `e_γ = coef_γ(‖v‖^{2(r−1)} vᵀQv) − Σ_{α+β=γ} (T_αβ + G_αβ) − Σ_j g'_j coef_γ(q_j)`.
#[allow(non_snake_case)]
fn gram_residual(
    lay: &Layout,
    Q: &DMatrix<f64>,
    T: &BallMatrix,
    G: &DMatrix<f64>,
    parts: &[MultiplierPart],
    place: &[(usize, usize)],
) -> BallMatrix {
    let (n, s) = (lay.n, lay.mons.len());
    let mut coef = vec![Dot::new(); lay.products.len()];
    for (beta, c) in &lay.lower {
        for k in 0..n {
            for l in 0..n {
                coef[lay.quad(beta, k, l)].add_exact_prod(*c, Q[(k, l)]);
            }
        }
    }
    for a in 0..s {
        for b in 0..s {
            let t = T.at(a, b);
            let d = &mut coef[lay.sum[a][b]];
            d.add(Ball {
                mid: -t.mid,
                rad: t.rad,
            });
            d.add(Ball::exact(-G[(a, b)]));
        }
    }
    for part in parts {
        for (g, d) in coef.iter_mut().enumerate() {
            let c = lay.multiplier_coefficient(&part.S, g);
            if c != 0.0 {
                d.add_exact_prod(-c, part.gp);
            }
        }
    }
    let mut Y = BallMatrix::exact(G);
    for (g, d) in coef.iter().enumerate() {
        let e = d.ball();
        let (a, b) = place[g];
        if a == b {
            let mid = Y.mid[(a, a)] + e.mid;
            Y.rad[(a, a)] = up(e.rad + U * mid.abs(), 3);
            Y.mid[(a, a)] = mid;
        } else {
            for (x, y) in [(a, b), (b, a)] {
                let mid = Y.mid[(x, y)] + 0.5 * e.mid;
                Y.rad[(x, y)] = up(0.5 * e.rad + U * mid.abs(), 3);
                Y.mid[(x, y)] = mid;
            }
        }
    }
    Y
}

/// `M` itself when `first` (the enclosure of what must be PSD, formed from `M`) is proven
/// PSD, else `M + δI` with the smallest `δ` of a doubling sequence (from `psd_shift(first)`)
/// for which `proves` succeeds; `NotProven { what }` when none of 60 does.
#[allow(non_snake_case)]
pub(super) fn shift_until_proven(
    M: DMatrix<f64>,
    first: &BallMatrix,
    what: &str,
    proves: impl Fn(&DMatrix<f64>) -> bool,
) -> Result<DMatrix<f64>, SolveError> {
    if is_psd(&first.mid, &first.rad) {
        return Ok(M);
    }
    let mut delta = psd_shift(first).ok_or_else(|| repair_failed(what))?;
    let scale = M.amax().max(f64::MIN_POSITIVE);
    for _ in 0..60 {
        let mut shifted = M.clone();
        for i in 0..shifted.nrows() {
            shifted[(i, i)] += delta;
        }
        if proves(&shifted) {
            return Ok(shifted);
        }
        delta = 2.0 * delta + 1e-16 * scale;
    }
    Err(repair_failed(what))
}

pub(super) fn repair_failed(what: &str) -> SolveError {
    SolveError::NotProven { what: what.into() }
}
