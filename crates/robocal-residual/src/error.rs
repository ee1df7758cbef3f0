//! Errors of residual learning.

use std::path::PathBuf;

/// What can go wrong training, saving or loading a residual model.
#[derive(Debug, thiserror::Error)]
pub enum ResidualError {
    /// A file could not be read or written.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The cause.
        source: std::io::Error,
    },
    /// A saved model is malformed or from another format version.
    #[error("{path}: {message}")]
    Format {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
    /// Settings that cannot be trained (the message names the field).
    #[error("residual settings: {}: {}", .0.key, .0.message)]
    Settings(robocal_data::Invalid),
    /// The data cannot train this model.
    #[error("residual training: {0}")]
    Data(String),
    /// CA-SOMM's classes leave one of its two sets (`A` or `B`) with fewer than two training
    /// rows: nothing to gate (with the fallback on, one SOMM on every row instead).
    #[error("residual training: class {class} has fewer than two training samples")]
    EmptyClass {
        /// `A` or `B`.
        class: &'static str,
    },
}

/// Result with [`ResidualError`].
pub type Result<T> = std::result::Result<T, ResidualError>;
