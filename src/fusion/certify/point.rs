//! Three or four states: a given rule `(K, Q₀)` — the cutting planes' — proven on cones of
//! directions cut where `Q₀` is short (the parent's module docs, "At a given rule": the
//! argument, the rule for cutting and how the cones' certificates are joined into one bound).

use std::cell::Cell;

use nalgebra::{DMatrix, DVector};

use crate::error::SolveError;
use crate::fusion::program::{Deadline, SdpStatus};
use crate::fusion::scale::Pow2;
use crate::fusion::upper::trace_upper_bound;
use crate::fusion::{Fused, FusionProblem};

use super::geometry::{bisect, cone_piece, orthants, Cone};
use super::layout::Layout;
use super::rule::{certification_blocks, CertifiedResult};
use super::settings::{CertifySettings, MAX_CONES};
use super::sos::{prove_piece, solve_pieces, Base, BlockCertificate, Piece, RawPiece, Solved};

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
/// given rule"); its `iterations` are summed over every program solved, its status
/// `AlmostSolved` if any ended so.
#[allow(non_snake_case)]
pub(super) fn certify_point<const N: usize>(
    problem: &FusionProblem,
    K_a: &DMatrix<f64>,
    Q0: &DMatrix<f64>,
    target: f64,
    budget: usize,
    settings: &CertifySettings,
) -> Result<(BlockCertificate, Vec<DVector<f64>>), SolveError> {
    let n = problem.dim();
    let deadline = Deadline::after(settings.time_limit);
    let round = || CertifySettings {
        time_limit: settings.time_limit.map(|_| deadline.remaining()),
        ..*settings
    };
    let pieces = |cones: &[Cone<N>]| -> Vec<Piece> {
        cones
            .iter()
            .map(|u| Piece {
                multipliers: cone_piece(u),
            })
            .collect()
    };
    // Interior-point iterations over every program solved, and whether any ended
    // `AlmostSolved`.
    let iterations = Cell::new(0u32);
    let almost = Cell::new(false);
    let count = |solved: &Solved| {
        iterations.set(iterations.get() + solved.iterations);
        almost.set(almost.get() || solved.status == SdpStatus::AlmostSolved);
    };
    // Seconds spent solving the cones' programs and proving their certificates, and how many
    // of each: the time a cut (two programs) and a pass proving every cone will take. The
    // cutting stops while the time left still holds a cut and two such passes (the candidates
    // below), so the time limit is kept rather than overrun by the last repairs.
    let spent = Cell::new((0.0f64, 0.0f64, 0u32));
    let layout = Layout::new(n, 1);
    let identity = DMatrix::<f64>::identity(n, n);
    // A cone's t: the solver's, plus what proving its certificate at Q₀ + tI adds (a cone
    // the solver meets only to reduced accuracy needs a large repair, and is cut like one
    // where Q₀ is short).
    let solve = |cone: Cone<N>| -> Result<Leaf<N>, SolveError> {
        let one = pieces(&[cone]);
        let began = web_time::Instant::now();
        let solved = solve_pieces(problem, Some(K_a), Base::Shift(Q0), 1, &one, &round())?;
        count(&solved);
        let solving = began.elapsed().as_secs_f64();
        let raw = solved.pieces.into_iter().next().expect("one piece");
        let start = Q0 + &identity * ((solved.Q.trace() - Q0.trace()) / n as f64);
        let mut Q = start.clone();
        let began = web_time::Instant::now();
        prove_piece(problem, &layout, K_a, &mut Q, &raw)?;
        let (solves, proofs, cones) = spent.get();
        spent.set((
            solves + solving,
            proofs + began.elapsed().as_secs_f64(),
            cones + 1,
        ));
        let t = (Q.trace() - Q0.trace()) / n as f64;
        Ok(Leaf {
            cone,
            raw,
            t,
            settled: false,
            stalls: 0,
        })
    };
    // A cone the solver fails on is cut in two and its halves tried instead, a few times at
    // most (the cover must be complete before anything is proven).
    fn solve_or_cut<const N: usize>(
        solve: &dyn Fn(Cone<N>) -> Result<Leaf<N>, SolveError>,
        cone: Cone<N>,
        depth: u32,
    ) -> Result<Vec<Leaf<N>>, SolveError> {
        match solve(cone) {
            Ok(leaf) => Ok(vec![leaf]),
            Err(SolveError::SolverFailed { .. } | SolveError::NotProven { .. })
                if depth < FAILED_CUTS =>
            {
                let halves = bisect(&cone).ok_or_else(|| SolveError::SolverFailed {
                    status: "a cone the solver fails on cannot be cut further".into(),
                    iterations: 0,
                })?;
                let mut leaves = solve_or_cut(solve, halves[0], depth + 1)?;
                leaves.extend(solve_or_cut(solve, halves[1], depth + 1)?);
                Ok(leaves)
            }
            Err(e) => Err(e),
        }
    }
    let mut leaves = Vec::new();
    for orthant in orthants::<N>() {
        leaves.extend(solve_or_cut(&solve, orthant, 0)?);
    }
    // Seconds per cone so far: solving its program, and proving its certificate.
    let per_cone = || {
        let (solves, proofs, cones) = spent.get();
        let cones = f64::from(cones.max(1));
        (solves / cones, proofs / cones)
    };
    let time_for_a_cut = |leaves: usize| {
        let (solve, prove) = per_cone();
        deadline.remaining() > 2.0 * solve + 2.0 * prove * (leaves + 1) as f64
    };
    while leaves.len() < budget && time_for_a_cut(leaves.len()) {
        let Some(worst) = (0..leaves.len())
            .filter(|&k| !leaves[k].settled && leaves[k].t > target)
            .max_by(|&a, &b| leaves[a].t.total_cmp(&leaves[b].t))
        else {
            break;
        };
        let Some(halves) = bisect(&leaves[worst].cone) else {
            leaves[worst].settled = true;
            continue;
        };
        let halves = match (
            solve_or_cut(&solve, halves[0], 1),
            solve_or_cut(&solve, halves[1], 1),
        ) {
            // Within the budget: the parent's place goes to its halves (or their parts).
            (Ok(mut a), Ok(b)) if leaves.len() - 1 + a.len() + b.len() <= budget => {
                a.extend(b);
                a
            }
            // Over the budget, or a part the solver fails on: the cone stays whole.
            (Ok(_), Ok(_))
            | (Err(SolveError::SolverFailed { .. } | SolveError::NotProven { .. }), _)
            | (_, Err(SolveError::SolverFailed { .. } | SolveError::NotProven { .. })) => {
                leaves[worst].settled = true;
                continue;
            }
            // Out of time: the cover as it is.
            (Err(SolveError::TimeLimit { .. }), _) | (_, Err(SolveError::TimeLimit { .. })) => {
                break
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
    }
    // The cones within the target are proven at Q₀ + τI (τ their largest t); the others
    // share one program with Q ⪰ Q₀, whose Q − Q₀ follows the directions where Q₀ is short.
    // Where that program fails, runs out of time or ends with the larger bound after the
    // repair, every cone is proven at Q₀ + tI, t the largest of all.
    let t_all = leaves.iter().map(|l| l.t).fold(f64::NEG_INFINITY, f64::max);
    let (open, within): (Vec<&Leaf<N>>, Vec<&Leaf<N>>) = leaves.iter().partition(|l| l.t > target);
    let tau = within.iter().map(|l| l.t).fold(0.0, f64::max);
    let proven = |start: DMatrix<f64>, raws: &mut dyn Iterator<Item = &RawPiece>| {
        let mut Q = start.clone();
        for raw in raws {
            prove_piece(problem, &layout, K_a, &mut Q, raw)?;
        }
        let repair = (Q.trace() - start.trace()).max(0.0);
        Ok::<_, SolveError>((Q, repair))
    };
    // A repair that fails on one candidate leaves the other.
    let mut best = proven(Q0 + &identity * t_all, &mut leaves.iter().map(|l| &l.raw));
    // Under a time limit the joint program runs where the time left, after a pass proving
    // its result, holds twice what its cones took alone (it takes about that, and a limit
    // stops it only between iterations, so it gets the time left less once that).
    let (solve, prove) = per_cone();
    let alone = open.len() as f64 * solve;
    let joint_time = settings
        .time_limit
        .map(|_| deadline.remaining() - prove * leaves.len() as f64 - alone);
    if !open.is_empty() && joint_time.is_none_or(|t| t >= alone.max(1e-3)) {
        let cones: Vec<_> = open.iter().map(|l| l.cone).collect();
        let joint_settings = CertifySettings {
            time_limit: joint_time,
            ..*settings
        };
        match solve_pieces(
            problem,
            Some(K_a),
            Base::Above(Q0),
            1,
            &pieces(&cones),
            &joint_settings,
        ) {
            Ok(joint) => {
                count(&joint);
                // Q ⪰ Q₀ only to the solver's tolerance: the repair proves every cone at the
                // final Q, whatever it is.
                let start = &joint.Q + &identity * tau;
                let raws = within.iter().map(|l| &l.raw).chain(&joint.pieces);
                if let Ok((Q, repair)) = proven(start, &mut raws.into_iter()) {
                    let tighter =
                        |b: &(DMatrix<f64>, f64)| trace_upper_bound(&b.0) <= trace_upper_bound(&Q);
                    if !best.as_ref().is_ok_and(tighter) {
                        best = Ok((Q, repair));
                    }
                }
            }
            Err(
                SolveError::SolverFailed { .. }
                | SolveError::NotProven { .. }
                | SolveError::TimeLimit { .. },
            ) => {}
            Err(e) => return Err(e),
        }
    }
    let (Q, repair) = best?;
    let mut short: Vec<&Leaf<N>> = open.clone();
    short.sort_by(|a, b| b.t.total_cmp(&a.t));
    // A cone's centre: the sum of its unit generators.
    let centre = |cone: &Cone<N>| {
        DVector::from_fn(N, |r, _| {
            cone.iter()
                .map(|u| u[r] as f64 / u.iter().map(|&x| (x * x) as f64).sum::<f64>().sqrt())
                .sum::<f64>()
        })
        .normalize()
    };
    let short = short
        .iter()
        .take(SHORT_DIRECTIONS)
        .map(|l| centre(&l.cone))
        .collect();
    let certificate = BlockCertificate {
        K_a: K_a.clone(),
        P: Q,
        status: if almost.get() {
            SdpStatus::AlmostSolved
        } else {
            SdpStatus::Solved
        },
        iterations: iterations.get(),
        repair,
        pieces: leaves.len() as u32,
    };
    Ok((certificate, short))
}
