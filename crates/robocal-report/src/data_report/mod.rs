//! The pictures of a calibration on the user's own measurements (`robocal report`,
//! `calibrate --report`): the error before and after as cumulative distributions, per pose, per
//! axis against every joint angle, against the load (two or more loads) and over the
//! workspace; PNG and SVG, `report.md`, one self-contained `report.html` (the SVGs inline) and
//! `statistics.json`.
//!
//! "Before" is the nominal table with its base and tool registered in the tracker frame (the
//! model directory's `nominal.toml`, written by `calibrate`); a model without it is shown after
//! calibration only.

mod figures;
mod stats;
mod text;

use crate::error::{ReportError, Result};
use robocal_data::{ErrorStats, Measurement, write_dir_atomically, write_text_in};
use robocal_model::CalibratedModel;
use std::path::Path;

use figures::{Errors, configuration_numbers, draw, draw_sigma, mean_by_load};
pub use stats::{
    AxisStats, DataReport, DataRole, Figure, LoadStats, OrientationStats, SigmaCheck, TargetStats,
    WorstRow,
};
use stats::{axis_stats, by_target, loads, parts, sigma_check};
use text::{html, markdown};

/// Writes the report of `model` (called `model_name` in the texts) on `rows` of `data` into the
/// folder `out`, atomically (a complete new folder, or nothing).
pub fn write_data_report(
    model: &CalibratedModel,
    model_name: &str,
    data: &Path,
    rows: &[&Measurement],
    role: DataRole,
    out: &Path,
) -> Result<DataReport> {
    if rows.is_empty() {
        return Err(ReportError::Data(format!(
            "{}: no rows to report on",
            data.display()
        )));
    }
    let signed = model.residuals(rows.iter().copied());
    let after: Vec<f64> = signed.iter().map(|r| r.norm()).collect();
    let before: Option<Vec<f64>> = model
        .nominal
        .as_ref()
        .map(|n| CalibratedModel::kinematic(n.clone()).errors(rows));
    let kinematic: Option<Vec<f64>> = model.residual.is_some().then(|| {
        CalibratedModel {
            residual: None,
            ..model.clone()
        }
        .errors(rows)
    });
    let sigmas = model
        .predict_with_sigma(rows.iter().map(|m| &m.sample), true)
        .1;
    let before_by_load = before.as_ref().map(|b| mean_by_load(rows, b));
    let mut order: Vec<usize> = (0..rows.len()).collect();
    order.sort_by(|&a, &b| after[b].total_cmp(&after[a]));
    let mut report = DataReport {
        data: data.to_path_buf(),
        role,
        model: model_name.to_string(),
        parts: parts(model),
        rows: rows.len(),
        configurations: configuration_numbers(rows).1,
        loads: loads(rows),
        before: before.as_deref().map(ErrorStats::from_errors),
        kinematic: kinematic.as_deref().map(ErrorStats::from_errors),
        after: ErrorStats::from_errors(&after),
        axes: axis_stats(&signed),
        by_load: mean_by_load(rows, &after)
            .into_iter()
            .enumerate()
            .map(|(i, (load, after_mean))| LoadStats {
                load,
                rows: rows.iter().filter(|m| m.sample.load == load).count(),
                before: before_by_load.as_ref().map(|b| b[i].1),
                after: after_mean,
            })
            .collect(),
        by_target: by_target(rows, before.as_deref(), &after),
        orientation: rows
            .iter()
            .any(|m| m.orientation.is_some())
            .then(|| OrientationStats {
                before: (model.nominal.as_ref()).map(|n| {
                    ErrorStats::from_errors(
                        &CalibratedModel::kinematic(n.clone()).orientation_errors(rows),
                    )
                }),
                after: ErrorStats::from_errors(&model.orientation_errors(rows)),
            }),
        sigma: sigmas.as_deref().and_then(|s| sigma_check(&after, s)),
        worst: order
            .iter()
            .take(5)
            .map(|&i| WorstRow {
                line: rows[i].sample.line,
                pose: rows[i].sample.pose.clone(),
                load: rows[i].sample.load,
                error: after[i],
            })
            .collect(),
        figures: Vec::new(),
    };
    write_dir_atomically(out, |dir| -> Result<()> {
        let errors = Errors {
            rows,
            before: before.as_deref(),
            kinematic: kinematic.as_deref(),
            after: &after,
            signed: &signed,
        };
        report.figures = draw(dir, out, &errors)?;
        if let Some(sigmas) = sigmas.as_deref() {
            report.figures.push(draw_sigma(dir, out, &after, sigmas)?);
        }
        let json = serde_json::to_string_pretty(&report)
            .map_err(|e| ReportError::Data(format!("statistics.json: {e}")))?;
        write_text_in(dir, out, "statistics.json", &(json + "\n"))?;
        write_text_in(dir, out, "report.md", &markdown(&report))?;
        let html = html(&report, dir).map_err(|(file, e)| ReportError::Read {
            path: out.join(file),
            source: e,
        })?;
        write_text_in(dir, out, "report.html", &html)?;
        Ok(())
    })?;
    Ok(report)
}

#[cfg(test)]
mod tests;
