//! Compensation: for a target position, a seed command and a load, the joint command for which
//! the calibrated model (identified kinematics, joint compliance under that load and the
//! residual model) puts the target point on the target.
//!
//! The residual model and the deflection depend on the command, so the command is found by a
//! fixed-point iteration: solve the kinematics for the arm's real angles that put the point at
//! `target − residual(q_k)` by damped least squares (from `q_k` deflected; the seed first), take
//! off the deflection at `q_k`, then re-evaluate residual and deflection at the new command,
//! until the whole model's error is below the tolerance. With six or more joints the flange orientation the
//! calibrated kinematics give at the seed is kept (the program's tool orientation stays as it
//! was; only the position is corrected), so the answer is the command nearest the seed with
//! that orientation; with fewer joints the orientation is left free.
//!
//! ```
//! use nalgebra::Vector3;
//! use robocal_compensate::{CompensationOptions, compensate};
//! use robocal_model::CalibratedModel;
//! use robocal_robot::Robot;
//!
//! let robot = Robot::from_toml_str(
//!     "name = \"planar\"\n[base]\nxyz = [0, 0, 0]\nrpy = [0, 0, 0]\n[tool]\nxyz = [100, 0, 0]\n\
//!      [[joint]]\na = 0\nalpha = 0\nd = 0\ntheta = 0\n[[joint]]\na = 300\nalpha = 0\nd = 0\ntheta = 0\n",
//!     "planar.toml",
//! )?;
//! let seed = [10.0, 20.0];
//! let target = Vector3::new(350.0, 120.0, 0.0);
//! let model = CalibratedModel::kinematic(robot.clone());
//! let c = compensate(&model, &target, 0.0, &seed, &CompensationOptions::default()).unwrap();
//! let q: Vec<f64> = c.joints_deg.iter().map(|d| d.to_radians()).collect();
//! assert!((robot.point(&q) - target).norm() < 1e-3);
//! # Ok::<(), robocal_robot::RobotError>(())
//! ```

mod error;

pub use error::Failure;
use nalgebra::Vector3;
use robocal_model::CalibratedModel;
use robocal_robot::{IkOptions, IkTarget};
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

/// The joint command (deg) near `seed_deg` for which `model` puts the target point at `target`
/// (mm, world frame) under `load` (kg).
pub fn compensate(
    model: &CalibratedModel,
    target: &Vector3<f64>,
    load: f64,
    seed_deg: &[f64],
    options: &CompensationOptions,
) -> Result<Compensation, Failure> {
    let robot = &model.robot;
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
    if !target.iter().all(|v| v.is_finite()) {
        return Err(Failure::BadSeed("the target is not finite".into()));
    }
    let seed: Vec<f64> = seed_deg.iter().map(|d| d.to_radians()).collect();
    let keep_orientation = robot.dof() >= 6;
    let add = |a: &[f64], b: &[f64]| -> Vec<f64> { a.iter().zip(b).map(|(a, b)| a + b).collect() };
    // The orientation the model gives the flange at the seed, under the load.
    let rotation = robot
        .flange_frame(&add(&seed, &model.deflection(&seed, load)))
        .0;
    let ik = IkOptions {
        // The kinematic solve only needs to be well inside the model tolerance.
        position_tolerance: options.tolerance * 1e-2,
        ..IkOptions::default()
    };
    // The residual (with the bearings' tilts and the axis runouts, which move the point but
    // turn no joint) and the deflection at the current command, evaluated once per iteration:
    // they set the next aim and, with the kinematics, the model's error there.
    let offset = |q: &[f64]| model.residual_at(q, load) + model.turn_offset(q, load);
    let mut q = seed;
    let mut r = offset(&q);
    let mut bend = model.deflection(&q, load);
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
        // Solve for the angles the arm must really take, then take off the deflection the
        // load gives at the command.
        let actual = match robot.inverse_kinematics(&goal, &add(&q, &bend), &ik) {
            Ok(actual) => actual,
            Err(_) => {
                return Err(Failure::Unreachable {
                    model_error: (model.point(&q, load) - target).norm(),
                    limited: robot.joints.iter().any(|j| j.limits.is_some()),
                });
            }
        };
        let next: Vec<f64> = actual.iter().zip(&bend).map(|(a, b)| a - b).collect();
        if !robot.within_limits(&next) {
            return Err(Failure::BeyondLimits {
                model_error: (model.point(&next, load) - target).norm(),
            });
        }
        q = next;
        r = offset(&q);
        bend = model.deflection(&q, load);
        error = (robot.point(&add(&q, &bend)) + r - target).norm();
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
