//! The model directory (interface.md section 4) and loading the model a command predicts with.

use std::path::Path;

use anyhow::{Context, Result, bail};
use nalgebra::Vector3;
use robocal_data::Sample;
use robocal_residual::{MANIFEST, ResidualModel, inputs_of};
use robocal_robot::{Compliance, Robot};
use serde::Deserialize;

use crate::cli::ModelSource;

/// The compliance model's file in a model directory.
pub const COMPLIANCE_FILE: &str = "compliance.toml";

/// Version of the model-directory layout this build writes and reads.
pub const MODEL_FORMAT: u32 = 1;

/// A model that predicts the world position of the target point for a sample.
#[derive(Debug, Clone)]
pub struct Model {
    /// Kinematic table (nominal or identified).
    pub robot: Robot,
    /// Joint compliance under the payload (if an elasto-geometric stage ran).
    pub compliance: Option<Compliance>,
    /// What the kinematics leave, learned (if a residual stage ran).
    pub residual: Option<ResidualModel>,
}

#[derive(Deserialize)]
struct Manifest {
    model_format: Option<u32>,
    robocal_version: Option<String>,
}

impl Model {
    /// Loads `--robot FILE` or `--model DIR`.
    pub fn load(source: &ModelSource) -> Result<Self> {
        match (&source.robot, &source.model) {
            (Some(robot), _) => Ok(Self {
                robot: Robot::load(robot)?,
                compliance: None,
                residual: None,
            }),
            (None, Some(dir)) => Self::load_dir(dir),
            (None, None) => bail!("give --robot ROBOT_TOML or --model MODEL_DIR"),
        }
    }

    /// Loads a model directory written by `calibrate`, checking its format version.
    pub fn load_dir(dir: &Path) -> Result<Self> {
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
        Ok(Self {
            robot,
            compliance,
            residual,
        })
    }

    /// The geometric (and elastic) part of the prediction for a sample, mm, world frame.
    pub fn base_point(&self, s: &Sample) -> Vector3<f64> {
        let q = s.joints_rad();
        match &self.compliance {
            Some(c) => c.point(&self.robot, &q, s.load),
            None => self.robot.point(&q),
        }
    }

    /// Predicted target points, mm, world frame: kinematics (deflected by the compliance model
    /// under the sample's load), plus the residual model's error.
    pub fn predict_all<'a>(
        &self,
        samples: impl IntoIterator<Item = &'a Sample>,
    ) -> Vec<Vector3<f64>> {
        let samples: Vec<&Sample> = samples.into_iter().collect();
        let mut points: Vec<Vector3<f64>> = samples.iter().map(|s| self.base_point(s)).collect();
        if let Some(residual) = &self.residual {
            let inputs: Vec<Vec<f64>> = samples.iter().map(|s| inputs_of(s)).collect();
            for (p, e) in points.iter_mut().zip(residual.predict(&inputs)) {
                *p += Vector3::from(e);
            }
        }
        points
    }
}
