//! `robocal calibrate`: identify a model from measurements and write the model directory.
//!
//! With `--config`, the stages the file asks for; without, the default calibration, which
//! chooses its stages from the data by their error on held-out poses (see
//! `robocal_pipeline::calibration`).

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use robocal_data::{ErrorStats, Measurement, MeasurementSet};
use robocal_ident::KinematicReport;
use robocal_model::CalibratedModel;
use robocal_pipeline::calibration::{ResidualReport, Selection};
use robocal_pipeline::{AutoSettings, Stages, automatic, configured};
use robocal_robot::Robot;
use serde::Serialize;

use super::terminal::Terminal;

/// Before/after statistics on the validation file.
#[derive(Debug, Serialize)]
struct Validation {
    file: PathBuf,
    /// Nominal table, base and tool fitted.
    before: ErrorStats,
    /// Calibrated kinematics (and compliance) alone.
    after_kinematic: ErrorStats,
    /// The whole model (kinematics + compliance + residual, if any).
    after: ErrorStats,
}

/// `report.json` (after the layout version and robocal's version, which the model writes).
#[derive(Debug, Serialize)]
struct Report {
    robot_file: PathBuf,
    data_file: PathBuf,
    /// `config FILE`, or the default calibration.
    stages_from: String,
    /// How the default calibration chose its stages.
    #[serde(skip_serializing_if = "Option::is_none")]
    selection: Option<Selection>,
    /// Lightest load in the data: a rigid kinematic stage uses the rows at this load; an
    /// elasto-geometric one uses every row.
    kinematic_load: f64,
    kinematic: KinematicReport,
    residual: Option<ResidualReport>,
    validation: Option<Validation>,
}

/// Runs the calibration and writes `out` atomically.
pub fn run(
    robot: &Path,
    data: &Path,
    validate: Option<&Path>,
    out: &Path,
    config: Option<&Path>,
) -> Result<()> {
    let stages = config.map(Stages::load).transpose()?;
    let nominal = Robot::load(robot)?;
    let set = MeasurementSet::read(data, nominal.dof())?;
    let validation = validate
        .map(|v| MeasurementSet::read(v, nominal.dof()))
        .transpose()?;
    let rows: Vec<&Measurement> = set.rows.iter().collect();
    let val_rows: Option<Vec<&Measurement>> = validation.as_ref().map(|v| v.rows.iter().collect());
    let val = val_rows
        .as_deref()
        .zip(validation.as_ref())
        .map(|(r, v)| (r, v.source.display().to_string()));
    let auto = AutoSettings::default();
    let terminal = Terminal::default();
    let built = match &stages {
        Some(stages) => configured(stages, &nominal, &rows, val, &terminal),
        None => automatic(&auto, &nominal, &rows, val, &terminal),
    }
    .with_context(|| format!("{}: calibration failed", data.display()))?;
    let lightest = set.loads().first().copied().unwrap_or(0.0);
    let r = &built.kinematic.report;
    eprintln!(
        "robocal: kinematic ({}{}): {} points, mean error {:.4} → {:.4} mm (max {:.4} → {:.4}), {} iterations",
        r.solver,
        if r.compliance.is_some() {
            " with joint compliance"
        } else {
            ""
        },
        r.points,
        r.before.mean,
        r.after.mean,
        r.before.max,
        r.after.max,
        r.iterations
    );
    for w in &r.warnings {
        eprintln!("robocal: warning: {w}");
    }
    if let Some(c) = &r.compliance {
        for j in c.joints.iter().filter(|j| j.identified) {
            eprintln!(
                "robocal: joint {} compliance {:.4} deg/kN·m{}{}",
                j.joint,
                j.compliance,
                j.std.map_or(String::new(), |s| format!(" ± {s:.4}")),
                if j.compliance < 0.0 {
                    " (warning: negative; see report.json)"
                } else {
                    ""
                }
            );
        }
    }
    if !r.fixed.is_empty() {
        let names: Vec<&str> = r.fixed.iter().map(|f| f.name.as_str()).collect();
        eprintln!(
            "robocal: not identifiable with these poses, held fixed: {}",
            names.join(", ")
        );
    }
    if let Some((_, r)) = &built.residual {
        let validation = match (&r.validation_before, &r.validation_after) {
            (Some(b), Some(a)) => format!(
                ", validation ({}) {:.4} → {:.4} mm",
                r.validation_source, b.mean, a.mean
            ),
            _ => format!(" (validation: {})", r.validation_source),
        };
        eprintln!(
            "robocal: residual ({}): training mean {:.4} → {:.4} mm{validation}{}",
            r.model,
            r.training_before.mean,
            r.training_after.mean,
            r.classifier_accuracy_validation
                .map_or(String::new(), |a| format!(
                    ", classifier accuracy {:.1} %",
                    100.0 * a
                ))
        );
    }
    let mut model = built.model();
    let validation = validation.map(|v| {
        let rows: Vec<&Measurement> = v.rows.iter().collect();
        Validation {
            file: v.source.clone(),
            before: CalibratedModel::kinematic(built.kinematic.aligned.clone()).stats(&rows),
            after_kinematic: CalibratedModel {
                residual: None,
                ..model.clone()
            }
            .stats(&rows),
            after: model.stats(&rows),
        }
    });
    if let Some(v) = &validation {
        eprintln!(
            "robocal: validation {}: mean {:.4} → {:.4} mm (kinematics alone {:.4})",
            v.file.display(),
            v.before.mean,
            v.after.mean,
            v.after_kinematic.mean
        );
    }
    let report = Report {
        robot_file: robot.to_path_buf(),
        data_file: data.to_path_buf(),
        stages_from: match config {
            Some(c) => format!("config {}", c.display()),
            None => {
                "default: the candidate with the lowest held-out error (cross-validated)".into()
            }
        },
        selection: built.selection.clone(),
        kinematic_load: lightest,
        kinematic: built.kinematic.report.clone(),
        residual: built.residual.as_ref().map(|(_, r)| r.clone()),
        validation,
    };
    model.robot.name = format!("{} (calibrated by robocal)", nominal.name);
    model.save(out, &report)?;
    Ok(())
}
