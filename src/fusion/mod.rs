//! Fusion rules for two estimates with partially known cross-covariance.

pub(crate) mod bracket;
pub(crate) mod certify;
pub(crate) mod check;
pub(crate) mod ci;
pub(crate) mod cuts;
pub(crate) mod ei;
pub(crate) mod ici;
pub(crate) mod known;
pub(crate) mod lower;
pub(crate) mod nmci;
pub(crate) mod nway;
pub(crate) mod program;
pub(crate) mod rules;
pub(crate) mod sample;
pub(crate) mod scale;
pub(crate) mod sdp;
pub(crate) mod semidefinite;
pub(crate) mod upper;
pub(crate) mod verify;

use nalgebra::{DMatrix, DVector};
use serde::{Deserialize, Serialize};

use crate::error::InputError;
use crate::linalg::{
    cholesky_of, first_non_finite, largest_abs, max_eigenvalue, min_eigenvalue, symmetrize,
    SYMMETRY_RTOL,
};
use crate::structure::CrossPattern;

/// What a fusion rule minimises over its weights.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Criterion {
    /// `tr P` (the paper's choice).
    #[default]
    Trace,
    /// `log det P` (volume of the covariance ellipsoid).
    Logdet,
}

/// Two estimates `(x_a, P_a)`, `(x_b, P_b)` and the pattern of their unknown cross-covariance,
/// validated: square, same size, finite, symmetric to a relative `1e-9`, positive definite.
///
/// Inputs are symmetrised (`(A + Aᵀ)/2`) after the check, so every rule sees exactly symmetric
/// matrices.
#[allow(non_snake_case)]
#[derive(Debug, Clone, PartialEq)]
pub struct FusionProblem {
    /// Estimate of agent `a`.
    pub x_a: DVector<f64>,
    /// Its error covariance.
    pub P_a: DMatrix<f64>,
    /// Estimate of agent `b`.
    pub x_b: DVector<f64>,
    /// Its error covariance.
    pub P_b: DMatrix<f64>,
    /// Which entries of `P_ab` may be non-zero.
    pub cross_pattern: CrossPattern,
}

/// Checks that `m` is `n × n` and finite (an error names it otherwise): what is asked of a
/// matrix given beside a problem of size `n` (a gain, a cross-covariance, a fused bound).
pub(crate) fn validate_square(name: &str, m: &DMatrix<f64>, n: usize) -> Result<(), InputError> {
    if m.nrows() != m.ncols() {
        return Err(InputError::NotSquare {
            name: name.into(),
            rows: m.nrows(),
            cols: m.ncols(),
        });
    }
    if m.nrows() != n {
        return Err(InputError::SizeMismatch {
            name: name.into(),
            found: m.nrows(),
            expected: n,
        });
    }
    if let Some((row, col)) = first_non_finite(m) {
        return Err(InputError::NotFinite {
            name: name.into(),
            row,
            col,
        });
    }
    Ok(())
}

/// Checks that `m` is non-empty, square, finite and symmetric to a relative
/// [`SYMMETRY_RTOL`] of its largest entry: what [`validate_covariance`] checks before
/// definiteness, and all that is asked of a matrix that need not be definite (the true error
/// covariance of a conservativeness index).
pub(crate) fn validate_symmetric(name: &str, m: &DMatrix<f64>) -> Result<(), InputError> {
    if m.nrows() == 0 {
        return Err(InputError::Empty { name: name.into() });
    }
    validate_square(name, m, m.nrows())?;
    let n = m.nrows();
    let scale = largest_abs(m);
    for i in 0..n {
        for j in i + 1..n {
            let (v, w) = (m[(i, j)], m[(j, i)]);
            if (v - w).abs() > SYMMETRY_RTOL * scale {
                return Err(InputError::NotSymmetric {
                    name: name.into(),
                    row: i,
                    col: j,
                    value: v,
                    mirror: w,
                });
            }
        }
    }
    Ok(())
}

/// Checks that `m` is a usable covariance: non-empty, square, finite, symmetric, positive definite.
///
/// Positive definite means: proven so for `(m + mᵀ)/2` by a verified Cholesky test (Rump,
/// BIT 2006; `fusion::verify`), or, for a matrix too close to singular for that proof, a
/// floating-point Cholesky factorization that completes and a positive computed smallest
/// eigenvalue (a numerical judgement at rounding level, not a proof). A matrix that fails
/// both but is proven positive definite once equilibrated by powers of two
/// (`scale::equilibrated`: variances of very different orders) is refused as
/// ill-conditioned, not as indefinite: the rules compute in floating point with it as given.
/// Any other refused matrix is called not positive definite only when a vector with
/// `vᵀ P v ≤ 0` is proven (`verify::is_not_positive_definite`, on it or its equilibrated form),
/// and singular to working precision otherwise: nmci's floating-point checks cannot decide it.
pub fn validate_covariance(name: &str, m: &DMatrix<f64>) -> Result<(), InputError> {
    symmetric_covariance(name, m).map(drop)
}

/// [`validate_covariance`]'s checks, and on success `(m + mᵀ)/2`, the matrix the rules use.
pub(crate) fn symmetric_covariance(
    name: &str,
    m: &DMatrix<f64>,
) -> Result<DMatrix<f64>, InputError> {
    validate_symmetric(name, m)?;
    let scale = largest_abs(m);
    let sym = symmetrize(m);
    // The common case in one factorization: proven positive definite by the verified
    // Cholesky test (`verify::is_positive_definite`). A matrix too close to singular for
    // that proof is judged as always: a floating-point Cholesky factorization and a positive
    // computed smallest eigenvalue, which also names the eigenvalue in the error.
    if verify::is_positive_definite(&sym) {
        return Ok(sym);
    }
    let lambda_min = min_eigenvalue(&sym);
    // An eigenvalue computation that overflowed (or a symmetrisation that did, above half the
    // largest float), or a matrix below the normal range, says nothing about definiteness:
    // name the range instead.
    if !lambda_min.is_finite() || (scale > 0.0 && scale < f64::MIN_POSITIVE) {
        return Err(InputError::OutOfRange {
            name: name.into(),
            largest: scale,
        });
    }
    if cholesky_of(sym.clone()).is_none() || lambda_min <= 0.0 {
        return Err(refusal(name, &sym, lambda_min));
    }
    Ok(sym)
}

/// Why the symmetric `sym` (smallest eigenvalue `lambda_min` as computed), not proven positive
/// definite as given, cannot be used as a covariance: the three refusals of
/// [`validate_covariance`], each said only when it is true.
fn refusal(name: &str, sym: &DMatrix<f64>, lambda_min: f64) -> InputError {
    // Variances of very different orders (mixed units) can make a positive definite matrix
    // look singular in floating point; the verified test on the matrix equilibrated by powers
    // of two (a congruence that keeps definiteness, `scale::equilibrated`) tells the two apart,
    // and the error says which it is.
    if scale::equilibrated(sym).is_some_and(|e| verify::is_positive_definite(&e)) {
        return InputError::IllConditioned {
            name: name.into(),
            min_eigenvalue: lambda_min,
            max_eigenvalue: max_eigenvalue(sym),
        };
    }
    // Indefinite (or singular) only when a vector with vᵀ P v ≤ 0 is proven, on the matrix or
    // on its equilibrated congruent form; otherwise these checks cannot decide, and the error
    // says that instead of a definiteness it cannot know.
    if verify::is_not_positive_definite(sym)
        || scale::equilibrated(sym).is_some_and(|e| verify::is_not_positive_definite(&e))
    {
        return InputError::NotPositiveDefinite {
            name: name.into(),
            min_eigenvalue: lambda_min,
        };
    }
    InputError::Singular {
        name: name.into(),
        min_eigenvalue: lambda_min,
        max_eigenvalue: max_eigenvalue(sym),
    }
}

/// The error for a covariance `m` (an input, or a covariance the filter or a rule computed)
/// whose Cholesky factorization failed inside a computation: the refusal
/// [`validate_covariance`] would give, so a matrix is called not positive definite only when
/// that is proven. A matrix that factors nonetheless (the failing factorization was of another
/// form of it) is named ill-conditioned: positive definite, but not usable in floating point
/// as given.
pub(crate) fn definiteness_error(name: &str, m: &DMatrix<f64>) -> InputError {
    let sym = symmetrize(m);
    let lambda_min = min_eigenvalue(&sym);
    let scale = largest_abs(m);
    if !lambda_min.is_finite() || !scale.is_finite() || (scale > 0.0 && scale < f64::MIN_POSITIVE) {
        return InputError::OutOfRange {
            name: name.into(),
            largest: scale,
        };
    }
    // Proven positive definite as given (only the factorization that failed was of another
    // form of it): ill-conditioned. `validate_covariance` has already asked this.
    if verify::is_positive_definite(&sym) {
        return InputError::IllConditioned {
            name: name.into(),
            min_eigenvalue: lambda_min,
            max_eigenvalue: max_eigenvalue(&sym),
        };
    }
    refusal(name, &sym, lambda_min)
}

pub(crate) fn validate_vector(name: &str, v: &DVector<f64>, n: usize) -> Result<(), InputError> {
    if v.len() != n {
        return Err(InputError::SizeMismatch {
            name: name.into(),
            found: v.len(),
            expected: n,
        });
    }
    if let Some(i) = v.iter().position(|x| !x.is_finite()) {
        return Err(InputError::NotFiniteElement {
            name: name.into(),
            index: i,
        });
    }
    Ok(())
}

#[allow(non_snake_case)]
impl FusionProblem {
    /// Validates and builds a problem.
    ///
    /// ```
    /// use nalgebra::{DMatrix, DVector};
    /// use nmci::{CrossPattern, FusionProblem};
    /// let p = FusionProblem::new(
    ///     DVector::zeros(2), DMatrix::from_diagonal(&DVector::from_vec(vec![3.0, 1.0])),
    ///     DVector::zeros(2), DMatrix::from_diagonal(&DVector::from_vec(vec![1.0, 4.0])),
    ///     CrossPattern::diagonal(2),
    /// ).unwrap();
    /// assert_eq!(p.dim(), 2);
    /// let bad = FusionProblem::new(
    ///     DVector::zeros(2), DMatrix::from_row_slice(2, 2, &[1.0, 2.0, 2.0, 1.0]),
    ///     DVector::zeros(2), DMatrix::identity(2, 2), CrossPattern::fully_unknown(2),
    /// );
    /// assert_eq!(bad.unwrap_err().to_string(),
    ///     "P_a is not positive definite (smallest eigenvalue -1.000000e0)");
    /// ```
    pub fn new(
        x_a: DVector<f64>,
        P_a: DMatrix<f64>,
        x_b: DVector<f64>,
        P_b: DMatrix<f64>,
        cross_pattern: CrossPattern,
    ) -> Result<Self, InputError> {
        let P_a = symmetric_covariance("P_a", &P_a)?;
        let n = P_a.nrows();
        if P_b.nrows() != n || P_b.ncols() != n {
            return Err(InputError::SizeMismatch {
                name: "P_b".into(),
                found: P_b.nrows().max(P_b.ncols()),
                expected: n,
            });
        }
        let P_b = symmetric_covariance("P_b", &P_b)?;
        validate_vector("x_a", &x_a, n)?;
        validate_vector("x_b", &x_b, n)?;
        if cross_pattern.dim() != n {
            return Err(InputError::SizeMismatch {
                name: "pab_unknown".into(),
                found: cross_pattern.dim(),
                expected: n,
            });
        }
        Ok(Self {
            x_a,
            P_a,
            x_b,
            P_b,
            cross_pattern,
        })
    }

    /// A problem from matrices the caller guarantees valid (symmetric, positive definite, sizes
    /// consistent): a filter's own estimates. Skips the eigenvalue check of [`FusionProblem::new`];
    /// the rules still fail with an [`InputError`] if a factorization breaks down.
    pub fn new_trusted(
        x_a: DVector<f64>,
        P_a: DMatrix<f64>,
        x_b: DVector<f64>,
        P_b: DMatrix<f64>,
        cross_pattern: CrossPattern,
    ) -> Self {
        Self {
            x_a,
            P_a,
            x_b,
            P_b,
            cross_pattern,
        }
    }

    /// A problem with zero means (only covariances matter for the bounds).
    pub fn from_covariances(
        P_a: DMatrix<f64>,
        P_b: DMatrix<f64>,
        cross_pattern: CrossPattern,
    ) -> Result<Self, InputError> {
        let n = P_a.nrows();
        Self::new(
            DVector::zeros(n),
            P_a,
            DVector::zeros(P_b.nrows()),
            P_b,
            cross_pattern,
        )
    }

    /// State dimension `n`.
    pub fn dim(&self) -> usize {
        self.P_a.nrows()
    }

    /// The sub-problem on the states `idx` (rows/columns of every matrix, entries of the vectors).
    pub fn restrict(&self, idx: &[usize]) -> Self {
        let k = idx.len();
        Self {
            x_a: DVector::from_fn(k, |i, _| self.x_a[idx[i]]),
            P_a: DMatrix::from_fn(k, k, |i, j| self.P_a[(idx[i], idx[j])]),
            x_b: DVector::from_fn(k, |i, _| self.x_b[idx[i]]),
            P_b: DMatrix::from_fn(k, k, |i, j| self.P_b[(idx[i], idx[j])]),
            cross_pattern: self.cross_pattern.restrict(idx),
        }
    }

    /// The joint covariance `[[P_a, P_ab], [P_abᵀ, P_b]]` for a given cross term.
    pub fn joint_covariance(&self, P_ab: &DMatrix<f64>) -> DMatrix<f64> {
        let n = self.dim();
        let mut joint = DMatrix::zeros(2 * n, 2 * n);
        joint.view_mut((0, 0), (n, n)).copy_from(&self.P_a);
        joint.view_mut((n, n), (n, n)).copy_from(&self.P_b);
        joint.view_mut((0, n), (n, n)).copy_from(P_ab);
        joint.view_mut((n, 0), (n, n)).copy_from(&P_ab.transpose());
        joint
    }
}

/// An estimate `(x, P)`: a mean and its error covariance — the one estimate type of the crate:
/// an input of N-way fusion ([`Estimate::new`] validates it). (The tracking study keeps its
/// covariances, shared by its runs, apart from each run's means: `MeanPlan`.)
#[allow(non_snake_case)]
#[derive(Debug, Clone, PartialEq)]
pub struct Estimate {
    /// Mean.
    pub x: DVector<f64>,
    /// Error covariance (symmetric positive definite).
    pub P: DMatrix<f64>,
}

#[allow(non_snake_case)]
impl Estimate {
    /// Validates `P` (square, finite, symmetric, positive definite) and `x` (its size, finite);
    /// `name` labels errors (e.g. `estimates[2]`).
    pub fn new(name: &str, x: DVector<f64>, P: DMatrix<f64>) -> Result<Self, InputError> {
        let P = symmetric_covariance(&format!("{name}.p"), &P)?;
        validate_vector(&format!("{name}.x"), &x, P.nrows())?;
        Ok(Self { x, P })
    }
}

/// For each block of two block-stored covariances, the first earlier block whose covariances
/// are equal to its own in *both* estimates (exactly), or `None`. Covariance recursions do not
/// depend on the data, so a symmetric model gives bitwise-equal blocks (the study's x and y
/// blocks of one group: same dynamics, same isotropic noises); twins have the same CI pencil,
/// the same `ω` and the same fused covariance, and only their means differ.
pub(crate) fn covariance_twins(a: &[DMatrix<f64>], b: &[DMatrix<f64>]) -> Vec<Option<usize>> {
    (0..a.len())
        .map(|k| {
            (0..k)
                .find(|&t| a[t].as_slice() == a[k].as_slice() && b[t].as_slice() == b[k].as_slice())
        })
        .collect()
}

/// How the block-stored in-place rules (`ci_in_place`, `nmci_in_place`, `ici_in_place`,
/// `naive_in_place`: the tracking study's fusions) fuse the *means*, decided by the
/// covariances alone. A fusion of block-stored estimates is split in two: the covariance side
/// updates the covariances and returns this plan; [`MeanPlan::apply`] then fuses any number of
/// mean pairs with it. The weights, pencils and factorizations depend on the covariances only,
/// so Monte Carlo runs that share their covariances (every run of the study: Kalman
/// covariances do not depend on the measurements) share one plan per fusion, and each run's
/// means are bit for bit what a fusion of that run alone gives (the same operations on the
/// same numbers).
#[derive(Default)]
pub(crate) struct MeanPlan {
    /// The CI/ICI pencils the blocks refer to.
    pencils: Vec<ci::Pencil>,
    /// Naive fusion's `(L, P_b)` with `P_a + P_b = L Lᵀ`.
    factors: Vec<(DMatrix<f64>, DMatrix<f64>)>,
    /// Explicit gains `(K_a, K_b)` (naive fusion's fallback, dense storage).
    gains: Vec<(DMatrix<f64>, DMatrix<f64>)>,
    /// One entry per block.
    blocks: Vec<BlockMean>,
}

/// How one block's mean is fused ([`MeanPlan`]).
#[derive(Debug, Clone, Copy, PartialEq)]
enum BlockMean {
    /// `x_a` stays.
    Keep,
    /// `x_a ← x_b`.
    Take,
    /// CI at an interior `ω` with pencil `pencil`.
    Ci { pencil: usize, omega: f64 },
    /// ICI at an interior `ω` with pencil `pencil`.
    Ici { pencil: usize, omega: f64 },
    /// Naive fusion with factor `factor`.
    Naive { factor: usize },
    /// `K_a x_a + K_b x_b` with gains `gains`.
    Gains { gains: usize },
}

#[allow(non_snake_case)]
impl MeanPlan {
    fn with_blocks(blocks: usize) -> Self {
        Self {
            blocks: Vec::with_capacity(blocks),
            ..Self::default()
        }
    }

    fn push_pencil(&mut self, pencil: ci::Pencil) -> usize {
        self.pencils.push(pencil);
        self.pencils.len() - 1
    }

    /// A plan fusing every block by explicit gains (one block: dense storage).
    pub(crate) fn from_gains(K_a: DMatrix<f64>, K_b: DMatrix<f64>) -> Self {
        Self {
            gains: vec![(K_a, K_b)],
            blocks: vec![BlockMean::Gains { gains: 0 }],
            ..Self::default()
        }
    }

    /// Fuses the means block by block: `a[k] ← fused(a[k], b[k])`.
    pub(crate) fn apply(&self, a: &mut [DVector<f64>], b: &[DVector<f64>]) {
        for ((x_a, x_b), how) in a.iter_mut().zip(b).zip(&self.blocks) {
            match *how {
                BlockMean::Keep => {}
                BlockMean::Take => x_a.clone_from(x_b),
                BlockMean::Ci { pencil, omega } => {
                    *x_a = self.pencils[pencil].fused_mean(x_a, x_b, omega);
                }
                BlockMean::Ici { pencil, omega } => {
                    *x_a = ici::fused_mean(&self.pencils[pencil], x_a, x_b, omega);
                }
                BlockMean::Naive { factor } => {
                    let (L, P_b) = &self.factors[factor];
                    *x_a = known::naive_mean(L, P_b, x_a, x_b);
                }
                BlockMean::Gains { gains } => {
                    let (K_a, K_b) = &self.gains[gains];
                    *x_a = K_a * &*x_a + K_b * x_b;
                }
            }
        }
    }
}

/// Test helper: a block-stored in-place rule on whole estimates — its covariance side, then
/// its [`MeanPlan`] on the means.
#[cfg(test)]
#[allow(non_snake_case)]
pub(crate) fn fuse_estimates<R>(
    a: &mut [Estimate],
    b: &[Estimate],
    rule: impl FnOnce(&mut [DMatrix<f64>], &[DMatrix<f64>]) -> Result<(R, MeanPlan), InputError>,
) -> Result<R, InputError> {
    let mut P_a: Vec<DMatrix<f64>> = a.iter().map(|e| e.P.clone()).collect();
    let P_b: Vec<DMatrix<f64>> = b.iter().map(|e| e.P.clone()).collect();
    let (result, plan) = rule(&mut P_a, &P_b)?;
    let mut x_a: Vec<DVector<f64>> = a.iter().map(|e| e.x.clone()).collect();
    let x_b: Vec<DVector<f64>> = b.iter().map(|e| e.x.clone()).collect();
    plan.apply(&mut x_a, &x_b);
    for ((e, x), P) in a.iter_mut().zip(x_a).zip(P_a) {
        e.x = x;
        e.P = P;
    }
    Ok(result)
}

/// The skeleton of every rule that solves each independent block on its own (nmCI, the
/// sampled SDP, the certified rule): for each block, `solve(block, sub)` gets the block's
/// states and the problem restricted to them (the problem itself when there is one block)
/// and returns the block's `(K_a, P)`; these are scattered into the whole, then
/// `K_b = I − K_a` and `x = K_a x_a + K_b x_b`. What else a rule reports per block (status,
/// iterations, bounds, ω) it gathers in `solve`.
#[allow(non_snake_case)]
pub(crate) fn per_block<E>(
    problem: &FusionProblem,
    blocks: &[Vec<usize>],
    mut solve: impl FnMut(&[usize], FusionProblem) -> Result<(DMatrix<f64>, DMatrix<f64>), E>,
) -> Result<Fused, E> {
    let n = problem.dim();
    let mut K_a = DMatrix::zeros(n, n);
    let mut P = DMatrix::zeros(n, n);
    for block in blocks {
        let sub = if blocks.len() == 1 {
            problem.clone()
        } else {
            problem.restrict(block)
        };
        let (K_a_block, P_block) = solve(block, sub)?;
        scatter_block(&mut K_a, block, &K_a_block);
        scatter_block(&mut P, block, &P_block);
    }
    let K_b = DMatrix::identity(n, n) - &K_a;
    let x = &K_a * &problem.x_a + &K_b * &problem.x_b;
    Ok(Fused { x, P, K_a, K_b })
}

/// Writes `part` into the rows and columns `block` of `whole` — the inverse of restricting
/// a matrix to `block`: how per-block results (nmCI, the split SDP, the certified rule,
/// N-way nmCI) are assembled.
pub(crate) fn scatter_block(whole: &mut DMatrix<f64>, block: &[usize], part: &DMatrix<f64>) {
    for (bj, &j) in block.iter().enumerate() {
        for (bi, &i) in block.iter().enumerate() {
            whole[(i, j)] = part[(bi, bj)];
        }
    }
}

/// The result of a linear fusion rule `x = K_a x_a + K_b x_b` with its covariance bound `P`.
#[allow(non_snake_case)]
#[derive(Debug, Clone, PartialEq)]
pub struct Fused {
    /// Fused estimate.
    pub x: DVector<f64>,
    /// Covariance bound `P̄` (symmetric).
    pub P: DMatrix<f64>,
    /// Gain on `x_a`.
    pub K_a: DMatrix<f64>,
    /// Gain on `x_b` (`K_a + K_b = I`).
    pub K_b: DMatrix<f64>,
}

#[allow(non_snake_case)]
impl Fused {
    /// `tr P`.
    pub fn trace(&self) -> f64 {
        self.P.trace()
    }

    /// `log det P`.
    pub fn logdet(&self) -> f64 {
        crate::linalg::logdet_spd(&self.P)
    }

    /// The value of a criterion at `P`.
    pub fn criterion(&self, criterion: Criterion) -> f64 {
        match criterion {
            Criterion::Trace => self.trace(),
            Criterion::Logdet => self.logdet(),
        }
    }
}
