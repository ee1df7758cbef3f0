//! Stage configs (`robocal calibrate --config FILE`, and each `[[model]]` of an experiment): the
//! kinematic stage (with joint compliances when `[compliance]` is present), then an optional
//! residual stage, raw and validated.

use robocal_data::Invalid;
use std::path::Path;

use robocal_ident::{KinematicSettings, RawComplianceStage, RawJointErrorStage, RawKinematicStage};
use robocal_residual::{Defaults, RawResidualStage, ResidualStage};
use serde::Deserialize;

use crate::error::{CalibrationError, Result, read_text};
use crate::options::DefaultOptions;

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
    /// `[default]`: the default calibration with these options, which chooses its own stages
    /// (the file then holds no other table).
    pub default: Option<DefaultOptions>,
}

/// Validated stages, in the order they run.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Stages {
    /// Kinematic identification.
    pub kinematic: KinematicSettings,
    /// Residual learning on what the kinematics leave, if any.
    pub residual: Option<ResidualStage>,
    /// The default calibration's options, where the file asks for the default instead of
    /// stages of its own.
    pub default: Option<DefaultOptions>,
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
        if let Some(default) = &self.default {
            let (k, c, j, r) = (
                self.kinematic.is_some(),
                self.compliance.is_some(),
                self.joint_errors.is_some(),
                self.residual.is_some(),
            );
            if k || c || j || r {
                return Err(Invalid::new(
                    "default",
                    "the default calibration chooses its own stages: a file with [default] holds no [kinematic], [compliance], [joint_errors] or [residual]",
                ));
            }
            default
                .check(None)
                .map_err(|e| Invalid::new("default", e.to_string()))?;
            return Ok(Stages {
                default: Some(default.clone()),
                ..Stages::default()
            });
        }
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
            default: None,
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

#[cfg(test)]
mod tests {
    use super::*;

    fn parsed(text: &str) -> std::result::Result<Stages, Invalid> {
        let raw: RawStages =
            toml::from_str(text).map_err(|e| Invalid::new("toml", e.to_string()))?;
        raw.validate(None, Defaults::Robocal)
    }

    /// A `[default]` table holds the default calibration's options, read as the command line
    /// and Python take them; with a stage of its own, an unknown option, or a value out of
    /// range, it is refused, named.
    #[test]
    fn a_default_table_holds_the_options_and_nothing_else() {
        let stages = parsed("[default]\nbudget = 30\ntilt = true\nrunout = 0\n").unwrap();
        assert_eq!(
            stages.default,
            Some(DefaultOptions {
                budget: Some(30.0),
                tilt: true,
                runout: Some(0),
                ..DefaultOptions::default()
            })
        );
        let mixed = parsed("[default]\nbudget = 30\n[kinematic]\nsolver = \"lm\"\n");
        assert_eq!(mixed.unwrap_err().key, "default");
        assert!(parsed("[default]\nbudgett = 30\n").is_err());
        let negative = parsed("[default]\nbudget = -1\n").unwrap_err();
        assert_eq!(negative.key, "default");
        assert!(
            negative.message.contains("-1 is not a positive number"),
            "{negative:?}"
        );
        let frame = parsed("[default]\nresidual_frame = \"tool\"\n").unwrap_err();
        assert!(frame.message.contains("`tool` is not a frame"), "{frame:?}");
    }
}
