//! The model directory (`docs/formats.md`, "Model directory"): its layout version and every file name.
//!
//! ```text
//! MODEL_DIR/
//!   kinematics.toml   the identified table, in the robot file's format
//!   compliance.toml   joint errors (payload compliance, harmonics, self-weight), when identified
//!   residual.json     the residual model's manifest, and its network files, when learned
//!   nominal.toml      the nominal table with base and tool registered in the tracker frame
//!                     (the arm before calibration), when the calibration gives one
//!   domain.toml       the joint readings and loads the model was calibrated on (rows outside
//!                     are extrapolation, warned of), when the calibration gives one
//!   covariance.json   the identified parameters' covariance (a physical model's predicted
//!                     points' standard deviations), when the identification gives one
//!   motion.toml       the play that follows the order of motion, when the calibration keeps it
//!   report.json       model_format, robocal_version, then what the calibration reports
//! ```

use std::path::Path;

use robocal_data::{write_dir_atomically, write_text_in};
use robocal_residual::{MANIFEST, ResidualModel};
use robocal_robot::{JointErrors, ParameterCovariance, Robot};
use serde::{Deserialize, Serialize};

use crate::domain::{DOMAIN_FILE, Domain};
use crate::error::{ModelError, Result};
use crate::model::CalibratedModel;
use crate::motion::{MOTION_FILE, MotionPlay};

/// Version of the model-directory layout this build writes and reads.
pub const MODEL_FORMAT: u32 = 1;
/// The identified kinematic table.
pub const KINEMATICS_FILE: &str = "kinematics.toml";
/// The joint-error model.
pub const COMPLIANCE_FILE: &str = "compliance.toml";
/// The nominal table registered in the tracker frame: the arm before calibration.
pub const NOMINAL_FILE: &str = "nominal.toml";
/// The identified parameters' covariance.
pub const COVARIANCE_FILE: &str = "covariance.json";
/// The calibration's report, which carries the layout version.
pub const REPORT_FILE: &str = "report.json";

/// The keys of `report.json` a reader checks before anything else.
#[derive(Deserialize)]
struct Manifest {
    model_format: Option<u32>,
    robocal_version: Option<String>,
}

/// `report.json`: the layout version and the writer's version first, then the calibration's
/// own report.
#[derive(Serialize)]
struct Stamped<'a, R> {
    model_format: u32,
    robocal_version: &'static str,
    #[serde(flatten)]
    report: &'a R,
}

impl CalibratedModel {
    /// Writes the model directory `out` atomically (a complete new directory, or nothing):
    /// the table, the joint errors and the residual model when there are any, and
    /// `report.json` — `model_format` and `robocal_version`, then the fields of `report` (a
    /// value that serialises to a JSON object).
    pub fn save<R: Serialize>(&self, out: &Path, report: &R) -> Result<()> {
        let json = serde_json::to_string_pretty(&Stamped {
            model_format: MODEL_FORMAT,
            robocal_version: env!("CARGO_PKG_VERSION"),
            report,
        })
        .map_err(|source| ModelError::Report {
            file: out.join(REPORT_FILE),
            source,
        })? + "\n";
        write_dir_atomically(out, |dir| -> Result<()> {
            write_text_in(dir, out, KINEMATICS_FILE, &self.robot.to_toml_string())?;
            if let Some(e) = &self.joint_errors {
                write_text_in(dir, out, COMPLIANCE_FILE, &e.to_toml_string())?;
            }
            if let Some(residual) = &self.residual {
                residual.save(dir)?;
            }
            if let Some(nominal) = &self.nominal {
                write_text_in(dir, out, NOMINAL_FILE, &nominal.to_toml_string())?;
            }
            if let Some(domain) = &self.domain {
                write_text_in(dir, out, DOMAIN_FILE, &domain.to_toml_string())?;
            }
            if let Some(motion) = &self.motion {
                write_text_in(dir, out, MOTION_FILE, &motion.to_toml_string())?;
            }
            if let Some(covariance) = &self.covariance {
                let text = serde_json::to_string_pretty(covariance).map_err(|source| {
                    ModelError::Json {
                        file: out.join(COVARIANCE_FILE),
                        source,
                    }
                })? + "\n";
                write_text_in(dir, out, COVARIANCE_FILE, &text)?;
            }
            write_text_in(dir, out, REPORT_FILE, &json)?;
            Ok(())
        })
    }

    /// Reads a model directory written by [`Self::save`], checking its layout version and that
    /// its parts fit one another.
    pub fn load(dir: &Path) -> Result<Self> {
        if !dir.is_dir() {
            return Err(ModelError::NotFound {
                dir: dir.to_path_buf(),
            });
        }
        let file = dir.join(REPORT_FILE);
        let text = std::fs::read_to_string(&file).map_err(|source| ModelError::NotAModel {
            file: file.clone(),
            source,
        })?;
        let manifest: Manifest =
            serde_json::from_str(&text).map_err(|source| ModelError::Json {
                file: file.clone(),
                source,
            })?;
        match manifest.model_format {
            Some(MODEL_FORMAT) => {}
            Some(found) => {
                return Err(ModelError::Format {
                    file,
                    found,
                    written_by: manifest.robocal_version.unwrap_or("unknown".into()),
                });
            }
            None => return Err(ModelError::NoFormat { file }),
        }
        let robot = Robot::load(dir.join(KINEMATICS_FILE))?;
        let errors_file = dir.join(COMPLIANCE_FILE);
        let joint_errors = errors_file
            .exists()
            .then(|| JointErrors::load(&errors_file, robot.dof()))
            .transpose()?;
        let residual = if dir.join(MANIFEST).exists() {
            let model = ResidualModel::load(dir)?;
            if model.inputs != robot.dof() + 1 {
                return Err(ModelError::Inputs {
                    file: dir.join(MANIFEST),
                    inputs: model.inputs,
                    joints: robot.dof(),
                });
            }
            Some(model)
        } else {
            None
        };
        let nominal_file = dir.join(NOMINAL_FILE);
        let nominal = if nominal_file.exists() {
            let nominal = Robot::load(&nominal_file)?;
            if nominal.dof() != robot.dof() {
                return Err(ModelError::Nominal {
                    file: nominal_file,
                    nominal: nominal.dof(),
                    joints: robot.dof(),
                });
            }
            Some(nominal)
        } else {
            None
        };
        let domain_file = dir.join(DOMAIN_FILE);
        let domain = (domain_file.exists())
            .then(|| Domain::load(&domain_file, robot.dof()))
            .transpose()?;
        let covariance = load_covariance(dir, &robot, joint_errors.as_ref())?;
        let motion_file = dir.join(MOTION_FILE);
        let motion = (motion_file.exists())
            .then(|| MotionPlay::load(&motion_file, robot.dof()))
            .transpose()?;
        Ok(Self {
            nominal,
            domain,
            covariance,
            motion,
            ..Self::new(robot, joint_errors, residual)
        })
    }
}

/// `covariance.json` of the model directory `dir`, when there is one: checked, and every name
/// found among the parameters of `robot` and `errors`.
fn load_covariance(
    dir: &Path,
    robot: &Robot,
    errors: Option<&JointErrors>,
) -> Result<Option<ParameterCovariance>> {
    let file = dir.join(COVARIANCE_FILE);
    if !file.exists() {
        return Ok(None);
    }
    let text = std::fs::read_to_string(&file).map_err(|source| ModelError::Read {
        file: file.clone(),
        source,
    })?;
    let covariance: ParameterCovariance =
        serde_json::from_str(&text).map_err(|source| ModelError::Json {
            file: file.clone(),
            source,
        })?;
    let fault = |key: String, message: String| ModelError::Covariance {
        file: file.clone(),
        key,
        message,
    };
    covariance
        .check()
        .map_err(|(key, message)| fault(key, message))?;
    covariance
        .resolve(robot, errors)
        .map_err(|message| fault("parameters".into(), message))?;
    Ok(Some(covariance))
}
