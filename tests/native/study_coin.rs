//! The tracking study's exact conservativeness index (COIN): the propagated true error
//! covariance against Monte Carlo, and the properties the theory fixes (the centralized
//! Kalman filter is exact, CI and nmCI are conservative, naive fusion is not).

use nalgebra::{DMatrix, DVector};
use nmci::study::*;

/// Run `run` of `steps` steps (seed `seed`), done: truth and every estimator's agents.
fn finished_run(model: &Model, steps: usize, seed: u64, run: u64) -> RunState {
    let spec = RunSpec {
        steps,
        seed,
        run,
        agent: 0,
        watched: 1,
        storage: Storage::Blocks,
    };
    let mut state = RunState::new(model, &spec);
    while !state.finished() {
        state.step(model).unwrap();
    }
    state
}

/// The full `n × n` matrix of per-block matrices.
fn assemble(model: &Model, blocks: &[DMatrix<f64>]) -> DMatrix<f64> {
    let mut full = DMatrix::zeros(model.dim(), model.dim());
    for (b, m) in model.blocks.iter().zip(blocks) {
        for (i, &gi) in b.iter().enumerate() {
            for (j, &gj) in b.iter().enumerate() {
                full[(gi, gj)] = m[(i, j)];
            }
        }
    }
    full
}

/// The exact error covariance of agent 0 of each rule (and of the centralized filter) after
/// a few steps equals the sample covariance of the simulated errors over many runs: every
/// entry within 5 standard errors (`sd(Ê_ij) = √((E_ii E_jj + E_ij²)/R)` for zero-mean
/// Gaussian errors). A small network (one group of 2 agents, 3 targets: 16 states) so that
/// 4000 runs are cheap; the seed is fixed, so the check is deterministic.
#[test]
#[allow(non_snake_case)]
fn exact_error_covariance_matches_monte_carlo() {
    let scenario = Scenario {
        groups: 1,
        agents_per_group: 2,
        targets_per_group: 3,
        bridges: vec![],
        ..Scenario::default()
    };
    let model = Model::new(&scenario).unwrap();
    let steps = 4;
    let runs = 4000;
    let estimators: Vec<Estimator> = estimators().collect();
    let exact: Vec<DMatrix<f64>> = estimators
        .iter()
        .map(|&e| {
            let mut p = ErrorPropagation::new(&model, e);
            for _ in 0..steps {
                p.step(&model).unwrap();
            }
            assemble(&model, &p.error_covariance(0))
        })
        .collect();
    let n = model.dim();
    let mut sample = vec![DMatrix::<f64>::zeros(n, n); estimators.len()];
    for r in 0..runs {
        let run = finished_run(&model, steps, 11, r);
        for (s, acc) in sample.iter_mut().enumerate() {
            let e: DVector<f64> = run.error(s, 0).unwrap();
            acc.ger(1.0 / runs as f64, &e, &e, 1.0);
        }
    }
    for (s, (E, S)) in exact.iter().zip(&sample).enumerate() {
        let name = estimators[s].name();
        for i in 0..n {
            for j in 0..n {
                let sd = ((E[(i, i)] * E[(j, j)] + E[(i, j)].powi(2)) / runs as f64).sqrt();
                assert!(
                    (S[(i, j)] - E[(i, j)]).abs() <= 5.0 * sd + 1e-12,
                    "{name} ({i}, {j}): sample {} vs exact {} (sd {sd})",
                    S[(i, j)],
                    E[(i, j)]
                );
            }
        }
    }
    // Not a vacuous match: naive fusion's error covariance is far from its own P.
    let mut naive = ErrorPropagation::new(&model, Estimator::Decentralized(StudyRule::Naive));
    for _ in 0..steps {
        naive.step(&model).unwrap();
    }
    assert!(naive.coin(0) > 1.5, "naive COIN {}", naive.coin(0));
}

/// The same against simulation on the chained-fusion network of the brute-force test (agents
/// with 2 and 3 neighbours): for every agent of every estimator, the errors whitened by the
/// exact `E` have `E[eᵀ E⁻¹ e] = n` and `Var = 2n` (Gaussian errors), so the mean over `R`
/// runs must lie within 5 standard errors `5·√(2n/R)` of `n` — a 2 % test at `n = 28`,
/// `R = 4000`, on the whole covariance at once rather than entry by entry.
#[test]
#[allow(non_snake_case)]
fn exact_error_covariance_whitens_the_simulated_errors_of_a_chained_network() {
    let scenario = Scenario {
        groups: 1,
        agents_per_group: 4,
        targets_per_group: 5,
        bridges: vec![(1, 3)],
        ..Scenario::default()
    };
    let model = Model::new(&scenario).unwrap();
    let (n, agents, steps, runs) = (model.dim(), scenario.agents(), 5, 4000);
    let estimators: Vec<Estimator> = estimators().collect();
    // Per estimator and agent: the Cholesky factor of the exact E.
    let factors: Vec<Vec<nalgebra::Cholesky<f64, nalgebra::Dyn>>> = estimators
        .iter()
        .map(|&e| {
            let mut p = ErrorPropagation::new(&model, e);
            for _ in 0..steps {
                p.step(&model).unwrap();
            }
            let filters = if e.rule().is_some() { agents } else { 1 };
            (0..filters)
                .map(|a| assemble(&model, &p.error_covariance(a)).cholesky().unwrap())
                .collect()
        })
        .collect();
    let mut sums: Vec<Vec<f64>> = factors.iter().map(|f| vec![0.0; f.len()]).collect();
    for r in 0..runs {
        let run = finished_run(&model, steps, 12, r);
        for (s, per_agent) in sums.iter_mut().enumerate() {
            for (a, sum) in per_agent.iter_mut().enumerate() {
                let e: DVector<f64> = run.error(s, a).unwrap();
                *sum += e.dot(&factors[s][a].solve(&e));
            }
        }
    }
    let bound = 5.0 * (2.0 * n as f64 / runs as f64).sqrt();
    for (s, per_agent) in sums.iter().enumerate() {
        for (a, sum) in per_agent.iter().enumerate() {
            let mean = sum / runs as f64;
            assert!(
                (mean - n as f64).abs() <= bound,
                "{} agent {a}: mean whitened squared error {mean} vs {n} ± {bound}",
                estimators[s].name()
            );
        }
    }
}

/// On the paper's scenario (first 40 steps, agent 7): the centralized filter's COIN is 1
/// (its covariance is its error covariance), CI and nmCI never exceed 1 (conservative, as
/// proven) and naive fusion exceeds it from the first exchange on. Which of CI and nmCI is
/// closer to 1 changes over time: over these 40 steps nmCI's mean COIN is lower, 0.86 vs
/// 0.97 (asserted: docs/study.md quotes it); over the full 400 steps it is higher, 0.909 vs
/// 0.894 (`docs/figures/track/summary.json`).
#[test]
fn coin_of_the_paper_study() {
    let model = Model::new(&Scenario::default()).unwrap();
    let series = |e: Estimator| coin_series(&model, 40, 6, e).unwrap();
    let central = series(Estimator::Central);
    assert!(
        central.iter().all(|c| (c - 1.0).abs() < 1e-9),
        "{central:?}"
    );
    let (ci, nmci) = (
        series(Estimator::Decentralized(StudyRule::Ci)),
        series(Estimator::Decentralized(StudyRule::Nmci)),
    );
    for (name, s) in [("ci", &ci), ("nmci", &nmci)] {
        assert!(s.iter().all(|c| *c <= 1.0 + 1e-9), "{name}: {s:?}");
        assert!(
            s.iter().any(|c| *c < 0.99),
            "{name} is strictly conservative somewhere"
        );
    }
    let mean = |s: &[f64]| s.iter().sum::<f64>() / s.len() as f64;
    assert!((mean(&nmci) - 0.856).abs() < 1e-3, "nmCI {}", mean(&nmci));
    assert!((mean(&ci) - 0.972).abs() < 1e-3, "CI {}", mean(&ci));
    let naive = series(Estimator::Decentralized(StudyRule::Naive));
    assert!(naive.iter().all(|c| *c > 1.0 + 1e-6), "{naive:?}");
    // ICI: computed, finite and positive (its conservativeness here is a finding, not a theorem).
    let ici = series(Estimator::Decentralized(StudyRule::Ici));
    assert!(ici.iter().all(|c| c.is_finite() && *c > 0.0));
}

/// The summary carries each estimator's COIN mean and maximum from the series.
#[test]
fn summary_attaches_coin() {
    let config = StudyConfig {
        runs: 1,
        steps: 6,
        ..StudyConfig::default()
    };
    let (summary, report) = run_study(&config).unwrap();
    assert_eq!(summary.coin_series.len(), 5);
    let ci = &summary.coin_series[1];
    assert_eq!(
        report.ci.coin_max,
        Some(ci.iter().copied().fold(f64::MIN, f64::max))
    );
    assert!(report.central.coin_mean.is_some() && report.ici.coin_mean.is_some());
    let (without, report) = run_study(&StudyConfig {
        coin: false,
        ..config
    })
    .unwrap();
    assert!(without.coin_series.is_empty() && report.ci.coin_mean.is_none());
}

/// The exact COIN's propagation against a brute-force one written the slow, obvious way: the
/// whole joint error covariance of all agents over the whole state (no blocks, no twins, no
/// sparse rows), dense `M Σ Mᵀ` for every scalar update and `C Σ Cᵀ` for the exchange, with
/// the fusion gains recomputed from the dense rules' weights (`K_a = ω P P_a⁻¹`,
/// `K_b = (1 − ω) P P_b⁻¹`, per block for nmCI; naive `K = P P⁻¹`; ICI
/// `K_a = P (P_a⁻¹ − ω Γ⁻¹)`, `K_b = P (P_b⁻¹ − (1 − ω) Γ⁻¹)`, `Γ = ω P_a + (1 − ω) P_b`). On a
/// network where agents have 2 and 3 neighbours, so one step chains several fusions of one
/// agent.
#[test]
#[allow(non_snake_case)]
fn exact_error_covariance_matches_a_brute_force_dense_propagation() {
    // One group: a ring 1-2-3-4 plus the chord 1–3 (degrees 3, 2, 3, 2), one model block per
    // axis, every rule. Two groups of three agents (rings) with two bridges, 3–4 and 1–5,
    // nmCI: several blocks per axis, so nmCI keeps or takes whole blocks (ω = 1 or 0) while
    // it mixes others — agents 4 and 5 take group 1's blocks from agents 3 and 1, and agent 6
    // mixes the two, reading the cross-covariances of blocks taken at the exchange before
    // (with a single bridge every fusion in the far group keeps or takes, and those are
    // never read).
    let chained = Scenario {
        groups: 1,
        agents_per_group: 4,
        targets_per_group: 5,
        bridges: vec![(1, 3)],
        ..Scenario::default()
    };
    brute_force_check(
        &chained,
        6,
        &[
            StudyRule::Ci,
            StudyRule::Nmci,
            StudyRule::Naive,
            StudyRule::Ici,
        ],
    );
    let two_groups = Scenario {
        groups: 2,
        agents_per_group: 3,
        targets_per_group: 4,
        bridges: vec![(3, 4), (1, 5)],
        ..Scenario::default()
    };
    assert!(
        brute_force_check(&two_groups, 6, &[StudyRule::Nmci]) > 0,
        "no kept or taken nmCI block"
    );
}

/// [`exact_error_covariance_matches_a_brute_force_dense_propagation`] on one network for
/// `steps` steps with each of `rules`; returns how many nmCI block weights were exactly 0 or
/// 1 (kept or taken blocks).
#[allow(non_snake_case)]
fn brute_force_check(scenario: &Scenario, steps: usize, rules: &[StudyRule]) -> usize {
    use nmci::{
        rules::{covariance_intersection, inverse_covariance_intersection, non_monolithic_ci},
        Criterion, FusionProblem,
    };
    let model = Model::new(scenario).unwrap();
    let (n, agents) = (model.dim(), scenario.agents());
    let nb = scenario.neighbours();
    if scenario.groups == 1 {
        assert_eq!(nb.iter().map(Vec::len).collect::<Vec<_>>(), [3, 2, 3, 2]);
    }
    let inv = |m: &DMatrix<f64>| m.clone().try_inverse().unwrap();
    let central = ErrorPropagation::new(&model, Estimator::Central);
    assert!(central.is_central() && central.steps_done() == 0);
    let mut endpoints = 0;
    for &rule in rules {
        let mut exact = ErrorPropagation::new(&model, Estimator::Decentralized(rule));
        assert!(!exact.is_central());
        // Brute force: every agent's dense covariance and the joint error covariance.
        let mut P: Vec<DMatrix<f64>> = vec![model.P0.clone(); agents];
        let big = agents * n;
        let mut S = DMatrix::from_fn(big, big, |i, j| model.P0[(i % n, j % n)]);
        for step in 0..steps {
            // Prediction with the common process noise.
            let mut A = DMatrix::zeros(big, big);
            for i in 0..agents {
                A.view_mut((i * n, i * n), (n, n)).copy_from(&model.F);
            }
            S = &A * &S * A.transpose()
                + DMatrix::from_fn(big, big, |i, j| model.Q[(i % n, j % n)]);
            for p in &mut P {
                *p = &model.F * &*p * model.F.transpose() + &model.Q;
            }
            // Each agent's scalar updates: e ← (I − K hᵀ) e − K v.
            for (i, ms) in model.measurements.iter().enumerate() {
                for m in ms {
                    let h = DVector::from_fn(n, |k, _| {
                        m.row.iter().filter(|(j, _)| *j == k).map(|(_, c)| c).sum()
                    });
                    let Ph = &P[i] * &h;
                    let K = &Ph / (h.dot(&Ph) + m.variance);
                    let J = DMatrix::identity(n, n) - &K * h.transpose();
                    P[i] = &J * &P[i] * J.transpose() + &K * K.transpose() * m.variance;
                    let mut M = DMatrix::identity(big, big);
                    M.view_mut((i * n, i * n), (n, n)).copy_from(&J);
                    let mut u = DVector::zeros(big);
                    u.rows_mut(i * n, n).copy_from(&K);
                    S = &M * &S * M.transpose() + &u * u.transpose() * m.variance;
                }
            }
            // Exchange: fuse the copies sent before it, one neighbour at a time, ascending.
            let sent = P.clone();
            let mut C = DMatrix::zeros(big, big);
            for a in 0..agents {
                let mut row = DMatrix::zeros(n, big); // e_a after the exchange, as Σ_j C_aj e_j
                row.view_mut((0, a * n), (n, n))
                    .copy_from(&DMatrix::identity(n, n));
                for &b in &nb[a] {
                    let problem = FusionProblem::new_trusted(
                        DVector::zeros(n),
                        P[a].clone(),
                        DVector::zeros(n),
                        sent[b].clone(),
                        model.cross_pattern.clone(),
                    );
                    let (K_a, K_b, fused) = match rule {
                        StudyRule::Ci => {
                            let ci = covariance_intersection(&problem, Criterion::Trace).unwrap();
                            let w = ci.omega;
                            let F = ci.fused.P;
                            (&F * inv(&P[a]) * w, &F * inv(&sent[b]) * (1.0 - w), F)
                        }
                        StudyRule::Nmci => {
                            let nm = non_monolithic_ci(&problem, Criterion::Trace).unwrap();
                            // ω of each state's block (the estimates are block-diagonal).
                            let mut w = DVector::zeros(n);
                            endpoints += nm.omega.iter().filter(|&&w| w == 0.0 || w == 1.0).count();
                            for (block, omega) in nm.blocks.iter().zip(&nm.omega) {
                                for &i in block {
                                    w[i] = *omega;
                                }
                            }
                            let F = nm.fused.P;
                            let one_minus = w.map(|v| 1.0 - v);
                            (
                                &F * DMatrix::from_diagonal(&w) * inv(&P[a]),
                                &F * DMatrix::from_diagonal(&one_minus) * inv(&sent[b]),
                                F,
                            )
                        }
                        StudyRule::Ici => {
                            let ici = inverse_covariance_intersection(&problem, Criterion::Trace)
                                .unwrap();
                            let w = ici.omega;
                            let Gamma = &P[a] * w + &sent[b] * (1.0 - w);
                            let F = ici.fused.P;
                            (
                                &F * (inv(&P[a]) - inv(&Gamma) * w),
                                &F * (inv(&sent[b]) - inv(&Gamma) * (1.0 - w)),
                                F,
                            )
                        }
                        StudyRule::Naive => {
                            let F = inv(&(inv(&P[a]) + inv(&sent[b])));
                            (&F * inv(&P[a]), &F * inv(&sent[b]), F)
                        }
                    };
                    let mut next = &K_a * &row;
                    let mut cols = next.columns_mut(b * n, n);
                    cols += &K_b;
                    row = next;
                    P[a] = fused;
                }
                C.rows_mut(a * n, n).copy_from(&row);
            }
            S = &C * &S * C.transpose();
            exact.step(&model).unwrap();
            assert_eq!(exact.steps_done(), step + 1);
            // Compare every agent's covariance and true error covariance.
            for (a, P_a) in P.iter().enumerate() {
                let E_brute = S.view((a * n, a * n), (n, n)).into_owned();
                let E = assemble(&model, &exact.error_covariance(a));
                let P_exact = assemble(&model, &exact.covariance(a));
                let scale = E_brute.amax();
                assert!(
                    (&E - &E_brute).amax() <= 1e-12 * scale,
                    "{rule:?} step {step} agent {a}: E differs by {:e} (scale {scale:e})",
                    (&E - &E_brute).amax()
                );
                assert!((&P_exact - P_a).amax() <= 1e-12 * P_a.amax());
                // The brute force is block-diagonal too: nothing leaks across model blocks.
                let off = &E_brute - assemble(&model, &split(&model, &E_brute));
                assert!(off.amax() <= 1e-12 * scale, "{rule:?}: {:e}", off.amax());
            }
        }
    }
    endpoints
}

/// The model blocks of a full matrix.
fn split(model: &Model, full: &DMatrix<f64>) -> Vec<DMatrix<f64>> {
    model
        .blocks
        .iter()
        .map(|b| DMatrix::from_fn(b.len(), b.len(), |i, j| full[(b[i], b[j])]))
        .collect()
}
