//! Three or four states: a given rule `(K, Q₀)` — the cutting planes' — proven on cones of
//! directions cut where `Q₀` is short (the parent's module docs, "At a given rule": the
//! argument, the rule for cutting and how the cones' certificates are joined into one bound).

use nalgebra::{DMatrix, DVector};

use crate::error::SolveError;
use crate::fusion::program::{Deadline, SdpStatus};
use crate::fusion::scale::Pow2;
use crate::fusion::upper::trace_upper_bound;
use crate::fusion::{Fused, FusionProblem};

use super::assemble::{Base, Piece};
use super::geometry::{bisect, cone_piece, orthants, Cone};
use super::layout::Layout;
use super::rule::{certification_blocks, CertifiedResult};
use super::settings::{CertifySettings, MAX_CONES};
use super::sos::{prove_piece, solve_pieces, BlockCertificate, RawPiece, Solved};

/// A cut whose larger half needs at least this fraction of its own `t` has reached the
/// violation of `Q₀` itself there: that half is not cut again.
const SETTLED: f64 = 0.99;

/// Cuts in a row without progress before a cone counts as settled (a cut along an edge
/// away from the short direction does not lower the half that holds it).
const STALLS: u32 = 4;

/// How many times an octant the solver fails on is cut before the proof gives up.
const FAILED_CUTS: u32 = 3;

/// A given rule `rule = (K, P̄)` of a three- or four-state problem — e.g. the cutting
/// planes' — proven on at most `budget` cones of directions (module docs of
/// `fusion::certify`, "At a given rule"; at four states at least the eight orthants): the
/// certificate of `K` with a bound near `P̄`, the cones cut until each adds at most
/// `rtol · tr P̄ / 8` to the trace (`budget` in `4..=`[`MAX_CONES`], `rtol` in `(0, 1)`, a
/// finite gain and a finite symmetric bound; otherwise [`SolveError::InvalidSettings`]).
/// `None` where the problem with this gain is not one block of three or four states. The
/// bound is proven whatever `P̄` is; how close to `P̄` it ends depends on how close `P̄` is to
/// dominating `K P' Kᵀ` for every admissible `P'`.
///
/// ```
/// use nalgebra::DMatrix;
/// use nmci::prelude::*;
/// use nmci::certify::certify_rule;
/// let p = FusionProblem::from_covariances(
///     DMatrix::from_row_slice(3, 3, &[4.0, 1.0, 0.5, 1.0, 3.0, 0.2, 0.5, 0.2, 2.0]),
///     DMatrix::from_row_slice(3, 3, &[2.0, -0.3, 0.1, -0.3, 5.0, 1.0, 0.1, 1.0, 1.5]),
///     CrossPattern::from_fn(3, |i, j| i + j != 2), // the anti-diagonal known zero
/// ).unwrap();
/// let cuts = optimal_fusion_cuts(&p, &CutsSettings { own_rule_cones: 0, ..Default::default() }).unwrap();
/// let proven = certify_rule(&p, &cuts.fused, 64, 1e-6, &CertifySettings::default())
///     .unwrap()
///     .expect("one block of three states");
/// assert_eq!(proven.fused.K_a, cuts.fused.K_a);
/// assert!(proven.fused.trace() >= cuts.lower_bound);
/// ```
pub fn certify_rule(
    problem: &FusionProblem,
    rule: &Fused,
    budget: u32,
    rtol: f64,
    settings: &CertifySettings,
) -> Result<Option<CertifiedResult>, SolveError> {
    Ok(certify_rule_short(problem, rule, budget, rtol, settings)?.map(|(proven, _)| proven))
}

/// [`certify_rule`], with the directions where the rule is short: the centres of the cones
/// whose `t` stayed above the target (module docs, "At a given rule"), largest `t` first, at
/// most [`SHORT_DIRECTIONS`]. `t` bounds the largest violation of `P̄` in its cone from above,
/// so these are where a violation may sit (the cutting planes search there,
/// `fusion::cuts`).
pub(crate) fn certify_rule_short(
    problem: &FusionProblem,
    rule: &Fused,
    budget: u32,
    rtol: f64,
    settings: &CertifySettings,
) -> Result<Option<ShortRule>, SolveError> {
    settings.validate()?;
    let n = problem.dim();
    let square = |m: &DMatrix<f64>| m.shape() == (n, n) && m.iter().all(|x| x.is_finite());
    if !square(&rule.K_a) || !square(&rule.P) || rule.P != rule.P.transpose() {
        return Err(SolveError::InvalidSettings(format!(
            "the rule must have a finite {n}×{n} gain and a finite symmetric {n}×{n} bound"
        )));
    }
    if !(4..=MAX_CONES).contains(&budget) {
        return Err(SolveError::InvalidSettings(format!(
            "the cone budget must be in 4..={MAX_CONES} (got {budget})"
        )));
    }
    if !(rtol > 0.0 && rtol < 1.0) {
        return Err(SolveError::InvalidSettings(format!(
            "rtol must be in (0, 1) (got {rtol})"
        )));
    }
    if !(3..=4).contains(&n) || certification_blocks(problem, Some(&rule.K_a)).len() != 1 {
        return Ok(None);
    }
    // At unit scale, as every certificate (`block::certify_one_block`): the covariances and
    // P̄ times the same power of two, exactly; the gain is unchanged, the bound mapped back
    // dominating (or, where that overflows, the rule certified as given).
    let (scaled, scale) = Pow2::normalising(problem).scaled_problem(problem);
    let at_scale = |p: &FusionProblem, bound: &DMatrix<f64>| {
        let target = rtol * bound.trace().abs() / (8.0 * n as f64);
        match n {
            3 => certify_point::<3>(p, &rule.K_a, bound, target, budget as usize, settings),
            _ => certify_point::<4>(p, &rule.K_a, bound, target, budget as usize, settings),
        }
    };
    let mut proven = None;
    if scale != Pow2::ONE {
        let (outcome, short) = at_scale(&scaled, &scale.scale(&rule.P))?;
        if let Some(bound) = scale.unscale_dominating(&outcome.P) {
            let outcome = BlockCertificate {
                P: bound,
                repair: scale.unscale_value(outcome.repair),
                ..outcome
            };
            proven = Some((outcome, short));
        }
    }
    let (proven, short) = match proven {
        Some(p) => p,
        None => at_scale(problem, &rule.P)?,
    };
    Ok(Some((
        CertifiedResult {
            fused: Fused {
                P: proven.P,
                ..rule.clone()
            },
            status: proven.status,
            iterations: proven.iterations,
            repair: proven.repair,
            blocks: vec![(0..n).collect()],
            levels: vec![1],
            sectors: vec![proven.pieces],
            ci_blocks: vec![false],
        },
        short,
    )))
}

/// A proven rule and the directions where it is short ([`certify_rule_short`]).
pub(crate) type ShortRule = (CertifiedResult, Vec<DVector<f64>>);

/// Most directions [`certify_rule_short`] returns.
pub(crate) const SHORT_DIRECTIONS: usize = 8;

/// One cone of the cover: its generators, its certificate and the `t` it needs.
struct Leaf<const N: usize> {
    cone: Cone<N>,
    raw: RawPiece,
    t: f64,
    settled: bool,
    /// Cuts in a row that left this cone's `t` within `SETTLED` of its parent's.
    stalls: u32,
}

/// The certificate of `K_a` and a bound near `Q₀` on cones of directions (module docs, "At a
/// given rule"), in its steps: the orthants solved ([`PointProof::solve_or_cut`]), the cones
/// cut where `Q₀` is short ([`PointProof::cut`]), the bound joined over the cover
/// ([`PointProof::bound`]) and the directions left short ([`short_directions`]). Its
/// `iterations` are summed over every program solved, its status `AlmostSolved` if any ended
/// so.
#[allow(non_snake_case)]
pub(super) fn certify_point<const N: usize>(
    problem: &FusionProblem,
    K_a: &DMatrix<f64>,
    Q0: &DMatrix<f64>,
    target: f64,
    budget: usize,
    settings: &CertifySettings,
) -> Result<(BlockCertificate, Vec<DVector<f64>>), SolveError> {
    let mut proof = PointProof::new(problem, K_a, Q0, settings);
    let mut leaves = Vec::new();
    for orthant in orthants::<N>() {
        leaves.extend(proof.solve_or_cut(orthant, 0)?);
    }
    proof.cut(&mut leaves, budget, target)?;
    let (Q, repair) = proof.bound(&leaves, target)?;
    let certificate = BlockCertificate {
        K_a: K_a.clone(),
        P: Q,
        status: if proof.almost {
            SdpStatus::AlmostSolved
        } else {
            SdpStatus::Solved
        },
        iterations: proof.iterations,
        repair,
        pieces: leaves.len() as u32,
    };
    Ok((certificate, short_directions(&leaves, target)))
}

/// The proof of one rule on a cover of cones: the problem, the rule and what its programs
/// have cost so far.
#[allow(non_snake_case)]
struct PointProof<'a> {
    problem: &'a FusionProblem,
    K_a: &'a DMatrix<f64>,
    Q0: &'a DMatrix<f64>,
    settings: &'a CertifySettings,
    deadline: Deadline,
    layout: Layout,
    identity: DMatrix<f64>,
    /// Interior-point iterations over every program solved, and whether any ended
    /// `AlmostSolved`.
    iterations: u32,
    almost: bool,
    /// Seconds spent solving the cones' programs and proving their certificates, and how many
    /// of each: the time a cut (two programs) and a pass proving every cone will take. The
    /// cutting stops while the time left still holds a cut and two such passes (the
    /// candidates of [`PointProof::bound`]), so the time limit is kept rather than overrun by
    /// the last repairs.
    spent: (f64, f64, u32),
}

/// Whether the cutting goes on after a cut.
enum Cut {
    Next,
    Stop,
}

#[allow(non_snake_case)]
impl<'a> PointProof<'a> {
    fn new(
        problem: &'a FusionProblem,
        K_a: &'a DMatrix<f64>,
        Q0: &'a DMatrix<f64>,
        settings: &'a CertifySettings,
    ) -> Self {
        let n = problem.dim();
        PointProof {
            problem,
            K_a,
            Q0,
            settings,
            deadline: Deadline::after(settings.time_limit),
            layout: Layout::new(n, 1),
            identity: DMatrix::identity(n, n),
            iterations: 0,
            almost: false,
            spent: (0.0, 0.0, 0),
        }
    }

    /// The settings of one program: the time left.
    fn round(&self) -> CertifySettings {
        CertifySettings {
            time_limit: self.settings.time_limit.map(|_| self.deadline.remaining()),
            ..*self.settings
        }
    }

    fn count(&mut self, solved: &Solved) {
        self.iterations += solved.iterations;
        self.almost |= solved.status == SdpStatus::AlmostSolved;
    }

    /// A cone's `t`: the solver's, plus what proving its certificate at `Q₀ + tI` adds (a
    /// cone the solver meets only to reduced accuracy needs a large repair, and is cut like
    /// one where `Q₀` is short).
    fn solve<const N: usize>(&mut self, cone: Cone<N>) -> Result<Leaf<N>, SolveError> {
        let n = self.problem.dim() as f64;
        let one = pieces(&[cone]);
        let began = web_time::Instant::now();
        let (problem, K_a, Q0) = (self.problem, self.K_a, self.Q0);
        let solved = solve_pieces(problem, Some(K_a), Base::Shift(Q0), 1, &one, &self.round())?;
        self.count(&solved);
        let solving = began.elapsed().as_secs_f64();
        let raw = solved.pieces.into_iter().next().expect("one piece");
        let start = Q0 + &self.identity * ((solved.Q.trace() - Q0.trace()) / n);
        let mut Q = start.clone();
        let began = web_time::Instant::now();
        prove_piece(problem, &self.layout, K_a, &mut Q, &raw)?;
        let (solves, proofs, cones) = self.spent;
        self.spent = (
            solves + solving,
            proofs + began.elapsed().as_secs_f64(),
            cones + 1,
        );
        let t = (Q.trace() - Q0.trace()) / n;
        Ok(Leaf {
            cone,
            raw,
            t,
            settled: false,
            stalls: 0,
        })
    }

    /// A cone the solver fails on is cut in two and its halves tried instead, a few times at
    /// most (the cover must be complete before anything is proven).
    fn solve_or_cut<const N: usize>(
        &mut self,
        cone: Cone<N>,
        depth: u32,
    ) -> Result<Vec<Leaf<N>>, SolveError> {
        match self.solve(cone) {
            Ok(leaf) => Ok(vec![leaf]),
            Err(SolveError::SolverFailed { .. } | SolveError::NotProven { .. })
                if depth < FAILED_CUTS =>
            {
                let halves = bisect(&cone).ok_or_else(|| SolveError::SolverFailed {
                    status: "a cone the solver fails on cannot be cut further".into(),
                    iterations: 0,
                })?;
                let mut leaves = self.solve_or_cut(halves[0], depth + 1)?;
                leaves.extend(self.solve_or_cut(halves[1], depth + 1)?);
                Ok(leaves)
            }
            Err(e) => Err(e),
        }
    }

    /// Seconds per cone so far: solving its program, and proving its certificate.
    fn per_cone(&self) -> (f64, f64) {
        let (solves, proofs, cones) = self.spent;
        let cones = f64::from(cones.max(1));
        (solves / cones, proofs / cones)
    }

    /// Whether the time left holds a cut and two passes proving `leaves + 1` cones.
    fn time_for_a_cut(&self, leaves: usize) -> bool {
        let (solve, prove) = self.per_cone();
        self.deadline.remaining() > 2.0 * solve + 2.0 * prove * (leaves + 1) as f64
    }

    /// The cones cut, the one with the largest `t` above `target` first, until every cone is
    /// within `target` or settled, the cover holds `budget` cones, or the time left holds no
    /// more cuts.
    fn cut<const N: usize>(
        &mut self,
        leaves: &mut Vec<Leaf<N>>,
        budget: usize,
        target: f64,
    ) -> Result<(), SolveError> {
        while leaves.len() < budget && self.time_for_a_cut(leaves.len()) {
            let Some(worst) = (0..leaves.len())
                .filter(|&k| !leaves[k].settled && leaves[k].t > target)
                .max_by(|&a, &b| leaves[a].t.total_cmp(&leaves[b].t))
            else {
                break;
            };
            if let Cut::Stop = self.cut_one(leaves, worst, budget)? {
                break;
            }
        }
        Ok(())
    }

    /// The cone `worst` cut in two. Its halves take its place within the budget, each
    /// settled after `STALLS` cuts in a row without progress; over the budget, or where the
    /// solver fails on a part, the cone stays whole and settled; out of time, the cutting
    /// stops.
    fn cut_one<const N: usize>(
        &mut self,
        leaves: &mut Vec<Leaf<N>>,
        worst: usize,
        budget: usize,
    ) -> Result<Cut, SolveError> {
        let Some(halves) = bisect(&leaves[worst].cone) else {
            leaves[worst].settled = true;
            return Ok(Cut::Next);
        };
        let halves = match (
            self.solve_or_cut(halves[0], 1),
            self.solve_or_cut(halves[1], 1),
        ) {
            (Ok(mut a), Ok(b)) if leaves.len() - 1 + a.len() + b.len() <= budget => {
                a.extend(b);
                a
            }
            (Ok(_), Ok(_))
            | (Err(SolveError::SolverFailed { .. } | SolveError::NotProven { .. }), _)
            | (_, Err(SolveError::SolverFailed { .. } | SolveError::NotProven { .. })) => {
                leaves[worst].settled = true;
                return Ok(Cut::Next);
            }
            (Err(SolveError::TimeLimit { .. }), _) | (_, Err(SolveError::TimeLimit { .. })) => {
                return Ok(Cut::Stop)
            }
            (Err(e), _) | (_, Err(e)) => return Err(e),
        };
        let parent = leaves.swap_remove(worst);
        for mut half in halves {
            half.stalls = if half.t >= parent.t - (1.0 - SETTLED) * parent.t.abs() {
                parent.stalls + 1
            } else {
                0
            };
            half.settled = half.stalls >= STALLS;
            leaves.push(half);
        }
        Ok(Cut::Next)
    }

    /// `raws` proven from `start` on: the bound and what the repair added to its trace.
    fn prove<'r>(
        &self,
        start: DMatrix<f64>,
        raws: impl Iterator<Item = &'r RawPiece>,
    ) -> Result<(DMatrix<f64>, f64), SolveError> {
        let mut Q = start.clone();
        for raw in raws {
            prove_piece(self.problem, &self.layout, self.K_a, &mut Q, raw)?;
        }
        let repair = (Q.trace() - start.trace()).max(0.0);
        Ok((Q, repair))
    }

    /// The bound over the cover: every cone proven at `Q₀ + tI`, `t` the largest of all; or,
    /// where tighter, the cones within the target proven at `Q₀ + τI` (`τ` their largest `t`)
    /// and the others sharing one program with `Q ⪰ Q₀`, whose `Q − Q₀` follows the
    /// directions where `Q₀` is short. A repair that fails on one candidate leaves the
    /// other.
    fn bound<const N: usize>(
        &mut self,
        leaves: &[Leaf<N>],
        target: f64,
    ) -> Result<(DMatrix<f64>, f64), SolveError> {
        let t_all = leaves.iter().map(|l| l.t).fold(f64::NEG_INFINITY, f64::max);
        let (open, within): (Vec<&Leaf<N>>, Vec<&Leaf<N>>) =
            leaves.iter().partition(|l| l.t > target);
        let tau = within.iter().map(|l| l.t).fold(0.0, f64::max);
        let mut best = self.prove(
            self.Q0 + &self.identity * t_all,
            leaves.iter().map(|l| &l.raw),
        );
        if let Some((Q, repair)) = self.joint(&open, &within, tau, leaves.len())? {
            let tighter =
                |b: &(DMatrix<f64>, f64)| trace_upper_bound(&b.0) <= trace_upper_bound(&Q);
            if !best.as_ref().is_ok_and(tighter) {
                best = Ok((Q, repair));
            }
        }
        best
    }

    /// The joint program of the `open` cones (`Q ⪰ Q₀`), proven with the cones `within` the
    /// target from `Q + τI`; `None` where it does not run, the solver fails, it runs out of
    /// time or its repair fails. Under a time limit it runs where the time left, after a pass
    /// proving all `cones`, holds twice what its cones took alone (it takes about that, and a
    /// limit stops it only between iterations, so it gets the time left less once that).
    fn joint<const N: usize>(
        &mut self,
        open: &[&Leaf<N>],
        within: &[&Leaf<N>],
        tau: f64,
        cones: usize,
    ) -> Result<Option<(DMatrix<f64>, f64)>, SolveError> {
        let (solve, prove) = self.per_cone();
        let alone = open.len() as f64 * solve;
        let joint_time = self
            .settings
            .time_limit
            .map(|_| self.deadline.remaining() - prove * cones as f64 - alone);
        if open.is_empty() || !joint_time.is_none_or(|t| t >= alone.max(1e-3)) {
            return Ok(None);
        }
        let open_cones: Vec<_> = open.iter().map(|l| l.cone).collect();
        let joint_settings = CertifySettings {
            time_limit: joint_time,
            ..*self.settings
        };
        let (problem, K_a, Q0) = (self.problem, self.K_a, self.Q0);
        let one = pieces(&open_cones);
        let joint = match solve_pieces(
            problem,
            Some(K_a),
            Base::Above(Q0),
            1,
            &one,
            &joint_settings,
        ) {
            Ok(joint) => joint,
            Err(
                SolveError::SolverFailed { .. }
                | SolveError::NotProven { .. }
                | SolveError::TimeLimit { .. },
            ) => return Ok(None),
            Err(e) => return Err(e),
        };
        self.count(&joint);
        // Q ⪰ Q₀ only to the solver's tolerance: the repair proves every cone at the final
        // Q, whatever it is.
        let start = &joint.Q + &self.identity * tau;
        let raws = within.iter().map(|l| &l.raw).chain(&joint.pieces);
        Ok(self.prove(start, raws).ok())
    }
}

/// The pieces of a cover: each cone's multipliers.
fn pieces<const N: usize>(cones: &[Cone<N>]) -> Vec<Piece> {
    cones
        .iter()
        .map(|u| Piece {
            multipliers: cone_piece(u),
        })
        .collect()
}

/// The centres of the cones above `target`, largest `t` first, at most
/// [`SHORT_DIRECTIONS`]: where the rule is short.
fn short_directions<const N: usize>(leaves: &[Leaf<N>], target: f64) -> Vec<DVector<f64>> {
    let mut short: Vec<&Leaf<N>> = leaves.iter().filter(|l| l.t > target).collect();
    short.sort_by(|a, b| b.t.total_cmp(&a.t));
    short
        .iter()
        .take(SHORT_DIRECTIONS)
        .map(|l| centre(&l.cone))
        .collect()
}

/// A cone's centre: the sum of its unit generators, normalised.
fn centre<const N: usize>(cone: &Cone<N>) -> DVector<f64> {
    DVector::from_fn(N, |r, _| {
        cone.iter()
            .map(|u| u[r] as f64 / u.iter().map(|&x| (x * x) as f64).sum::<f64>().sqrt())
            .sum::<f64>()
    })
    .normalize()
}
