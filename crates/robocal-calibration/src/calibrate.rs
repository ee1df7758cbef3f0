//! The whole of `calibrate` — the plausibility check, the bad shots, the stages (a stage config
//! or the default), the model and `report.json` — shared by the command line and the Python
//! bindings, so that both make the same model from the same rows.

use std::path::{Path, PathBuf};

use robocal_data::{ErrorStats, Measurement, MeasurementSet, Observer, check_targets};
use robocal_ident::{FitMemo, KinematicReport};
use robocal_model::CalibratedModel;
use robocal_robot::{JointErrors, Robot};
use serde::Serialize;

use crate::built::Built;
use crate::configured::configured_with;
use crate::error::{CalibrationError, Result};
use crate::options::DefaultOptions;
use crate::outliers::{OutlierReport, OutlierSettings, find_outliers_with};
use crate::plausibility::check_plausible;
use crate::readings::{rounded_joints, rounding_warning};
use crate::repeats::{Repeats, repeats};
use crate::residual_report::ResidualReport;
use crate::select::{AutoSettings, Selection, automatic};
use crate::stages::Stages;

/// What `calibrate` checks before it makes a model.
#[derive(Debug, Clone, Copy, Default)]
pub struct Checks {
    /// Make the model even when the data do not fit the robot file.
    pub force: bool,
    /// Keep the bad shots in the fit.
    pub keep_outliers: bool,
}

/// Before/after statistics on the validation rows.
#[derive(Debug, Clone, Serialize)]
pub struct Validation {
    /// Where the rows came from.
    pub file: PathBuf,
    /// Nominal table, base and tool fitted.
    pub before: ErrorStats,
    /// Calibrated kinematics (and compliance) alone.
    pub after_kinematic: ErrorStats,
    /// The whole model (kinematics + compliance + residual, if any).
    pub after: ErrorStats,
}

/// `report.json` (after the layout version and robocal's version, which the model writes).
#[derive(Debug, Clone, Serialize)]
pub struct CalibrationReport {
    /// The robot file (or what the table came from).
    pub robot_file: PathBuf,
    /// The measurement file (or what the rows came from).
    pub data_file: PathBuf,
    /// `config FILE`, or the default calibration.
    pub stages_from: String,
    /// How the default calibration chose its stages.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub selection: Option<Selection>,
    /// Lightest load in the data: a rigid kinematic stage uses the rows at this load; an
    /// elasto-geometric one uses every row.
    pub kinematic_load: f64,
    /// The identification.
    pub kinematic: KinematicReport,
    /// The residual stage.
    pub residual: Option<ResidualReport>,
    /// Statistics on the validation rows.
    pub validation: Option<Validation>,
    /// The bad shots found (rows far beyond the data's own spread), and whether they were left
    /// out.
    pub outliers: Option<OutlierReport>,
    /// What the repeated shots (the same readings, load and reflector measured again) say of
    /// the measurement's own spread, and the held-out error against the floor it sets.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub repeats: Option<Repeats>,
}

/// What a calibration is given.
#[derive(Debug, Clone, Copy)]
pub struct CalibrationInput<'a> {
    /// The nominal table.
    pub nominal: &'a Robot,
    /// Where it came from (for the report).
    pub robot_file: &'a Path,
    /// The training rows (`source` names them in messages and the report).
    pub data: &'a MeasurementSet,
    /// Held-out rows for early stopping and the validation statistics.
    pub validation: Option<&'a MeasurementSet>,
    /// A stage config and its file; without, the default calibration.
    pub stages: Option<(&'a Stages, &'a Path)>,
    /// What to check.
    pub checks: Checks,
    /// The default calibration's options (the orientations' weight applies to a stage config's
    /// stages too, over its `[kinematic] angle_weight`).
    pub options: &'a DefaultOptions,
}

/// A calibration's result.
#[derive(Debug)]
pub struct Calibration {
    /// The model: the identified table (named after the nominal one), the joint errors and
    /// residual the stages made, and the registered nominal table.
    pub model: CalibratedModel,
    /// `report.json`.
    pub report: CalibrationReport,
    /// The stages' results, for what the caller prints.
    pub built: Built,
    /// Why the data do not fit the robot file, when the model was made anyway (`force`).
    pub implausible: Option<String>,
}

/// Calibrates `input.nominal` on `input.data`: refuses data that do not fit the robot file
/// (unless forced), finds the bad shots (left out unless kept), runs the stage config or the
/// default calibration, and gives the model with its report.
pub fn calibrate(input: &CalibrationInput, observer: &dyn Observer) -> Result<Calibration> {
    let data = &input.data.source;
    let failed = |source: CalibrationError| CalibrationError::Failed {
        data: data.clone(),
        source: Box::new(source),
    };
    // A stage file's `[default]`: the default calibration with its options, under the ones given
    // here.
    let (stages, options, default_from) = match input.stages {
        Some((stages, file)) if stages.default.is_some() => {
            let from_file = stages.default.as_ref().expect("a [default] table");
            (None, input.options.or(from_file), Some(file))
        }
        stages => (stages, input.options.clone(), None),
    };
    options.check(stages.map(|(_, file)| file))?;
    let names = input.nominal.point_names();
    for set in std::iter::once(input.data).chain(input.validation) {
        check_targets(&set.source, set.rows.iter().map(|m| &m.sample), &names)?;
    }
    let rows: Vec<&Measurement> = input.data.rows.iter().collect();
    let val_rows: Option<Vec<&Measurement>> = input.validation.map(|v| v.rows.iter().collect());
    let val = (val_rows.as_deref())
        .zip(input.validation)
        .map(|(r, v)| (r, v.source.display().to_string()));
    let implausible = check_plausible(input.nominal, &rows).map_err(failed)?;
    if let Some(why) = &implausible
        && !input.checks.force
    {
        return Err(CalibrationError::Implausible {
            data: data.clone(),
            why: why.to_string(),
        });
    }
    let outliers = OutlierSettings {
        keep: input.checks.keep_outliers,
        ..OutlierSettings::default()
    };
    let mut built = match stages {
        Some((stages, _)) => {
            let mut stages = stages.clone();
            if options.angle_weight.is_some() {
                stages.kinematic.angle_weight = options.angle_weight;
            }
            // Where the search fits the stage's physics (least squares, compliances where the
            // rows hold several loads), its last round is the stage's fit of the rows kept:
            // the stage takes it.
            let memo = FitMemo::default();
            let (report, kept) =
                find_outliers_with(input.nominal, &rows, &stages.kinematic, &outliers, &memo)
                    .map_err(failed)?;
            let mut built = configured_with(&stages, input.nominal, &kept, val, observer, &memo)
                .map_err(failed)?;
            built.outliers = Some(report);
            built
        }
        None => {
            let auto = options.apply(AutoSettings {
                outliers: Some(outliers),
                ..AutoSettings::default()
            })?;
            automatic(&auto, input.nominal, &rows, val, observer).map_err(failed)?
        }
    };
    // Readings rounded when logged: what the rounding alone leaves (the joint Jacobian of the
    // fitted table: its tool and base, not the robot file's guesses), against what the fit leaves.
    let rounded = rounded_joints(&built.kinematic.robot, &rows);
    if let Some(w) = rounding_warning(&rounded, built.kinematic.report.after.rms) {
        built.kinematic.report.warnings.push(w);
    }
    let mut model = as_saved(built.model())?;
    // What it was calibrated on (the data file's rows: the bad shots left out lie among them).
    model.domain = robocal_model::Domain::of(rows.iter().map(|m| &m.sample));
    let validation = input.validation.map(|v| {
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
    // The measurement's own spread, from the shots taken again (the bad shots left out), and
    // the chosen model's held-out error on random folds against the floor it sets (none with a
    // validation file, which scores the candidates instead).
    let flagged: Vec<u64> = (built.outliers.iter())
        .filter(|o| o.left_out)
        .flat_map(|o| o.rows.iter().map(|r| r.line))
        .collect();
    let kept: Vec<&Measurement> = (rows.iter().copied())
        .filter(|r| r.sample.line == 0 || !flagged.contains(&r.sample.line))
        .collect();
    let repeats = repeats(&kept).map(|mut r| {
        r.held_out_over_floor = (built.selection.as_ref())
            .filter(|_| input.validation.is_none())
            .and_then(Selection::chosen)
            .and_then(|c| c.held_out.as_ref())
            .filter(|_| r.floor_mm > 0.0)
            .map(|h| h.mean / r.floor_mm);
        r
    });
    let report = CalibrationReport {
        robot_file: input.robot_file.to_path_buf(),
        data_file: data.clone(),
        stages_from: match (stages, default_from) {
            (Some((_, file)), _) => format!("config {}", file.display()),
            (None, Some(file)) => format!(
                "default with the options of config {}: the candidate with the lowest held-out error (cross-validated)",
                file.display()
            ),
            (None, None) => {
                "default: the candidate with the lowest held-out error (cross-validated)".into()
            }
        },
        selection: built.selection.clone(),
        kinematic_load: input.data.loads().first().copied().unwrap_or(0.0),
        kinematic: built.kinematic.report.clone(),
        residual: built.residual.as_ref().map(|(_, r)| r.clone()),
        validation,
        outliers: built.outliers.clone(),
        repeats,
    };
    let name = &input.nominal.name;
    model.robot.name = format!("{name} (calibrated by robocal)");
    let mut registered = built.kinematic.aligned.clone();
    registered.name = format!("{name} (nominal, base and tool registered by robocal)");
    model.nominal = Some(registered);
    Ok(Calibration {
        model,
        report,
        built,
        implausible: implausible.map(|w| w.to_string()),
    })
}

/// `model` as its files hold it: the files give angles in degrees and compliances in deg/kN·m,
/// and some doubles (about one in ten) have no such number that reads back onto them exactly;
/// they are taken as a reload takes them (a unit in the last place off), so that a saved model
/// predicts exactly as the one calibrated, reported and validated.
fn as_saved(mut model: CalibratedModel) -> Result<CalibratedModel> {
    model.robot = Robot::from_toml_str(&model.robot.to_toml_string(), "kinematics.toml")?;
    if let Some(e) = &model.joint_errors {
        let dof = model.robot.dof();
        model.joint_errors = Some(JointErrors::from_toml_str(
            &e.to_toml_string(),
            "compliance.toml",
            dof,
        )?);
    }
    Ok(model)
}
