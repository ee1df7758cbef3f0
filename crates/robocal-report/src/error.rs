//! Errors of the report crate. Every variant names the file it was writing.

use std::path::PathBuf;

/// Everything that can stop a report.
#[derive(Debug, thiserror::Error)]
pub enum ReportError {
    /// A file the report reads back could not be read.
    #[error("{path}: cannot read: {source}")]
    Read {
        /// File at fault.
        path: PathBuf,
        /// Underlying error.
        source: std::io::Error,
    },
    /// A plot could not be drawn or written.
    #[error("{path}: cannot draw the plot: {message}")]
    Plot {
        /// Output file.
        path: PathBuf,
        /// What the plotting library said.
        message: String,
    },
    /// The data cannot be reported on (no rows, a value that cannot be written).
    #[error("{0}")]
    Data(String),
    /// An output could not be written.
    #[error(transparent)]
    Write(#[from] robocal_data::DataError),
}

/// Result of the report crate.
pub type Result<T> = std::result::Result<T, ReportError>;
