//! Kinematic identification for robocal: closed-form registration of the tracker frame,
//! best-fit alignment, identifiability analysis, Levenberg–Marquardt (an argmin `Solver` on faer)
//! and the paper's BFGS on the mean distance (argmin, More–Thuente line search).
//!
//! ```no_run
//! use robocal_ident::{KinematicSettings, Observations, calibrate_kinematics};
//! let robot = robocal_robot::Robot::load("configs/robots/pmc6va030.toml")?;
//! let data = robocal_data::MeasurementSet::read("datasets/pmc6va030/measurements.csv", 6)?;
//! let obs = Observations::from_rows(6, data.rows.iter().filter(|r| r.sample.load == 0.0));
//! let cal = calibrate_kinematics(&robot, &obs, &KinematicSettings::default())?;
//! println!("{:.3} mm → {:.3} mm", cal.report.before.mean, cal.report.after.mean);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

pub mod bfgs;
pub mod calibrate;
pub mod error;
mod flank;
pub mod identifiability;
pub mod lm;
pub mod problem;
pub mod registration;
pub mod stage;

pub use calibrate::{
    BACKLASH_BOUND_DEG, COMPLIANCE_BOUND, ComplianceReport, ComplianceSettings, ErrorTermReport,
    FAR_FROM_NOMINAL, FLANK_ROUNDS, FitMemo, Fixed, FixedParameter, HARMONIC_BOUND_DEG, HUBER_K,
    ILL_CONDITIONED, IRLS_ROUNDS, JointCompliance, JointErrorSettings, KinematicCalibration,
    KinematicReport, KinematicSettings, Loss, MOUNTING_ANGLE_DEG, OrientationReport,
    PAYLOAD_COM_BOUND, POOR_FIT, ParameterReport, SEARCH_FLANK_ROUNDS, SolverKind, TORQUE_SHARE,
    align, calibrate_kinematics, calibrate_kinematics_with, default_compliance_joints,
    far_from_nominal, prior_spread, tracker_down,
};
pub use error::{IdentError, Result};
pub use identifiability::{
    Column, Identifiability, NULL_RIDGE, analyse, null_ridged_standard_deviations,
    posterior_covariance, posterior_standard_deviations, ridged_standard_deviations,
    standard_deviations,
};
pub use lm::{COST_TOLERANCE, LevenbergMarquardt, STALLED_STEPS, Work, run_lm, run_lm_until};
pub use problem::{
    BestPoint, CalibrationProblem, DEFAULT_NOISE_DEG, DEFAULT_NOISE_MM, LeastSquares, MeanDistance,
    Observations, PriorSpreads, angle_weight, select,
};
pub use registration::{kabsch, register_base, register_tool_rotation};
pub use stage::{MAX_HARMONICS, RawComplianceStage, RawJointErrorStage, RawKinematicStage};
