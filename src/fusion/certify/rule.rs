//! The certified rule's entry points and results: [`certified_fusion`], [`certified_fusion_memo`],
//! [`certify_gain`], per independent block.

use nalgebra::DMatrix;
use serde::{Deserialize, Serialize};

use crate::error::SolveError;
use crate::fusion::program::SdpStatus;
use crate::fusion::scale::largest_variance;
use crate::fusion::{per_block, Fused, FusionProblem};
use crate::structure::independent_blocks;

use super::block::certify_one_block;
use super::memo::CertificateMemo;
use super::settings::CertifySettings;

/// The certified rule's certificate on each independent block.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Certificates {
    /// The certificate level per block (JSON `levels`).
    pub levels: Vec<u32>,
    /// The number of sectors (two states) or cones (three states) per block, 0 for one
    /// certificate for every direction (JSON `sectors`).
    pub sectors: Vec<u32>,
}

impl Certificates {
    /// The certificates of a computed certified rule.
    pub fn of(cert: &CertifiedResult) -> Self {
        Certificates {
            levels: cert.levels.clone(),
            sectors: cert.sectors.clone(),
        }
    }
}

/// A certified conservative bound (see the module docs).
#[derive(Debug, Clone, PartialEq)]
pub struct CertifiedResult {
    /// Fused estimate, the certified bound `P̄ = Q` and the gains.
    pub fused: Fused,
    /// How the (last) solve ended; `AlmostSolved` if any block's did.
    pub status: SdpStatus,
    /// Interior-point iterations, summed over blocks.
    pub iterations: u32,
    /// Trace added by the floating-point repair (≥ 0, summed over blocks).
    pub repair: f64,
    /// The independent blocks certified separately.
    pub blocks: Vec<Vec<usize>>,
    /// The level used on each block: the requested one, or a lower one where the solver
    /// broke down numerically on it (1 on a block certified by sectors, and on a block whose
    /// cross block is wholly unknown: CI's certificate, no solve).
    pub levels: Vec<u32>,
    /// The number of sectors or cones used on each block (0: one certificate for every direction).
    pub sectors: Vec<u32>,
    /// Per block: whether CI's proven bound (for the block's CI gain, or for the given gain
    /// with its best `ω`) was taken — without a solve where the block's cross block is wholly
    /// unknown (CI is the robust optimum there), or because it was tighter than the solver's
    /// certificate: the solver can end looser than CI where CI is optimal (`AlmostSolved` at
    /// high levels), or fail at every level (then the block's `status` is `AlmostSolved`).
    pub ci_blocks: Vec<bool>,
}

/// The tightest certified bound over gain and certificate: a conservative fusion rule never
/// looser than CI or nmCI in trace (up to solver tolerance).
///
/// ```
/// use nalgebra::{DMatrix, DVector};
/// use nmci::prelude::*;
/// let d = |v: &[f64]| DMatrix::from_diagonal(&DVector::from_row_slice(v));
/// let p = FusionProblem::from_covariances(d(&[3.0, 1.0]), d(&[1.0, 4.0]),
///     CrossPattern::diagonal(2)).unwrap();
/// let cert = certified_fusion(&p, &CertifySettings::default()).unwrap();
/// assert!((cert.fused.trace() - 2.0).abs() < 1e-6); // nmCI's diag(1, 1), proven
/// ```
pub fn certified_fusion(
    problem: &FusionProblem,
    settings: &CertifySettings,
) -> Result<CertifiedResult, SolveError> {
    certify(problem, None, settings, None)
}

/// [`certified_fusion`] with the blocks certified before taken from `memo` (and those
/// certified now added to it): the same result, bit for bit (see [`CertificateMemo`]).
///
/// ```
/// use nalgebra::{DMatrix, DVector};
/// use nmci::prelude::*;
/// use nmci::certify::{certified_fusion_memo, CertificateMemo};
/// let d = |v: &[f64]| DMatrix::from_diagonal(&DVector::from_row_slice(v));
/// let p = FusionProblem::from_covariances(d(&[3.0, 1.0]), d(&[1.0, 4.0]),
///     CrossPattern::diagonal(2)).unwrap();
/// let mut memo = CertificateMemo::new();
/// let settings = CertifySettings::default();
/// let first = certified_fusion_memo(&p, &settings, &mut memo).unwrap();
/// let again = certified_fusion_memo(&p, &settings, &mut memo).unwrap();
/// assert_eq!(first, again);
/// assert_eq!(first, certified_fusion(&p, &settings).unwrap());
/// assert_eq!(memo.hits(), 2); // two independent 1-state blocks, each certified once
/// ```
pub fn certified_fusion_memo(
    problem: &FusionProblem,
    settings: &CertifySettings,
    memo: &mut CertificateMemo,
) -> Result<CertifiedResult, SolveError> {
    certify(problem, None, settings, Some(memo))
}

/// The tightest certified bound for a given gain `K_a` (`K_b = I − K_a`), e.g. the sampled
/// SDP's: `P̄` with `P̄ ⪰ K P' Kᵀ` proven for every admissible `P'`.
///
/// ```
/// use nalgebra::{DMatrix, DVector};
/// use nmci::prelude::*;
/// use nmci::certify::certify_gain;
/// let d = |v: &[f64]| DMatrix::from_diagonal(&DVector::from_row_slice(v));
/// let p = FusionProblem::from_covariances(d(&[3.0, 1.0]), d(&[1.0, 4.0]),
///     CrossPattern::diagonal(2)).unwrap();
/// // The gain of nmCI with ω = [0, 1]: x_b's first state, x_a's second.
/// let cert = certify_gain(&p, &d(&[0.0, 1.0]), &CertifySettings::default()).unwrap();
/// assert!((&cert.fused.P - d(&[1.0, 1.0])).amax() < 1e-6);
/// ```
#[allow(non_snake_case)]
pub fn certify_gain(
    problem: &FusionProblem,
    K_a: &DMatrix<f64>,
    settings: &CertifySettings,
) -> Result<CertifiedResult, SolveError> {
    let n = problem.dim();
    if K_a.nrows() != n || K_a.ncols() != n || K_a.iter().any(|k| !k.is_finite()) {
        return Err(SolveError::InvalidSettings(format!(
            "the gain must be a finite {n}×{n} matrix (got {}×{})",
            K_a.nrows(),
            K_a.ncols()
        )));
    }
    certify(problem, Some(K_a), settings, None)
}

/// The blocks a certificate is computed on: the independent blocks, or the whole state when
/// a given gain mixes them.
#[allow(non_snake_case)]
pub(crate) fn certification_blocks(
    problem: &FusionProblem,
    gain: Option<&DMatrix<f64>>,
) -> Vec<Vec<usize>> {
    let n = problem.dim();
    let blocks = independent_blocks(&problem.P_a, &problem.P_b, &problem.cross_pattern);
    if let Some(K_a) = gain {
        let mut block_of = vec![0; n];
        for (b, block) in blocks.iter().enumerate() {
            for &i in block {
                block_of[i] = b;
            }
        }
        let mixes =
            (0..n).any(|i| (0..n).any(|j| block_of[i] != block_of[j] && K_a[(i, j)] != 0.0));
        if mixes {
            return vec![(0..n).collect()];
        }
    }
    blocks
}

#[allow(non_snake_case)]
pub(super) fn certify(
    problem: &FusionProblem,
    gain: Option<&DMatrix<f64>>,
    settings: &CertifySettings,
    mut memo: Option<&mut CertificateMemo>,
) -> Result<CertifiedResult, SolveError> {
    settings.validate()?;
    let blocks = certification_blocks(problem, gain);
    for block in &blocks {
        if block.len() > settings.max_block_dim {
            return Err(SolveError::BlockTooLarge {
                dim: block.len(),
                limit: settings.max_block_dim,
            });
        }
        let level = settings.family_for(block.len()).level();
        let cone = CertifySettings::cone_size(block.len(), level);
        if cone > settings.max_cone {
            return Err(SolveError::ConeTooLarge {
                dim: block.len(),
                level,
                cone,
                limit: settings.max_cone,
            });
        }
    }
    let (mut status, mut iterations, mut repair) = (SdpStatus::Solved, 0, 0.0);
    let mut levels = Vec::with_capacity(blocks.len());
    let mut sectors = Vec::with_capacity(blocks.len());
    let mut ci_blocks = Vec::with_capacity(blocks.len());
    let fused = per_block(problem, &blocks, |block, sub| {
        let sub_gain = gain
            .map(|K| DMatrix::from_fn(block.len(), block.len(), |i, j| K[(block[i], block[j])]));
        let outcome = match (&mut memo, &sub_gain) {
            (Some(memo), None) => memo.get_or_certify(&sub, settings)?,
            _ => certify_one_block(&sub, sub_gain.as_ref(), settings)?,
        };
        if outcome.P.iter().any(|v| !v.is_finite()) {
            return Err(SolveError::Overflow {
                what: "certified bound".into(),
                largest: largest_variance(&sub),
            });
        }
        ci_blocks.push(outcome.ci_used);
        if outcome.status == SdpStatus::AlmostSolved {
            status = SdpStatus::AlmostSolved;
        }
        iterations += outcome.iterations;
        repair += outcome.repair;
        levels.push(outcome.level);
        sectors.push(outcome.sectors);
        Ok::<_, SolveError>((outcome.K_a, outcome.P))
    })?;
    Ok(CertifiedResult {
        fused,
        status,
        iterations,
        repair,
        blocks,
        levels,
        sectors,
        ci_blocks,
    })
}
