//! The paper's multi-agent tracking scenario (Sec. "Simulation: Multi-Agent Multi-Target
//! Tracking"), with every value the paper omits stated here.

use serde::{Deserialize, Serialize};

/// Scenario parameters. Defaults: 4 groups × 4 agents, 5 targets per group, `dt = 0.1 s`,
/// `q = 0.05`, landmark variance 3, and the network that fits the paper best (rings plus the
/// bridges 4–7, 7–10, 7–11, 9–16, 12–13, 1-based agent ids: the best of `nmci sweep`, see
/// docs/reproduction.md; [`super::FIGURE_BRIDGES`] is the reading of the paper's figure).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Scenario {
    /// Number of agent groups.
    pub groups: usize,
    /// Agents per group (ring inside each group).
    pub agents_per_group: usize,
    /// Targets per group; the k-th agent of a group measures its group's targets k and k+1.
    pub targets_per_group: usize,
    /// Time step, seconds.
    pub dt: f64,
    /// Nearly-constant-velocity process noise intensity per axis.
    pub q: f64,
    /// Variance of each axis of the landmark measurement `m = s + w`.
    pub landmark_variance: f64,
    /// Prior variance of each target position coordinate (not given in the paper).
    pub prior_position_variance: f64,
    /// Prior variance of each target velocity coordinate (not given in the paper).
    pub prior_velocity_variance: f64,
    /// Prior variance of each bias coordinate (not given in the paper).
    pub prior_bias_variance: f64,
    /// Links between groups, 1-based agent ids (with a ring inside each group).
    pub bridges: Vec<(usize, usize)>,
    /// An explicit network instead of the rings and `bridges`: undirected links, 1-based
    /// agent ids (default empty: rings plus bridges). With `edges`, `bridges` must be `[]`;
    /// the network must be connected, without self-links or repeated links.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub edges: Vec<(usize, usize)>,
    /// Per-agent measured targets, 1-based (default empty: the `k`-th agent of a group
    /// measures its group's targets `k` and `k + 1`). One pair per agent when given.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub targets: Vec<[usize; 2]>,
}

impl Default for Scenario {
    fn default() -> Self {
        Self {
            groups: 4,
            agents_per_group: 4,
            targets_per_group: 5,
            dt: 0.1,
            q: 0.05,
            landmark_variance: 3.0,
            prior_position_variance: 10.0,
            prior_velocity_variance: 1.0,
            prior_bias_variance: 1.0,
            bridges: vec![(4, 7), (7, 10), (7, 11), (9, 16), (12, 13)],
            edges: Vec::new(),
            targets: Vec::new(),
        }
    }
}

/// One scalar measurement model row: `z = Σ coef·x[state] + v`, `v ~ N(0, variance)`.
#[derive(Debug, Clone, PartialEq)]
pub struct ScalarMeasurement {
    /// `(global state index, coefficient)` pairs.
    pub row: Vec<(usize, f64)>,
    /// Noise variance.
    pub variance: f64,
}

impl Scenario {
    /// Number of agents.
    pub fn agents(&self) -> usize {
        self.groups * self.agents_per_group
    }

    /// Number of targets.
    pub fn targets(&self) -> usize {
        self.groups * self.targets_per_group
    }

    /// State dimension: 4 per target (`x, ẋ, y, ẏ`) and 2 per agent bias (`b_x, b_y`).
    pub fn dim(&self) -> usize {
        4 * self.targets() + 2 * self.agents()
    }

    /// Index of coordinate `c` (0 `x`, 1 `ẋ`, 2 `y`, 3 `ẏ`) of target `t` (0-based).
    pub fn target_index(&self, t: usize, c: usize) -> usize {
        4 * t + c
    }

    /// Index of bias axis `axis` (0 `x`, 1 `y`) of agent `a` (0-based).
    pub fn bias_index(&self, a: usize, axis: usize) -> usize {
        4 * self.targets() + 2 * a + axis
    }

    /// Targets (0-based) agent `a` (0-based) measures: `targets[a]` when given, else its
    /// group's `k`-th and `k+1`-th.
    pub fn measured_targets(&self, a: usize) -> [usize; 2] {
        if let Some(&[t, u]) = self.targets.get(a) {
            return [t - 1, u - 1];
        }
        let (g, k) = (a / self.agents_per_group, a % self.agents_per_group);
        let first = g * self.targets_per_group + k;
        [first, first + 1]
    }

    /// Variance of agent `a`'s target measurements: `k` for the `k`-th agent (1-based) of its group.
    pub fn target_variance(&self, a: usize) -> f64 {
        (a % self.agents_per_group + 1) as f64
    }

    /// Agent `a`'s scalar measurements per step, per axis: each of its targets, then the landmark.
    pub fn measurements(&self, a: usize) -> Vec<ScalarMeasurement> {
        let mut out = Vec::new();
        for axis in 0..2 {
            for t in self.measured_targets(a) {
                out.push(ScalarMeasurement {
                    row: vec![
                        (self.target_index(t, 2 * axis), 1.0),
                        (self.bias_index(a, axis), 1.0),
                    ],
                    variance: self.target_variance(a),
                });
            }
            out.push(ScalarMeasurement {
                row: vec![(self.bias_index(a, axis), 1.0)],
                variance: self.landmark_variance,
            });
        }
        out
    }

    /// Undirected links (0-based, each as `(min, max)`): `edges` when given, else a ring inside
    /// each group plus the bridges.
    pub fn links(&self) -> Vec<(usize, usize)> {
        if !self.edges.is_empty() {
            return self
                .edges
                .iter()
                .map(|&(a, b)| ((a - 1).min(b - 1), (a - 1).max(b - 1)))
                .collect();
        }
        let m = self.agents_per_group;
        let mut links = Vec::new();
        for g in 0..self.groups {
            for k in 0..m {
                let (a, b) = (g * m + k, g * m + (k + 1) % m);
                if a != b && !links.contains(&(a.min(b), a.max(b))) {
                    links.push((a.min(b), a.max(b)));
                }
            }
        }
        for &(a, b) in &self.bridges {
            let (a, b) = (a - 1, b - 1);
            if !links.contains(&(a.min(b), a.max(b))) {
                links.push((a.min(b), a.max(b)));
            }
        }
        links
    }

    /// Neighbours of each agent, ascending.
    pub fn neighbours(&self) -> Vec<Vec<usize>> {
        let mut nb = vec![Vec::new(); self.agents()];
        for (a, b) in self.links() {
            nb[a].push(b);
            nb[b].push(a);
        }
        for v in &mut nb {
            v.sort_unstable();
        }
        nb
    }
}
