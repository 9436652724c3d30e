//! The cutting planes guided by the certified rule vs not (numbers in docs/methods.md): two random non-separable problems per dimension (seed 55, each entry of
//! `P_ab` unknown with probability 0.6).
//!
//! `cargo run --release --example cuts_probe -- 3 4 5 6`
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
                let c = optimal_fusion_cuts(
                    &p,
                    &CutsSettings {
                        certify,
                        ..Default::default()
                    },
                )
                .unwrap();
                let seconds = t.elapsed().as_secs_f64();
                let fresh =
                    sample_cross_covariances(&p, 10_000, 99, SamplerSettings::hit_and_run())
                        .unwrap();
                let margin = worst_margin(&p, &c.fused, &fresh.cross).unwrap() / c.fused.trace();
                println!("n={n} certify={certify}: tr {:.6} proven lower {:.6} certified {:?} closed {} stop {:?} it {} cons {} of {} viol {:.1e} ({seconds:.1}s) fresh margin/tr {margin:.1e}", c.fused.trace(), c.lower_bound, c.certified_trace, c.gap_closed, c.stop, c.iterations, c.constraints, c.constraints_generated, c.violation);
            }
        }
    }
}
