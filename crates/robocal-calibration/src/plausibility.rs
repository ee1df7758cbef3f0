//! Data that read well but do not fit the robot file: positions in inches or metres, joint
//! angles in radians, two joint columns swapped. The symptom is a kinematic fit that still misses
//! the points by millimetres, or link lengths that moved far from the drawing; the likely cause
//! is the hypothesis under which a fit of the same data would be plausible.

use robocal_data::Measurement;
use robocal_ident::{
    ComplianceSettings, JointErrorSettings, KinematicCalibration, KinematicSettings, POOR_FIT,
    far_from_nominal,
};
use robocal_robot::Robot;

use crate::error::Result;
use crate::fit::fit_kinematic;
use crate::rows::{configurations, coordinates_and_parameters, lightest_load_rows, loads};

/// Why a calibration is not plausible, and what probably went wrong.
#[derive(Debug, Clone, PartialEq)]
pub struct Implausible {
    /// What was seen.
    pub symptom: String,
    /// The hypothesis that would make the data fit, if one does.
    pub likely_cause: Option<String>,
    /// No more coordinates than parameters: the fit passes through every point, and nothing
    /// tells whether the data fit the robot file.
    pub too_few: bool,
}

impl std::fmt::Display for Implausible {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{}: {}; {}",
            if self.too_few {
                "too few poses to calibrate"
            } else {
                "the data do not fit the robot file"
            },
            self.symptom,
            self.likely_cause
                .as_deref()
                .unwrap_or("check the units (mm, deg), the joint order and signs, the measured point (the robot file's tool) and that the robot file describes this arm")
        )
    }
}

/// Identified link lengths that moved far from the robot file (see [`far_from_nominal`]).
fn far_lengths(fit: &KinematicCalibration, nominal: &Robot) -> Vec<String> {
    far_from_nominal(&fit.report.parameters, &nominal.param_ids())
        .iter()
        .map(|p| format!("{} {:.1} → {:.1} mm", p.name, p.nominal, p.identified))
        .collect()
}

/// Identified joint angles of the table (`alpha`, `theta`, `beta`) that turned by more than a
/// quarter turn from the robot file: the table took a joint whose readings count the other way
/// (an axis reversed fits as well, 180° away), and the physics, which start from the robot
/// file, do not (a wrist joint's readings negated: the default's held-out error 0.068 → 0.335
/// mm on the bundled twin).
fn turned_axes(fit: &KinematicCalibration) -> Vec<String> {
    (fit.report.parameters.iter())
        .filter(|p| p.identified_flag && p.name.starts_with('j'))
        .filter(|p| {
            [".alpha", ".theta", ".beta"]
                .iter()
                .any(|s| p.name.ends_with(s))
        })
        // The turn, wrapped into [−180°, 180°).
        .filter(|p| ((p.delta + 180.0).rem_euclid(360.0) - 180.0).abs() > 90.0)
        .map(|p| format!("{} {:.1} → {:.1}°", p.name, p.nominal, p.identified))
        .collect()
}

/// How much more a fit with the far-moved lengths held at the robot file's values may miss the
/// points, as a share of the free fit's mean error, for the move to count as not needed.
const HELD_SHARE: f64 = 0.25;

/// Whether the far moves of `fit`'s link lengths are ones the data do not need: the same fit
/// with those lengths held at the robot file's values meets the points within [`HELD_SHARE`]
/// more mean error. Biased by effects the model lacks, a length the poses barely separate from
/// others (a wrist offset on a grid of one wrist orientation) can move far by more than its
/// standard deviations, which assume the model right; data in other units need every length
/// scaled, and held they miss by orders of magnitude more.
fn far_moves_not_needed(
    fit: &KinematicCalibration,
    nominal: &Robot,
    rows: &[&Measurement],
) -> bool {
    let far: Vec<&str> = far_from_nominal(&fit.report.parameters, &nominal.param_ids())
        .iter()
        .map(|p| p.name.as_str())
        .collect();
    if far.is_empty() || fit.report.after.mean > POOR_FIT {
        return false;
    }
    let free: Vec<String> = (fit.report.parameters.iter())
        .filter(|p| p.identified_flag && !far.contains(&p.name.as_str()))
        .map(|p| p.name.clone())
        .collect();
    let held = KinematicSettings {
        parameters: Some(free),
        ..KinematicSettings::default()
    };
    fit_kinematic(nominal, rows, &held).is_ok_and(|h| {
        h.report.after.mean <= (1.0 + HELD_SHARE) * fit.report.after.mean
            && turned_axes(&h).is_empty()
    })
}

/// Whether the rigid fit `rigid` of `rows` is plausible, or else the fit with the arm's
/// deflection under its own weight and the payload's is, or else the rigid fit's far-moved
/// lengths are ones the data do not need ([`far_moves_not_needed`]).
fn fits(rigid: &KinematicCalibration, nominal: &Robot, rows: &[&Measurement]) -> bool {
    if plausible(rigid, nominal) {
        return true;
    }
    // A turned axis is no deflection's: the elastic fit, from the same start, may stop short of
    // the turn and still meet the points within the poor-fit bound.
    if !turned_axes(rigid).is_empty() {
        return false;
    }
    if far_moves_not_needed(rigid, nominal, rows) {
        return true;
    }
    let elastic = KinematicSettings {
        compliance: (loads(rows).len() >= 2).then(ComplianceSettings::default),
        joint_errors: Some(JointErrorSettings {
            harmonics: 0,
            self_weight: true,
            ..JointErrorSettings::default()
        }),
        ..KinematicSettings::default()
    };
    fit_kinematic(nominal, rows, &elastic).is_ok_and(|f| plausible(&f, nominal))
}

/// The distinct coordinates the rigid fit `fit` of `rows` had (three per configuration and
/// reflector of its load: [`coordinates_and_parameters`]) and the parameters it identified.
fn redundancy(fit: &KinematicCalibration, rows: &[&Measurement]) -> (usize, usize) {
    coordinates_and_parameters(fit, &lightest_load_rows(rows))
}

/// Whether a fit is plausible: it meets the points within [`POOR_FIT`] mm on average, no link
/// length moved far from the drawing and no joint angle of the table turned half round
/// ([`turned_axes`]).
fn plausible(fit: &KinematicCalibration, nominal: &Robot) -> bool {
    fit.report.after.mean <= POOR_FIT
        && far_lengths(fit, nominal).is_empty()
        && turned_axes(fit).is_empty()
}

/// Checks the rigid kinematic fit of `rows`, and when it is not plausible the fit with the
/// arm's deflection under its own weight and the payload's (a heavy arm's rigid table absorbs
/// it by moving a length the poses barely see: ARM6H's j5.d by 13 mm); when neither is, tries
/// the usual mistakes — positions in inches or metres, joint angles in radians, two joint
/// columns swapped — and names the one under which the data fit.
pub fn check_plausible(nominal: &Robot, rows: &[&Measurement]) -> Result<Option<Implausible>> {
    let settings = KinematicSettings::default();
    let fit = fit_kinematic(nominal, rows, &settings)?;
    if fits(&fit, nominal, rows) {
        return Ok(None);
    }
    // As many parameters as coordinates: the fit passes through every point, and no
    // hypothesis of units or joint order can be told from another.
    let (coordinates, parameters) = redundancy(&fit, rows);
    if coordinates <= parameters {
        return Ok(Some(Implausible {
            symptom: format!(
                "{} configurations give {coordinates} coordinates for {parameters} parameters: the fit passes through every point, so its lengths say nothing",
                configurations(rows).len()
            ),
            likely_cause: Some(
                "measure more configurations, spread over the joint ranges (a calibration wants several times as many coordinates, three per configuration, as parameters)".into(),
            ),
            too_few: true,
        }));
    }
    let far = far_lengths(&fit, nominal);
    let turned = turned_axes(&fit);
    let symptom = if fit.report.after.mean > POOR_FIT {
        format!(
            "the identified model still misses the points by {:.2} mm on average",
            fit.report.after.mean
        )
    } else if far.is_empty() && !turned.is_empty() {
        format!(
            "the fit turned joint angles of the table half round ({}): a joint's readings count the other way from the robot file's axis",
            turned.join(", ")
        )
    } else {
        format!(
            "identified link lengths moved far from the robot file ({})",
            far.join(", ")
        )
    };
    let transformed = |f: &dyn Fn(&mut Measurement)| -> Vec<Measurement> {
        rows.iter()
            .map(|r| {
                let mut m = (*r).clone();
                f(&mut m);
                m
            })
            .collect()
    };
    let dof = nominal.dof();
    let mut hypotheses: Vec<(String, Vec<Measurement>)> = vec![
        (
            "the positions look like inches (x, y, z must be mm)".into(),
            transformed(&|m| m.position *= 25.4),
        ),
        (
            "the positions look like metres (x, y, z must be mm)".into(),
            transformed(&|m| m.position *= 1000.0),
        ),
        (
            "the joint angles look like radians (q1..qN must be degrees)".into(),
            transformed(&|m| {
                for q in &mut m.sample.joints {
                    *q = q.to_degrees();
                }
            }),
        ),
    ];
    for j in 0..dof {
        hypotheses.push((
            format!(
                "q{} looks negated (its readings must count the robot file's way round: negate the column, or turn the joint's axis in the robot file)",
                j + 1
            ),
            transformed(&|m| m.sample.joints[j] = -m.sample.joints[j]),
        ));
    }
    for i in 0..dof {
        for j in i + 1..dof {
            hypotheses.push((
                format!(
                    "columns q{} and q{} look swapped (the file's joint order must be the robot file's)",
                    i + 1,
                    j + 1
                ),
                transformed(&|m| m.sample.joints.swap(i, j)),
            ));
        }
    }
    let mut best: Option<(String, f64)> = None;
    for (cause, data) in hypotheses {
        let refs: Vec<&Measurement> = data.iter().collect();
        let Ok(alternative) = fit_kinematic(nominal, &refs, &settings) else {
            continue;
        };
        let mean = alternative.report.after.mean;
        if best.as_ref().is_none_or(|b| mean < b.1) && fits(&alternative, nominal, &refs) {
            best = Some((cause, mean));
        }
    }
    Ok(Some(Implausible {
        too_few: false,
        symptom,
        likely_cause: best.map(|(cause, mean)| {
            format!(
                "likely cause: {cause} (with that correction the fit misses by {mean:.3} mm and keeps the drawing's lengths)"
            )
        }),
    }))
}
