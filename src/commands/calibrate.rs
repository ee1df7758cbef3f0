//! `robocal calibrate`: identify a model from measurements and write the model directory.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result, anyhow};
use robocal_data::{ErrorStats, MeasurementSet, write_dir_atomically, write_text_in};
use robocal_ident::{
    KinematicReport, KinematicSettings, Observations, RawKinematicStage, calibrate_kinematics,
};
use robocal_robot::Robot;
use serde::{Deserialize, Serialize};

use super::model::MODEL_FORMAT;

/// A stage config as written (`--config FILE`).
#[derive(Debug, Deserialize, Default)]
#[serde(deny_unknown_fields)]
struct RawStages {
    kinematic: Option<RawKinematicStage>,
}

/// Reads and validates a stage config.
fn load_stages(path: Option<&Path>) -> Result<KinematicSettings> {
    let Some(path) = path else {
        return Ok(KinematicSettings::default());
    };
    let text = std::fs::read_to_string(path)
        .with_context(|| format!("{}: cannot read the stage config", path.display()))?;
    let raw: RawStages =
        toml::from_str(&text).map_err(|e| anyhow!(robocal_robot::toml_error(path, &text, &e)))?;
    raw.kinematic
        .unwrap_or_default()
        .validate()
        .map_err(|(key, message)| anyhow!("{}: key `{key}`: {message}", path.display()))
}

/// Before/after statistics on the validation file.
#[derive(Debug, Serialize)]
struct Validation {
    file: PathBuf,
    before: ErrorStats,
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
    let settings = load_stages(config)?;
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
    let cal = calibrate_kinematics(&nominal, &obs, &settings)
        .with_context(|| format!("{}: calibration failed", data.display()))?;
    let validation = validation.map(|v| {
        let obs = Observations::from_set(&v);
        Validation {
            file: v.source.clone(),
            before: ErrorStats::from_errors(&obs.errors(&cal.aligned)),
            after: ErrorStats::from_errors(&obs.errors(&cal.robot)),
        }
    });
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
    if let Some(v) = &validation {
        eprintln!(
            "robocal: validation {}: mean {:.4} → {:.4} mm",
            v.file.display(),
            v.before.mean,
            v.after.mean
        );
    }
    let report = Report {
        model_format: MODEL_FORMAT,
        robocal_version: env!("CARGO_PKG_VERSION"),
        robot_file: robot.to_path_buf(),
        data_file: data.to_path_buf(),
        kinematic_load: lightest,
        kinematic: cal.report.clone(),
        validation,
    };
    let mut calibrated = cal.robot.clone();
    calibrated.name = format!("{} (calibrated by robocal)", nominal.name);
    let json = serde_json::to_string_pretty(&report)? + "\n";
    write_dir_atomically(out, |dir| {
        write_text_in(dir, out, "kinematics.toml", &calibrated.to_toml_string())?;
        write_text_in(dir, out, "report.json", &json)
    })?;
    Ok(())
}
