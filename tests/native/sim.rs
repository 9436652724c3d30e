//! The tracking study's core: derived structure, block storage equal to dense storage,
//! reproducibility, and the qualitative results of a reduced study.

use nmci::study::*;

fn spec(steps: usize, seed: u64, run: u64, storage: Storage) -> RunSpec {
    RunSpec {
        steps,
        seed,
        run,
        agent: 6,
        watched: 10,
        storage,
    }
}

#[test]
fn the_structure_gives_eight_blocks_of_fourteen() {
    let sc = Scenario::default();
    sc.validate().unwrap();
    let model = Model::new(&sc).unwrap();
    assert_eq!(model.dim(), 112);
    assert_eq!(model.blocks.len(), 8);
    assert!(model.blocks.iter().all(|b| b.len() == 14));
    // Block 0 is group 1, x axis: targets 1–5 (x, ẋ) and the x biases of agents 1–4.
    let mut g1x: Vec<usize> = (0..5)
        .flat_map(|t| [sc.target_index(t, 0), sc.target_index(t, 1)])
        .collect();
    g1x.extend((0..4).map(|a| sc.bias_index(a, 0)));
    g1x.sort_unstable();
    assert_eq!(model.blocks[0], g1x);
    // Block 1 is group 1, y axis; block 2 group 2, x axis.
    assert!(model.blocks[1].contains(&sc.target_index(0, 2)));
    assert!(model.blocks[2].contains(&sc.target_index(5, 0)));
    // Agent 7's neighbours, ascending: 4 (bridge), 6, 8 (ring), 10, 11 (bridges); 1-based.
    assert_eq!(sc.neighbours()[6], vec![3, 5, 7, 9, 10]);
}

#[test]
fn block_storage_gives_the_dense_numbers() {
    let model = Model::new(&Scenario::default()).unwrap();
    // A whole run of 12 steps, every series compared entry by entry (lengths first).
    let steps = 12;
    let blocks = simulate_run(&model, &spec(steps, 5, 0, Storage::Blocks)).unwrap();
    let dense = simulate_run(&model, &spec(steps, 5, 0, Storage::Dense)).unwrap();
    let close_n = |a: &[f64], b: &[f64], len: usize| {
        a.len() == len
            && b.len() == len
            && a.iter()
                .zip(b)
                .all(|(x, y)| (x - y).abs() <= 1e-9 * x.abs().max(1.0))
    };
    let close = |a: &[f64], b: &[f64]| close_n(a, b, steps);
    assert_eq!((blocks.nees.len(), dense.nees.len()), (5, 5));
    assert_eq!(blocks.omega_nmci.len(), steps);
    assert_eq!(dense.omega_nmci.len(), steps);
    for s in 0..5 {
        assert!(
            close(&blocks.nees[s], &dense.nees[s]),
            "NEES {s}: {:?} vs {:?}",
            blocks.nees[s],
            dense.nees[s]
        );
        assert!(close(&blocks.rmse[s], &dense.rmse[s]));
        assert!(close(&blocks.two_sigma[s], &dense.two_sigma[s]));
        let flat = |t: &RunTrace| t.group_sums[s].concat();
        assert!(close_n(&flat(&blocks), &flat(&dense), 8));
    }
    assert!(close(&blocks.omega_ci, &dense.omega_ci));
    assert!(close(&blocks.omega_ici, &dense.omega_ici));
    // Dense nmCI finds the same 8 blocks by itself (from the exact zeros and the pattern).
    for (b, d) in blocks.omega_nmci.iter().zip(&dense.omega_nmci) {
        assert!(close_n(b, d, 8), "{b:?} vs {d:?}");
    }
}

#[test]
fn same_seed_same_numbers_other_seed_other_numbers() {
    let model = Model::new(&Scenario::default()).unwrap();
    let a = simulate_run(&model, &spec(5, 9, 1, Storage::Blocks)).unwrap();
    let b = simulate_run(&model, &spec(5, 9, 1, Storage::Blocks)).unwrap();
    let c = simulate_run(&model, &spec(5, 10, 1, Storage::Blocks)).unwrap();
    let d = simulate_run(&model, &spec(5, 9, 2, Storage::Blocks)).unwrap();
    assert_eq!(a, b);
    assert_ne!(a.rmse, c.rmse);
    assert_ne!(a.rmse, d.rmse);
    let sa = serde_json::to_string(&summarize(&[a], 112)).unwrap();
    let sb = serde_json::to_string(&summarize(&[b], 112)).unwrap();
    assert_eq!(sa, sb);
}

#[test]
fn reduced_study_reproduces_the_qualitative_results() {
    let model = Model::new(&Scenario::default()).unwrap();
    let traces: Vec<RunTrace> = (0..2)
        .map(|r| simulate_run(&model, &spec(60, 1, r, Storage::Blocks)).unwrap())
        .collect();
    let s = summarize(&traces, model.dim());
    let get = |name: &str| &s.estimators.iter().find(|(n, _)| n == name).unwrap().1;
    let (central, ci, nmci, naive) = (get("central"), get("ci"), get("nmci"), get("naive"));
    // Centralized filter consistent for most steps; CI and nmCI never above the upper bound;
    // naive fusion (double counting) above it.
    let central_inside = s.nees_series[0]
        .iter()
        .filter(|v| **v >= s.nees_bounds.0 && **v <= s.nees_bounds.1)
        .count();
    assert!(
        central_inside as f64 >= 0.8 * 60.0,
        "central NEES inside the band for {central_inside} of 60 steps"
    );
    assert_eq!(ci.nees_frac_above_upper, 0.0);
    assert_eq!(nmci.nees_frac_above_upper, 0.0);
    assert!(naive.nees_frac_above_upper > 0.5);
    assert!(central.rmse_mean < nmci.rmse_mean);
    // nmCI tighter and more accurate than CI.
    assert!(
        nmci.rmse_mean < ci.rmse_mean,
        "{} vs {}",
        nmci.rmse_mean,
        ci.rmse_mean
    );
    assert!(nmci.two_sigma_mean < ci.two_sigma_mean);
    // ω(7←11) at every step of every run: on groups 1–2 (blocks 0–3) nmCI keeps agent 7's
    // own estimate, exactly; on groups 3–4 it mixes (strictly inside (0, 1)) from the third
    // step on; CI's one ω is inside (0, 1) throughout.
    for t in &traces {
        assert_eq!(t.omega_nmci.len(), 60);
        for w in &t.omega_nmci {
            assert_eq!(w.len(), 8);
            assert_eq!(&w[..4], &[1.0; 4], "{w:?}");
        }
        // Group 4's information first reaches agent 7 on its own route (13–…–16, 16–9, 9–10,
        // 10–7) in the third exchange; until then 11's blocks dominate there (ω = 0).
        for w in &t.omega_nmci[2..] {
            assert!(w[4..].iter().all(|w| *w > 0.0 && *w < 1.0), "{w:?}");
        }
        assert!(t.omega_ci.iter().all(|w| *w > 0.0 && *w < 1.0));
    }
}

#[test]
fn invalid_scenarios_are_rejected() {
    let bad = [
        Scenario {
            targets_per_group: 4,
            ..Default::default()
        },
        Scenario {
            dt: 0.0,
            ..Default::default()
        },
        Scenario {
            q: f64::NAN,
            ..Default::default()
        },
        Scenario {
            bridges: vec![(4, 17)],
            ..Default::default()
        },
        Scenario {
            groups: 0,
            ..Default::default()
        },
    ];
    for s in bad {
        let e = s.validate().unwrap_err();
        assert!(e.to_string().starts_with("invalid scenario:"), "{e}");
        assert!(Model::new(&s).is_err());
    }
}

fn config_file(name: &str) -> StudyConfig {
    let path = format!("{}/configs/{name}", env!("CARGO_MANIFEST_DIR"));
    toml::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

#[test]
fn configs_paper_toml_lists_the_defaults_and_bridges_toml_only_changes_the_network() {
    assert_eq!(config_file("paper.toml"), StudyConfig::default());
    let bridges = config_file("bridges.toml");
    assert_eq!(bridges.scenario.bridges, FIGURE_BRIDGES.to_vec());
    assert_eq!(
        bridges,
        StudyConfig {
            scenario: Scenario {
                bridges: FIGURE_BRIDGES.to_vec(),
                ..Scenario::default()
            },
            ..StudyConfig::default()
        }
    );
}

use crate::golden;

/// The tiny study of the golden file: 2 runs × 12 steps, seed 3, default scenario.
fn tiny_config() -> StudyConfig {
    StudyConfig {
        runs: 2,
        steps: 12,
        seed: 3,
        ..StudyConfig::default()
    }
}

fn golden_of(view: &StudyView, config: &StudyConfig) -> golden::GoldenStudy {
    golden::GoldenStudy {
        config: config.clone(),
        report: view.report.clone(),
        nees: view.nees.clone(),
        rmse: view.rmse.clone(),
        two_sigma: view.two_sigma.clone(),
        omega: view.omega.clone(),
        coin: view.coin.clone(),
    }
}

/// The exact COIN on its own (the page's second worker): the batch study's COIN series bit for
/// bit, whatever the chunking, with `summary.json`'s mean and largest value and `coin.svg`'s
/// chart.
#[test]
fn live_coin_alone_equals_the_studys_coin() {
    let config = tiny_config();
    let (summary, report) = run_study(&config).unwrap();
    let mut coin = nmci::study::LiveCoin::new(config.clone()).unwrap();
    assert_eq!(coin.view().coin_len, 0);
    let mut chunks = 0;
    while !coin.advance(7).unwrap() {
        chunks += 1;
        let v = coin.view();
        assert_eq!(v.coin.len(), 5 * v.coin_len);
        assert!(!v.finished);
    }
    assert_eq!(chunks, (5 * config.steps).div_ceil(7) - 1);
    let view = coin.view();
    assert!(view.finished && view.coin_len == config.steps);
    assert_eq!(view.coin, summary.coin_series.concat());
    let by_name = |name: &str| {
        view.estimators
            .iter()
            .find(|e| e.name == name)
            .unwrap()
            .clone()
    };
    for (name, e) in [
        ("central", &report.central),
        ("ci", &report.ci),
        ("nmci", &report.nmci),
        ("naive", &report.naive),
        ("ici", &report.ici),
    ] {
        let c = by_name(name);
        assert_eq!(
            (c.coin_mean, c.coin_max),
            (e.coin_mean, e.coin_max),
            "{name}"
        );
    }
    assert_eq!(
        coin.chart(),
        nmci::study::coin_chart(&config, &summary.coin_series)
    );
    let charts = nmci::study::study_charts(&config, &summary, config.runs);
    assert_eq!(charts.last().unwrap(), &("coin", coin.chart()));
}

/// The page's two COIN workers: a `LiveCoin` propagating `COIN_WORKER_ESTIMATORS[0]` and
/// absorbing the tails of a `LiveCoinPart` propagating the rest ends with the view and chart
/// of one `LiveCoin` propagating all five, bit for bit; on the way every view is a prefix of
/// the final series. Tails that do not fit are refused with what is wrong.
#[test]
fn the_coin_shared_by_two_workers_is_the_one_worker_coin_bit_for_bit() {
    let all: Vec<Estimator> = COIN_WORKER_ESTIMATORS.concat();
    assert_eq!(all.len(), 5, "the two COIN workers share every estimator");
    assert!(estimators().all(|e| all.contains(&e)));
    let config = tiny_config();
    let mut whole = LiveCoin::new(config.clone()).unwrap();
    while !whole.advance(7).unwrap() {}
    let done = whole.view();
    let mut first = LiveCoin::with_second_worker(config.clone()).unwrap();
    let mut second = LiveCoinPart::new(config.clone()).unwrap();
    let (mut finished, mut rounds) = (false, 0);
    while !finished {
        // The second runs ahead by a chunk: the first shows the steps every estimator reached.
        second.advance(5).unwrap();
        let tail = second.tail();
        assert!(!first.finished());
        first.advance(3).unwrap();
        first.absorb(tail).unwrap();
        let v = first.view();
        for (k, part) in v.coin.chunks(v.coin_len.max(1)).enumerate() {
            let whole_k = &done.coin[k * config.steps..(k + 1) * config.steps];
            assert_eq!(
                part,
                &whole_k[..part.len()],
                "estimator {k}, round {rounds}"
            );
        }
        finished = v.finished;
        rounds += 1;
    }
    assert_eq!(first.view(), done);
    assert_eq!(done.units_done, 5 * config.steps);
    assert_eq!(first.chart(), whole.chart());
    // Its own estimators done before the second's: it waits, and advancing does nothing.
    let mut alone = LiveCoin::with_second_worker(config.clone()).unwrap();
    assert!(!alone.waiting());
    assert!(!alone.advance(10 * config.steps).unwrap());
    assert!(alone.waiting());
    let v = alone.view();
    assert_eq!((v.coin_len, v.finished), (0, false));
    assert_eq!(v.units_done, COIN_WORKER_ESTIMATORS[0].len() * config.steps);
    assert!(!alone.advance(1).unwrap());
    // Refusals.
    let mut again = LiveCoinPart::new(config.clone()).unwrap();
    again.advance(4).unwrap();
    let tail = again.tail();
    let e = first.absorb(tail.clone()).unwrap_err();
    assert_eq!(
        e.to_string(),
        "two-worker study: the second COIN worker's steps of central start at step 0 but step 12 is next"
    );
    let e = LiveCoin::new(config.clone())
        .unwrap()
        .absorb(tail.clone())
        .unwrap_err();
    assert_eq!(
        e.to_string(),
        "two-worker study: the COIN of central is computed here, not by a second worker"
    );
    let mut short = tail;
    short.values.pop();
    let e = LiveCoin::with_second_worker(config)
        .unwrap()
        .absorb(short)
        .unwrap_err();
    assert_eq!(
        e.to_string(),
        "two-worker study: the second COIN worker sent 2 estimators, not 3"
    );
}

#[test]
fn live_study_equals_the_batch_study_and_the_golden_file() {
    let config = tiny_config();
    let mut live = LiveStudy::new(config.clone()).unwrap();
    let start = live.view();
    assert_eq!((start.runs_done, start.step, start.series_len), (0, 0, 0));
    let mut chunks = 0;
    while !live.advance(5).unwrap() {
        chunks += 1;
        let v = live.view();
        assert!(!v.finished && v.series_len <= config.steps);
        assert_eq!(v.nees.len(), 5 * v.series_len);
        assert_eq!(v.omega.len(), 10 * v.series_len);
        // The exact COIN comes after the runs, one estimator-step per unit of work.
        assert_eq!(v.coin.len(), 5 * v.coin_len);
        assert!(v.coin_len == 0 || v.runs_done == 2);
        // Both runs advance together: every series averages both.
        assert_eq!(v.report.runs, 2);
        assert!(v.coin_enabled);
    }
    assert_eq!(
        chunks, 14,
        "12 steps of both runs together and 5 × 12 COIN steps in chunks of 5"
    );
    let view = live.view();
    assert!(view.finished);
    assert_eq!((view.runs_done, view.step, view.series_len), (2, 12, 12));
    // The live study is the batch study, bit for bit.
    let (summary, report) = run_study(&config).unwrap();
    assert_eq!(view.report, report);
    assert_eq!(view.nees, summary.nees_series.concat());
    assert_eq!(view.coin, summary.coin_series.concat());
    // Golden data (shared with the wasm test).
    let ours = golden_of(&view, &config);
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/golden/tiny_study.json");
    if std::env::var_os("NMCI_BLESS").is_some() {
        std::fs::write(path, serde_json::to_string_pretty(&ours).unwrap() + "\n").unwrap();
    }
    let stored: golden::GoldenStudy = serde_json::from_str(golden::TINY_STUDY).unwrap();
    assert_eq!(stored.config, config);
    golden::within_1e9(
        &golden::headline(&ours.report),
        &golden::headline(&stored.report),
    )
    .unwrap();
    for (a, b) in [
        (&ours.nees, &stored.nees),
        (&ours.rmse, &stored.rmse),
        (&ours.two_sigma, &stored.two_sigma),
        (&ours.omega, &stored.omega),
        (&ours.coin, &stored.coin),
    ] {
        golden::within_1e9(a, b).unwrap();
    }
}

/// The page's two run workers: a study running `WORKER_RULES[0]` and absorbing the tails of a
/// `LiveRules` running `WORKER_RULES[1]` shows, after every chunk, the view of one study running
/// every rule — bit for bit, the COIN after the runs included. Between its own chunk and the
/// second worker's tail it shows the steps both reached (its own truncated, with the group
/// sums of that step).
#[test]
fn a_study_shared_by_two_workers_is_the_one_worker_study_bit_for_bit() {
    assert_eq!(
        WORKER_RULES.concat().len(),
        STUDY_RULES.len(),
        "the two workers share every rule"
    );
    assert!(STUDY_RULES
        .iter()
        .all(|r| WORKER_RULES.concat().contains(r)));
    for (config, chunk) in [
        (tiny_config(), 5),
        (
            StudyConfig {
                runs: 3,
                steps: 9,
                coin: false,
                ..tiny_config()
            },
            2,
        ),
    ] {
        let mut whole = LiveStudy::new(config.clone()).unwrap();
        let mut first = LiveStudy::with_second_worker(config.clone()).unwrap();
        let mut second = LiveRules::new(config.clone()).unwrap();
        assert_eq!(first.view(), whole.view());
        let mut before = whole.view();
        let mut tails = std::collections::VecDeque::new();
        let mut chunks = 0;
        loop {
            let done = whole.advance(chunk).unwrap();
            assert!(!first.advance(chunk).unwrap() || done);
            chunks += 1;
            if first.waiting() {
                // Waiting: no work, and the view of the steps both reached.
                assert!(!first.advance(chunk).unwrap());
                assert_eq!(first.view(), before, "chunk {chunk}, {chunks} chunks");
            }
            // The second worker may be ahead: its tails wait in a queue.
            while first.waiting() {
                if tails.is_empty() {
                    second.advance(chunk).unwrap();
                    tails.push_back(second.tail());
                    second.advance(chunk).unwrap();
                    tails.push_back(second.tail());
                }
                first.absorb(tails.pop_front().unwrap()).unwrap();
            }
            let view = first.view();
            assert_eq!(view, whole.view(), "chunk {chunk}, {chunks} chunks");
            assert_eq!(first.charts(), whole.charts());
            before = view;
            if done {
                assert!(first.finished());
                break;
            }
        }
        let (summary, report) = run_study(&config).unwrap();
        assert_eq!(before.report, report);
        assert_eq!(before.nees, summary.nees_series.concat());
    }
}

/// Tails that do not fit are refused with what is wrong, and the study is unchanged.
#[test]
fn a_study_refuses_second_worker_steps_that_do_not_fit() {
    let config = StudyConfig {
        coin: false,
        ..tiny_config()
    };
    let mut second = LiveRules::new(config.clone()).unwrap();
    second.advance(4).unwrap();
    let four = second.tail();
    assert_eq!((four.from, four.end()), (0, 4));
    second.advance(4).unwrap();
    let eight = second.tail();
    assert_eq!((eight.from, eight.end()), (4, 8));
    let e = LiveStudy::new(config.clone())
        .unwrap()
        .absorb(four.clone())
        .unwrap_err();
    assert_eq!(
        e.to_string(),
        "two-worker study: this study runs every rule itself: it takes no second worker's steps"
    );
    let mut first = LiveStudy::with_second_worker(config.clone()).unwrap();
    let e = first.absorb(four.clone()).unwrap_err();
    assert_eq!(
        e.to_string(),
        "two-worker study: the second worker's steps reach step 4 but this worker's runs are at step 0"
    );
    first.advance(4).unwrap();
    assert!(first.waiting());
    let e = first.absorb(eight.clone()).unwrap_err();
    assert_eq!(
        e.to_string(),
        "two-worker study: the second worker's steps start at step 4 but step 0 is next"
    );
    let mut one_run = four.clone();
    one_run.traces.pop();
    let e = first.absorb(one_run).unwrap_err();
    assert_eq!(
        e.to_string(),
        "two-worker study: the second worker sent 1 runs, the study has 2"
    );
    let mut short = four.clone();
    short.traces[1].rmse[2].pop();
    let e = first.absorb(short).unwrap_err();
    assert_eq!(
        e.to_string(),
        "two-worker study: a run of the second worker's steps does not have 3 series of 4 steps and 4 groups"
    );
    assert!(first.waiting());
    first.absorb(four).unwrap();
    assert!(!first.waiting());
}

#[test]
fn live_study_rejects_an_invalid_configuration() {
    let config = StudyConfig {
        agent: 7,
        watched: 1,
        ..tiny_config()
    };
    let e = LiveStudy::new(config).err().unwrap();
    assert_eq!(
        e.to_string(),
        "invalid scenario: agent 7 has no link to agent 1"
    );
}

#[test]
fn the_parallel_study_split_by_rule_is_the_sequential_study_bit_for_bit() {
    let config = StudyConfig {
        runs: 3,
        steps: 9,
        seed: 8,
        ..StudyConfig::default()
    };
    let model = Model::new(&config.scenario).unwrap();
    let pieces = std::sync::atomic::AtomicUsize::new(0);
    let parallel = simulate_runs_parallel(&config, &model, || {
        pieces.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    })
    .unwrap();
    assert_eq!(pieces.into_inner(), run_pieces(3, STUDY_RULES.len()));
    for (r, trace) in parallel.iter().enumerate() {
        let sequential = simulate_run(&model, &config.run_spec(r as u64, Storage::Blocks)).unwrap();
        assert_eq!(trace, &sequential, "run {r}");
    }
}

/// Runs batched together share their covariances and keep their own means: each run of a
/// batch — any set of run indices, in any order, one rule or all — is bit for bit the run
/// alone, so no run's means leak into another's and the shared covariance side is what each
/// run alone computes.
#[test]
fn a_batch_of_runs_is_each_run_alone_bit_for_bit() {
    let config = StudyConfig {
        runs: 4,
        steps: 14,
        seed: 21,
        ..StudyConfig::default()
    };
    let model = Model::new(&config.scenario).unwrap();
    let spec = config.run_spec(0, Storage::Blocks);
    let alone: Vec<RunTrace> = [5u64, 0, 2]
        .iter()
        .map(|&r| simulate_run(&model, &config.run_spec(r, Storage::Blocks)).unwrap())
        .collect();
    let mut batch = RunBatch::new(&model, &spec, [5u64, 0, 2], &STUDY_RULES);
    while !batch.finished() {
        batch.step(&model).unwrap();
    }
    let batched = batch.into_traces();
    assert_eq!(batched.len(), 3);
    for (k, (b, a)) in batched.iter().zip(&alone).enumerate() {
        assert_eq!(b, a, "run {k} of the batch");
    }
    // The runs differ (else sharing would be untested) ...
    assert_ne!(alone[0].rmse, alone[1].rmse);
    // ... and so do the rules' series within a run.
    assert_ne!(alone[0].nees[1], alone[0].nees[2]);
    for rule in STUDY_RULES {
        let by_rule = simulate_runs_for_rule(&model, &spec, 1..4, rule).unwrap();
        for (k, trace) in by_rule.iter().enumerate() {
            let run = 1 + k as u64;
            let single =
                simulate_run_for_rule(&model, &config.run_spec(run, Storage::Blocks), rule)
                    .unwrap();
            assert_eq!(trace, &single, "{rule:?} run {run}");
        }
    }
}

#[test]
fn an_explicit_edge_list_equal_to_rings_and_bridges_gives_bit_identical_studies() {
    // The default network written out: a ring in each group of four, then the bridges; and
    // the default target assignment written out.
    let mut edges = Vec::new();
    for g in 0..4 {
        for k in 0..4 {
            // listed in another order and orientation than `links()` makes them
            edges.push((4 * g + (k + 1) % 4 + 1, 4 * g + k + 1));
        }
    }
    edges.extend(Scenario::default().bridges.iter().map(|&(a, b)| (b, a)));
    edges.reverse();
    let targets: Vec<[usize; 2]> = (0..16)
        .map(|a| [5 * (a / 4) + a % 4 + 1, 5 * (a / 4) + a % 4 + 2])
        .collect();
    let explicit = StudyConfig {
        scenario: Scenario {
            bridges: vec![],
            edges,
            targets,
            ..Scenario::default()
        },
        ..tiny_config()
    };
    let (a, ra) = run_study(&tiny_config()).unwrap();
    let (b, rb) = run_study(&explicit).unwrap();
    assert_eq!(a, b);
    assert_eq!(ra, rb);
    assert_eq!(
        Scenario::default().neighbours(),
        explicit.scenario.neighbours()
    );
}

#[test]
fn invalid_networks_are_rejected_by_name() {
    let with = |edges: Vec<(usize, usize)>| Scenario {
        bridges: vec![],
        edges,
        ..Scenario::default()
    };
    let mut ring: Vec<(usize, usize)> = (1..16).map(|a| (a, a + 1)).collect();
    let cases = [
        (
            Scenario {
                edges: vec![(1, 2)],
                ..Scenario::default()
            },
            "not both",
        ),
        (
            with(vec![(1, 17)]),
            "edge 1–17 names an agent outside 1..=16",
        ),
        (with(vec![(3, 3)]), "edge 3–3 links an agent to itself"),
        (with(vec![(1, 2), (2, 1)]), "edge 2–1 is listed twice"),
        (
            with(ring.clone()),
            "", // a path through all 16 agents is connected: accepted
        ),
        (
            {
                ring.retain(|&e| e != (8, 9));
                with(ring)
            },
            "not connected: agent 9 cannot be reached from agent 1",
        ),
        (
            // Rings and bridges: group 1 joined to nothing (agent 1 reaches only its own ring).
            Scenario {
                bridges: vec![(7, 11), (12, 13)],
                ..Scenario::default()
            },
            "the network is not connected: agent 5 cannot be reached from agent 1",
        ),
        (
            Scenario {
                targets: vec![[1, 2]; 3],
                ..Scenario::default()
            },
            "`targets` has 3 entries; give one pair per agent (16)",
        ),
        (
            Scenario {
                targets: vec![[1, 21]; 16],
                ..Scenario::default()
            },
            "`targets` of agent 1: [1, 21] must be two different targets among 1..=20",
        ),
    ];
    for (scenario, expected) in cases {
        match scenario.validate() {
            Ok(()) => assert!(expected.is_empty(), "accepted, expected: {expected}"),
            Err(e) => {
                assert!(!expected.is_empty(), "rejected: {e}");
                assert!(
                    e.to_string().contains(expected),
                    "{e}\n  expected: {expected}"
                );
            }
        }
    }
}

// ---- The network sweep (src/sim/sweep.rs) ----

/// A study on the network of `bridges` (rings plus these links between groups).
fn on_network(bridges: &[(usize, usize)], steps: usize) -> StudyConfig {
    StudyConfig {
        steps,
        runs: 1,
        seed: 4,
        scenario: Scenario {
            bridges: bridges.to_vec(),
            ..Scenario::default()
        },
        ..StudyConfig::default()
    }
}

#[test]
fn the_covariance_only_recursion_gives_the_monte_carlo_omega_and_two_sigma_bit_for_bit() {
    for bridges in [Scenario::default().bridges, FIGURE_BRIDGES.to_vec()] {
        let config = on_network(&bridges, 25);
        let model = Model::new(&config.scenario).unwrap();
        for run in [0, 3] {
            let spec = config.run_spec(run, Storage::Blocks);
            let ci_run = simulate_run_for_rule(&model, &spec, StudyRule::Ci).unwrap();
            let nm_run = simulate_run_for_rule(&model, &spec, StudyRule::Nmci).unwrap();
            let ci = covariance_series(&config, StudyRule::Ci).unwrap();
            let nm = covariance_series(&config, StudyRule::Nmci).unwrap();
            assert_eq!(ci.omega.len(), 25);
            assert_eq!(
                ci.omega.iter().map(|w| w[0]).collect::<Vec<_>>(),
                ci_run.omega_ci
            );
            assert_eq!(nm.omega, nm_run.omega_nmci);
            assert_eq!(ci.two_sigma, ci_run.two_sigma[1]);
            assert_eq!(nm.two_sigma, nm_run.two_sigma[1]);
        }
    }
}

/// Sum of hop distances from agent `from` (0-based), breadth-first; written here, not shared
/// with the library.
fn closeness_sum(sc: &Scenario, from: usize) -> usize {
    let nb = sc.neighbours();
    let mut dist = vec![usize::MAX; nb.len()];
    dist[from] = 0;
    let mut frontier = vec![from];
    let mut d = 0;
    while !frontier.is_empty() {
        d += 1;
        let mut next = Vec::new();
        for v in frontier {
            for &w in &nb[v] {
                if dist[w] == usize::MAX {
                    dist[w] = d;
                    next.push(w);
                }
            }
        }
        frontier = next;
    }
    assert!(dist.iter().all(|&d| d != usize::MAX));
    dist.iter().sum()
}

#[test]
fn the_text_conditions_reject_networks_that_break_them() {
    let with = |bridges: &[(usize, usize)]| Scenario {
        bridges: bridges.to_vec(),
        ..Scenario::default()
    };
    assert_eq!(check_text(&Scenario::default()), Ok(()));
    // The figure's reading: 7 hears of groups 3–4 only through 11.
    assert_eq!(
        check_text(&with(&FIGURE_BRIDGES)),
        Err(TextMismatch::OnlyThrough11)
    );
    // Agent 3 reaches 11 over 3–12 without passing through 7.
    assert_eq!(
        check_text(&with(&[(4, 7), (7, 10), (7, 11), (3, 12), (12, 13)])),
        Err(TextMismatch::Bypasses7 { agent: 1 })
    );
    // Over 8–14, 14–13, 13–12: agent 5 (the first of 1–8 that can; group 1 hangs on 4–7)
    // reaches 11 through 8 without passing through 7.
    assert_eq!(
        check_text(&with(&[(4, 7), (7, 10), (7, 11), (8, 14), (12, 13)])),
        Err(TextMismatch::Bypasses7 { agent: 5 })
    );
    assert_eq!(
        check_text(&with(&[(4, 7), (7, 10), (10, 11), (12, 13)])),
        Err(TextMismatch::No7To11)
    );
    // A group that is a path, not a ring (explicit edges without 9–12).
    let mut edges: Vec<(usize, usize)> = Scenario::default()
        .links()
        .into_iter()
        .map(|(a, b)| (a + 1, b + 1))
        .filter(|&l| l != (9, 12))
        .collect();
    edges.push((1, 9));
    let path = Scenario {
        bridges: vec![],
        edges: edges.clone(),
        ..Scenario::default()
    };
    path.validate().unwrap();
    assert_eq!(
        check_text(&path),
        Err(TextMismatch::NoRing {
            group: 3,
            a: 12,
            b: 9
        })
    );
    assert_eq!(
        check_text(&Scenario {
            groups: 2,
            agents_per_group: 8,
            targets_per_group: 10,
            ..with(&[])
        }),
        Err(TextMismatch::NotFourGroupsOfFour {
            groups: 2,
            per_group: 8
        })
    );
}

#[test]
fn the_sweep_enumerates_every_fitting_network_and_seven_is_always_more_central() {
    let base = Scenario::default();
    let one = candidate_networks(&base, NetworkFamily::Bridges { extra: 1 });
    let two = candidate_networks(&base, NetworkFamily::Bridges { extra: 2 });
    // Counts from an independent enumeration (a Python script over the same conditions).
    assert_eq!((one.len(), two.len()), (7, 238));
    assert_eq!(&two[..7], &one[..]);
    assert!(two.contains(&base.bridges));
    let mut seen = std::collections::BTreeSet::new();
    for links in &two {
        assert!(seen.insert(links.clone()), "listed twice: {links:?}");
        for fixed in FIGURE_BRIDGES {
            assert!(links.contains(&fixed));
        }
        let sc = Scenario {
            bridges: links.clone(),
            ..base.clone()
        };
        assert_eq!(check_text(&sc), Ok(()), "{links:?}");
        // The module docs prove agent 7 strictly more central than 11 under the conditions.
        assert!(closeness_sum(&sc, 6) < closeness_sum(&sc, 10), "{links:?}");
    }
    assert_eq!(
        candidate_networks(&base, NetworkFamily::Links { count: 1 }),
        Vec::<Vec<_>>::new()
    );
    // The other family: 7–11 and any two more links (connected networks only).
    let links = candidate_networks(&base, NetworkFamily::Links { count: 3 });
    assert_eq!(links.len(), 768);
    for l in &links {
        let sc = Scenario {
            bridges: l.clone(),
            ..base.clone()
        };
        assert!(closeness_sum(&sc, 6) < closeness_sum(&sc, 10), "{l:?}");
    }
}

#[test]
fn a_small_sweep_ranks_by_distance_and_runs_the_monte_carlo_for_the_short_list() {
    let config = SweepConfig {
        study: StudyConfig {
            steps: 8,
            runs: 2,
            ..StudyConfig::default()
        },
        family: NetworkFamily::Bridges { extra: 1 },
        short_list: 3,
        ..SweepConfig::default()
    };
    let calls = std::sync::atomic::AtomicUsize::new(0);
    let report = sweep(&config, |_, total| {
        // 8 networks × 2 rules, then (3 short-listed + 1 reference) × 2 rules of Monte Carlo.
        assert_eq!(total, 2 * 8 + 2 * (3 + 1));
        calls.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    })
    .unwrap();
    assert_eq!(calls.into_inner(), 2 * 8 + 2 * 4);
    assert_eq!(report.fitting, 7);
    assert_eq!(report.ranked.len(), 7);
    let (short, rest) = report.ranked.split_at(3);
    for part in [short, rest] {
        assert!(part.windows(2).all(|w| w[0].distance <= w[1].distance));
    }
    assert!(short
        .iter()
        .all(|c| c.rmse.is_some() && c.text_mismatch.is_none()));
    assert!(rest.iter().all(|c| c.rmse.is_none()));
    // Each candidate's numbers are its network's covariance-only recursion.
    for c in &report.ranked {
        let study = config.network(&c.links);
        let ci = covariance_series(&study, StudyRule::Ci).unwrap();
        let last_half = |v: Vec<f64>| v[4..].iter().sum::<f64>() / 4.0;
        assert_eq!(
            c.omega_ci,
            last_half(ci.omega.iter().map(|w| w[0]).collect())
        );
        let nm = covariance_series(&study, StudyRule::Nmci).unwrap();
        let two_sigma = |s: &[f64]| s.iter().sum::<f64>() / 8.0;
        assert_eq!(
            c.two_sigma,
            [two_sigma(&ci.two_sigma), two_sigma(&nm.two_sigma)]
        );
    }
    // The Monte Carlo RMSE is the study's.
    let best = &report.ranked[0];
    let study = config.network(&best.links);
    let (summary, _) = run_study(&study).unwrap();
    let rmse = |name: &str| {
        summary
            .estimators
            .iter()
            .find(|(n, _)| n == name)
            .unwrap()
            .1
            .rmse_mean
    };
    assert_eq!(best.rmse, Some([rmse("ci"), rmse("nmci")]));
    // The figure's reading is evaluated as a reference and marked as not fitting the text.
    assert_eq!(report.references.len(), 1);
    assert_eq!(report.references[0].links, FIGURE_BRIDGES.to_vec());
    assert_eq!(
        report.references[0].text_mismatch.as_deref(),
        Some("no agent of groups 3–4 reaches agent 7 without passing through agent 11")
    );
    assert_eq!(report.references[0].omega_nmci[4..], [0.0; 4]);
}

#[test]
fn invalid_sweeps_are_rejected_by_name() {
    let bad = |family| SweepConfig {
        family,
        ..SweepConfig::default()
    };
    for (config, message) in [
        (
            bad(NetworkFamily::Bridges { extra: 4 }),
            "invalid scenario: extra links: at most 3 (got 4; the count grows as 93^extra)",
        ),
        (
            bad(NetworkFamily::Links { count: 0 }),
            "invalid scenario: links between groups: 1 to 4 (got 0; the count grows as 95^(count−1))",
        ),
    ] {
        assert_eq!(sweep(&config, |_, _| {}).unwrap_err().to_string(), message);
    }
}

#[test]
fn per_group_rmse_and_two_sigma_recombine_into_the_totals() {
    // One step of one run: each group has 5 targets (10 position coordinates), so the
    // squared total RMSE is the mean of the groups' squared RMSEs, and likewise (2σ/2)².
    let config = StudyConfig {
        steps: 2,
        runs: 1,
        ..StudyConfig::default()
    };
    let model = Model::new(&config.scenario).unwrap();
    let mut run = RunState::new(&model, &config.run_spec(0, Storage::Blocks));
    run.step(&model).unwrap();
    let s = summarize(std::slice::from_ref(run.trace()), model.dim());
    for (k, (name, e)) in s.estimators.iter().enumerate() {
        assert_eq!(e.rmse_by_group.len(), 4, "{name}");
        let mean_square = |v: &[f64], half: f64| {
            v.iter().map(|x| (x * half).powi(2)).sum::<f64>() / v.len() as f64
        };
        let (rmse, two_sigma) = (s.rmse_series[k][0], s.two_sigma_series[k][0]);
        assert!((mean_square(&e.rmse_by_group, 1.0) - rmse * rmse).abs() <= 1e-12 * rmse * rmse);
        let var = (two_sigma / 2.0).powi(2);
        assert!(
            (mean_square(&e.two_sigma_by_group, 0.5) - var).abs() <= 1e-12 * var,
            "{name}"
        );
        // And each group's own error, from the run's error vector directly.
        let err = run.error(k, 6).unwrap();
        for g in 0..4 {
            let se: f64 = (5 * g..5 * g + 5)
                .flat_map(|t| [4 * t, 4 * t + 2])
                .map(|i| err[i] * err[i])
                .sum();
            assert!((e.rmse_by_group[g] - (se / 5.0).sqrt()).abs() <= 1e-12 * e.rmse_by_group[g]);
        }
    }
}

/// The steady-state value the study reports: the mean over the last half of the steps.
fn steady(values: impl Iterator<Item = f64>) -> f64 {
    let v: Vec<f64> = values.collect();
    v[v.len() / 2..].iter().sum::<f64>() / (v.len() - v.len() / 2) as f64
}

/// The first steps, at which the two agents still hold equal covariances of a far group's
/// block (a flat criterion: `ω = ½`, its midpoint).
const TIE_STEPS: usize = 2;

#[test]
fn the_documented_weights_and_two_sigma_of_both_networks() {
    // docs/reproduction.md and docs/study.md quote these (400 steps; the covariance-only
    // recursion is every Monte Carlo run's, bit for bit, so they hold for every run).
    for (name, config, omega_ci, far, reduction) in [
        (
            "paper",
            config_file("paper.toml"),
            0.8716,
            [0.4691, 0.5320],
            -0.520,
        ),
        (
            "bridges",
            config_file("bridges.toml"),
            0.6573,
            [0.0, 0.0],
            -0.551,
        ),
    ] {
        let ci = covariance_series(&config, StudyRule::Ci).unwrap();
        let nm = covariance_series(&config, StudyRule::Nmci).unwrap();
        assert_eq!(nm.omega.len(), 400);
        let w_ci = steady(ci.omega.iter().map(|w| w[0]));
        assert!((w_ci - omega_ci).abs() < 1e-4, "{name}: CI ω {w_ci}");
        // Groups 1–2: exactly 1 at every step.
        assert!(nm.omega.iter().all(|w| w[..4] == [1.0; 4]), "{name}");
        for (g, expected) in far.iter().enumerate() {
            for axis in 0..2 {
                let b = 4 + 2 * g + axis;
                let w = steady(nm.omega.iter().map(|w| w[b]));
                assert!((w - expected).abs() < 1e-4, "{name}: block {b} ω {w}");
                if *expected == 0.0 {
                    // Exactly 0 at every step, not just on average, but where both agents
                    // hold equal covariances (a flat criterion: its midpoint, ½).
                    let ties: Vec<usize> = (0..nm.omega.len())
                        .filter(|&k| nm.omega[k][b] != 0.0)
                        .collect();
                    assert!(
                        ties.iter().all(|&k| nm.omega[k][b] == 0.5 && k < TIE_STEPS),
                        "{name}: block {b}: not 0 at steps {ties:?}"
                    );
                } else {
                    // Strictly inside (0, 1) from the third step on.
                    assert!(
                        nm.omega[2..].iter().all(|w| w[b] > 0.0 && w[b] < 1.0),
                        "{name}: block {b}"
                    );
                }
            }
        }
        let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
        let r = mean(&nm.two_sigma) / mean(&ci.two_sigma) - 1.0;
        assert!((r - reduction).abs() < 5e-4, "{name}: 2σ {r}");
    }
}

/// Shards of a study, run separately and merged in any order, are the one study bit for bit
/// (traces, summary with COIN, report); every way shards can fail to make one study is
/// refused with its reason.
#[test]
fn shards_merged_in_any_order_are_the_whole_study_bit_for_bit() {
    use nmci::study::{
        merge_shards, run_shard, study_parallel, MergeError, StudyShard, SHARD_FORMAT,
    };
    let config = StudyConfig {
        runs: 5,
        steps: 8,
        seed: 4,
        ..StudyConfig::default()
    };
    let model = Model::new(&config.scenario).unwrap();
    let whole = study_parallel(&config, &model, || {}).unwrap();
    assert!(!whole.summary.coin_series.is_empty());
    let shard = |first: usize, runs: usize| {
        run_shard(
            &StudyConfig {
                runs,
                ..config.clone()
            },
            &model,
            first,
            || {},
        )
        .unwrap()
    };
    let (a, b, c) = (shard(0, 2), shard(2, 1), shard(3, 2));
    assert!(a.coin.is_some() && b.coin.is_none() && c.coin.is_none());
    // Through JSON, as shards travel between machines.
    let travel = |s: &StudyShard| -> StudyShard {
        serde_json::from_str(&serde_json::to_string(s).unwrap()).unwrap()
    };
    for order in [[&a, &b, &c], [&c, &a, &b], [&b, &c, &a]] {
        let merged = merge_shards(order.iter().map(|s| travel(s)).collect()).unwrap();
        assert_eq!(merged, whole);
        assert_eq!(merged.report(), whole.report());
    }
    // Refusals.
    let err = |shards: Vec<StudyShard>| merge_shards(shards).unwrap_err();
    assert_eq!(err(vec![]), MergeError::NoShards);
    assert_eq!(
        err(vec![a.clone(), c.clone()]),
        MergeError::Missing { first: 2, end: 3 }
    );
    assert_eq!(
        err(vec![a.clone(), b.clone(), shard(2, 3)]),
        MergeError::Overlap { run: 2 }
    );
    assert_eq!(
        err(vec![b.clone(), c.clone()]),
        MergeError::Missing { first: 0, end: 2 }
    );
    let other_seed = run_shard(
        &StudyConfig {
            runs: 1,
            seed: 5,
            ..config.clone()
        },
        &model,
        2,
        || {},
    )
    .unwrap();
    assert_eq!(
        err(vec![a.clone(), other_seed, c.clone()]),
        MergeError::ConfigMismatch {
            index: 1,
            first_run: 2,
            field: "seed".into()
        }
    );
    let mut bad = b.clone();
    bad.format = "something else".into();
    assert_eq!(
        err(vec![a.clone(), bad, c.clone()]),
        MergeError::Format {
            index: 1,
            found: "something else".into()
        }
    );
    let mut short = c.clone();
    short.traces.pop();
    assert_eq!(
        err(vec![a.clone(), b.clone(), short]),
        MergeError::TraceCount {
            index: 2,
            first_run: 3,
            expected: 2,
            found: 1
        }
    );
    let mut no_coin = a.clone();
    no_coin.coin = None;
    assert!(
        matches!(err(vec![no_coin, b.clone(), c.clone()]), MergeError::Coin(m) if m.contains("carries no COIN"))
    );
    let mut extra_coin = b.clone();
    extra_coin.coin = a.coin.clone();
    assert!(
        matches!(err(vec![a.clone(), extra_coin, c.clone()]), MergeError::Coin(m) if m.contains("belongs only"))
    );
    assert_eq!(a.format, SHARD_FORMAT);
    // A first run past the last run index is refused, not wrapped around.
    let past = run_shard(&config, &model, usize::MAX, || {}).unwrap_err();
    assert!(
        past.to_string().contains("past the last run index"),
        "{past}"
    );
}
