//! Errors of the measurement-data crate. Every variant names the file, and the line and column
//! where there is one.

use std::path::PathBuf;

/// Everything that can be wrong with a measurement or target file.
#[derive(Debug, thiserror::Error)]
pub enum DataError {
    /// The file could not be opened or read.
    #[error("{path}: cannot read: {source}")]
    Io {
        /// File at fault.
        path: PathBuf,
        /// Underlying I/O error.
        source: std::io::Error,
    },
    /// An output file could not be written.
    #[error("{path}: cannot write: {source}")]
    Write {
        /// File at fault.
        path: PathBuf,
        /// Underlying I/O error.
        source: std::io::Error,
    },
    /// The file has no content at all (not even a header).
    #[error("{path}: the file is empty; a header line is required")]
    Empty {
        /// File at fault.
        path: PathBuf,
    },
    /// A header but no data row.
    #[error("{path}: line 1: header only, no data rows")]
    NoRows {
        /// File at fault.
        path: PathBuf,
    },
    /// A required column is absent from the header.
    #[error("{path}: line 1: missing column `{column}`")]
    MissingColumn {
        /// File at fault.
        path: PathBuf,
        /// Name of the missing column.
        column: String,
    },
    /// The same column name appears twice in the header.
    #[error("{path}: line 1, column {index}: duplicate column `{column}`")]
    DuplicateColumn {
        /// File at fault.
        path: PathBuf,
        /// The repeated name.
        column: String,
        /// 1-based position of the second occurrence.
        index: usize,
    },
    /// The header's joint columns do not match the robot.
    #[error(
        "{path}: line 1: the file has joint columns q1..q{found}, the robot has {expected} joints"
    )]
    JointCountMismatch {
        /// File at fault.
        path: PathBuf,
        /// Joints in the robot.
        expected: usize,
        /// Joint columns in the file.
        found: usize,
    },
    /// A row the CSV reader could not split (wrong field count, bad quoting, bad UTF-8).
    #[error("{path}: line {line}: {message}")]
    Malformed {
        /// File at fault.
        path: PathBuf,
        /// 1-based line.
        line: u64,
        /// What the CSV reader said.
        message: String,
    },
    /// A required field is blank.
    #[error("{path}: line {line}, column `{column}`: empty value")]
    EmptyValue {
        /// File at fault.
        path: PathBuf,
        /// 1-based line.
        line: u64,
        /// Column name.
        column: String,
    },
    /// A numeric field holds text.
    #[error("{path}: line {line}, column `{column}`: `{value}` is not a number")]
    NotANumber {
        /// File at fault.
        path: PathBuf,
        /// 1-based line.
        line: u64,
        /// Column name.
        column: String,
        /// The text found.
        value: String,
    },
    /// A numeric field is NaN, infinite or out of range (e.g. 1e400).
    #[error("{path}: line {line}, column `{column}`: `{value}` is not a finite number")]
    NonFinite {
        /// File at fault.
        path: PathBuf,
        /// 1-based line.
        line: u64,
        /// Column name.
        column: String,
        /// The text found.
        value: String,
    },
    /// A negative payload mass.
    #[error("{path}: line {line}, column `load`: negative load {value} kg")]
    NegativeLoad {
        /// File at fault.
        path: PathBuf,
        /// 1-based line.
        line: u64,
        /// The value found.
        value: f64,
    },
    /// Two rows share a pose id but not its joint readings.
    #[error(
        "{path}: line {line}, column `pose`: pose `{pose}` has different joint readings than on line {first_line}"
    )]
    InconsistentPose {
        /// File at fault.
        path: PathBuf,
        /// 1-based line of the conflicting row.
        line: u64,
        /// The pose id.
        pose: String,
        /// Line where the pose first appeared.
        first_line: u64,
    },
    /// A row's `target` names no point of the robot file.
    #[error("{path}: line {line}, column `target`: no point `{target}`; {known}")]
    UnknownTarget {
        /// File at fault.
        path: PathBuf,
        /// 1-based line.
        line: u64,
        /// The name given.
        target: String,
        /// The names there are.
        known: String,
    },
    /// Some of the orientation columns `rx, ry, rz` are in the header, not all three.
    #[error(
        "{path}: line 1: orientation column `{present}` without `{missing}`: a 6-DoF probe's rows have all of `rx, ry, rz` (deg) or none"
    )]
    PartialOrientation {
        /// File at fault.
        path: PathBuf,
        /// A column that is there.
        present: String,
        /// A column that is not.
        missing: String,
    },
    /// A row fills some of `rx, ry, rz`, not all three.
    #[error(
        "{path}: line {line}, column `{column}`: empty while the row's other orientation columns are given: give all of `rx, ry, rz` or none"
    )]
    PartialOrientationRow {
        /// File at fault.
        path: PathBuf,
        /// 1-based line.
        line: u64,
        /// The empty column.
        column: String,
    },
    /// An orientation angle outside its range.
    #[error(
        "{path}: line {line}, column `{column}`: {value} deg is out of range ({range}); orientation is fixed-axis roll-pitch-yaw in degrees"
    )]
    AngleOutOfRange {
        /// File at fault.
        path: PathBuf,
        /// 1-based line.
        line: u64,
        /// Column name.
        column: String,
        /// The value found.
        value: f64,
        /// The accepted range, in words.
        range: &'static str,
    },
    /// A cell that must hold a whole number holds something else.
    #[error("{path}: line {line}, column `{column}`: `{value}` is not a whole number")]
    NotAnInteger {
        /// File at fault.
        path: PathBuf,
        /// 1-based line.
        line: u64,
        /// Column name.
        column: String,
        /// The text found.
        value: String,
    },
    /// Two rows share a `seq` (one pose) but not their joint readings.
    #[error(
        "{path}: line {line}, column `seq`: seq {seq} was given on line {first_line} to other joint readings; rows that share a seq are one pose"
    )]
    InconsistentSeq {
        /// File at fault.
        path: PathBuf,
        /// 1-based line of the second use.
        line: u64,
        /// The seq.
        seq: i64,
        /// Line of the first use.
        first_line: u64,
    },
    /// Two targets share an id.
    #[error("{path}: line {line}, column `id`: id `{id}` already used on line {first_line}")]
    DuplicateId {
        /// File at fault.
        path: PathBuf,
        /// 1-based line of the second use.
        line: u64,
        /// The id.
        id: String,
        /// Line of the first use.
        first_line: u64,
    },
}

/// Result with [`DataError`].
pub type Result<T> = std::result::Result<T, DataError>;

/// A setting with an unacceptable value: its dotted key (`kinematic.solver`,
/// `residual.x.learning_rate`) and why. Validation of settings returns it; the caller that knows
/// the file adds the path.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("key `{key}`: {message}")]
pub struct Invalid {
    /// Dotted key.
    pub key: String,
    /// What is wrong, and what would be right.
    pub message: String,
}

impl Invalid {
    /// The key and message.
    pub fn new(key: impl Into<String>, message: impl Into<String>) -> Self {
        Self {
            key: key.into(),
            message: message.into(),
        }
    }

    /// The same error one table down: `prefix.key`.
    #[must_use]
    pub fn within(self, prefix: &str) -> Self {
        Self {
            key: format!("{prefix}.{}", self.key),
            ..self
        }
    }
}

/// The names a key accepts, quoted, for an error message: `"a"`, `"a" or "b"`,
/// `"a", "b" or "c"`.
pub fn one_of(names: &[&str]) -> String {
    let names: Vec<String> = names.iter().map(|n| format!("\"{n}\"")).collect();
    match names.split_last() {
        Some((last, rest)) if !rest.is_empty() => format!("{} or {last}", rest.join(", ")),
        Some((last, _)) => last.clone(),
        None => String::new(),
    }
}
