//! The tracking study's core: derived structure, block storage equal to dense storage,
//! reproducibility, and the qualitative results of a reduced study.
#![cfg(not(target_arch = "wasm32"))] // native tests; tests/web.rs runs in the browser

use nmci::sim::*;

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
    // Agent 7's neighbours, ascending: 4 (bridge), 6, 8 (ring), 11 (bridge); 1-based.
    assert_eq!(sc.neighbours()[6], vec![3, 5, 7, 10]);
}

#[test]
fn block_storage_gives_the_dense_numbers() {
    let model = Model::new(&Scenario::default()).unwrap();
    let blocks = simulate_run(&model, &spec(3, 5, 0, Storage::Blocks)).unwrap();
    let dense = simulate_run(&model, &spec(3, 5, 0, Storage::Dense)).unwrap();
    let close = |a: &[f64], b: &[f64]| {
        a.iter()
            .zip(b)
            .all(|(x, y)| (x - y).abs() <= 1e-9 * x.abs().max(1.0))
    };
    for s in 0..5 {
        assert!(
            close(&blocks.nees[s], &dense.nees[s]),
            "NEES {s}: {:?} vs {:?}",
            blocks.nees[s],
            dense.nees[s]
        );
        assert!(close(&blocks.rmse[s], &dense.rmse[s]));
        assert!(close(&blocks.two_sigma[s], &dense.two_sigma[s]));
    }
    assert!(close(&blocks.omega_ci, &dense.omega_ci));
    assert!(close(&blocks.omega_ici, &dense.omega_ici));
    // Dense nmCI finds the same 8 blocks by itself (from the exact zeros and the pattern).
    for (b, d) in blocks.omega_nmci.iter().zip(&dense.omega_nmci) {
        assert_eq!(b.len(), 8);
        assert!(close(b, d), "{b:?} vs {d:?}");
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
    // ω(7←11): groups 1–2 (blocks 0–3) take agent 7's own estimate; groups 3–4 do not.
    assert_eq!(s.omega_nmci.len(), 8);
    assert!(
        s.omega_nmci[..4].iter().all(|w| *w >= 0.95),
        "{:?}",
        s.omega_nmci
    );
    assert!(
        s.omega_nmci[4..].iter().all(|w| *w < 1.0),
        "{:?}",
        s.omega_nmci
    );
    assert!(s.omega_ci > 0.0 && s.omega_ci < 1.0);
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

#[test]
fn configs_study_toml_lists_the_defaults() {
    let text = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/configs/study.toml"))
        .unwrap();
    let parsed: StudyConfig = toml::from_str(&text).unwrap();
    assert_eq!(parsed, StudyConfig::default());
}

#[path = "golden/mod.rs"]
mod golden;

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
        assert!(v.coin_enabled);
    }
    assert_eq!(
        chunks, 16,
        "24 run steps and 5 × 12 COIN steps in chunks of 5"
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
    assert_eq!(pieces.into_inner(), 3 * RULES.len());
    for (r, trace) in parallel.iter().enumerate() {
        let sequential = simulate_run(&model, &config.run_spec(r as u64, Storage::Blocks)).unwrap();
        assert_eq!(trace, &sequential, "run {r}");
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
    edges.extend([(7, 4), (11, 7), (13, 12)]);
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
