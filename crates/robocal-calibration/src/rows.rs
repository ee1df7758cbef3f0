//! The rows of a measurement file as the calibration groups them: by configuration, by load,
//! by their joint readings; the hold-outs residual training stops early on.

use crate::error::{CalibrationError, Result};
use rand::SeedableRng;
use rand::seq::SliceRandom;
use rand_chacha::ChaCha8Rng;
use robocal_data::Measurement;
use robocal_ident::KinematicCalibration;
use std::collections::HashSet;

/// The configurations (pose ids) of `rows`, sorted, each once.
pub(crate) fn configurations<'a>(rows: &[&'a Measurement]) -> Vec<&'a str> {
    let mut poses: Vec<&str> = rows.iter().map(|r| r.sample.pose.as_str()).collect();
    poses.sort_unstable();
    poses.dedup();
    poses
}

/// The rows of `rows` at its lightest load: what a rigid kinematic stage is fitted on.
pub(crate) fn lightest_load_rows<'a>(rows: &[&'a Measurement]) -> Vec<&'a Measurement> {
    let lightest = (rows.iter())
        .map(|r| r.sample.load)
        .fold(f64::INFINITY, f64::min);
    (rows.iter().copied())
        .filter(|r| r.sample.load == lightest)
        .collect()
}

/// A row's joint readings, bit for bit: rows with the same key are the same configuration
/// whatever their pose ids.
pub(crate) fn readings_key(r: &Measurement) -> Vec<u64> {
    r.sample.joints.iter().map(|q| q.to_bits()).collect()
}

/// Three coordinates per configuration and reflector of `rows` (the loads add nothing to the
/// geometry), and the parameters `fit` identified (its covariance's, or the table's identified
/// entries where it kept none).
pub(crate) fn coordinates_and_parameters(
    fit: &KinematicCalibration,
    rows: &[&Measurement],
) -> (usize, usize) {
    let mut points: Vec<(&str, &str)> = (rows.iter())
        .map(|r| (r.sample.pose.as_str(), r.sample.target.as_str()))
        .collect();
    points.sort_unstable();
    points.dedup();
    let parameters = fit.covariance.as_ref().map_or_else(
        || {
            (fit.report.parameters.iter())
                .filter(|p| p.identified_flag)
                .count()
        },
        |c| c.parameters.len(),
    );
    (3 * points.len(), parameters)
}

/// The loads (kg) of `rows`, ascending, each once.
pub(crate) fn loads(rows: &[&Measurement]) -> Vec<f64> {
    let mut loads: Vec<f64> = rows.iter().map(|r| r.sample.load).collect();
    loads.sort_by(f64::total_cmp);
    loads.dedup();
    loads
}

/// Splits `rows` into (kept, held out) by whole configurations: `share` of them (at least one,
/// never all), drawn by `seed`. `None` when there are fewer than two configurations.
pub fn hold_out<'a>(
    rows: &[&'a Measurement],
    share: f64,
    seed: u64,
) -> Option<(Vec<&'a Measurement>, Vec<&'a Measurement>, String)> {
    let mut poses = configurations(rows);
    if poses.len() < 2 {
        return None;
    }
    poses.shuffle(&mut ChaCha8Rng::seed_from_u64(seed));
    let n = ((poses.len() as f64 * share).round() as usize).clamp(1, poses.len() - 1);
    let held: HashSet<&str> = poses[..n].iter().copied().collect();
    let (out, kept): (Vec<&Measurement>, Vec<&Measurement>) = rows
        .iter()
        .partition(|r| held.contains(r.sample.pose.as_str()));
    let how = format!(
        "{n} of {} configurations held out (seed {seed})",
        poses.len()
    );
    Some((kept, out, how))
}

/// [`hold_out`] for a residual stage's early stopping, or the error that the stage needs a
/// validation file.
pub(super) fn early_stopping_hold_out<'a>(
    rows: &[&'a Measurement],
    share: f64,
    seed: u64,
) -> Result<(Vec<&'a Measurement>, Vec<&'a Measurement>, String)> {
    hold_out(rows, share, seed).ok_or_else(|| {
        CalibrationError::Stage(
            "the residual stage needs a --validate file or at least two configurations to hold one out".into(),
        )
    })
}
