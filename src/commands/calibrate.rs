//! `robocal calibrate`: identify a model from measurements and write the model directory.
//!
//! With `--config`, the stages the file asks for; without, the default calibration, which
//! chooses its stages from the data by their error on held-out poses (see
//! `robocal_pipeline::calibration`).

use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use robocal_data::{ErrorStats, Measurement, MeasurementSet};
use robocal_ident::KinematicReport;
use robocal_model::CalibratedModel;
use robocal_pipeline::calibration::{
    OutlierReport, OutlierSettings, ResidualReport, Selection, check_plausible, find_outliers,
};
use robocal_pipeline::{AutoSettings, DataRole, Stages, automatic, configured, write_data_report};
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
    /// The bad shots found (rows far beyond the data's own spread), and whether they were left
    /// out.
    outliers: Option<OutlierReport>,
}

/// What `calibrate` checks before it writes a model.
#[derive(Debug, Clone, Copy)]
pub struct Checks {
    /// Write even when the data do not fit the robot file.
    pub force: bool,
    /// Keep the bad shots in the fit.
    pub keep_outliers: bool,
}

/// Runs the calibration and writes `out` atomically.
pub fn run(
    robot: &Path,
    data: &Path,
    validate: Option<&Path>,
    out: &Path,
    config: Option<&Path>,
    checks: Checks,
    pictures: Option<&Path>,
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
    let failed = || format!("{}: calibration failed", data.display());
    if let Some(why) = check_plausible(&nominal, &rows).with_context(failed)? {
        if checks.force {
            eprintln!("robocal: warning: {why} (written anyway: --force)");
        } else {
            bail!(
                "{}: {why}; nothing written (--force writes the model anyway)",
                data.display()
            );
        }
    }
    let outliers = OutlierSettings {
        keep: checks.keep_outliers,
        ..OutlierSettings::default()
    };
    let auto = AutoSettings {
        outliers: Some(outliers),
        ..AutoSettings::default()
    };
    let terminal = Terminal::default();
    let built = match &stages {
        Some(stages) => {
            let (report, kept) = find_outliers(&nominal, &rows, &stages.kinematic, &outliers)
                .with_context(failed)?;
            let mut built =
                configured(stages, &nominal, &kept, val, &terminal).with_context(failed)?;
            built.outliers = Some(report);
            built
        }
        None => automatic(&auto, &nominal, &rows, val, &terminal).with_context(failed)?,
    };
    if let Some(o) = &built.outliers {
        for row in &o.rows {
            eprintln!(
                "robocal: bad shot: {} line {} (pose {}, load {} kg): {:.3} mm from the model, {:.0} robust standard deviations ({:.4} mm); {}",
                data.display(),
                row.line,
                row.pose,
                row.load,
                row.error,
                row.sigmas,
                o.robust_std,
                if o.left_out {
                    "left out of the fit (--keep-outliers keeps it)"
                } else {
                    "kept in the fit (--keep-outliers)"
                }
            );
        }
    }
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
        if let Some(d) = r.gate.as_ref().and_then(|g| g.decision.as_ref()) {
            eprintln!("robocal: CA-SOMM: {d}");
        }
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
        outliers: built.outliers.clone(),
    };
    model.robot.name = format!("{} (calibrated by robocal)", nominal.name);
    let mut registered = built.kinematic.aligned.clone();
    registered.name = format!(
        "{} (nominal, base and tool registered by robocal)",
        nominal.name
    );
    model.nominal = Some(registered);
    // The pictures first: a report that cannot be drawn leaves no model either.
    if let Some(dir) = pictures {
        let said = super::replacing(dir);
        let written = write_data_report(
            &model,
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
    let said = super::replacing(out);
    model.save(out, &report)?;
    said();
    let held_out = match (&report.validation, &report.selection) {
        (Some(v), _) => format!(
            "error on the validation file {}: mean {:.4} mm, max {:.4} mm",
            v.file.display(),
            v.after.mean,
            v.after.max
        ),
        (None, Some(s)) => match s.candidates.iter().find(|c| c.status == "chosen") {
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
    Ok(())
}
