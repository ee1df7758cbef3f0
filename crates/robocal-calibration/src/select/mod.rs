//! The default calibration: candidates scored on held-out poses, a chain of decisions, the
//! chosen model fitted again on every row.

mod chain;
mod decisions;
mod gravity;
mod motion;
mod physics;
mod plan;
mod residual;
mod run;
mod scoring;
pub(crate) mod selection;
pub(crate) mod settings;
mod status;
mod targets;

pub use decisions::REACH_GAIN;
pub use gravity::{JOINT1_GRAVITY_ANGLE_DEG, joint1_gravity_angle, residual_stages};
pub use run::automatic;
pub use selection::{Candidate, Decision, Selection};
pub use settings::{AutoSettings, DEFAULT_BUDGET_SECONDS, DEFAULT_FOLDS};
pub use status::{Stage, Status};

#[cfg(test)]
mod tests;
