//! The calibrated model: what `robocal calibrate` produces, as one value.
//!
//! A [`CalibratedModel`] is the identified kinematic table, the joint-error physics identified
//! with it (payload compliance, transmission harmonics, self-weight terms: one
//! [`JointErrors`] value) and the residual model learned on what those leave. It predicts the
//! measured point of a configuration under a load, and it is the only code that reads or
//! writes a model directory ([`CalibratedModel::save`], [`CalibratedModel::load`]; the layout is
//! in `docs/formats.md` ("Model directory") and [`dir`]).
//!
//! A library user loads a model directory written by `robocal calibrate` and predicts:
//!
//! ```
//! use robocal_data::Sample;
//! use robocal_model::CalibratedModel;
//! use robocal_robot::Robot;
//!
//! # let tmp = tempfile::tempdir()?;
//! # let model_dir = tmp.path().join("model");
//! # let robot = Robot::from_toml_str(
//! #     "name = \"planar\"\n[base]\nxyz = [0, 0, 0]\nrpy = [0, 0, 0]\n[tool]\nxyz = [100, 0, 0]\n\
//! #      [[joint]]\na = 0\nalpha = 0\nd = 0\ntheta = 0\n[[joint]]\na = 300\nalpha = 0\nd = 0\ntheta = 0\n",
//! #     "planar.toml",
//! # )?;
//! # CalibratedModel::kinematic(robot).save(&model_dir, &serde_json::json!({}))?;
//! let model = CalibratedModel::load(&model_dir)?;
//! let pose = Sample { pose: "p1".into(), joints: vec![10.0, 20.0], load: 0.0, line: 0, target: String::new(), seq: None, last_move: Vec::new() };
//! let points = model.predict([&pose]);
//! assert!((points[0].x - (300.0 * 10f64.to_radians().cos() + 100.0 * 30f64.to_radians().cos())).abs() < 1e-9);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

pub mod dir;
pub mod domain;
mod error;
pub mod export;
pub mod import;
mod model;
pub mod motion;

pub use dir::{COMPLIANCE_FILE, KINEMATICS_FILE, MODEL_FORMAT, NOMINAL_FILE, REPORT_FILE};
pub use domain::{DOMAIN_FILE, Domain, Excess, WARN_BEYOND_DEG};
pub use error::{ModelError, Result};
pub use model::{
    CalibratedModel, gate_physics_row, gate_physics_rows, resolve_gate_physics, rotation_angle,
    with_gate_physics,
};
pub use motion::{MOTION_FILE, MotionPlay};
pub use robocal_robot::JointErrors;
