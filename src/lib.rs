//! # nmci — conservative fusion when the cross-covariance is unknown except for known zeros
//!
//! Two estimates `(x_a, P_a)`, `(x_b, P_b)` are to be fused into `x = K_a x_a + K_b x_b`
//! with a covariance bound `P̄` that dominates the true fused covariance for every
//! cross-covariance `P_ab` consistent with what is known: the joint covariance is positive
//! definite and the entries of `P_ab` in a known index set `I` are zero. This crate
//! implements the rules of Funk, Dagan, Noack and Ahmed, *Exploiting Structure for Optimal
//! Multi-Agent Bayesian Decentralized Estimation*:
//!
//! | rule | function | bound type |
//! |---|---|---|
//! | CI, exact optimal `ω` (trace or log-det) | [`covariance_intersection`] | conservative (upper bound) |
//! | non-monolithic CI, one `ω` per independent block | [`non_monolithic_ci`] | conservative (upper bound) |
//! | sampled SDP (paper eq. (sampled_sdp)) | [`optimal_fusion`] | optimum is a lower bound on the robust optimum |
//!
//! and the tools around them: [`independent_blocks`] (the structure), the rejection sampler
//! [`sample_cross_covariances`] and [`worst_margin`] (`λ_min(P̄ − K P' Kᵀ)`, the conservativeness
//! check). [`fuse`] is the JSON request/response contract shared by the CLI and the wasm module.
//!
//! ## Symbols
//! Textbook symbols are kept (`#[allow(non_snake_case)]`): `P_a`, `P_b` covariances of the
//! two estimates, `P_ab` their cross-covariance, `x_a`, `x_b` the estimates, `K_a`, `K_b` the
//! gains (`K_a + K_b = I`), `P` / `P̄` the fused bound, `ω` the CI weight on `P_a⁻¹`, `P'` an
//! admissible joint covariance `[[P_a, P_ab'], [P_ab'ᵀ, P_b]]`.
//!
//! ```
//! use nalgebra::{DMatrix, DVector};
//! use nmci::*;
//! let d = |v: &[f64]| DMatrix::from_diagonal(&DVector::from_row_slice(v));
//! // The paper's example: P_a = diag(3, 1), P_b = diag(1, 4), P_ab diagonal.
//! let p = FusionProblem::from_covariances(d(&[3.0, 1.0]), d(&[1.0, 4.0]),
//!     CrossPattern::diagonal(2)).unwrap();
//! let ci = covariance_intersection(&p, Criterion::Trace).unwrap();
//! let nm = non_monolithic_ci(&p, Criterion::Trace).unwrap();
//! assert_eq!(nm.fused.P, d(&[1.0, 1.0]));
//! assert!(nm.fused.trace() < ci.fused.trace());
//! ```
#![deny(missing_docs)]

// First, so that its `wide!` macro is in scope in the modules below.
#[macro_use]
mod linalg;
mod api;
/// The README's Rust example, run as a doc test.
#[cfg(doctest)]
#[doc = include_str!("../README.md")]
struct ReadmeExample;
mod chart;
mod error;
mod explore;
mod fig2;
mod fusion;
pub mod sim;
mod structure;
#[cfg(target_arch = "wasm32")]
pub mod wasm;

pub use api::{
    fuse, fuse_json, CertifiedDetails, CovarianceSummary, CutsDetails, Details, FuseRequest,
    FuseResponse, Gains, NwayEstimate, NwayPair, Options, PairInput, Plan, Rows, SdpDetails,
    StructureDetails, MAX_ESTIMATES, MAX_REQUEST_BYTES, MAX_SAMPLES, MAX_TRIALS,
};
#[cfg(all(feature = "charts", not(target_arch = "wasm32")))]
pub use chart::charts_svg;
#[cfg(feature = "charts")]
pub use chart::draw as draw_chart;
pub use chart::{Axis, Band, Chart, Line};
pub use error::{
    request_field, DrawError, InputError, ReportError, RequestError, SampleError, SolveError,
};
pub use explore::{
    explore, explore_with_memo, CoinStats, Exploration, ExploreRequest, Gap, RuleReport,
};
#[cfg(all(feature = "files", not(target_arch = "wasm32")))]
pub use fig2::write_fig2;
pub use fig2::{
    fig2_charts, fig2_csv, fig2_problem, fig2_run, fig2_summary, Fig2Config, Fig2Record, Fig2Row,
    MAX_FIG2_RUNS, MAX_FIG2_SIZES,
};
pub use fusion::bracket::{
    ci_upper_bound, lower_bound as lagrangian_lower_bound, nmci_upper_bound, trace_upper_bound,
    Bracket, UpperBounds, UpperRule, BRACKET_CERTIFY_MAX_BLOCK, CLOSED_RTOL,
};
pub use fusion::certify::{
    certified_fusion, certified_fusion_memo, certify_gain, CertificateMemo, Certificates,
    CertifiedResult, CertifySettings, Family, DEFAULT_SECTORS, MAX_BLOCK_DIM, MAX_LEVEL,
    MAX_SECTORS, MEMO_BLOCKS,
};
pub use fusion::check::{
    conservativeness_index, conservativeness_margin, fused_coin, fused_coins,
    fused_error_covariance, worst_margin,
};
pub use fusion::ci::{
    ci_covariance, covariance_intersection, covariance_intersection_blocks, CiResult,
};
pub use fusion::cuts::{optimal_fusion_cuts, CutsResult, CutsSettings, CutsStop};
pub use fusion::ei::ellipsoidal_intersection;
pub use fusion::ici::{inverse_covariance_intersection, IciResult};
pub use fusion::known::{known_correlation_fusion, naive_fusion};
pub use fusion::nmci::{non_monolithic_ci, NmciResult};
pub use fusion::nway::{
    absorb_couplings_nway, covariance_intersection_nway, non_monolithic_ci_nway, NwayResult,
    PairPattern,
};
pub use fusion::program::SdpStatus;
pub use fusion::rules::{
    rules, BlockUse, Criteria, Guarantee, Limits, Method, RequestOption, RuleInfo, RULES,
};
pub use fusion::sample::{
    sample_cross_covariances, sample_cross_covariances_with, AutoChoice, CrossSamples, SamplerKind,
    SamplerSettings, AUTO_MIN_ACCEPTED, AUTO_PILOT_TRIALS, MAX_SAMPLE_COUNT, MAX_SAMPLE_ENTRIES,
};
pub use fusion::sdp::{optimal_fusion, optimal_fusion_for_samples, SdpResult, SdpSettings};
pub use fusion::{validate_covariance, Criterion, Estimate, Fused, FusionProblem};
pub use linalg::{logdet_spd, min_eigenvalue};
pub use sim::{coin_chart, study_charts};
pub use structure::{
    absorb_couplings, check_partition, independent_blocks, Absorbed, BlockStructure, Coupling,
    CrossPattern, StructureSettings, COUPLING_HINT, DEFAULT_COUPLING_TOL,
};
