//! The exact conservativeness index (COIN) of the tracking study's estimators.
//!
//! Every covariance and every gain of the study is deterministic: Kalman covariances do not
//! depend on the measurements, and the CI, nmCI and ICI weights depend on covariances only.
//! So the *true* error covariance of each agent can be propagated exactly, without Monte
//! Carlo, next to the covariance the agent believes. Per model block (the errors of different
//! blocks are independent), keep the joint covariance `Σ` of the errors `eᵢ = x − x̂ᵢ` of all
//! `N` agents (`N m × N m` for a block of `m` states):
//!
//! - prior: every estimate starts at the prior mean, so `eᵢ = x` and `Σ = 𝟙𝟙ᵀ ⊗ P₀`;
//! - prediction: `eᵢ ← F eᵢ + w` with the *common* process noise `w`, so
//!   `Σ ← (I ⊗ F) Σ (I ⊗ F)ᵀ + 𝟙𝟙ᵀ ⊗ Q`;
//! - agent `i`'s scalar measurement `z = hᵀx + v` with gain `K`: `eᵢ ← (I − K hᵀ) eᵢ − K v`,
//!   `v` independent of everything else (rows and columns of agent `i` multiplied by
//!   `I − K hᵀ`, then `r K Kᵀ` added to its diagonal block);
//! - exchange: agent `a` fuses its neighbours' sent estimates one after the other,
//!   `e_a ← K_a e_a + K_b e_b`, so after the exchange `e_a = Σⱼ C_aj eⱼ` (pre-exchange errors)
//!   and `Σ ← C Σ Cᵀ`. The gains follow from the weights the rule chose: CI (and nmCI per
//!   block) `K_b = (1−ω) P P_b⁻¹`, naive `K_b = P P_b⁻¹`, ICI `K_b = P (P_b⁻¹ − (1−ω) Γ⁻¹)`
//!   with `Γ = ω P_a + (1−ω) P_b`.
//!
//! ## What is assumed (each is true of the study as coded, and each is needed)
//! - **Truth from the common prior, filters started at its mean.** Each run draws the truth
//!   from `N(0, P₀)` and starts every filter at `0`, so the initial errors are `eᵢ = x` for all
//!   agents and `E` is an expectation over truth *and* noise together (not conditional on a
//!   fixed truth).
//! - **Matched model.** The filters use the `F`, `Q`, `H`, `R` and `P₀` that generate the data.
//! - **`R` diagonal.** Each agent's measurements are applied as independent scalar updates
//!   (the study's [`Partition::update`]); a correlated `R` would need a whitening step here.
//! - **White, independent noises.** Process noise is shared by all agents (one truth), but is
//!   white over steps; measurement noises are white over steps and independent across agents,
//!   measurements and the process noise.
//! - **Gains independent of the data.** Kalman gains depend on covariances only, and CI, nmCI
//!   and ICI choose ω from covariances only, so every `C` above is deterministic and
//!   `Σ ← C Σ Cᵀ` is exact. (A rule whose weights depended on the means would break this.)
//! - **Pre-exchange copies.** Agents fuse the copies their neighbours sent before the
//!   exchange began; the schedule is [`super::partition::exchange`], the one the Monte Carlo runs
//!   use, so the two cannot drift apart.
//!
//! The agent's COIN is then `λ_max(L⁻¹ E L⁻ᵀ)` with `P = L Lᵀ` its covariance and `E` its
//! diagonal block of `Σ` ([`conservativeness_index`](crate::check::conservativeness_index)); both are
//! block-diagonal over the model blocks, so it is the largest block value. `≤ 1` means the agent's covariance bounds its
//! true error covariance (conservative); `> 1` means it is overconfident. The centralized
//! filter is the optimal Kalman filter of the model, so its `E` equals its `P` (COIN `= 1`):
//! computed the same way, it checks the propagation.

use nalgebra::{DMatrix, DVector};

use super::model::Model;
use super::partition::{exchange, fuse, BlockCovariance, Partition};
use super::{Estimator, SimError, Storage, StudyRule};
use crate::error::InputError;
use crate::fusion::check::coin_of;

/// The exact error covariances of one estimator of the study (the centralized filter or the
/// agents of one rule), advanced a step at a time as [`super::RunState`] advances a run.
#[allow(non_snake_case)]
pub struct ErrorPropagation {
    part: Partition,
    /// `None`: the centralized filter (one filter applying every agent's measurements).
    rule: Option<StudyRule>,
    neighbours: Vec<Vec<usize>>,
    /// The filters' covariances (means stay at zero: nothing here depends on them).
    filters: Vec<BlockCovariance>,
    /// Per model block, the joint covariance of all filters' errors (empty for a twin block).
    joint: Vec<DMatrix<f64>>,
    /// Per model block, an earlier block whose recursion is the same (equal transition, process
    /// noise, prior and, agent by agent, the same measurements in local coordinates — the
    /// x and y blocks of a group): its joint covariance is not propagated twice.
    twin: Vec<Option<usize>>,
    done: usize,
}

#[allow(non_snake_case)]
impl ErrorPropagation {
    /// Starts at the common prior: the centralized filter, or every agent of a rule.
    pub fn new(model: &Model, estimator: Estimator) -> Self {
        let rule = estimator.rule();
        let part = Partition::new(model, Storage::Blocks);
        let filters: Vec<BlockCovariance> = match rule {
            None => vec![part.prior(model)],
            Some(_) => (0..model.scenario.agents())
                .map(|_| part.prior(model))
                .collect(),
        };
        // Each agent's measurements of block k: (local row, variance).
        type Local = Vec<Vec<(Vec<(usize, f64)>, f64)>>;
        let local = |k: usize| -> Local {
            part.measurements
                .iter()
                .map(|ms| {
                    ms.iter()
                        .filter(|(b, _, _)| *b == k)
                        .map(|(_, row, r)| (row.clone(), *r))
                        .collect()
                })
                .collect()
        };
        let twin: Vec<Option<usize>> = (0..part.blocks.len())
            .map(|k| {
                (0..k).find(|&t| {
                    part.F[t] == part.F[k]
                        && part.Q[t] == part.Q[k]
                        && filters[0][t] == filters[0][k]
                        && local(t) == local(k)
                })
            })
            .collect();
        // Twin blocks keep no joint covariance of their own (empty): they read their source's.
        let count = filters.len();
        let joint = part
            .blocks
            .iter()
            .enumerate()
            .map(|(k, b)| {
                let m = if twin[k].is_some() { 0 } else { b.len() };
                let P0 = &filters[0][k];
                DMatrix::from_fn(count * m, count * m, |i, j| P0[(i % m, j % m)])
            })
            .collect();
        Self {
            part,
            rule,
            neighbours: model.scenario.neighbours(),
            filters,
            joint,
            twin,
            done: 0,
        }
    }

    /// Whether this follows the centralized filter (its only filter is `0`).
    pub fn is_central(&self) -> bool {
        self.rule.is_none()
    }

    /// Steps done.
    pub fn steps_done(&self) -> usize {
        self.done
    }

    /// One time step: prediction, every filter's measurements, and the rule's exchange.
    /// `model` must be the one the propagation was created with.
    pub fn step(&mut self, model: &Model) -> Result<(), SimError> {
        self.predict();
        self.measure(model.scenario.agents());
        if let Some(rule) = self.rule {
            self.exchange(model, rule)?;
        }
        // A twin block shares its source's joint covariance; that is exact only while every
        // filter's covariances of the two blocks are equal (same recursion, same operations:
        // bit for bit). Checked, never assumed.
        for (k, twin) in self.twin.iter().enumerate() {
            if let Some(t) = *twin {
                if self.filters.iter().any(|f| f[k] != f[t]) {
                    return Err(SimError::Diverged(format!(
                        "exact COIN: model blocks {t} and {k} no longer evolve identically"
                    )));
                }
            }
        }
        self.done += 1;
        Ok(())
    }

    fn predict(&mut self) {
        let count = self.filters.len();
        for (k, S) in self.joint.iter_mut().enumerate() {
            if self.twin[k].is_some() {
                continue;
            }
            // F's rows have at most two non-zeros: column operations.
            let (F, Q) = (&self.part.F[k], &self.part.Q[k]);
            let m = F.len();
            let right_multiply = |X: &DMatrix<f64>| {
                let mut Y = DMatrix::zeros(count * m, count * m);
                for j in 0..count {
                    for (r, row) in F.iter().enumerate() {
                        for &(l, f) in row {
                            Y.column_mut(j * m + r).axpy(f, &X.column(j * m + l), 1.0);
                        }
                    }
                }
                Y
            };
            // (I ⊗ F) Σ (I ⊗ F)ᵀ = Uᵀ (I ⊗ F)ᵀ with U = Σ (I ⊗ F)ᵀ (Σ symmetric).
            let U = right_multiply(S).transpose();
            *S = right_multiply(&U);
            for i in 0..count {
                for j in 0..count {
                    let mut view = S.view_mut((i * m, j * m), (m, m));
                    view += Q;
                }
            }
        }
        for f in &mut self.filters {
            self.part.predict(f);
        }
    }

    fn measure(&mut self, agents: usize) {
        for i in 0..self.filters.len() {
            let sources: Vec<usize> = match self.rule {
                None => (0..agents).collect(),
                Some(_) => vec![i],
            };
            for a in sources {
                for m_index in 0..self.part.measurements[a].len() {
                    let (b, row, r) = &self.part.measurements[a][m_index];
                    // The filter's own update, which returns its gain K = P h / (hᵀ P h + r).
                    let K = self.part.update(&mut self.filters[i], a, m_index);
                    if self.twin[*b].is_some() {
                        continue;
                    }
                    let m = K.len();
                    let S = &mut self.joint[*b];
                    // Rows of filter i: Σ[i, :] ← Σ[i, :] − K (hᵀ Σ[i, :]).
                    let hS: Vec<f64> = (0..S.ncols())
                        .map(|col| row.iter().map(|&(j, c)| c * S[(i * m + j, col)]).sum())
                        .collect();
                    for (col, &h) in hS.iter().enumerate() {
                        for l in 0..m {
                            S[(i * m + l, col)] -= K[l] * h;
                        }
                    }
                    // Columns of filter i: Σ[:, i] ← Σ[:, i] − (Σ[:, i] h) Kᵀ.
                    let mut Sh = DVector::zeros(S.nrows());
                    for &(j, c) in row {
                        Sh.axpy(c, &S.column(i * m + j), 1.0);
                    }
                    for l in 0..m {
                        let mut target = S.column_mut(i * m + l);
                        target.axpy(-K[l], &Sh, 1.0);
                    }
                    // Measurement noise: Σ[i, i] += r K Kᵀ.
                    let mut diag = S.view_mut((i * m, i * m), (m, m));
                    diag.ger(*r, &K, &K, 1.0);
                }
            }
        }
    }

    fn exchange(&mut self, model: &Model, rule: StudyRule) -> Result<(), SimError> {
        let count = self.filters.len();
        let blocks = self.part.blocks.len();
        // coefficients[a][k]: agent a's post-exchange error in block k as Σⱼ C_aj eⱼ
        // (`None` = the identity: most fusions keep or take whole blocks).
        let mut coefficients: Vec<Vec<Coefficients>> = (0..count)
            .map(|a| (0..blocks).map(|_| vec![(a, None)]).collect())
            .collect();
        let twin = &self.twin;
        let mut sent = Vec::with_capacity(count);
        exchange(
            &mut self.filters,
            &mut sent,
            &self.neighbours,
            |a, b, mine: &mut BlockCovariance, theirs: &BlockCovariance| {
                let coef = &mut coefficients[a];
                let before: Vec<DMatrix<f64>> = mine.clone();
                let (omega, _) = fuse(model, Storage::Blocks, rule, mine, theirs)?;
                for k in (0..blocks).filter(|&k| twin[k].is_none()) {
                    let gain = gain_b(rule, &omega, k, &before[k], &theirs[k], &mine[k])?;
                    match gain {
                        Gain::Keep => {}
                        Gain::Take => coef[k] = vec![(b, None)],
                        Gain::Mix(K_b) => {
                            let m = K_b.nrows();
                            let K_a = DMatrix::identity(m, m) - &K_b;
                            for (_, c) in coef[k].iter_mut() {
                                *c = Some(match c.take() {
                                    Some(c) => &K_a * c,
                                    None => K_a.clone(),
                                });
                            }
                            // A second entry for `b` (a repeated edge) is summed by
                            // `right_multiply` below, as a merged one would be.
                            coef[k].push((b, Some(K_b)));
                        }
                    }
                }
                Ok(())
            },
        )?;
        for (k, S) in self.joint.iter_mut().enumerate() {
            if self.twin[k].is_some() {
                continue;
            }
            let m = self.part.blocks[k].len();
            // Column operations only (contiguous in column-major storage), using symmetry:
            // U = Σ Cᵀ, then C Σ Cᵀ = C U = (Uᵀ Cᵀ)ᵀ = Uᵀ Cᵀ (symmetric).
            let right_multiply = |X: &DMatrix<f64>| {
                let mut Y = DMatrix::zeros(count * m, count * m);
                for (c, coef) in coefficients.iter().enumerate() {
                    for (l, C) in &coef[k] {
                        let mut target = Y.columns_mut(c * m, m);
                        match C {
                            None => target += X.columns(l * m, m),
                            Some(C) => target.gemm(1.0, &X.columns(l * m, m), &C.transpose(), 1.0),
                        }
                    }
                }
                Y
            };
            let U = right_multiply(S).transpose();
            *S = right_multiply(&U);
            crate::linalg::symmetrize_in_place(S);
        }
        Ok(())
    }

    /// Filter `i`'s covariance (agent `i` of the rule, or `0` for the centralized filter),
    /// per model block.
    pub fn covariance(&self, i: usize) -> Vec<DMatrix<f64>> {
        self.filters[i].clone()
    }

    /// Filter `i`'s true error covariance, per model block.
    pub fn error_covariance(&self, i: usize) -> Vec<DMatrix<f64>> {
        (0..self.joint.len())
            .map(|k| {
                let S = &self.joint[self.twin[k].unwrap_or(k)];
                let m = self.part.blocks[k].len();
                S.view((i * m, i * m), (m, m)).into_owned()
            })
            .collect()
    }

    /// Filter `i`'s COIN: the largest block value of `λ_max(L⁻¹ E L⁻ᵀ)`. Naive fusion double
    /// counts until its covariance is numerically singular; then, as for the study's NEES, the
    /// eigenvalues of `P` are floored at `λ_max(P) · ε` and the COIN is reported as the huge
    /// finite number it is, not as a failure.
    pub fn coin(&self, i: usize) -> f64 {
        self.covariance(i)
            .iter()
            .zip(self.error_covariance(i))
            .map(|(P, E)| coin_of(P, &E).unwrap_or_else(|_| floored_coin(P, &E)))
            .fold(f64::NEG_INFINITY, f64::max)
    }
}

/// `λ_max(D^{-1/2} Vᵀ E V D^{-1/2})` with `P = V D Vᵀ` and `D` floored at `λ_max(P) · ε`.
#[allow(non_snake_case)]
fn floored_coin(P: &DMatrix<f64>, E: &DMatrix<f64>) -> f64 {
    let eig = nalgebra::SymmetricEigen::new(P.clone());
    let floor = eig.eigenvalues.amax() * f64::EPSILON;
    let scale = eig.eigenvalues.map(|l| 1.0 / l.max(floor).sqrt());
    let mut W = eig.eigenvectors.transpose() * E * &eig.eigenvectors;
    for i in 0..W.nrows() {
        for j in 0..W.ncols() {
            W[(i, j)] *= scale[i] * scale[j];
        }
    }
    crate::linalg::max_eigenvalue(&W)
}

/// Agent `a`'s error after the exchange in one block: `Σⱼ C_aj eⱼ` (`None` = identity).
type Coefficients = Vec<(usize, Option<DMatrix<f64>>)>;

/// The gain on the sent estimate of one fusion in one block.
enum Gain {
    /// `K_b = 0`: the agent keeps its block.
    Keep,
    /// `K_b = I`: the agent takes the sent block.
    Take,
    /// Anything else.
    Mix(DMatrix<f64>),
}

/// The gain on the sent estimate of one fusion in block `k`, from the rule's weights, the
/// covariances before (`P_a`, `P_b`) and the fused covariance `P` (see the module docs).
#[allow(non_snake_case)]
fn gain_b(
    rule: StudyRule,
    omega: &[f64],
    k: usize,
    P_a: &DMatrix<f64>,
    P_b: &DMatrix<f64>,
    P: &DMatrix<f64>,
) -> Result<Gain, InputError> {
    let weight = match rule {
        StudyRule::Ci | StudyRule::Ici => omega.first().copied(),
        StudyRule::Nmci => omega.get(k).copied(),
        StudyRule::Naive => None,
    };
    // Endpoints exactly: CI/nmCI ω = 1 and ICI ω = 0 keep `a`; CI ω = 0 and ICI ω = 1 take `b`.
    match (rule, weight) {
        (StudyRule::Ci | StudyRule::Nmci, Some(1.0)) | (StudyRule::Ici, Some(0.0)) => {
            return Ok(Gain::Keep)
        }
        (StudyRule::Ci | StudyRule::Nmci, Some(0.0)) | (StudyRule::Ici, Some(1.0)) => {
            return Ok(Gain::Take)
        }
        _ => {}
    }
    // P P_b⁻¹ = (P_b⁻¹ P)ᵀ (both symmetric).
    let over_b = crate::linalg::cholesky(P_b)
        .ok_or_else(|| crate::fusion::definiteness_error("P_b", P_b))?
        .solve(P)
        .transpose();
    Ok(Gain::Mix(match (rule, weight) {
        (StudyRule::Naive, _) => over_b,
        (StudyRule::Ici, Some(w)) => {
            let Gamma = P_a * w + P_b * (1.0 - w);
            let over_gamma = crate::linalg::cholesky(&Gamma)
                .ok_or_else(|| InputError::Unfactored {
                    matrix: "Γ = ω P_a + (1−ω) P_b".into(),
                    inputs: "P_a and P_b".into(),
                })?
                .solve(P)
                .transpose();
            over_b - over_gamma * (1.0 - w)
        }
        (_, Some(w)) => over_b * (1.0 - w),
        (_, None) => {
            return Err(InputError::Estimates(format!(
                "fusion rule {} returned no weight for block {k}",
                rule.name()
            )))
        }
    }))
}

/// The COIN of `estimator` per step over `steps` steps: of the headline agent (`agent`,
/// 0-based) for a rule, of the one filter for the centralized one.
pub fn coin_series(
    model: &Model,
    steps: usize,
    agent: usize,
    estimator: Estimator,
) -> Result<Vec<f64>, SimError> {
    let mut propagation = ErrorPropagation::new(model, estimator);
    let filter = if estimator.rule().is_some() { agent } else { 0 };
    let mut series = Vec::with_capacity(steps);
    for _ in 0..steps {
        propagation.step(model)?;
        series.push(propagation.coin(filter));
    }
    Ok(series)
}

#[cfg(test)]
#[allow(non_snake_case)]
mod tests {
    use super::*;

    /// `λ_max` of a symmetric 2 × 2 matrix in closed form (independent of any eigensolver).
    fn lambda_max_2x2(a: f64, b: f64, c: f64) -> f64 {
        0.5 * (a + c) + (0.25 * (a - c).powi(2) + b * b).sqrt()
    }

    /// Where `P` is well conditioned nothing is floored, and the floored COIN is the COIN of
    /// [`coin_of`] (Cholesky and triangular solves: another computation).
    #[test]
    fn floored_coin_equals_the_coin_where_nothing_is_floored() {
        let P = DMatrix::from_row_slice(3, 3, &[4.0, 1.0, 0.5, 1.0, 3.0, 0.2, 0.5, 0.2, 2.0]);
        for E in [
            DMatrix::from_row_slice(3, 3, &[2.0, -0.3, 0.1, -0.3, 5.0, 1.0, 0.1, 1.0, 1.5]),
            DMatrix::from_row_slice(3, 3, &[0.5, 0.1, 0.0, 0.1, 0.2, 0.0, 0.0, 0.0, 0.1]),
        ] {
            let expected = coin_of(&P, &E).unwrap();
            let got = floored_coin(&P, &E);
            assert!(
                (got - expected).abs() <= 1e-13 * expected,
                "{got} vs {expected}"
            );
        }
    }

    /// A singular (and a slightly indefinite) `P`: its small eigenvalue is floored at
    /// `λ_max(P)·ε`, and the COIN is `λ_max(D^{-1/2} E D^{-1/2})` with `D = diag(4, 4ε)`,
    /// here in closed form. `P` is diagonal, so its eigen-decomposition is exact.
    #[test]
    fn floored_coin_floors_the_small_eigenvalues_of_a_singular_covariance() {
        let E = DMatrix::from_row_slice(2, 2, &[2.0, 1.0, 1.0, 3.0]);
        let (d1, d2) = (4.0, 4.0 * f64::EPSILON);
        let expected = lambda_max_2x2(2.0 / d1, 1.0 / (d1 * d2).sqrt(), 3.0 / d2);
        for small in [0.0, -1e-20, 1e-30] {
            let P = DMatrix::from_diagonal(&DVector::from_row_slice(&[4.0, small]));
            let got = floored_coin(&P, &E);
            assert!(
                (got - expected).abs() <= 1e-12 * expected,
                "P₂₂ = {small}: {got} vs {expected}"
            );
        }
    }
}
