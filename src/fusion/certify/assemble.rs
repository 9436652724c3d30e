//! The sum-of-squares program of one block, assembled for Clarabel (the parent's module docs,
//! "The program"): its variables ([`Variables`]), the equalities of conditions 2 and 3
//! ([`equalities`]), and the cones ([`Constraints`]): the zero cone (conditions 2 and 3, and
//! `Q = Q₀ + tI` for `Base::Shift`), per piece condition 1 as `[[C, W D^{1/2}], [·, I]] ⪰ 0`
//! with its multipliers, condition 4 (`G ⪰ 0`) and `C' ⪰ 0`, the multipliers' `g' ≥ 0`, and
//! `Q ⪰ Q₀` for `Base::Above`; the gain enters the off-diagonal blocks of condition 1
//! ([`Constraints::gain`]).

use std::collections::BTreeMap;

use clarabel::algebra::CscMatrix;
use clarabel::solver::SupportedConeT;
use nalgebra::DMatrix;

use crate::fusion::program::svec_index;
use crate::fusion::FusionProblem;

use super::layout::Layout;

const SQRT_2: f64 = std::f64::consts::SQRT_2;

/// One piece of a block's certificate: its conditions hold for every direction (no
/// multipliers), or only on a cone of directions and its negative, through multipliers
/// `q_j(v) = vᵀ S_j v ≥ 0` there (level 1; module docs, "Sectors").
#[allow(non_snake_case)]
pub(super) struct Piece {
    pub(super) multipliers: Vec<DMatrix<f64>>,
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

/// Where one piece's variables start: its `C`, its `G` and, per multiplier, its `C'` and
/// its `g'`.
pub(super) struct Offsets {
    c: usize,
    g: usize,
    pub(super) mult: Vec<(usize, usize)>,
}

/// The program's variables, in order: `Q` (svec of `n`), `K_a` (`n²`, when free), then per
/// piece `C` (svec of `N`), `G` (svec of `s`) and, per multiplier of the piece, `C'` (svec of
/// `m`) and `g'` (one); with `Base::Shift`, `t` (the multiple of `I` added to `Q₀`) last.
#[allow(non_snake_case)]
pub(super) struct Variables {
    n: usize,
    pub(super) pieces: Vec<Offsets>,
    t: usize,
    pub(super) total: usize,
}

#[allow(non_snake_case)]
impl Variables {
    pub(super) fn new(lay: &Layout, free_gain: bool, base: Base, pieces: &[Piece]) -> Self {
        let (n, m, s, N) = (lay.n, lay.m, lay.mons.len(), lay.big());
        let mut next = n * (n + 1) / 2 + if free_gain { n * n } else { 0 };
        let offsets = pieces
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
        Variables {
            n,
            pieces: offsets,
            t: next,
            total: next + usize::from(matches!(base, Base::Shift(_))),
        }
    }

    /// `Q_kl` (either order).
    pub(super) fn q(&self, k: usize, l: usize) -> usize {
        svec_index(k.min(l), k.max(l))
    }

    /// `K_a[k, i]` (a free gain only).
    pub(super) fn k(&self, k: usize, i: usize) -> usize {
        self.n * (self.n + 1) / 2 + k + i * self.n
    }

    /// The piece's `C_xy` (either order).
    pub(super) fn c(&self, o: &Offsets, x: usize, y: usize) -> usize {
        o.c + svec_index(x.min(y), x.max(y))
    }

    /// The piece's `G_ab` (either order).
    pub(super) fn g(&self, o: &Offsets, a: usize, b: usize) -> usize {
        o.g + svec_index(a.min(b), a.max(b))
    }

    /// `C'_xy` of the multiplier whose `C'` starts at `cp` (either order).
    pub(super) fn cp(&self, cp: usize, x: usize, y: usize) -> usize {
        cp + svec_index(x.min(y), x.max(y))
    }
}

/// Conditions 2 and 3 of every piece: the groups of `C` entries that must sum to zero (one
/// per degree-`2r` monomial `γ` and unknown entry `(i, j)`), and one row per `γ` of the
/// sum-of-squares identity (`Σ_β c_β Q`'s coefficient less `C`'s against the joint
/// covariance, `G`'s and the multipliers' `g'`).
#[allow(non_snake_case)]
pub(super) fn equalities(
    problem: &FusionProblem,
    lay: &Layout,
    vars: &Variables,
    pieces: &[Piece],
) -> (Vec<Vec<usize>>, Vec<BTreeMap<usize, f64>>) {
    let (n, m, s) = (lay.n, lay.m, lay.mons.len());
    let J0 = |p: usize, q: usize| match (p < n, q < n) {
        (true, true) => problem.P_a[(p, q)],
        (false, false) => problem.P_b[(p - n, q - n)],
        _ => 0.0,
    };
    let mut groups: Vec<Vec<usize>> = Vec::new();
    let mut sos: Vec<BTreeMap<usize, f64>> = Vec::new();
    for (piece, o) in pieces.iter().zip(&vars.pieces) {
        let mut by_key: BTreeMap<(usize, usize, usize), Vec<usize>> = BTreeMap::new();
        for a in 0..s {
            for b in 0..s {
                let g = lay.sum[a][b];
                for i in 0..n {
                    for j in 0..n {
                        if problem.cross_pattern.is_unknown(i, j) {
                            let c = vars.c(o, a * m + i, b * m + n + j);
                            by_key.entry((g, i, j)).or_default().push(c);
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
                    *rows[lay.quad(beta, k, l)].entry(vars.q(k, l)).or_default() += c;
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
                            *row.entry(vars.c(o, a * m + p, b * m + q)).or_default() -= j;
                        }
                    }
                }
                *row.entry(vars.g(o, a, b)).or_default() -= 1.0;
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
    (groups, sos)
}

/// The constraints `A x + s = b`, `s` in `cones`, as triplets, filled row block by row
/// block in the order of the cones.
#[allow(non_snake_case)]
pub(super) struct Constraints {
    rows: Vec<usize>,
    cols: Vec<usize>,
    vals: Vec<f64>,
    pub(super) b: Vec<f64>,
    pub(super) cones: Vec<SupportedConeT<f64>>,
    /// The first row of the next block.
    next: usize,
    /// The first row of each piece's condition 1 block.
    schur: Vec<usize>,
}

#[allow(non_snake_case)]
impl Constraints {
    /// The rows of the whole program.
    pub(super) fn new(lay: &Layout, equalities: usize, base: Base, pieces: &[Piece]) -> Self {
        let (n, m, s) = (lay.n, lay.m, lay.mons.len());
        let tri = |k: usize| k * (k + 1) / 2;
        let shift = if matches!(base, Base::Shift(_)) {
            tri(n)
        } else {
            0
        };
        let above = if matches!(base, Base::Above(_)) {
            tri(n)
        } else {
            0
        };
        let cone = lay.big() + lay.lower.len();
        let piece_rows =
            |piece: &Piece| tri(cone) + tri(s) + piece.multipliers.len() * (tri(m) + 1);
        let total = equalities + shift + pieces.iter().map(piece_rows).sum::<usize>() + above;
        Constraints {
            rows: Vec::new(),
            cols: Vec::new(),
            vals: Vec::new(),
            b: vec![0.0; total],
            cones: Vec::new(),
            next: 0,
            schur: Vec::with_capacity(pieces.len()),
        }
    }

    fn push(&mut self, row: usize, col: usize, val: f64) {
        self.rows.push(row);
        self.cols.push(col);
        self.vals.push(val);
    }

    /// The zero cone: conditions 2 (each group sums to zero) and 3 (the identity's rows), and
    /// for `Base::Shift` `Q_kl − δ_kl t = Q₀_kl`.
    pub(super) fn zero_cone(
        &mut self,
        groups: &[Vec<usize>],
        sos: &[BTreeMap<usize, f64>],
        base: Base,
        vars: &Variables,
    ) {
        for (e, group) in groups.iter().enumerate() {
            let mut coef: BTreeMap<usize, f64> = BTreeMap::new();
            for &v in group {
                *coef.entry(v).or_default() += 1.0;
            }
            for (v, c) in coef {
                self.push(e, v, c);
            }
        }
        for (g, row) in sos.iter().enumerate() {
            for (&v, &c) in row {
                if c != 0.0 {
                    self.push(groups.len() + g, v, c);
                }
            }
        }
        let mut zeros = groups.len() + sos.len();
        if let Base::Shift(Q0) = base {
            for l in 0..vars.n {
                for k in 0..=l {
                    let row = zeros + vars.q(k, l);
                    self.push(row, vars.q(k, l), 1.0);
                    if k == l {
                        self.push(row, vars.t, -1.0);
                    }
                    self.b[row] = Q0[(k, l)];
                }
            }
            zeros += vars.n * (vars.n + 1) / 2;
        }
        self.next = zeros;
        self.cones.push(SupportedConeT::ZeroConeT(zeros));
    }

    /// A PSD cone of `size` whose top left `filled × filled` block is `−var` (in svec); the
    /// rest of the block is constant (in `b`) or filled by the caller. Returns its first row.
    fn psd(&mut self, size: usize, filled: usize, var: &dyn Fn(usize, usize) -> usize) -> usize {
        let first = self.next;
        for c in 0..filled {
            for r in 0..=c {
                let val = if r == c { -1.0 } else { -SQRT_2 };
                self.push(first + svec_index(r, c), var(r, c), val);
            }
        }
        self.next += size * (size + 1) / 2;
        first
    }

    /// Per piece: condition 1, `[[C − Σ_j S_j ⊗ C'_j, W D^{1/2}], [·, I]] ⪰ 0` (the gain's
    /// part by [`Constraints::gain`]), condition 4 (`G ⪰ 0`) and per multiplier `C' ⪰ 0`;
    /// then `g' ≥ 0` for each multiplier and, for `Base::Above`, `Q − Q₀ ⪰ 0`.
    pub(super) fn cones(&mut self, lay: &Layout, vars: &Variables, pieces: &[Piece], base: Base) {
        let (n, m, s, N) = (lay.n, lay.m, lay.mons.len(), lay.big());
        let cone = N + lay.lower.len();
        for (piece, o) in pieces.iter().zip(&vars.pieces) {
            let first = self.psd(cone, N, &|x, y| vars.c(o, x, y));
            // (S ⊗ C')[(a,p),(b,q)] = S_ab C'_pq, subtracted from the top left block.
            let mut coef: BTreeMap<(usize, usize), f64> = BTreeMap::new();
            for (S, &(cp, _)) in piece.multipliers.iter().zip(&o.mult) {
                for c in 0..N {
                    for r in 0..=c {
                        let (a, p, bb, q) = (r / m, r % m, c / m, c % m);
                        let w = if r == c { 1.0 } else { SQRT_2 };
                        if S[(a, bb)] != 0.0 {
                            *coef
                                .entry((first + svec_index(r, c), vars.cp(cp, p, q)))
                                .or_default() += w * S[(a, bb)];
                        }
                    }
                }
            }
            for ((row, var), c) in coef {
                self.push(row, var, c);
            }
            self.schur.push(first);
            self.cones.push(SupportedConeT::PSDTriangleConeT(cone));
            self.psd(s, s, &|x, y| vars.g(o, x, y));
            self.cones.push(SupportedConeT::PSDTriangleConeT(s));
            for &(cp, _) in &o.mult {
                self.psd(m, m, &|x, y| vars.cp(cp, x, y));
                self.cones.push(SupportedConeT::PSDTriangleConeT(m));
            }
        }
        let mut multipliers = 0;
        for o in &vars.pieces {
            for &(_, gp) in &o.mult {
                self.push(self.next, gp, -1.0);
                self.next += 1;
                multipliers += 1;
            }
        }
        if multipliers > 0 {
            self.cones
                .push(SupportedConeT::NonnegativeConeT(multipliers));
        }
        // s = b − A x = svec(Q) − svec(Q₀).
        if let Base::Above(Q0) = base {
            let first = self.psd(n, n, &|k, l| vars.q(k, l));
            for l in 0..n {
                for k in 0..=l {
                    let scale = if k == l { 1.0 } else { SQRT_2 };
                    self.b[first + svec_index(k, l)] = -scale * Q0[(k, l)];
                }
            }
            self.cones.push(SupportedConeT::PSDTriangleConeT(n));
        }
        debug_assert_eq!(self.next, self.b.len());
    }

    /// The off-diagonal blocks `W D^{1/2}` of each piece's condition 1 and its identity
    /// block: `K[k, p] = K_a[k, p]` (`p < n`), `δ_{k, p−n} − K_a[k, p−n]` (`p ≥ n`), constant
    /// for a given gain, in the variables `K_a` for a free one.
    pub(super) fn gain(&mut self, lay: &Layout, vars: &Variables, gain: Option<&DMatrix<f64>>) {
        let (n, m, s, N) = (lay.n, lay.m, lay.mons.len(), lay.big());
        for i in 0..self.schur.len() {
            let schur = self.schur[i];
            for (t, (beta, cb)) in lay.lower.iter().enumerate() {
                let scale = SQRT_2 * cb.sqrt();
                for alpha in 0..s {
                    let Some(k) = lay.step(alpha, beta) else {
                        continue;
                    };
                    for p in 0..m {
                        let e = schur + svec_index(alpha * m + p, N + t);
                        let (constant, coefficient, column) = if p < n {
                            (0.0, 1.0, p)
                        } else {
                            (if k == p - n { 1.0 } else { 0.0 }, -1.0, p - n)
                        };
                        match gain {
                            Some(K_a) => {
                                self.b[e] = scale * (constant + coefficient * K_a[(k, column)])
                            }
                            None => {
                                self.b[e] = scale * constant;
                                self.push(e, vars.k(k, column), -scale * coefficient);
                            }
                        }
                    }
                }
                self.b[schur + svec_index(N + t, N + t)] = 1.0;
            }
        }
    }

    /// `A` in compressed columns, for `columns` variables.
    pub(super) fn matrix(&mut self, columns: usize) -> CscMatrix<f64> {
        CscMatrix::new_from_triplets(
            self.b.len(),
            columns,
            std::mem::take(&mut self.rows),
            std::mem::take(&mut self.cols),
            std::mem::take(&mut self.vals),
        )
    }
}
