//! The model restricted to its independent blocks, the agents' exchange schedule and the
//! fusion of one exchange, per block.

use nalgebra::{DMatrix, DVector};

use super::estimators::{Storage, StudyRule};
use super::model::Model;
use super::SimError;
use crate::fusion::ci::{ci_in_place, covariance_intersection, nmci_in_place};
use crate::fusion::ici::{ici_in_place, inverse_covariance_intersection};
use crate::fusion::known::{naive_fusion, naive_in_place};
use crate::fusion::nmci::non_monolithic_ci;
use crate::fusion::{Criterion, FusionProblem, MeanPlan};
use crate::linalg::symmetrize_in_place;

/// The covariance side of a filter state stored in blocks: one covariance per storage block.
/// Kalman and fusion covariances do not depend on the data, so the runs of a study share it
/// ([`RunBatch`]); each run keeps only its means ([`BlockMeans`]).
pub(super) type BlockCovariance = Vec<DMatrix<f64>>;

/// The mean side of a filter state stored in blocks: one mean per storage block.
pub(super) type BlockMeans = Vec<DVector<f64>>;

/// One scalar measurement in block coordinates: `(block, local sparse row, noise variance)`.
pub(super) type LocalMeasurement = (usize, Vec<(usize, f64)>, f64);

/// Per-block restrictions of the model.
#[allow(non_snake_case)]
pub(super) struct Partition {
    pub(super) blocks: Vec<Vec<usize>>,
    /// The non-zeros of each block's transition matrix, row by row: `F[k][i] = [(j, F_ij)]`
    /// (at most two per row for nearly-constant-velocity targets and constant biases, so the
    /// prediction `F P Fᵀ` is O(n²) instead of two dense products).
    pub(super) F: Vec<Vec<Vec<(usize, f64)>>>,
    pub(super) Q: Vec<DMatrix<f64>>,
    /// For each agent: `(block, local row, variance)` per scalar measurement.
    pub(super) measurements: Vec<Vec<LocalMeasurement>>,
    /// Local indices of the target position coordinates in each block.
    pub(super) positions: Vec<Vec<usize>>,
    /// The target group (`target / targets_per_group`) of each of those coordinates.
    pub(super) position_groups: Vec<Vec<usize>>,
}

#[allow(non_snake_case)]
impl Partition {
    pub(super) fn new(model: &Model, storage: Storage) -> Self {
        let blocks = match storage {
            Storage::Blocks => model.blocks.clone(),
            Storage::Dense => vec![(0..model.dim()).collect()],
        };
        let mut where_ = vec![(0, 0); model.dim()];
        for (b, block) in blocks.iter().enumerate() {
            for (k, &i) in block.iter().enumerate() {
                where_[i] = (b, k);
            }
        }
        let restrict = |m: &DMatrix<f64>, b: &[usize]| {
            DMatrix::from_fn(b.len(), b.len(), |i, j| m[(b[i], b[j])])
        };
        let measurements = model
            .measurements
            .iter()
            .map(|ms| {
                ms.iter()
                    .map(|m| {
                        let block = where_[m.row[0].0].0;
                        let local = m.row.iter().map(|&(i, c)| (where_[i].1, c)).collect();
                        (block, local, m.variance)
                    })
                    .collect()
            })
            .collect();
        let sc = &model.scenario;
        let is_position: Vec<bool> = (0..model.dim())
            .map(|i| i < 4 * sc.targets() && i % 2 == 0)
            .collect();
        let positions: Vec<Vec<usize>> = blocks
            .iter()
            .map(|b| (0..b.len()).filter(|&k| is_position[b[k]]).collect())
            .collect();
        let position_groups = blocks
            .iter()
            .zip(&positions)
            .map(|(b, p)| p.iter().map(|&k| b[k] / 4 / sc.targets_per_group).collect())
            .collect();
        Self {
            positions,
            position_groups,
            F: blocks
                .iter()
                .map(|b| {
                    let f = restrict(&model.F, b);
                    (0..b.len())
                        .map(|i| {
                            (0..b.len())
                                .filter(|&j| f[(i, j)] != 0.0)
                                .map(|j| (j, f[(i, j)]))
                                .collect()
                        })
                        .collect()
                })
                .collect(),
            Q: blocks.iter().map(|b| restrict(&model.Q, b)).collect(),
            measurements,
            blocks,
        }
    }

    /// The common prior's covariance, block by block (its mean is zero).
    pub(super) fn prior(&self, model: &Model) -> BlockCovariance {
        self.blocks
            .iter()
            .map(|b| DMatrix::from_fn(b.len(), b.len(), |i, j| model.P0[(b[i], b[j])]))
            .collect()
    }

    /// The common prior's mean (zero), block by block.
    pub(super) fn prior_mean(&self) -> BlockMeans {
        self.blocks
            .iter()
            .map(|b| DVector::zeros(b.len()))
            .collect()
    }

    /// The mean 2σ of the position coordinates: `2·√(mean of P_ii)` over every target's `x`
    /// and `y` (blocks in order, positions in order within a block). Depends on `P` only.
    pub(super) fn two_sigma(&self, e: &[DMatrix<f64>]) -> f64 {
        let mut var = 0.0;
        let mut count = 0usize;
        for (k, P) in e.iter().enumerate() {
            for &i in &self.positions[k] {
                var += P[(i, i)];
                count += 1;
            }
        }
        2.0 * (var / count as f64).sqrt()
    }

    /// `P ← F P Fᵀ + Q` block by block, with the sparse rows of `F`.
    pub(super) fn predict(&self, e: &mut [DMatrix<f64>]) {
        for (k, P) in e.iter_mut().enumerate() {
            let F = &self.F[k];
            let n = P.nrows();
            // FP = F P (row i of FP combines the rows of P that row i of F names) …
            let mut FP = DMatrix::<f64>::zeros(n, n);
            for (i, row) in F.iter().enumerate() {
                for &(l, f) in row {
                    for j in 0..n {
                        FP[(i, j)] += f * P[(l, j)];
                    }
                }
            }
            // … then P = FP Fᵀ + Q (column j of the result combines the columns of FP that row
            // j of F names).
            let mut next = self.Q[k].clone();
            for (j, row) in F.iter().enumerate() {
                for &(l, f) in row {
                    for i in 0..n {
                        next[(i, j)] += f * FP[(i, l)];
                    }
                }
            }
            *P = next;
        }
    }

    /// `x ← F x` block by block (the mean side of [`Partition::predict`]).
    pub(super) fn predict_mean(&self, x: &mut [DVector<f64>]) {
        for (k, g) in x.iter_mut().enumerate() {
            let F = &self.F[k];
            *g = DVector::from_fn(g.len(), |i, _| F[i].iter().map(|&(j, f)| f * g[j]).sum());
        }
    }

    /// Joseph-form scalar update of the covariance with agent `a`'s measurement `m`:
    /// `P ← (I − K hᵀ) P (I − K hᵀ)ᵀ + r K Kᵀ`, evaluated exactly through its rank-one factors
    /// (`(I − K hᵀ) P = P − K (P h)ᵀ`, then `Y (I − h Kᵀ) = Y − (Y h) Kᵀ`): O(n²) instead of
    /// two dense products. Returns the gain `K` (of the measurement's block), which the means
    /// take ([`Partition::update_mean`]) and the exact COIN propagation applies to the joint
    /// error covariance.
    pub(super) fn update(&self, e: &mut [DMatrix<f64>], a: usize, m: usize) -> DVector<f64> {
        let (b, row, r) = &self.measurements[a][m];
        let P = &mut e[*b];
        let sparse_dot = |v: &DMatrix<f64>, col: usize| -> f64 {
            row.iter().map(|&(i, c)| c * v[(col, i)]).sum()
        };
        let n = P.nrows();
        // P h (P symmetric: row `i` of P dotted with h).
        let Ph = DVector::from_fn(n, |i, _| sparse_dot(P, i));
        let s = row.iter().map(|&(i, c)| c * Ph[i]).sum::<f64>() + r;
        let K = Ph.unscale(s);
        P.ger(-1.0, &K, &Ph, 1.0); // Y = (I − K hᵀ) P
        let Yh = DVector::from_fn(n, |i, _| sparse_dot(P, i));
        P.ger(-1.0, &Yh, &K, 1.0); // Y (I − h Kᵀ)
        P.ger(*r, &K, &K, 1.0);
        symmetrize_in_place(P);
        K
    }

    /// The mean side of [`Partition::update`]: `x ← x + K (z − hᵀx)` with its gain `K`.
    pub(super) fn update_mean(
        &self,
        x: &mut [DVector<f64>],
        a: usize,
        m: usize,
        z: f64,
        K: &DVector<f64>,
    ) {
        let (b, row, _) = &self.measurements[a][m];
        let x = &mut x[*b];
        let innovation = z - row.iter().map(|&(i, c)| c * x[i]).sum::<f64>();
        x.axpy(innovation, K, 1.0);
    }
}

/// The study's exchange schedule, in one place (the Monte Carlo runs, the exact COIN and the
/// covariance-only sweep all call it, so a change of schedule cannot make them drift): every
/// agent sends a copy of its current estimate (after its own prediction and update) to all
/// its neighbours at once; then each agent, in ascending id, fuses what it received one
/// neighbour at a time, in ascending neighbour id: `fuse_one(a, b, estimate of a, copy sent
/// by b)`. `sent` is a reused buffer.
pub(super) fn exchange<E: Clone>(
    agents: &mut [E],
    sent: &mut Vec<E>,
    neighbours: &[Vec<usize>],
    mut fuse_one: impl FnMut(usize, usize, &mut E, &E) -> Result<(), SimError>,
) -> Result<(), SimError> {
    sent.truncate(agents.len());
    for (k, estimate) in agents.iter().enumerate() {
        match sent.get_mut(k) {
            Some(copy) => copy.clone_from(estimate),
            None => sent.push(estimate.clone()),
        }
    }
    for (a, mine) in agents.iter_mut().enumerate() {
        for &b in &neighbours[a] {
            fuse_one(a, b, mine, &sent[b])?;
        }
    }
    Ok(())
}

/// Fuses the covariances of `b` into those of `a` with `rule`; returns the weights used (CI:
/// one; nmCI: one per model block) and the plan that fuses the means ([`MeanPlan`]).
pub(super) fn fuse(
    model: &Model,
    storage: Storage,
    rule: StudyRule,
    a: &mut [DMatrix<f64>],
    b: &[DMatrix<f64>],
) -> Result<(Vec<f64>, MeanPlan), SimError> {
    match storage {
        Storage::Blocks => Ok(match rule {
            StudyRule::Ci => {
                let (omega, plan) = ci_in_place(a, b, Criterion::Trace)?;
                (vec![omega], plan)
            }
            StudyRule::Nmci => nmci_in_place(a, b, Criterion::Trace)?,
            StudyRule::Naive => (vec![], naive_in_place(a, b)),
            StudyRule::Ici => {
                let (omega, plan) = ici_in_place(a, b, Criterion::Trace)?;
                (vec![omega], plan)
            }
        }),
        Storage::Dense => {
            // The generic dense rules; the means follow from their gains,
            // `x = K_a x_a + K_b x_b`, as the rules compute it.
            let n = a[0].nrows();
            let p = FusionProblem::new_trusted(
                DVector::zeros(n),
                a[0].clone(),
                DVector::zeros(n),
                b[0].clone(),
                model.cross_pattern.clone(),
            );
            let (fused, omega) = match rule {
                StudyRule::Ci => {
                    let ci = covariance_intersection(&p, Criterion::Trace)?;
                    (ci.fused, vec![ci.omega])
                }
                StudyRule::Nmci => {
                    let nm = non_monolithic_ci(&p, Criterion::Trace)?;
                    (nm.fused, nm.omega)
                }
                StudyRule::Naive => (naive_fusion(&p), vec![]),
                StudyRule::Ici => {
                    let ici = inverse_covariance_intersection(&p, Criterion::Trace)?;
                    (ici.fused, vec![ici.omega])
                }
            };
            a[0] = fused.P;
            Ok((omega, MeanPlan::from_gains(fused.K_a, fused.K_b)))
        }
    }
}
