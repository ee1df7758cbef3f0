//! Closed-form rigid registration (Kabsch / Horn, by SVD): where the robot base stands in the
//! tracker frame, from nominal predictions and measured points, wherever the tracker is.

use nalgebra::{Matrix3, Vector3};
use robocal_robot::{Base, Robot, matrix_to_rpy};

use crate::error::{IdentError, Result};
use crate::problem::Observations;

/// The rotation `R` and translation `t` minimising `Σ |R a_i + t − b_i|²` (proper rotation).
pub fn kabsch(a: &[Vector3<f64>], b: &[Vector3<f64>]) -> Result<(Matrix3<f64>, Vector3<f64>)> {
    if a.len() != b.len() || a.is_empty() {
        return Err(IdentError::Registration(
            "needs matching, non-empty point sets".into(),
        ));
    }
    let n = a.len() as f64;
    let ca = a.iter().sum::<Vector3<f64>>() / n;
    let cb = b.iter().sum::<Vector3<f64>>() / n;
    let h: Matrix3<f64> = a
        .iter()
        .zip(b)
        .map(|(p, q)| (p - ca) * (q - cb).transpose())
        .sum();
    let svd = h.svd(true, true);
    let (Some(u), Some(vt)) = (svd.u, svd.v_t) else {
        return Err(IdentError::Registration("SVD failed".into()));
    };
    let v = vt.transpose();
    let d = (v * u.transpose()).determinant().signum();
    let r = v
        * Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, if d == 0.0 { 1.0 } else { d }))
        * u.transpose();
    if !r.iter().all(|x| x.is_finite()) {
        return Err(IdentError::Registration("degenerate point set".into()));
    }
    Ok((r, cb - r * ca))
}

/// `robot` with its base replaced by the rigid registration of its base-frame predictions onto
/// the measured points.
pub fn register_base(robot: &Robot, obs: &Observations) -> Result<Robot> {
    let local = Robot {
        base: Base {
            xyz: Vector3::zeros(),
            rpy: Vector3::zeros(),
        },
        ..robot.clone()
    };
    let predicted: Vec<Vector3<f64>> = (0..obs.len())
        .map(|i| local.for_target(obs.target(&local, i)).point(obs.joints(i)))
        .collect();
    let (r, t) = kabsch(&predicted, &obs.points)?;
    Ok(Robot {
        base: Base {
            xyz: t,
            rpy: matrix_to_rpy(&r),
        },
        ..robot.clone()
    })
}

/// `robot` with its tool frame orientation (`[tool] rpy`) replaced by the rotation that best
/// maps its flange frames onto the measured tool frames of the observations that have one: the
/// chordal mean of `Fᵢᵀ Rᵢ`, projected onto the rotations by SVD. `robot` unchanged when no
/// observation has an orientation or the table declares no tool frame.
pub fn register_tool_rotation(robot: &Robot, obs: &Observations) -> Result<Robot> {
    let oriented = obs.oriented();
    if oriented.is_empty() || robot.tool_rpy.is_none() {
        return Ok(robot.clone());
    }
    let sum: Matrix3<f64> = oriented
        .iter()
        .filter_map(|&i| {
            let measured = obs.orientation(i)?;
            Some(robot.flange_frame(obs.joints(i)).0.transpose() * measured)
        })
        .sum();
    let svd = sum.svd(true, true);
    let (Some(u), Some(vt)) = (svd.u, svd.v_t) else {
        return Err(IdentError::Registration("SVD failed".into()));
    };
    let d = (u * vt).determinant().signum();
    let r =
        u * Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, if d == 0.0 { 1.0 } else { d })) * vt;
    if !r.iter().all(|x| x.is_finite()) {
        return Err(IdentError::Registration("degenerate orientations".into()));
    }
    Ok(Robot {
        tool_rpy: Some(matrix_to_rpy(&r)),
        ..robot.clone()
    })
}
