//! Errors of the experiments: the calibration library's (a file, a key, a stage, a fit), a
//! twin's, a report's.

use robocal_calibration::CalibrationError;
use robocal_report::ReportError;

pub use robocal_calibration::message;

/// Everything that can stop an experiment.
#[derive(Debug, thiserror::Error)]
pub enum PipelineError {
    /// A file cannot be read, a key has an unacceptable value, a stage cannot run, or a fit
    /// failed (every variant names the file, and the key or line where there is one).
    #[error(transparent)]
    Calibration(#[from] CalibrationError),
    /// A twin description is bad.
    #[error(transparent)]
    Twin(#[from] robocal_twin::TwinError),
    /// A figure or a report file could not be written.
    #[error(transparent)]
    Report(#[from] ReportError),
}

/// The errors of the crates below, as the calibration library takes them.
macro_rules! through_calibration {
    ($($error:ty),*) => {$(
        impl From<$error> for PipelineError {
            fn from(e: $error) -> Self {
                Self::Calibration(e.into())
            }
        }
    )*};
}

through_calibration!(
    robocal_robot::RobotError,
    robocal_data::DataError,
    robocal_ident::IdentError,
    robocal_residual::ResidualError
);

/// Result of the experiments.
pub type Result<T> = std::result::Result<T, PipelineError>;

/// The error of a key of the file at `path`.
pub(crate) fn key(
    path: &std::path::Path,
    key: impl Into<String>,
    message: impl Into<String>,
) -> PipelineError {
    invalid(path, robocal_data::Invalid::new(key, message))
}

/// A setting of the file at `path` with an unacceptable value.
pub(crate) fn invalid(path: &std::path::Path, invalid: robocal_data::Invalid) -> PipelineError {
    CalibrationError::invalid(path, invalid).into()
}
