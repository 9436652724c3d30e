//! The tracking study's exact conservativeness index (COIN): the propagated true error
//! covariance against Monte Carlo, and the properties the theory fixes (the centralized
//! Kalman filter is exact, CI and nmCI are conservative, naive fusion is not).

use nalgebra::{DMatrix, DVector};
use nmci::sim::*;

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
    let estimators: Vec<Option<Rule>> = estimators().collect();
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
        let spec = RunSpec {
            steps,
            seed: 11,
            run: r,
            agent: 0,
            watched: 1,
            storage: Storage::Blocks,
        };
        let mut run = RunState::new(&model, &spec);
        while !run.finished() {
            run.step(&model).unwrap();
        }
        for (s, acc) in sample.iter_mut().enumerate() {
            let e: DVector<f64> = run.error(s, 0).unwrap();
            acc.ger(1.0 / runs as f64, &e, &e, 1.0);
        }
    }
    for (s, (E, S)) in exact.iter().zip(&sample).enumerate() {
        let name = estimator_name(estimators[s]);
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
    let mut naive = ErrorPropagation::new(&model, Some(Rule::Naive));
    for _ in 0..steps {
        naive.step(&model).unwrap();
    }
    assert!(naive.coin(0) > 1.5, "naive COIN {}", naive.coin(0));
}

/// On the paper's scenario (first 40 steps, agent 7): the centralized filter's COIN is 1
/// (its covariance is its error covariance), CI and nmCI never exceed 1 (conservative, as
/// proven) and naive fusion exceeds it from the first exchange on. (Which of CI and nmCI is
/// closer to 1 changes over time: over these 40 steps nmCI's mean COIN is lower, 0.86 vs
/// 0.98; over the full 400 steps it is higher, 0.914 vs 0.902 — see the README.)
#[test]
fn coin_of_the_paper_study() {
    let model = Model::new(&Scenario::default()).unwrap();
    let series = |e: Option<Rule>| coin_series(&model, 40, 6, e).unwrap();
    let central = series(None);
    assert!(
        central.iter().all(|c| (c - 1.0).abs() < 1e-9),
        "{central:?}"
    );
    let (ci, nmci) = (series(Some(Rule::Ci)), series(Some(Rule::Nmci)));
    for (name, s) in [("ci", &ci), ("nmci", &nmci)] {
        assert!(s.iter().all(|c| *c <= 1.0 + 1e-9), "{name}: {s:?}");
        assert!(
            s.iter().any(|c| *c < 0.99),
            "{name} is strictly conservative somewhere"
        );
    }
    let naive = series(Some(Rule::Naive));
    assert!(naive.iter().all(|c| *c > 1.0 + 1e-6), "{naive:?}");
    // ICI: computed, finite and positive (its conservativeness here is a finding, not a theorem).
    let ici = series(Some(Rule::Ici));
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
