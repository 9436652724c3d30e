//! `cargo bench --bench study`: the full default tracking study exactly as `nmci track` runs
//! it (15 runs × 400 steps, the centralized filter and CI, nmCI, naive and ICI agents, and the
//! exact COIN of every estimator, in parallel), the paper's workload alone (the runs of the
//! centralized filter and the CI, nmCI and naive agents, no ICI, no COIN: what the ≤ 20 s
//! target was set for), the exact COIN alone, and one run alone. A plain timing harness:
//! criterion's minimum of 10 samples would take minutes for a 20 s workload.
//! `NMCI_STUDY_REPEATS` (default 3) sets the repetitions; the minimum and the median are
//! reported.

use std::time::Instant;

use nmci::sim::{
    coin_parallel, merge_rule_traces, simulate_run, simulate_run_for_rule, study_parallel, Model,
    Rule, Storage, StudyConfig,
};
use rayon::prelude::*;

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
    // The paper's rules only, split into runs × rules pieces as `simulate_runs_parallel` does.
    let paper = [Rule::Ci, Rule::Nmci, Rule::Naive];
    report(
        "study/paper_rules",
        time(&|| {
            let pieces: Vec<(u64, Rule)> = (0..config.runs as u64)
                .flat_map(|r| paper.iter().map(move |&rule| (r, rule)))
                .collect();
            let traces = pieces
                .par_iter()
                .map(|&(r, rule)| {
                    simulate_run_for_rule(&model, &config.run_spec(r, Storage::Blocks), rule)
                        .expect("run")
                })
                .collect::<Vec<_>>();
            let _runs: Vec<_> = traces
                .chunks(paper.len())
                .map(|c| merge_rule_traces(c.to_vec()))
                .collect();
        }),
    );
    report(
        "study/coin",
        time(&|| {
            coin_parallel(&config, &model, || {}).expect("coin");
        }),
    );
}
