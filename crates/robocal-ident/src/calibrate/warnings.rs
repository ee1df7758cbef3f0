//! The warnings of a fit: ill-conditioned, far from the nominal table, barely determined,
//! poorly fitting.

use super::report::ParameterReport;
use crate::problem::Observations;
use robocal_robot::{ParamId, Unit};

/// Condition number of the scaled Jacobian above which the report warns.
pub const ILL_CONDITIONED: f64 = 1e5;

/// How far (mm, and 10 % of the nominal value) an identified link length may move from the
/// robot file before the report warns.
pub const FAR_FROM_NOMINAL: f64 = 10.0;

/// Mean error (mm) the identified model may leave before the report warns that the data and
/// the robot file do not describe the same arm: a kinematic calibration leaves well under a
/// millimetre on a real arm, elastic and gear effects a few tenths.
pub const POOR_FIT: f64 = 5.0;

/// Warnings about the data and the fit: too few distinct poses for the parameters, an
/// ill-conditioned problem, a model that still misses the points by more than a calibration
/// should.
pub(super) fn fit_warnings(
    obs: &Observations,
    parameters: usize,
    condition_number: f64,
    mean_after: f64,
) -> Vec<String> {
    let mut warnings = Vec::new();
    let distinct = |rows: &mut dyn Iterator<Item = usize>| {
        let mut d: Vec<&[f64]> = rows.map(|i| obs.joints(i)).collect();
        d.sort_by(|a, b| a.partial_cmp(b).unwrap_or(std::cmp::Ordering::Equal));
        d.dedup();
        d.len()
    };
    let configurations = distinct(&mut (0..obs.len()));
    // A 6-DoF probe's orientation adds three equations per configuration that has one.
    let equations = 3 * configurations + 3 * distinct(&mut obs.oriented().into_iter());
    if equations < parameters {
        warnings.push(format!(
            "only {configurations} distinct joint configurations ({equations} equations) for {parameters} parameters: most cannot be determined; measure more, and more varied, poses"
        ));
    }
    if condition_number > ILL_CONDITIONED {
        warnings.push(format!(
            "ill-conditioned: the scaled Jacobian's condition number is {:.1e}; the identified values are sensitive to noise (spread the poses over the joint ranges)",
            condition_number
        ));
    }
    if mean_after > POOR_FIT {
        warnings.push(format!(
            "the identified model still misses the measured points by {:.4} mm on average (more than {POOR_FIT} mm): the data and the robot file do not describe the same arm; check the units (mm, deg), the joint order and signs, the measured point (the robot file's tool point) and the tracker frame",
            mean_after
        ));
    }
    warnings
}

/// Standard deviations a far move must exceed to count as determined by the data.
pub const FAR_SIGMAS: f64 = 3.0;

/// Identified link lengths that moved more than [`FAR_FROM_NOMINAL`] mm and 10 % from the
/// robot file, by more than [`FAR_SIGMAS`] standard deviations: the data are in other units (a
/// table scaled with them fits exactly), or the robot file is not this arm's. A move within its
/// uncertainty says only that the poses barely determine the parameter
/// ([`poorly_determined`]). Base, tool and named points are frames whose nominal values are
/// guesses, so they are left out. `ids` are the table's parameters, in the order of
/// `parameters`.
pub fn far_from_nominal<'a>(
    parameters: &'a [ParameterReport],
    ids: &[ParamId],
) -> Vec<&'a ParameterReport> {
    far_moves(parameters, ids)
        .filter(|p| p.std.is_none_or(|s| p.delta.abs() > FAR_SIGMAS * s))
        .collect()
}

/// Identified link lengths that moved as far as [`far_from_nominal`] says, but within
/// [`FAR_SIGMAS`] standard deviations: the poses barely determine them.
pub fn poorly_determined<'a>(
    parameters: &'a [ParameterReport],
    ids: &[ParamId],
) -> Vec<&'a ParameterReport> {
    far_moves(parameters, ids)
        .filter(|p| p.std.is_some_and(|s| p.delta.abs() <= FAR_SIGMAS * s))
        .collect()
}

/// Identified link lengths (not frames) more than [`FAR_FROM_NOMINAL`] mm and 10 % from the
/// robot file.
pub(super) fn far_moves<'a>(
    parameters: &'a [ParameterReport],
    ids: &[ParamId],
) -> impl Iterator<Item = &'a ParameterReport> {
    parameters
        .iter()
        .zip(ids)
        .filter(|(p, id)| {
            p.identified_flag
                && id.unit() == Unit::Mm
                && !matches!(
                    id,
                    ParamId::Base(_)
                        | ParamId::Tool(_)
                        | ParamId::ToolRot(_)
                        | ParamId::Point { .. }
                )
                && p.delta.abs() > FAR_FROM_NOMINAL.max(0.1 * p.nominal.abs())
        })
        .map(|(p, _)| p)
}
