//! Errors of loading and saving a model directory.

use std::path::PathBuf;

/// What can go wrong reading or writing a model directory.
#[derive(Debug, thiserror::Error)]
pub enum ModelError {
    /// The directory does not exist.
    #[error("{dir}: model directory not found")]
    NotFound {
        /// The directory given.
        dir: PathBuf,
    },
    /// The directory has no readable `report.json`.
    #[error("{file}: not a model directory written by `robocal calibrate`")]
    NotAModel {
        /// The `report.json` looked for.
        file: PathBuf,
        /// Why it could not be read.
        source: std::io::Error,
    },
    /// `report.json` is not JSON.
    #[error("{file}: invalid JSON")]
    Json {
        /// The file.
        file: PathBuf,
        /// The parser's message.
        source: serde_json::Error,
    },
    /// The directory was written in another layout version.
    #[error(
        "{file}: key `model_format`: model format {found} (written by robocal {written_by}), this robocal reads format {}",
        crate::MODEL_FORMAT
    )]
    Format {
        /// `report.json`.
        file: PathBuf,
        /// The version it declares.
        found: u32,
        /// The robocal version that wrote it, as it says (`unknown` when it does not).
        written_by: String,
    },
    /// `report.json` declares no layout version.
    #[error("{file}: key `model_format` missing")]
    NoFormat {
        /// `report.json`.
        file: PathBuf,
    },
    /// The residual model does not fit the robot.
    #[error(
        "{file}: key `inputs`: the residual model takes {inputs} inputs, the robot has {joints} joints (+ load)"
    )]
    Inputs {
        /// The residual model's manifest.
        file: PathBuf,
        /// Inputs it takes.
        inputs: usize,
        /// Joints of the robot.
        joints: usize,
    },
    /// The registered nominal table does not fit the identified one.
    #[error("{file}: the nominal table has {nominal} joints, the identified table {joints}")]
    Nominal {
        /// `nominal.toml`.
        file: PathBuf,
        /// Joints of the nominal table.
        nominal: usize,
        /// Joints of the identified table.
        joints: usize,
    },
    /// A file of the directory could not be read.
    #[error("{file}: cannot read: {source}")]
    Read {
        /// The file.
        file: PathBuf,
        /// Why.
        source: std::io::Error,
    },
    /// `covariance.json` holds a bad value, or names a parameter the model lacks.
    #[error("{file}: key `{key}`: {message}")]
    Covariance {
        /// `covariance.json`.
        file: PathBuf,
        /// The key at fault.
        key: String,
        /// What is wrong.
        message: String,
    },
    /// `domain.toml` or `motion.toml` holds a bad value.
    #[error("{file}: key `{key}`: {message}")]
    Domain {
        /// The file.
        file: PathBuf,
        /// The key at fault.
        key: String,
        /// What is wrong.
        message: String,
    },
    /// `domain.toml` or `motion.toml` is not TOML of its form.
    #[error("{file}: {message}")]
    DomainToml {
        /// The file.
        file: PathBuf,
        /// The parser's message (with its line and column).
        message: String,
    },
    /// The report could not be serialised.
    #[error("{file}: cannot write the report: {source}")]
    Report {
        /// `report.json` in the output directory.
        file: PathBuf,
        /// The serialiser's message.
        source: serde_json::Error,
    },
    /// The kinematic table or the joint-error file.
    #[error(transparent)]
    Robot(#[from] robocal_robot::RobotError),
    /// The residual model's files.
    #[error(transparent)]
    Residual(#[from] robocal_residual::ResidualError),
    /// Writing the directory.
    #[error(transparent)]
    Data(#[from] robocal_data::DataError),
}

/// Result with [`ModelError`].
pub type Result<T> = std::result::Result<T, ModelError>;
