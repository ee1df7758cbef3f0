//! Errors of the identification crate.

/// What can stop an identification.
#[derive(Debug, thiserror::Error)]
pub enum IdentError {
    /// A parameter name in the selection is not in the table.
    #[error(transparent)]
    Robot(#[from] robocal_robot::RobotError),
    /// Fewer measured coordinates than parameters to identify.
    #[error(
        "too few measurements: {points} points give {equations} equations for {parameters} parameters"
    )]
    TooFewMeasurements {
        /// Measured points.
        points: usize,
        /// 3 × points.
        equations: usize,
        /// Parameters asked for.
        parameters: usize,
    },
    /// Measurements made with a different number of joints than the robot has.
    #[error("the measurements have {found} joints, the robot {expected}")]
    JointCountMismatch {
        /// Robot joints.
        expected: usize,
        /// Measurement joints.
        found: usize,
    },
    /// The optimiser failed.
    #[error("the {solver} solver failed: {message}")]
    Solver {
        /// Which solver.
        solver: &'static str,
        /// What it said.
        message: String,
    },
    /// The compliance stage cannot run on these data or settings.
    #[error("compliance: {0}")]
    Compliance(String),
    /// Registration could not place the robot (e.g. all points coincide).
    #[error("registration failed: {0}")]
    Registration(String),
    /// A solve still running at the fit's deadline ([`crate::KinematicSettings::deadline`]).
    #[error("stopped: the fit ran past its deadline")]
    Deadline,
}

/// Result with [`IdentError`].
pub type Result<T> = std::result::Result<T, IdentError>;
