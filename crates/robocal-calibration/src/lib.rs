//! `robocal calibrate` as a library: the stages a stage config asks for, or — with no config —
//! the default calibration, whose stages are chosen from the data by their error on held-out
//! poses.
//!
//! The default ([`automatic`]) scores candidate models — the nominal table with base and tool
//! fitted; kinematic identification; with joint compliances (two or more loads); with
//! transmission harmonics; with self-weight terms; residual models (GP, SOMM) on the best
//! identified one — on random folds of configurations and on blocks of joint 1's range (or the
//! `--validate` file), takes each richer one only if it lowers the held-out errors
//! significantly, fits the chosen one again on every row, and reports every candidate and
//! decision.
//!
//! Modules: [`calibrate`](mod@calibrate) (the library's entry: checks, bad shots, the stages or the default, the
//! report), [`select`] (the default: candidates, the chain of decisions, the final fit),
//! [`folds`](mod@folds) (random folds, blocks of joint 1, the paired significance test),
//! [`configured`](mod@configured) (the stages a stage config asks for), [`stages`] (the stage file),
//! [`outliers`] (bad shots), [`plausibility`] (data that do not fit the robot file).

pub mod budget;
pub mod built;
pub mod calibrate;
pub mod configured;
pub mod error;
pub mod fit;
pub mod folds;
pub mod options;
pub mod outliers;
pub mod plausibility;
pub mod readings;
pub mod repeats;
pub mod residual_report;
pub mod rows;
pub mod select;
pub mod spread;
pub mod stages;
pub mod summary;

pub use calibrate::{
    Calibration, CalibrationInput, CalibrationReport, Checks, Validation, calibrate,
};
pub use folds::{SIGNIFICANCE, blocks, folds, improves};
pub use outliers::{Outlier, OutlierReport, OutlierSettings, find_outliers, find_outliers_with};
pub use plausibility::{Implausible, check_plausible};
pub use repeats::{Repeats, repeats};
pub use select::{
    AutoSettings, Candidate, DEFAULT_BUDGET_SECONDS, DEFAULT_FOLDS, Decision,
    JOINT1_GRAVITY_ANGLE_DEG, REACH_GAIN, Selection, Stage, Status, automatic,
    joint1_gravity_angle, residual_stages,
};

pub use built::Built;
pub use configured::{configured, configured_with, train_residual, train_residual_model};
pub use fit::{fit_kinematic, fit_kinematic_with, physical_model};
pub use residual_report::{
    GateSplit, GateSummary, GpSummary, NetTraining, ResidualReport, gate_ready, gate_summary,
};
pub use rows::hold_out;

pub use error::{CalibrationError, Result, message};
pub use options::DefaultOptions;
pub use stages::{RawStages, Stages};
pub use summary::{Summary, fit_lines, repeats_line};
