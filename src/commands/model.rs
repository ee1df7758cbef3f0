//! The model a command predicts with: a model directory, or a robot file's table alone.

use anyhow::{Result, bail};
use robocal_model::CalibratedModel;
use robocal_robot::Robot;

use crate::cli::ModelSource;

/// Loads `--robot FILE` (the table alone) or `--model DIR`.
pub fn load(source: &ModelSource) -> Result<CalibratedModel> {
    match (&source.robot, &source.model) {
        (Some(robot), _) => Ok(CalibratedModel::kinematic(Robot::load(robot)?)),
        (None, Some(dir)) => Ok(CalibratedModel::load(dir)?),
        (None, None) => bail!("give --robot ROBOT_TOML or --model MODEL_DIR"),
    }
}
