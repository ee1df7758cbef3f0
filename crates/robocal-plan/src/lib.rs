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
//!
//! Thirty configurations of the bundled UR5 chosen out of 200 random ones, and the position
//! error they will leave over 50 check poses predicted beside random sets of the same size:
//!
//! ```
//! use std::path::Path;
//! use robocal_data::Silent;
//! use robocal_plan::{PlanSettings, candidates_from_limits, plan};
//! use robocal_robot::Robot;
//!
//! let file = Path::new("../../datasets/ur5/robot.toml");
//! let robot = Robot::load(file)?;
//! let settings = PlanSettings::from_toml_str("pool = 200\ncheck = 50\n", Path::new("plan.toml"))?;
//! let pool = candidates_from_limits(&robot, file, &settings, settings.pool, 1, &Silent)?;
//! let checks = candidates_from_limits(&robot, file, &settings, settings.check, 2, &Silent)?;
//! let result = plan(&robot, pool, "random".into(), &checks, &[30], &settings, &Silent)?;
//! let planned = &result.plans[0];
//! assert_eq!(planned.chosen.len(), 30);
//! // Mean predicted error at the check poses, mm: the plan's against the median random set's.
//! assert!(planned.predicted[0] < planned.predicted_random[0]);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

pub mod design;
pub mod error;
pub mod plan;
pub mod settings;

pub use design::{Design, Indices, Pool, log_det};
pub use error::{PlanError, Result};
pub use plan::{ParameterSigma, PlanReport, PlanResult, candidates_from_limits, plan};
pub use settings::{Criterion, PlanSettings, RawPlan};
