//! Every native integration test, in one binary: one link of the crate (and Clarabel)
//! instead of one per file. Each module is one concern; its docs say what it checks.
//! `tests/web.rs` runs in headless Chromium (wasm-pack test) and is not part of this binary.
#![cfg(not(target_arch = "wasm32"))]
#![allow(non_snake_case)] // textbook symbols: P_a, K_b, …

#[path = "../common/mod.rs"]
mod common;
#[path = "../golden/mod.rs"]
mod golden;

mod bracket;
mod certify;
#[cfg(feature = "files")]
mod charts;
mod ci;
mod cuts;
mod docs;
mod explore;
mod fig2;
mod fixtures;
mod fuzz;
mod limits;
mod nmci_rule;
mod nway;
mod properties;
mod registry;
mod rules;
mod sample;
mod scale;
mod sdp;
mod sim;
mod structure;
mod study_coin;
mod validation;
