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

/// Restarts allowed after a line search failure.
const RESTARTS: usize = 3;

/// Runs BFGS from `u0`; returns (solution, iterations, termination text).
///
/// Near the minimum of this non-smooth cost, round-off can leave the inverse-Hessian estimate
/// pointing uphill and the line search then fails. The run goes on from the best point seen with
/// the estimate reset to the identity (a steepest-descent step), at most 3 times; when
/// even that step finds no descent, the best point is the answer and the termination says so.
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
    let mut start = u0;
    let mut iterations = 0;
    let mut restarts = 0;
    loop {
        let solver = BFGS::new(MoreThuenteLineSearch::new())
            .with_tolerance_grad(1e-12)
            .map_err(fail)?
            .with_tolerance_cost(1e-10)
            .map_err(fail)?;
        let cost = MeanDistance::new(problem);
        let best_seen = cost.best();
        let start_cost = problem.mean_distance(&start);
        let result = Executor::new(cost, solver)
            .configure(|s| {
                s.param(start.clone())
                    .inv_hessian(identity.clone())
                    .max_iters(max_iters - iterations)
            })
            .run();
        match result {
            Ok(res) => {
                let reason = res
                    .state
                    .get_termination_reason()
                    .map_or("stopped".to_string(), |r| r.text().to_string());
                iterations += res.state.get_iter();
                let u = res.state.get_best_param().cloned().unwrap_or(start);
                let reason = if restarts > 0 {
                    format!("{reason} (after {restarts} restart(s) on line search failures)")
                } else {
                    reason
                };
                return Ok((u, iterations, reason));
            }
            Err(e) => {
                let Some((best_cost, best)) = best_seen.borrow_mut().take() else {
                    return Err(fail(e));
                };
                // Iterations of the failed run are not reported by argmin; count the restart.
                iterations += 1;
                let improved = best_cost < start_cost;
                if !improved || restarts == RESTARTS || iterations >= max_iters {
                    let u = if improved { best } else { start };
                    return Ok((
                        u,
                        iterations,
                        format!("line search found no descent from the best point ({e})"),
                    ));
                }
                restarts += 1;
                start = best;
            }
        }
    }
}
