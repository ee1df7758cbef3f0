//! `robocal predict`.

use std::path::Path;

use anyhow::{Result, bail};
use robocal_data::{Prediction, SampleSet, write_predictions};

use super::model;
use crate::cli::ModelSource;

/// Predicts every row of `data` and writes `pose,load,x,y,z` to `out`, atomically.
pub fn run(source: &ModelSource, data: &Path, out: &Path) -> Result<()> {
    let model = model::load(source)?;
    let samples = SampleSet::read(data, model.robot.dof())?;
    let rows: Vec<Prediction> = samples
        .rows
        .iter()
        .zip(model.predict(&samples.rows))
        .map(|(s, position)| Prediction {
            pose: s.pose.clone(),
            load: s.load,
            position,
        })
        .collect();
    // Finite inputs through a finite model give finite points; a table with absurd values can
    // still overflow, and a file must never hold NaN.
    if let Some((s, _)) =
        (samples.rows.iter().zip(&rows)).find(|(_, p)| !p.position.iter().all(|v| v.is_finite()))
    {
        bail!(
            "{}: line {}: the model's prediction for pose `{}` is not a finite number (check the robot table's values); nothing written",
            data.display(),
            s.line,
            s.pose
        );
    }
    write_predictions(out, &rows)?;
    Ok(())
}
