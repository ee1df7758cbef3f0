//! Errors of the twin crate.

use std::path::PathBuf;

/// Everything that can be wrong with a twin description or its generation.
#[derive(Debug, thiserror::Error)]
pub enum TwinError {
    /// The twin file could not be read.
    #[error("{path}: cannot read the twin file: {source}")]
    Io {
        /// File at fault.
        path: PathBuf,
        /// Underlying error.
        source: std::io::Error,
    },
    /// The twin file is not valid TOML, or has an unknown, missing or mistyped key.
    #[error(transparent)]
    Toml(robocal_robot::TomlFault),
    /// A robot table (the nominal file, or the embedded truth) is bad.
    #[error(transparent)]
    Robot(#[from] robocal_robot::RobotError),
    /// A key has an unacceptable value.
    #[error("{path}: key `{key}`: {message}")]
    InvalidValue {
        /// File at fault.
        path: PathBuf,
        /// Dotted key.
        key: String,
        /// Why.
        message: String,
    },
    /// No grid point could be reached by the nominal robot.
    #[error(
        "{path}: [poses]: no grid point is reachable within the joint limits away from singularities"
    )]
    NoReachablePose {
        /// File at fault.
        path: PathBuf,
    },
    /// Writing the dataset failed.
    #[error(transparent)]
    Data(#[from] robocal_data::DataError),
}

/// Result with [`TwinError`].
pub type Result<T> = std::result::Result<T, TwinError>;
