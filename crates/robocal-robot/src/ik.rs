//! Numerical inverse kinematics: damped least squares with adaptive damping (Levenberg–Marquardt),
//! joint limits enforced by clamping, starting at (and ending nearest to) a seed.

use std::f64::consts::{PI, TAU};

use nalgebra::{DMatrix, DVector, Matrix3, Rotation3, Vector3};

use crate::error::{Result, RobotError};
use crate::kinematics::JointAxes;
use crate::table::Robot;

/// What the inverse kinematics must reach, world frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum IkTarget {
    /// The target (tool) point at a position, mm; orientation free.
    Point(Vector3<f64>),
    /// The target point at `point` (mm) with the flange frame at `rotation`.
    Pose {
        /// Target point position, mm, world frame.
        point: Vector3<f64>,
        /// Flange orientation in the world frame.
        rotation: Matrix3<f64>,
    },
}

/// Settings of [`Robot::inverse_kinematics`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct IkOptions {
    /// Iteration budget (accepted and rejected steps together).
    pub max_iterations: usize,
    /// Largest position error accepted as a solution, mm.
    pub position_tolerance: f64,
    /// Largest orientation error accepted as a solution, rad.
    pub orientation_tolerance: f64,
    /// Length that weighs one radian of orientation error against one mm of position error.
    pub orientation_scale: f64,
}

impl Default for IkOptions {
    fn default() -> Self {
        Self {
            max_iterations: 500,
            position_tolerance: 1e-7,
            orientation_tolerance: 1e-9,
            orientation_scale: 1000.0,
        }
    }
}

struct Residual {
    e: DVector<f64>,
    position: f64,
    orientation: f64,
}

/// Rotation vector (axis × angle, rad) of a rotation matrix, accurate near the identity, where
/// an angle taken from `acos` of the trace resolves only about 1e-8 rad.
pub fn rotation_vector(r: &Matrix3<f64>) -> Vector3<f64> {
    let s = 0.5
        * Vector3::new(
            r[(2, 1)] - r[(1, 2)],
            r[(0, 2)] - r[(2, 0)],
            r[(1, 0)] - r[(0, 1)],
        );
    let c = 0.5 * (r.trace() - 1.0);
    let sin = s.norm();
    if c > 0.0 {
        // |angle| < 90°: atan2 is exact at small angles, and s → angle · axis there.
        if sin < 1e-300 {
            s
        } else {
            s * (sin.atan2(c) / sin)
        }
    } else {
        Rotation3::from_matrix_unchecked(*r).scaled_axis()
    }
}

impl Robot {
    fn clamp_to_limits(&self, q: &mut [f64]) {
        for (v, j) in q.iter_mut().zip(&self.joints) {
            if let Some((lo, hi)) = j.limits {
                *v = v.clamp(lo, hi);
            }
        }
    }

    fn ik_residual(&self, target: &IkTarget, q: &[f64], scale: f64) -> Residual {
        let (r, o) = self.flange_frame(q);
        let p = o + r * self.tool;
        match target {
            IkTarget::Point(t) => {
                let dp = t - p;
                Residual {
                    position: dp.norm(),
                    orientation: 0.0,
                    e: DVector::from_column_slice(dp.as_slice()),
                }
            }
            IkTarget::Pose { point, rotation } => {
                let dp = point - p;
                let dr = rotation_vector(&(rotation * r.transpose()));
                let mut e = DVector::zeros(6);
                e.fixed_rows_mut::<3>(0).copy_from(&dp);
                e.fixed_rows_mut::<3>(3).copy_from(&(dr * scale));
                Residual {
                    position: dp.norm(),
                    orientation: dr.norm(),
                    e,
                }
            }
        }
    }

    fn ik_jacobian(&self, target: &IkTarget, q: &[f64], scale: f64) -> DMatrix<f64> {
        let JointAxes { axes, point: p, .. } = self.joint_axes(q);
        let rows = match target {
            IkTarget::Point(_) => 3,
            IkTarget::Pose { .. } => 6,
        };
        let mut jac = DMatrix::zeros(rows, self.dof());
        for (i, (w, o)) in axes.iter().enumerate() {
            jac.fixed_view_mut::<3, 1>(0, i)
                .copy_from(&w.cross(&(p - o)));
            if rows == 6 {
                jac.fixed_view_mut::<3, 1>(3, i).copy_from(&(w * scale));
            }
        }
        jac
    }

    /// Joint readings (rad) that put the target point (and, for [`IkTarget::Pose`], the flange
    /// orientation) at `target`, found by damped least squares from `seed` and kept within the
    /// joint limits. Among equivalent readings (±2π on a joint) the one nearest the seed is
    /// returned. Fails with [`RobotError::IkNotConverged`] rather than return a wrong answer.
    pub fn inverse_kinematics(
        &self,
        target: &IkTarget,
        seed: &[f64],
        options: &IkOptions,
    ) -> Result<Vec<f64>> {
        self.check_joints(seed)?;
        let scale = options.orientation_scale;
        let mut q = seed.to_vec();
        self.clamp_to_limits(&mut q);
        let mut res = self.ik_residual(target, &q, scale);
        let mut lambda: Option<f64> = None;
        let converged = |r: &Residual| {
            r.position <= options.position_tolerance
                && r.orientation <= options.orientation_tolerance
        };
        let n = self.dof();
        let mut iterations = 0;
        let mut stalled = 0;
        while iterations < options.max_iterations && !converged(&res) && stalled < 8 {
            let jac = self.ik_jacobian(target, &q, scale);
            let jtj = jac.transpose() * &jac;
            let jte = jac.transpose() * &res.e;
            let lam = *lambda.get_or_insert_with(|| 1e-6 * jtj.diagonal().max().max(1e-12));
            let mut accepted = false;
            let mut mu = lam;
            while iterations < options.max_iterations {
                iterations += 1;
                let mut a = jtj.clone();
                for i in 0..n {
                    a[(i, i)] += mu;
                }
                let Some(chol) = a.cholesky() else {
                    mu *= 10.0;
                    continue;
                };
                let dq = chol.solve(&jte);
                let mut trial: Vec<f64> = q.iter().zip(dq.iter()).map(|(a, b)| a + b).collect();
                self.clamp_to_limits(&mut trial);
                let trial_res = self.ik_residual(target, &trial, scale);
                if trial_res.e.norm_squared() < res.e.norm_squared() {
                    // A minimum that is not a solution (an unreachable target) shows as steps
                    // that barely lower the error: give up after a few of them.
                    let gain = 1.0 - trial_res.e.norm_squared() / res.e.norm_squared();
                    stalled = if gain < 1e-6 { stalled + 1 } else { 0 };
                    q = trial;
                    res = trial_res;
                    lambda = Some((mu / 10.0).max(1e-15));
                    accepted = true;
                    break;
                }
                mu *= 10.0;
                if mu > 1e12 * lam.max(1.0) {
                    break;
                }
            }
            if !accepted {
                break;
            }
        }
        if !converged(&res) || q.iter().any(|v| !v.is_finite()) {
            return Err(RobotError::IkNotConverged {
                position_error: res.position,
                orientation_error: res.orientation.to_degrees(),
                iterations,
            });
        }
        self.nearest_equivalent(&mut q, seed);
        Ok(q)
    }

    /// Moves each joint by whole turns towards the seed where the limits allow it.
    fn nearest_equivalent(&self, q: &mut [f64], seed: &[f64]) {
        for ((v, &s), j) in q.iter_mut().zip(seed).zip(&self.joints) {
            let turns = ((*v - s + PI) / TAU).floor();
            let candidate = *v - turns * TAU;
            let allowed = j
                .limits
                .is_none_or(|(lo, hi)| candidate >= lo && candidate <= hi);
            if allowed {
                *v = candidate;
            }
        }
    }
}
