//! The identification problem: a robot table, the parameters to identify, and measured points.
//!
//! Optimisers see scaled, dimensionless offsets `u`: parameter `j` is `x0_j + s_j u_j`, where
//! `s_j` makes every Jacobian column have unit RMS length per measured point at the start.
//! That puts millimetres and radians on one footing for LM's damping and BFGS's first step.

use std::cell::RefCell;
use std::rc::Rc;

use argmin::core::{CostFunction, Error as ArgminError, Gradient, Jacobian, Operator};
use faer::Mat;
use nalgebra::{DMatrix, Vector3};
use robocal_data::MeasurementSet;
use robocal_robot::{ParamId, Robot};

/// Measured points with their joint readings.
#[derive(Debug, Clone, PartialEq)]
pub struct Observations {
    /// Joints per configuration.
    pub dof: usize,
    /// Joint readings, rad, row-major `m × dof`.
    pub q: Vec<f64>,
    /// Measured target points, mm, world frame.
    pub points: Vec<Vector3<f64>>,
}

impl Observations {
    /// Rows of a measurement set (all of them).
    pub fn from_set(set: &MeasurementSet) -> Self {
        Self::from_rows(set.joint_count, set.rows.iter())
    }

    /// Selected rows of a measurement set.
    pub fn from_rows<'a>(
        dof: usize,
        rows: impl Iterator<Item = &'a robocal_data::Measurement>,
    ) -> Self {
        let mut q = Vec::new();
        let mut points = Vec::new();
        for row in rows {
            q.extend(row.sample.joints.iter().map(|d| d.to_radians()));
            points.push(row.position);
        }
        Self { dof, q, points }
    }

    /// Number of measured points.
    pub fn len(&self) -> usize {
        self.points.len()
    }

    /// Whether there is no point.
    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }

    /// Joint readings of point `i`, rad.
    pub fn joints(&self, i: usize) -> &[f64] {
        &self.q[i * self.dof..(i + 1) * self.dof]
    }

    /// Euclidean errors of `robot`'s predictions, mm.
    pub fn errors(&self, robot: &Robot) -> Vec<f64> {
        (0..self.len())
            .map(|i| (robot.point(self.joints(i)) - self.points[i]).norm())
            .collect()
    }
}

/// A robot, a parameter selection and observations: residuals, Jacobians and costs in scaled
/// coordinates `u` (see the module documentation).
#[derive(Debug, Clone)]
pub struct CalibrationProblem<'a> {
    robot: Robot,
    x0: Vec<f64>,
    selected: Vec<usize>,
    scale: Vec<f64>,
    obs: &'a Observations,
}

impl<'a> CalibrationProblem<'a> {
    /// A problem that identifies `selected` (indices into `robot.param_ids()`) starting from
    /// `robot`'s values.
    pub fn new(robot: &Robot, selected: Vec<usize>, obs: &'a Observations) -> Self {
        let x0 = robot.params();
        let (_, full) = robot.param_jacobian_batch(&obs.q);
        let m = obs.len().max(1) as f64;
        let norms: Vec<f64> = selected
            .iter()
            .map(|&j| full.column(j).norm() / m.sqrt())
            .collect();
        let largest = norms.iter().copied().fold(0.0, f64::max);
        // Columns that are round-off next to the largest keep their size, so that the
        // identifiability analysis sees them as having no effect.
        let scale = norms
            .iter()
            .map(|&norm| {
                if norm > 1e-9 * largest {
                    1.0 / norm
                } else {
                    1.0
                }
            })
            .collect();
        Self {
            robot: robot.clone(),
            x0,
            selected,
            scale,
            obs,
        }
    }

    /// The same problem with only some of its parameters (`positions` in [`Self::selected`]),
    /// keeping their scales: no new Jacobian is computed.
    pub fn restricted(&self, positions: &[usize]) -> Self {
        Self {
            robot: self.robot.clone(),
            x0: self.x0.clone(),
            selected: positions.iter().map(|&p| self.selected[p]).collect(),
            scale: positions.iter().map(|&p| self.scale[p]).collect(),
            obs: self.obs,
        }
    }

    /// Indices (into `param_ids()`) of the parameters being identified.
    pub fn selected(&self) -> &[usize] {
        &self.selected
    }

    /// Scale of each selected parameter (internal units per unit of `u`).
    pub fn scale(&self) -> &[f64] {
        &self.scale
    }

    /// The observations.
    pub fn observations(&self) -> &Observations {
        self.obs
    }

    /// Every parameter of the model at `u`, internal units.
    pub fn full_params(&self, u: &[f64]) -> Vec<f64> {
        let mut x = self.x0.clone();
        for ((&j, &s), &v) in self.selected.iter().zip(&self.scale).zip(u) {
            x[j] += s * v;
        }
        x
    }

    /// The robot at `u`.
    pub fn robot_at(&self, u: &[f64]) -> Robot {
        // The parameter vector always has the table's length, so this cannot fail.
        self.robot
            .with_params(&self.full_params(u))
            .unwrap_or_else(|_| self.robot.clone())
    }

    /// Predicted minus measured coordinates, mm, `3m` entries.
    pub fn residuals(&self, u: &[f64]) -> Vec<f64> {
        let robot = self.robot_at(u);
        let mut r = Vec::with_capacity(3 * self.obs.len());
        for i in 0..self.obs.len() {
            let d = robot.point(self.obs.joints(i)) - self.obs.points[i];
            r.extend_from_slice(d.as_slice());
        }
        r
    }

    /// Residuals and the `3m × k` Jacobian with respect to `u`.
    pub fn residuals_and_jacobian(&self, u: &[f64]) -> (Vec<f64>, Mat<f64>) {
        let robot = self.robot_at(u);
        let m = self.obs.len();
        let mut full = DMatrix::zeros(3 * m, robot.param_count());
        let mut r = Vec::with_capacity(3 * m);
        for i in 0..m {
            let p = robot.write_param_jacobian(self.obs.joints(i), &mut full, 3 * i);
            r.extend_from_slice((p - self.obs.points[i]).as_slice());
        }
        let jac = Mat::from_fn(3 * m, self.selected.len(), |row, col| {
            full[(row, self.selected[col])] * self.scale[col]
        });
        (r, jac)
    }

    /// The paper's cost, eq. (15): mean Euclidean distance, mm.
    pub fn mean_distance(&self, u: &[f64]) -> f64 {
        let r = self.residuals(u);
        let m = self.obs.len().max(1) as f64;
        r.chunks_exact(3)
            .map(|c| (c[0] * c[0] + c[1] * c[1] + c[2] * c[2]).sqrt())
            .sum::<f64>()
            / m
    }

    /// [`Self::mean_distance`] and its gradient `(1/m) Σ J_iᵀ r_i / |r_i|` in one pass over the
    /// poses, each pose's 3 × P Jacobian block written into one small buffer (no `3m × k` matrix
    /// is formed); a point with a zero residual (where the cost is not differentiable)
    /// contributes nothing to the gradient.
    pub fn mean_distance_and_gradient(&self, u: &[f64]) -> (f64, Vec<f64>) {
        let robot = self.robot_at(u);
        let m = self.obs.len();
        let mut block = DMatrix::zeros(3, robot.param_count());
        let mut cost = 0.0;
        let mut g = vec![0.0; self.selected.len()];
        for i in 0..m {
            let d =
                robot.write_param_jacobian(self.obs.joints(i), &mut block, 0) - self.obs.points[i];
            let norm = d.norm();
            cost += norm;
            if norm == 0.0 {
                continue;
            }
            let unit = d / norm;
            for ((gk, &col), &scale) in g.iter_mut().zip(&self.selected).zip(&self.scale) {
                let c = block.column(col);
                *gk += (c[0] * unit.x + c[1] * unit.y + c[2] * unit.z) * scale;
            }
        }
        let m = m.max(1) as f64;
        g.iter_mut().for_each(|gk| *gk /= m);
        (cost / m, g)
    }
}

/// Least squares view (residual vector and its Jacobian) for Levenberg–Marquardt.
#[derive(Debug, Clone)]
pub struct LeastSquares<'p, 'a>(pub &'p CalibrationProblem<'a>);

impl Operator for LeastSquares<'_, '_> {
    type Param = Vec<f64>;
    type Output = Vec<f64>;
    fn apply(&self, u: &Vec<f64>) -> Result<Vec<f64>, ArgminError> {
        Ok(self.0.residuals(u))
    }
}

impl Jacobian for LeastSquares<'_, '_> {
    type Param = Vec<f64>;
    type Jacobian = Mat<f64>;
    fn jacobian(&self, u: &Vec<f64>) -> Result<Mat<f64>, ArgminError> {
        Ok(self.0.residuals_and_jacobian(u).1)
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
type Evaluation = (Vec<f64>, f64, Vec<f64>);

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

    fn evaluate(&self, u: &[f64]) -> (f64, Vec<f64>) {
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

/// Indices of `names` in `robot.param_ids()`, in table order; `None` selects every parameter.
pub fn select(robot: &Robot, names: Option<&[String]>) -> crate::Result<Vec<usize>> {
    let ids = robot.param_ids();
    match names {
        None => Ok((0..ids.len()).collect()),
        Some(names) => {
            let mut wanted: Vec<ParamId> = Vec::new();
            for name in names {
                wanted.push(robot.param_by_name(name)?);
            }
            Ok((0..ids.len())
                .filter(|&i| wanted.contains(&ids[i]))
                .collect())
        }
    }
}
