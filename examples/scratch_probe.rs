#![allow(non_snake_case)]
use nmci::*;
#[path = "../tests/common/mod.rs"]
mod common;
use common::*;
fn main() {
    let mut r = rng(55);
    for (n, prob) in [(2usize, 0.6), (2, 0.6), (2, 0.6), (2, 0.6), (2, 0.6), (3, 0.6), (3, 0.6)] {
        let p = random_problem(n, random_pattern(n, prob, &mut r), &mut r);
        let ci = covariance_intersection(&p, Criterion::Trace).unwrap().fused.trace();
        let nm = non_monolithic_ci(&p, Criterion::Trace).unwrap().fused.trace();
        print!("n={n} ci {ci:.9} nm {nm:.9}:");
        for level in 1..=5 { if n == 3 && level > 2 { break; }
            for tol in [1e-9, 1e-10] {
            let c = certified_fusion(&p, &CertifySettings { level: Some(level), tolerance: tol, ..Default::default() }).unwrap();
            print!(" L{level}/{tol:e} {:.9} ({:?}, rep {:.1e})", c.fused.trace(), c.status, c.repair);
            }
        }
        println!();
    }
}
