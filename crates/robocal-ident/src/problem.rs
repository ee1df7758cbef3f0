//! The identification problem: a robot table, the parameters to identify, and measured points.
//!
//! Optimisers see scaled, dimensionless offsets `u`: parameter `j` is `x0_j + s_j u_j`, where
//! `s_j` makes every Jacobian column have unit RMS length per measured point at the start.
//! That puts millimetres and radians on one footing for LM's damping and BFGS's first step.

use std::cell::RefCell;
use std::rc::Rc;
use std::sync::Arc;

use argmin::core::{CostFunction, Error as ArgminError, Gradient, Jacobian, Operator};
use faer::Mat;
use nalgebra::{DMatrix, Matrix3, Vector3};
use rayon::prelude::*;
use robocal_data::MeasurementSet;
use robocal_robot::{
    Compliance, DeflectionRates, ErrorParam, JointErrors, JointField, ParamId, ParamTwist, Robot,
    RowTerms, Turns, left_jacobian_inverse, rotation_vector, rpy_to_matrix, turn_rotation, turned,
};

use crate::identifiability::posterior_covariance;

/// Rows of a residual or Jacobian evaluation per parallel task: enough that a task outweighs
/// its scheduling, few enough that the rows of one fit spread over the cores.
const ROWS_PER_TASK: usize = 64;

/// Consecutive rows of the residuals and of their Jacobian
/// ([`CalibrationProblem::jacobian_blocks`]).
struct RowBlock {
    /// The first row's index in the whole residual vector.
    first: usize,
    /// The rows' residuals.
    r: Vec<f64>,
    /// The rows' entries of every table parameter's column.
    full: DMatrix<f64>,
    /// The rows' entries of every joint-error coefficient's column.
    cjac: DMatrix<f64>,
}

/// Measured points with their joint readings and loads.
#[derive(Debug, Clone, PartialEq)]
pub struct Observations {
    /// Joints per configuration.
    pub dof: usize,
    /// Joint readings, rad, row-major `m × dof`.
    pub q: Vec<f64>,
    /// Payload of each point, kg.
    pub loads: Vec<f64>,
    /// Measured target points, mm, world frame.
    pub points: Vec<Vector3<f64>>,
    /// The point each row measures (`target`: a `[tool.points]` name, empty for the default
    /// point); empty when every row measures the default point.
    pub targets: Vec<String>,
    /// Measured orientation of the tool frame of each row (a 6-DoF probe's `rx, ry, rz`),
    /// world frame; `None` for a row without. Empty when no row has one.
    pub orientations: Vec<Option<Matrix3<f64>>>,
    /// Weight of an orientation residual against a position one, mm per rad: a rotation
    /// residual of `ω` rad counts as `angle_weight · ω` mm ([`angle_weight`]).
    pub angle_weight: f64,
}

/// A tracker's position noise when none is stated, mm per coordinate (1σ).
pub const DEFAULT_NOISE_MM: f64 = 0.02;

/// A 6-DoF probe's angular noise when none is stated, deg per axis (1σ).
pub const DEFAULT_NOISE_DEG: f64 = 0.01;

/// The weight of an orientation residual, mm per rad, from the stated noises: `noise_mm /
/// noise_deg` (mm per deg) in radians, so that both kinds of residual weigh by their noise.
pub fn angle_weight(noise_mm: f64, noise_deg: f64) -> f64 {
    noise_mm / noise_deg.to_radians()
}

impl Observations {
    /// No observation yet, of an arm with `dof` joints (the default angle weight).
    pub fn new(dof: usize) -> Self {
        Self {
            dof,
            q: Vec::new(),
            loads: Vec::new(),
            points: Vec::new(),
            targets: Vec::new(),
            orientations: Vec::new(),
            angle_weight: angle_weight(DEFAULT_NOISE_MM, DEFAULT_NOISE_DEG),
        }
    }

    /// Rows of a measurement set (all of them).
    pub fn from_set(set: &MeasurementSet) -> Self {
        Self::from_rows(set.joint_count, set.rows.iter())
    }

    /// Selected rows of a measurement set.
    pub fn from_rows<'a>(
        dof: usize,
        rows: impl Iterator<Item = &'a robocal_data::Measurement>,
    ) -> Self {
        let mut obs = Self::new(dof);
        for row in rows {
            obs.targets.push(row.sample.target.clone());
            obs.orientations.push(
                row.orientation
                    .map(|a| rpy_to_matrix(&a.map(f64::to_radians))),
            );
            obs.q
                .extend(row.sample.joints.iter().map(|d| d.to_radians()));
            obs.loads.push(row.sample.load);
            obs.points.push(row.position);
        }
        if obs.targets.iter().all(String::is_empty) {
            obs.targets.clear();
        }
        if obs.orientations.iter().all(Option::is_none) {
            obs.orientations.clear();
        }
        obs
    }

    /// The measured orientation of observation `i`, when it has one.
    pub fn orientation(&self, i: usize) -> Option<&Matrix3<f64>> {
        self.orientations.get(i).and_then(Option::as_ref)
    }

    /// The observations with a measured orientation, in order.
    pub fn oriented(&self) -> Vec<usize> {
        (0..self.len())
            .filter(|&i| self.orientation(i).is_some())
            .collect()
    }

    /// The model's tool frame orientation for observation `i` (deflected by `compliance`
    /// under its load when there is one).
    pub fn predict_rotation(
        &self,
        robot: &Robot,
        compliance: Option<&Compliance>,
        i: usize,
    ) -> Matrix3<f64> {
        robot.rotation_under_load(compliance, self.joints(i), self.loads[i])
    }

    /// The angle between the measured and the predicted tool frame of every observation with
    /// a measured orientation, rad.
    pub fn orientation_errors_with(
        &self,
        robot: &Robot,
        compliance: Option<&Compliance>,
    ) -> Vec<f64> {
        self.oriented()
            .into_iter()
            .filter_map(|i| {
                let measured = self.orientation(i)?;
                let predicted = self.predict_rotation(robot, compliance, i);
                Some(rotation_vector(&(predicted * measured.transpose())).norm())
            })
            .collect()
    }

    /// The target index of observation `i` in `robot` ([`Robot::target_index`]; 0, the default
    /// point, for a name the table does not have: data are checked against the table first).
    pub fn target(&self, robot: &Robot, i: usize) -> usize {
        self.targets
            .get(i)
            .and_then(|t| robot.target_index(t))
            .unwrap_or(0)
    }

    /// Every observation's target index in `robot`.
    pub fn target_indices(&self, robot: &Robot) -> Vec<usize> {
        (0..self.len()).map(|i| self.target(robot, i)).collect()
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

    /// The lowest and highest reading of every joint, rad (`None` without observations).
    pub fn joint_ranges(&self) -> Option<Vec<[f64; 2]>> {
        let mut ranges: Option<Vec<[f64; 2]>> = None;
        for i in 0..self.len() {
            let q = self.joints(i);
            let r = ranges.get_or_insert_with(|| q.iter().map(|&v| [v, v]).collect());
            for (r, &v) in r.iter_mut().zip(q) {
                *r = [r[0].min(v), r[1].max(v)];
            }
        }
        ranges
    }

    /// The distinct loads, ascending, kg.
    pub fn distinct_loads(&self) -> Vec<f64> {
        let mut loads = self.loads.clone();
        loads.sort_by(f64::total_cmp);
        loads.dedup();
        loads
    }

    /// The model's point for observation `i`: `robot`, deflected by `compliance` under the
    /// observation's load when there is one.
    pub fn predict(
        &self,
        robot: &Robot,
        compliance: Option<&Compliance>,
        i: usize,
    ) -> Vector3<f64> {
        self.predict_on_waves(robot, compliance, None, i)
    }

    /// [`Self::predict`], on the bases of `compliance`'s waves at the observation's readings
    /// where they are given ([`JointErrors::wave_bases`]; the same point to the bit).
    pub(crate) fn predict_on_waves(
        &self,
        robot: &Robot,
        compliance: Option<&Compliance>,
        waves: Option<&[(f64, f64)]>,
        i: usize,
    ) -> Vector3<f64> {
        let robot = robot.for_target(self.target(robot, i));
        let (q, load) = (self.joints(i), self.loads[i]);
        match (compliance, waves) {
            (Some(c), Some(waves)) => c.point_on_waves(&robot, q, load, waves),
            _ => robot.point_under_load(compliance, q, load),
        }
    }

    /// Euclidean errors of `robot`'s predictions (rigid), mm.
    pub fn errors(&self, robot: &Robot) -> Vec<f64> {
        self.errors_with(robot, None)
    }

    /// Euclidean errors of the predictions of `robot` with `compliance`, mm.
    pub fn errors_with(&self, robot: &Robot, compliance: Option<&Compliance>) -> Vec<f64> {
        (0..self.len())
            .map(|i| (self.predict(robot, compliance, i) - self.points[i]).norm())
            .collect()
    }
}

/// A robot, a parameter selection and observations: residuals, Jacobians and costs in scaled
/// coordinates `u` (see the module documentation).
///
/// With a compliance model ([`Self::with_compliance`]) the unknowns are the selected geometric
/// parameters followed by the compliances of the selected joints, and every point is predicted
/// at the joint angles its load deflects the arm to.
#[derive(Debug, Clone)]
pub struct CalibrationProblem<'a> {
    robot: Robot,
    x0: Vec<f64>,
    selected: Vec<usize>,
    /// One per unknown: geometric parameters first, then compliances.
    scale: Vec<f64>,
    compliance: Option<ComplianceFit>,
    obs: &'a Observations,
    /// The observations with a measured orientation: their three rotation residuals follow
    /// the `3m` position residuals, in this order.
    oriented: Vec<usize>,
    /// Square roots of the points' weights (none: every point weighs 1); the iteratively
    /// reweighted least squares of a robust loss set them.
    root_weights: Option<Vec<f64>>,
    /// Zero-mean Gaussian priors on joint-error coefficients: `(coefficient, weight)`, each a
    /// residual row `weight × value` (mm-equivalent) that the least-squares view appends.
    prior: Vec<(ErrorParam, f64)>,
    /// The priors' spreads (their standard deviations, internal units), by group.
    prior_spread: PriorSpreads,
}

/// The spreads (standard deviations, rad) of the priors on the joint errors, one per group of
/// coefficients that shares one: the transmission harmonics' and the axis runouts'.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct PriorSpreads {
    /// The harmonics' spread, when they are under a prior.
    pub harmonics: Option<f64>,
    /// The runouts' spread, when they are under a prior.
    pub runouts: Option<f64>,
}

/// The joint-error part of a problem.
#[derive(Debug, Clone)]
struct ComplianceFit {
    /// The model at `u = 0` (and gravity and payload).
    start: JointErrors,
    /// Its coefficients that are identified.
    params: Vec<ErrorParam>,
    /// The bases of its waves at every row.
    waves: RowWaves,
}

/// The bases of a model's waves at every row's readings ([`JointErrors::wave_bases`]): the
/// same at every `u`, where only coefficients change, so computed once per problem (shared by
/// its restrictions) rather than at every evaluation.
#[derive(Debug, Clone)]
struct RowWaves {
    /// Row after row, `per_row` each.
    bases: Arc<[(f64, f64)]>,
    per_row: usize,
}

impl RowWaves {
    /// `model`'s wave bases at every row of `obs`.
    fn of(model: &JointErrors, obs: &Observations) -> Self {
        let per_row = model.harmonics.len() + model.runouts.len();
        let bases = if per_row == 0 {
            Arc::from([])
        } else {
            (0..obs.len())
                .flat_map(|i| model.wave_bases(obs.joints(i)))
                .collect()
        };
        Self { bases, per_row }
    }

    /// Row `i`'s bases.
    fn row(&self, i: usize) -> &[(f64, f64)] {
        &self.bases[i * self.per_row..(i + 1) * self.per_row]
    }
}

/// Scale of each column from its RMS length per point: `1 / norm`, or 1 for a column that is
/// round-off next to the largest (so that the identifiability analysis sees it as having no
/// effect).
fn column_scales(norms: &[f64]) -> Vec<f64> {
    let largest = norms.iter().copied().fold(0.0, f64::max);
    norms
        .iter()
        .map(|&norm| {
            if norm > 1e-9 * largest {
                1.0 / norm
            } else {
                1.0
            }
        })
        .collect()
}

impl<'a> CalibrationProblem<'a> {
    /// A problem that identifies `selected` (indices into `robot.param_ids()`) starting from
    /// `robot`'s values, rigid (no compliance).
    pub fn new(robot: &Robot, selected: Vec<usize>, obs: &'a Observations) -> Self {
        let x0 = robot.params();
        let mut problem = Self {
            robot: robot.clone(),
            x0,
            selected,
            scale: Vec::new(),
            compliance: None,
            obs,
            oriented: obs.oriented(),
            root_weights: None,
            prior: Vec::new(),
            prior_spread: PriorSpreads::default(),
        };
        let (_, full, _) = problem.full_jacobian(robot, None, false);
        let m = obs.len().max(1) as f64;
        let norms: Vec<f64> = (problem.selected.iter())
            .map(|&j| full.column(j).norm() / m.sqrt())
            .collect();
        problem.scale = column_scales(&norms);
        problem
    }

    /// Rows of the residual vector: three per point, three per measured orientation.
    pub fn rows(&self) -> usize {
        3 * self.obs.len() + 3 * self.oriented.len()
    }

    /// The unweighted residuals (position rows, then the rotation rows times the angle weight)
    /// of `robot` (deflected by `compliance`), with the Jacobian of every table parameter and
    /// of every identified joint-error coefficient (unscaled, internal units).
    ///
    /// `exact`: with the table's columns' second-order terms — the deflection's own dependence
    /// on the table (a compliance times the change of the torques it holds, taken at the
    /// command) and the turns' (their turn of every column and the motion of the runouts' axes
    /// and origins); without them, the first-order columns ([`Self::first_order_jacobian`]).
    fn full_jacobian(
        &self,
        robot: &Robot,
        compliance: Option<&Compliance>,
        exact: bool,
    ) -> (Vec<f64>, DMatrix<f64>, DMatrix<f64>) {
        let rows = self.rows();
        let mut full = DMatrix::zeros(rows, robot.param_count());
        let mut cjac = DMatrix::zeros(rows, self.error_params().len());
        let mut r = Vec::with_capacity(rows);
        for block in self.jacobian_blocks(robot, compliance, exact) {
            let first = block.first;
            (full.view_mut((first, 0), block.full.shape())).copy_from(&block.full);
            (cjac.view_mut((first, 0), block.cjac.shape())).copy_from(&block.cjac);
            r.extend(block.r);
        }
        (r, full, cjac)
    }

    /// [`Self::full_jacobian`]'s rows as the tasks that computed them hold them: blocks of
    /// consecutive rows in order (the points' in blocks of [`ROWS_PER_TASK`], then the measured
    /// orientations' in one), each entry the same number the whole matrices hold, which a
    /// caller that copies every row into a matrix of its own needs not assemble first.
    fn jacobian_blocks(
        &self,
        robot: &Robot,
        compliance: Option<&Compliance>,
        exact: bool,
    ) -> Vec<RowBlock> {
        let m = self.obs.len();
        let params = self.error_params();
        let targets = self.obs.target_indices(robot);
        let waves = compliance.and_then(|c| self.row_waves(c));
        // Each joint's `theta` column: the joint Jacobian's column (every joint is revolute), of
        // which a joint-error coefficient's column is the sum over the joints it turns, each
        // times its basis value.
        let theta: Vec<usize> = (robot.param_ids().iter().enumerate())
            .filter_map(|(col, id)| match id {
                ParamId::Joint {
                    field: JointField::Theta,
                    ..
                } => Some(col),
                _ => None,
            })
            .collect();
        // The points' rows, a block of them per task on every core (each row's entries are its
        // own: the same matrices on any number of cores), the blocks in order.
        let mut blocks: Vec<RowBlock> = (targets.par_chunks(ROWS_PER_TASK).enumerate())
            .map(|(b, block)| {
                let first = b * ROWS_PER_TASK;
                let mut full = DMatrix::zeros(3 * block.len(), robot.param_count());
                let mut cjac = DMatrix::zeros(3 * block.len(), params.len());
                let mut r = Vec::with_capacity(3 * block.len());
                // One row's terms after the other in the same buffers.
                let mut row = RowTerms::default();
                for (l, &t) in block.iter().enumerate() {
                    let i = first + l;
                    let (q, load) = (self.obs.joints(i), self.obs.loads[i]);
                    let p = match compliance {
                        Some(c) => {
                            let waves = waves.map(|w| w.row(i));
                            c.write_row_terms(robot, q, load, params, waves, &mut row);
                            let p =
                                robot.write_param_jacobian_at(&row.deflected, t, &mut full, 3 * l);
                            for &(k, j, phi) in &row.basis {
                                for a in 0..3 {
                                    cjac[(3 * l + a, k)] += full[(3 * l + a, theta[j])] * phi;
                                }
                            }
                            if exact {
                                let columns = (&mut full, &mut cjac);
                                exact_terms(
                                    robot,
                                    c,
                                    (q, load),
                                    &row.turns,
                                    p,
                                    &theta,
                                    columns,
                                    3 * l,
                                );
                            }
                            // A tilt turns the parts beyond its joint about the joint's origin
                            // (the geometry's columns leave out the micro-radians it turns them
                            // by).
                            for &(k, origin, turn) in &row.turn_basis {
                                let column = turn.cross(&(p - origin));
                                for a in 0..3 {
                                    cjac[(3 * l + a, k)] += column[a];
                                }
                            }
                            turned(&row.turns, p)
                        }
                        None => robot.write_param_jacobian_at(q, t, &mut full, 3 * l),
                    };
                    r.extend_from_slice((p - self.obs.points[i]).as_slice());
                }
                RowBlock {
                    first: 3 * first,
                    r,
                    full,
                    cjac,
                }
            })
            .collect();
        if self.oriented.is_empty() {
            return blocks;
        }
        // The measured orientations' rows, one block after the points'.
        let n = 3 * self.oriented.len();
        let mut full = DMatrix::zeros(n, robot.param_count());
        let mut cjac = DMatrix::zeros(n, params.len());
        let mut r = Vec::with_capacity(n);
        let w = self.obs.angle_weight;
        for (k, &i) in self.oriented.iter().enumerate() {
            let (q, load) = (self.obs.joints(i), self.obs.loads[i]);
            let row = 3 * k;
            let rot = match compliance {
                Some(c) => {
                    let (_, jac) = c.orientation_param_jacobian(robot, q, load, params);
                    cjac.view_mut((row, 0), (3, params.len())).copy_from(&jac);
                    let deflected = c.deflected(robot, q, load);
                    let rot = robot.write_orientation_jacobian(&deflected, &mut full, row);
                    if exact {
                        // The joints turn the tool frame about their axes (their `theta`
                        // columns).
                        let joints = joint_columns(&full, &theta, row);
                        let rates = c.deflection_rates(robot, q, load);
                        let twists = robot.param_twists(q);
                        add_deflection_rates(&twists, &rates, &joints, &mut full, row);
                    }
                    // The tilts and the runouts turn the parts beyond their joints, the tool
                    // frame with them.
                    if !c.has_turns() {
                        rot
                    } else {
                        turn_rotation(&c.turns(robot, q, load)) * rot
                    }
                }
                None => robot.write_orientation_jacobian(q, &mut full, row),
            };
            // r = log(R Rₘᵀ): a turn δ of R moves it by J⁻¹(r) δ (exact, not only near r = 0).
            let phi = self.rotation_residual(i, &rot);
            let jinv = left_jacobian_inverse(&phi) * w;
            let block = jinv * full.view((row, 0), (3, full.ncols()));
            full.view_mut((row, 0), (3, full.ncols())).copy_from(&block);
            let block = jinv * cjac.view((row, 0), (3, cjac.ncols()));
            cjac.view_mut((row, 0), (3, cjac.ncols())).copy_from(&block);
            r.extend_from_slice((phi * w).as_slice());
        }
        blocks.push(RowBlock {
            first: 3 * m,
            r,
            full,
            cjac,
        });
        blocks
    }

    /// The rotation residual of observation `i` for a predicted tool frame: the rotation vector
    /// `log(R Rₘᵀ)` from the measured frame to the predicted one, rad (zero without a measured
    /// frame), before any weight.
    fn rotation_residual(&self, i: usize, predicted: &Matrix3<f64>) -> Vector3<f64> {
        self.obs.orientation(i).map_or_else(Vector3::zeros, |m| {
            rotation_vector(&(predicted * m.transpose()))
        })
    }

    /// The root weight of residual row `row` (a position row's point, or a rotation row's).
    fn row_weight(&self, row: usize) -> f64 {
        let m3 = 3 * self.obs.len();
        if row < m3 {
            self.root_weight(row / 3)
        } else {
            self.root_weight(self.oriented[(row - m3) / 3])
        }
    }

    /// The same problem with the compliances of `joints` (0-based) identified too, starting
    /// from `start`; their columns are scaled like the geometric ones (unit RMS per point),
    /// independently of the geometric scales.
    pub fn with_compliance(self, start: Compliance, joints: Vec<usize>) -> Self {
        let params = joints.into_iter().map(ErrorParam::Compliance).collect();
        self.with_joint_errors(start, params)
    }

    /// The same problem with the joint-error coefficients `params` of `start` identified too
    /// (compliances, harmonics, self-weight terms), starting from `start`'s values; their
    /// columns are scaled like the geometric ones (unit RMS per point).
    pub fn with_joint_errors(mut self, start: JointErrors, params: Vec<ErrorParam>) -> Self {
        let m = self.obs.len().max(1) as f64;
        self.compliance = Some(ComplianceFit {
            waves: RowWaves::of(&start, self.obs),
            start: start.clone(),
            params,
        });
        let (_, _, cjac) = self.full_jacobian(&self.robot, Some(&start), false);
        let norms: Vec<f64> = (0..cjac.ncols())
            .map(|k| cjac.column(k).norm() / m.sqrt())
            .collect();
        self.scale.truncate(self.selected.len());
        self.scale.extend(column_scales(&norms));
        self
    }

    /// The same problem with only some of its unknowns (`positions` among the geometric
    /// parameters, then the compliances), keeping their scales: no new Jacobian is computed.
    pub fn restricted(&self, positions: &[usize]) -> Self {
        let ng = self.selected.len();
        let compliance = self.compliance.as_ref().map(|c| {
            let params: Vec<ErrorParam> = (positions.iter())
                .filter(|&&p| p >= ng)
                .map(|&p| c.params[p - ng])
                .collect();
            // A tilt left out is rigid: it starts above zero only so that the identifiability
            // analysis sees the links' weights tilt the joints.
            let mut start = c.start.clone();
            for &p in &c.params {
                if let ErrorParam::Tilt(i) = p
                    && !params.contains(&p)
                {
                    start.tilts[i].value = 0.0;
                }
            }
            // Only tilts' values changed: the same waves.
            ComplianceFit {
                start,
                params,
                waves: c.waves.clone(),
            }
        });
        // The priors of the coefficients still identified.
        let prior = (self.prior.iter())
            .filter(|(p, _)| compliance.as_ref().is_some_and(|c| c.params.contains(p)))
            .copied()
            .collect();
        let mut order: Vec<usize> = positions.iter().copied().filter(|&p| p < ng).collect();
        order.extend(positions.iter().copied().filter(|&p| p >= ng));
        Self {
            robot: self.robot.clone(),
            x0: self.x0.clone(),
            selected: (order.iter())
                .filter(|&&p| p < ng)
                .map(|&p| self.selected[p])
                .collect(),
            scale: order.iter().map(|&p| self.scale[p]).collect(),
            compliance,
            obs: self.obs,
            oriented: self.oriented.clone(),
            root_weights: self.root_weights.clone(),
            prior,
            prior_spread: self.prior_spread,
        }
    }

    /// Sets zero-mean Gaussian priors on joint-error coefficients, `(coefficient, weight)`: the
    /// least-squares view ([`LeastSquares`]) appends a row `weight × value` for each (a prior of
    /// standard deviation `τ` against residuals of standard deviation `σ`: weight `σ / τ`);
    /// coefficients not identified are left out. `spread` holds the groups' `τ` (reported).
    pub fn set_prior(&mut self, prior: Vec<(ErrorParam, f64)>, spread: PriorSpreads) {
        let params = self.error_params().to_vec();
        self.prior = prior
            .into_iter()
            .filter(|(p, _)| params.contains(p))
            .collect();
        self.prior_spread = spread;
    }

    /// Whether the problem has priors.
    pub fn has_prior(&self) -> bool {
        !self.prior.is_empty()
    }

    /// The priors' spreads, internal units ([`Self::set_prior`]; none without priors).
    pub fn prior_spread(&self) -> PriorSpreads {
        if self.has_prior() {
            self.prior_spread
        } else {
            PriorSpreads::default()
        }
    }

    /// The priors' rows at `u`, and for each its unknown's position and derivative.
    fn prior_rows(&self, u: &[f64]) -> Vec<(f64, usize, f64)> {
        let ng = self.selected.len();
        let Some(c) = self.compliance.as_ref() else {
            return Vec::new();
        };
        (self.prior.iter())
            .filter_map(|&(p, w)| {
                let k = c.params.iter().position(|&q| q == p)?;
                let value = c.start.param(p) + self.scale[ng + k] * u[ng + k];
                Some((w * value, ng + k, w * self.scale[ng + k]))
            })
            .collect()
    }

    /// The unknowns' covariance at `u` (`u` units), from the exact Jacobian
    /// ([`Self::exact_jacobian`]): the posterior's under the priors where there
    /// are any ([`crate::posterior_covariance`]: the data's `σ²`, the priors' rows added to
    /// `JᵀJ`), else the data's alone. `None` as [`crate::posterior_covariance`].
    pub fn covariance(&self, u: &[f64]) -> Option<Mat<f64>> {
        // At the solution, the exact linearization: the parameters' spread is what the exact
        // columns say, where the first-order ones differ by several per cent on a heavily
        // loaded compliant arm.
        let (r, jac) = self.exact_jacobian(u);
        let prior: Vec<(usize, f64)> = (self.prior_rows(u).iter())
            .map(|&(_, j, d)| (j, d))
            .collect();
        posterior_covariance(&jac, &r, &prior)
    }

    /// Weights each point's residual by `weights` (one per point, ≥ 0): least squares on
    /// `Σ wᵢ |rᵢ|²`.
    pub fn set_point_weights(&mut self, weights: &[f64]) {
        self.root_weights = Some(weights.iter().map(|w| w.max(0.0).sqrt()).collect());
    }

    /// The weight root of point `i` (1 without weights).
    fn root_weight(&self, i: usize) -> f64 {
        self.root_weights.as_ref().map_or(1.0, |w| w[i])
    }

    /// Every point's unweighted error vector (predicted − measured), mm, at `u`.
    pub fn point_errors(&self, u: &[f64]) -> Vec<nalgebra::Vector3<f64>> {
        let robot = self.robot_at(u);
        let compliance = self.compliance_at(u);
        let waves = compliance.as_ref().and_then(|c| self.row_waves(c));
        // Every core's share of the rows (each point its own: the same errors on any number).
        (0..self.obs.len())
            .into_par_iter()
            .with_min_len(ROWS_PER_TASK)
            .map(|i| {
                let waves = waves.map(|w| w.row(i));
                self.obs
                    .predict_on_waves(&robot, compliance.as_ref(), waves, i)
                    - self.obs.points[i]
            })
            .collect()
    }

    /// The bases of `compliance`'s waves at every row, computed with the problem, where its
    /// waves are the start's (the same bases: [`JointErrors::same_waves`]); none where it has no
    /// wave or others.
    fn row_waves(&self, compliance: &Compliance) -> Option<&RowWaves> {
        let fit = self.compliance.as_ref()?;
        (fit.waves.per_row > 0 && fit.start.same_waves(compliance)).then_some(&fit.waves)
    }

    /// Indices (into `param_ids()`) of the geometric parameters being identified.
    pub fn selected(&self) -> &[usize] {
        &self.selected
    }

    /// The joint-error coefficients identified (empty for a rigid problem).
    pub fn error_params(&self) -> &[ErrorParam] {
        self.compliance.as_ref().map_or(&[], |c| &c.params)
    }

    /// Number of unknowns: geometric parameters, then compliances.
    pub fn unknowns(&self) -> usize {
        self.scale.len()
    }

    /// Scale of each unknown (internal units per unit of `u`).
    pub fn scale(&self) -> &[f64] {
        &self.scale
    }

    /// The observations.
    pub fn observations(&self) -> &Observations {
        self.obs
    }

    /// Every geometric parameter of the model at `u`, internal units.
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

    /// The compliance model at `u` (none for a rigid problem).
    pub fn compliance_at(&self, u: &[f64]) -> Option<Compliance> {
        let ng = self.selected.len();
        self.compliance.as_ref().map(|c| {
            let mut model = c.start.clone();
            for (k, &p) in c.params.iter().enumerate() {
                let v = model.param(p) + self.scale[ng + k] * u[ng + k];
                model.set_param(p, v);
            }
            model
        })
    }

    /// Predicted minus measured coordinates, mm, `3m` entries (each point's times the root of its
    /// weight when the problem is weighted), then, for each observation with a measured
    /// orientation, the rotation vector from the measured to the predicted tool frame times the
    /// angle weight (mm-equivalent; times the point's weight root too).
    pub fn residuals(&self, u: &[f64]) -> Vec<f64> {
        let mut r: Vec<f64> = (self.point_errors(u).iter().enumerate())
            .flat_map(|(i, d)| {
                let d = d * self.root_weight(i);
                [d.x, d.y, d.z]
            })
            .collect();
        if !self.oriented.is_empty() {
            let robot = self.robot_at(u);
            let compliance = self.compliance_at(u);
            for &i in &self.oriented {
                let predicted = self.obs.predict_rotation(&robot, compliance.as_ref(), i);
                let w = self.obs.angle_weight * self.root_weight(i);
                r.extend_from_slice((self.rotation_residual(i, &predicted) * w).as_slice());
            }
        }
        r
    }

    /// Residuals and the `3m × k` Jacobian with respect to `u`, the one the solvers step on.
    ///
    /// The joint errors' columns are exact. The table's are taken at the deflected joint angles,
    /// to first order ([`Self::first_order_jacobian`]): they leave out the torques' own
    /// dependence on the table (a compliance times a torque's change) and the turns' (tilts',
    /// runouts') dependence on it; the residual is exact, so LM converges to a true optimum.
    /// [`Self::exact_jacobian`] has those terms; stepping on it, on the paper's arm with the
    /// runouts, the solves converge in tens of iterations where these crawl to 200, but the fits
    /// land elsewhere (6 of 24 development cases lower and 6 higher, ARM6H by up to 123 %), and
    /// without runouts it converges no faster (compliance and self-weight on the paper's arm: 33 iterations and
    /// 2.0 s against 26 and 1.2 s, the same cost to four digits).
    pub fn residuals_and_jacobian(&self, u: &[f64]) -> (Vec<f64>, Mat<f64>) {
        self.residuals_and_columns(u, false, 0)
    }

    /// Residuals and the Jacobian with the table's columns exact for every smooth term
    /// (checked against central differences): the torques' own dependence on the geometry (the
    /// joints deflect under torques taken at the command, whose lever arms the table sets:
    /// [`JointErrors::deflection_rates`] along each parameter's [`Robot::param_twists`]); every
    /// column turned with the point by the tilts' and runouts' turns; the motion of the
    /// runouts' axes and origins. Left out: the tilts' moments' dependence on the table; a
    /// backlash flank's switch (not differentiable).
    pub fn exact_jacobian(&self, u: &[f64]) -> (Vec<f64>, Mat<f64>) {
        self.residuals_and_columns(u, true, 0)
    }

    /// The Jacobian at `u` with the table's columns to first order: the geometry's at the
    /// deflected angles, without the deflection's and the turns' own dependence on the table
    /// (a compliance times a torque's change, micro-radians of turn; [`Self::exact_jacobian`]
    /// has them). The identifiability analysis decides on these: those small terms would make
    /// combinations the poses cannot tell apart (joint 6's offset and the payload's centre of
    /// mass, say) look barely determined, through the compliances alone, and be identified,
    /// ill-conditioned.
    pub fn first_order_jacobian(&self, u: &[f64]) -> Mat<f64> {
        self.residuals_and_columns(u, false, 0).1
    }

    /// [`Self::residuals_and_jacobian`], the table's columns `exact` or to first order, with
    /// `extra` rows of zeros below the residuals' (for the priors' rows, which the caller
    /// writes: the Jacobian is not copied to make room for them).
    fn residuals_and_columns(&self, u: &[f64], exact: bool, extra: usize) -> (Vec<f64>, Mat<f64>) {
        let robot = self.robot_at(u);
        let compliance = self.compliance_at(u);
        let ng = self.selected.len();
        let rows = self.rows();
        let blocks = self.jacobian_blocks(&robot, compliance.as_ref(), exact);
        let mut r = Vec::with_capacity(rows);
        for block in &blocks {
            r.extend_from_slice(&block.r);
        }
        let weights: Option<Vec<f64>> = (self.root_weights.as_ref())
            .map(|_| (0..rows).map(|row| self.row_weight(row)).collect());
        if let Some(weights) = &weights {
            for (v, w) in r.iter_mut().zip(weights) {
                *v *= w;
            }
        }
        // Column by column, each block's part of it (the blocks hold their columns whole):
        // each entry its column's scale times its row's weight root, in that order (without
        // weights, times nothing: a product with 1 is the same number).
        let mut jac = Mat::zeros(rows + extra, self.unknowns());
        for (col, &scale) in self.scale.iter().enumerate() {
            let column = jac.col_as_slice_mut(col);
            for block in &blocks {
                let (matrix, j) = if col < ng {
                    (&block.full, self.selected[col])
                } else {
                    (&block.cjac, col - ng)
                };
                let n = matrix.nrows();
                let source = &matrix.as_slice()[j * n..(j + 1) * n];
                let out = &mut column[block.first..block.first + n];
                match &weights {
                    Some(weights) => {
                        let weights = &weights[block.first..block.first + n];
                        for ((o, v), w) in out.iter_mut().zip(source).zip(weights) {
                            *o = v * scale * w;
                        }
                    }
                    None => {
                        for (o, v) in out.iter_mut().zip(source) {
                            *o = v * scale;
                        }
                    }
                }
            }
        }
        (r, jac)
    }

    /// The paper's cost, eq. (15): mean Euclidean distance, mm (of the points: measured
    /// orientations take no part in it).
    pub fn mean_distance(&self, u: &[f64]) -> f64 {
        let r = self.residuals(u);
        let m = self.obs.len().max(1) as f64;
        r[..3 * self.obs.len()]
            .chunks_exact(3)
            .map(|c| (c[0] * c[0] + c[1] * c[1] + c[2] * c[2]).sqrt())
            .sum::<f64>()
            / m
    }

    /// [`Self::mean_distance`] and its gradient `(1/m) Σ J_iᵀ r_i / |r_i|`. Rigid problems go
    /// through the poses one at a time, each pose's 3 × P Jacobian block written into one small
    /// buffer (no `3m × k` matrix is formed); a point with a zero residual (where the cost is
    /// not differentiable) contributes nothing to the gradient.
    pub fn mean_distance_and_gradient(&self, u: &[f64]) -> (f64, Vec<f64>) {
        if self.compliance.is_some() {
            return self.mean_distance_and_gradient_from_jacobian(u);
        }
        let robot = self.robot_at(u);
        let m = self.obs.len();
        let mut block = DMatrix::zeros(3, robot.param_count());
        let mut cost = 0.0;
        let mut g = vec![0.0; self.selected.len()];
        let targets = self.obs.target_indices(&robot);
        for (i, &t) in targets.iter().enumerate() {
            let d = robot.write_param_jacobian_at(self.obs.joints(i), t, &mut block, 0)
                - self.obs.points[i];
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

    /// The mean distance and its gradient through the full residual Jacobian.
    fn mean_distance_and_gradient_from_jacobian(&self, u: &[f64]) -> (f64, Vec<f64>) {
        let (r, jac) = self.residuals_and_jacobian(u);
        let m = self.obs.len().max(1) as f64;
        let mut cost = 0.0;
        let mut g = vec![0.0; self.unknowns()];
        for (i, d) in r[..3 * self.obs.len()].chunks_exact(3).enumerate() {
            let norm = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
            cost += norm;
            if norm == 0.0 {
                continue;
            }
            for (k, gk) in g.iter_mut().enumerate() {
                *gk += (0..3).map(|a| jac[(3 * i + a, k)] * d[a]).sum::<f64>() / norm;
            }
        }
        g.iter_mut().for_each(|gk| *gk /= m);
        (cost / m, g)
    }
}

/// The second-order terms of [`CalibrationProblem::exact_jacobian`] in the position rows
/// `row..row + 3` of the table's columns `full` and the joint errors' `cjac` for the command `q`
/// under `load` (the point `p` before the `turns`; the joint errors' columns written from the
/// `theta` columns, the turns' own not yet): every column turned with the point — the turns
/// move it by `Σ t × (p − a)`, linear in `p`, so a column that moves `p` moves the turned point
/// `(I + Σ [t]×)` times as much —, then the torques' and the runouts' dependence on the table.
#[allow(clippy::too_many_arguments)]
fn exact_terms(
    robot: &Robot,
    model: &JointErrors,
    (q, load): (&[f64], f64),
    turns: &Turns,
    p: Vector3<f64>,
    theta: &[usize],
    (full, cjac): (&mut DMatrix<f64>, &mut DMatrix<f64>),
    row: usize,
) {
    if !turns.is_empty() {
        let sum: Vector3<f64> = turns.iter().map(|(t, _)| t).sum();
        let turn = Matrix3::identity() + sum.cross_matrix();
        for m in [&mut *full, &mut *cjac] {
            let turned = turn * m.rows(row, 3);
            m.rows_mut(row, 3).copy_from(&turned);
        }
    }
    let joints = joint_columns(full, theta, row);
    let twists = robot.param_twists(q);
    let rates = model.deflection_rates(robot, q, load);
    add_deflection_rates(&twists, &rates, &joints, full, row);
    add_runout_rates(model, &twists, turns, p, full, row);
}

/// Each joint's column (its `theta` column) in rows `row..row + 3` of `full`: how the point
/// (or the tool frame) moves as the joint turns, copied before the table's columns change.
fn joint_columns(full: &DMatrix<f64>, theta: &[usize], row: usize) -> Vec<Vector3<f64>> {
    (theta.iter())
        .map(|&c| full.fixed_view::<3, 1>(row, c).into_owned())
        .collect()
}

/// Adds to the table's columns in rows `row..row + 3` of `full` what the deflection adds as the
/// table moves the gravity torques it holds: `Σ_j joints[j] · δd_j`, with `δd_j` the rate of
/// joint `j`'s deflection ([`JointErrors::deflection_rates`]) along each joint parameter's
/// `twists` at the command ([`Robot::param_twists`]) and `joints[j]` the rows' column of joint
/// `j`. The base's parameters turn gravity with the arm: they move no torque.
fn add_deflection_rates(
    twists: &[Option<ParamTwist>],
    rates: &DeflectionRates,
    joints: &[Vector3<f64>],
    full: &mut DMatrix<f64>,
    row: usize,
) {
    if rates.is_empty() {
        return;
    }
    for (col, twist) in twists.iter().enumerate() {
        let Some(ParamTwist {
            joint: Some(k),
            w,
            v,
            ..
        }) = twist
        else {
            continue;
        };
        let mut column = full.fixed_view_mut::<3, 1>(row, col);
        for (joint, rate) in joints.iter().zip(rates) {
            let (rw, rv) = rate[*k];
            column += joint * (rw.dot(w) + rv.dot(v));
        }
    }
}

/// Adds to the table's position columns in rows `row..row + 3` of `full` how the runouts'
/// turns of the point `p` (before them) change as the table moves their axes and origins: a
/// parameter that moves runout joint `j`'s frame by the twist `(ω, v)` turns its turn `t` by
/// `ω × t` and slides its origin `a` by `δa` (`ω × a + v`; the twist's `origin` for a parameter
/// of joint `j` itself), moving `t × (p − a)` by `(ω × t) × (p − a) − t × δa` (the part through
/// `p` is in the column already).
/// Tilts (turns under gravity moments) are left out.
fn add_runout_rates(
    model: &JointErrors,
    twists: &[Option<ParamTwist>],
    turns: &Turns,
    p: Vector3<f64>,
    full: &mut DMatrix<f64>,
    row: usize,
) {
    if model.runouts.is_empty() {
        return;
    }
    let runouts = model.runout_turns(turns);
    for (col, twist) in twists.iter().enumerate() {
        let Some(ParamTwist {
            joint,
            w,
            v,
            origin,
        }) = twist
        else {
            continue;
        };
        let from = joint.unwrap_or(0);
        let mut column = full.fixed_view_mut::<3, 1>(row, col);
        for (r, (t, a)) in model.runouts.iter().zip(runouts) {
            let j = r.wave.joint;
            if j >= from {
                let slide = if *joint == Some(j) {
                    *origin
                } else {
                    w.cross(a) + v
                };
                column += w.cross(t).cross(&(p - a)) - t.cross(&slide);
            }
        }
    }
}

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
