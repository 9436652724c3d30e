//! The structure of a fusion problem: which entries of the cross-covariance `P_ab` may be
//! non-zero, and the finest partition of the state into mutually independent blocks.
//!
//! Two states `i` and `j` are *linked* when `P_a[i,j]`, `P_b[i,j]`, `P_ab[i,j]` or `P_ab[j,i]`
//! may be non-zero. The blocks are the connected components of that graph. Across blocks
//! every covariance and cross-covariance is zero, so the problem splits into one independent
//! fusion per block (the paper's eq. for the non-monolithic GMD): this is what nmCI exploits.
//! An entry of `P_a` or `P_b` counts as zero only when it is exactly `0.0` here;
//! [`absorb_couplings`] (module `absorb`) also keeps blocks that only near-zero entries link,
//! by a proven inflation, and takes declared blocks.

pub(crate) mod absorb;

use nalgebra::DMatrix;

use crate::error::InputError;

pub use absorb::{
    absorb_couplings, check_partition, Absorbed, BlockStructure, Coupling, StructureSettings,
    COUPLING_HINT, DEFAULT_COUPLING_TOL,
};

/// Which entries of the `n × n` cross-covariance `P_ab = E[e_a e_bᵀ]` may be non-zero.
///
/// `true` = unknown (may be non-zero), `false` = known zero (the index set `I` of the paper).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct CrossPattern {
    unknown: DMatrix<bool>,
}

impl CrossPattern {
    /// Every entry unknown: classic CI's assumption.
    pub fn fully_unknown(n: usize) -> Self {
        Self {
            unknown: DMatrix::from_element(n, n, true),
        }
    }

    /// Only the diagonal unknown (the paper's 2-D example: `P_ab = diag(·, ·)`).
    pub fn diagonal(n: usize) -> Self {
        Self {
            unknown: DMatrix::from_fn(n, n, |i, j| i == j),
        }
    }

    /// Every entry known to be zero: the two estimates are uncorrelated.
    pub fn independent(n: usize) -> Self {
        Self {
            unknown: DMatrix::from_element(n, n, false),
        }
    }

    /// From a function of `(i, j)` (`true` = may be non-zero).
    pub fn from_fn(n: usize, unknown: impl Fn(usize, usize) -> bool) -> Self {
        Self {
            unknown: DMatrix::from_fn(n, n, unknown),
        }
    }

    /// From a boolean matrix (`true` = may be non-zero).
    pub fn from_matrix(unknown: DMatrix<bool>) -> Result<Self, InputError> {
        if unknown.nrows() != unknown.ncols() {
            return Err(InputError::NotSquare {
                name: "pab_unknown".into(),
                rows: unknown.nrows(),
                cols: unknown.ncols(),
            });
        }
        Ok(Self { unknown })
    }

    /// From nested rows (`true` = may be non-zero).
    pub fn from_rows(rows: &[Vec<bool>]) -> Result<Self, InputError> {
        let n = rows.len();
        if let Some(r) = rows.iter().find(|r| r.len() != n) {
            return Err(InputError::NotSquare {
                name: "pab_unknown".into(),
                rows: n,
                cols: r.len(),
            });
        }
        Ok(Self {
            unknown: DMatrix::from_fn(n, n, |i, j| rows[i][j]),
        })
    }

    /// Size `n`.
    pub fn dim(&self) -> usize {
        self.unknown.nrows()
    }

    /// Whether `P_ab[i, j]` may be non-zero.
    pub fn is_unknown(&self, i: usize, j: usize) -> bool {
        self.unknown[(i, j)]
    }

    /// Number of unknown entries.
    pub fn unknown_count(&self) -> usize {
        self.unknown.iter().filter(|u| **u).count()
    }

    /// The pattern restricted to the states in `idx` (rows and columns).
    pub fn restrict(&self, idx: &[usize]) -> Self {
        Self {
            unknown: DMatrix::from_fn(idx.len(), idx.len(), |i, j| self.unknown[(idx[i], idx[j])]),
        }
    }

    /// The boolean matrix.
    pub fn as_matrix(&self) -> &DMatrix<bool> {
        &self.unknown
    }
}

/// Finest partition of the states `0..n` into independent blocks (connected components of
/// the link graph described in the module docs). Blocks are sorted by their smallest state,
/// states inside a block ascending; blocks need not be contiguous.
///
/// ```
/// use nalgebra::DMatrix;
/// use nmci::{CrossPattern, structure::independent_blocks};
/// let P_a = DMatrix::from_diagonal_element(2, 2, 3.0);
/// let P_b = DMatrix::from_diagonal_element(2, 2, 1.0);
/// let blocks = independent_blocks(&P_a, &P_b, &CrossPattern::diagonal(2));
/// assert_eq!(blocks, vec![vec![0], vec![1]]);
/// ```
#[allow(non_snake_case)]
pub fn independent_blocks(
    P_a: &DMatrix<f64>,
    P_b: &DMatrix<f64>,
    cross_pattern: &CrossPattern,
) -> Vec<Vec<usize>> {
    connected_components(P_a.nrows(), |i, j| {
        P_a[(i, j)] != 0.0
            || P_a[(j, i)] != 0.0
            || P_b[(i, j)] != 0.0
            || P_b[(j, i)] != 0.0
            || cross_pattern.is_unknown(i, j)
            || cross_pattern.is_unknown(j, i)
    })
}

/// The connected components of the graph on `0..n` with an edge where `linked(i, j)` (asked
/// for `i < j`; `linked` must be symmetric), by union-find: blocks ordered by their first
/// state, states ascending. Shared by [`independent_blocks`] and non-monolithic N-way CI.
pub(crate) fn connected_components(
    n: usize,
    linked: impl Fn(usize, usize) -> bool,
) -> Vec<Vec<usize>> {
    let mut parent: Vec<usize> = (0..n).collect();
    fn find(parent: &mut [usize], mut i: usize) -> usize {
        while parent[i] != i {
            parent[i] = parent[parent[i]];
            i = parent[i];
        }
        i
    }
    for i in 0..n {
        for j in i + 1..n {
            if linked(i, j) {
                let (ri, rj) = (find(&mut parent, i), find(&mut parent, j));
                if ri != rj {
                    parent[ri.max(rj)] = ri.min(rj);
                }
            }
        }
    }
    let mut blocks: Vec<Vec<usize>> = Vec::new();
    let mut block_of_root = vec![usize::MAX; n];
    for i in 0..n {
        let r = find(&mut parent, i);
        if block_of_root[r] == usize::MAX {
            block_of_root[r] = blocks.len();
            blocks.push(Vec::new());
        }
        blocks[block_of_root[r]].push(i);
    }
    blocks
}
