//! The identification of a stage's kinematics on rows, and the physical model it makes.

use crate::error::Result;
use crate::rows::lightest_load_rows;
use robocal_data::Measurement;
use robocal_ident::{
    FitMemo, KinematicCalibration, KinematicSettings, Observations, calibrate_kinematics_with,
};
use robocal_model::CalibratedModel;
use robocal_robot::Robot;

/// The geometric (and elastic) model of an identification, without a residual model, with its
/// parameters' covariance.
pub fn physical_model(calibration: &KinematicCalibration) -> CalibratedModel {
    CalibratedModel {
        covariance: calibration.covariance.clone(),
        ..CalibratedModel::new(
            calibration.robot.clone(),
            calibration.compliance.clone(),
            None,
        )
    }
}

/// Identifies the kinematic stage from `rows`: a rigid stage from the rows at the lightest load
/// (geometry alone, as in the paper), an elasto-geometric one from every row.
pub fn fit_kinematic(
    nominal: &Robot,
    rows: &[&Measurement],
    settings: &KinematicSettings,
) -> Result<KinematicCalibration> {
    fit_kinematic_with(nominal, rows, settings, &FitMemo::default())
}

/// [`fit_kinematic`], sharing with the other fits of the same rows the alignments and
/// identifications `memo` remembers ([`robocal_ident::calibrate_kinematics_with`]: the same
/// results, bit for bit).
pub fn fit_kinematic_with(
    nominal: &Robot,
    rows: &[&Measurement],
    settings: &KinematicSettings,
    memo: &FitMemo,
) -> Result<KinematicCalibration> {
    let obs = if settings.compliance.is_some() {
        Observations::from_rows(nominal.dof(), rows.iter().copied())
    } else {
        Observations::from_rows(nominal.dof(), lightest_load_rows(rows).into_iter())
    };
    Ok(calibrate_kinematics_with(nominal, &obs, settings, memo)?)
}
