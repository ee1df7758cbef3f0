//! Loading the model a command predicts with.

use std::path::Path;

use anyhow::{Context, Result, bail};
use nalgebra::Vector3;
use robocal_data::Sample;
use robocal_robot::Robot;

use crate::cli::ModelSource;

/// A model that predicts the world position of the target point for a sample.
#[derive(Debug, Clone)]
pub struct Model {
    /// Kinematic table (nominal or identified).
    pub robot: Robot,
}

impl Model {
    /// Loads `--robot FILE` or `--model DIR` (its `kinematics.toml`).
    pub fn load(source: &ModelSource) -> Result<Self> {
        match (&source.robot, &source.model) {
            (Some(robot), _) => Ok(Self {
                robot: Robot::load(robot)?,
            }),
            (None, Some(dir)) => Self::load_dir(dir),
            (None, None) => bail!("give --robot ROBOT_TOML or --model MODEL_DIR"),
        }
    }

    fn load_dir(dir: &Path) -> Result<Self> {
        if !dir.is_dir() {
            bail!("{}: model directory not found", dir.display());
        }
        let kin = dir.join("kinematics.toml");
        let robot = Robot::load(&kin)
            .with_context(|| format!("{}: cannot load the model", dir.display()))?;
        Ok(Self { robot })
    }

    /// Predicted target point, mm, world frame.
    pub fn predict(&self, sample: &Sample) -> Vector3<f64> {
        self.robot.point(&sample.joints_rad())
    }
}
