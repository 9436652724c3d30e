//! The README's "how tight" table: nmCI, the certified rule and the cutting planes' lower
//! bound on random non-separable problems (fixed seed).
//!
//! `cargo run --release --example certified_vs_nmci`
#![allow(non_snake_case)]
use nalgebra::DMatrix;
use nmci::*;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

// The tests' seeded generators (same draws: the documented numbers are unchanged).
#[path = "../tests/common/mod.rs"]
mod common;
use common::random_spd;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut rng = ChaCha8Rng::seed_from_u64(55);
    println!("| n | nmCI | certified | lower bound (cuts) | relative gap | certified in |");
    println!("|---|---|---|---|---|---|");
    for (n, count) in [(2usize, 6), (3, 3), (4, 2), (5, 1), (6, 1)] {
        let mut done = 0;
        while done < count {
            let pattern =
                CrossPattern::from_matrix(DMatrix::from_fn(n, n, |_, _| rng.random_bool(0.6)))?;
            let p = FusionProblem::from_covariances(
                random_spd(n, &mut rng),
                random_spd(n, &mut rng),
                pattern,
            )?;
            if independent_blocks(&p.P_a, &p.P_b, &p.cross_pattern).len() > 1
                || p.cross_pattern.unknown_count() == n * n
            {
                continue; // separable or fully unknown: nmCI / CI is optimal there
            }
            done += 1;
            let nm = non_monolithic_ci(&p, Criterion::Trace)?.fused.trace();
            let start = std::time::Instant::now();
            let cert = certified_fusion(&p, &CertifySettings::default())?;
            let seconds = start.elapsed().as_secs_f64();
            let c = cert.fused.trace();
            let (lower, gap) = if n <= 4 {
                let lb = optimal_fusion_cuts(&p, &CutsSettings::default())?.dual_objective;
                (format!("{lb:.4}"), format!("{:.1e}", (c - lb) / c))
            } else {
                ("—".into(), "—".into())
            };
            println!("| {n} | {nm:.4} | {c:.4} | {lower} | {gap} | {seconds:.3} s |");
        }
    }
    Ok(())
}
