//! The sum-of-squares program of one block and one family (the parent's module docs, "The
//! program"): assembled, solved, its certificate repaired.

use std::collections::BTreeMap;

use clarabel::algebra::CscMatrix;
use clarabel::solver::SupportedConeT;
use nalgebra::DMatrix;

use crate::error::SolveError;
use crate::fusion::program::{solve_program, svec_index, Deadline, Kkt, SdpStatus};
use crate::fusion::FusionProblem;

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

/// One piece of a block's certificate: its conditions hold for every direction (no
/// multipliers), or only on a cone of directions and its negative, through multipliers
/// `q_j(v) = vᵀ S_j v ≥ 0` there (level 1; module docs, "Sectors").
#[allow(non_snake_case)]
pub(super) struct Piece {
    pub(super) multipliers: Vec<DMatrix<f64>>,
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

/// Where the program's `Q` may go (the parent's module docs, "At a given rule").
#[allow(non_snake_case)]
#[derive(Clone, Copy)]
pub(super) enum Base<'a> {
    /// `Q` free.
    Free,
    /// `Q = Q₀ + tI` with a free scalar `t` (of either sign).
    Shift(&'a DMatrix<f64>),
    /// `Q ⪰ Q₀`.
    Above(&'a DMatrix<f64>),
}

/// The program of [`certify_pieces`], solved, with `Q` restricted by `base`.
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
    let (m, s, N) = (lay.m, lay.mons.len(), lay.big());
    let nb = lay.lower.len();
    let J0 = |p: usize, q: usize| match (p < n, q < n) {
        (true, true) => problem.P_a[(p, q)],
        (false, false) => problem.P_b[(p - n, q - n)],
        _ => 0.0,
    };
    // Variables: Q (svec of n), K_a (n², when free), then per piece C (svec of N), G (svec of
    // s) and, per multiplier of the piece, C' (svec of m) and g' (one).
    let var_q = |k: usize, l: usize| svec_index(k.min(l), k.max(l));
    let off_k = n * (n + 1) / 2;
    let var_k = |k: usize, i: usize| off_k + k + i * n;
    let mut next = off_k + if gain.is_none() { n * n } else { 0 };
    struct Offsets {
        c: usize,
        g: usize,
        /// Per multiplier: the offsets of its C' and of its g'.
        mult: Vec<(usize, usize)>,
    }
    let offsets: Vec<Offsets> = pieces
        .iter()
        .map(|piece| {
            let c = next;
            let g = c + N * (N + 1) / 2;
            next = g + s * (s + 1) / 2;
            let mult = piece
                .multipliers
                .iter()
                .map(|_| {
                    let cp = next;
                    next = cp + m * (m + 1) / 2 + 1;
                    (cp, cp + m * (m + 1) / 2)
                })
                .collect();
            Offsets { c, g, mult }
        })
        .collect();
    // With `Base::Shift`: t, the multiple of I added to Q₀.
    let var_t = next;
    let total_vars = next + usize::from(matches!(base, Base::Shift(_)));
    let var_c = |o: &Offsets, x: usize, y: usize| o.c + svec_index(x.min(y), x.max(y));
    let var_g = |o: &Offsets, a: usize, b: usize| o.g + svec_index(a.min(b), a.max(b));
    let var_cp = |cp: usize, x: usize, y: usize| cp + svec_index(x.min(y), x.max(y));

    // Condition 2: per piece, one group of C entries per (γ, unknown (i, j)) that must sum to
    // zero.
    let mut groups: Vec<Vec<usize>> = Vec::new();
    // Condition 3, per piece one row per degree-2r monomial γ.
    let mut sos: Vec<BTreeMap<usize, f64>> = Vec::new();
    for (piece, o) in pieces.iter().zip(&offsets) {
        let mut by_key: BTreeMap<(usize, usize, usize), Vec<usize>> = BTreeMap::new();
        for a in 0..s {
            for b in 0..s {
                let g = lay.sum[a][b];
                for i in 0..n {
                    for j in 0..n {
                        if problem.cross_pattern.is_unknown(i, j) {
                            by_key.entry((g, i, j)).or_default().push(var_c(
                                o,
                                a * m + i,
                                b * m + n + j,
                            ));
                        }
                    }
                }
            }
        }
        groups.extend(by_key.into_values());
        let mut rows = vec![BTreeMap::new(); lay.products.len()];
        for (beta, c) in &lay.lower {
            for k in 0..n {
                for l in 0..n {
                    *rows[lay.quad(beta, k, l)].entry(var_q(k, l)).or_default() += c;
                }
            }
        }
        for a in 0..s {
            for b in 0..s {
                let row = &mut rows[lay.sum[a][b]];
                for p in 0..m {
                    for q in 0..m {
                        let j = J0(p, q);
                        if j != 0.0 {
                            *row.entry(var_c(o, a * m + p, b * m + q)).or_default() -= j;
                        }
                    }
                }
                *row.entry(var_g(o, a, b)).or_default() -= 1.0;
            }
        }
        for (S, &(_, gp)) in piece.multipliers.iter().zip(&o.mult) {
            for (g, row) in rows.iter_mut().enumerate() {
                let sg = lay.multiplier_coefficient(S, g);
                if sg != 0.0 {
                    *row.entry(gp).or_default() -= sg;
                }
            }
        }
        sos.extend(rows);
    }
    let sqrt2 = std::f64::consts::SQRT_2;
    let base_rows = match base {
        Base::Shift(_) => n * (n + 1) / 2,
        _ => 0,
    };
    let above_rows = match base {
        Base::Above(_) => n * (n + 1) / 2,
        _ => 0,
    };
    let zeros = groups.len() + sos.len() + base_rows;
    let cone = N + nb;
    let multipliers: usize = pieces.iter().map(|p| p.multipliers.len()).sum();
    let piece_rows = |piece: &Piece| {
        cone * (cone + 1) / 2 + s * (s + 1) / 2 + piece.multipliers.len() * m * (m + 1) / 2
    };
    let rows_total =
        zeros + pieces.iter().map(piece_rows).sum::<usize>() + multipliers + above_rows;
    let mut b = vec![0.0; rows_total];
    let (mut rows, mut cols, mut vals) = (Vec::new(), Vec::new(), Vec::new());
    for (e, group) in groups.iter().enumerate() {
        let mut coef: BTreeMap<usize, f64> = BTreeMap::new();
        for &v in group {
            *coef.entry(v).or_default() += 1.0;
        }
        for (v, c) in coef {
            rows.push(e);
            cols.push(v);
            vals.push(c);
        }
    }
    for (g, row) in sos.iter().enumerate() {
        for (&v, &c) in row {
            if c != 0.0 {
                rows.push(groups.len() + g);
                cols.push(v);
                vals.push(c);
            }
        }
    }
    // Q_kl − δ_kl t = Q₀_kl.
    if let Base::Shift(Q0) = base {
        for l in 0..n {
            for k in 0..=l {
                let row = groups.len() + sos.len() + var_q(k, l);
                rows.push(row);
                cols.push(var_q(k, l));
                vals.push(1.0);
                if k == l {
                    rows.push(row);
                    cols.push(var_t);
                    vals.push(-1.0);
                }
                b[row] = Q0[(k, l)];
            }
        }
    }
    let mut base_row = zeros;
    let mut cones = vec![SupportedConeT::ZeroConeT(zeros)];
    let psd = |rows: &mut Vec<usize>,
               cols: &mut Vec<usize>,
               vals: &mut Vec<f64>,
               base_row: usize,
               size: usize,
               var: &dyn Fn(usize, usize) -> usize| {
        for c in 0..size {
            for r in 0..=c {
                rows.push(base_row + svec_index(r, c));
                cols.push(var(r, c));
                vals.push(if r == c { -1.0 } else { -sqrt2 });
            }
        }
    };
    // Per piece: condition 1 as [[C, W D^{1/2}], [·, I]] ⪰ 0, condition 4 (G ⪰ 0) and, per
    // multiplier, C' ⪰ 0.
    let mut schur_bases = Vec::with_capacity(pieces.len());
    for (piece, o) in pieces.iter().zip(&offsets) {
        psd(&mut rows, &mut cols, &mut vals, base_row, N, &|x, y| {
            var_c(o, x, y)
        });
        // The top left block is C − Σ_j S_j ⊗ C'_j (S_j the matrix of q_j):
        // (S ⊗ C')[(a,p),(b,q)] = S_ab C'_pq.
        let mut coef: BTreeMap<(usize, usize), f64> = BTreeMap::new();
        for (S, &(cp, _)) in piece.multipliers.iter().zip(&o.mult) {
            for c in 0..N {
                for r in 0..=c {
                    let (a, p, bb, q) = (r / m, r % m, c / m, c % m);
                    let w = if r == c { 1.0 } else { sqrt2 };
                    if S[(a, bb)] != 0.0 {
                        *coef
                            .entry((base_row + svec_index(r, c), var_cp(cp, p, q)))
                            .or_default() += w * S[(a, bb)];
                    }
                }
            }
        }
        for ((row, var), c) in coef {
            rows.push(row);
            cols.push(var);
            vals.push(c);
        }
        schur_bases.push(base_row);
        base_row += cone * (cone + 1) / 2;
        cones.push(SupportedConeT::PSDTriangleConeT(cone));
        psd(&mut rows, &mut cols, &mut vals, base_row, s, &|x, y| {
            var_g(o, x, y)
        });
        base_row += s * (s + 1) / 2;
        cones.push(SupportedConeT::PSDTriangleConeT(s));
        for &(cp, _) in &o.mult {
            psd(&mut rows, &mut cols, &mut vals, base_row, m, &|x, y| {
                var_cp(cp, x, y)
            });
            base_row += m * (m + 1) / 2;
            cones.push(SupportedConeT::PSDTriangleConeT(m));
        }
    }
    // g' ≥ 0 for each multiplier.
    for o in &offsets {
        for &(_, gp) in &o.mult {
            rows.push(base_row);
            cols.push(gp);
            vals.push(-1.0);
            base_row += 1;
        }
    }
    if multipliers > 0 {
        cones.push(SupportedConeT::NonnegativeConeT(multipliers));
    }
    // Q − Q₀ ⪰ 0: s = b − A x = svec(Q) − svec(Q₀).
    if let Base::Above(Q0) = base {
        psd(&mut rows, &mut cols, &mut vals, base_row, n, &|k, l| {
            var_q(k, l)
        });
        for l in 0..n {
            for k in 0..=l {
                let scale = if k == l { 1.0 } else { sqrt2 };
                b[base_row + svec_index(k, l)] = -scale * Q0[(k, l)];
            }
        }
        base_row += n * (n + 1) / 2;
        cones.push(SupportedConeT::PSDTriangleConeT(n));
    }
    debug_assert_eq!(base_row, rows_total);
    for &schur in &schur_bases {
        for (t, (beta, cb)) in lay.lower.iter().enumerate() {
            let scale = sqrt2 * cb.sqrt();
            for alpha in 0..s {
                let Some(k) = lay.step(alpha, beta) else {
                    continue;
                };
                for p in 0..m {
                    let e = schur + svec_index(alpha * m + p, N + t);
                    // K[k, p] = K_a[k, p] (p < n), δ_{k, p−n} − K_a[k, p−n] (p ≥ n).
                    let (constant, coefficient, column) = if p < n {
                        (0.0, 1.0, p)
                    } else {
                        (if k == p - n { 1.0 } else { 0.0 }, -1.0, p - n)
                    };
                    match gain {
                        Some(K_a) => b[e] = scale * (constant + coefficient * K_a[(k, column)]),
                        None => {
                            b[e] = scale * constant;
                            rows.push(e);
                            cols.push(var_k(k, column));
                            vals.push(-scale * coefficient);
                        }
                    }
                }
            }
            b[schur + svec_index(N + t, N + t)] = 1.0;
        }
    }
    let mut q = vec![0.0; total_vars];
    for k in 0..n {
        q[var_q(k, k)] = 1.0;
    }
    let A = CscMatrix::new_from_triplets(rows_total, total_vars, rows, cols, vals);
    let P_quad = CscMatrix::zeros((total_vars, total_vars));
    let (solver, status) = solve_program(
        &P_quad,
        &q,
        &A,
        &b,
        &cones,
        Kkt::Platform,
        (settings.max_iter, settings.tolerance),
        &Deadline::after(settings.time_limit),
        "the certified bound's SDP",
    )?;
    let sol = &solver.solution;
    let K_a = match gain {
        Some(K_a) => K_a.clone(),
        None => DMatrix::from_fn(n, n, |k, i| sol.x[var_k(k, i)]),
    };
    let mut x = sol.x.clone();
    for group in &groups {
        exact_zero_sum(&mut x, group);
        let terms: Vec<f64> = group.iter().map(|&v| x[v]).collect();
        if !sums_to_zero(&terms) {
            return Err(repair_failed("the zero-sum groups"));
        }
    }
    let Q = DMatrix::from_fn(n, n, |k, l| x[var_q(k, l)]);
    let raw = pieces
        .iter()
        .zip(&offsets)
        .map(|(piece, o)| RawPiece {
            C: DMatrix::from_fn(N, N, |r, c| x[var_c(o, r, c)]),
            G: DMatrix::from_fn(s, s, |a, b| x[var_g(o, a, b)]),
            parts: piece
                .multipliers
                .iter()
                .zip(&o.mult)
                .map(|(S, &(cp, gp))| MultiplierPart {
                    S: S.clone(),
                    Cp: DMatrix::from_fn(m, m, |r, c| x[var_cp(cp, r, c)]),
                    gp: x[gp].max(0.0),
                })
                .collect(),
        })
        .collect();
    let shares = (0..pieces.len())
        .map(|k| {
            let first = groups.len() + k * lay.products.len();
            let mut share = 0.0;
            for (beta, c) in &lay.lower {
                for i in 0..n {
                    share -= c * sol.z[first + lay.quad(beta, i, i)];
                }
            }
            share
        })
        .collect();
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
