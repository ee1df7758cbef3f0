//! `robocal report`: the pictures of a calibration on measurements.

use std::path::Path;

use anyhow::Result;
use robocal_data::{Measurement, MeasurementSet};
use robocal_model::CalibratedModel;
use robocal_report::{DataRole, write_data_report};

/// Writes the report of the model in `model` on the rows of `data` into `out`, atomically.
pub fn run(model_dir: &Path, data: &Path, out: &Path) -> Result<()> {
    let model = CalibratedModel::load(model_dir)?;
    let set = MeasurementSet::read(data, model.dof())?;
    model.check_targets(data, set.rows.iter().map(|m| &m.sample))?;
    let rows: Vec<&Measurement> = set.rows.iter().collect();
    let said = super::replacing(out);
    let report = write_data_report(
        &model,
        &model_dir.display().to_string(),
        data,
        &rows,
        DataRole::HeldOut,
        out,
    )?;
    said();
    let before = report.before.as_ref().map_or(
        "no registered nominal table in the model".to_string(),
        |b| format!("before {:.4} mm", b.mean),
    );
    super::print_out(&format!(
        "{} rows: mean error {:.4} mm (max {:.4}), {before}\nreport written to {}: report.md, report.html, statistics.json, {} figures (PNG and SVG)\n",
        report.rows,
        report.after.mean,
        report.after.max,
        out.display(),
        report.figures.len()
    ))?;
    Ok(())
}
