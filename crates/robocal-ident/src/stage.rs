//! The kinematic stage of a stage config (`robocal calibrate --config FILE`), raw and validated.

use serde::{Deserialize, Serialize};

use crate::calibrate::{KinematicSettings, SolverKind};

/// `[kinematic]` as written.
#[derive(Debug, Clone, Serialize, Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub struct RawKinematicStage {
    /// `"lm"` (least squares, Levenberg–Marquardt) or `"bfgs"` (the paper's mean distance).
    pub solver: Option<String>,
    /// Parameter names to identify; absent: all.
    pub parameters: Option<Vec<String>>,
    /// Iteration limit.
    pub max_iterations: Option<u64>,
    /// Relative column norm below which a parameter counts as unidentifiable.
    pub rank_tolerance: Option<f64>,
}

impl RawKinematicStage {
    /// Validates into settings; errors name the key.
    pub fn validate(&self) -> Result<KinematicSettings, (String, String)> {
        let mut s = KinematicSettings::default();
        if let Some(solver) = &self.solver {
            s.solver = match solver.as_str() {
                "lm" => SolverKind::Lm,
                "bfgs" => SolverKind::Bfgs,
                other => {
                    return Err((
                        "kinematic.solver".into(),
                        format!("`{other}` is not a solver; use \"lm\" or \"bfgs\""),
                    ));
                }
            };
        }
        if let Some(params) = &self.parameters {
            if params.is_empty() {
                return Err(("kinematic.parameters".into(), "lists no parameter".into()));
            }
            s.parameters = Some(params.clone());
        }
        if let Some(n) = self.max_iterations {
            if n == 0 {
                return Err((
                    "kinematic.max_iterations".into(),
                    "must be at least 1".into(),
                ));
            }
            s.max_iterations = n;
        }
        if let Some(t) = self.rank_tolerance {
            if !(t.is_finite() && t > 0.0 && t < 1.0) {
                return Err((
                    "kinematic.rank_tolerance".into(),
                    "must lie between 0 and 1".into(),
                ));
            }
            s.rank_tolerance = t;
        }
        Ok(s)
    }
}
