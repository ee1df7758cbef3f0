//! `robocal evaluate`.

use std::path::Path;

use anyhow::Result;
use robocal_data::{ErrorStats, MeasurementSet};

use super::model;
use crate::cli::ModelSource;

/// Prints the statistics of the Euclidean error between predicted and measured points.
pub fn run(source: &ModelSource, data: &Path, json: bool) -> Result<()> {
    let model = model::load(source)?;
    let set = MeasurementSet::read(data, model.robot.dof())?;
    let predicted = model.predict(set.rows.iter().map(|m| &m.sample));
    let errors: Vec<f64> = set
        .rows
        .iter()
        .zip(predicted)
        .map(|(m, p)| (p - m.position).norm())
        .collect();
    let stats = ErrorStats::from_errors(&errors);
    if json {
        println!("{}", serde_json::to_string(&stats)?);
    } else {
        println!("count {}", stats.count);
        println!("mean  {:.6} mm", stats.mean);
        println!("std   {:.6} mm", stats.std);
        println!("rms   {:.6} mm", stats.rms);
        println!("max   {:.6} mm", stats.max);
    }
    Ok(())
}
