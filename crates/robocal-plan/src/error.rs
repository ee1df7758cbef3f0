//! Errors of planning.

use std::path::PathBuf;

use robocal_robot::TomlFault;

/// What can go wrong while planning.
#[derive(Debug, thiserror::Error)]
pub enum PlanError {
    /// `plan.toml` is not valid TOML or has an unknown key.
    #[error("{0}")]
    Toml(TomlFault),
    /// A value is out of range; `key` names it.
    #[error("{}: key `{key}`: {message}", path.display())]
    Invalid {
        /// File (or command-line option) at fault.
        path: PathBuf,
        /// The key.
        key: String,
        /// What is wrong.
        message: String,
    },
    /// The plan file could not be read.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// Why.
        source: std::io::Error,
    },
    /// The identification problem could not be set up.
    #[error(transparent)]
    Ident(#[from] robocal_ident::IdentError),
}

/// Result of planning.
pub type Result<T> = std::result::Result<T, PlanError>;

impl PlanError {
    /// An invalid value of `key` in `path`.
    pub fn invalid(path: impl Into<PathBuf>, key: &str, message: impl Into<String>) -> Self {
        Self::Invalid {
            path: path.into(),
            key: key.into(),
            message: message.into(),
        }
    }
}
