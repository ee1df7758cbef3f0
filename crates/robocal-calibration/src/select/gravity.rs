//! Gravity and the default: the mounting decided once before the candidates, and the residual
//! models' frames where joint 1 lies off the line of gravity.

use super::physics::{Effect, Physics};
use super::settings::AutoSettings;
use crate::rows::loads;
use nalgebra::Vector3;
use robocal_data::Measurement;
use robocal_ident::{
    ComplianceSettings, KinematicSettings, MOUNTING_ANGLE_DEG, Observations, calibrate_kinematics,
    tracker_down,
};
use robocal_residual::{Frame, ResidualStage};
use robocal_robot::Robot;

/// How far (deg) joint 1's axis may lie from the line of gravity (either way along it: an arm
/// on a ceiling stands along it too) before the default also tries its residual models in the
/// world frame ([`AutoSettings::both_frames_off_gravity`]). At 10° a sixth of gravity turns with
/// joint 1; the twins stand at 0° (floor and ceiling), 45° (ARM6T) and 90° (ARM5W, ARM6W).
pub const JOINT1_GRAVITY_ANGLE_DEG: f64 = 10.0;

/// The angle (deg, 0–90) between joint 1's axis in `robot`'s table and the line of `gravity`
/// (base frame {0}); `None` for a robot without joints or a zero gravity.
pub fn joint1_gravity_angle(robot: &Robot, gravity: &Vector3<f64>) -> Option<f64> {
    // Joint 1's axis in the base frame: the world axis turned back by the base's rotation (so
    // the base's pose in the tracker frame does not matter).
    let axis = robot.base_rotation().transpose() * robot.joint1_axis()?;
    let cos = axis.dot(gravity).abs() / (axis.norm() * gravity.norm());
    cos.is_finite().then(|| cos.min(1.0).acos().to_degrees())
}

/// The residual models the default tries on `nominal` with `gravity` (base frame): `settings`'
/// own, and where [`AutoSettings::both_frames_off_gravity`] asks it and joint 1 lies more than
/// [`JOINT1_GRAVITY_ANGLE_DEG`] from gravity, each one in the frame turning with joint 1 again
/// in the world frame, after them all.
pub fn residual_stages(
    settings: &AutoSettings,
    nominal: &Robot,
    gravity: &Vector3<f64>,
) -> Vec<ResidualStage> {
    let mut stages = settings.residuals.clone();
    let off = joint1_gravity_angle(nominal, gravity).is_some_and(|a| a > JOINT1_GRAVITY_ANGLE_DEG);
    if settings.both_frames_off_gravity && off {
        let world = (settings.residuals.iter())
            .filter(|s| s.settings.frame == Frame::Joint1)
            .map(|s| {
                let mut s = s.clone();
                s.settings.frame = Frame::World;
                s
            })
            .collect::<Vec<_>>();
        stages.extend(world);
    }
    stages
}

/// Gravity for an arm whose registered base is more than [`MOUNTING_ANGLE_DEG`] from upright
/// (on a wall or a ceiling), when the rows hold two or more loads: the base's −z or a levelled
/// tracker's −z, whichever a fit with the compliances on every row fits better
/// ([`ComplianceSettings::detect_mounting`]), and the warning that fit gave when it took the
/// tracker's. `None` for an upright arm (each fit keeps the base's −z) or where no fit can tell.
/// The fit's work is counted on `work`.
pub(super) fn mounting(
    settings: &AutoSettings,
    nominal: &Robot,
    rows: &[&Measurement],
    work: &robocal_ident::Work,
) -> Option<(Vector3<f64>, Option<String>)> {
    if loads(rows).len() < 2 {
        return None;
    }
    let obs = Observations::from_rows(nominal.dof(), rows.iter().copied());
    let (_, angle) = tracker_down(nominal, &obs, &ComplianceSettings::default().gravity).ok()?;
    if angle <= MOUNTING_ANGLE_DEG {
        return None;
    }
    let physics = Physics::RIGID.with(Effect::Compliance);
    let counted = KinematicSettings {
        work: Some(work.clone()),
        ..physics.settings(settings)
    };
    let fit = calibrate_kinematics(nominal, &obs, &counted).ok()?;
    Some((fit.compliance?.gravity, fit.report.mounting_warning))
}
