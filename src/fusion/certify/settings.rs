//! The certified rule's settings ([`CertifySettings`], with defaults and `validate`), its limits
//! and the certificate families ([`Family`]).

use crate::error::SolveError;
use crate::fusion::program::check_time_limit;

use super::geometry::{cone_generators, MAX_SECTORS};
use super::layout::binomial;

/// The default of [`CertifySettings::max_block_dim`], and the certified rule's block limit in
/// the request contract ([`crate::rules::RULES`]).
pub const MAX_BLOCK_DIM: usize = 6;

/// Settings of the certified bound, with defaults and [`CertifySettings::validate`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CertifySettings {
    /// Interior-point iteration limit (default 200).
    pub max_iter: u32,
    /// Clarabel's gap and feasibility tolerances (default `1e-10`: the repair then adds
    /// `~1e-9` relative instead of `~1e-7` at `1e-9`; they affect how tight the bound is,
    /// never whether it is proven).
    pub tolerance: f64,
    /// Largest independent block certified (default 6).
    pub max_block_dim: usize,
    /// The certificate's level `r ≥ 1` (module docs); `None` (default) chooses per block:
    /// [`CertifySettings::auto_level`].
    pub level: Option<u32>,
    /// Largest PSD cone accepted (default 90 rows: the level-1 cone of a 6-state block is 73,
    /// level 3 of a 3-state block 66, level 2 of a 4-state block 84). The interior-point
    /// solver holds a dense block of `(m(m+1)/2)²` numbers for a cone of `m` rows: 134 MB at
    /// 90 rows, 1.7 GB at 170 (a level-3 4-state block, minutes per iteration).
    pub max_cone: usize,
    /// Wall-clock limit of each block's solve in seconds (default none); past it the solve
    /// ends with [`SolveError::TimeLimit`].
    pub time_limit: Option<f64>,
    /// Blocks of two states: the number of sectors of the half-circle of directions, each
    /// with its own level-1 certificate (module docs, "Sectors"), in
    /// `2..=`[`MAX_SECTORS`]. `None` (default): [`DEFAULT_SECTORS`] unless `level` is set,
    /// which then applies to two-state blocks too (one certificate for every direction).
    pub sectors: Option<u32>,
    /// Blocks of three states: the number of cones of directions (4, 16 or 64), each with its
    /// own level-1 certificate (module docs, "Sectors"); `None` (default): the adaptive cones
    /// when `max_cones` is set, else one certificate of [`CertifySettings::level_for`].
    pub cones: Option<u32>,
    /// Blocks of three states: cones of directions cut where the bound is tight, at most this
    /// many, at least 4 (module docs, "Adaptive cones"; opt-in, `None` by default).
    pub max_cones: Option<u32>,
}

impl Default for CertifySettings {
    fn default() -> Self {
        Self {
            max_iter: 200,
            tolerance: 1e-10,
            max_block_dim: MAX_BLOCK_DIM,
            level: None,
            max_cone: 90,
            time_limit: None,
            sectors: None,
            cones: None,
            max_cones: None,
        }
    }
}

impl CertifySettings {
    /// Checks every value.
    pub fn validate(&self) -> Result<(), SolveError> {
        if self.max_iter == 0 || self.max_block_dim == 0 || self.max_cone == 0 {
            return Err(SolveError::InvalidSettings(
                "max_iter, max_block_dim and max_cone must be at least 1".into(),
            ));
        }
        if !(self.tolerance > 0.0 && self.tolerance < 1.0) {
            return Err(SolveError::InvalidSettings(format!(
                "tolerance must be in (0, 1) (got {})",
                self.tolerance
            )));
        }
        if let Some(level) = self.level {
            if !(1..=MAX_LEVEL).contains(&level) {
                return Err(SolveError::InvalidSettings(format!(
                    "level must be in 1..={MAX_LEVEL} (got {level})"
                )));
            }
        }
        if let Some(count) = self.sectors {
            if !(2..=MAX_SECTORS).contains(&count) {
                return Err(SolveError::InvalidSettings(format!(
                    "sectors must be in 2..={MAX_SECTORS} (got {count})"
                )));
            }
        }
        if let Some(count) = self.cones {
            cone_generators(count)?;
        }
        if let Some(budget) = self.max_cones {
            if !(4..=MAX_CONES).contains(&budget) {
                return Err(SolveError::InvalidSettings(format!(
                    "max_cones must be in 4..={MAX_CONES} (got {budget})"
                )));
            }
            if self.cones.is_some() {
                return Err(SolveError::InvalidSettings(
                    "give cones (uniform) or max_cones (adaptive), not both".into(),
                ));
            }
        }
        check_time_limit(self.time_limit)
    }

    /// The certificate of a block of `dim` states: sectors for two states (the setting, or
    /// [`DEFAULT_SECTORS`] when neither `sectors` nor `level` is set), cones for three states
    /// (`cones`, else the adaptive cones when `max_cones` is set), else one certificate of
    /// [`CertifySettings::level_for`].
    pub fn family_for(&self, dim: usize) -> Family {
        match (dim, self.cones, self.max_cones) {
            (3, Some(count), _) => return Family::Cones(count),
            (3, None, Some(budget)) => return Family::Adaptive(budget),
            _ => {}
        }
        match (dim, self.sectors, self.level) {
            (2, Some(_), _) | (2, None, None) => {
                Family::Sectors(self.sectors.unwrap_or(DEFAULT_SECTORS))
            }
            _ => Family::Global(self.level_for(dim)),
        }
    }

    /// The level used for a block of `dim` states: the setting, or by default the level
    /// chosen from the measured gap-and-time curves (docs/methods.md, `examples/certify_levels.rs`):
    /// 5 for blocks of at most 2 states (level 4 left a few measured brackets open by up to
    /// `10⁻⁴`), 2 for 3 states (the highest level below a second), 1 above.
    pub fn level_for(&self, dim: usize) -> u32 {
        self.level.unwrap_or_else(|| Self::auto_level(dim))
    }

    /// The default level for a block of `dim` states (see [`CertifySettings::level_for`]).
    pub fn auto_level(dim: usize) -> u32 {
        match dim {
            0..=2 => 5,
            3 => 2,
            _ => 1,
        }
    }

    /// Rows of the level-`level` PSD cone for a block of `dim` states.
    pub fn cone_size(dim: usize, level: u32) -> usize {
        let r = level as usize;
        2 * dim * binomial(dim + r - 1, r) + binomial(dim + r - 2, r - 1)
    }
}

/// Highest certificate level accepted.
pub const MAX_LEVEL: u32 = 6;

/// The default number of sectors of a two-state block, chosen from the measured
/// gap-and-time curves (docs/methods.md, `examples/certify_levels.rs`).
pub const DEFAULT_SECTORS: u32 = 24;

/// Most cones accepted for the adaptive cones ([`CertifySettings::max_cones`]): the program
/// grows by a PSD cone of 19 rows per cone.
pub const MAX_CONES: u32 = 256;

/// A block solved only `AlmostSolved` whose repair added more than this fraction of its trace
/// is certified again with the next lower family, and the smaller bound kept (a tenth of
/// [`crate::bounds::CLOSED_RTOL`]: below it the repair cannot keep a bracket open).
pub(super) const RETRY_REPAIR_RTOL: f64 = 1e-7;

/// Sectors halve down to this count before a failed or reduced-accuracy sector certificate
/// falls back to a level (`Family::lower`).
pub(super) const MIN_FALLBACK_SECTORS: u32 = 16;

/// Which certificate a block gets (module docs).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Family {
    /// One certificate of this level for every direction.
    Global(u32),
    /// Two states: a level-1 certificate on each of this many sectors of directions.
    Sectors(u32),
    /// Three states: a level-1 certificate on each of this many cones of directions (4, 16
    /// or 64: the octants of a half-space, subdivided 0, 1 or 2 times).
    Cones(u32),
    /// Three states: level-1 certificates on cones cut where the bound is tight, at most
    /// this many (module docs, "Adaptive cones").
    Adaptive(u32),
}

impl Family {
    /// The family's level (1 for sectors).
    pub fn level(self) -> u32 {
        match self {
            Family::Global(level) => level,
            Family::Sectors(_) | Family::Cones(_) | Family::Adaptive(_) => 1,
        }
    }

    /// The number of sectors or cones (0 for one certificate for every direction; the budget
    /// of the adaptive cones).
    pub fn sectors(self) -> u32 {
        match self {
            Family::Global(_) => 0,
            Family::Sectors(count) | Family::Cones(count) | Family::Adaptive(count) => count,
        }
    }

    /// The family tried when this one breaks down numerically or solves to reduced accuracy
    /// only: sectors halve down to [`MIN_FALLBACK_SECTORS`], then fall back to the default
    /// level of a two-state block, a level to the one below; `None` after level 1.
    pub(super) fn lower(self) -> Option<Family> {
        match self {
            Family::Sectors(count) if count / 2 >= MIN_FALLBACK_SECTORS => {
                Some(Family::Sectors(count / 2))
            }
            Family::Sectors(_) => Some(Family::Global(CertifySettings::auto_level(2))),
            Family::Cones(count) if count / 4 >= 4 => Some(Family::Cones(count / 4)),
            Family::Cones(_) | Family::Adaptive(_) => {
                Some(Family::Global(CertifySettings::auto_level(3)))
            }
            Family::Global(level) if level > 1 => Some(Family::Global(level - 1)),
            Family::Global(_) => None,
        }
    }
}
