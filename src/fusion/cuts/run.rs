//! The cutting-plane loop of the parent module, one method per step of its module docs:
//!
//! - [`Run::start`]: the starting samples, the guiding certificate and (1) the worst cases
//!   at its bound ([`Run::guide`]);
//! - [`Run::program`]: the relaxation on the current cuts, within the time limit (past it,
//!   the last finished program's result, [`Run::stopped`]);
//! - [`Run::search`]: the worst-case search from the current program's worst constraint and
//!   from random directions, and (3) the wider search where the bracket is open;
//! - [`Run::stop`]: the stop rule, (2) the closed gap included;
//! - [`Run::in_out`]: (4) the deeper cuts between the optimum and a feasible point;
//! - [`Run::conclude`]: (5) the program on the active cuts ([`prune`]), (6) the own rule
//!   proven, (7) the proof's short directions ([`Run::short_cuts`]) and (8) the finer loop
//!   ([`Run::refinable`]), each of which may start another round ([`Run::restart_from`]).

use nalgebra::{DMatrix, DVector, SymmetricEigen};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use super::own_rule::{prove_own_rule, still_open, tighter, PROOF_ROUNDS, REFINED_TOLERANCE};
use super::result::CutsResult;
use super::search::{
    direction_grid, random_starts, top_eigen, violation_matrix, worst_case_search,
    OPEN_BRACKET_STARTS,
};
use super::settings::{CutsSettings, CutsStop};
use crate::error::SolveError;
use crate::fusion::certify::{
    certification_blocks, certified_fusion, Certificates, CertifiedResult, CertifySettings,
};
use crate::fusion::check::{lowest_margin, margin};
use crate::fusion::nmci::non_monolithic_ci;
use crate::fusion::program::Deadline;
use crate::fusion::sample::{sample_cross_covariances, CrossSamples, SamplerSettings};
use crate::fusion::sdp::{solve_samples, SdpResult, SdpSettings};
use crate::fusion::upper::trace_upper_bound;
use crate::fusion::{Criterion, Fused, FusionProblem};

/// The fraction of `CutsSettings::time_limit` the loop keeps in reserve (it plans its work to
/// the limit less this share of it).
const TIME_RESERVE: f64 = 0.01;

/// A cut: the violation found and the cross-covariance that attains it.
type Cut = (f64, DMatrix<f64>);

/// [`super::optimal_fusion_cuts`] on the problem as given.
pub(super) fn cuts_at_scale(
    problem: &FusionProblem,
    settings: &CutsSettings,
) -> Result<CutsResult, SolveError> {
    let mut run = Run::start(problem, settings)?;
    loop {
        run.iterations += 1;
        let opt = match run.program()? {
            Program::Solved(opt) => opt,
            Program::Stopped(result) => return Ok(result),
        };
        let threshold = run.tolerance * opt.fused.trace().max(1.0);
        let found = run.search(&opt, threshold)?;
        if let Some(stop) = run.stop(&found, threshold) {
            match run.conclude(opt, found.violation, stop, threshold)? {
                Some(result) => return Ok(result),
                None => continue,
            }
        }
        run.previous = Some((opt.clone(), run.cross.len(), found.violation));
        let cuts = run.in_out(&opt, found.cuts, threshold)?;
        run.add_cuts(cuts, threshold);
    }
}

/// What one program gave: its solution, or (past the time limit) the loop's result.
enum Program {
    Solved(SdpResult),
    Stopped(CutsResult),
}

/// What the worst-case search found at one program's solution.
struct Found {
    /// The cuts of the starts that found a violation.
    cuts: Vec<Cut>,
    /// The worst violation found.
    violation: f64,
    /// Whether the deadline stopped a search (the violation is then a lower estimate).
    cut_short: bool,
    /// Whether the proven bracket is closed at the loop's tolerance (module docs, (2)).
    gap_closed: bool,
}

/// The state of the loop between its steps.
#[allow(non_snake_case)]
struct Run<'a> {
    problem: &'a FusionProblem,
    settings: &'a CutsSettings,
    /// The time limit less `TIME_RESERVE` of it: what runs between its checks (a worst-case
    /// search, the wider search's random points, the result) is kept inside the limit.
    deadline: Deadline,
    rng: ChaCha8Rng,
    /// The cuts (and starting samples) of the next program.
    cross: Vec<DMatrix<f64>>,
    /// The programs' settings: every constraint here is a worst case, so nearly all are
    /// active, and one program with all of them beats the sampled SDP's working-set loop
    /// (which re-solves to add 8 at a time).
    sdp: SdpSettings,
    /// The guiding certificate (module docs, "Guided by the certified rule") and its trace
    /// rounded up.
    certified: Option<CertifiedResult>,
    certified_trace: Option<f64>,
    /// A feasible point for the in-out separation: the certified rule, else nmCI.
    inside: Fused,
    iterations: usize,
    /// The best proven lower bound over the programs solved.
    best_lower: f64,
    /// The last finished program (its result, its number of cuts, the violation found at
    /// it): what a solve stopped by the time limit falls back to.
    previous: Option<(SdpResult, usize, f64)>,
    /// Rounds the proof's short directions restarted the loop (module docs, (7)).
    rounds: usize,
    /// The result of the round before, where a round restarted the loop.
    earlier: Option<CutsResult>,
    /// Constraints generated in the rounds before, not carried into this one.
    earlier_generated: usize,
    /// The loop's tolerance: the setting's, then `REFINED_TOLERANCE` once where the proof
    /// left the bracket open (module docs, (8)).
    tolerance: f64,
    /// Seconds per interior-point iteration of the last program, per cut. A program stopped
    /// by the time limit stops after the iteration running at it, so each is given the
    /// deadline less one iteration's estimated length (the cost of an iteration grows about
    /// linearly with the cuts, one PSD block each): the limit is kept, not overrun by it.
    per_cut_iteration: f64,
}

impl<'a> Run<'a> {
    /// The starting samples, the guiding certificate and the worst cases at its bound.
    fn start(problem: &'a FusionProblem, settings: &'a CutsSettings) -> Result<Self, SolveError> {
        let deadline = Deadline::after(settings.time_limit)
            .earlier(settings.time_limit.map_or(0.0, |t| t * TIME_RESERVE));
        let cross = sample_cross_covariances(
            problem,
            settings.initial_samples,
            settings.seed,
            SamplerSettings::hit_and_run(),
        )?
        .cross;
        let rng = ChaCha8Rng::seed_from_u64(settings.seed ^ 0x5EED_C075);
        let certified = guiding_certificate(problem, settings, &deadline)?;
        let inside = match &certified {
            Some(c) => c.fused.clone(),
            None => non_monolithic_ci(problem, Criterion::Trace)?.fused,
        };
        let mut run = Run {
            problem,
            settings,
            deadline,
            rng,
            cross,
            sdp: SdpSettings {
                working_set: false,
                ..settings.sdp
            },
            certified_trace: certified.as_ref().map(|c| trace_upper_bound(&c.fused.P)),
            certified,
            inside,
            iterations: 0,
            best_lower: 0.0,
            previous: None,
            rounds: 0,
            earlier: None,
            earlier_generated: 0,
            tolerance: settings.tolerance,
            per_cut_iteration: 0.0,
        };
        run.guide()?;
        Ok(run)
    }

    /// Module docs, (1): the worst cases at the certified bound, where it is tight (the likely
    /// active constraints of the robust optimum), from the eigenvectors of its `P̄` and random
    /// directions.
    #[allow(non_snake_case)]
    fn guide(&mut self) -> Result<(), SolveError> {
        let Some(at) = self.certified.as_ref().map(|c| c.fused.clone()) else {
            return Ok(());
        };
        let n = self.problem.dim();
        let eig = SymmetricEigen::new(at.P.clone());
        for k in 0..self.settings.restarts.max(n) {
            let v = if k < n {
                eig.eigenvectors.column(k).into_owned()
            } else {
                random_direction(&mut self.rng, n)
            };
            let (_, P_ab) = worst_case_search(self.problem, &at, v, self.settings, &self.deadline)?;
            self.push_new(P_ab);
        }
        Ok(())
    }

    /// The settings at the loop's current tolerance.
    fn now(&self) -> CutsSettings {
        CutsSettings {
            tolerance: self.tolerance,
            ..*self.settings
        }
    }

    /// The relaxation on the current cuts, given the deadline less one iteration's estimated
    /// length. Past the deadline, the loop's result so far ([`Run::stopped`]).
    fn program(&mut self) -> Result<Program, SolveError> {
        let set = CrossSamples {
            cross: self.cross.clone(),
            trials: 0,
            auto: None,
        };
        let deadline = self
            .deadline
            .earlier(self.per_cut_iteration * self.cross.len() as f64);
        let began = web_time::Instant::now();
        let opt = match solve_samples(self.problem, &set, &self.sdp, &deadline) {
            Ok(o) => o,
            Err(e @ SolveError::TimeLimit { .. }) => {
                return self.stopped().map(Program::Stopped).ok_or(e);
            }
            Err(e) => return Err(e),
        };
        self.per_cut_iteration = began.elapsed().as_secs_f64()
            / f64::from(opt.iterations.max(1))
            / self.cross.len().max(1) as f64;
        self.best_lower = self.best_lower.max(opt.lower_bound);
        Ok(Program::Solved(opt))
    }

    /// The result when the program of this iteration ran out of time: the round before's
    /// where the proof started one, else the last finished program's (a time limit); `None`
    /// before any program finished.
    fn stopped(&mut self) -> Option<CutsResult> {
        let iterations = self.iterations - 1;
        if let Some(mut result) = self.earlier.take() {
            result.iterations = iterations;
            result.constraints_generated = self.earlier_generated + self.cross.len();
            result.proof_rounds = self.rounds;
            return Some(result);
        }
        let (opt, len, violation) = self.previous.take()?;
        let generated = self.cross.len();
        let mut cross = std::mem::take(&mut self.cross);
        cross.truncate(len);
        let mut result = self.finish(opt, cross, generated, violation, CutsStop::TimeLimit);
        result.iterations = iterations;
        Some(result)
    }

    /// The worst-case search at the program's solution, from the top eigenvector of its worst
    /// constraint and from random directions; every start that finds a violation contributes
    /// its cut (distinct directions cut off different parts of the relaxation) and the worst
    /// decides convergence. Where it finds nothing but the proven bracket is open, the wider
    /// search too (module docs, (3)). The searches share the deadline: one stopped by it
    /// marks the result `cut_short`.
    #[allow(non_snake_case)]
    fn search(&mut self, opt: &SdpResult, threshold: f64) -> Result<Found, SolveError> {
        let n = self.problem.dim();
        let mut starts: Vec<DVector<f64>> = Vec::with_capacity(self.settings.restarts);
        if let Some((_, v)) = self
            .cross
            .iter()
            .map(|P_ab| top_eigen(&violation_matrix(self.problem, &opt.fused, P_ab)))
            .max_by(|a, b| a.0.total_cmp(&b.0))
        {
            starts.push(v);
        }
        while starts.len() < self.settings.restarts {
            starts.push(random_direction(&mut self.rng, n));
        }
        let mut cut_short = false;
        let mut cuts = Vec::with_capacity(starts.len());
        for start in starts {
            cuts.extend(self.search_from(&opt.fused, start, &mut cut_short)?);
        }
        let mut violation = worst(&cuts, f64::NEG_INFINITY);
        let gap_closed = self
            .certified_trace
            .is_some_and(|upper| self.now().closes(self.best_lower, upper));
        if violation <= threshold && !gap_closed && self.certified_trace.is_some() {
            let extra = self.wider_search(&opt.fused, threshold, &mut cut_short)?;
            if !extra.is_empty() {
                violation = worst(&extra, violation);
                cuts.extend(extra);
            }
        }
        Ok(Found {
            cuts,
            violation,
            cut_short,
            gap_closed,
        })
    }

    /// One worst-case search from `v`; `None` once the deadline stopped one (`cut_short`).
    fn search_from(
        &self,
        fused: &Fused,
        v: DVector<f64>,
        cut_short: &mut bool,
    ) -> Result<Option<Cut>, SolveError> {
        if *cut_short {
            return Ok(None);
        }
        match worst_case_search(self.problem, fused, v, self.settings, &self.deadline) {
            Ok(f) => Ok(Some(f)),
            Err(SolveError::TimeLimit { .. }) => {
                *cut_short = true;
                Ok(None)
            }
            Err(e) => Err(e),
        }
    }

    /// Module docs, (3): the search from random admissible points, more random directions
    /// and (for `n ≤ 3`) the even grid of directions; the cuts above `threshold`.
    fn wider_search(
        &mut self,
        fused: &Fused,
        threshold: f64,
        cut_short: &mut bool,
    ) -> Result<Vec<Cut>, SolveError> {
        let mut extra = Vec::new();
        let round = self.iterations as u64;
        for v in random_starts(self.problem, fused, self.settings, round, threshold)? {
            extra.extend(self.search_from(fused, v, cut_short)?);
        }
        let n = self.problem.dim();
        let random = (0..OPEN_BRACKET_STARTS * self.settings.restarts)
            .map(|_| random_direction(&mut self.rng, n))
            .collect::<Vec<_>>();
        for v in direction_grid(n).into_iter().chain(random) {
            if let Some(f) = self.search_from(fused, v, cut_short)? {
                if f.0 > threshold {
                    extra.push(f);
                }
            }
        }
        Ok(extra)
    }

    /// The stop rule: a closed gap (module docs, (2)), no violation above `threshold` from a
    /// search not cut short, the time limit, or `max_iterations`; `None` to go on.
    fn stop(&self, found: &Found, threshold: f64) -> Option<CutsStop> {
        let converged = found.gap_closed || (!found.cut_short && found.violation <= threshold);
        let timed_out = found.cut_short || self.deadline.passed();
        if !(converged || timed_out || self.iterations >= self.settings.max_iterations) {
            return None;
        }
        Some(if found.gap_closed {
            CutsStop::GapClosed
        } else if found.violation <= threshold && !found.cut_short {
            CutsStop::Tolerance
        } else if timed_out {
            CutsStop::TimeLimit
        } else {
            CutsStop::MaxIterations
        })
    }

    /// Module docs, (4): cuts at the point `α` of the way from the feasible point to the
    /// relaxation's optimum (deeper, better centred, started from the directions just
    /// found). No violation there makes it the new feasible point and keeps the cuts found
    /// at the optimum; a violation gives its cuts instead. Cut short by the deadline: the
    /// cuts found at the optimum (the next program stops at the deadline and the loop
    /// returns this one).
    #[allow(non_snake_case)]
    fn in_out(
        &mut self,
        opt: &SdpResult,
        found: Vec<Cut>,
        threshold: f64,
    ) -> Result<Vec<Cut>, SolveError> {
        let alpha = self.settings.in_out;
        if alpha <= 0.0 {
            return Ok(found);
        }
        let inside = &self.inside;
        let mid = Fused {
            x: opt.fused.x.clone(),
            P: &opt.fused.P * alpha + &inside.P * (1.0 - alpha),
            K_a: &opt.fused.K_a * alpha + &inside.K_a * (1.0 - alpha),
            K_b: &opt.fused.K_b * alpha + &inside.K_b * (1.0 - alpha),
        };
        let mut deeper = Vec::with_capacity(found.len());
        for (_, P_ab) in &found {
            let (_, v) = top_eigen(&violation_matrix(self.problem, &mid, P_ab));
            match worst_case_search(self.problem, &mid, v, self.settings, &self.deadline) {
                Ok(f) => deeper.push(f),
                Err(SolveError::TimeLimit { .. }) => return Ok(found),
                Err(e) => return Err(e),
            }
        }
        if worst(&deeper, f64::NEG_INFINITY) <= threshold {
            self.inside = mid;
            Ok(found)
        } else {
            Ok(deeper)
        }
    }

    /// The cuts violated beyond `threshold`, each unless the program has it already.
    fn add_cuts(&mut self, found: Vec<Cut>, threshold: f64) {
        for (v, cut) in found {
            if v > threshold {
                self.push_new(cut);
            }
        }
    }

    /// Adds a cut unless an equal one (to `10⁻¹²` relative) is in the program already.
    #[allow(non_snake_case)]
    fn push_new(&mut self, P_ab: DMatrix<f64>) {
        let scale = 1e-12 * P_ab.amax().max(1.0);
        if !self.cross.iter().any(|c| (c - &P_ab).amax() <= scale) {
            self.cross.push(P_ab);
        }
    }

    /// The loop's result from a program, its cuts and the violation found at it;
    /// `converged` and `gap_closed` follow from `stop`.
    fn finish(
        &self,
        opt: SdpResult,
        cross: Vec<DMatrix<f64>>,
        generated: usize,
        violation: f64,
        stop: CutsStop,
    ) -> CutsResult {
        let certified = self.certified.as_ref();
        CutsResult {
            lower_bound: self.best_lower.max(opt.lower_bound),
            fused: opt.fused,
            status: opt.status,
            iterations: self.iterations,
            constraints: cross.len(),
            constraints_generated: generated,
            violation,
            converged: matches!(stop, CutsStop::Tolerance | CutsStop::GapClosed),
            stop,
            certified_trace: self.certified_trace,
            certificates: certified.map(Certificates::of),
            certified: certified.map(|c| c.fused.clone()),
            own_rule_proven: false,
            gap_closed: stop == CutsStop::GapClosed,
            dual_objective: opt.dual_objective,
            cross,
            proof_rounds: 0,
        }
    }

    /// The loop stopped (`stop`) at this program: (5) on its active cuts where it
    /// converged, (6) its own rule proven, then another round where (7) the proof's short
    /// directions give cuts or (8) the finer loop may close the bracket (`None`), else the
    /// result, the narrower of this round's and the round before's.
    fn conclude(
        &mut self,
        opt: SdpResult,
        violation: f64,
        stop: CutsStop,
        threshold: f64,
    ) -> Result<Option<CutsResult>, SolveError> {
        let converged = matches!(stop, CutsStop::Tolerance | CutsStop::GapClosed);
        let generated = self.earlier_generated + self.cross.len();
        let (mut opt, mut cross, mut violation) = (opt, std::mem::take(&mut self.cross), violation);
        if converged {
            let deadline = self
                .deadline
                .earlier(self.per_cut_iteration * cross.len() as f64);
            let at = Pruning {
                threshold,
                violation,
                deadline: &deadline,
            };
            if let Some((reduced, kept, v)) =
                prune(self.problem, &opt, &cross, &self.sdp, self.settings, &at)?
            {
                (opt, cross, violation) = (reduced, kept, v);
            }
        }
        let now = self.now();
        let latest = self.finish(opt, cross, generated, violation, stop);
        let (latest, short) = prove_own_rule(self.problem, latest, &now, &self.deadline)?;
        if converged && self.rounds < PROOF_ROUNDS && self.iterations < self.settings.max_iterations
        {
            let new = self.short_cuts(&latest, short, threshold)?;
            if !new.is_empty() && !self.deadline.passed() {
                self.rounds += 1;
                self.restart_from(latest, generated, &now);
                for cut in new {
                    self.push_new(cut);
                }
                return Ok(None);
            }
        }
        if converged && self.refinable(&latest) {
            self.tolerance = REFINED_TOLERANCE;
            let refined = self.now();
            self.restart_from(latest, generated, &refined);
            return Ok(None);
        }
        let mut result = match self.earlier.take() {
            Some(before) => tighter(before, latest, &now),
            None => latest,
        };
        (result.iterations, result.constraints_generated) = (self.iterations, generated);
        result.proof_rounds = self.rounds;
        Ok(Some(result))
    }

    /// Module docs, (7): the proof's short directions searched for cuts at the round's rule;
    /// those violated beyond `threshold`, none if the deadline stopped a search.
    #[allow(non_snake_case)]
    fn short_cuts(
        &self,
        latest: &CutsResult,
        short: Vec<DVector<f64>>,
        threshold: f64,
    ) -> Result<Vec<DMatrix<f64>>, SolveError> {
        let mut new = Vec::new();
        for v in short {
            match worst_case_search(
                self.problem,
                &latest.fused,
                v,
                self.settings,
                &self.deadline,
            ) {
                Ok((found, P_ab)) if found > threshold => new.push(P_ab),
                Ok(_) => {}
                Err(SolveError::TimeLimit { .. }) => return Ok(Vec::new()),
                Err(e) => return Err(e),
            }
        }
        Ok(new)
    }

    /// Module docs, (8): whether the loop goes on to `REFINED_TOLERANCE` (once, on problems
    /// of three states where the own rule's proof left the bracket open, in time).
    fn refinable(&self, latest: &CutsResult) -> bool {
        self.tolerance > REFINED_TOLERANCE
            && self.settings.own_rule_cones > 0
            && self.problem.dim() == 3
            && still_open(latest)
            && self.iterations < self.settings.max_iterations
            && !self.deadline.passed()
    }

    /// Another round from this round's cuts: the cuts carried over are counted once, in the
    /// next round, and this round's result is kept (the narrower of it and the round
    /// before's, `settings` deciding closure) for the end.
    fn restart_from(&mut self, latest: CutsResult, generated: usize, settings: &CutsSettings) {
        self.cross = latest.cross.clone();
        self.earlier_generated = generated - self.cross.len();
        self.earlier = Some(match self.earlier.take() {
            Some(before) => tighter(before, latest, settings),
            None => latest,
        });
        self.previous = None;
    }
}

/// The guiding certificate (module docs, "Guided by the certified rule"): where `certify`
/// is set and every block fits the certificate's limits, the certified rule, given half of
/// the time limit; if it does not finish, the loop runs unguided (the limit is for the
/// loop's bracket, not for the guide).
fn guiding_certificate(
    problem: &FusionProblem,
    settings: &CutsSettings,
    deadline: &Deadline,
) -> Result<Option<CertifiedResult>, SolveError> {
    let certify_settings = CertifySettings {
        time_limit: deadline.share(0.5),
        ..settings.certify_settings
    };
    let fits = |b: &Vec<usize>| {
        b.len() <= certify_settings.max_block_dim
            && CertifySettings::cone_size(b.len(), certify_settings.family_for(b.len()).level())
                <= certify_settings.max_cone
    };
    if !settings.certify || !certification_blocks(problem, None).iter().all(fits) {
        return Ok(None);
    }
    match certified_fusion(problem, &certify_settings) {
        Ok(c) => Ok(Some(c)),
        Err(SolveError::TimeLimit { .. }) => Ok(None),
        Err(e) => Err(e),
    }
}

/// A random direction: uniform entries in `[−1, 1)`, normalised.
fn random_direction(rng: &mut ChaCha8Rng, n: usize) -> DVector<f64> {
    DVector::from_fn(n, |_, _| rng.random_range(-1.0..1.0)).normalize()
}

/// The worst violation of `cuts`, and `floor`.
fn worst(cuts: &[Cut], floor: f64) -> f64 {
    cuts.iter().map(|f| f.0).fold(floor, f64::max)
}

/// Where [`prune`] runs: the stopping threshold, the violation found at the full program and
/// the deadline.
struct Pruning<'d> {
    threshold: f64,
    violation: f64,
    deadline: &'d Deadline,
}

/// Module docs, (5): the program on the active cuts alone (margin
/// `λ_min(P̄ − K P' Kᵀ) ≤ 10⁻⁶ max(tr P̄, 1)` at the converged solution), accepted when its
/// optimum is no lower (beyond `threshold`), every dropped cut holds at its solution (beyond
/// `threshold`), and the worst-case search from the eigenvectors of its `P̄` finds no
/// violation above `max(threshold, violation)`. Returns the reduced solution, its cuts and
/// the violation found.
#[allow(non_snake_case, clippy::type_complexity)]
fn prune(
    problem: &FusionProblem,
    full: &SdpResult,
    cross: &[DMatrix<f64>],
    sdp: &SdpSettings,
    settings: &CutsSettings,
    at: &Pruning,
) -> Result<Option<(SdpResult, Vec<DMatrix<f64>>, f64)>, SolveError> {
    let Pruning {
        threshold,
        violation,
        deadline,
    } = *at;
    let scale = full.fused.trace().max(1.0);
    let (kept, dropped): (Vec<DMatrix<f64>>, Vec<DMatrix<f64>>) = cross
        .iter()
        .cloned()
        .partition(|P_ab| margin(problem, &full.fused, P_ab) <= 1e-6 * scale);
    if dropped.is_empty() || kept.is_empty() {
        return Ok(None);
    }
    let set = CrossSamples {
        cross: kept.clone(),
        trials: 0,
        auto: None,
    };
    let reduced = match solve_samples(problem, &set, sdp, deadline) {
        Ok(r) => r,
        // Pruning is optional: out of time, keep the full program.
        Err(SolveError::TimeLimit { .. }) => return Ok(None),
        Err(e) => return Err(e),
    };
    if reduced.fused.trace() < full.fused.trace() - threshold
        || lowest_margin(problem, &reduced.fused, &dropped) < -threshold
    {
        return Ok(None);
    }
    let eig = SymmetricEigen::new(reduced.fused.P.clone());
    let mut found = f64::NEG_INFINITY;
    for k in 0..problem.dim() {
        let v = eig.eigenvectors.column(k).into_owned();
        match worst_case_search(problem, &reduced.fused, v, settings, deadline) {
            Ok((v, _)) => found = found.max(v),
            // Not verified in time: keep the full program.
            Err(SolveError::TimeLimit { .. }) => return Ok(None),
            Err(e) => return Err(e),
        }
    }
    if found > threshold.max(violation) {
        return Ok(None);
    }
    Ok(Some((reduced, kept, violation.max(found))))
}
