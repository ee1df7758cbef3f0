//! `robocal calibrate`: identify a model from measurements and write the model directory.

use std::path::{Path, PathBuf};

use std::collections::HashSet;

use anyhow::{Context, Result, bail};
use indicatif::{ProgressBar, ProgressStyle};
use rand::SeedableRng;
use rand::seq::SliceRandom;
use rand_chacha::ChaCha8Rng;
use robocal_data::{ErrorStats, Measurement, MeasurementSet, write_dir_atomically, write_text_in};
use robocal_ident::{KinematicReport, Observations, calibrate_kinematics};
use robocal_pipeline::Stages;
use robocal_residual::{ResidualModel, ResidualStage, Samples, SearchLog};
use robocal_robot::Robot;
use serde::Serialize;

use super::model::{MODEL_FORMAT, Model};

/// Reads and validates a stage config (absent: the defaults).
fn load_stages(path: Option<&Path>) -> Result<Stages> {
    Ok(path.map(Stages::load).transpose()?.unwrap_or_default())
}

/// One network's training, in the report.
#[derive(Debug, Clone, Serialize)]
struct NetTraining {
    axes: String,
    epochs: usize,
    best_epoch: usize,
    stopped_early: bool,
}

/// The residual stage in `report.json`.
#[derive(Debug, Clone, Serialize)]
struct ResidualReport {
    model: &'static str,
    seed: u64,
    /// Where the early-stopping data came from.
    validation_source: String,
    training_rows: usize,
    validation_rows: usize,
    networks: Vec<NetTraining>,
    /// Training rows: error after kinematics, and after kinematics + residual.
    training_before: ErrorStats,
    training_after: ErrorStats,
    validation_before: ErrorStats,
    validation_after: ErrorStats,
    /// CA-SOMM: share of rows the classifier puts in their true class.
    classifier_accuracy_training: Option<f64>,
    classifier_accuracy_validation: Option<f64>,
    /// TPE searches that chose the settings (when the stage asked for one).
    search: Vec<SearchLog>,
}

/// Trains the residual stage on every row of `set` (less a hold-out of whole configurations when
/// no validation file is given).
fn train_residual(
    stage: &ResidualStage,
    robot: &Robot,
    set: &MeasurementSet,
    validation: Option<&MeasurementSet>,
) -> Result<(ResidualModel, ResidualReport)> {
    let seed = stage.settings.seed;
    let (train, val, source) = match validation {
        Some(v) => (
            Samples::from_measurements(robot, &set.rows),
            Samples::from_measurements(robot, &v.rows),
            format!("{}", v.source.display()),
        ),
        None => {
            let mut poses: Vec<&str> = set.rows.iter().map(|r| r.sample.pose.as_str()).collect();
            poses.sort_unstable();
            poses.dedup();
            if poses.len() < 2 {
                bail!(
                    "{}: the residual stage needs a --validate file or at least two configurations to hold one out",
                    set.source.display()
                );
            }
            poses.shuffle(&mut ChaCha8Rng::seed_from_u64(seed));
            let n =
                ((poses.len() as f64 * stage.holdout).round() as usize).clamp(1, poses.len() - 1);
            let held: HashSet<&str> = poses[..n].iter().copied().collect();
            let (v, t): (Vec<&Measurement>, Vec<&Measurement>) = set
                .rows
                .iter()
                .partition(|r| held.contains(r.sample.pose.as_str()));
            (
                Samples::from_measurements(robot, t),
                Samples::from_measurements(robot, v),
                format!(
                    "{n} of {} configurations held out (seed {seed})",
                    poses.len()
                ),
            )
        }
    };
    let bar = ProgressBar::new(ResidualModel::max_epochs(&stage.settings));
    bar.set_style(
        ProgressStyle::with_template(
            "robocal: residual {msg} [{bar:30}] {pos}/{len} epochs (at most) {elapsed}",
        )
        .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    bar.set_message(stage.settings.kind.name());
    let model = ResidualModel::fit(&stage.settings, &train, &val, Some(&bar))?;
    bar.finish_and_clear();
    let left = |s: &Samples, predicted: Option<&[[f64; 3]]>| {
        ErrorStats::from_errors(&s.remaining(predicted))
    };
    let axes = |a: &[usize]| a.iter().map(|&i| ["x", "y", "z"][i]).collect::<String>();
    let report = ResidualReport {
        model: stage.settings.kind.name(),
        seed,
        validation_source: source,
        training_rows: train.len(),
        validation_rows: val.len(),
        networks: model
            .nets
            .iter()
            .map(|n| NetTraining {
                axes: axes(&n.axes),
                epochs: n.report.epochs,
                best_epoch: n.report.best_epoch,
                stopped_early: n.report.stopped_early,
            })
            .collect(),
        training_before: left(&train, None),
        training_after: left(&train, Some(&model.predict(&train.inputs))),
        validation_before: left(&val, None),
        validation_after: left(&val, Some(&model.predict(&val.inputs))),
        classifier_accuracy_training: model.classifier.as_ref().map(|c| c.accuracy(&train)),
        classifier_accuracy_validation: model.classifier.as_ref().map(|c| c.accuracy(&val)),
        search: model.search.clone(),
    };
    Ok((model, report))
}

/// Before/after statistics on the validation file.
#[derive(Debug, Serialize)]
struct Validation {
    file: PathBuf,
    /// Nominal table, base and tool fitted.
    before: ErrorStats,
    /// Calibrated kinematics alone.
    after_kinematic: ErrorStats,
    /// The whole model (kinematics + residual, if any).
    after: ErrorStats,
}

/// `report.json`.
#[derive(Debug, Serialize)]
struct Report {
    model_format: u32,
    robocal_version: &'static str,
    robot_file: PathBuf,
    data_file: PathBuf,
    /// Rows used by the kinematic stage: those at the lightest load in the data.
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
    let stages = load_stages(config)?;
    let nominal = Robot::load(robot)?;
    let set = MeasurementSet::read(data, nominal.dof())?;
    let validation = validate
        .map(|v| MeasurementSet::read(v, nominal.dof()))
        .transpose()?;
    // Geometry is identified from the unloaded (lightest-load) rows, as in the paper.
    let lightest = set.loads().first().copied().unwrap_or(0.0);
    let obs = Observations::from_rows(
        nominal.dof(),
        set.rows.iter().filter(|r| r.sample.load == lightest),
    );
    let cal = calibrate_kinematics(&nominal, &obs, &stages.kinematic)
        .with_context(|| format!("{}: calibration failed", data.display()))?;
    let r = &cal.report;
    eprintln!(
        "robocal: kinematic ({}): {} points at {} kg, mean error {:.4} → {:.4} mm (max {:.4} → {:.4}), {} iterations",
        r.solver,
        r.points,
        lightest,
        r.before.mean,
        r.after.mean,
        r.before.max,
        r.after.max,
        r.iterations
    );
    if !r.fixed.is_empty() {
        let names: Vec<&str> = r.fixed.iter().map(|f| f.name.as_str()).collect();
        eprintln!(
            "robocal: not identifiable with these poses, held fixed: {}",
            names.join(", ")
        );
    }
    let residual = stages
        .residual
        .as_ref()
        .map(|stage| train_residual(stage, &cal.robot, &set, validation.as_ref()))
        .transpose()?;
    if let Some((_, r)) = &residual {
        eprintln!(
            "robocal: residual ({}): training mean {:.4} → {:.4} mm, validation ({}) {:.4} → {:.4} mm{}",
            r.model,
            r.training_before.mean,
            r.training_after.mean,
            r.validation_source,
            r.validation_before.mean,
            r.validation_after.mean,
            r.classifier_accuracy_validation
                .map_or(String::new(), |a| format!(
                    ", classifier accuracy {:.1} %",
                    100.0 * a
                ))
        );
    }
    let model = Model {
        robot: cal.robot.clone(),
        residual: residual.as_ref().map(|(m, _)| m.clone()),
    };
    let validation = validation.map(|v| {
        let obs = Observations::from_set(&v);
        let full: Vec<f64> = model
            .predict_all(v.rows.iter().map(|m| &m.sample))
            .iter()
            .zip(&v.rows)
            .map(|(p, m)| (p - m.position).norm())
            .collect();
        Validation {
            file: v.source.clone(),
            before: ErrorStats::from_errors(&obs.errors(&cal.aligned)),
            after_kinematic: ErrorStats::from_errors(&obs.errors(&cal.robot)),
            after: ErrorStats::from_errors(&full),
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
        model_format: MODEL_FORMAT,
        robocal_version: env!("CARGO_PKG_VERSION"),
        robot_file: robot.to_path_buf(),
        data_file: data.to_path_buf(),
        kinematic_load: lightest,
        kinematic: cal.report.clone(),
        residual: residual.as_ref().map(|(_, r)| r.clone()),
        validation,
    };
    let mut calibrated = cal.robot.clone();
    calibrated.name = format!("{} (calibrated by robocal)", nominal.name);
    let json = serde_json::to_string_pretty(&report)? + "\n";
    write_dir_atomically(out, |dir| -> Result<()> {
        write_text_in(dir, out, "kinematics.toml", &calibrated.to_toml_string())?;
        if let Some((model, _)) = &residual {
            model.save(dir)?;
        }
        write_text_in(dir, out, "report.json", &json)?;
        Ok(())
    })?;
    Ok(())
}
