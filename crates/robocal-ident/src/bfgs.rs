//! The paper's identification (section III-A, steps 1–7): BFGS on the mean Euclidean distance,
//! eq. (15), with a More–Thuente line search (argmin), gradient from the analytic Jacobian.
//!
//! Differences from the paper's description: the optimiser works in scaled parameter offsets
//! (so the identity start of the inverse-Hessian estimate is meaningful across mm and rad),
//! the cost is the mean distance with 1/m rather than 1/(m − 1) (same minimiser), argmin's BFGS
//! updates the inverse Hessian rather than solving eq. (18) with the Hessian, and parameters the
//! identifiability analysis finds redundant are held at their start values.

use argmin::core::{Executor, State};
use argmin::solver::linesearch::MoreThuenteLineSearch;
use argmin::solver::quasinewton::BFGS;

use crate::error::{IdentError, Result};
use crate::problem::{CalibrationProblem, MeanDistance};

/// Runs BFGS from `u0`; returns (solution, iterations, termination text).
pub fn run_bfgs(
    problem: &CalibrationProblem<'_>,
    u0: Vec<f64>,
    max_iters: u64,
) -> Result<(Vec<f64>, u64, String)> {
    let fail = |e: argmin::core::Error| IdentError::Solver {
        solver: "bfgs",
        message: e.to_string(),
    };
    let k = u0.len();
    let identity: Vec<Vec<f64>> = (0..k)
        .map(|i| (0..k).map(|j| if i == j { 1.0 } else { 0.0 }).collect())
        .collect();
    let solver = BFGS::new(MoreThuenteLineSearch::new())
        .with_tolerance_grad(1e-12)
        .map_err(fail)?
        .with_tolerance_cost(1e-15)
        .map_err(fail)?;
    let result = Executor::new(MeanDistance(problem), solver)
        .configure(|s| {
            s.param(u0.clone())
                .inv_hessian(identity)
                .max_iters(max_iters)
        })
        .run();
    match result {
        Ok(res) => {
            let reason = res
                .state
                .get_termination_reason()
                .map_or("stopped".to_string(), |r| r.text().to_string());
            let iters = res.state.get_iter();
            let u = res.state.get_best_param().cloned().unwrap_or(u0);
            Ok((u, iters, reason))
        }
        Err(e) => Err(fail(e)),
    }
}
