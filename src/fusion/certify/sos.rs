//! The sum-of-squares program of one block and one family (the parent's module docs, "The
//! program"): assembled, solved, its certificate repaired.

use clarabel::algebra::CscMatrix;
use nalgebra::DMatrix;

use crate::error::SolveError;
use crate::fusion::program::{solve_program, Deadline, Kkt, SdpStatus};
use crate::fusion::FusionProblem;

use super::assemble::{equalities, Base, Constraints, Piece, Variables};
use super::layout::Layout;
use super::repair::{exact_zero_sum, repair, repair_failed, sums_to_zero, MultiplierPart};
use super::settings::CertifySettings;

#[allow(non_snake_case)]
pub(super) struct BlockCertificate {
    pub(super) K_a: DMatrix<f64>,
    pub(super) P: DMatrix<f64>,
    pub(super) status: SdpStatus,
    pub(super) iterations: u32,
    pub(super) repair: f64,
    /// The cones or sectors of directions certified on (0: one certificate for every
    /// direction).
    pub(super) pieces: u32,
}

/// The level-`level` certificate on `pieces` (module docs), solved and repaired; with each
/// piece's share of the objective: the trace of the moment matrix the solver's dual puts on
/// the piece's condition 3 (the dual of `Q`'s rows; the shares sum to `n` up to tolerance),
/// large where the bound is tight, zero where the piece's certificate has slack.
#[allow(non_snake_case)]
pub(super) fn certify_pieces(
    problem: &FusionProblem,
    gain: Option<&DMatrix<f64>>,
    level: u32,
    pieces: &[Piece],
    settings: &CertifySettings,
) -> Result<(BlockCertificate, Vec<f64>), SolveError> {
    let solved = solve_pieces(problem, gain, Base::Free, level, pieces, settings)?;
    let mut Q = solved.Q.clone();
    for raw in &solved.pieces {
        prove_piece(problem, &solved.layout, &solved.K_a, &mut Q, raw)?;
    }
    let repair = (Q.trace() - solved.Q.trace()).max(0.0);
    let count = match pieces {
        [whole] if whole.multipliers.is_empty() => 0,
        _ => pieces.len() as u32,
    };
    Ok((
        BlockCertificate {
            K_a: solved.K_a,
            P: Q,
            status: solved.status,
            iterations: solved.iterations,
            repair,
            pieces: count,
        },
        solved.shares,
    ))
}

/// A piece's certificate as solved, its zero-sum groups made exact (module docs): the parts
/// [`prove_piece`] repairs against a given `Q`.
#[allow(non_snake_case)]
pub(super) struct RawPiece {
    pub(super) C: DMatrix<f64>,
    pub(super) G: DMatrix<f64>,
    pub(super) parts: Vec<MultiplierPart>,
}

/// The solver's point of the program on `pieces`, before the repair.
#[allow(non_snake_case)]
pub(super) struct Solved {
    pub(super) layout: Layout,
    pub(super) K_a: DMatrix<f64>,
    /// The solver's `Q` (in its `base`, up to the solver's tolerance).
    pub(super) Q: DMatrix<f64>,
    pub(super) status: SdpStatus,
    pub(super) iterations: u32,
    pub(super) pieces: Vec<RawPiece>,
    /// Each piece's share of the objective ([`certify_pieces`]).
    pub(super) shares: Vec<f64>,
}

/// Repairs `Q` (by multiples of `I`) until `raw`'s certificate is proven for `K_a` and `Q`
/// (module docs, "Exact in floating point"). `Q` only grows, so pieces proven before stay
/// proven.
#[allow(non_snake_case)]
pub(super) fn prove_piece(
    problem: &FusionProblem,
    layout: &Layout,
    K_a: &DMatrix<f64>,
    Q: &mut DMatrix<f64>,
    raw: &RawPiece,
) -> Result<(), SolveError> {
    let parts = raw
        .parts
        .iter()
        .map(|p| MultiplierPart {
            S: p.S.clone(),
            Cp: p.Cp.clone(),
            gp: p.gp,
        })
        .collect();
    repair(problem, layout, K_a, raw.C.clone(), Q, &raw.G, parts)
}

/// The program of [`certify_pieces`], solved, with `Q` restricted by `base`: assembled
/// (`assemble`), solved, and read back with its zero-sum groups made exact.
#[allow(non_snake_case)]
pub(super) fn solve_pieces(
    problem: &FusionProblem,
    gain: Option<&DMatrix<f64>>,
    base: Base,
    level: u32,
    pieces: &[Piece],
    settings: &CertifySettings,
) -> Result<Solved, SolveError> {
    let n = problem.dim();
    let lay = Layout::new(n, level as usize);
    let vars = Variables::new(&lay, gain.is_none(), base, pieces);
    let (groups, sos) = equalities(problem, &lay, &vars, pieces);
    let mut constraints = Constraints::new(&lay, groups.len() + sos.len(), base, pieces);
    constraints.zero_cone(&groups, &sos, base, &vars);
    constraints.cones(&lay, &vars, pieces, base);
    constraints.gain(&lay, &vars, gain);
    let mut q = vec![0.0; vars.total];
    for k in 0..n {
        q[vars.q(k, k)] = 1.0;
    }
    let A = constraints.matrix(vars.total);
    let P_quad = CscMatrix::zeros((vars.total, vars.total));
    let (solver, status) = solve_program(
        &P_quad,
        &q,
        &A,
        &constraints.b,
        &constraints.cones,
        Kkt::Platform,
        (settings.max_iter, settings.tolerance),
        &Deadline::after(settings.time_limit),
        "the certified bound's SDP",
    )?;
    let sol = &solver.solution;
    let K_a = match gain {
        Some(K_a) => K_a.clone(),
        None => DMatrix::from_fn(n, n, |k, i| sol.x[vars.k(k, i)]),
    };
    let mut x = sol.x.clone();
    for group in &groups {
        exact_zero_sum(&mut x, group);
        let terms: Vec<f64> = group.iter().map(|&v| x[v]).collect();
        if !sums_to_zero(&terms) {
            return Err(repair_failed("the zero-sum groups"));
        }
    }
    let (m, s, N) = (lay.m, lay.mons.len(), lay.big());
    let Q = DMatrix::from_fn(n, n, |k, l| x[vars.q(k, l)]);
    let raw = pieces
        .iter()
        .zip(&vars.pieces)
        .map(|(piece, o)| RawPiece {
            C: DMatrix::from_fn(N, N, |r, c| x[vars.c(o, r, c)]),
            G: DMatrix::from_fn(s, s, |a, b| x[vars.g(o, a, b)]),
            parts: piece
                .multipliers
                .iter()
                .zip(&o.mult)
                .map(|(S, &(cp, gp))| MultiplierPart {
                    S: S.clone(),
                    Cp: DMatrix::from_fn(m, m, |r, c| x[vars.cp(cp, r, c)]),
                    gp: x[gp].max(0.0),
                })
                .collect(),
        })
        .collect();
    let shares = shares(&lay, pieces.len(), groups.len(), &sol.z);
    Ok(Solved {
        layout: lay,
        K_a,
        Q,
        status,
        iterations: sol.iterations,
        pieces: raw,
        shares,
    })
}

/// Each piece's share of the objective ([`certify_pieces`]): the trace of the moment matrix
/// the dual `z` puts on its condition 3 rows (which start after the `groups` rows of
/// condition 2, one block of `lay.products` rows per piece).
fn shares(lay: &Layout, pieces: usize, groups: usize, z: &[f64]) -> Vec<f64> {
    (0..pieces)
        .map(|k| {
            let first = groups + k * lay.products.len();
            let mut share = 0.0;
            for (beta, c) in &lay.lower {
                for i in 0..lay.n {
                    share -= c * z[first + lay.quad(beta, i, i)];
                }
            }
            share
        })
        .collect()
}
