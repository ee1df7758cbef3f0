//! The frames a fit starts from: the registration's alignment of the tracker's frame with the
//! robot's, gravity's direction in it, and which parameters the reflectors tell apart.

use super::settings::KinematicSettings;
use crate::error::Result;
use crate::identifiability::{Column, Identifiability, analyse};
use crate::lm::run_lm;
use crate::problem::{CalibrationProblem, LeastSquares, Observations};
use crate::registration::{register_base, register_tool_rotation};
use faer::Mat;
use nalgebra::Vector3;
use robocal_robot::{ParamId, Robot};

/// Indices of the parameters of `robot` that satisfy `keep`.
pub(super) fn indices(robot: &Robot, keep: impl Fn(ParamId) -> bool) -> Vec<usize> {
    (robot.param_ids().into_iter().enumerate())
        .filter(|&(_, id)| keep(id))
        .map(|(i, _)| i)
        .collect()
}

/// The tracker's −z with the length of `gravity`, in the base frame `nominal` registers to from
/// `obs` ([`align`]), and its angle (degrees) from `gravity` (base frame): how far from upright
/// the arm stands if the tracker is levelled. Beyond [`MOUNTING_ANGLE_DEG`] the arm is taken
/// to hang on a wall or a ceiling, and the data decide which of the two gravity is.
///
/// [`MOUNTING_ANGLE_DEG`]: super::MOUNTING_ANGLE_DEG
pub fn tracker_down(
    nominal: &Robot,
    obs: &Observations,
    gravity: &Vector3<f64>,
) -> Result<(Vector3<f64>, f64)> {
    Ok(down_of_aligned(&align(nominal, obs)?, gravity))
}

/// [`tracker_down`] from the aligned table.
pub(super) fn down_of_aligned(aligned: &Robot, gravity: &Vector3<f64>) -> (Vector3<f64>, f64) {
    let down = aligned.base_rotation().transpose() * -Vector3::z() * gravity.norm();
    (down, down.angle(gravity).to_degrees())
}

/// Fits only the base and tool of `robot` (after a closed-form registration of the base):
/// the "before calibration" model of a tracker's best-fit alignment.
pub fn align(robot: &Robot, obs: &Observations) -> Result<Robot> {
    let registered = register_tool_rotation(&register_base(robot, obs)?, obs)?;
    // Tool (and the named points) first (base held), then base and tool together.
    let tool = indices(&registered, |id| {
        matches!(
            id,
            ParamId::Tool(_) | ParamId::ToolRot(_) | ParamId::Point { .. }
        )
    });
    let frame = indices(&registered, |id| {
        matches!(
            id,
            ParamId::Base(_) | ParamId::Tool(_) | ParamId::ToolRot(_) | ParamId::Point { .. }
        )
    });
    let mut current = registered;
    for sel in [tool, frame] {
        let problem = CalibrationProblem::new(&current, sel, obs);
        let k = problem.unknowns();
        let (u, _, _) = run_lm(LeastSquares(&problem), vec![0.0; k], 100)?;
        current = problem.robot_at(&u);
    }
    Ok(current)
}

/// The parameters `ident` identifies that the rows of the default reflector alone (`jac`'s rows
/// of observations without a target) would not: what the extra reflectors buy. Empty when no
/// row names a target.
pub(super) fn by_reflectors(
    obs: &Observations,
    jac: &Mat<f64>,
    columns: &[Column],
    ident: &Identifiability,
    settings: &KinematicSettings,
) -> Vec<String> {
    if obs.targets.iter().all(String::is_empty) {
        return Vec::new();
    }
    let rows: Vec<usize> = (0..obs.len())
        .filter(|&i| obs.targets[i].is_empty())
        .flat_map(|i| 3 * i..3 * i + 3)
        .collect();
    let alone = Mat::from_fn(rows.len(), jac.ncols(), |r, c| jac[(rows[r], c)]);
    let alone = analyse(&alone, columns, settings.rank_tolerance);
    (ident.identifiable.iter())
        .filter(|p| !alone.identifiable.contains(p))
        .filter(|&&p| !matches!(columns[p], Column::Param(ParamId::Point { .. })))
        .map(|&p| columns[p].to_string())
        .collect()
}
