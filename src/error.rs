//! One error enum per concern, as in Clarabel: bad input, sampling, solving, and the
//! request/response contract that wraps them.

use std::path::PathBuf;

use thiserror::Error;

/// An input matrix, vector or pattern that cannot be fused.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum InputError {
    /// A matrix with no rows.
    #[error("{name} is empty")]
    Empty {
        /// Which input (e.g. `P_a`).
        name: String,
    },
    /// A matrix that is not square, or a nested array whose rows differ in length.
    #[error("{name} is not square ({rows}×{cols})")]
    NotSquare {
        /// Which input.
        name: String,
        /// Number of rows.
        rows: usize,
        /// Number of columns (of the offending row for nested arrays).
        cols: usize,
    },
    /// A NaN or infinite entry of a vector.
    #[error("{name}[{index}] is not finite (NaN or ±∞)")]
    NotFiniteElement {
        /// Which vector.
        name: String,
        /// The element (0-based).
        index: usize,
    },
    /// A NaN or infinite entry of a matrix.
    #[error("{name} has a non-finite entry at ({row}, {col})")]
    NotFinite {
        /// Which input.
        name: String,
        /// Row (0-based).
        row: usize,
        /// Column (0-based; 0 for vectors).
        col: usize,
    },
    /// `|A[i,j] − A[j,i]|` exceeds the relative symmetry tolerance.
    #[error(
        "{name} is not symmetric: entry ({row}, {col}) is {value} but ({col}, {row}) is {mirror}"
    )]
    NotSymmetric {
        /// Which input.
        name: String,
        /// Row (0-based).
        row: usize,
        /// Column (0-based).
        col: usize,
        /// `A[row, col]`.
        value: f64,
        /// `A[col, row]`.
        mirror: f64,
    },
    /// A covariance with a non-positive eigenvalue.
    #[error("{name} is not positive definite (smallest eigenvalue {min_eigenvalue:.6e})")]
    NotPositiveDefinite {
        /// Which input.
        name: String,
        /// Its smallest eigenvalue.
        min_eigenvalue: f64,
    },
    /// A covariance proven positive definite (equilibrated by powers of two) whose smallest
    /// eigenvalue is nonetheless lost to rounding as given: variances of very different
    /// orders (mixed units) that the rules cannot compute with in floating point.
    #[error("{name} is positive definite but too ill-conditioned to fuse in floating point (eigenvalues computed from {min_eigenvalue:.6e} to {max_eigenvalue:.6e}; rescale its states to comparable units)")]
    IllConditioned {
        /// Which input.
        name: String,
        /// Its smallest eigenvalue as computed (at or below rounding level).
        min_eigenvalue: f64,
        /// Its largest eigenvalue as computed.
        max_eigenvalue: f64,
    },
    /// A covariance whose definiteness nmci's floating-point checks cannot decide: not proven positive
    /// definite (as given or equilibrated by powers of two), and not proven otherwise either
    /// (no vector with `vᵀ P v ≤ 0` is proven): its smallest eigenvalue is within rounding of
    /// zero next to its largest.
    #[error("{name} is singular to working precision: its smallest eigenvalue (computed {min_eigenvalue:.6e}) is within rounding of zero next to its largest ({max_eigenvalue:.6e}), so nmci cannot tell in floating point whether it is positive definite")]
    Singular {
        /// Which input.
        name: String,
        /// Its smallest eigenvalue as computed.
        min_eigenvalue: f64,
        /// Its largest eigenvalue as computed.
        max_eigenvalue: f64,
    },
    /// `P_a` and `P_b`, each accepted as positive definite, so far apart along some axis that
    /// the ratio of `P_a` to `P_b` there (a generalized eigenvalue of the pair) is lost to
    /// rounding: the CI family's pencil cannot be computed (`fusion::ci`'s module docs).
    #[error("P_a and P_b are each accepted as positive definite, but the ratios of P_a to P_b along their common axes span more than nmci's computation resolves in floating point (computed from {min_ratio:.3e} to {max_ratio:.3e}); rescale the states to comparable units")]
    UnresolvedPair {
        /// The smallest ratio as computed.
        min_ratio: f64,
        /// The largest ratio as computed.
        max_ratio: f64,
    },
    /// A weight or tolerance outside `[0, 1]`: CI's `ω`, the coupling tolerance.
    #[error("{name} must be in [0, 1] (got {value})")]
    WeightOutOfRange {
        /// Which value (`omega`, `coupling_tol`).
        name: String,
        /// The value given.
        value: f64,
    },
    /// A matrix nmci forms from inputs it accepted (`P_a + t P_b`, a fused information matrix,
    /// ICI's `Γ`) that is positive definite in exact arithmetic but whose factorization fails
    /// in floating point: the inputs are too far apart to fuse at working precision. No input
    /// is named, because no single one is at fault.
    #[error("{matrix}, formed from {inputs} and positive definite in exact arithmetic when they are, cannot be factored in floating point: they are too far apart to fuse at working precision; rescale the states to comparable units")]
    Unfactored {
        /// The matrix whose factorization failed, as a formula.
        matrix: String,
        /// The inputs it was formed from.
        inputs: String,
    },
    /// A covariance whose positive definiteness cannot be judged in floating point: its
    /// eigenvalue computation overflows (entries near the largest float) or all its entries
    /// are below the normal range (subnormal).
    #[error("{name} is out of the range nmci computes in: its largest entry in magnitude is {largest:e} (rescale the units)")]
    OutOfRange {
        /// Which input.
        name: String,
        /// Its largest entry in magnitude.
        largest: f64,
    },
    /// A matrix with a non-zero entry outside the blocks it was declared block-diagonal in.
    #[error("{name} is not block-diagonal in the given blocks: entry ({row}, {col}) is {value}")]
    NotBlockDiagonal {
        /// Which input.
        name: String,
        /// Row (0-based).
        row: usize,
        /// Column (0-based).
        col: usize,
        /// The non-zero value.
        value: f64,
    },
    /// Blocks that are not a partition of the states `0..n`.
    #[error("the blocks are not a partition of the {n} states: {problem}")]
    InvalidBlocks {
        /// State dimension.
        n: usize,
        /// What is wrong.
        problem: String,
    },
    /// An entry of `P_a` or `P_b` between two declared blocks above the coupling tolerance:
    /// the blocks are not independent in it (`crate::structure::absorb_couplings`).
    #[error("{}[{row}][{col}] = {value} couples blocks {} and {} ({} relative to the square root of its diagonal entries, above coupling_tol {tol:e}): the declared blocks are not independent", request_field(name), blocks[0], blocks[1], digits_above(*relative, *tol))]
    CouplingTooLarge {
        /// The covariance's request field (`pa`, `pb`, `estimates[i].p`).
        name: String,
        /// Row (0-based).
        row: usize,
        /// Column (0-based).
        col: usize,
        /// The entry.
        value: f64,
        /// Its size relative to `√(P[row,row] P[col,col])`.
        relative: f64,
        /// The declared blocks it links (indices into the declared list, the first smaller).
        blocks: [usize; 2],
        /// The coupling tolerance.
        tol: f64,
    },
    /// An unknown entry of the pattern of `P_ab` between two declared blocks: declared blocks
    /// have independent errors, so it must be a known zero (`crate::structure::absorb_couplings`).
    #[error("{field}[{row}][{col}] is true, but states {row} and {col} are in declared blocks {} and {}, whose errors are independent (make it false, or join the blocks)", blocks[0], blocks[1])]
    PatternCrossesBlocks {
        /// The pattern's request field (`pab_unknown`, `patterns[k].pab_unknown`).
        field: String,
        /// Row (0-based).
        row: usize,
        /// Column (0-based).
        col: usize,
        /// The declared blocks of `row` and `col`.
        blocks: [usize; 2],
    },
    /// An input whose size does not match `P_a`.
    #[error("{name} has size {found}, expected {expected} (the size of P_a)")]
    SizeMismatch {
        /// Which input.
        name: String,
        /// Size found.
        found: usize,
        /// Size expected.
        expected: usize,
    },
    /// A set of estimates for N-way fusion that cannot be fused (too few, sizes differ, a pair
    /// pattern out of range or given twice).
    #[error("invalid estimates: {0}")]
    Estimates(String),
}

/// The sampler of admissible cross-covariances could not deliver.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum SampleError {
    /// The rejection sampler used up its trial budget.
    #[error("the rejection sampler accepted only {accepted} of {requested} requested samples in {trials} trials (acceptance rate {rate:.2e}); raise max_trials or make fewer entries of P_ab unknown")]
    BudgetExhausted {
        /// Samples accepted before the budget ran out.
        accepted: usize,
        /// Samples requested.
        requested: usize,
        /// Trials used (the budget).
        trials: u64,
        /// `accepted / trials`.
        rate: f64,
    },
    /// A settings value out of range.
    #[error("invalid sampler setting: {0}")]
    InvalidSettings(String),
    /// The hit-and-run chain met a numerically singular point.
    #[error("the hit-and-run sampler broke down: {0}")]
    NumericalBreakdown(String),
}

/// The sampled semidefinite program did not produce a usable bound.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum SolveError {
    /// Clarabel ended with a status other than `Solved` or `AlmostSolved`.
    #[error("the SDP solver stopped with status {status} after {iterations} iterations; no bound was produced")]
    SolverFailed {
        /// Clarabel's status, e.g. `MaxIterations`.
        status: String,
        /// Interior-point iterations used.
        iterations: u32,
    },
    /// Clarabel refused the problem data or settings.
    #[error("the SDP solver rejected the problem: {0}")]
    Setup(String),
    /// A settings value out of range.
    #[error("invalid SDP setting: {0}")]
    InvalidSettings(String),
    /// The working-set loop hit its round limit with samples still violated.
    #[error("the working-set loop stopped after {rounds} rounds with {violated} samples still violated (worst {worst:.3e})")]
    WorkingSetStalled {
        /// Rounds run.
        rounds: usize,
        /// Samples still violated.
        violated: usize,
        /// Their worst `λ_min(P̄ − K P' Kᵀ)`.
        worst: f64,
    },
    /// A block too large for the certified bound's program (its cone grows as `2n²` at level 1).
    #[error("the certified bound is limited to independent blocks of at most {limit} states (this one has {dim}): its PSD cone grows as 2n² at level 1 (max_block_dim)")]
    BlockTooLarge {
        /// States in the block.
        dim: usize,
        /// The limit (`CertifySettings::max_block_dim`).
        limit: usize,
    },
    /// A certificate's PSD cone above the limit (`CertifySettings::max_cone`).
    #[error("the level-{level} certificate of a {dim}-state block needs a PSD cone of {cone} rows, above the limit of {limit} (max_cone); choose a lower level")]
    ConeTooLarge {
        /// States in the block.
        dim: usize,
        /// The certificate level.
        level: u32,
        /// Rows of its PSD cone.
        cone: usize,
        /// The limit.
        limit: usize,
    },
    /// A solve that ran past its `time_limit`.
    #[error("{what} stopped at its time limit of {seconds} s; no bound was produced")]
    TimeLimit {
        /// The limit in seconds.
        seconds: f64,
        /// What was being solved.
        what: String,
    },
    /// The floating-point repair of a certificate could not prove it (the solver's point
    /// was too far from feasible); no bound is reported.
    #[error("the certified bound could not be proven: {what} is not provably positive semidefinite after the repair")]
    NotProven {
        /// The matrix that failed the verified test.
        what: String,
    },
    /// A proven bound left the range of floating point: covariances so large that the
    /// proof's products of entries overflow, and which cannot be scaled to order one exactly
    /// (`fusion::scale`: an entry would fall below the normal range).
    #[error("the {what} overflowed: the covariances (largest diagonal entry {largest:e}) are too large for its floating-point proof and could not be scaled exactly (rescale the problem's units)")]
    Overflow {
        /// The bound that overflowed.
        what: String,
        /// The largest diagonal entry of `P_a` and `P_b`.
        largest: f64,
    },
    /// Drawing the sample set failed.
    #[error(transparent)]
    Sample(#[from] SampleError),
    /// A conservative rule needed for the certified upper bound failed on the problem.
    #[error(transparent)]
    Input(#[from] InputError),
}

/// Any failure of a [`crate::contract::FuseRequest`]: the one error type of the JSON contract shared
/// by the CLI and the wasm module.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum RequestError {
    /// The request is not valid JSON, has an unknown field, or a value of the wrong type.
    #[error("invalid request: {0}")]
    Malformed(String),
    /// The request text is longer than [`crate::contract::MAX_REQUEST_BYTES`] (refused before parsing).
    #[error("invalid request: longer than the limit of {limit} bytes ({bytes} bytes read)")]
    TooLarge {
        /// The bytes read (the CLI stops one past the limit).
        bytes: usize,
        /// The limit.
        limit: usize,
    },
    /// A field value out of range (e.g. `samples: 0`), or a field that does not apply.
    #[error("invalid request: {message}")]
    Invalid {
        /// The request field at fault (`"samples"`).
        field: String,
        /// What is wrong with it.
        message: String,
    },
    /// A matrix, vector or pattern that cannot be fused.
    #[error(transparent)]
    Input(#[from] InputError),
    /// The optimal bound could not be computed.
    #[error(transparent)]
    Solve(#[from] SolveError),
    /// Sampling admissible cross-covariances failed.
    #[error(transparent)]
    Sample(#[from] SampleError),
    /// One pair of a stack ([`crate::contract::fuse_stack`]) failed: its index and its error.
    #[error("pair {index}: {source}")]
    InStack {
        /// The pair's index in the stack.
        index: usize,
        /// What went wrong with it.
        source: Box<RequestError>,
    },
    /// One request of a list ([`crate::contract::fuse_list`]) failed: its index and its error.
    #[error("request {index}: {source}")]
    InList {
        /// The request's index in the list.
        index: usize,
        /// What went wrong with it.
        source: Box<RequestError>,
    },
}

impl RequestError {
    /// A field value out of range, or a field that does not apply.
    pub fn invalid(field: impl Into<String>, message: impl Into<String>) -> Self {
        RequestError::Invalid {
            field: field.into(),
            message: message.into(),
        }
    }

    /// The request field at fault, when there is one: the field of [`RequestError::Invalid`],
    /// the field of an [`InputError`] (`pa`, `pb`, `xa`, `xb`, `pab_unknown`,
    /// `estimates[i].p`, `estimates`), or the unknown or missing field named by the JSON
    /// parser. The page places its messages by it; the wasm layer hands it over as the thrown
    /// `Error`'s `field`, the Python package as the exception's `field`.
    pub fn field(&self) -> Option<String> {
        match self {
            RequestError::Invalid { field, .. } => Some(field.clone()),
            RequestError::Input(e) => e.request_field(),
            RequestError::Malformed(message) => ["unknown field `", "missing field `"]
                .iter()
                .find_map(|prefix| message.strip_prefix(prefix))
                .and_then(|rest| rest.split('`').next())
                .map(str::to_owned),
            RequestError::Solve(SolveError::Input(e)) => e.request_field(),
            RequestError::Solve(_) | RequestError::Sample(_) | RequestError::TooLarge { .. } => {
                None
            }
            // A stacked field indexed by the pair (`pa[17]`); a shared one (`blocks`) as it is.
            RequestError::InStack { index, source } => source.field().map(|field| {
                match ["pa", "pb", "xa", "xb", "pab_unknown"].contains(&field.as_str()) {
                    true => format!("{field}[{index}]"),
                    false => field,
                }
            }),
            // The field of the list's element: `[2].pa`.
            RequestError::InList { index, source } => {
                source.field().map(|field| format!("[{index}].{field}"))
            }
        }
    }
}

impl InputError {
    /// The name of the input at fault (`"P_a"`, `"estimates[1].p"`), when there is one.
    pub fn name(&self) -> Option<&str> {
        match self {
            InputError::Empty { name }
            | InputError::NotSquare { name, .. }
            | InputError::NotFinite { name, .. }
            | InputError::NotFiniteElement { name, .. }
            | InputError::NotSymmetric { name, .. }
            | InputError::NotPositiveDefinite { name, .. }
            | InputError::OutOfRange { name, .. }
            | InputError::IllConditioned { name, .. }
            | InputError::Singular { name, .. }
            | InputError::WeightOutOfRange { name, .. }
            | InputError::NotBlockDiagonal { name, .. }
            | InputError::CouplingTooLarge { name, .. }
            | InputError::SizeMismatch { name, .. } => Some(name),
            InputError::PatternCrossesBlocks { field, .. } => Some(field),
            InputError::InvalidBlocks { .. }
            | InputError::UnresolvedPair { .. }
            | InputError::Unfactored { .. }
            | InputError::Estimates(_) => None,
        }
    }

    /// The JSON request field of the input at fault ([`request_field`]); a set of estimates
    /// that cannot be fused is `estimates`.
    pub fn request_field(&self) -> Option<String> {
        match self {
            InputError::Estimates(_) => return Some("estimates".into()),
            InputError::InvalidBlocks { .. } => return Some("blocks".into()),
            _ => {}
        }
        self.name().map(request_field)
    }
}

/// The JSON request field of an input named in an error: `P_a` is `pa`, `x_b` is `xb`; other
/// names are already the field's (`pab_unknown`, `estimates[1].p`).
pub fn request_field(name: &str) -> String {
    match name {
        "P_a" => "pa",
        "P_b" => "pb",
        "x_a" => "xa",
        "x_b" => "xb",
        other => other,
    }
    .into()
}

/// A report's files (a study's, fig. 2's) could not be written.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum ReportError {
    /// The output folder could not be created.
    #[error("cannot create {}: {message}", path.display())]
    Create {
        /// The folder.
        path: PathBuf,
        /// The system's message.
        message: String,
    },
    /// A file could not be written.
    #[error("cannot write {}: {message}", path.display())]
    Write {
        /// The file.
        path: PathBuf,
        /// The system's message.
        message: String,
    },
    /// A chart could not be drawn.
    #[error("cannot draw {}: {message}", path.display())]
    Draw {
        /// The chart's file.
        path: PathBuf,
        /// The plotting library's message.
        message: String,
    },
}

/// A chart could not be drawn ([`crate::chart::Chart`]): the plotting library's or the canvas'
/// message.
#[derive(Debug, Clone, PartialEq, Error)]
#[error("cannot draw the chart: {0}")]
pub struct DrawError(pub String);

/// `value` (above `floor`) in the fewest significant digits (two at least) that still read
/// above `floor` written shortest, so a coupling printed beside its tolerance is never shown
/// at or below it.
pub(crate) fn digits_above(value: f64, floor: f64) -> String {
    (2..=17)
        .map(|digits| format!("{:.*e}", digits - 1, value))
        .find(|text| text.parse::<f64>().is_ok_and(|v| v > floor))
        .unwrap_or_else(|| format!("{value:e}"))
}
