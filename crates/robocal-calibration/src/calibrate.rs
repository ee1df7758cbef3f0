//! The whole of `calibrate` — the plausibility check, the bad shots, the stages (a stage config
//! or the default), the model and `report.json` — shared by the command line and the Python
//! bindings, so that both make the same model from the same rows.

use std::path::{Path, PathBuf};

use robocal_data::{ErrorStats, Measurement, MeasurementSet, Observer, check_targets};
use robocal_ident::{FitMemo, KinematicReport};
use robocal_model::CalibratedModel;
use robocal_residual::Frame;
use robocal_robot::{JointErrors, Robot};
use serde::Serialize;

use crate::error::{CalibrationError, Result};
use crate::stages::Stages;
use crate::{
    AutoSettings, Built, DEFAULT_BUDGET_SECONDS, OutlierReport, OutlierSettings, Repeats,
    ResidualReport, Selection, check_plausible, configured_with, find_outliers_with,
    readings::{rounded_joints, rounding_warning},
    repeats::repeats,
    select::automatic,
};

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
    /// Weight of a 6-DoF probe's orientation residuals, mm per deg (over a stage config's
    /// `[kinematic] angle_weight`); `None`: the settings' own (default `noise_mm / noise_deg`).
    pub angle_weight: Option<f64>,
    /// The default calibration's time budget, s (`None`: [`DEFAULT_BUDGET_SECONDS`]); a stage
    /// config runs what it asks for and takes none.
    pub budget_seconds: Option<f64>,
    /// Whether the default calibration keeps its budget by counted work instead of the clock
    /// ([`AutoSettings::reproducible`]).
    pub reproducible: bool,
    /// Whether the default calibration also tries the bearings' tilt, last, on the physics it
    /// chose ([`AutoSettings::tilt`]); a stage config asks for it in `[joint_errors]`.
    pub tilt: bool,
    /// Whether the default calibration also tries backlash with its flanks searched where the
    /// physics it chose holds none ([`AutoSettings::flank_search`]); a stage config asks for
    /// it with `backlash` and `flank_search` in `[joint_errors]`.
    pub flank_search: bool,
    /// The highest order of the axis runouts the default calibration tries (0: none;
    /// [`AutoSettings::runout`]; `None`: its default); a stage config asks for them with
    /// `runout` in `[joint_errors]`.
    pub runout: Option<u32>,
    /// The frame the default calibration's residual models learn in (`None`: each candidate's
    /// own, [`AutoSettings::residuals`]); a stage config asks for it with `frame` in
    /// `[residual]`.
    pub residual_frame: Option<Frame>,
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
    if let Some(b) = input.budget_seconds {
        if !(b.is_finite() && b > 0.0) {
            return Err(CalibrationError::Stage(format!(
                "the time budget (`--budget`, or `budget=` in Python): {b} is not a positive number of seconds"
            )));
        }
        if let Some((_, file)) = input.stages {
            return Err(CalibrationError::Stage(format!(
                "the time budget (`--budget`, or `budget=` in Python) is the default calibration's; {} runs the stages it names and takes none",
                file.display()
            )));
        }
    }
    if let (Some(frame), Some((_, file))) = (input.residual_frame, input.stages) {
        return Err(CalibrationError::Stage(format!(
            "`--residual-frame` (or `residual_frame=` in Python) is the default calibration's; {} runs the stages it names: add `frame = \"{}\"` to its [residual]",
            file.display(),
            frame.name()
        )));
    }
    if let (true, Some((_, file))) = (input.tilt, input.stages) {
        return Err(CalibrationError::Stage(format!(
            "`--tilt` (or `tilt=True` in Python) is the default calibration's; {} runs the stages it names: add `tilt = true` to its [joint_errors]",
            file.display()
        )));
    }
    if let Some(r) = input.runout
        && r > robocal_ident::MAX_HARMONICS
    {
        return Err(CalibrationError::Stage(format!(
            "--runout: {r} orders; at most {}",
            robocal_ident::MAX_HARMONICS
        )));
    }
    if let (Some(_), Some((_, file))) = (input.runout, input.stages) {
        return Err(CalibrationError::Stage(format!(
            "`--runout` is the default calibration's; {} runs the stages it names: add `runout = 2` to its [joint_errors]",
            file.display()
        )));
    }
    if let (true, Some((_, file))) = (input.flank_search, input.stages) {
        return Err(CalibrationError::Stage(format!(
            "`--flank-search` (or `flank_search=True` in Python) is the default calibration's; {} runs the stages it names: add `backlash = true` and `flank_search = true` to its [joint_errors]",
            file.display()
        )));
    }
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
    let mut built = match input.stages {
        Some((stages, _)) => {
            let mut stages = stages.clone();
            if input.angle_weight.is_some() {
                stages.kinematic.angle_weight = input.angle_weight;
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
            let mut auto = AutoSettings {
                outliers: Some(outliers),
                angle_weight: input.angle_weight,
                budget_seconds: input.budget_seconds.unwrap_or(DEFAULT_BUDGET_SECONDS),
                reproducible: input.reproducible,
                tilt: input.tilt,
                flank_search: input.flank_search,
                ..AutoSettings::default()
            };
            if let Some(orders) = input.runout {
                auto.runout = orders;
            }
            if let Some(frame) = input.residual_frame {
                for stage in &mut auto.residuals {
                    stage.settings.frame = frame;
                }
                auto.both_frames_off_gravity = false;
            }
            automatic(&auto, input.nominal, &rows, val, observer).map_err(failed)?
        }
    };
    // Readings rounded when logged: what the rounding alone leaves (the joint Jacobian of the
    // fitted table: its tool and base, not the robot file's guesses), against what the fit leaves.
    let rounded = rounded_joints(&built.kinematic.robot, &rows);
    if let Some(w) = rounding_warning(&rounded, built.kinematic.report.after.rms) {
        built.kinematic.report.warnings.push(w);
    }
    let mut model = built.model();
    // The model as its files hold it: the files give angles in degrees and compliances in
    // deg/kN·m, and some doubles (about one in ten) have no such number that reads back onto
    // them exactly; they are taken as a reload takes them (a unit in the last place off), so
    // that a saved model predicts exactly as the one calibrated, reported and validated here.
    model.robot = Robot::from_toml_str(&model.robot.to_toml_string(), "kinematics.toml")?;
    if let Some(e) = &model.joint_errors {
        let dof = model.robot.dof();
        model.joint_errors = Some(JointErrors::from_toml_str(
            &e.to_toml_string(),
            "compliance.toml",
            dof,
        )?);
    }
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
        stages_from: match input.stages {
            Some((_, file)) => format!("config {}", file.display()),
            None => {
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
