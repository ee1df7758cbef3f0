//! The identification problem: a robot table, the parameters to identify, and measured points.
//!
//! Optimisers see scaled, dimensionless offsets `u`: parameter `j` is `x0_j + s_j u_j`, where
//! `s_j` makes every Jacobian column have unit RMS length per measured point at the start.
//! That puts millimetres and radians on one footing for LM's damping and BFGS's first step.

mod jacobian;
mod observations;
mod setup;
mod solvers;

pub use observations::{DEFAULT_NOISE_DEG, DEFAULT_NOISE_MM, Observations, angle_weight};
pub use setup::{CalibrationProblem, PriorSpreads, select};
pub use solvers::{BestPoint, LeastSquares, MeanDistance};
