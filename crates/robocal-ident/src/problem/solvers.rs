//! The problem as the solvers see it: least squares for Levenberg–Marquardt, the mean distance
//! for BFGS (argmin's operator, Jacobian, cost and gradient).

use super::setup::CalibrationProblem;
use argmin::core::{CostFunction, Error as ArgminError, Gradient, Jacobian, Operator};
use faer::Mat;
use std::cell::RefCell;
use std::rc::Rc;

/// Least squares view (residual vector and its Jacobian) for Levenberg–Marquardt: the problem's
/// residuals, then one row per prior ([`CalibrationProblem::set_prior`]).
#[derive(Debug, Clone)]
pub struct LeastSquares<'p, 'a>(pub &'p CalibrationProblem<'a>);

impl Operator for LeastSquares<'_, '_> {
    type Param = Vec<f64>;
    type Output = Vec<f64>;
    fn apply(&self, u: &Vec<f64>) -> Result<Vec<f64>, ArgminError> {
        let mut r = self.0.residuals(u);
        r.extend(self.0.prior_rows(u).iter().map(|row| row.0));
        Ok(r)
    }
}

impl Jacobian for LeastSquares<'_, '_> {
    type Param = Vec<f64>;
    type Jacobian = Mat<f64>;
    fn jacobian(&self, u: &Vec<f64>) -> Result<Mat<f64>, ArgminError> {
        // The residuals' columns to first order, as `residuals_and_jacobian` gives them, then
        // one row per prior: its weight on its unknown.
        let rows = self.0.prior_rows(u);
        let (_, mut jac) = self.0.residuals_and_columns(u, false, rows.len());
        let n = self.0.rows();
        for (i, &(_, k, d)) in rows.iter().enumerate() {
            jac[(n + i, k)] = d;
        }
        Ok(jac)
    }
}

/// The paper's cost (mean distance) and its gradient, for BFGS.
///
/// The line search asks for the cost and then the gradient at the same point, and BFGS asks for
/// the gradient at the point the line search accepted: both come from one evaluation, cached
/// for the last point. It also remembers the lowest cost seen, so a run that stops on a line
/// search failure can go on from there.
#[derive(Debug)]
pub struct MeanDistance<'p, 'a> {
    problem: &'p CalibrationProblem<'a>,
    last: RefCell<Option<Evaluation>>,
    best: BestPoint,
}

/// A point with its cost and gradient.
pub(super) type Evaluation = (Vec<f64>, f64, Vec<f64>);

/// The lowest cost a [`MeanDistance`] has evaluated and its point, shared with whoever runs it.
pub type BestPoint = Rc<RefCell<Option<(f64, Vec<f64>)>>>;

impl<'p, 'a> MeanDistance<'p, 'a> {
    /// Wraps a problem.
    pub fn new(problem: &'p CalibrationProblem<'a>) -> Self {
        Self {
            problem,
            last: RefCell::new(None),
            best: Rc::new(RefCell::new(None)),
        }
    }

    /// A handle on the lowest cost evaluated and its point; it outlives the executor run.
    pub fn best(&self) -> BestPoint {
        Rc::clone(&self.best)
    }

    pub(super) fn evaluate(&self, u: &[f64]) -> (f64, Vec<f64>) {
        if let Some((at, cost, grad)) = &*self.last.borrow()
            && at.as_slice() == u
        {
            return (*cost, grad.clone());
        }
        let (cost, grad) = self.problem.mean_distance_and_gradient(u);
        let mut best = self.best.borrow_mut();
        if cost.is_finite() && best.as_ref().is_none_or(|(c, _)| cost < *c) {
            *best = Some((cost, u.to_vec()));
        }
        *self.last.borrow_mut() = Some((u.to_vec(), cost, grad.clone()));
        (cost, grad)
    }
}

impl CostFunction for MeanDistance<'_, '_> {
    type Param = Vec<f64>;
    type Output = f64;
    fn cost(&self, u: &Vec<f64>) -> Result<f64, ArgminError> {
        Ok(self.evaluate(u).0)
    }
}

impl Gradient for MeanDistance<'_, '_> {
    type Param = Vec<f64>;
    type Gradient = Vec<f64>;
    fn gradient(&self, u: &Vec<f64>) -> Result<Vec<f64>, ArgminError> {
        Ok(self.evaluate(u).1)
    }
}
