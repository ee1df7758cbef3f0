//! Joint compliance under the payload: the elasto-geometric part of a calibrated model.
//!
//! A joint whose gear and bearings give under torque turns by `compliance × torque`. The torque
//! that changes with the payload is gravity's on the payload's centre of mass,
//! `τ_i = w_i · ((c − a_i) × m g)`, with `w_i` the joint axis through `a_i` and `c` the payload's
//! centre of mass (world frame). The model's point for a command `q` under `m` kg is the rigid
//! table's point at `q + compliance ∘ τ(q, m)`: with no load it is the rigid table.
//!
//! The torques of the links' own masses do not change with the payload; their deflections are a
//! smooth function of the configuration that the geometric parameters absorb, so they are not
//! modelled here.
//!
//! ```
//! use robocal_robot::{Compliance, Robot};
//! let robot = Robot::from_toml_str(
//!     "name = \"arm\"\n[base]\nxyz = [0, 0, 0]\nrpy = [0, 0, 0]\n[tool]\nxyz = [1000, 0, 0]\n\
//!      [[joint]]\na = 0\nalpha = 90\nd = 0\ntheta = 0\n",
//!     "arm.toml",
//! )?;
//! // A horizontal joint holding 10 kg one metre out: 98 N·m, turning it by 98 × 1e-5 rad, so
//! // the point sinks by about 0.98 mm.
//! let payload = [1000.0, 0.0, 0.0].into(); // centre of mass at the point, flange frame
//! let c = Compliance::new(vec![1e-5], [0.0, 0.0, -9.80665].into(), payload);
//! let t = c.torques(&robot, &[0.0], 10.0);
//! assert!((t[0].abs() - 98.0665).abs() < 1e-9);
//! let sag = robot.point(&[0.0]).z - c.point(&robot, &[0.0], 10.0).z;
//! assert!((sag - 0.980665).abs() < 1e-3);
//! # Ok::<(), robocal_robot::RobotError>(())
//! ```

use std::path::Path;

use nalgebra::{Matrix3xX, Vector3};
use serde::{Deserialize, Serialize};

use crate::error::{Result, RobotError};
use crate::table::{Robot, toml_error};

/// Degrees per kN·m in radians per N·m: the file unit of a compliance.
pub const DEG_PER_KNM: f64 = std::f64::consts::PI / 180.0 / 1000.0;

/// Joint compliances under the payload's gravity torque.
#[derive(Debug, Clone, PartialEq)]
pub struct Compliance {
    /// Compliance of each joint, rad/(N·m); 0 for a joint taken as rigid.
    pub values: Vec<f64>,
    /// Gravity in the robot's base frame {0}, m/s².
    pub gravity: Vector3<f64>,
    /// The payload's centre of mass in the flange frame, mm.
    pub payload_com: Vector3<f64>,
}

impl Robot {
    /// The target point for command `q` (rad) under `load` kg, mm, world frame: the table's
    /// point, at the angles `compliance` deflects the arm to when there is a compliance model.
    pub fn point_under_load(
        &self,
        compliance: Option<&Compliance>,
        q: &[f64],
        load: f64,
    ) -> Vector3<f64> {
        match compliance {
            Some(c) => c.point(self, q, load),
            None => self.point(q),
        }
    }
}

/// `compliance.toml` as written: compliances in deg/(kN·m).
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawCompliance {
    /// Gravity in the robot's base frame {0}, m/s².
    #[serde(deserialize_with = "crate::exact::array")]
    pub gravity: [f64; 3],
    /// The payload's centre of mass in the flange frame, mm.
    #[serde(deserialize_with = "crate::exact::array")]
    pub payload_com: [f64; 3],
    /// One per joint, deg per kN·m (0: rigid).
    pub compliance: Vec<f64>,
}

impl Compliance {
    /// A compliance model; `values` in rad/(N·m), one per joint.
    pub fn new(values: Vec<f64>, gravity: Vector3<f64>, payload_com: Vector3<f64>) -> Self {
        Self {
            values,
            gravity,
            payload_com,
        }
    }

    /// Gravity in the world frame of `robot`, m/s².
    pub fn gravity_world(&self, robot: &Robot) -> Vector3<f64> {
        robot.base_rotation() * self.gravity
    }

    /// Gravity torque of `load` kg at the payload's centre of mass about every joint axis, N·m,
    /// at command `q` (rad).
    pub fn torques(&self, robot: &Robot, q: &[f64], load: f64) -> Vec<f64> {
        if load == 0.0 {
            return vec![0.0; q.len()];
        }
        let axes = robot.joint_axes(q);
        let (r, o) = robot.flange_frame(q);
        let com = o + r * self.payload_com;
        let force = self.gravity_world(robot) * load;
        axes.axes
            .iter()
            .map(|(w, a)| w.dot(&(com - a).cross(&force)) * 1e-3)
            .collect()
    }

    /// How far each joint turns under `load` kg at command `q` (rad), rad: compliance × torque.
    pub fn deflection(&self, robot: &Robot, q: &[f64], load: f64) -> Vec<f64> {
        let t = self.torques(robot, q, load);
        self.values.iter().zip(&t).map(|(c, t)| c * t).collect()
    }

    /// The joint angles the arm really takes for command `q` (rad) under `load` kg, rad.
    pub fn deflected(&self, robot: &Robot, q: &[f64], load: f64) -> Vec<f64> {
        if load == 0.0 {
            return q.to_vec();
        }
        (q.iter().zip(self.deflection(robot, q, load)))
            .map(|(q, d)| q + d)
            .collect()
    }

    /// The model's target point for command `q` (rad) under `load` kg, mm, world frame.
    pub fn point(&self, robot: &Robot, q: &[f64], load: f64) -> Vector3<f64> {
        robot.point(&self.deflected(robot, q, load))
    }

    /// Jacobian of the point with respect to each joint's compliance (mm per rad/(N·m)), and
    /// the point, at command `q` under `load`: column `i` is the joint Jacobian's column at the
    /// deflected angles times the torque on joint `i`.
    pub fn jacobian(&self, robot: &Robot, q: &[f64], load: f64) -> (Vector3<f64>, Matrix3xX<f64>) {
        let t = self.torques(robot, q, load);
        let qd = self.deflected(robot, q, load);
        let mut jac = robot.joint_jacobian(&qd);
        for (i, t) in t.iter().enumerate() {
            jac.column_mut(i).scale_mut(*t);
        }
        (robot.point(&qd), jac)
    }

    /// Parses `compliance.toml` for a robot with `dof` joints.
    pub fn from_toml_str(text: &str, path: impl AsRef<Path>, dof: usize) -> Result<Self> {
        let path = path.as_ref();
        let raw: RawCompliance = toml::from_str(text).map_err(|e| toml_error(path, text, &e))?;
        let invalid = |key: &str, message: String| RobotError::InvalidValue {
            path: path.to_path_buf(),
            key: key.into(),
            message,
        };
        if raw.compliance.len() != dof {
            return Err(invalid(
                "compliance",
                format!(
                    "{} values for a robot with {dof} joints",
                    raw.compliance.len()
                ),
            ));
        }
        for (key, values) in [
            ("gravity", &raw.gravity[..]),
            ("payload_com", &raw.payload_com[..]),
            ("compliance", &raw.compliance[..]),
        ] {
            if values.iter().any(|v| !v.is_finite()) {
                return Err(invalid(key, "every value must be a finite number".into()));
            }
        }
        if raw.gravity.iter().all(|g| *g == 0.0) {
            return Err(invalid("gravity", "must not be zero".into()));
        }
        Ok(Self {
            values: raw.compliance.iter().map(|c| c * DEG_PER_KNM).collect(),
            gravity: Vector3::from(raw.gravity),
            payload_com: Vector3::from(raw.payload_com),
        })
    }

    /// Reads `compliance.toml` for a robot with `dof` joints.
    pub fn load(path: impl AsRef<Path>, dof: usize) -> Result<Self> {
        let path = path.as_ref();
        let text = std::fs::read_to_string(path).map_err(|source| RobotError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        Self::from_toml_str(&text, path, dof)
    }

    /// The file form, with a header saying what the numbers mean.
    pub fn to_toml_string(&self) -> String {
        let raw = RawCompliance {
            gravity: self.gravity.into(),
            payload_com: self.payload_com.into(),
            compliance: self.values.iter().map(|c| c / DEG_PER_KNM).collect(),
        };
        let body = toml::to_string(&raw).unwrap_or_default();
        format!(
            "# Joint compliance under the payload, identified by robocal: joint deflection =\n\
             # compliance × gravity torque of the payload (deg per kN·m, one per joint; 0 = rigid).\n\
             # gravity: m/s² in the robot base frame {{0}}; payload_com: mm in the flange frame.\n{body}"
        )
    }
}
