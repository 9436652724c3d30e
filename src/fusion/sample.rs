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
//!
//! [`SamplerKind::HitAndRun`] targets the same distribution — uniform on the admissible set in
//! the correlation coordinates `C` — without rejections, for any dimension: a coordinate
//! hit-and-run (Gibbs) chain. From an admissible `C` (the chain starts at `C = 0`), each step
//! picks the next free entry `(i, j)` and moves it to a uniform point of the chord of the
//! admissible set through `C` along that entry. With the joint correlation matrix `J ≻ 0`,
//! `J + t (e_i e_{n+j}ᵀ + e_{n+j} e_iᵀ) ≻ 0` exactly for `t ∈ (−1/λ₊, −1/λ₋)`, where
//! `λ± = G_{i,n+j} ± √(G_ii G_{n+j,n+j})` and `G = J⁻¹` (the rank-two update has these two
//! non-zero eigenvalues relative to `J`), so every step is O(n²) with `J⁻¹` kept by the
//! Woodbury identity and refreshed from a Cholesky factorization after every sweep over the
//! free entries. The uniform distribution on an open convex set is the chain's stationary
//! law and every admissible `C` is reachable, so the support is the whole admissible set;
//! samples are taken every `sweeps_per_sample` sweeps after `burn_in_sweeps`.
//!
//! [`SamplerKind::Auto`] picks one of the two per problem: a pilot of the rejection sampler
//! (its own generator, derived from the seed, at most [`AUTO_PILOT_TRIALS`] proposals)
//! estimates the acceptance rate `p̂`; the rejection sampler is used when the `count` samples
//! are expected to need at most a quarter of the trial budget (`count / p̂ ≤ max_trials / 4`,
//! with at least [`AUTO_MIN_ACCEPTED`] acceptances seen), hit-and-run otherwise — and also if
//! the chosen rejection sampler still runs out of budget. Both samplers have the same law, so
//! the choice changes how the samples are drawn, not what they are samples of; with a seed,
//! the samples are exactly those of the chosen sampler run alone with that seed (after a
//! fallback, hit-and-run continues the generator the rejection sampler left).

use nalgebra::{DMatrix, DVector};
use rand::Rng;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

use serde::{Deserialize, Serialize};

use super::FusionProblem;
use crate::error::SampleError;
use crate::linalg::cholesky;

/// Which sampler draws the admissible cross-covariances.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SamplerKind {
    /// The paper's rejection sampler (independent samples; dies with dimension).
    #[default]
    Rejection,
    /// Coordinate hit-and-run on the admissible set (no rejections; correlated samples).
    HitAndRun,
    /// The rejection sampler where its acceptance is workable, hit-and-run otherwise (decided
    /// by a pilot; see the module docs). [`CrossSamples::auto`] says what was chosen and why.
    Auto,
}

/// The pilot's largest number of rejection-sampler proposals ([`SamplerKind::Auto`]).
pub const AUTO_PILOT_TRIALS: u64 = 2000;
/// The fewest acceptances in the pilot for which [`SamplerKind::Auto`] trusts its estimate of
/// the acceptance rate enough to choose the rejection sampler.
pub const AUTO_MIN_ACCEPTED: u64 = 10;

/// The most samples one call draws: they are returned together, one matrix each.
pub const MAX_SAMPLE_COUNT: usize = 1_000_000;

/// The most entries (`count × n²`) one call returns: 8 bytes each, 0.8 GB at the limit. Draw
/// more in batches with different seeds.
pub const MAX_SAMPLE_ENTRIES: usize = 100_000_000;

/// `count` samples of an `n`-state problem within [`MAX_SAMPLE_COUNT`] and
/// [`MAX_SAMPLE_ENTRIES`], checked before anything is allocated.
fn check_count(problem: &FusionProblem, count: usize) -> Result<(), SampleError> {
    let n2 = problem.dim() * problem.dim();
    if count > MAX_SAMPLE_COUNT {
        return Err(SampleError::InvalidSettings(format!(
            "count {count} is above the limit of {MAX_SAMPLE_COUNT} samples per call; draw them in batches with different seeds"
        )));
    }
    match count.checked_mul(n2) {
        Some(entries) if entries <= MAX_SAMPLE_ENTRIES => Ok(()),
        _ => Err(SampleError::InvalidSettings(format!(
            "count × n² = {count} × {n2} entries is above the limit of {MAX_SAMPLE_ENTRIES} per call; draw them in batches with different seeds"
        ))),
    }
}

/// What [`SamplerKind::Auto`] chose, and the pilot it chose by.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct AutoChoice {
    /// The sampler that drew the samples ([`SamplerKind::Rejection`] or
    /// [`SamplerKind::HitAndRun`]).
    pub kind: SamplerKind,
    /// The pilot's proposals.
    pub pilot_trials: u64,
    /// The pilot's acceptances.
    pub pilot_accepted: u64,
    /// Whether the rejection sampler was chosen but ran out of budget, so hit-and-run drew
    /// the samples.
    pub fell_back: bool,
}

/// Settings of the samplers.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SamplerSettings {
    /// Which sampler (default: the paper's rejection sampler).
    pub kind: SamplerKind,
    /// Rejection: total proposals allowed before giving up (default `2·10⁶`).
    pub max_trials: u64,
    /// Hit-and-run: sweeps over the free entries between two samples (default 1).
    pub sweeps_per_sample: usize,
    /// Hit-and-run: sweeps discarded before the first sample (default 50).
    pub burn_in_sweeps: usize,
}

impl Default for SamplerSettings {
    fn default() -> Self {
        Self {
            kind: SamplerKind::Rejection,
            max_trials: 2_000_000,
            sweeps_per_sample: 1,
            burn_in_sweeps: 50,
        }
    }
}

impl SamplerSettings {
    /// The default rejection sampler with a trial budget.
    pub fn rejection(max_trials: u64) -> Self {
        Self {
            max_trials,
            ..Self::default()
        }
    }

    /// The default hit-and-run sampler.
    pub fn hit_and_run() -> Self {
        Self {
            kind: SamplerKind::HitAndRun,
            ..Self::default()
        }
    }

    /// Checks the settings.
    pub fn validate(&self) -> Result<(), SampleError> {
        if self.max_trials == 0 {
            return Err(SampleError::InvalidSettings(
                "max_trials must be at least 1".into(),
            ));
        }
        if self.sweeps_per_sample == 0 {
            return Err(SampleError::InvalidSettings(
                "sweeps_per_sample must be at least 1".into(),
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
    /// Rejection: proposals drawn to get them. Hit-and-run: chain steps (burn-in included;
    /// every step is accepted).
    pub trials: u64,
    /// With [`SamplerKind::Auto`]: the sampler chosen and why (`None` otherwise).
    pub auto: Option<AutoChoice>,
}

impl CrossSamples {
    /// Samples / trials: the rejection sampler's acceptance rate, or the hit-and-run chain's
    /// samples per step.
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
/// use nmci::{CrossPattern, FusionProblem, sample::{SamplerSettings, sample_cross_covariances}};
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
    check_count(problem, count)?;
    if settings.kind == SamplerKind::Auto {
        settings.validate()?;
        let mut pilot_rng = ChaCha8Rng::seed_from_u64(pilot_seed(seed));
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        return auto(problem, count, &mut pilot_rng, &mut rng, settings);
    }
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    sample_cross_covariances_with(problem, count, &mut rng, settings)
}

/// The pilot's seed for a sampler seed: a fixed odd offset (the golden ratio's bits), so the
/// pilot's proposals are not the chosen sampler's first ones.
fn pilot_seed(seed: u64) -> u64 {
    seed.wrapping_add(0x9E37_79B9_7F4A_7C15)
}

/// [`SamplerKind::Auto`]: the pilot from `pilot_rng`, then the chosen sampler from `rng` (see
/// the module docs).
fn auto<P: Rng, R: Rng>(
    problem: &FusionProblem,
    count: usize,
    pilot_rng: &mut P,
    rng: &mut R,
    settings: SamplerSettings,
) -> Result<CrossSamples, SampleError> {
    let (pilot_trials, pilot_accepted) = pilot(problem, count, pilot_rng, settings.max_trials);
    let workable = workable(count, pilot_trials, pilot_accepted, settings.max_trials);
    let mut choice = AutoChoice {
        kind: SamplerKind::HitAndRun,
        pilot_trials,
        pilot_accepted,
        fell_back: false,
    };
    if workable {
        match rejection(problem, count, rng, settings.max_trials) {
            Ok(drawn) => {
                choice.kind = SamplerKind::Rejection;
                return Ok(CrossSamples {
                    auto: Some(choice),
                    ..drawn
                });
            }
            Err(SampleError::BudgetExhausted { .. }) => choice.fell_back = true,
            Err(e) => return Err(e),
        }
    }
    let drawn = hit_and_run(problem, count, rng, settings)?;
    Ok(CrossSamples {
        auto: Some(choice),
        ..drawn
    })
}

/// Whether `accepted` of `trials` proposals make the rejection sampler workable for `count`
/// samples: at least [`AUTO_MIN_ACCEPTED`] acceptances and an expected `count · trials /
/// accepted` trials within a quarter of `max_trials` (integer arithmetic, exact).
fn workable(count: usize, trials: u64, accepted: u64, max_trials: u64) -> bool {
    accepted >= AUTO_MIN_ACCEPTED
        && (count as u128) * (trials as u128) * 4 <= (accepted as u128) * (max_trials as u128)
}

/// The pilot of [`SamplerKind::Auto`]: rejection-sampler proposals until the acceptance seen
/// makes the rejection sampler [`workable`], or [`AUTO_PILOT_TRIALS`] (at most the budget) are
/// spent. Returns `(trials, accepted)`.
fn pilot<R: Rng>(
    problem: &FusionProblem,
    count: usize,
    rng: &mut R,
    max_trials: u64,
) -> (u64, u64) {
    let n = problem.dim();
    let (mut joint, _, _, free) = correlation_frame(problem);
    let limit = AUTO_PILOT_TRIALS.min(max_trials);
    let (mut trials, mut accepted) = (0_u64, 0_u64);
    while trials < limit {
        trials += 1;
        if propose(&mut joint, &free, n, rng) {
            accepted += 1;
            if workable(count, trials, accepted, max_trials) {
                break;
            }
        }
    }
    (trials, accepted)
}

/// As [`sample_cross_covariances`], drawing from a caller's generator. With
/// [`SamplerKind::Auto`] the pilot's generator is seeded by one draw from it first, so the
/// samples are not those of the chosen sampler run alone on the same generator (they are with
/// [`sample_cross_covariances`] and a seed).
#[allow(non_snake_case)]
pub fn sample_cross_covariances_with<R: Rng>(
    problem: &FusionProblem,
    count: usize,
    rng: &mut R,
    settings: SamplerSettings,
) -> Result<CrossSamples, SampleError> {
    check_count(problem, count)?;
    settings.validate()?;
    match settings.kind {
        SamplerKind::HitAndRun => hit_and_run(problem, count, rng, settings),
        SamplerKind::Auto => {
            // The pilot's generator is seeded from the caller's, which then draws the samples.
            let mut pilot_rng = ChaCha8Rng::seed_from_u64(rng.random());
            auto(problem, count, &mut pilot_rng, rng, settings)
        }
        SamplerKind::Rejection => rejection(problem, count, rng, settings.max_trials),
    }
}

/// The paper's rejection sampler (see the module docs), within `max_trials` proposals.
#[allow(non_snake_case)]
fn rejection<R: Rng>(
    problem: &FusionProblem,
    count: usize,
    rng: &mut R,
    max_trials: u64,
) -> Result<CrossSamples, SampleError> {
    let n = problem.dim();
    let (mut joint, d_a, d_b, free) = correlation_frame(problem);
    let mut cross = Vec::with_capacity(count);
    let mut trials = 0_u64;
    while cross.len() < count {
        if trials >= max_trials {
            return Err(SampleError::BudgetExhausted {
                accepted: cross.len(),
                requested: count,
                trials,
                rate: cross.len() as f64 / trials as f64,
            });
        }
        trials += 1;
        if propose(&mut joint, &free, n, rng) {
            let P_ab = DMatrix::from_fn(n, n, |i, j| joint[(i, n + j)] * d_a[i] * d_b[j]);
            cross.push(P_ab);
        }
    }
    Ok(CrossSamples {
        cross,
        trials,
        auto: None,
    })
}

/// One proposal of the rejection sampler: the free entries of the correlation cross term of
/// `joint` drawn uniformly from `[−1, 1]`; whether `joint` is then positive definite.
fn propose<R: Rng>(
    joint: &mut DMatrix<f64>,
    free: &[(usize, usize)],
    n: usize,
    rng: &mut R,
) -> bool {
    for &(i, j) in free {
        let c: f64 = rng.random_range(-1.0..=1.0);
        joint[(i, n + j)] = c;
        joint[(n + j, i)] = c;
    }
    cholesky(joint).is_some()
}

/// The joint correlation matrix `[[R_a, 0], [0, R_b]]`, the scales `D_a`, `D_b` and the free
/// entries `(i, j)` of `C`.
#[allow(clippy::type_complexity)]
fn correlation_frame(
    problem: &FusionProblem,
) -> (
    DMatrix<f64>,
    DVector<f64>,
    DVector<f64>,
    Vec<(usize, usize)>,
) {
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
    let free = (0..n)
        .flat_map(|i| (0..n).map(move |j| (i, j)))
        .filter(|&(i, j)| problem.cross_pattern.is_unknown(i, j))
        .collect();
    (joint, d_a, d_b, free)
}

/// `J⁻¹` of a positive definite joint correlation matrix.
fn inverse(joint: &DMatrix<f64>) -> Result<DMatrix<f64>, SampleError> {
    cholesky(joint).map(|c| c.inverse()).ok_or_else(|| {
        SampleError::NumericalBreakdown(
            "the hit-and-run chain left the positive definite set (rounding at the boundary)"
                .into(),
        )
    })
}

/// Coordinate hit-and-run on the admissible correlation cross terms (see the module docs).
#[allow(non_snake_case)]
fn hit_and_run<R: Rng>(
    problem: &FusionProblem,
    count: usize,
    rng: &mut R,
    settings: SamplerSettings,
) -> Result<CrossSamples, SampleError> {
    let n = problem.dim();
    let (mut J, d_a, d_b, free) = correlation_frame(problem);
    let sample = |J: &DMatrix<f64>| DMatrix::from_fn(n, n, |i, j| J[(i, n + j)] * d_a[i] * d_b[j]);
    if free.is_empty() {
        // The admissible set is the single point P_ab = 0.
        return Ok(CrossSamples {
            cross: vec![DMatrix::zeros(n, n); count],
            trials: 0,
            auto: None,
        });
    }
    let mut G = inverse(&J)?;
    let mut cross = Vec::with_capacity(count);
    let mut trials = 0_u64;
    let mut sweep = 0_usize;
    let m = 2 * n;
    while cross.len() < count {
        for &(i, j) in &free {
            let (p, q) = (i, n + j);
            let (g_pp, g_qq, g_pq) = (G[(p, p)], G[(q, q)], G[(p, q)]);
            let root = (g_pp * g_qq).sqrt();
            // Chord: 1 + t λ > 0 for λ± = g_pq ± √(g_pp g_qq) (λ₊ > 0 > λ₋).
            let (lo, hi) = (-1.0 / (g_pq + root), -1.0 / (g_pq - root));
            trials += 1;
            if !(lo < 0.0 && hi > 0.0 && lo.is_finite() && hi.is_finite()) {
                return Err(SampleError::NumericalBreakdown(format!(
                    "degenerate chord ({lo}, {hi}) for entry ({i}, {j})"
                )));
            }
            let t: f64 = rng.random_range(lo..hi);
            if t == lo || t == 0.0 {
                continue; // measure zero: stay (the chord endpoint itself is not admissible)
            }
            J[(p, q)] += t;
            J[(q, p)] += t;
            // Woodbury: (J + U T Uᵀ)⁻¹ = G − G U (T⁻¹ + Uᵀ G U)⁻¹ Uᵀ G with U = [e_p e_q],
            // T = t [[0, 1], [1, 0]], T⁻¹ = [[0, 1], [1, 0]] / t.
            let (a, b, d) = (g_pp, g_pq + 1.0 / t, g_qq);
            let det = a * d - b * b;
            let (s11, s12, s22) = (d / det, -b / det, a / det); // (T⁻¹ + UᵀGU)⁻¹
            let gp: Vec<f64> = (0..m).map(|k| G[(k, p)]).collect();
            let gq: Vec<f64> = (0..m).map(|k| G[(k, q)]).collect();
            for c in 0..m {
                let (wp, wq) = (s11 * gp[c] + s12 * gq[c], s12 * gp[c] + s22 * gq[c]);
                for r in 0..m {
                    G[(r, c)] -= gp[r] * wp + gq[r] * wq;
                }
            }
        }
        // Refresh J⁻¹ exactly once per sweep (no drift of the rank-two updates).
        G = inverse(&J)?;
        sweep += 1;
        if sweep > settings.burn_in_sweeps
            && (sweep - settings.burn_in_sweeps) % settings.sweeps_per_sample == 0
        {
            cross.push(sample(&J));
        }
    }
    Ok(CrossSamples {
        cross,
        trials,
        auto: None,
    })
}
