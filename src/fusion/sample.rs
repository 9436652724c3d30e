//! Rejection sampler of admissible cross-covariances (the paper's Sec. "Approximately
//! Optimal Fusion Gains and Bounds").
//!
//! The admissible set is `U = {P_ab : [[P_a, P_ab], [P_abᵀ, P_b]] ≻ 0, P_ab[i,j] = 0 for (i,j) ∈ I}`.
//! As `U` is unbounded in covariance units, the sampler works with correlations: with
//! `D_a = diag(P_a)^½`, `D_b = diag(P_b)^½`, `R_a = D_a⁻¹ P_a D_a⁻¹`, `R_b = D_b⁻¹ P_b D_b⁻¹`,
//! (i) every free entry of the correlation cross term `C` is drawn uniformly from `[−1, 1]`,
//! (ii) `C` is accepted when `[[R_a, C], [Cᵀ, R_b]] ≻ 0` (a Cholesky factorization succeeds),
//! (iii) `P_ab = D_a C D_b`. Every accepted sample is admissible and every admissible `P_ab`
//! has positive density. Acceptance collapses with the number of free entries (≈ 4·10⁻⁴ at
//! `n = 4` with a fully unknown `P_ab`), so the sampler stops with a clear error after a trial
//! budget instead of looping forever.

use nalgebra::{DMatrix, DVector};
use rand::Rng;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

use super::FusionProblem;
use crate::error::SampleError;

/// Settings of the rejection sampler.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SamplerSettings {
    /// Total proposals allowed before giving up (default `2·10⁶`).
    pub max_trials: u64,
}

impl Default for SamplerSettings {
    fn default() -> Self {
        Self {
            max_trials: 2_000_000,
        }
    }
}

impl SamplerSettings {
    /// Checks the settings.
    pub fn validate(&self) -> Result<(), SampleError> {
        if self.max_trials == 0 {
            return Err(SampleError::InvalidSettings(
                "max_trials must be at least 1".into(),
            ));
        }
        Ok(())
    }
}

/// A set of admissible cross-covariances `P_ab'` with the sampler's bookkeeping.
#[allow(non_snake_case)]
#[derive(Debug, Clone, PartialEq)]
pub struct CrossSamples {
    /// The accepted cross-covariances `P_ab'` (each `n × n`).
    pub cross: Vec<DMatrix<f64>>,
    /// Proposals drawn to get them.
    pub trials: u64,
}

impl CrossSamples {
    /// Accepted / proposed.
    pub fn acceptance_rate(&self) -> f64 {
        if self.trials == 0 {
            1.0
        } else {
            self.cross.len() as f64 / self.trials as f64
        }
    }

    /// Number of samples.
    pub fn len(&self) -> usize {
        self.cross.len()
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.cross.is_empty()
    }
}

/// Draws `count` admissible cross-covariances for `problem` with a `ChaCha8Rng` seeded by `seed`.
///
/// ```
/// use nalgebra::{DMatrix, DVector};
/// use nmci::{sample_cross_covariances, CrossPattern, FusionProblem, SamplerSettings};
/// let d = |v: &[f64]| DMatrix::from_diagonal(&DVector::from_row_slice(v));
/// let p = FusionProblem::from_covariances(d(&[3.0, 1.0]), d(&[1.0, 4.0]),
///     CrossPattern::diagonal(2)).unwrap();
/// let s = sample_cross_covariances(&p, 10, 7, SamplerSettings::default()).unwrap();
/// assert_eq!(s.len(), 10);
/// assert_eq!(s.cross[0][(0, 1)], 0.0); // known zeros stay zero
/// ```
pub fn sample_cross_covariances(
    problem: &FusionProblem,
    count: usize,
    seed: u64,
    settings: SamplerSettings,
) -> Result<CrossSamples, SampleError> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    sample_cross_covariances_with(problem, count, &mut rng, settings)
}

/// As [`sample_cross_covariances`], drawing from a caller's generator.
#[allow(non_snake_case)]
pub fn sample_cross_covariances_with<R: Rng>(
    problem: &FusionProblem,
    count: usize,
    rng: &mut R,
    settings: SamplerSettings,
) -> Result<CrossSamples, SampleError> {
    settings.validate()?;
    let n = problem.dim();
    let d_a = DVector::from_iterator(n, problem.P_a.diagonal().iter().map(|v| v.sqrt()));
    let d_b = DVector::from_iterator(n, problem.P_b.diagonal().iter().map(|v| v.sqrt()));
    let mut joint = DMatrix::<f64>::zeros(2 * n, 2 * n);
    for i in 0..n {
        for j in 0..n {
            joint[(i, j)] = problem.P_a[(i, j)] / (d_a[i] * d_a[j]);
            joint[(n + i, n + j)] = problem.P_b[(i, j)] / (d_b[i] * d_b[j]);
        }
    }
    let free: Vec<(usize, usize)> = (0..n)
        .flat_map(|i| (0..n).map(move |j| (i, j)))
        .filter(|&(i, j)| problem.cross_pattern.is_unknown(i, j))
        .collect();
    let mut cross = Vec::with_capacity(count);
    let mut trials = 0_u64;
    while cross.len() < count {
        if trials >= settings.max_trials {
            return Err(SampleError::BudgetExhausted {
                accepted: cross.len(),
                requested: count,
                trials,
                rate: cross.len() as f64 / trials as f64,
            });
        }
        trials += 1;
        for &(i, j) in &free {
            let c: f64 = rng.random_range(-1.0..=1.0);
            joint[(i, n + j)] = c;
            joint[(n + j, i)] = c;
        }
        if nalgebra::Cholesky::new(joint.clone()).is_some() {
            let P_ab = DMatrix::from_fn(n, n, |i, j| joint[(i, n + j)] * d_a[i] * d_b[j]);
            cross.push(P_ab);
        }
    }
    Ok(CrossSamples { cross, trials })
}
