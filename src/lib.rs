//! # nmci — conservative fusion when the cross-covariance is unknown except for known zeros
//!
//! Two estimates `(x_a, P_a)`, `(x_b, P_b)` are to be fused into `x = K_a x_a + K_b x_b`
//! with a covariance bound `P̄` that dominates the true fused covariance for every
//! cross-covariance `P_ab` consistent with what is known: the joint covariance is positive
//! definite and the entries of `P_ab` in a known index set `I` are zero. This crate
//! implements the rules of Funk, Dagan, Noack and Ahmed, *Exploiting Structure for Optimal
//! Multi-Agent Bayesian Decentralized Estimation*:
//!
//! | namespace | what it holds |
//! |---|---|
//! | the root | the problem ([`FusionProblem`], [`CrossPattern`], [`Criterion`]), its result ([`Fused`]) and the errors |
//! | [`prelude`] | the common path in one import |
//! | [`rules`] | CI, nmCI, ICI, EI, naive fusion, and the registry naming every rule once ([`rules::RULES`]) |
//! | [`certify`] | the certified rule: a bound proven for every admissible `P_ab` |
//! | [`sdp`] | the sampled SDP (paper eq. (sampled_sdp)) and the cutting planes: relaxations |
//! | [`bounds`] | the proven bracket `[lower, upper]` on the robust optimum |
//! | [`nway`] | `k ≥ 2` estimates |
//! | [`structure`] | independent blocks, found or declared; round-off between them absorbed |
//! | [`sample`], [`check`] | admissible `P_ab` drawn at random; margins and COIN |
//! | [`contract`] | the JSON request/response shared by the CLI, the wasm module and Python |
//! | [`explore`], [`study`], [`fig2`], [`chart`] | the explorer's analysis, the paper's tracking study and fig. 2, their charts |
//!
//! Feature `charts` draws charts (plotters); `files` writes the study's files (SVG, CSV,
//! TOML). The default build has neither.
//!
//! ## Symbols
//! Textbook symbols are kept (`#[allow(non_snake_case)]`): `P_a`, `P_b` covariances of the
//! two estimates, `P_ab` their cross-covariance, `x_a`, `x_b` the estimates, `K_a`, `K_b` the
//! gains (`K_a + K_b = I`), `P` / `P̄` the fused bound, `ω` the CI weight on `P_a⁻¹`, `P'` an
//! admissible joint covariance `[[P_a, P_ab'], [P_ab'ᵀ, P_b]]`.
//!
//! ```
//! use nalgebra::{DMatrix, DVector};
//! use nmci::prelude::*;
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
pub mod chart;
mod error;
pub mod explore;
pub mod fig2;
mod fusion;
mod sim;
pub mod structure;
#[cfg(target_arch = "wasm32")]
pub mod wasm;

// The Fortran BLAS and LAPACK symbols (`dgemm_`, `dsyevr_`, …) over the pure-Rust shims
// (shims/*/src/ffi.rs). Inside this workspace `[patch.crates-io]` puts the shims in place of
// the `blas` and `lapack` crates Clarabel's SDP cones call; a crate depending on nmci does not
// see that patch, gets the real crates, and links against these symbols instead of a system
// BLAS/LAPACK (tested: scripts/dependent.sh builds such a crate and runs the README's example).
#[cfg(not(target_arch = "wasm32"))]
extern crate blas_shim as _;
#[cfg(not(target_arch = "wasm32"))]
extern crate lapack_shim as _;

/// The nalgebra nmci's matrices are, re-exported so a dependent crate uses the same version:
/// `use nmci::nalgebra::{DMatrix, DVector};`.
pub use nalgebra;

// The common path at the root: the problem, its result, the errors.
pub use error::{
    request_field, DrawError, InputError, ReportError, RequestError, SampleError, SolveError,
};
pub use fusion::{validate_covariance, Criterion, Estimate, Fused, FusionProblem};
pub use structure::CrossPattern;

/// The common path in one import: `use nmci::prelude::*;`.
pub mod prelude {
    pub use crate::certify::{certified_fusion, CertifySettings};
    pub use crate::check::worst_margin;
    pub use crate::contract::{fuse, fuse_json, FuseRequest, FuseResponse};
    pub use crate::rules::{covariance_intersection, non_monolithic_ci, Method};
    pub use crate::sample::{sample_cross_covariances, SamplerSettings};
    pub use crate::sdp::{optimal_fusion, optimal_fusion_cuts, CutsSettings, SdpSettings};
    pub use crate::structure::{absorb_couplings, independent_blocks, StructureSettings};
    pub use crate::{
        Criterion, CrossPattern, Estimate, Fused, FusionProblem, InputError, RequestError,
        SolveError,
    };
}

/// The rules and their registry: [`RULES`](rules::RULES) names every rule once (its name in
/// the contract, guarantee, criteria and options); the closed-form rules are here, the
/// certified rule in [`certify`], the SDP relaxations in [`sdp`],
/// N estimates in [`nway`].
pub mod rules {
    pub use crate::fusion::ci::{
        ci_covariance, covariance_intersection, covariance_intersection_blocks, CiResult,
    };
    pub use crate::fusion::ei::ellipsoidal_intersection;
    pub use crate::fusion::ici::{inverse_covariance_intersection, IciResult};
    pub use crate::fusion::known::{known_correlation_fusion, naive_fusion};
    pub use crate::fusion::nmci::{non_monolithic_ci, NmciResult};
    pub use crate::fusion::rules::{
        rules, BlockUse, Criteria, Guarantee, Limits, Method, RequestOption, RuleInfo, RULES,
    };
    pub use crate::fusion::semidefinite::{
        fuse_semidefinite, fuse_semidefinite_problem, SemidefiniteResult, SemidefiniteRule,
    };
}

/// The certified rule: a bound proven to dominate `K P' Kᵀ` for every admissible `P'`, by a
/// sum-of-squares certificate repaired with every rounding accounted for.
pub mod certify {
    pub use crate::fusion::certify::{
        certified_fusion, certified_fusion_memo, certify_gain, certify_rule, CertificateMemo,
        Certificates, CertifiedResult, CertifySettings, Family, DEFAULT_SECTORS, MAX_BLOCK_DIM,
        MAX_CONES, MAX_LEVEL, MAX_SECTORS, MEMO_BLOCKS,
    };
}

/// The optimal bound's relaxations: the paper's sampled SDP and the cutting planes, each with
/// a proven bracket on the robust optimum ([`bounds`]).
pub mod sdp {
    pub use crate::fusion::cuts::{optimal_fusion_cuts, CutsResult, CutsSettings, CutsStop};
    pub use crate::fusion::program::SdpStatus;
    pub use crate::fusion::sdp::{
        optimal_fusion, optimal_fusion_for_samples, SdpResult, SdpSettings,
    };
}

/// Proven bounds on the robust optimum: the Lagrangian lower end, the rules' rounded-up upper
/// ends, and the bracket they make.
pub mod bounds {
    pub use crate::fusion::bracket::{
        ci_upper_bound, lower_bound, nmci_upper_bound, trace_upper_bound, Bracket, UpperBounds,
        UpperRule, BRACKET_CERTIFY_MAX_BLOCK, CLOSED_RTOL,
    };
}

/// `k ≥ 2` estimates: CI and nmCI with weights on the simplex, and the structure of N
/// estimates' pairwise patterns.
pub mod nway {
    pub use crate::fusion::nway::{
        absorb_couplings_nway, covariance_intersection_nway, non_monolithic_ci_nway, NwayResult,
        PairPattern,
    };
}

/// Admissible cross-covariances drawn at random: the paper's rejection sampler and a
/// hit-and-run chain with the same law.
pub mod sample {
    pub use crate::fusion::sample::{
        sample_cross_covariances, sample_cross_covariances_with, AutoChoice, CrossSamples,
        SamplerKind, SamplerSettings, AUTO_MIN_ACCEPTED, AUTO_PILOT_TRIALS, MAX_SAMPLE_COUNT,
        MAX_SAMPLE_ENTRIES,
    };
}

/// Conservativeness checks: margins `λ_min(P̄ − K P' Kᵀ)`, the conservativeness index (COIN)
/// and the small linear algebra they use.
pub mod check {
    pub use crate::fusion::check::{
        conservativeness_index, conservativeness_margin, fused_coin, fused_coins,
        fused_error_covariance, worst_margin,
    };
    pub use crate::linalg::{logdet_spd, min_eigenvalue};
}

/// The JSON request/response contract shared by the CLI, the wasm module and Python
/// (docs/contract.md).
pub mod contract {
    pub use crate::api::{
        field_names, fuse, fuse_json, fuse_list, fuse_stack, request_fields, response_fields,
        CertifiedDetails, CovarianceSummary, CutsDetails, Details, FuseRequest, FuseResponse,
        Gains, NwayEstimate, NwayPair, Options, PairInput, Plan, Rows, SdpDetails, StackRequest,
        StackResponse, StructureDetails, MAX_ESTIMATES, MAX_REQUEST_BYTES, MAX_SAMPLES, MAX_TRIALS,
    };
}

/// The paper's multi-agent tracking study (16 agents, 20 targets, 112 states): scenario,
/// runs, the exact COIN, shards, the network sweep and the study's charts.
pub mod study {
    pub use crate::sim::*;
}
