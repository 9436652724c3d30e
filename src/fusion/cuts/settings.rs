//! The cutting-plane loop's settings ([`CutsSettings`], with defaults and `validate`) and why
//! it stopped ([`CutsStop`]).

use crate::error::SolveError;
use crate::fusion::bracket::{Bracket, UpperRule};
use crate::fusion::certify::{CertifySettings, MAX_CONES};
use crate::fusion::program::check_time_limit;
use crate::fusion::sdp::SdpSettings;

/// Settings of the cutting-plane loop.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CutsSettings {
    /// Random admissible cross-covariances to start from (default 4, hit-and-run).
    pub initial_samples: usize,
    /// Seed of the starting samples and of the random search directions (default 0).
    pub seed: u64,
    /// Outer iterations (one solve and one search each; default 60).
    pub max_iterations: usize,
    /// Starting directions of the worst-case search per iteration (default 4).
    pub restarts: usize,
    /// Stop when the worst violation is below `tolerance · max(tr P̄, 1)` (default `1e-7`);
    /// where the own rule's proof leaves a three-state bracket open, the loop goes on once to
    /// `10⁻¹⁰` (module docs of `fusion::cuts`, (8)).
    pub tolerance: f64,
    /// Settings of each SDP solve (its sample and working-set fields are ignored).
    pub sdp: SdpSettings,
    /// Guide the loop with the certified rule (default `true`; blocks of at most
    /// [`CertifySettings::max_block_dim`] states): seed it with the worst cases at the
    /// certified bound, and stop as soon as the lower bound reaches the certified upper bound
    /// within `tolerance` — a proven optimum.
    pub certify: bool,
    /// In-out separation weight `α ∈ [0, 1)` (default 0.5; 0 = cut at the relaxation's
    /// optimum only): the search also runs at `α·(K, P̄)_out + (1 − α)·(K, P̄)_in` between the
    /// relaxation's optimum and a feasible point (the certified rule, else nmCI); its cuts
    /// replace the optimum's when it finds a violation, otherwise it becomes the new
    /// feasible point.
    pub in_out: f64,
    /// Settings of the certified rule that guides the loop and closes its gap.
    pub certify_settings: CertifySettings,
    /// Wall-clock limit in seconds (default none) of the whole loop: past it (checked between
    /// iterations and inside each solve) the loop returns the last finished program's result
    /// and its proven bracket with `converged: false` and `stop: TimeLimit` — an error only if
    /// the first program did not finish in time. The guiding certificate gets half of the
    /// limit and is left out if it does not finish. The loop plans to finish 1 % before the
    /// limit (the steps between its deadline checks take milliseconds); a solve stops only
    /// between its interior-point iterations, so each program is given the deadline less one
    /// iteration's length as the last one took, and the proof of the loop's own rule stops
    /// cutting while the time left holds what its last steps took per cone: kept by these
    /// estimates, not a hard bound (docs/benchmarks.md gives the worst time measured).
    pub time_limit: Option<f64>,
    /// Three-state problems whose bracket the certified rule leaves open: the loop's own rule
    /// is proven on at most this many cones of directions (module docs, "Its own rule,
    /// proven"; default 128, 0: off, else at least 4 and at most
    /// [`MAX_CONES`]).
    pub own_rule_cones: u32,
    /// Also stop ([`CutsStop::GapClosed`]) as soon as the proven bracket is closed to this
    /// relative width, `upper − lower ≤ bracket_rtol · upper` as
    /// [`crate::bounds::Bracket::closed`] tests it (the difference rounded up), even where the
    /// loop's own tolerance is not yet met (default `None`: only the loop's tolerance closes
    /// the gap; else in `(0, 1)`). The explorer's second stage sets it to
    /// [`crate::bounds::CLOSED_RTOL`]: it wants the bracket closed, and the loop's `P̄` is then
    /// a relaxation's, not conservative to `tolerance`.
    pub bracket_rtol: Option<f64>,
}

/// Why the cutting-plane loop stopped.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum CutsStop {
    /// The worst violation found was below the tolerance.
    Tolerance,
    /// The proven lower bound reached the certified rule's proven trace within the tolerance,
    /// or the bracket closed to [`CutsSettings::bracket_rtol`].
    GapClosed,
    /// `max_iterations` ran out.
    MaxIterations,
    /// `time_limit` ran out.
    TimeLimit,
}

impl Default for CutsSettings {
    fn default() -> Self {
        Self {
            initial_samples: 4,
            seed: 0,
            max_iterations: 60,
            restarts: 4,
            tolerance: 1e-7,
            sdp: SdpSettings::default(),
            certify: true,
            in_out: 0.5,
            certify_settings: CertifySettings::default(),
            time_limit: None,
            own_rule_cones: 128,
            bracket_rtol: None,
        }
    }
}

impl CutsSettings {
    /// Checks the settings.
    pub fn validate(&self) -> Result<(), SolveError> {
        if self.initial_samples == 0 || self.max_iterations == 0 || self.restarts == 0 {
            return Err(SolveError::InvalidSettings(
                "sdp_cuts needs initial_samples, max_iterations and restarts of at least 1".into(),
            ));
        }
        if !(0.0..1.0).contains(&self.in_out) {
            return Err(SolveError::InvalidSettings(format!(
                "in_out must be in [0, 1) (got {})",
                self.in_out
            )));
        }
        self.certify_settings.validate()?;
        check_time_limit(self.time_limit)?;
        if self.own_rule_cones != 0 && !(4..=MAX_CONES).contains(&self.own_rule_cones) {
            return Err(SolveError::InvalidSettings(format!(
                "own_rule_cones must be 0 or in 4..={MAX_CONES} (got {})",
                self.own_rule_cones
            )));
        }
        if let Some(r) = self.bracket_rtol {
            if !(r > 0.0 && r < 1.0) {
                return Err(SolveError::InvalidSettings(format!(
                    "bracket_rtol must be in (0, 1) (got {r})"
                )));
            }
        }
        if !(self.tolerance > 0.0 && self.tolerance.is_finite()) {
            return Err(SolveError::InvalidSettings(format!(
                "tolerance must be positive and finite (got {})",
                self.tolerance
            )));
        }
        Ok(())
    }

    /// Whether the loop counts the proven bracket `[lower, upper]` as closed
    /// ([`CutsStop::GapClosed`]): `lower ≥ upper − tolerance · max(upper, 1)`, or with
    /// `bracket_rtol`, the bracket closed to it as [`Bracket::closed`] tests it.
    pub(crate) fn closes(&self, lower: f64, upper: f64) -> bool {
        let bracket = Bracket {
            lower,
            upper,
            upper_rule: UpperRule::Certified,
        };
        lower >= upper - self.tolerance * upper.max(1.0)
            || self.bracket_rtol.is_some_and(|r| bracket.closed(r))
    }
}
