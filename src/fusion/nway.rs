//! N-way covariance intersection: `k ≥ 2` estimates at once, and its non-monolithic form.
//!
//! `P⁻¹ = Σᵢ ωᵢ Pᵢ⁻¹`, `P⁻¹ x = Σᵢ ωᵢ Pᵢ⁻¹ xᵢ`, weights on the simplex (`ωᵢ ≥ 0`, `Σ ωᵢ = 1`),
//! conservative for any unknown cross-covariances (Julier & Uhlmann's CI for `k` estimates;
//! MATLAB's `fusecovint`). Both criteria are convex in `ω`: with `Yᵢ = Pᵢ⁻¹` and
//! `Aᵢ = P Yᵢ`,
//!
//! - trace: `∂ᵢ tr P = −tr(Aᵢ P)`, `∂ᵢ∂ⱼ tr P = 2 tr(Aᵢ Aⱼ P)`;
//! - log-det: `∂ᵢ log det P = −tr Aᵢ`, `∂ᵢ∂ⱼ log det P = tr(Aᵢ Aⱼ)`.
//!
//! The minimiser is found by an active-set projected Newton method: Newton steps on the
//! face of the simplex spanned by the current support (the equality `Σ ωᵢ = 1` kept by a
//! KKT system), a ratio test that drops a weight reaching 0, Armijo backtracking, and on a
//! stationary face the KKT test `∂ⱼ ≥ λ` for every weight at 0 (`λ` the multiplier), which
//! re-enters the most attractive one otherwise. Near the optimum the criterion's change is
//! quadratic in the step and drops below its rounding before the gradients agree; there a
//! full Newton step is accepted when it shrinks the spread of the gradients on the support
//! (judged on the gradients, not the criterion). It ends when the KKT conditions hold to
//! `1e-10` relative (`|∂ᵢ − λ| ≤ 10⁻¹⁰ max|∂|` on the support, `∂ⱼ ≥ λ − 10⁻¹⁰ max|∂|` off it),
//! or, failing that, when the Newton step (with backtracking) lowers neither the criterion nor
//! the gradients' spread in floating point, or after 200 iterations (the result's `iterations`
//! reports the count); a test checks the KKT conditions to `1e-10`
//! with gradients computed independently. Two estimates are handed to
//! the exact two-estimate CI ([`covariance_intersection`](crate::rules::covariance_intersection)),
//! so `k = 2` gives exactly the pairwise results.
//!
//! Non-monolithic N-way CI splits the state into the independent blocks of all the
//! covariances and all the pairwise cross patterns (a pair without a pattern is fully
//! unknown) and fuses each block with its own weights.

use nalgebra::{DMatrix, DVector};

use super::ci::covariance_intersection;
use super::{definiteness_error, scatter_block, Criterion, Estimate, FusionProblem};
use crate::error::InputError;
use crate::linalg::{cholesky, symmetrize};
use crate::structure::absorb::absorb;
use crate::structure::{connected_components, BlockStructure, CrossPattern, StructureSettings};

/// The pattern of the cross-covariance `P_ij` of estimates `i < j` (pairs not listed are
/// fully unknown).
#[derive(Debug, Clone, PartialEq)]
pub struct PairPattern {
    /// First estimate (0-based).
    pub i: usize,
    /// Second estimate (0-based, `≠ i`).
    pub j: usize,
    /// Which entries of `P_ij` may be non-zero.
    pub pattern: CrossPattern,
}

/// N-way (nm)CI result.
#[allow(non_snake_case)]
#[derive(Debug, Clone, PartialEq)]
pub struct NwayResult {
    /// Fused estimate.
    pub x: DVector<f64>,
    /// Covariance bound.
    pub P: DMatrix<f64>,
    /// Gains `Kᵢ` (`x = Σ Kᵢ xᵢ`, `Σ Kᵢ = I`).
    pub gains: Vec<DMatrix<f64>>,
    /// The blocks (one for monolithic CI), state indices ascending.
    pub blocks: Vec<Vec<usize>>,
    /// Per block, the weights `ω` on the estimates (on the simplex).
    pub omega: Vec<Vec<f64>>,
    /// Newton iterations (summed over blocks; 0 where the two-estimate CI was used).
    pub iterations: usize,
}

fn check_estimates(estimates: &[Estimate]) -> Result<usize, InputError> {
    if estimates.len() < 2 {
        return Err(InputError::Estimates(format!(
            "fusion needs at least 2 estimates (got {})",
            estimates.len()
        )));
    }
    let n = estimates[0].P.nrows();
    for (i, e) in estimates.iter().enumerate() {
        if e.P.nrows() != n || e.x.len() != n {
            return Err(InputError::Estimates(format!(
                "estimates[{i}] has size {}, estimates[0] has size {n}",
                e.P.nrows()
            )));
        }
    }
    Ok(n)
}

/// Monolithic N-way CI: one weight per estimate, minimising `criterion` on the simplex.
///
/// ```
/// use nalgebra::{DMatrix, DVector};
/// use nmci::prelude::*;
/// use nmci::nway::covariance_intersection_nway;
/// let d = |v: &[f64]| DMatrix::from_diagonal(&DVector::from_row_slice(v));
/// let e = |p: &[f64]| Estimate::new("e", DVector::zeros(2), d(p)).unwrap();
/// let fused = covariance_intersection_nway(&[e(&[1.0, 9.0]), e(&[9.0, 1.0]), e(&[4.0, 4.0])],
///     Criterion::Trace).unwrap();
/// let w = &fused.omega[0];
/// assert!((w.iter().sum::<f64>() - 1.0).abs() < 1e-12 && w.iter().all(|&v| v >= 0.0));
/// assert!(fused.P.trace() < 8.0); // better than any single estimate (tr 10, 10, 8)
/// ```
pub fn covariance_intersection_nway(
    estimates: &[Estimate],
    criterion: Criterion,
) -> Result<NwayResult, InputError> {
    let n = check_estimates(estimates)?;
    fuse_block(estimates, &(0..n).collect::<Vec<_>>(), criterion)
}

/// Checks the estimates and the pairs' patterns (each pair names two different estimates,
/// once, with a pattern of their size); returns the size and whether every pair is given.
fn check_pairs(estimates: &[Estimate], pairs: &[PairPattern]) -> Result<(usize, bool), InputError> {
    let n = check_estimates(estimates)?;
    let k = estimates.len();
    let mut given = vec![vec![false; k]; k];
    for p in pairs {
        if p.i >= k || p.j >= k || p.i == p.j {
            return Err(InputError::Estimates(format!(
                "pair ({}, {}) does not name two different estimates of the {k}",
                p.i, p.j
            )));
        }
        if given[p.i][p.j] {
            return Err(InputError::Estimates(format!(
                "pair ({}, {}) is given twice",
                p.i, p.j
            )));
        }
        given[p.i][p.j] = true;
        given[p.j][p.i] = true;
        if p.pattern.dim() != n {
            return Err(InputError::Estimates(format!(
                "the pattern of pair ({}, {}) is {}×{0}, the estimates have size {n}",
                p.i,
                p.j,
                p.pattern.dim()
            )));
        }
    }
    let all_pairs_given = (0..k).all(|i| (i + 1..k).all(|j| given[i][j]));
    Ok((n, all_pairs_given))
}

/// The structure of N-way estimates under `settings` with their near-zero couplings absorbed
/// (`structure::absorb`'s module docs: the argument holds for `k` estimates, since raising
/// each `Pᵢ` to `P̄ᵢ ⪰ Pᵢ` raises the joint covariance and keeps its cross blocks). Pairs not
/// listed are fully unknown, so without declared blocks they link every state; with declared
/// blocks they take the pattern those imply ([`CrossPattern::within_blocks`]), and are
/// returned with it. Returns the estimates with `P̄ᵢ`, the pairs, and the structure.
#[allow(non_snake_case)]
pub fn absorb_couplings_nway(
    estimates: &[Estimate],
    pairs: &[PairPattern],
    settings: &StructureSettings,
) -> Result<(Vec<Estimate>, Vec<PairPattern>, BlockStructure), InputError> {
    let (n, all_pairs_given) = check_pairs(estimates, pairs)?;
    let given = pairs.len();
    let mut pairs = pairs.to_vec();
    let unknown = CrossPattern::fully_unknown(n);
    let mut wholly_unknown = None;
    if !all_pairs_given {
        match &settings.blocks {
            Some(blocks) => {
                let implied = CrossPattern::within_blocks(n, blocks)?;
                let k = estimates.len();
                for i in 0..k {
                    for j in i + 1..k {
                        if !pairs
                            .iter()
                            .any(|p| (p.i, p.j) == (i, j) || (p.j, p.i) == (i, j))
                        {
                            pairs.push(PairPattern {
                                i,
                                j,
                                pattern: implied.clone(),
                            });
                        }
                    }
                }
            }
            None => wholly_unknown = Some(("estimates".to_string(), &unknown)),
        }
    }
    let names: Vec<String> = (0..estimates.len())
        .map(|i| format!("estimates[{i}].p"))
        .collect();
    let matrices: Vec<(String, &DMatrix<f64>)> = names
        .iter()
        .cloned()
        .zip(estimates.iter().map(|e| &e.P))
        .collect();
    let mut patterns: Vec<(String, &CrossPattern)> = pairs
        .iter()
        .enumerate()
        .map(|(k, p)| {
            let field = if k < given {
                format!("patterns[{k}].pab_unknown")
            } else {
                "blocks".to_string()
            };
            (field, &p.pattern)
        })
        .collect();
    patterns.extend(wholly_unknown);
    let (bounds, structure) = absorb(n, &matrices, &patterns, settings)?;
    let estimates = estimates
        .iter()
        .zip(bounds)
        .map(|(e, b)| Estimate {
            x: e.x.clone(),
            P: b.above,
        })
        .collect();
    Ok((estimates, pairs, structure))
}

/// Non-monolithic N-way CI: the independent blocks of every `Pᵢ` and every pair pattern, and
/// N-way CI with its own weights in each block.
pub fn non_monolithic_ci_nway(
    estimates: &[Estimate],
    pairs: &[PairPattern],
    criterion: Criterion,
) -> Result<NwayResult, InputError> {
    let (n, all_pairs_given) = check_pairs(estimates, pairs)?;
    let k = estimates.len();
    let blocks = if all_pairs_given {
        let linked = |i: usize, j: usize| {
            estimates
                .iter()
                .any(|e| e.P[(i, j)] != 0.0 || e.P[(j, i)] != 0.0)
                || pairs
                    .iter()
                    .any(|p| p.pattern.is_unknown(i, j) || p.pattern.is_unknown(j, i))
        };
        connected_components(n, linked)
    } else {
        vec![(0..n).collect()]
    };
    let mut result = NwayResult {
        x: DVector::zeros(n),
        P: DMatrix::zeros(n, n),
        gains: vec![DMatrix::zeros(n, n); k],
        blocks: Vec::with_capacity(blocks.len()),
        omega: Vec::with_capacity(blocks.len()),
        iterations: 0,
    };
    for block in blocks {
        let part = fuse_block(estimates, &block, criterion)?;
        for (bi, &i) in block.iter().enumerate() {
            result.x[i] = part.x[bi];
        }
        scatter_block(&mut result.P, &block, &part.P);
        for (g, pg) in result.gains.iter_mut().zip(&part.gains) {
            scatter_block(g, &block, pg);
        }
        result
            .omega
            .push(part.omega.into_iter().next().unwrap_or_default());
        result.iterations += part.iterations;
        result.blocks.push(block);
    }
    Ok(result)
}

/// N-way CI of the estimates restricted to `block` (as one monolithic problem).
#[allow(non_snake_case)]
fn fuse_block(
    estimates: &[Estimate],
    block: &[usize],
    criterion: Criterion,
) -> Result<NwayResult, InputError> {
    let m = block.len();
    let sub: Vec<Estimate> = estimates
        .iter()
        .map(|e| Estimate {
            x: DVector::from_fn(m, |i, _| e.x[block[i]]),
            P: DMatrix::from_fn(m, m, |i, j| e.P[(block[i], block[j])]),
        })
        .collect();
    if sub.len() == 2 {
        let problem = FusionProblem::new_trusted(
            sub[0].x.clone(),
            sub[0].P.clone(),
            sub[1].x.clone(),
            sub[1].P.clone(),
            CrossPattern::fully_unknown(m),
        );
        let ci = covariance_intersection(&problem, criterion)?;
        return Ok(NwayResult {
            x: ci.fused.x,
            P: ci.fused.P,
            gains: vec![ci.fused.K_a, ci.fused.K_b],
            blocks: vec![block.to_vec()],
            omega: vec![vec![ci.omega, 1.0 - ci.omega]],
            iterations: 0,
        });
    }
    let info = sub
        .iter()
        .enumerate()
        .map(|(i, e)| {
            inverse(&e.P).ok_or_else(|| definiteness_error(&format!("estimates[{i}].p"), &e.P))
        })
        .collect::<Result<Vec<_>, _>>()?;
    let (omega, iterations) = simplex_newton(&info, criterion)?;
    let Y = weighted_sum(&info, &omega);
    let P = inverse(&Y).ok_or_else(|| InputError::Unfactored {
        matrix: "the fused information Σ ωᵢ Pᵢ⁻¹".into(),
        inputs: "the estimates' covariances".into(),
    })?;
    let gains: Vec<DMatrix<f64>> = info
        .iter()
        .zip(&omega)
        .map(|(Yi, &w)| &P * Yi * w)
        .collect();
    let x = gains
        .iter()
        .zip(&sub)
        .fold(DVector::zeros(m), |acc, (K, e)| acc + K * &e.x);
    Ok(NwayResult {
        x,
        P,
        gains,
        blocks: vec![block.to_vec()],
        omega: vec![omega],
        iterations,
    })
}

/// The inverse of an SPD matrix (symmetrized), `None` if Cholesky fails.
fn inverse(m: &DMatrix<f64>) -> Option<DMatrix<f64>> {
    Some(symmetrize(&cholesky(m)?.inverse()))
}

fn weighted_sum(info: &[DMatrix<f64>], omega: &[f64]) -> DMatrix<f64> {
    let n = info[0].nrows();
    info.iter()
        .zip(omega)
        .fold(DMatrix::zeros(n, n), |acc, (info_i, &w)| acc + info_i * w)
}

/// The criterion alone at `ω` (the line search needs no derivatives).
fn criterion_value(info: &[DMatrix<f64>], omega: &[f64], criterion: Criterion) -> Option<f64> {
    let chol = cholesky(&weighted_sum(info, omega))?;
    Some(match criterion {
        Criterion::Trace => chol.inverse().trace(),
        Criterion::Logdet => -2.0 * chol.l().diagonal().map(f64::ln).sum(),
    })
}

/// Criterion, gradient and Hessian at `ω` (see the module docs).
#[allow(non_snake_case)]
fn evaluate(
    info: &[DMatrix<f64>],
    omega: &[f64],
    criterion: Criterion,
) -> Option<(f64, DVector<f64>, DMatrix<f64>)> {
    let k = info.len();
    let chol = cholesky(&weighted_sum(info, omega))?;
    let P = symmetrize(&chol.inverse());
    let A: Vec<DMatrix<f64>> = info.iter().map(|Y| &P * Y).collect();
    let tr_prod = |X: &DMatrix<f64>, Z: &DMatrix<f64>| X.transpose().component_mul(Z).sum();
    match criterion {
        Criterion::Trace => {
            let B: Vec<DMatrix<f64>> = A.iter().map(|Ai| Ai * &P).collect();
            let g = DVector::from_fn(k, |i, _| -B[i].trace());
            let H = DMatrix::from_fn(k, k, |i, j| 2.0 * tr_prod(&A[i], &B[j]));
            Some((P.trace(), g, symmetrize(&H)))
        }
        Criterion::Logdet => {
            let logdet = -2.0 * chol.l().diagonal().map(f64::ln).sum();
            let g = DVector::from_fn(k, |i, _| -A[i].trace());
            let H = DMatrix::from_fn(k, k, |i, j| tr_prod(&A[i], &A[j]));
            Some((logdet, g, symmetrize(&H)))
        }
    }
}

/// Relative KKT tolerance of the simplex Newton method.
const KKT_TOL: f64 = 1e-10;

/// Minimises the criterion over the simplex (see the module docs): the weights and the
/// number of Newton iterations.
#[allow(non_snake_case)]
fn simplex_newton(
    info: &[DMatrix<f64>],
    criterion: Criterion,
) -> Result<(Vec<f64>, usize), InputError> {
    let k = info.len();
    let breakdown =
        || InputError::Estimates("the fused information matrix lost definiteness".into());
    let mut omega = vec![1.0 / k as f64; k];
    let mut support = vec![true; k];
    for iteration in 1..=200 {
        let (f, g, H) = evaluate(info, &omega, criterion).ok_or_else(breakdown)?;
        let scale = g.amax().max(f64::MIN_POSITIVE);
        let free: Vec<usize> = (0..k).filter(|&i| support[i]).collect();
        let m = free.len();
        // KKT system of the Newton step on the face: [H_SS 1; 1ᵀ 0] [d; ν] = [−g_S; 0].
        let mut kkt = DMatrix::zeros(m + 1, m + 1);
        let mut rhs = DVector::zeros(m + 1);
        let ridge = 1e-14 * H.diagonal().amax().max(f64::MIN_POSITIVE);
        for (a, &i) in free.iter().enumerate() {
            for (b, &j) in free.iter().enumerate() {
                kkt[(a, b)] = H[(i, j)];
            }
            kkt[(a, a)] += ridge;
            kkt[(a, m)] = 1.0;
            kkt[(m, a)] = 1.0;
            rhs[a] = -g[i];
        }
        let sol = kkt.lu().solve(&rhs);
        let mean_g = free.iter().map(|&i| g[i]).sum::<f64>() / m as f64;
        let (mut d, lambda) = match sol {
            Some(s) if s.iter().all(|v| v.is_finite()) => (s.rows(0, m).into_owned(), -s[m]),
            _ => (DVector::from_fn(m, |a, _| mean_g - g[free[a]]), mean_g),
        };
        let mut slope: f64 = free.iter().enumerate().map(|(a, &i)| g[i] * d[a]).sum();
        if slope > 0.0 {
            // Not a descent direction (numerically indefinite model): projected gradient.
            d = DVector::from_fn(m, |a, _| mean_g - g[free[a]]);
            slope = free.iter().enumerate().map(|(a, &i)| g[i] * d[a]).sum();
        }
        let spread = free
            .iter()
            .map(|&i| (g[i] - lambda).abs())
            .fold(0.0, f64::max);
        // Near the optimum the criterion stops resolving progress (its change is quadratic in
        // the step, the gradient's linear): then a full Newton step is taken if it shrinks
        // the KKT residual, judged on the gradients, not on the criterion.
        let flat = -slope <= 1e-3 * f64::EPSILON * f.abs().max(1.0);
        if flat && spread > KKT_TOL * scale {
            if let Some(w) = gradient_step(info, &omega, &free, &d, criterion, spread) {
                omega = w;
                continue;
            }
        }
        if spread <= KKT_TOL * scale || flat {
            // Stationary on the face: does a weight at 0 want to enter (∂ⱼ < λ)?
            let entering = (0..k)
                .filter(|&j| !support[j] && g[j] < lambda - KKT_TOL * scale)
                .min_by(|&a, &b| g[a].total_cmp(&g[b]));
            match entering {
                Some(j) => {
                    support[j] = true;
                    continue;
                }
                None => return Ok((omega, iteration)),
            }
        }
        // Ratio test: the largest step keeping the weights ≥ 0.
        let mut alpha_max = f64::INFINITY;
        let mut blocking = None;
        for (a, &i) in free.iter().enumerate() {
            if d[a] < 0.0 {
                let t = -omega[i] / d[a];
                if t < alpha_max {
                    alpha_max = t;
                    blocking = Some(i);
                }
            }
        }
        let mut alpha = alpha_max.min(1.0);
        let trial = |alpha: f64| {
            let mut w = omega.clone();
            for (a, &i) in free.iter().enumerate() {
                w[i] = (omega[i] + alpha * d[a]).max(0.0);
            }
            w
        };
        let mut accepted = None;
        for _ in 0..60 {
            let w = trial(alpha);
            if let Some(fw) = criterion_value(info, &w, criterion) {
                if fw <= f + 1e-4 * alpha * slope {
                    accepted = Some(w);
                    break;
                }
            }
            alpha *= 0.5;
        }
        let Some(mut w) = accepted else {
            // No decrease representable: a Newton step judged on the gradients, or the
            // current point is optimal to rounding.
            if let Some(w) = gradient_step(info, &omega, &free, &d, criterion, spread) {
                omega = w;
                continue;
            }
            return Ok((omega, iteration));
        };
        if alpha == alpha_max {
            if let Some(i) = blocking {
                w[i] = 0.0;
            }
        }
        for i in 0..k {
            if support[i] && w[i] <= 0.0 {
                w[i] = 0.0;
                support[i] = false;
            }
        }
        let sum: f64 = w.iter().sum();
        omega = w.into_iter().map(|v| v / sum).collect();
    }
    Ok((omega, 200))
}

/// The full Newton step `ω + d` on the support (when it stays inside the simplex), if its
/// gradients are closer to stationary — `max |gᵢ − mean g|` over the support smaller than
/// `spread` at the current point — else `None`.
fn gradient_step(
    info: &[DMatrix<f64>],
    omega: &[f64],
    free: &[usize],
    d: &DVector<f64>,
    criterion: Criterion,
    spread: f64,
) -> Option<Vec<f64>> {
    let mut w = omega.to_vec();
    for (a, &i) in free.iter().enumerate() {
        w[i] = omega[i] + d[a];
        if w[i] <= 0.0 {
            return None;
        }
    }
    let sum: f64 = w.iter().sum();
    let w: Vec<f64> = w.into_iter().map(|v| v / sum).collect();
    let (_, g, _) = evaluate(info, &w, criterion)?;
    let mean = free.iter().map(|&i| g[i]).sum::<f64>() / free.len() as f64;
    let new_spread = free
        .iter()
        .map(|&i| (g[i] - mean).abs())
        .fold(0.0, f64::max);
    (new_spread < spread).then_some(w)
}

#[cfg(test)]
#[allow(non_snake_case)]
mod tests {
    use super::*;
    use crate::fusion::ci::covariance_intersection;

    fn spd(seed: u64, n: usize) -> DMatrix<f64> {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        let g = DMatrix::from_fn(n, n, |_, _| rng.random_range(-1.0..1.0));
        &g * g.transpose() + DMatrix::identity(n, n) * 0.3
    }

    /// The Newton solver itself (not the two-estimate route) reproduces exact CI for k = 2.
    #[test]
    fn newton_on_two_estimates_matches_exact_ci() {
        for seed in 0..20 {
            for criterion in [Criterion::Trace, Criterion::Logdet] {
                let (P_a, P_b) = (spd(seed, 4), spd(seed + 100, 4));
                let info = vec![inverse(&P_a).unwrap(), inverse(&P_b).unwrap()];
                let (omega, _) = simplex_newton(&info, criterion).unwrap();
                let p = FusionProblem::from_covariances(P_a, P_b, CrossPattern::fully_unknown(4))
                    .unwrap();
                let ci = covariance_intersection(&p, criterion).unwrap();
                assert!(
                    (omega[0] - ci.omega).abs() < 1e-7,
                    "{seed}: {omega:?} vs {}",
                    ci.omega
                );
                let P = inverse(&weighted_sum(&info, &omega)).unwrap();
                let f = |P: &DMatrix<f64>| match criterion {
                    Criterion::Trace => P.trace(),
                    Criterion::Logdet => crate::linalg::logdet_spd(P),
                };
                assert!(
                    (f(&P) - ci.fused.criterion(criterion)).abs() <= 1e-12 * f(&P).abs().max(1.0)
                );
            }
        }
    }
}
