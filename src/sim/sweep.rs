//! Which network did the paper simulate? A sweep over the networks its text allows.
//!
//! The paper's network figure is not in its source, and the text says only: 16 agents in 4
//! groups of 4, an "undirected and cyclic network topology"; for groups 1–2 "information must
//! pass through 7 before reaching 11" and for groups 3–4 "some data flows from agent 11 before
//! reaching 7". The three bridges 4–7, 7–11, 12–13 read from the figure make 7–11 the only
//! link between agents 1–8 and 9–16, which contradicts the second sentence (agent 7 would hear
//! of groups 3–4 only through 11) and forces nmCI's ω to exactly 0 there. So we enumerate.
//!
//! ## The text's conditions ([`check_text`])
//! A network fits the text when (agent ids 1-based, as in the paper):
//! 1. it has 4 groups of 4 agents and a ring inside each group (`1-2-3-4-1`, …);
//! 2. agents 7 and 11 are linked (the paper plots their fusion);
//! 3. *every* path from an agent of groups 1–2 to agent 11 passes through agent 7: in the
//!    network without agent 7, no agent of 1–8 reaches 11;
//! 4. at least one route from groups 3–4 to agent 7 avoids agent 11: in the network without
//!    agent 11, agent 7 reaches some agent of 9–16.
//!
//! Agent 7 being more central than agent 11 (as in the figure's reading) follows from 1–4
//! with the network connected (which every scenario must be), so it is not checked
//! separately. With `D` the hop distance and `S_v = Σ_x D(v, x)`: by 3 every path from `x ∈ {1..8} ∖ {7}` to 11 passes through 7, so
//! `D(11, x) = 1 + D(7, x)`; for `x ∈ {9..16} ∖ {11}`, `D(7, x) ≤ 1 + D(11, x)`. Both sets have 7
//! agents, so `S_11 − S_7 = 7 + Σ_{x ∈ {9..16}∖{11}} (D(11, x) − D(7, x)) ≥ 0`, and it is `> 0` as
//! soon as one `x` there has `D(7, x) < 1 + D(11, x)`. By 4 a path from 7 to some `y ∈ {9..16}`
//! avoids 11; let `z` be its vertex after 7. If `z ∈ {9..16}`, `D(7, z) = 1 < 1 + D(11, z)`. If
//! `z ∈ {1..8}`, the rest of the path joins `z` to `y` without 7, so by 3 `y` cannot reach 11
//! without 7 and `D(11, y) = 1 + D(7, y)`. Either way `S_7 < S_11`: agent 7 is strictly more
//! central (closeness). A test checks it on every network the sweep enumerates.
//!
//! ## The families enumerated ([`NetworkFamily`])
//! The rings are fixed; the sweep chooses the links between groups. [`NetworkFamily::Bridges`] keeps
//! the three bridges read from the figure and adds up to `extra` more links between groups;
//! [`NetworkFamily::Links`] takes 7–11 and any `count − 1` further links between groups. Every
//! candidate is checked against the conditions; the ones that pass are evaluated.
//!
//! ## What is computed, and why it is exact without Monte Carlo
//! Kalman covariances do not depend on the measurements, and CI and nmCI choose ω from the
//! covariances only; so ω of every fusion and every agent's covariance — hence the mean 2σ —
//! are deterministic. [`CovarianceRun`] runs the study's recursion on covariances alone (the
//! same [`Partition`] prediction and Joseph update, the same exchange schedule
//! [`super::partition::exchange`], the same fusion code): its ω and 2σ are bit for bit those of
//! every Monte Carlo run of the same network (tested). The RMSE does depend on the data; it is
//! estimated by the study's Monte Carlo runs for the short list only.
//!
//! ## Distance to the paper
//! With `r = 1 − nmCI/CI` the reductions of the mean RMSE and 2σ, and steady-state ω (mean over
//! the last half of the steps, as in the study's report):
//! `d = |ω_CI − 0.87| + mean_{blocks of groups 1–2} |ω − 1|
//!    + mean_{blocks of groups 3–4} dist(ω, [0.59, 0.70]) + |r_2σ − 0.40| (+ |r_RMSE − 0.33|)`,
//! each term a difference of fractions, so equally weighted. The RMSE term is added for the
//! short list; the sweep ranks every network by the covariance-only terms, runs the Monte
//! Carlo for the best `short_list`, and ranks those by the full distance.

use serde::{Deserialize, Serialize};
use thiserror::Error;

use super::model::Model;
use super::partition::{exchange, fuse, BlockCovariance, Partition};
use super::{Scenario, SimError, Storage, StudyConfig, StudyRule};

/// The paper's steady-state CI ω of agent 7 fusing agent 11.
pub const PAPER_OMEGA_CI: f64 = 0.87;
/// The paper's range of nmCI's ω on the blocks of groups 3–4 (1 on groups 1–2).
pub const PAPER_OMEGA_NMCI_FAR: [f64; 2] = [0.59, 0.70];
/// The paper's reduction of the mean RMSE, nmCI against CI.
pub const PAPER_RMSE_REDUCTION: f64 = 0.33;
/// The paper's reduction of the mean 2σ, nmCI against CI.
pub const PAPER_TWO_SIGMA_REDUCTION: f64 = 0.40;

/// Why a network does not fit the paper's text (agent ids 1-based).
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum TextMismatch {
    /// Condition 1: the paper has 4 groups of 4 agents.
    #[error("the paper's network has 4 groups of 4 agents (this one: {groups} of {per_group})")]
    NotFourGroupsOfFour {
        /// Groups.
        groups: usize,
        /// Agents per group.
        per_group: usize,
    },
    /// Condition 1: each group is a ring.
    #[error("group {group} is not a ring: link {a}–{b} is missing")]
    NoRing {
        /// The group (1-based).
        group: usize,
        /// One end of the missing link.
        a: usize,
        /// The other end.
        b: usize,
    },
    /// Condition 2: the paper plots the fusion of agent 11's estimate by agent 7.
    #[error("agents 7 and 11 are not linked")]
    No7To11,
    /// Condition 3: information from groups 1–2 must pass through 7 before reaching 11.
    #[error("agent {agent} reaches agent 11 without passing through agent 7")]
    Bypasses7 {
        /// The agent of groups 1–2 with a path to 11 avoiding 7.
        agent: usize,
    },
    /// Condition 4: some data from groups 3–4 reaches 7 without passing through 11.
    #[error("no agent of groups 3–4 reaches agent 7 without passing through agent 11")]
    OnlyThrough11,
}

/// Checks a (validated, connected) scenario's network against the paper's text (module docs).
pub fn check_text(scenario: &Scenario) -> Result<(), TextMismatch> {
    let (groups, per_group) = (scenario.groups, scenario.agents_per_group);
    if (groups, per_group) != (4, 4) {
        return Err(TextMismatch::NotFourGroupsOfFour { groups, per_group });
    }
    let nb = scenario.neighbours();
    for g in 0..4 {
        for k in 0..4 {
            let (a, b) = (4 * g + k, 4 * g + (k + 1) % 4);
            if !nb[a].contains(&b) {
                return Err(TextMismatch::NoRing {
                    group: g + 1,
                    a: a + 1,
                    b: b + 1,
                });
            }
        }
    }
    let (seven, eleven) = (6, 10);
    if !nb[seven].contains(&eleven) {
        return Err(TextMismatch::No7To11);
    }
    if let Some(agent) = (0..8).find(|&a| a != seven && reachable(&nb, a, seven)[eleven]) {
        return Err(TextMismatch::Bypasses7 { agent: agent + 1 });
    }
    if !reachable(&nb, seven, eleven)[8..].iter().any(|&r| r) {
        return Err(TextMismatch::OnlyThrough11);
    }
    Ok(())
}

/// The agents reachable from `from` in the network without agent `removed`.
fn reachable(nb: &[Vec<usize>], from: usize, removed: usize) -> Vec<bool> {
    let mut seen = vec![false; nb.len()];
    seen[from] = true;
    let mut stack = vec![from];
    while let Some(v) = stack.pop() {
        for &w in &nb[v] {
            if w != removed && !seen[w] {
                seen[w] = true;
                stack.push(w);
            }
        }
    }
    seen
}

/// Which networks the sweep enumerates (rings in the 4 groups are always there).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase", tag = "family")]
pub enum NetworkFamily {
    /// The bridges 4–7, 7–11, 12–13 plus up to `extra` more links between groups.
    Bridges {
        /// Most links added.
        extra: usize,
    },
    /// 7–11 plus exactly `count − 1` more links between groups.
    Links {
        /// Links between groups in all.
        count: usize,
    },
}

impl Default for NetworkFamily {
    fn default() -> Self {
        NetworkFamily::Bridges { extra: 2 }
    }
}

/// The bridges read from the paper's figure (1-based): today's `configs/bridges.toml`.
pub const FIGURE_BRIDGES: [(usize, usize); 3] = [(4, 7), (7, 11), (12, 13)];

/// The networks of `family` that fit the text ([`check_text`]), each as its sorted list of
/// links between groups (1-based, `a < b`), in enumeration order. `base` supplies every other
/// scenario value.
pub fn candidate_networks(base: &Scenario, family: NetworkFamily) -> Vec<Vec<(usize, usize)>> {
    let group = |a: usize| (a - 1) / 4;
    let all: Vec<(usize, usize)> = (1..=16)
        .flat_map(|a| (a + 1..=16).map(move |b| (a, b)))
        .filter(|&(a, b)| group(a) != group(b))
        .collect();
    let (fixed, sizes): (Vec<(usize, usize)>, Vec<usize>) = match family {
        NetworkFamily::Bridges { extra } => (FIGURE_BRIDGES.to_vec(), (1..=extra).collect()),
        NetworkFamily::Links { count } => (vec![(7, 11)], vec![count.saturating_sub(1)]),
    };
    let pool: Vec<(usize, usize)> = all.into_iter().filter(|l| !fixed.contains(l)).collect();
    let mut out = Vec::new();
    for size in sizes {
        for_each_subset(pool.len(), size, &mut |chosen| {
            let mut links = fixed.clone();
            links.extend(chosen.iter().map(|&i| pool[i]));
            links.sort_unstable();
            let scenario = Scenario {
                groups: 4,
                agents_per_group: 4,
                bridges: links.clone(),
                edges: Vec::new(),
                ..base.clone()
            };
            if scenario.validate().is_ok() && check_text(&scenario).is_ok() {
                out.push(links);
            }
        });
    }
    out
}

/// Calls `f` with every `size`-subset of `0..n` (ascending indices, lexicographic order).
fn for_each_subset(n: usize, size: usize, f: &mut dyn FnMut(&[usize])) {
    fn go(
        start: usize,
        n: usize,
        size: usize,
        chosen: &mut Vec<usize>,
        f: &mut dyn FnMut(&[usize]),
    ) {
        if chosen.len() == size {
            return f(chosen);
        }
        for i in start..n {
            chosen.push(i);
            go(i + 1, n, size, chosen, f);
            chosen.pop();
        }
    }
    go(0, n, size, &mut Vec::with_capacity(size), f)
}

/// The study's recursion on covariances alone for the agents of one rule (no means): what
/// decides ω and 2σ.
pub struct CovarianceRun {
    part: Partition,
    rule: StudyRule,
    neighbours: Vec<Vec<usize>>,
    agents: Vec<BlockCovariance>,
    sent: Vec<BlockCovariance>,
}

impl CovarianceRun {
    /// Every agent at the common prior.
    pub fn new(model: &Model, rule: StudyRule) -> Self {
        let part = Partition::new(model, Storage::Blocks);
        let agents = (0..model.scenario.agents())
            .map(|_| part.prior(model))
            .collect();
        Self {
            rule,
            neighbours: model.scenario.neighbours(),
            agents,
            sent: Vec::new(),
            part,
        }
    }

    /// One step (prediction, each agent's measurements, the exchange); returns the weights of
    /// agent `agent` fusing neighbour `watched` (0-based; empty if they are not linked).
    pub fn step(
        &mut self,
        model: &Model,
        agent: usize,
        watched: usize,
    ) -> Result<Vec<f64>, SimError> {
        let part = &self.part;
        for (a, e) in self.agents.iter_mut().enumerate() {
            part.predict(e);
            for m in 0..part.measurements[a].len() {
                // The gain and the covariance do not depend on the measured value.
                part.update(e, a, m);
            }
        }
        let rule = self.rule;
        let mut watched_omega = Vec::new();
        exchange(
            &mut self.agents,
            &mut self.sent,
            &self.neighbours,
            |a, b, mine, theirs| {
                let (omega, _) = fuse(model, Storage::Blocks, rule, mine, theirs)?;
                if (a, b) == (agent, watched) {
                    watched_omega = omega;
                }
                Ok(())
            },
        )?;
        Ok(watched_omega)
    }

    /// Agent `agent`'s mean 2σ of the position coordinates (as the study reports it).
    pub fn two_sigma(&self, agent: usize) -> f64 {
        self.part.two_sigma(&self.agents[agent])
    }
}

/// The covariance-only series of one rule for the headline agent of `config`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CovarianceSeries {
    /// The weights of the watched fusion per step (CI one, nmCI one per model block).
    pub omega: Vec<Vec<f64>>,
    /// The headline agent's mean 2σ per step.
    pub two_sigma: Vec<f64>,
}

/// Runs [`CovarianceRun`] for `config.steps` steps.
pub fn covariance_series(
    config: &StudyConfig,
    rule: StudyRule,
) -> Result<CovarianceSeries, SimError> {
    config.validate()?;
    let model = Model::new(&config.scenario)?;
    let mut run = CovarianceRun::new(&model, rule);
    let (agent, watched) = (config.agent - 1, config.watched - 1);
    let mut series = CovarianceSeries {
        omega: Vec::with_capacity(config.steps),
        two_sigma: Vec::with_capacity(config.steps),
    };
    for _ in 0..config.steps {
        series.omega.push(run.step(&model, agent, watched)?);
        series.two_sigma.push(run.two_sigma(agent));
    }
    Ok(series)
}

/// One network of the sweep and how close it comes to the paper.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Candidate {
    /// Links between groups (1-based), beside the rings.
    pub links: Vec<(usize, usize)>,
    /// `None` when the network fits the paper's text; otherwise why not (reference networks).
    pub text_mismatch: Option<String>,
    /// CI's steady-state ω of agent 7 fusing agent 11.
    pub omega_ci: f64,
    /// nmCI's steady-state ω per model block (G1x, G1y, G2x, …).
    pub omega_nmci: Vec<f64>,
    /// Mean 2σ, CI and nmCI.
    pub two_sigma: [f64; 2],
    /// `1 − nmCI/CI` of the mean 2σ.
    pub two_sigma_reduction: f64,
    /// Mean RMSE, CI and nmCI, from the Monte Carlo runs (short list only).
    pub rmse: Option<[f64; 2]>,
    /// `1 − nmCI/CI` of the mean RMSE (short list only).
    pub rmse_reduction: Option<f64>,
    /// Distance to the paper's numbers (module docs): covariance-only terms, plus the RMSE
    /// term when the RMSE is known.
    pub distance: f64,
}

/// The sweep: the family, how many networks get Monte Carlo RMSE, and the study values
/// (`scenario` except its network, `steps`, `runs`, `seed`) everything runs with.
#[derive(Debug, Clone, PartialEq)]
pub struct SweepConfig {
    /// The study (its network is replaced by each candidate's; agent 7, watched 11).
    pub study: StudyConfig,
    /// The networks enumerated.
    pub family: NetworkFamily,
    /// How many of the best covariance-only candidates get the Monte Carlo RMSE.
    pub short_list: usize,
    /// Networks evaluated in full beside the family whether or not they fit the text
    /// (links between groups, 1-based), e.g. [`FIGURE_BRIDGES`].
    pub references: Vec<Vec<(usize, usize)>>,
}

impl Default for SweepConfig {
    fn default() -> Self {
        Self {
            study: StudyConfig {
                scenario: Scenario {
                    bridges: FIGURE_BRIDGES.to_vec(),
                    ..Scenario::default()
                },
                ..StudyConfig::default()
            },
            family: NetworkFamily::default(),
            short_list: 5,
            references: vec![FIGURE_BRIDGES.to_vec()],
        }
    }
}

/// The result of a sweep.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SweepReport {
    /// Networks in the family that fit the text.
    pub fitting: usize,
    /// The short list with RMSE, best first, then every other fitting network by covariance
    /// distance.
    pub ranked: Vec<Candidate>,
    /// The reference networks, evaluated in full.
    pub references: Vec<Candidate>,
}

impl SweepConfig {
    /// The study config of a network given by its links between groups.
    pub fn network(&self, links: &[(usize, usize)]) -> StudyConfig {
        StudyConfig {
            agent: 7,
            watched: 11,
            coin: false,
            scenario: Scenario {
                bridges: links.to_vec(),
                edges: Vec::new(),
                ..self.study.scenario.clone()
            },
            ..self.study.clone()
        }
    }

    /// Checks the values.
    pub fn validate(&self) -> Result<(), SimError> {
        self.study.validate()?;
        let bad = |m: String| Err(SimError::InvalidScenario(m));
        if (
            self.study.scenario.groups,
            self.study.scenario.agents_per_group,
        ) != (4, 4)
        {
            return bad("the sweep is over the paper's 4 groups of 4 agents".into());
        }
        match self.family {
            NetworkFamily::Bridges { extra } if extra > 3 => bad(format!(
                "extra links: at most 3 (got {extra}; the count grows as 93^extra)"
            )),
            NetworkFamily::Links { count } if !(1..=4).contains(&count) => bad(format!(
                "links between groups: 1 to 4 (got {count}; the count grows as 95^(count−1))"
            )),
            _ => Ok(()),
        }?;
        for links in &self.references {
            self.network(links).validate()?;
        }
        Ok(())
    }
}

/// The group (0-based) of each model block: that of its first target.
#[cfg(not(target_arch = "wasm32"))] // used by `sweep` (native: rayon)
fn block_groups(model: &Model) -> Vec<usize> {
    let sc = &model.scenario;
    model
        .blocks
        .iter()
        .map(|b| {
            let first = b.iter().copied().min().unwrap_or(0);
            (first / 4).min(sc.targets().saturating_sub(1)) / sc.targets_per_group
        })
        .collect()
}

/// The steady-state value of a per-step series: the mean over the last half of the steps.
#[cfg(not(target_arch = "wasm32"))] // used by `sweep` (native: rayon)
fn steady(series: impl ExactSizeIterator<Item = f64>) -> f64 {
    let half = series.len() / 2;
    let (mut sum, mut count) = (0.0, 0usize);
    for v in series.skip(half) {
        sum += v;
        count += 1;
    }
    sum / count.max(1) as f64
}

/// The covariance-only candidate of one network from its CI and nmCI series.
#[cfg(not(target_arch = "wasm32"))] // used by `sweep` (native: rayon)
fn candidate(
    model: &Model,
    links: &[(usize, usize)],
    ci: &CovarianceSeries,
    nmci: &CovarianceSeries,
) -> Candidate {
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len().max(1) as f64;
    let omega_ci = steady(ci.omega.iter().map(|w| w[0]));
    let blocks = model.blocks.len();
    let omega_nmci: Vec<f64> = (0..blocks)
        .map(|k| steady(nmci.omega.iter().map(|w| w[k])))
        .collect();
    let two_sigma = [mean(&ci.two_sigma), mean(&nmci.two_sigma)];
    let two_sigma_reduction = 1.0 - two_sigma[1] / two_sigma[0];
    let mut c = Candidate {
        links: links.to_vec(),
        text_mismatch: check_text(&model.scenario).err().map(|e| e.to_string()),
        omega_ci,
        omega_nmci,
        two_sigma,
        two_sigma_reduction,
        rmse: None,
        rmse_reduction: None,
        distance: 0.0,
    };
    c.distance = distance(&c, &block_groups(model));
    c
}

/// The distance of the module docs.
#[cfg(not(target_arch = "wasm32"))] // used by `sweep` (native: rayon)
fn distance(c: &Candidate, groups: &[usize]) -> f64 {
    let [lo, hi] = PAPER_OMEGA_NMCI_FAR;
    let (mut near, mut far) = ((0.0, 0usize), (0.0, 0usize));
    for (w, &g) in c.omega_nmci.iter().zip(groups) {
        if g < 2 {
            near = (near.0 + (1.0 - w).abs(), near.1 + 1);
        } else {
            far = (far.0 + (lo - w).max(w - hi).max(0.0), far.1 + 1);
        }
    }
    (c.omega_ci - PAPER_OMEGA_CI).abs()
        + near.0 / near.1.max(1) as f64
        + far.0 / far.1.max(1) as f64
        + (c.two_sigma_reduction - PAPER_TWO_SIGMA_REDUCTION).abs()
        + c.rmse_reduction
            .map_or(0.0, |r| (r - PAPER_RMSE_REDUCTION).abs())
}

/// Runs the sweep on every core (rayon): the covariance-only recursion of CI and nmCI for
/// every fitting network and reference, then the Monte Carlo runs of CI and nmCI for the
/// short list and the references (all runs of one network and rule as one [`super::RunBatch`]).
/// `on_piece(done, total)` is called after each piece (one rule of one network: its
/// covariance-only series, then its Monte Carlo runs).
#[cfg(not(target_arch = "wasm32"))]
pub fn sweep(
    config: &SweepConfig,
    on_piece: impl Fn(usize, usize) + Sync,
) -> Result<SweepReport, SimError> {
    use rayon::prelude::*;
    use std::sync::atomic::{AtomicUsize, Ordering};
    config.validate()?;
    let networks = candidate_networks(&config.study.scenario, config.family);
    let everything: Vec<&Vec<(usize, usize)>> = networks.iter().chain(&config.references).collect();
    let short = config.short_list.min(networks.len());
    let total = 2 * everything.len() + 2 * (short + config.references.len());
    let done = AtomicUsize::new(0);
    let tick = || on_piece(done.fetch_add(1, Ordering::Relaxed) + 1, total);
    let series = everything
        .par_iter()
        .flat_map(|links| [(*links, StudyRule::Ci), (*links, StudyRule::Nmci)])
        .map(|(links, rule)| {
            let s = covariance_series(&config.network(links), rule);
            tick();
            s
        })
        .collect::<Result<Vec<_>, _>>()?;
    let mut candidates: Vec<Candidate> = everything
        .iter()
        .zip(series.chunks(2))
        .map(|(links, pair)| {
            let model = Model::new(&config.network(links).scenario)?;
            Ok(candidate(&model, links, &pair[0], &pair[1]))
        })
        .collect::<Result<_, SimError>>()?;
    let mut references = candidates.split_off(networks.len());
    candidates.sort_by(|a, b| a.distance.total_cmp(&b.distance));
    // Monte Carlo RMSE for the short list and the references.
    let full: Vec<&mut Candidate> = candidates
        .iter_mut()
        .take(short)
        .chain(references.iter_mut())
        .collect();
    let pieces: Vec<(usize, StudyRule)> = (0..full.len())
        .flat_map(|c| [(c, StudyRule::Ci), (c, StudyRule::Nmci)])
        .collect();
    let configs: Vec<StudyConfig> = full.iter().map(|c| config.network(&c.links)).collect();
    let models = configs
        .iter()
        .map(|c| Model::new(&c.scenario))
        .collect::<Result<Vec<_>, _>>()?;
    let runs = config.study.runs;
    // traces[2 c + rule][run]
    let traces = pieces
        .par_iter()
        .map(|&(c, rule)| {
            let spec = configs[c].run_spec(0, Storage::Blocks);
            let traces = super::simulate_runs_for_rule(&models[c], &spec, 0..runs as u64, rule);
            tick();
            traces
        })
        .collect::<Result<Vec<_>, _>>()?;
    for (k, c) in full.into_iter().enumerate() {
        let rmse_of = |rule: usize| {
            super::summarize(&traces[k * 2 + rule], models[k].dim()).estimators[1]
                .1
                .rmse_mean
        };
        let rmse = [rmse_of(0), rmse_of(1)];
        c.rmse = Some(rmse);
        c.rmse_reduction = Some(1.0 - rmse[1] / rmse[0]);
        c.distance = distance(c, &block_groups(&models[k]));
    }
    candidates[..short].sort_by(|a, b| a.distance.total_cmp(&b.distance));
    Ok(SweepReport {
        fitting: networks.len(),
        ranked: candidates,
        references,
    })
}
