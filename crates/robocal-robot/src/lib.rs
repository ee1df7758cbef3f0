//! The robot model of robocal: modified Denavit–Hartenberg tables with an optional Hayati β per
//! joint, a base frame in the measurement (laser-tracker) frame and a measured point on the flange.
//!
//! Kinematics are pure functions of `(robot, joints)`. Lengths are mm; angles are radians in the
//! API and degrees in files. Every parameter has a stable name (`j2.d`, `j3.beta`, `base.rz`,
//! `tool.x`) and a place in one flat vector, with analytic Jacobians for identification.
//!
//! ```
//! use robocal_robot::Robot;
//! let robot = Robot::from_toml_str(r#"
//!     name = "planar"
//!     [[joint]]
//!     a = 0.0
//!     alpha = 0.0
//!     d = 0.0
//!     theta = 0.0
//!     [base]
//!     xyz = [0.0, 0.0, 0.0]
//!     rpy = [0.0, 0.0, 0.0]
//!     [tool]
//!     xyz = [100.0, 0.0, 0.0]
//! "#, "planar.toml")?;
//! let p = robot.point(&[90f64.to_radians()]);
//! assert!((p.y - 100.0).abs() < 1e-12 && p.x.abs() < 1e-12);
//! assert_eq!(robot.param_ids()[0].to_string(), "j1.a");
//! # Ok::<(), robocal_robot::RobotError>(())
//! ```

pub mod compliance;
pub mod covariance;
pub mod error;
pub mod exact;
pub mod ik;
pub mod kinematics;
pub mod params;
pub mod table;

pub use compliance::{
    Across, Backlash, Compliance, DEG_PER_KNM, DeflectionRates, ErrorParam, Flank, HARMONIC_REACH,
    Harmonic, JointErrors, LinkWeight, MomentPart, RawCompliance, RowTerms, Runout, SelfWeight,
    TORQUE_FEATURES_PER_LINK, Tilt, Turns, backlash_name, compliance_name, harmonic_name,
    link_weight_name, payload_com_name, payload_mass_feature, runout_name, self_weight_name,
    tilt_name, torque_side, turn_rotation, turned,
};
pub use covariance::{Parameter, ParameterCovariance, displaced};
pub use error::{Result, RobotError};
pub use ik::{IkOptions, IkTarget};
pub use kinematics::{JointAxes, ParamTwist};
pub use kinematics::{left_jacobian_inverse, matrix_to_rpy, rotation_vector, rpy_to_matrix};
pub use params::{JointField, ParamId, Unit};
pub use table::{
    Base, Joint, RawBase, RawJoint, RawTool, Robot, RobotTable, TomlFault, toml_error,
};
