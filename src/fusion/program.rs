//! The plumbing under every solver of the crate: one Clarabel call ([`solve_program`]) with
//! the crate's settings, its KKT-solver fallback and its wall-clock [`Deadline`], and the
//! svec layout of symmetric matrices Clarabel's PSD cones use ([`svec_index`]). The sampled
//! SDP (`fusion::sdp`), the certified rule (`fusion::certify`) and the cutting planes
//! (`fusion::cuts`) build their programs and call it; it knows none of them.

use clarabel::algebra::CscMatrix;
use clarabel::solver::{DefaultSettings, DefaultSolver, IPSolver, SolverStatus, SupportedConeT};

use crate::error::SolveError;

/// How Clarabel ended a solve that produced a usable bound (in JSON: `"Solved"`,
/// `"AlmostSolved"`, as Clarabel spells it).
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum SdpStatus {
    /// Solved to the requested tolerances.
    Solved,
    /// Solved to Clarabel's reduced tolerances: a valid but less accurate result.
    AlmostSolved,
}

impl SdpStatus {
    /// The status name as Clarabel spells it.
    pub fn as_str(self) -> &'static str {
        match self {
            SdpStatus::Solved => "Solved",
            SdpStatus::AlmostSolved => "AlmostSolved",
        }
    }
}

/// Checks an optional wall-clock limit (positive and finite).
pub(crate) fn check_time_limit(limit: Option<f64>) -> Result<(), SolveError> {
    match limit {
        Some(t) if !(t > 0.0 && t.is_finite()) => Err(SolveError::InvalidSettings(format!(
            "time_limit must be a positive number of seconds (got {t})"
        ))),
        _ => Ok(()),
    }
}

/// A wall-clock deadline (`web_time`: `performance.now()` in the browser).
#[derive(Debug, Clone, Copy)]
pub(crate) struct Deadline {
    end: Option<web_time::Instant>,
    limit: f64,
}

impl Deadline {
    /// `limit` seconds from now (`None`: never). A limit beyond what the clock can represent
    /// (`Duration` holds at most `u64::MAX` seconds, and the instant it ends at must exist)
    /// is a deadline that cannot pass: the same as none, not an error and not a clamp.
    pub(crate) fn after(limit: Option<f64>) -> Self {
        Self {
            end: limit.and_then(|t| {
                let duration = web_time::Duration::try_from_secs_f64(t).ok()?;
                web_time::Instant::now().checked_add(duration)
            }),
            limit: limit.unwrap_or(f64::INFINITY),
        }
    }

    /// Seconds left (infinite without a limit; 0 when past).
    pub(crate) fn remaining(&self) -> f64 {
        match self.end {
            None => f64::INFINITY,
            Some(end) => end
                .saturating_duration_since(web_time::Instant::now())
                .as_secs_f64(),
        }
    }

    /// This deadline `seconds` earlier (the same without one, or for `seconds` not a positive
    /// number; passed now where the clock cannot go back that far): the deadline of a step
    /// that may run up to `seconds` past the one it is given.
    pub(crate) fn earlier(&self, seconds: f64) -> Self {
        let end = self.end.map(|end| {
            match web_time::Duration::try_from_secs_f64(seconds) {
                Ok(by) => end.checked_sub(by),
                // Beyond what a duration holds: passed now.
                Err(_) if seconds > 0.0 => None,
                Err(_) => Some(end),
            }
            .unwrap_or_else(web_time::Instant::now)
        });
        Self {
            end,
            limit: self.limit,
        }
    }

    /// `fraction` of the seconds left, at least a millisecond (`None` without a deadline):
    /// the time limit of a part of the solve.
    pub(crate) fn share(&self, fraction: f64) -> Option<f64> {
        self.end.map(|_| (fraction * self.remaining()).max(1e-3))
    }

    /// Whether the deadline has passed.
    pub(crate) fn passed(&self) -> bool {
        self.remaining() <= 0.0
    }

    /// The error of a solve stopped by this deadline.
    pub(crate) fn error(&self, what: &str) -> SolveError {
        SolveError::TimeLimit {
            seconds: self.limit,
            what: what.into(),
        }
    }

    /// `Err` if the deadline has passed.
    pub(crate) fn check(&self, what: &str) -> Result<(), SolveError> {
        if self.passed() {
            Err(self.error(what))
        } else {
            Ok(())
        }
    }
}

/// Clarabel's KKT solver for a program.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Kkt {
    /// The platform's: natively faer's supernodal LDLᵀ — the sampled SDP's and the
    /// certificate's KKT systems are an arrow of dense PSD-cone blocks around the few gain
    /// variables, where it is several times faster than QDLDL's scalar factorization; faer
    /// does not build for 32-bit wasm, where QDLDL is used.
    Platform,
    /// QDLDL everywhere: the cutting planes' worst-case search (one small cone). With faer
    /// there, the search missed violations QDLDL's solves find (the anti-diagonal bracket test
    /// `bracket::higher_levels_…`, case 2: the cuts' lower end stopped at 4.6214578 instead of
    /// 4.6214648, leaving the bracket open), and the search is local, so a weaker worst case
    /// is a weaker cut.
    Qdldl,
}

impl Kkt {
    fn method(self) -> &'static str {
        match self {
            #[cfg(not(target_arch = "wasm32"))]
            Kkt::Platform => "faer",
            #[cfg(target_arch = "wasm32")]
            Kkt::Platform => "qdldl",
            Kkt::Qdldl => "qdldl",
        }
    }
}

/// Builds and solves one Clarabel program — every program of the crate goes through here
/// (the sampled SDP, the certified bound's SDP, the cutting planes' worst-case search) — with
/// the crate's settings: one thread (the caller — a study, a Python process pool, a page's
/// worker — owns the parallelism), `tolerance` on the absolute and relative gap and on
/// feasibility, at most `max_iter` iterations, and the time left before `deadline`, with the
/// KKT solver `kkt`; when faer's factorization breaks down (status `NumericalError` or
/// `InsufficientProgress`: seen on certificate programs, where faer's first solve returned
/// NaN), the program is solved again with QDLDL.
///
/// Returns the solver (its solution) and the status when Clarabel solved the program to its
/// tolerance (`Solved`) or to its reduced one (`AlmostSolved`); a program stopped by the
/// deadline is [`SolveError::TimeLimit`] naming `what`, any other status
/// [`SolveError::SolverFailed`]. Never hidden: the caller reports the status.
#[allow(non_snake_case)]
#[allow(clippy::too_many_arguments)]
pub(crate) fn solve_program(
    P: &CscMatrix<f64>,
    q: &[f64],
    A: &CscMatrix<f64>,
    b: &[f64],
    cones: &[SupportedConeT<f64>],
    kkt: Kkt,
    (max_iter, tolerance): (u32, f64),
    deadline: &Deadline,
    what: &str,
) -> Result<(DefaultSolver<f64>, SdpStatus), SolveError> {
    let run = |method: &str| -> Result<DefaultSolver<f64>, SolveError> {
        let settings = DefaultSettings {
            verbose: false,
            max_threads: 1,
            max_iter,
            tol_gap_abs: tolerance,
            tol_gap_rel: tolerance,
            tol_feas: tolerance,
            time_limit: deadline.remaining(),
            direct_solve_method: method.into(),
            ..DefaultSettings::default()
        };
        let mut solver = DefaultSolver::new(P, q, A, b, cones, settings)
            .map_err(|e| SolveError::Setup(e.to_string()))?;
        solver.solve();
        Ok(solver)
    };
    let mut solver = run(kkt.method())?;
    let broke_down = matches!(
        solver.solution.status,
        SolverStatus::NumericalError | SolverStatus::InsufficientProgress
    );
    if broke_down && kkt.method() != "qdldl" {
        solver = run("qdldl")?;
    }
    let status = match solver.solution.status {
        SolverStatus::Solved => SdpStatus::Solved,
        SolverStatus::AlmostSolved => SdpStatus::AlmostSolved,
        SolverStatus::MaxTime => return Err(deadline.error(what)),
        other => {
            return Err(SolveError::SolverFailed {
                status: format!("{other:?}"),
                iterations: solver.solution.iterations,
            })
        }
    };
    Ok((solver, status))
}

/// svec index of `(r, c)`, `r ≤ c`, in Clarabel's column-major upper-triangle order.
pub(crate) fn svec_index(r: usize, c: usize) -> usize {
    c * (c + 1) / 2 + r
}

#[cfg(test)]
mod tests {
    use super::Deadline;

    /// `earlier` moves the end back by the seconds given (a step that may overrun by that much
    /// is given it), to "passed" where that is before now; without a deadline, or for seconds
    /// that are not a positive number, nothing changes.
    #[test]
    fn an_earlier_deadline_ends_that_much_sooner() {
        let d = Deadline::after(Some(100.0));
        let left = d.earlier(30.0).remaining();
        assert!(left <= 70.0 && left > 69.0, "{left}");
        assert!(d.earlier(100.5).passed());
        assert!(d.earlier(1e300).passed());
        for same in [0.0, -1.0, f64::NAN] {
            let left = d.earlier(same).remaining();
            assert!(left <= 100.0 && left > 99.0, "{same}: {left}");
        }
        let none = Deadline::after(None).earlier(5.0);
        assert!(none.remaining().is_infinite() && !none.passed());
    }
}
