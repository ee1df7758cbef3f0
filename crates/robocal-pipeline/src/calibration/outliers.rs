//! Bad shots: rows whose error under the identified model is far beyond the data's own spread
//! (a reflector mis-seated, the beam broken, a row typed wrong). They are found after a fit, the
//! model is fitted again without them until the set no longer changes, and the calibration
//! leaves them out (or keeps them, named, when asked).

use std::collections::BTreeSet;

use nalgebra::Vector3;
use robocal_data::{Measurement, robust_std};
use robocal_ident::{ComplianceSettings, KinematicCalibration, KinematicSettings};
use robocal_robot::Robot;
use serde::Serialize;

use super::{configurations, coordinates_and_parameters, fit_kinematic, loads, physical_model};
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

/// Fewer coordinates than this many times the identified parameters (three per configuration
/// and reflector: the loads add nothing to the geometry) and a fit of every row bends to each
/// of them, so that its errors are no measure of the model's: with 8 configurations of the
/// paper's arm at six loads the clean rows of four lay 37–55 robust standard deviations out
/// (the joint-4 backlash that flips with the payload, which such a fit absorbs elsewhere),
/// while a fit without a configuration may miss it by tens of millimetres, so that neither
/// alone tells a bad shot. Below it a row is a bad shot only when both leave it beyond the
/// threshold: the fit of every row, and the fit without its configuration.
pub const HELD_OUT_REDUNDANCY: f64 = 2.0;

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
    /// With too few configurations for the parameters ([`HELD_OUT_REDUNDANCY`]): the robust
    /// standard deviation of the rows' errors under fits without their configurations, mm; a
    /// row flagged was beyond the threshold in both.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub held_out_std: Option<f64>,
    /// The rows flagged, in file order.
    pub rows: Vec<Outlier>,
    /// With too few configurations: the rows the fit of every row leaves beyond the threshold
    /// but a fit without their configuration does not (kept, and named for checking), in file
    /// order.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub suspects: Vec<Outlier>,
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
/// With too few configurations for the parameters ([`HELD_OUT_REDUNDANCY`]) a row is flagged
/// only when the fit without its configuration (each left out in turn) also leaves it beyond
/// the threshold of that fit's own spread. Returns the report and the rows to calibrate on
/// (all of them with `keep`).
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
    let mut folds: Option<Vec<usize>> = None;
    let mut held_sigma = None;
    for round in 0..outliers.rounds.max(1) {
        let inliers = |keep: &dyn Fn(usize) -> bool| -> Vec<&Measurement> {
            (rows.iter().enumerate())
                .filter(|&(i, _)| !flagged.contains(&i) && keep(i))
                .map(|(_, r)| *r)
                .collect()
        };
        let fit = fit_kinematic(nominal, &inliers(&|_| true), &physics)?;
        if round == 0 && too_few_configurations(&fit, rows) {
            folds = Some(configuration_folds(rows));
        }
        let residuals = physical_model(&fit).residuals(rows.iter().copied());
        let spread = |residuals: &[Vector3<f64>]| {
            let components: Vec<f64> = (residuals.iter().enumerate())
                .filter(|(i, _)| !flagged.contains(i))
                .flat_map(|(_, r)| [r.x, r.y, r.z])
                .collect();
            robust_std(&components)
        };
        sigma = spread(&residuals);
        errors = residuals.iter().map(|r| r.norm()).collect::<Vec<f64>>();
        let beyond = |errors: &[f64], sigma: f64| -> BTreeSet<usize> {
            (errors.iter().enumerate())
                .filter(|(_, e)| sigma > 0.0 && **e > outliers.threshold * sigma)
                .map(|(i, _)| i)
                .collect()
        };
        let mut next = beyond(&errors, sigma);
        if let Some(fold) = &folds {
            let mut held = vec![Vector3::zeros(); rows.len()];
            for k in 0..configurations(rows).len() {
                let test: Vec<usize> = (0..rows.len()).filter(|&i| fold[i] == k).collect();
                if test.is_empty() {
                    continue;
                }
                // A fold whose others cannot be fitted leaves nothing to tell a bad shot by.
                let Ok(without) = fit_kinematic(nominal, &inliers(&|i| fold[i] != k), &physics)
                else {
                    return Ok(none_found(rows, outliers, sigma));
                };
                let model = physical_model(&without);
                for (&i, r) in test
                    .iter()
                    .zip(model.residuals(test.iter().map(|&i| rows[i])))
                {
                    held[i] = r;
                }
            }
            let held_std = spread(&held);
            let held_errors: Vec<f64> = held.iter().map(|r| r.norm()).collect();
            next = &next & &beyond(&held_errors, held_std);
            held_sigma = Some(held_std);
        }
        if next == flagged {
            break;
        }
        flagged = next;
    }
    let outlier = |i: usize| Outlier {
        pose: rows[i].sample.pose.clone(),
        load: rows[i].sample.load,
        line: rows[i].sample.line,
        error: errors[i],
        sigmas: errors[i] / sigma,
    };
    let report = OutlierReport {
        robust_std: sigma,
        threshold: outliers.threshold,
        left_out: !outliers.keep,
        held_out_std: held_sigma,
        rows: flagged.iter().map(|&i| outlier(i)).collect(),
        suspects: (0..rows.len())
            .filter(|i| held_sigma.is_some() && !flagged.contains(i))
            .filter(|&i| sigma > 0.0 && errors[i] > outliers.threshold * sigma)
            .map(outlier)
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

/// Whether `rows` hold fewer coordinates than [`HELD_OUT_REDUNDANCY`] times the parameters
/// `fit` identified (three per configuration and reflector).
fn too_few_configurations(fit: &KinematicCalibration, rows: &[&Measurement]) -> bool {
    let (coordinates, parameters) = coordinates_and_parameters(fit, rows);
    (coordinates as f64) < HELD_OUT_REDUNDANCY * parameters as f64
}

/// Each row's configuration's place among the sorted configurations (every load and reflector
/// of a configuration held out together).
fn configuration_folds(rows: &[&Measurement]) -> Vec<usize> {
    let poses = configurations(rows);
    (rows.iter())
        .map(|r| poses.binary_search(&r.sample.pose.as_str()).unwrap_or(0))
        .collect()
}

/// No bad shot found (a fold could not be fitted without its configurations: nothing could
/// be told), every row kept; `sigma` the fit of every row's robust standard deviation.
fn none_found<'a>(
    rows: &[&'a Measurement],
    outliers: &OutlierSettings,
    sigma: f64,
) -> (OutlierReport, Vec<&'a Measurement>) {
    let report = OutlierReport {
        robust_std: sigma,
        threshold: outliers.threshold,
        left_out: !outliers.keep,
        held_out_std: None,
        rows: Vec::new(),
        suspects: Vec::new(),
    };
    (report, rows.to_vec())
}
