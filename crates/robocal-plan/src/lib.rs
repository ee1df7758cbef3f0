//! Pose planning (`robocal plan`): which configurations to measure, and what accuracy they will
//! buy, before the tracker is set up.
//!
//! - [`settings`]: `plan.toml` (seed, loads, workspace box, noise, which physics the
//!   calibration will identify), validated with errors that name the file and key.
//! - [`design`]: the candidates' scaled identification Jacobian (the parameter set and column
//!   scaling `calibrate` uses, joint-error blocks included when asked), the information matrix
//!   of a set, greedy then exchange D-optimal selection, the observability indices O1 (D), O3
//!   (smallest singular value) and O4 (noise amplification), and the propagation of tracker
//!   noise to each parameter's standard deviation and to the position error at check poses.
//! - [`plan`](mod@plan): candidates from the joint limits (or the user's file), the selection
//!   for each asked count, and the report.

pub mod design;
pub mod error;
pub mod plan;
pub mod settings;

pub use design::{Criterion, Design, Indices, Pool, log_det};
pub use error::{PlanError, Result};
pub use plan::{ParameterSigma, PlanReport, PlanResult, candidates_from_limits, plan};
pub use settings::{PlanSettings, RawPlan};
