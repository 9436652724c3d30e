//! `cargo bench --bench study`: the full default tracking study exactly as `nmci track` runs
//! it (15 runs × 400 steps, the centralized filter and CI, nmCI, naive and ICI agents, and the
//! exact COIN of every estimator, in parallel), the paper's workload alone (the runs of the
//! centralized filter and the CI, nmCI and naive agents, no ICI, no COIN: what the ≤ 20 s
//! target was set for), the exact COIN alone, and one run alone. A plain timing harness:
//! criterion's minimum of 10 samples would take minutes for a 20 s workload.
//! `NMCI_STUDY_REPEATS` (default 3) sets the repetitions; the minimum and the median are
//! reported.

use std::time::Instant;

use nmci::study::{
    coin_parallel, simulate_rules_parallel, simulate_run, study_parallel, Model, Storage,
    StudyConfig, StudyRule,
};

fn report(name: &str, mut seconds: Vec<f64>) {
    seconds.sort_by(f64::total_cmp);
    let median = seconds[seconds.len() / 2];
    println!(
        "{name:<24} min {:>7.2} s   median {:>7.2} s   ({} repeats)",
        seconds[0],
        median,
        seconds.len()
    );
}

fn main() {
    let repeats: usize = std::env::var("NMCI_STUDY_REPEATS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(3)
        .max(1);
    let config = StudyConfig::default();
    let model = Model::new(&config.scenario).expect("the default scenario is valid");
    println!(
        "tracking study: {} runs × {} steps, {} states, {} threads",
        config.runs,
        config.steps,
        model.dim(),
        rayon::current_num_threads()
    );
    let one_run: Vec<f64> = (0..repeats)
        .map(|_| {
            let started = Instant::now();
            simulate_run(&model, &config.run_spec(0, Storage::Blocks)).expect("run");
            started.elapsed().as_secs_f64()
        })
        .collect();
    report("study/one_run", one_run);
    let time = |work: &dyn Fn()| -> Vec<f64> {
        (0..repeats)
            .map(|_| {
                let started = Instant::now();
                work();
                started.elapsed().as_secs_f64()
            })
            .collect()
    };
    report(
        "study/full_default",
        time(&|| {
            study_parallel(&config, &model, || {}).expect("study");
        }),
    );
    // The paper's rules only, in the pieces `simulate_runs_parallel` cuts them into.
    let paper = [StudyRule::Ci, StudyRule::Nmci, StudyRule::Naive];
    report(
        "study/paper_rules",
        time(&|| {
            simulate_rules_parallel(&config, &model, &paper, 0, || {}).expect("runs");
        }),
    );
    report(
        "study/coin",
        time(&|| {
            coin_parallel(&config, &model, || {}).expect("coin");
        }),
    );
}
