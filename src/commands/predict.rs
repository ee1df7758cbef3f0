//! `robocal predict`.

use std::path::Path;

use anyhow::{Result, bail};
use robocal_data::{Prediction, SampleSet, write_predictions};

use super::model;
use crate::cli::ModelSource;

/// Predicts every row of `data` and writes `pose,load,x,y,z` to `out`, atomically; with
/// `sigma`, also each point's standard deviation (a model with a Gaussian-process residual: the
/// GP's; a network residual: the physics' deviation with the network's spread; a physical
/// model without a residual model: its identified parameters');
/// with `rx, ry, rz` columns in `data` (a 6-DoF probe's file), the tool frame's predicted
/// orientation in them.
pub fn run(source: &ModelSource, data: &Path, out: &Path, sigma: bool) -> Result<()> {
    let model = model::load(source)?;
    let samples = SampleSet::read(data, model.robot.dof())?;
    model.check_targets(data, &samples.rows)?;
    super::warn_outside(&model, data, &samples.rows);
    let (points, sigmas) = model.predict_with_sigma(&samples.rows, sigma);
    if sigma && sigmas.is_none() {
        bail!(
            "--sigma: this model gives no standard deviation (a model with a Gaussian-process residual gives the GP's, a physical model without a residual model its parameters' covariance's; a network residual gives the physics' with its spread when the default calibration estimated one, else none; a table alone, or a model directory without covariance.json, has no covariance); nothing written"
        );
    }
    let rows: Vec<Prediction> = (samples.rows.iter().zip(points).enumerate())
        .map(|(i, (s, position))| Prediction {
            pose: s.pose.clone(),
            target: s.target.clone(),
            load: s.load,
            position,
            sigma: sigmas.as_ref().map(|v| v[i]),
            // A 6-DoF probe's file: the tool frame's orientation too.
            orientation: samples.orientation.then(|| model.orientation_deg(s)),
        })
        .collect();
    // Finite inputs through a finite model give finite points; a table with absurd values can
    // still overflow, and a file must never hold NaN.
    if let Some((s, _)) = (samples.rows.iter().zip(&rows)).find(|(_, p)| {
        !(p.position.iter().chain(p.orientation.iter().flatten())).all(|v| v.is_finite())
    }) {
        bail!(
            "{}: line {}: the model's prediction for pose `{}` is not a finite number (check the robot table's values); nothing written",
            data.display(),
            s.line,
            s.pose
        );
    }
    let said = super::replacing(out);
    write_predictions(out, &rows)?;
    said();
    Ok(())
}
