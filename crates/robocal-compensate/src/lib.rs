//! Compensation: for a target position, a seed command and a load, the joint command for which
//! the calibrated model (identified kinematics plus the residual model, under that load) puts
//! the target point on the target.
//!
//! The residual model depends on the command, so the command is found by a fixed-point
//! iteration: solve the kinematics for `target − residual(q_k)` by damped least squares from
//! `q_k` (the seed first), then re-evaluate the residual at the new command, until the whole
//! model's error is below the tolerance. With six or more joints the flange orientation the
//! calibrated kinematics give at the seed is kept (the program's tool orientation stays as it
//! was; only the position is corrected), so the answer is the command nearest the seed with
//! that orientation; with fewer joints the orientation is left free.
//!
//! ```
//! use nalgebra::Vector3;
//! use robocal_compensate::{CompensationOptions, compensate};
//! use robocal_robot::Robot;
//!
//! let robot = Robot::from_toml_str(
//!     "name = \"planar\"\n[base]\nxyz = [0, 0, 0]\nrpy = [0, 0, 0]\n[tool]\nxyz = [100, 0, 0]\n\
//!      [[joint]]\na = 0\nalpha = 0\nd = 0\ntheta = 0\n[[joint]]\na = 300\nalpha = 0\nd = 0\ntheta = 0\n",
//!     "planar.toml",
//! )?;
//! let seed = [10.0, 20.0];
//! let target = Vector3::new(350.0, 120.0, 0.0);
//! let c = compensate(&robot, None, &target, 0.0, &seed, &CompensationOptions::default()).unwrap();
//! let q: Vec<f64> = c.joints_deg.iter().map(|d| d.to_radians()).collect();
//! assert!((robot.point(&q) - target).norm() < 1e-3);
//! # Ok::<(), robocal_robot::RobotError>(())
//! ```

use nalgebra::Vector3;
use robocal_residual::ResidualModel;
use robocal_robot::{IkOptions, IkTarget, Robot};
use serde::Serialize;

/// Settings of [`compensate`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CompensationOptions {
    /// Largest error of the model's point from the target accepted, mm.
    pub tolerance: f64,
    /// Most fixed-point iterations (each a kinematic solve and a residual evaluation).
    pub max_iterations: usize,
}

impl Default for CompensationOptions {
    fn default() -> Self {
        Self {
            tolerance: 1e-3,
            max_iterations: 20,
        }
    }
}

/// A compensated command.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Compensation {
    /// Joint command, deg.
    pub joints_deg: Vec<f64>,
    /// Distance of the model's point from the target at this command, mm.
    pub model_error: f64,
    /// Fixed-point iterations used.
    pub iterations: usize,
}

/// Why a target could not be compensated.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub enum Failure {
    /// The seed has the wrong number of joints or a non-finite value.
    BadSeed(String),
    /// The kinematic solve did not reach the point (unreachable, or only beyond the limits).
    Unreachable {
        /// Error of the model's point after the last attempt, mm.
        model_error: f64,
    },
    /// The fixed-point iteration did not bring the model's error below the tolerance.
    NotConverged {
        /// Error of the model's point after the last iteration, mm.
        model_error: f64,
    },
}

impl std::fmt::Display for Failure {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::BadSeed(m) => write!(f, "bad seed: {m}"),
            Self::Unreachable { model_error } => write!(
                f,
                "not reachable within the joint limits (model error {model_error:.4} mm)"
            ),
            Self::NotConverged { model_error } => write!(
                f,
                "did not converge (model error {model_error:.4} mm after the last iteration)"
            ),
        }
    }
}

/// The residual model's predicted error at a command (deg) and load, mm (zero without one).
fn residual_at(residual: Option<&ResidualModel>, q_deg: &[f64], load: f64) -> Vector3<f64> {
    match residual {
        Some(r) => {
            let mut row = q_deg.to_vec();
            row.push(load);
            Vector3::from(r.predict(&[row])[0])
        }
        None => Vector3::zeros(),
    }
}

/// The whole model's predicted point at a command (rad) and load, mm, world frame.
pub fn model_point(
    robot: &Robot,
    residual: Option<&ResidualModel>,
    q: &[f64],
    load: f64,
) -> Vector3<f64> {
    let deg: Vec<f64> = q.iter().map(|v| v.to_degrees()).collect();
    robot.point(q) + residual_at(residual, &deg, load)
}

/// The joint command (deg) near `seed_deg` for which `robot` plus `residual` put the target
/// point at `target` (mm, world frame) under `load` (kg).
pub fn compensate(
    robot: &Robot,
    residual: Option<&ResidualModel>,
    target: &Vector3<f64>,
    load: f64,
    seed_deg: &[f64],
    options: &CompensationOptions,
) -> Result<Compensation, Failure> {
    if seed_deg.len() != robot.dof() {
        return Err(Failure::BadSeed(format!(
            "{} joint values for a robot with {} joints",
            seed_deg.len(),
            robot.dof()
        )));
    }
    if seed_deg.iter().any(|v| !v.is_finite()) || !load.is_finite() {
        return Err(Failure::BadSeed("a value is not finite".into()));
    }
    let seed: Vec<f64> = seed_deg.iter().map(|d| d.to_radians()).collect();
    let keep_orientation = robot.dof() >= 6;
    let rotation = robot.flange_frame(&seed).0;
    let ik = IkOptions {
        // The kinematic solve only needs to be well inside the model tolerance.
        position_tolerance: options.tolerance * 1e-2,
        ..IkOptions::default()
    };
    // The residual at the current command, evaluated once per iteration: it sets the next aim
    // and, with the kinematics, the model's error there.
    let at = |q: &[f64]| {
        let deg: Vec<f64> = q.iter().map(|v| v.to_degrees()).collect();
        residual_at(residual, &deg, load)
    };
    let mut r = at(&seed);
    let mut q = seed;
    let mut error = f64::INFINITY;
    for iteration in 1..=options.max_iterations {
        let aim = target - r;
        let goal = if keep_orientation {
            IkTarget::Pose {
                point: aim,
                rotation,
            }
        } else {
            IkTarget::Point(aim)
        };
        let next = match robot.inverse_kinematics(&goal, &q, &ik) {
            Ok(next) => next,
            Err(_) => {
                return Err(Failure::Unreachable {
                    model_error: (robot.point(&q) + r - target).norm(),
                });
            }
        };
        if !robot.within_limits(&next) {
            return Err(Failure::Unreachable {
                model_error: (model_point(robot, residual, &next, load) - target).norm(),
            });
        }
        q = next;
        r = at(&q);
        error = (robot.point(&q) + r - target).norm();
        if error < options.tolerance {
            return Ok(Compensation {
                joints_deg: q.iter().map(|v| v.to_degrees()).collect(),
                model_error: error,
                iterations: iteration,
            });
        }
    }
    Err(Failure::NotConverged { model_error: error })
}
