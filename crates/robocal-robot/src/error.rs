//! Errors of the robot model crate.

use std::path::PathBuf;

/// Everything that can go wrong when loading a robot table or solving its kinematics.
#[derive(Debug, thiserror::Error)]
pub enum RobotError {
    /// The robot file could not be read.
    #[error("{path}: cannot read the robot file: {source}")]
    Io {
        /// File at fault.
        path: PathBuf,
        /// Underlying I/O error.
        source: std::io::Error,
    },
    /// The TOML was malformed, had an unknown key, a missing key or a wrong type.
    #[error("{path}: line {line}, column {column}: {message}")]
    Toml {
        /// File at fault.
        path: PathBuf,
        /// 1-based line of the offending text.
        line: usize,
        /// 1-based column of the offending text.
        column: usize,
        /// What the TOML parser said.
        message: String,
    },
    /// A key parsed but its value is not acceptable.
    #[error("{path}: key `{key}`: {message}")]
    InvalidValue {
        /// File at fault (`<memory>` when parsed from a string).
        path: PathBuf,
        /// Dotted key, e.g. `joint[3].limits` (joints counted from 1).
        key: String,
        /// Why the value is rejected.
        message: String,
    },
    /// The table has no `[[joint]]`.
    #[error("{path}: the robot needs at least one [[joint]] table")]
    NoJoints {
        /// File at fault.
        path: PathBuf,
    },
    /// A parameter name that does not exist in this table.
    #[error(
        "unknown parameter `{name}` (parameters are named like j2.d, j3.beta, base.rz, tool.x)"
    )]
    UnknownParameter {
        /// The name that was asked for.
        name: String,
    },
    /// A flat parameter vector of the wrong length.
    #[error("parameter vector has {found} entries, the table has {expected}")]
    ParameterCount {
        /// Parameters in the table.
        expected: usize,
        /// Entries given.
        found: usize,
    },
    /// A joint vector of the wrong length.
    #[error("{found} joint values given, the robot has {expected} joints")]
    JointCountMismatch {
        /// Joints in the robot.
        expected: usize,
        /// Values given.
        found: usize,
    },
    /// Inverse kinematics found no solution within tolerance.
    #[error(
        "inverse kinematics did not converge: {position_error:.4} mm and {orientation_error:.4} deg left after {iterations} iterations"
    )]
    IkNotConverged {
        /// Position error left, mm.
        position_error: f64,
        /// Orientation error left, degrees (0 for position-only targets).
        orientation_error: f64,
        /// Iterations spent.
        iterations: usize,
    },
}

/// Result with [`RobotError`].
pub type Result<T> = std::result::Result<T, RobotError>;
