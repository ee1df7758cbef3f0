//! `robocal predict`.

use std::path::Path;

use anyhow::Result;
use robocal_data::{Prediction, SampleSet, write_predictions};

use super::model::Model;
use crate::cli::ModelSource;

/// Predicts every row of `data` and writes `pose,load,x,y,z` to `out`, atomically.
pub fn run(source: &ModelSource, data: &Path, out: &Path) -> Result<()> {
    let model = Model::load(source)?;
    let samples = SampleSet::read(data, model.robot.dof())?;
    let rows: Vec<Prediction> = samples
        .rows
        .iter()
        .zip(model.predict_all(&samples.rows))
        .map(|(s, position)| Prediction {
            pose: s.pose.clone(),
            load: s.load,
            position,
        })
        .collect();
    write_predictions(out, &rows)?;
    Ok(())
}
