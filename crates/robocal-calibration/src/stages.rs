//! Stage configs (`robocal calibrate --config FILE`, and each `[[model]]` of an experiment): the
//! kinematic stage (with joint compliances when `[compliance]` is present), then an optional
//! residual stage, raw and validated.

use robocal_data::Invalid;
use std::path::Path;

use robocal_ident::{KinematicSettings, RawComplianceStage, RawJointErrorStage, RawKinematicStage};
use robocal_residual::{Defaults, RawResidualStage, ResidualStage};
use serde::Deserialize;

use crate::error::{CalibrationError, Result, read_text};

/// A stage config as written.
#[derive(Debug, Clone, Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub struct RawStages {
    /// `[kinematic]`; absent: the defaults (LM, every parameter).
    pub kinematic: Option<RawKinematicStage>,
    /// `[compliance]`; absent: a rigid arm. Present: joint compliances are identified with the
    /// geometry, on the points of every load.
    pub compliance: Option<RawComplianceStage>,
    /// `[joint_errors]`; absent: none. Present: transmission harmonics (and, if asked,
    /// self-weight terms) are identified with the geometry.
    pub joint_errors: Option<RawJointErrorStage>,
    /// `[residual]`; absent: no residual model.
    pub residual: Option<RawResidualStage>,
}

/// Validated stages, in the order they run.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Stages {
    /// Kinematic identification.
    pub kinematic: KinematicSettings,
    /// Residual learning on what the kinematics leave, if any.
    pub residual: Option<ResidualStage>,
}

impl RawStages {
    /// Validates; errors give the key relative to the stage table (`kinematic.solver`,
    /// `residual.x.learning_rate`). `seed` is the residual seed when the stage gives none;
    /// `defaults` fill the residual settings it leaves out (robocal's in a stage file, the
    /// paper's in an experiment).
    pub fn validate(
        &self,
        seed: Option<u64>,
        defaults: Defaults,
    ) -> std::result::Result<Stages, Invalid> {
        let mut kinematic = self.kinematic.clone().unwrap_or_default().validate()?;
        kinematic.compliance = self
            .compliance
            .as_ref()
            .map(RawComplianceStage::validate)
            .transpose()?;
        kinematic.joint_errors = self
            .joint_errors
            .as_ref()
            .map(RawJointErrorStage::validate)
            .transpose()?;
        if let (Some(je), Some(c)) = (&mut kinematic.joint_errors, &kinematic.compliance) {
            je.gravity = c.gravity;
        }
        // Terms that act through, or start from, the joint compliances.
        if let (Some(je), None) = (&kinematic.joint_errors, &kinematic.compliance) {
            for (asked, key, why) in [
                (
                    je.link_weights,
                    "joint_errors.link_weights",
                    "the links' weights act through the joint compliances: add [compliance]",
                ),
                (
                    je.tilt,
                    "joint_errors.tilt",
                    "the tilts start from the joint compliances and meet the same moments: add [compliance]",
                ),
            ] {
                if asked {
                    return Err(Invalid::new(key, why));
                }
            }
        }
        let residual = match &self.residual {
            None => None,
            Some(raw) => {
                let mut stage = raw.validate(defaults)?;
                if let (None, Some(seed)) = (raw.seed, seed) {
                    stage.settings.seed = seed;
                }
                Some(stage)
            }
        };
        Ok(Stages {
            kinematic,
            residual,
        })
    }
}

impl Stages {
    /// Reads and validates a stage config file.
    pub fn load(path: &Path) -> Result<Self> {
        let text = read_text(path)?;
        let raw: RawStages =
            toml::from_str(&text).map_err(|e| CalibrationError::toml(path, &text, &e))?;
        raw.validate(None, Defaults::Robocal)
            .map_err(|e| CalibrationError::invalid(path, e))
    }
}
