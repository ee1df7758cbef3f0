//! Bad shots: rows whose error under the identified model is far beyond the data's own spread
//! (a reflector mis-seated, the beam broken, a row typed wrong). They are found after a fit, the
//! model is fitted again without them until the set no longer changes, and the calibration
//! leaves them out (or keeps them, named, when asked).

use std::collections::BTreeSet;

use robocal_data::{Measurement, robust_std};
use robocal_ident::{ComplianceSettings, KinematicSettings};
use robocal_robot::Robot;
use serde::Serialize;

use super::{fit_kinematic, loads, physical_model};
use crate::error::Result;

/// How bad shots are found.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OutlierSettings {
    /// A row is an outlier when its error exceeds this many robust standard deviations of the
    /// error components (1.4826 × their median absolute deviation).
    pub threshold: f64,
    /// Most fits (each without the rows the one before flagged).
    pub rounds: usize,
    /// Keep the flagged rows in the fit (they are still named).
    pub keep: bool,
}

/// The default threshold, in robust standard deviations: no clean row of robocal's twins came
/// near it (their largest is under half of it, every family and seed of the accuracy suite),
/// while a 2 mm bad shot on a 0.1 mm calibration is 20 of them and more.
pub const OUTLIER_THRESHOLD: f64 = 12.0;

impl Default for OutlierSettings {
    fn default() -> Self {
        Self {
            threshold: OUTLIER_THRESHOLD,
            rounds: 4,
            keep: false,
        }
    }
}

/// A row found to be a bad shot.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Outlier {
    /// Configuration id.
    pub pose: String,
    /// Load, kg.
    pub load: f64,
    /// Line in its file (1-based; 0 when made in memory).
    pub line: u64,
    /// Its error under the model fitted without the outliers, mm.
    pub error: f64,
    /// That error in robust standard deviations.
    pub sigmas: f64,
}

/// What the search found.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct OutlierReport {
    /// Robust standard deviation of the error components of the inliers, mm.
    pub robust_std: f64,
    /// The threshold, in robust standard deviations.
    pub threshold: f64,
    /// Whether the outliers were left out of the fit.
    pub left_out: bool,
    /// The rows flagged, in file order.
    pub rows: Vec<Outlier>,
}

/// The physics the search fits: `settings`, with joint compliances when the data hold two or
/// more loads and `settings` have none (a rigid table cannot tell a heavy load's deflection
/// from a bad shot). Least squares, on purpose: the threshold is in robust standard deviations
/// of a least-squares fit's errors (a Huber fit hugs the bulk closer, and the same rows then
/// sit further out); the refits without the flagged rows keep the shots from pulling it.
fn search_physics(settings: &KinematicSettings, rows: &[&Measurement]) -> KinematicSettings {
    let mut s = settings.clone();
    if loads(rows).len() >= 2 && s.compliance.is_none() {
        s.compliance = Some(ComplianceSettings::default());
    }
    s
}

/// The bad shots of `rows` under the physics of `settings`: fit, flag the rows beyond the
/// threshold, fit again without them, until the flagged set repeats (at most `rounds` fits).
/// Returns the report and the rows to calibrate on (all of them with `keep`).
pub fn find_outliers<'a>(
    nominal: &Robot,
    rows: &[&'a Measurement],
    settings: &KinematicSettings,
    outliers: &OutlierSettings,
) -> Result<(OutlierReport, Vec<&'a Measurement>)> {
    let physics = search_physics(settings, rows);
    let mut flagged: BTreeSet<usize> = BTreeSet::new();
    let mut errors = Vec::new();
    let mut sigma = 0.0;
    for _ in 0..outliers.rounds.max(1) {
        let inliers: Vec<&Measurement> = (rows.iter().enumerate())
            .filter(|(i, _)| !flagged.contains(i))
            .map(|(_, r)| *r)
            .collect();
        let model = physical_model(&fit_kinematic(nominal, &inliers, &physics)?);
        let residuals = model.residuals(rows.iter().copied());
        let components: Vec<f64> = (residuals.iter().enumerate())
            .filter(|(i, _)| !flagged.contains(i))
            .flat_map(|(_, r)| [r.x, r.y, r.z])
            .collect();
        sigma = robust_std(&components);
        errors = residuals.iter().map(|r| r.norm()).collect::<Vec<f64>>();
        let next: BTreeSet<usize> = (errors.iter().enumerate())
            .filter(|(_, e)| sigma > 0.0 && **e > outliers.threshold * sigma)
            .map(|(i, _)| i)
            .collect();
        if next == flagged {
            break;
        }
        flagged = next;
    }
    let report = OutlierReport {
        robust_std: sigma,
        threshold: outliers.threshold,
        left_out: !outliers.keep,
        rows: flagged
            .iter()
            .map(|&i| Outlier {
                pose: rows[i].sample.pose.clone(),
                load: rows[i].sample.load,
                line: rows[i].sample.line,
                error: errors[i],
                sigmas: errors[i] / sigma,
            })
            .collect(),
    };
    let kept = if outliers.keep {
        rows.to_vec()
    } else {
        (rows.iter().enumerate())
            .filter(|(i, _)| !flagged.contains(i))
            .map(|(_, r)| *r)
            .collect()
    };
    Ok((report, kept))
}
