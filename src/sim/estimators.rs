//! The study's estimators: the decentralized rules ([`StudyRule`]) beside the centralized
//! filter, and how a run stores its estimates ([`Storage`]).

use serde::{Deserialize, Serialize};

use crate::fusion::rules::{Guarantee, Method};

/// The decentralized fusion rules of the study.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum StudyRule {
    /// Monolithic CI (one ω).
    Ci,
    /// Non-monolithic CI (one ω per independent block).
    Nmci,
    /// Naive fusion as if independent.
    Naive,
    /// Inverse covariance intersection (one ω): conservative for common-information
    /// correlation only (not the paper's; issue 6).
    Ici,
}

/// The rules, in report order (series `1..` of a [`RunTrace`](super::RunTrace); series 0 is the centralized
/// filter).
pub const STUDY_RULES: [StudyRule; 4] = [
    StudyRule::Ci,
    StudyRule::Nmci,
    StudyRule::Naive,
    StudyRule::Ici,
];

impl StudyRule {
    /// The rule in the registry of rules ([`crate::rules::RULES`]: name, label, colour, guarantee).
    pub fn method(self) -> Method {
        match self {
            StudyRule::Ci => Method::Ci,
            StudyRule::Nmci => Method::Nmci,
            StudyRule::Naive => Method::Naive,
            StudyRule::Ici => Method::Ici,
        }
    }

    /// The name used in reports (`ci`, `nmci`, `naive`, `ici`: [`Method::name`]).
    pub fn name(self) -> &'static str {
        self.method().name()
    }
}

/// An estimator of the study: the centralized Kalman filter (every measurement) or a
/// decentralized fusion rule.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Estimator {
    /// The centralized Kalman filter.
    Central,
    /// The agents' filters fusing with a rule.
    Decentralized(StudyRule),
}

impl Estimator {
    /// The rule, for the decentralized estimators.
    pub fn rule(self) -> Option<StudyRule> {
        match self {
            Estimator::Central => None,
            Estimator::Decentralized(rule) => Some(rule),
        }
    }

    /// The name used in reports and CSV columns (`central`, then the rules' names).
    pub fn name(self) -> &'static str {
        self.rule().map_or("central", StudyRule::name)
    }

    /// The label in charts and tables (`centralized KF`, then the rules' legends).
    pub fn label(self) -> String {
        self.rule()
            .map_or(self.short_label().into(), |r| r.method().info().legend())
    }

    /// The short label, without the guarantee's phrase (`centralized KF`, `ICI`).
    pub fn short_label(self) -> &'static str {
        self.rule().map_or("centralized KF", |r| r.method().label())
    }

    /// The colour in charts (the rules' colours from the registry).
    pub fn colour(self) -> &'static str {
        self.rule().map_or("#1d1f21", |r| r.method().info().colour)
    }

    /// Whether the study's charts draw it: all but the rules guaranteed nothing (naive
    /// fusion's NEES and COIN grow by orders of magnitude; the CSV files have them).
    pub fn charted(self) -> bool {
        self.rule()
            .is_none_or(|r| r.method().guarantee() != Guarantee::None)
    }
}

impl Serialize for Estimator {
    /// `{name, label, short_label, colour, charted}` (what the page's study tab draws with).
    fn serialize<S: serde::Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        use serde::ser::SerializeStruct;
        let mut s = serializer.serialize_struct("Estimator", 5)?;
        s.serialize_field("name", self.name())?;
        s.serialize_field("label", &self.label())?;
        s.serialize_field("short_label", self.short_label())?;
        s.serialize_field("colour", self.colour())?;
        s.serialize_field("charted", &self.charted())?;
        s.end()
    }
}

/// How estimates are stored and fused.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Storage {
    /// One `(x, P)` per independent block of the model.
    Blocks,
    /// One dense `(x, P)` for the whole state.
    Dense,
}
