//! Why a target could not be compensated.

use serde::Serialize;

/// Why a target could not be compensated.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub enum Failure {
    /// The seed has the wrong number of joints or a non-finite value.
    BadSeed(String),
    /// The kinematic solve did not reach the point.
    Unreachable {
        /// Error of the model's point after the last attempt, mm.
        model_error: f64,
        /// Whether the robot file limits any joint (the solve keeps within the limits).
        limited: bool,
    },
    /// The point is reached only with a joint beyond its limits.
    BeyondLimits {
        /// Error of the model's point at that command, mm.
        model_error: f64,
    },
    /// The fixed-point iteration did not bring the model's error below the tolerance.
    NotConverged {
        /// Error of the model's point after the last iteration, mm.
        model_error: f64,
    },
}

impl std::fmt::Display for Failure {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::BadSeed(m) => write!(f, "bad seed: {m}"),
            Self::Unreachable {
                model_error,
                limited: true,
            } => write!(
                f,
                "not reachable within the joint limits (model error {model_error:.4} mm)"
            ),
            Self::Unreachable {
                model_error,
                limited: false,
            } => write!(
                f,
                "not reachable: the kinematic solve did not reach it (model error {model_error:.4} mm)"
            ),
            Self::BeyondLimits { model_error } => write!(
                f,
                "reachable only with a joint beyond its limits (model error {model_error:.4} mm)"
            ),
            Self::NotConverged { model_error } => write!(
                f,
                "did not converge (model error {model_error:.4} mm after the last iteration)"
            ),
        }
    }
}

impl std::error::Error for Failure {}
