//! Errors of the calibration library. Every variant names the file, and the key or line where there is
//! one.

use std::path::PathBuf;

/// Everything that can stop a calibration or a stage config.
#[derive(Debug, thiserror::Error)]
pub enum CalibrationError {
    /// A config file could not be read.
    #[error("{path}: cannot read: {source}")]
    Read {
        /// File at fault.
        path: PathBuf,
        /// Underlying error.
        source: std::io::Error,
    },
    /// A key has an unacceptable value (also: a value the data contradict).
    #[error("{path}: key `{key}`: {message}")]
    Key {
        /// File at fault.
        path: PathBuf,
        /// Dotted key, e.g. `model[2].residual.x.learning_rate`.
        key: String,
        /// Why.
        message: String,
    },
    /// A config file is not valid TOML, or has an unknown, missing or mistyped key.
    #[error(transparent)]
    Toml(robocal_robot::TomlFault),
    /// A stage cannot run on these data.
    #[error("{0}")]
    Stage(String),
    /// A robot table is bad.
    #[error(transparent)]
    Robot(#[from] robocal_robot::RobotError),
    /// A measurement file is bad, or an output could not be written.
    #[error(transparent)]
    Data(#[from] robocal_data::DataError),
    /// Kinematic identification failed.
    #[error(transparent)]
    Ident(#[from] robocal_ident::IdentError),
    /// Residual learning failed.
    #[error(transparent)]
    Residual(#[from] robocal_residual::ResidualError),
    /// The data do not fit the robot file (units, frame, joint order), and the calibration was
    /// not forced.
    #[error(
        "{data}: {why}; nothing written (force writes the model anyway: `--force`, or `force=True` in Python)"
    )]
    Implausible {
        /// The measurement file.
        data: PathBuf,
        /// What does not fit, and the likely cause.
        why: String,
    },
    /// A calibration stage failed on the data.
    #[error("{data}: calibration failed")]
    Failed {
        /// The measurement file.
        data: PathBuf,
        /// Why.
        #[source]
        source: Box<CalibrationError>,
    },
}

/// An error and its causes as one line, each cause once: errors quote their source already
/// (`{path}: cannot read: {source}`), so a cause whose text is in the message is not repeated.
/// The command line and the Python bindings show errors this way.
pub fn message(err: &(dyn std::error::Error + 'static)) -> String {
    let mut text = String::new();
    let mut cause = Some(err);
    while let Some(c) = cause {
        let part = c.to_string();
        if !text.contains(&part) {
            if !text.is_empty() {
                text.push_str(": ");
            }
            text.push_str(&part);
        }
        cause = c.source();
    }
    text
}

/// Result of the calibration library.
pub type Result<T> = std::result::Result<T, CalibrationError>;

/// Reads a config file as text, naming it when that fails.
pub fn read_text(path: &std::path::Path) -> Result<String> {
    std::fs::read_to_string(path).map_err(|source| CalibrationError::Read {
        path: path.to_path_buf(),
        source,
    })
}

impl CalibrationError {
    /// The TOML error `err` of the file at `path`, whose text is `text`.
    pub fn toml(path: &std::path::Path, text: &str, err: &toml::de::Error) -> Self {
        Self::Toml(robocal_robot::TomlFault::of(path, text, err))
    }

    /// A setting of the file at `path` with an unacceptable value.
    pub fn invalid(path: &std::path::Path, invalid: robocal_data::Invalid) -> Self {
        Self::Key {
            path: path.to_path_buf(),
            key: invalid.key,
            message: invalid.message,
        }
    }
}
