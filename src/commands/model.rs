//! The model directory (interface.md section 4) and loading the model a command predicts with.

use std::path::Path;

use anyhow::{Context, Result, bail};
use robocal_pipeline::Predictor;
use robocal_residual::{MANIFEST, ResidualModel};
use robocal_robot::{Compliance, Robot};
use serde::Deserialize;

use crate::cli::ModelSource;

/// The compliance model's file in a model directory.
pub const COMPLIANCE_FILE: &str = "compliance.toml";

/// Version of the model-directory layout this build writes and reads.
pub const MODEL_FORMAT: u32 = 1;

#[derive(Deserialize)]
struct Manifest {
    model_format: Option<u32>,
    robocal_version: Option<String>,
}

/// Loads `--robot FILE` (the table alone) or `--model DIR`.
pub fn load(source: &ModelSource) -> Result<Predictor> {
    match (&source.robot, &source.model) {
        (Some(robot), _) => Ok(Predictor {
            robot: Robot::load(robot)?,
            compliance: None,
            residual: None,
        }),
        (None, Some(dir)) => load_dir(dir),
        (None, None) => bail!("give --robot ROBOT_TOML or --model MODEL_DIR"),
    }
}

/// Loads a model directory written by `calibrate`, checking its format version.
pub fn load_dir(dir: &Path) -> Result<Predictor> {
    if !dir.is_dir() {
        bail!("{}: model directory not found", dir.display());
    }
    let report = dir.join("report.json");
    let text = std::fs::read_to_string(&report).with_context(|| {
        format!(
            "{}: not a model directory written by `robocal calibrate`",
            report.display()
        )
    })?;
    let manifest: Manifest = serde_json::from_str(&text)
        .with_context(|| format!("{}: invalid JSON", report.display()))?;
    match manifest.model_format {
        Some(MODEL_FORMAT) => {}
        Some(other) => bail!(
            "{}: key `model_format`: model format {other} (written by robocal {}), this robocal reads format {MODEL_FORMAT}",
            report.display(),
            manifest.robocal_version.as_deref().unwrap_or("unknown")
        ),
        None => bail!("{}: key `model_format` missing", report.display()),
    }
    let robot = Robot::load(dir.join("kinematics.toml"))?;
    let compliance_file = dir.join(COMPLIANCE_FILE);
    let compliance = compliance_file
        .exists()
        .then(|| Compliance::load(&compliance_file, robot.dof()))
        .transpose()?;
    let residual = if dir.join(MANIFEST).exists() {
        let model = ResidualModel::load(dir)?;
        if model.inputs != robot.dof() + 1 {
            bail!(
                "{}: key `inputs`: the residual model takes {} inputs, the robot has {} joints (+ load)",
                dir.join(MANIFEST).display(),
                model.inputs,
                robot.dof()
            );
        }
        Some(model)
    } else {
        None
    };
    Ok(Predictor {
        robot,
        compliance,
        residual,
    })
}
