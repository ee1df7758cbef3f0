//! `robocal calibrate`: identify a model from measurements and write the model directory.
//!
//! With `--config`, the stages the file asks for; without, the default calibration, which
//! chooses its stages from the data by their error on held-out poses (see
//! `robocal_calibration`).

use std::path::Path;

use anyhow::Result;
use robocal_calibration::{
    Calibration, CalibrationInput, Checks, DefaultOptions, OutlierReport, Stages, Summary,
    calibrate, fit_lines, repeats_line,
};
use robocal_data::{Measurement, MeasurementSet};
use robocal_report::{DataRole, write_data_report};
use robocal_robot::Robot;

use super::terminal::Terminal;

/// Runs the calibration and writes `out` atomically (and the pictures of the fit into
/// `pictures` when given), with the default calibration's `options`.
#[allow(clippy::too_many_arguments)]
pub fn run(
    robot: &Path,
    data: &Path,
    validate: Option<&Path>,
    out: &Path,
    config: Option<&Path>,
    checks: Checks,
    pictures: Option<&Path>,
    options: &DefaultOptions,
) -> Result<()> {
    let started = std::time::Instant::now();
    let stages = config.map(Stages::load).transpose()?;
    let nominal = Robot::load(robot)?;
    let set = MeasurementSet::read(data, nominal.dof())?;
    let validation = validate
        .map(|v| MeasurementSet::read(v, nominal.dof()))
        .transpose()?;
    let input = CalibrationInput {
        nominal: &nominal,
        robot_file: robot,
        data: &set,
        validation: validation.as_ref(),
        stages: stages.as_ref().zip(config),
        checks,
        options,
    };
    let calibration = calibrate(&input, &Terminal::default())?;
    let Calibration {
        model,
        report,
        built,
        implausible,
    } = &calibration;
    if let Some(why) = implausible {
        eprintln!("robocal: warning: {why} (written anyway: --force)");
    }
    if let Some(o) = &built.outliers {
        for line in outlier_lines(o, data) {
            eprintln!("robocal: {line}");
        }
    }
    for line in fit_lines(&calibration) {
        eprintln!("robocal: {line}");
    }
    let rows: Vec<&Measurement> = set.rows.iter().collect();
    // The pictures first: a report that cannot be drawn leaves no model either.
    if let Some(dir) = pictures {
        let said = super::replacing(dir);
        let written = write_data_report(
            model,
            &out.display().to_string(),
            data,
            &rows,
            DataRole::Training,
            dir,
        )?;
        said();
        eprintln!(
            "robocal: report on the training rows written to {} ({} figures, report.html)",
            dir.display(),
            written.figures.len()
        );
    }
    if let Some(line) = repeats_line(report) {
        eprintln!("robocal: {line}");
    }
    let said = super::replacing(out);
    model.save(out, report)?;
    said();
    let held_out = match (&report.validation, &report.selection) {
        (Some(v), _) => format!(
            "error on the validation file {}: mean {:.4} mm, max {:.4} mm",
            v.file.display(),
            v.after.mean,
            v.after.max
        ),
        (None, Some(s)) => match s.chosen() {
            Some(c) => format!(
                "held-out error (score of the chosen candidate, {}): {:.4} mm",
                s.held_out,
                c.score.unwrap_or(f64::NAN)
            ),
            None => format!("no held-out error ({})", s.held_out),
        },
        (None, None) => format!(
            "no held-out error (pass --validate FILE); training error {:.4} mm",
            model.stats(&rows).mean
        ),
    };
    eprintln!("robocal: model written to {}; {held_out}", out.display());
    let seconds = started.elapsed().as_secs_f64();
    print!("{}", Summary::new(report, Some(out), seconds));
    Ok(())
}

/// The lines on the bad shots `o` found in `data`: each one, and the rows kept that a fit of every
/// row leaves far out where too few configurations could tell.
fn outlier_lines(o: &OutlierReport, data: &Path) -> Vec<String> {
    let mut said = Vec::new();
    for row in &o.rows {
        said.push(format!(
            "bad shot: {} line {} (pose {}, load {} kg): {:.3} mm from the model, {:.0} robust standard deviations ({:.4} mm){}; {}",
            data.display(),
            row.line,
            row.pose,
            row.load,
            row.error,
            row.sigmas,
            o.robust_std,
            (row.refined_sigmas.zip(o.refined_std))
                .map(|(n, std)| format!(
                    ", {n:.0} ({std:.4} mm) under the physics with the transmission harmonics"
                ))
                .unwrap_or_default(),
            if o.left_out {
                "left out of the fit (--keep-outliers keeps it)"
            } else {
                "kept in the fit (--keep-outliers)"
            }
        ));
    }
    if let (Some(held), false) = (o.held_out_std, o.suspects.is_empty()) {
        let named: Vec<String> = (o.suspects.iter().take(10))
            .map(|r| {
                format!(
                    "line {} (pose {}, load {} kg) {:.3} mm",
                    r.line, r.pose, r.load, r.error
                )
            })
            .collect();
        said.push(format!(
            "warning: {}: too few configurations for the parameters to tell a bad shot from the model's own error (a fit without a configuration misses its rows by {:.3} mm, robust standard deviation): {} row(s) the fit of every row leaves beyond {:.0} robust standard deviations ({:.4} mm) were kept; check them: {}{}",
            data.display(),
            held,
            o.suspects.len(),
            o.threshold,
            o.robust_std,
            named.join(", "),
            if o.suspects.len() > named.len() {
                ", …"
            } else {
                ""
            }
        ));
    }
    said
}
