//! The explorer's memo of certified blocks, checked on both targets.
#![allow(dead_code)]

use nmci::{
    certify::CertificateMemo,
    explore::{explore, explore_with_memo, ExploreRequest},
};

/// A sequence of explorer states analysed with one memo of certified blocks: each analysis
/// equals a fresh one bit for bit, and the memo's hits and size are as expected (the native
/// test `explore::the_memo_…` and the wasm test in `tests/web.rs` run it).
pub fn memo_sequence_matches_fresh_analyses() {
    // The two-block preset with one known zero in each cross block: two 24-sector proofs.
    // `p11` is P_a[1][1] (block 1), `sectors` the certified rule's setting.
    let state = |p11: f64, sectors: u32| {
        serde_json::from_str::<ExploreRequest>(&format!(
            r#"{{"pa": [[{p11}, 0.5, 0, 0], [0.5, 1, 0, 0], [0, 0, 1, 0.2], [0, 0, 0.2, 2]],
                "pb": [[1, -0.3, 0, 0], [-0.3, 2, 0, 0], [0, 0, 4, 1], [0, 0, 1, 2]],
                "pab_unknown": [[true, true, false, false], [false, true, false, false],
                                [false, false, true, true], [false, false, false, true]],
                "samples": 50, "region_samples": 40, "sectors": {sectors}}}"#
        ))
        .unwrap()
    };
    // The page's largest size (n = 6): three 2 × 2 blocks, one known zero in each cross block.
    let six = |p11: f64| {
        let blocks = [
            ([[p11, 0.4], [0.4, 1.0]], [[1.0, 0.2], [0.2, 3.0]]),
            ([[1.0, 0.0], [0.0, 2.0]], [[2.5, 0.6], [0.6, 1.0]]),
            ([[2.0, -0.5], [-0.5, 1.5]], [[1.0, 0.3], [0.3, 2.5]]),
        ];
        let dense = |which: usize| {
            let mut m = vec![vec![0.0; 6]; 6];
            for (b, pair) in blocks.iter().enumerate() {
                let block = if which == 0 { pair.0 } else { pair.1 };
                for i in 0..2 {
                    for j in 0..2 {
                        m[2 * b + i][2 * b + j] = block[i][j];
                    }
                }
            }
            m
        };
        let unknown: Vec<Vec<bool>> = (0..6)
            .map(|i| {
                (0..6)
                    .map(|j| i / 2 == j / 2 && !(i % 2 == 1 && j + 1 == i))
                    .collect()
            })
            .collect();
        serde_json::from_value::<ExploreRequest>(serde_json::json!({
            "pa": dense(0), "pb": dense(1), "pab_unknown": unknown,
            "samples": 50, "region_samples": 40
        }))
        .unwrap()
    };
    let mut memo = CertificateMemo::new();
    // Each step: the state, then the hits and blocks held the memo must show after it.
    let steps = [
        (state(3.0, 24), 0, 2),
        (state(3.1, 24), 1, 3), // block 1 edited: block 2 reused
        (state(3.0, 24), 3, 3), // back: both blocks reused
        (state(3.0, 16), 3, 5), // another setting: a different certificate
        (six(3.0), 3, 8),       // three new blocks: the memo full
        // Block 1 edited: its new proof evicts the least recently used entry, never a block
        // of the state before (the memo keeps more blocks than a page state has, n ≤ 6).
        (six(3.1), 5, 8),
    ];
    for (k, (req, hits, held)) in steps.iter().enumerate() {
        let with = explore_with_memo(req, &mut memo).unwrap();
        let without = explore(req).unwrap();
        assert_eq!(with, without, "step {k}: the same analysis, bit for bit");
        if k == 0 {
            let certs = with.gap.as_ref().unwrap().certificates.clone().unwrap();
            assert_eq!(certs.sectors, vec![24, 24], "two proofs on 24 sectors");
        }
        assert_eq!((memo.hits(), memo.len()), (*hits, *held), "step {k}");
    }
}
