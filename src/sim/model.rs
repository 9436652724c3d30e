//! The linear-Gaussian model of the scenario and its independence structure.

use nalgebra::{DMatrix, DVector};

use super::scenario::{ScalarMeasurement, Scenario};
use super::SimError;
use crate::structure::{independent_blocks, CrossPattern};

/// Dynamics, prior, measurements and the blocks the structure implies.
#[allow(non_snake_case)]
#[derive(Debug, Clone)]
pub struct Model {
    /// The scenario.
    pub scenario: Scenario,
    /// Transition matrix (nearly constant velocity per axis; biases constant).
    pub F: DMatrix<f64>,
    /// Process noise covariance.
    pub Q: DMatrix<f64>,
    /// Common prior covariance (the prior mean is zero).
    pub P0: DMatrix<f64>,
    /// Each agent's scalar measurements per step.
    pub measurements: Vec<Vec<ScalarMeasurement>>,
    /// The independent blocks, derived from which states the dynamics, the process noise and
    /// the measurements couple (not declared): 8 blocks of 14 for the default scenario.
    pub blocks: Vec<Vec<usize>>,
    /// Cross-covariance pattern between two agents' estimates: unknown within blocks, zero across.
    pub cross_pattern: CrossPattern,
}

#[allow(non_snake_case)]
impl Model {
    /// Builds the model of a (validated) scenario.
    pub fn new(scenario: &Scenario) -> Result<Self, SimError> {
        scenario.validate()?;
        let n = scenario.dim();
        let (dt, q) = (scenario.dt, scenario.q);
        let mut F = DMatrix::identity(n, n);
        let mut Q = DMatrix::zeros(n, n);
        let mut P0 = DMatrix::zeros(n, n);
        for t in 0..scenario.targets() {
            for axis in 0..2 {
                let (p, v) = (
                    scenario.target_index(t, 2 * axis),
                    scenario.target_index(t, 2 * axis + 1),
                );
                F[(p, v)] = dt;
                Q[(p, p)] = q * dt.powi(3) / 3.0;
                Q[(p, v)] = q * dt.powi(2) / 2.0;
                Q[(v, p)] = q * dt.powi(2) / 2.0;
                Q[(v, v)] = q * dt;
                P0[(p, p)] = scenario.prior_position_variance;
                P0[(v, v)] = scenario.prior_velocity_variance;
            }
        }
        for a in 0..scenario.agents() {
            for axis in 0..2 {
                let b = scenario.bias_index(a, axis);
                P0[(b, b)] = scenario.prior_bias_variance;
            }
        }
        let measurements: Vec<Vec<ScalarMeasurement>> = (0..scenario.agents())
            .map(|a| scenario.measurements(a))
            .collect();
        // Structure: which states can ever become correlated.
        let mut coupled = DMatrix::<f64>::identity(n, n);
        for i in 0..n {
            for j in 0..n {
                if F[(i, j)] != 0.0 || Q[(i, j)] != 0.0 || P0[(i, j)] != 0.0 {
                    coupled[(i, j)] = 1.0;
                    coupled[(j, i)] = 1.0;
                }
            }
        }
        for m in measurements.iter().flatten() {
            for &(i, _) in &m.row {
                for &(j, _) in &m.row {
                    coupled[(i, j)] = 1.0;
                }
            }
        }
        let blocks = independent_blocks(&coupled, &coupled, &CrossPattern::independent(n));
        let mut block_of = vec![0; n];
        for (b, block) in blocks.iter().enumerate() {
            for &i in block {
                block_of[i] = b;
            }
        }
        let cross_pattern = CrossPattern::from_fn(n, |i, j| block_of[i] == block_of[j]);
        Ok(Self {
            scenario: scenario.clone(),
            F,
            Q,
            P0,
            measurements,
            blocks,
            cross_pattern,
        })
    }

    /// State dimension.
    pub fn dim(&self) -> usize {
        self.F.nrows()
    }

    /// The zero prior mean.
    pub fn x0(&self) -> DVector<f64> {
        DVector::zeros(self.dim())
    }
}
