//! [`CertificateMemo`]: the blocks certified most recently, so an edit that leaves a block
//! unchanged does not certify it again.

use nalgebra::DMatrix;

use crate::error::SolveError;
use crate::fusion::FusionProblem;

use super::block::{certify_one_block, BlockOutcome};
use super::settings::CertifySettings;

/// How many certified blocks a [`CertificateMemo`] keeps.
pub const MEMO_BLOCKS: usize = 8;

/// Certified blocks kept for reuse by [`certified_fusion_memo`](super::certified_fusion_memo): the [`MEMO_BLOCKS`] blocks
/// used most recently, each under its exact inputs — the block's `P_a`, `P_b` (bit for bit)
/// and known-zero pattern, and the settings. A block certified before with the same inputs
/// gets the same gain, bound, status, iterations, repair, level and sector count as then,
/// which a fresh solve would give again (the program and its repair are deterministic), so
/// results are the same with and without the memo (tested); only the time differs. The
/// explorer keeps one per worker: an edit inside one block then solves that block alone.
/// Errors are not kept, and settings with a `time_limit` do not use the memo (a solve's
/// outcome then depends on the time it gets).
#[derive(Debug, Default)]
pub struct CertificateMemo {
    pub(super) entries: std::collections::VecDeque<(BlockKey, BlockOutcome)>,
    pub(super) hits: u64,
}

/// The exact inputs of one block's certificate (no given gain).
#[allow(non_snake_case)]
#[derive(Debug, PartialEq)]
pub(super) struct BlockKey {
    pub(super) P_a: Vec<u64>,
    pub(super) P_b: Vec<u64>,
    pub(super) unknown: Vec<bool>,
    pub(super) settings: CertifySettings,
}

impl BlockKey {
    pub(super) fn of(sub: &FusionProblem, settings: &CertifySettings) -> Self {
        let n = sub.dim();
        let bits = |m: &DMatrix<f64>| m.iter().map(|v| v.to_bits()).collect();
        BlockKey {
            P_a: bits(&sub.P_a),
            P_b: bits(&sub.P_b),
            unknown: (0..n)
                .flat_map(|i| (0..n).map(move |j| (i, j)))
                .map(|(i, j)| sub.cross_pattern.is_unknown(i, j))
                .collect(),
            settings: *settings,
        }
    }
}

impl CertificateMemo {
    /// An empty memo.
    pub fn new() -> Self {
        Self::default()
    }

    /// How many blocks were taken from the memo instead of certified.
    pub fn hits(&self) -> u64 {
        self.hits
    }

    /// How many blocks it holds (at most [`MEMO_BLOCKS`]).
    pub fn len(&self) -> usize {
        self.entries.len()
    }

    /// Whether it holds no block.
    pub fn is_empty(&self) -> bool {
        self.entries.is_empty()
    }

    pub(super) fn get_or_certify(
        &mut self,
        sub: &FusionProblem,
        settings: &CertifySettings,
    ) -> Result<BlockOutcome, SolveError> {
        // A solve with a time limit may end differently with other timing: never kept or
        // reused.
        if settings.time_limit.is_some() {
            return certify_one_block(sub, None, settings);
        }
        let key = BlockKey::of(sub, settings);
        if let Some(at) = self.entries.iter().position(|(k, _)| *k == key) {
            self.hits += 1;
            // The most recently used last: the first is evicted next.
            let entry = self.entries.remove(at).expect("found above");
            let outcome = entry.1.clone();
            self.entries.push_back(entry);
            return Ok(outcome);
        }
        let outcome = certify_one_block(sub, None, settings)?;
        if self.entries.len() == MEMO_BLOCKS {
            self.entries.pop_front();
        }
        self.entries.push_back((key, outcome.clone()));
        Ok(outcome)
    }
}
