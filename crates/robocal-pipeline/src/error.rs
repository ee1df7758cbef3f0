//! Errors of the experiments. Every variant names the file, and the key or line where there is
//! one.

use std::path::PathBuf;

/// Everything that can stop an experiment or a stage config.
#[derive(Debug, thiserror::Error)]
pub enum PipelineError {
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
    /// A plot could not be drawn or written.
    #[error("{path}: cannot draw the plot: {message}")]
    Plot {
        /// Output file.
        path: PathBuf,
        /// What the plotting library said.
        message: String,
    },
    /// A stage cannot run on these data.
    #[error("{0}")]
    Stage(String),
    /// A robot table is bad.
    #[error(transparent)]
    Robot(#[from] robocal_robot::RobotError),
    /// A measurement file is bad, or an output could not be written.
    #[error(transparent)]
    Data(#[from] robocal_data::DataError),
    /// A twin description is bad.
    #[error(transparent)]
    Twin(#[from] robocal_twin::TwinError),
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
        source: Box<PipelineError>,
    },
}

impl From<robocal_calibration::CalibrationError> for PipelineError {
    /// The calibration's error as the same variant here: an experiment names a bad stage file's
    /// key as it names its own.
    fn from(e: robocal_calibration::CalibrationError) -> Self {
        use robocal_calibration::CalibrationError as C;
        match e {
            C::Read { path, source } => Self::Read { path, source },
            C::Key { path, key, message } => Self::Key { path, key, message },
            C::Toml(fault) => Self::Toml(fault),
            C::Stage(message) => Self::Stage(message),
            C::Robot(e) => Self::Robot(e),
            C::Data(e) => Self::Data(e),
            C::Ident(e) => Self::Ident(e),
            C::Residual(e) => Self::Residual(e),
            C::Implausible { data, why } => Self::Implausible { data, why },
            C::Failed { data, source } => Self::Failed {
                data,
                source: Box::new(Self::from(*source)),
            },
        }
    }
}

impl From<robocal_report::ReportError> for PipelineError {
    fn from(e: robocal_report::ReportError) -> Self {
        use robocal_report::ReportError as R;
        match e {
            R::Read { path, source } => Self::Read { path, source },
            R::Plot { path, message } => Self::Plot { path, message },
            R::Data(message) => Self::Stage(message),
            R::Write(e) => Self::Data(e),
        }
    }
}

pub use robocal_calibration::message;

/// Result of the experiments.
pub type Result<T> = std::result::Result<T, PipelineError>;

/// Reads a config file as text, naming it when that fails.
pub(crate) fn read_text(path: &std::path::Path) -> Result<String> {
    std::fs::read_to_string(path).map_err(|source| PipelineError::Read {
        path: path.to_path_buf(),
        source,
    })
}

impl PipelineError {
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
