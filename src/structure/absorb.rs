//! Structure that survives round-off: declared blocks, and near-zero couplings absorbed into
//! a block-diagonal bound that provably dominates them.
//!
//! [`independent_blocks`](crate::structure::independent_blocks) finds blocks from *exact* zeros. A
//! filter's covariances rarely keep them: a Riccati recursion leaves cross-axis entries of
//! order `ε ‖P‖` where the model has none, and one such entry merges two blocks, so nmCI falls
//! back to CI on them. [`absorb_couplings`] keeps the blocks and pays for it with a proven
//! inflation.
//!
//! ## The blocks
//! States `i`, `j` are *linked* when an entry of the pattern of `P_ab` linking them is unknown,
//! or when `|P_a[i,j]| > τ √(P_a[i,i] P_a[j,j])` or the same holds for `P_b`, with the
//! coupling tolerance `τ` ([`StructureSettings::coupling_tol`]). The blocks are the connected
//! components of that graph. With `τ = 0` this is exactly
//! [`independent_blocks`](crate::structure::independent_blocks). Every entry
//! of `P_a`, `P_b` between two blocks is then at most `τ` relative (a *coupling*), and every
//! entry of `P_ab` between two blocks is a known zero.
//!
//! A *declared* partition ([`StructureSettings::blocks`]) is a modelling claim: errors in
//! different blocks are independent. It implies the pattern of `P_ab` (unknown within a block,
//! known zero across: [`CrossPattern::within_blocks`]); a given pattern must agree with it
//! ([`InputError::PatternCrossesBlocks`]), and an entry of `P_a` or `P_b` across declared
//! blocks above `τ` relative is refused ([`InputError::CouplingTooLarge`]) rather than
//! absorbed, since it contradicts the claim. The blocks found as above are then at least as
//! fine as the declared ones.
//!
//! ## The inflation (Gershgorin over blocks)
//! Write `P_a = D + E` with `D` the block-diagonal part and `E` the couplings, `E_ij` the
//! coupling of blocks `i ≠ j` (`E_ji = E_ijᵀ`). With `r_ij ≥ ‖E_ij‖₂` (`r_ij = r_ji`) and
//! `v = (v_1, …, v_m)` split by blocks,
//!
//! `vᵀ E v = Σ_{i≠j} v_iᵀ E_ij v_j ≤ Σ_{i≠j} r_ij ‖v_i‖ ‖v_j‖ ≤ Σ_{i≠j} r_ij (‖v_i‖² + ‖v_j‖²)/2 = Σ_i d_i ‖v_i‖²`,
//! `d_i = Σ_{j≠i} r_ij`,
//!
//! so `P̄_a = D + diag(d_i I) ⪰ D + E = P_a`. The same for `P_b`. Here `r_ij` is
//! `max(‖E_ij‖₁, ‖E_ij‖_∞) ≥ √(‖E_ij‖₁ ‖E_ij‖_∞) ≥ ‖E_ij‖₂` (Higham, *Accuracy and
//! Stability*, §6.3), its sums and `d_i` evaluated with rounding accounted for
//! ([`verify::up`](crate::fusion::verify)), and each inflated diagonal entry
//! `P_a[k,k] + d_i` rounded up to the next float: so `P̄_a ⪰ P_a` holds for the problem's
//! floats exactly, not to rounding. Blocks without couplings are not touched, so a problem
//! whose couplings are all exact zeros comes back bit for bit.
//!
//! ## Why every conservative rule stays conservative
//! Let a rule be conservative for the absorbed problem `(P̄_a, P̄_b, pattern)`: its gains `K`
//! and bound `P̄` satisfy `K J̄ Kᵀ ⪯ P̄` for every admissible joint `J̄` of that problem. Take
//! any admissible joint `J = [[P_a, P_ab], [P_abᵀ, P_b]]` of the *given* problem. Then
//! `J̄ = J + diag(P̄_a − P_a, P̄_b − P_b) ⪰ J ⪰ 0` has the same `P_ab`, with its known zeros
//! (those across blocks among them), so `J̄` is admissible for the absorbed problem and
//! `K J Kᵀ ⪯ K J̄ Kᵀ ⪯ P̄`. So nmCI and the certified rule on the absorbed problem are bounds
//! for the given one, with the same guarantee they have on exact zeros (nmCI's to rounding of
//! the exact `P`, the certified rule's with every rounding included).
//!
//! ## A lower end
//! The argument is about upper bounds: a lower bound on the absorbed problem's robust optimum
//! is not one on the given problem's (which can only be smaller). For a lower end, lower the
//! diagonal instead: `P_a⁻ = D − diag(d_i I)`, each entry rounded down, so
//! `P_a − P_a⁻ ⪰ E + diag(d_i I) ⪰ 0` by the same inequality. When `P_a⁻`, `P_b⁻` are proven
//! positive definite, every admissible joint `J⁻` of the *deflated* problem gives the
//! admissible joint `J⁻ + diag(P_a − P_a⁻, P_b − P_b⁻)` of the given one, with the same `P_ab`;
//! so for every gain the worst case over the given problem is at least the worst case over the
//! deflated one, and the robust optima satisfy `V*(deflated) ≤ V*(given) ≤ V*(absorbed)`. The
//! sampled SDP solves the deflated problem (block by block: it has the blocks), its proven
//! lower end is one for the given problem, and its bracket's upper end comes from the absorbed
//! problem ([`Absorbed::deflated`]). The cutting planes stop on their own bracket, computed on
//! the problem they solve, so they solve the given problem, couplings not absorbed.
//!
//! ## The default tolerance
//! [`DEFAULT_COUPLING_TOL`] is `10⁻⁹`, the relative tolerance nmci already takes for
//! round-off in a covariance (an asymmetry up to `10⁻⁹` of the largest entry is accepted and
//! symmetrised, `crate::linalg::SYMMETRY_RTOL`). Round-off of a filter's recursion is of order
//! `ε κ ≈ 10⁻¹⁶ κ`, below `10⁻⁹` up to a condition number of `10⁷`; a correlation of `10⁻⁹`
//! is not a modelled one. The price is small by construction: every entry of a coupling is at
//! most `τ √(P[i,i] P[j,j]) ≤ τ v` (`v` the largest variance), so with blocks of `n_i` states
//! `r_ij ≤ τ v max(n_i, n_j) ≤ τ v n`, `d_i ≤ τ v n²` and the trace grows by at most `τ v n³`
//! (rounding aside): relative to `tr P ≥ v`, at most `10⁻⁹ n³` (a bound; a filter's round-off
//! is far below `τ`, and so is its cost). Exact zeros are never couplings, so problems with
//! exact structure are unchanged, bit for bit.

use nalgebra::DMatrix;
use serde::{Deserialize, Serialize};

use super::{connected_components, CrossPattern};
use crate::error::InputError;
use crate::fusion::scale::{next_down, next_up};
use crate::fusion::verify::{is_positive_definite, up};
use crate::fusion::FusionProblem;

/// The default coupling tolerance `τ` (module docs: "The default tolerance").
pub const DEFAULT_COUPLING_TOL: f64 = 1e-9;

/// A coupling above this relative size merging blocks is mentioned in
/// [`BlockStructure::note`]: a correlation this weak is more likely round-off or a weak modelled
/// link than a structure the user meant, and the note says which tolerance would split it.
pub const COUPLING_HINT: f64 = 1e-3;

/// How a problem's structure is found: declared blocks and the coupling tolerance.
#[derive(Debug, Clone, PartialEq)]
pub struct StructureSettings {
    /// A declared partition of the states into independent blocks (module docs), or `None`:
    /// blocks from the pattern of `P_ab` and the couplings alone.
    pub blocks: Option<Vec<Vec<usize>>>,
    /// `τ`: an entry of `P_a` or `P_b` with `|P[i,j]| ≤ τ √(P[i,i] P[j,j])` may be absorbed
    /// (module docs); `0` keeps only exact zeros. In `[0, 1]`.
    pub coupling_tol: f64,
}

impl Default for StructureSettings {
    fn default() -> Self {
        Self {
            blocks: None,
            coupling_tol: DEFAULT_COUPLING_TOL,
        }
    }
}

impl StructureSettings {
    /// Checks the settings for a problem of `n` states: `coupling_tol` in `[0, 1]` (a relative
    /// entry of a positive definite matrix is below 1), `blocks` a partition of `0..n`.
    pub fn validate(&self, n: usize) -> Result<(), InputError> {
        if !(0.0..=1.0).contains(&self.coupling_tol) {
            return Err(InputError::WeightOutOfRange {
                name: "coupling_tol".into(),
                value: self.coupling_tol,
            });
        }
        if let Some(blocks) = &self.blocks {
            check_partition(n, blocks)?;
        }
        Ok(())
    }
}

/// Checks that `blocks` is a partition of `0..n`: every state in exactly one block, no empty
/// block ([`InputError::InvalidBlocks`] says which state is missing, repeated or beyond `n`).
pub fn check_partition(n: usize, blocks: &[Vec<usize>]) -> Result<(), InputError> {
    let invalid = |problem: String| Err(InputError::InvalidBlocks { n, problem });
    if let Some(b) = blocks.iter().position(Vec::is_empty) {
        return invalid(format!("block {b} is empty"));
    }
    let mut seen = vec![false; n];
    for &i in blocks.iter().flatten() {
        if i >= n {
            return invalid(format!("state {i} does not exist"));
        }
        if seen[i] {
            return invalid(format!("state {i} is in two blocks"));
        }
        seen[i] = true;
    }
    match seen.iter().position(|s| !s) {
        Some(i) => invalid(format!("state {i} is in no block")),
        None => Ok(()),
    }
}

/// The block of each state.
pub(crate) fn block_of(n: usize, blocks: &[Vec<usize>]) -> Vec<usize> {
    let mut of = vec![0; n];
    for (b, block) in blocks.iter().enumerate() {
        for &i in block {
            of[i] = b;
        }
    }
    of
}

/// `|P[i,j]|` relative to `√(P[i,i] P[j,j])` (as computed; a decision, not a proof).
fn relative(p: &DMatrix<f64>, i: usize, j: usize) -> f64 {
    p[(i, j)].abs() / (p[(i, i)].sqrt() * p[(j, j)].sqrt())
}

/// One absorbed coupling: the entries of `P_a` or `P_b` between two blocks.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Coupling {
    /// `pa` or `pb`.
    pub matrix: String,
    /// The two blocks (indices into [`BlockStructure::blocks`], the first smaller).
    pub blocks: [usize; 2],
    /// Row of the largest entry in magnitude between them.
    pub row: usize,
    /// Its column.
    pub col: usize,
    /// Its value.
    pub value: f64,
    /// Its size relative to `√(P[row,row] P[col,col])`.
    pub relative: f64,
    /// `r ≥ ‖E‖₂`, a proven bound on the coupling's spectral norm (module docs).
    pub norm_bound: f64,
    /// What absorbing it added to the trace of `matrix`: `r` times the states of both
    /// blocks (each of their variances is raised by `r`; the sums and the raised entries are
    /// then rounded up, by a few units in the last place).
    pub trace_added: f64,
}

/// The blocks of a problem and what was absorbed to keep them ([`absorb_couplings`]).
#[derive(Debug, Clone, PartialEq)]
pub struct BlockStructure {
    /// The blocks (module docs), ordered by first state, states ascending.
    pub blocks: Vec<Vec<usize>>,
    /// The couplings absorbed, by matrix then block pair.
    pub couplings: Vec<Coupling>,
    /// How many blocks exact zeros alone give ([`independent_blocks`](crate::structure::independent_blocks)
    /// of the given problem).
    pub exact_blocks: usize,
    /// The strongest coupling (relative, at most [`COUPLING_HINT`]) left that merges blocks,
    /// the number of blocks a tolerance at its size would give, and that tolerance as the
    /// note writes it: the shortest decimal at least the coupling that gives those blocks
    /// (so the advice works when followed).
    pub near_miss: Option<(f64, usize, String)>,
}

/// A problem with its near-zero couplings absorbed ([`absorb_couplings`]).
#[derive(Debug, Clone, PartialEq)]
pub struct Absorbed {
    /// The problem every structure-exploiting conservative rule solves: `P̄_a ⪰ P_a`,
    /// `P̄_b ⪰ P_b` block-diagonal in [`BlockStructure::blocks`], the same means and pattern.
    /// The given problem itself, bit for bit, when nothing was absorbed.
    pub problem: FusionProblem,
    /// The problem with the couplings dropped and the diagonals *lowered* by the same `d_i`
    /// (rounded down): its robust optimum is at most the given problem's, so a proven lower
    /// bound for it is one for the given problem (module docs, "A lower end"). `None` when
    /// nothing was absorbed, or when its covariances are not proven positive definite.
    pub deflated: Option<FusionProblem>,
    /// Its blocks and the couplings absorbed.
    pub structure: BlockStructure,
}

impl BlockStructure {
    /// Whether a response should say how its blocks were found: couplings absorbed, a weak
    /// coupling keeping blocks merged, or blocks `declared`.
    pub fn worth_saying(&self, declared: bool) -> bool {
        !self.couplings.is_empty() || self.near_miss.is_some() || declared
    }

    /// `tr P̄_a + tr P̄_b − tr P_a − tr P_b`, the sum of [`Coupling::trace_added`].
    pub fn trace_added(&self) -> f64 {
        self.couplings
            .iter()
            .fold(0.0, |sum, c| sum + c.trace_added)
    }

    /// A sentence for a person when the structure differs from what exact zeros give, or
    /// when a weak coupling keeps blocks merged; `None` otherwise.
    pub fn note(&self, tol: f64) -> Option<String> {
        let mut parts = Vec::new();
        if !self.couplings.is_empty() {
            let largest = self
                .couplings
                .iter()
                .map(|c| c.relative)
                .fold(0.0, f64::max);
            parts.push(format!(
                "{} near-zero coupling{} (largest {largest:.1e} relative, at most coupling_tol {tol:.0e}) absorbed into a proven block-diagonal bound: {} block{} instead of {} from exact zeros, covariance traces raised by {:.3e}",
                self.couplings.len(),
                if self.couplings.len() == 1 { "" } else { "s" },
                self.blocks.len(),
                if self.blocks.len() == 1 { "" } else { "s" },
                self.exact_blocks,
                self.trace_added(),
            ));
        }
        if let Some((size, count, advice)) = &self.near_miss {
            parts.push(format!(
                "a coupling of {} relative (above coupling_tol {tol:e}) keeps blocks merged: coupling_tol = {advice} would give {count} blocks",
                crate::error::digits_above(*size, tol),
            ));
        }
        (!parts.is_empty()).then(|| parts.join("; "))
    }
}

/// The blocks at tolerance `tol` of covariances `matrices` and cross patterns `patterns`:
/// components linked by a pattern or by entries above `tol` relative (module docs).
fn blocks_at(
    n: usize,
    matrices: &[(String, &DMatrix<f64>)],
    patterns: &[(String, &CrossPattern)],
    tol: f64,
) -> Vec<Vec<usize>> {
    connected_components(n, |i, j| {
        patterns
            .iter()
            .any(|(_, p)| p.is_unknown(i, j) || p.is_unknown(j, i))
            || matrices.iter().any(|(_, m)| relative(m, i, j) > tol)
    })
}

/// The structure of `problem` under `settings`, with its near-zero couplings absorbed
/// (module docs). Errors: invalid settings, a pattern with an unknown entry across declared
/// blocks, an entry across declared blocks above `coupling_tol`.
///
/// ```
/// use nalgebra::DMatrix;
/// use nmci::prelude::*;
/// // Two axes whose covariances carry a round-off coupling of 1e-13.
/// let P_a = DMatrix::from_row_slice(2, 2, &[4.0, 1e-13, 1e-13, 1.0]);
/// let P_b = DMatrix::from_row_slice(2, 2, &[1.0, 0.0, 0.0, 4.0]);
/// let p = FusionProblem::from_covariances(P_a, P_b, CrossPattern::diagonal(2)).unwrap();
/// let absorbed = absorb_couplings(&p, &StructureSettings::default()).unwrap();
/// assert_eq!(absorbed.structure.blocks, vec![vec![0], vec![1]]);
/// assert_eq!(absorbed.structure.exact_blocks, 1);
/// let nm = non_monolithic_ci(&absorbed.problem, Criterion::Trace).unwrap();
/// assert!((nm.fused.trace() - 2.0).abs() < 1e-12); // CI alone gives more
/// ```
#[allow(non_snake_case)]
pub fn absorb_couplings(
    problem: &FusionProblem,
    settings: &StructureSettings,
) -> Result<Absorbed, InputError> {
    let matrices = [
        ("pa".to_string(), &problem.P_a),
        ("pb".to_string(), &problem.P_b),
    ];
    let patterns = [("pab_unknown".to_string(), &problem.cross_pattern)];
    let (mut bounds, structure) = absorb(problem.dim(), &matrices, &patterns, settings)?;
    let Bounds {
        above: P_b,
        below: L_b,
    } = bounds.pop().expect("two matrices");
    let Bounds {
        above: P_a,
        below: L_a,
    } = bounds.pop().expect("two matrices");
    let deflated = (!structure.couplings.is_empty()
        && is_positive_definite(&L_a)
        && is_positive_definite(&L_b))
    .then(|| FusionProblem {
        P_a: L_a,
        P_b: L_b,
        ..problem.clone()
    });
    Ok(Absorbed {
        problem: FusionProblem {
            P_a,
            P_b,
            ..problem.clone()
        },
        deflated,
        structure,
    })
}

/// The structure of covariances `matrices` (named by their request field) of `n` states
/// linked by cross patterns `patterns` (named likewise), and the covariances with their
/// couplings absorbed, and with their diagonals lowered instead, in order. A problem where some
/// cross-covariance is wholly unknown is passed with a fully unknown pattern.
#[allow(non_snake_case)]
pub(crate) fn absorb(
    n: usize,
    matrices: &[(String, &DMatrix<f64>)],
    patterns: &[(String, &CrossPattern)],
    settings: &StructureSettings,
) -> Result<(Vec<Bounds>, BlockStructure), InputError> {
    settings.validate(n)?;
    let tol = settings.coupling_tol;
    if let Some(declared) = &settings.blocks {
        check_declared(n, matrices, patterns, declared, tol)?;
    }
    let blocks = blocks_at(n, matrices, patterns, tol);
    let exact_blocks = if tol == 0.0 {
        blocks.len()
    } else {
        blocks_at(n, matrices, patterns, 0.0).len()
    };
    let near_miss = near_miss(n, matrices, patterns, &blocks, tol);
    let of = block_of(n, &blocks);
    let mut couplings = Vec::new();
    let mut bounds = Vec::with_capacity(matrices.len());
    for (name, P) in matrices {
        let (b, found) = inflate(name, P, &blocks, &of)?;
        couplings.extend(found);
        bounds.push(b);
    }
    Ok((
        bounds,
        BlockStructure {
            blocks,
            couplings,
            exact_blocks,
            near_miss,
        },
    ))
}

/// A declared partition against the covariances and patterns: no pattern has an unknown
/// entry across it, and no covariance an entry across it above `tol` relative (the largest is
/// named).
fn check_declared(
    n: usize,
    matrices: &[(String, &DMatrix<f64>)],
    patterns: &[(String, &CrossPattern)],
    declared: &[Vec<usize>],
    tol: f64,
) -> Result<(), InputError> {
    let of = block_of(n, declared);
    for (field, pattern) in patterns {
        for i in 0..n {
            for j in 0..n {
                if of[i] != of[j] && pattern.is_unknown(i, j) {
                    return Err(InputError::PatternCrossesBlocks {
                        field: field.clone(),
                        row: i,
                        col: j,
                        blocks: [of[i], of[j]],
                    });
                }
            }
        }
    }
    match strongest_across(matrices, &of, tol) {
        Some((relative, k, row, col)) => Err(InputError::CouplingTooLarge {
            name: matrices[k].0.clone(),
            row,
            col,
            value: matrices[k].1[(row, col)],
            relative,
            blocks: [of[row].min(of[col]), of[row].max(of[col])],
            tol,
        }),
        None => Ok(()),
    }
}

/// The entry above `tol` relative, between different blocks of `of`, that is largest relative
/// to its diagonal: `(relative size, index into matrices, row, col)` with `row < col`.
fn strongest_across(
    matrices: &[(String, &DMatrix<f64>)],
    of: &[usize],
    tol: f64,
) -> Option<(f64, usize, usize, usize)> {
    let n = of.len();
    let mut strongest: Option<(f64, usize, usize, usize)> = None;
    for (k, (_, p)) in matrices.iter().enumerate() {
        for i in 0..n {
            for j in i + 1..n {
                let rel = relative(p, i, j);
                if of[i] != of[j] && rel > tol && strongest.is_none_or(|s| rel > s.0) {
                    strongest = Some((rel, k, i, j));
                }
            }
        }
    }
    strongest
}

/// The strongest coupling between `blocks` that stays at most [`COUPLING_HINT`] relative and
/// above `tol`, with the number of blocks a tolerance of its size would give, when that is
/// more than `blocks`.
fn near_miss(
    n: usize,
    matrices: &[(String, &DMatrix<f64>)],
    patterns: &[(String, &CrossPattern)],
    blocks: &[Vec<usize>],
    tol: f64,
) -> Option<(f64, usize, String)> {
    let finer = blocks_at(n, matrices, patterns, COUPLING_HINT);
    if finer.len() <= blocks.len() {
        return None;
    }
    let (size, ..) = strongest_across(matrices, &block_of(n, &finer), tol)?;
    let count = blocks_at(n, matrices, patterns, size).len();
    // The shortest decimal at least `size` that still gives `count` blocks (at 17 digits it
    // is `size` itself, which does).
    let advice = (2..=17)
        .map(|digits| format!("{:.*e}", digits - 1, size))
        .find(|text| {
            text.parse::<f64>()
                .is_ok_and(|t| t >= size && blocks_at(n, matrices, patterns, t).len() == count)
        })
        .unwrap_or_else(|| format!("{size:e}"));
    Some((size, count, advice))
}

/// `P` with its couplings between `blocks` (`of`: the block of each state) absorbed into the
/// diagonal (module docs), the same with the diagonal lowered instead (module docs, "A lower
/// end"), and the couplings found. `P` itself, bit for bit, twice, when there are none.
#[allow(non_snake_case)]
fn inflate(
    name: &str,
    P: &DMatrix<f64>,
    blocks: &[Vec<usize>],
    of: &[usize],
) -> Result<(Bounds, Vec<Coupling>), InputError> {
    let m = blocks.len();
    let mut found = Vec::new();
    // Proven bounds r_ij ≥ ‖E_ij‖₂ of each pair's coupling, added to d_i and d_j.
    let mut radii: Vec<Vec<f64>> = vec![Vec::new(); m];
    for bi in 0..m {
        for bj in bi + 1..m {
            let (rows, cols) = (&blocks[bi], &blocks[bj]);
            let mut largest = (0.0f64, 0, 0);
            let mut col_sums = vec![0.0f64; cols.len()];
            let mut max_row = 0.0f64;
            for &r in rows {
                let mut row_sum = 0.0;
                for (k, &c) in cols.iter().enumerate() {
                    let v = P[(r, c)].abs();
                    row_sum += v;
                    col_sums[k] += v;
                    if v > largest.0 {
                        largest = (v, r, c);
                    }
                }
                max_row = max_row.max(row_sum);
            }
            if largest.0 == 0.0 {
                continue;
            }
            let max_col = col_sums.iter().copied().fold(0.0, f64::max);
            // Each sum is of at most max(|rows|, |cols|) non-negative terms (verify::up).
            let r = up(max_row.max(max_col), rows.len().max(cols.len()));
            radii[bi].push(r);
            radii[bj].push(r);
            let (_, row, col) = largest;
            found.push(Coupling {
                matrix: name.into(),
                blocks: [bi, bj],
                row,
                col,
                value: P[(row, col)],
                relative: relative(P, row, col),
                norm_bound: r,
                trace_added: r * (rows.len() + cols.len()) as f64,
            });
        }
    }
    if found.is_empty() {
        return Ok((
            Bounds {
                above: P.clone(),
                below: P.clone(),
            },
            found,
        ));
    }
    let d: Vec<f64> = radii
        .iter()
        .map(|r| {
            if r.is_empty() {
                0.0
            } else {
                up(r.iter().sum(), r.len())
            }
        })
        .collect();
    let n = P.nrows();
    let mut P_bar = DMatrix::from_fn(n, n, |i, j| if of[i] == of[j] { P[(i, j)] } else { 0.0 });
    let mut P_low = P_bar.clone();
    for i in 0..n {
        let di = d[of[i]];
        if di > 0.0 {
            // Round up (down): the float sum is within half an ulp of the exact one.
            let raised = next_up(P_bar[(i, i)] + di);
            if !raised.is_finite() {
                return Err(InputError::OutOfRange {
                    name: name.into(),
                    largest: P.amax(),
                });
            }
            P_bar[(i, i)] = raised;
            P_low[(i, i)] = next_down(P_low[(i, i)] - di);
        }
    }
    Ok((
        Bounds {
            above: P_bar,
            below: P_low,
        },
        found,
    ))
}

/// A covariance with its couplings absorbed (`above ⪰ P`) and with its diagonal lowered
/// instead (`below ⪯ P`; module docs).
pub(crate) struct Bounds {
    /// `P̄`.
    pub above: DMatrix<f64>,
    /// `P⁻`.
    pub below: DMatrix<f64>,
}

impl CrossPattern {
    /// The pattern a declared partition implies: `P_ab[i][j]` unknown when `i`, `j` are in
    /// the same block, a known zero otherwise (independent errors across blocks).
    pub fn within_blocks(n: usize, blocks: &[Vec<usize>]) -> Result<Self, InputError> {
        check_partition(n, blocks)?;
        let of = block_of(n, blocks);
        Ok(Self::from_fn(n, |i, j| of[i] == of[j]))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn partitions_are_checked_by_state() {
        assert!(check_partition(3, &[vec![0, 2], vec![1]]).is_ok());
        for (blocks, says) in [
            (vec![vec![0, 1]], "state 2 is in no block"),
            (vec![vec![0, 1], vec![1, 2]], "state 1 is in two blocks"),
            (vec![vec![0, 1, 2], vec![3]], "state 3 does not exist"),
            (vec![vec![0, 1, 2], vec![]], "block 1 is empty"),
        ] {
            let e = check_partition(3, &blocks).unwrap_err().to_string();
            assert!(e.contains(says), "{e}");
        }
    }
}
