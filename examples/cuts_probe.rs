//! The cutting planes guided by the certified rule vs not, as a table (docs/benchmarks.md,
//! "The cutting planes"; read in docs/methods.md): two random non-separable problems per
//! dimension (seed 55, each entry of `P_ab` unknown with probability 0.6), default settings;
//! constraints in the final program (generated in the whole run), outer iterations, time, the
//! proven bracket and whether it is closed to `10⁻⁶`, why the loop stopped, and the worst
//! `λ_min(P̄ − K P' Kᵀ) / tr P̄` of the loop's own solution over 10⁴ fresh hit-and-run samples.
//!
//! `cargo run --release --example cuts_probe -- 3 4 5 6` (`PROBE_GUIDED_ONLY=1`: guided only)
#![allow(non_snake_case)]
use nalgebra::DMatrix;
use nmci::{check::*, sample::*, sdp::*, structure::*, *};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
// The tests' seeded generators (same draws: the documented numbers are unchanged).
#[path = "../tests/common/mod.rs"]
mod common;
use common::random_spd;

fn main() {
    let dims: Vec<usize> = std::env::args()
        .skip(1)
        .map(|a| a.parse().unwrap())
        .collect();
    let mut r = ChaCha8Rng::seed_from_u64(55);
    println!("| n | guided | LMIs (generated) | iterations | time | proven bracket `[lower, upper]` | closed (≤ 1e-6) | stop | fresh margin / tr |");
    println!("|---|---|---|---|---|---|---|---|---|");
    for &n in &dims {
        let mut done = 0;
        while done < 2 {
            let pat = CrossPattern::from_matrix(DMatrix::from_fn(n, n, |_, _| r.random_bool(0.6)))
                .unwrap();
            let p =
                FusionProblem::from_covariances(random_spd(n, &mut r), random_spd(n, &mut r), pat)
                    .unwrap();
            if independent_blocks(&p.P_a, &p.P_b, &p.cross_pattern).len() > 1
                || p.cross_pattern.unknown_count() == n * n
            {
                continue;
            }
            done += 1;
            let modes: &[bool] = if std::env::var("PROBE_GUIDED_ONLY").is_ok() {
                &[true]
            } else {
                &[true, false]
            };
            for &certify in modes {
                let t = std::time::Instant::now();
                let c = match optimal_fusion_cuts(
                    &p,
                    &CutsSettings {
                        certify,
                        ..Default::default()
                    },
                ) {
                    Ok(c) => c,
                    // A solver failure is the loop's answer too: a row, never hidden.
                    Err(e) => {
                        let seconds = t.elapsed().as_secs_f64();
                        let guided = if certify { "yes" } else { "no" };
                        println!(
                            "| {n} | {guided} | – | – | {seconds:.1} s | – | no | error: {e} | – |"
                        );
                        continue;
                    }
                };
                let seconds = t.elapsed().as_secs_f64();
                let fresh =
                    sample_cross_covariances(&p, 10_000, 99, SamplerSettings::hit_and_run())
                        .unwrap();
                let margin = worst_margin(&p, &c.fused, &fresh.cross).unwrap() / c.fused.trace();
                let (upper, closed) = match c.certified_trace {
                    Some(u) => (
                        format!("{u:.6}"),
                        if u - c.lower_bound <= bounds::CLOSED_RTOL * u {
                            "yes"
                        } else {
                            "no"
                        },
                    ),
                    None => ("–".into(), "no"),
                };
                println!(
                    "| {n} | {} | {} ({}) | {} | {seconds:.1} s | [{:.6}, {upper}] | {closed} | {:?} | {margin:.1e} |",
                    if certify { "yes" } else { "no" },
                    c.constraints,
                    c.constraints_generated,
                    c.iterations,
                    c.lower_bound,
                    c.stop,
                );
            }
        }
    }
}
