//! What the selection decided, as values: the stage a decision is about, what became of each
//! candidate; and the words they are said in (on the terminal as the candidates are scored, and
//! in the report), made here and nowhere else.

use std::fmt;

use serde::{Serialize, Serializer};

/// The stage a decision of the default calibration is about.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Stage {
    /// The identified table against the nominal one with base and tool fitted.
    Kinematic,
    /// Joint compliances under the payload.
    Compliance,
    /// The joint-error blocks (harmonics, self-weight, backlash) by stepwise selection.
    JointErrors,
    /// Axis runouts.
    Runout,
    /// Backlash flanks searched beyond each joint's own terms.
    FlankSearch,
    /// Tilting compliances.
    Tilt,
    /// A residual model on the physics.
    Residual,
    /// Joint 1's harmonics continued beyond the readings.
    HarmonicReach,
    /// Play that follows the order of motion (rows with `seq`).
    Motion,
    /// The rows of the points beyond the main one (other reflectors).
    ExtraPoints,
}

impl Stage {
    /// Its name in the report and on the terminal: `kinematic`, `joint_errors`, ….
    pub fn name(self) -> &'static str {
        match self {
            Self::Kinematic => "kinematic",
            Self::Compliance => "compliance",
            Self::JointErrors => "joint_errors",
            Self::Runout => "runout",
            Self::FlankSearch => "flank_search",
            Self::Tilt => "tilt",
            Self::Residual => "residual",
            Self::HarmonicReach => "harmonic_reach",
            Self::Motion => "motion",
            Self::ExtraPoints => "extra_points",
        }
    }
}

impl fmt::Display for Stage {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// What became of a candidate of the default calibration.
#[derive(Debug, Clone, PartialEq)]
pub enum Status {
    /// Scored, and the model chosen.
    Chosen,
    /// Scored.
    Evaluated,
    /// A residual model scored whose held-out errors are not significantly lower than the
    /// physical model's.
    NotSignificant,
    /// Skipped: a fold's fit failed (the error, in words).
    Failed(String),
    /// Skipped: a fold's training rows hold `fewest` configurations; a residual model needs
    /// `needed`.
    TooFewConfigurations {
        /// The fewest configurations of a fold's training rows.
        fewest: usize,
        /// The fewest a residual model is tried on.
        needed: usize,
    },
    /// Skipped: the physical model a residual model is trained on failed on a fold.
    PhysicsFailed,
    /// Skipped before its folds: the budget would be spent before they and the final fit end.
    Projected {
        /// The time budget, s.
        budget: f64,
        /// The seconds of it kept from this candidate for the residual models.
        reserve: f64,
        /// What the projection is taken from.
        from: &'static str,
        /// Its seconds.
        seconds: f64,
        /// The seconds projected.
        projected: f64,
    },
    /// Skipped: the budget is spent.
    Spent {
        /// The time budget, s.
        budget: f64,
    },
    /// Abandoned during its folds: they would run past the budget.
    Abandoned {
        /// The time budget, s.
        budget: f64,
        /// The seconds of it kept from this candidate for the residual models.
        reserve: f64,
    },
}

impl Status {
    /// Whether the time budget cut the candidate: skipped before its folds, or abandoned during
    /// them (what the report's warning of a cut search lists).
    pub fn budget_cut(&self) -> bool {
        matches!(
            self,
            Self::Projected { .. } | Self::Spent { .. } | Self::Abandoned { .. }
        )
    }
}

impl fmt::Display for Status {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Chosen => f.write_str("chosen"),
            Self::Evaluated => f.write_str("evaluated"),
            Self::NotSignificant => {
                f.write_str("evaluated: not significantly better than the physical model")
            }
            Self::Failed(why) => write!(f, "skipped: {why}"),
            Self::TooFewConfigurations { fewest, needed } => write!(
                f,
                "skipped: {fewest} configurations to train on; a residual model needs at least {needed}"
            ),
            Self::PhysicsFailed => f.write_str("skipped: its physical model failed on a fold"),
            Self::Projected {
                budget,
                reserve,
                from,
                seconds,
                projected,
            } => {
                let leaving = match leaving(*reserve) {
                    words if words.is_empty() => words,
                    words => words + ",",
                };
                write!(
                    f,
                    "skipped: {}{leaving} would be spent before its folds and the final fit end (projected from {from}, {seconds:.1} s: {projected:.1} s)",
                    the_budget(*budget)
                )
            }
            Self::Spent { budget } => write!(f, "skipped: {} is spent", the_budget(*budget)),
            Self::Abandoned { budget, reserve } => write!(
                f,
                "abandoned: its folds would run past {}{}",
                the_budget(*budget),
                leaving(*reserve)
            ),
        }
    }
}

impl Serialize for Status {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.collect_str(self)
    }
}

/// A candidate's seconds in words: under a tenth of a second is said so, not as `0.0 s`, which
/// reads as nothing having run (its fits were quick, or made already by a candidate before it).
pub(super) fn seconds_words(seconds: f64) -> String {
    if seconds < 0.1 {
        "under 0.1 s".into()
    } else {
        format!("{seconds:.1} s")
    }
}

/// `the time budget (120 s)`: how every status of a candidate the budget cut names it, and
/// [`budget_warning`] the budget.
pub(super) fn the_budget(budget_seconds: f64) -> String {
    format!("the time budget ({budget_seconds} s)")
}

/// The words naming the seconds of the budget a candidate leaves to the residual models:
/// nothing where it leaves none.
fn leaving(reserve: f64) -> String {
    if reserve > 0.0 {
        format!(", less the {reserve:.0} s left to the residual models")
    } else {
        String::new()
    }
}
