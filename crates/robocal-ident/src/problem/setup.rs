//! The problem itself: the table, the unknowns (the table's selected parameters and the
//! joint-error coefficients), their scales, the prior on the harmonics, and the model at a
//! solution.

use crate::identifiability::posterior_covariance;
use faer::Mat;
use robocal_robot::{Compliance, ErrorParam, JointErrors, ParamId, Robot};
use std::sync::Arc;

use super::observations::Observations;

/// A robot, a parameter selection and observations: residuals, Jacobians and costs in scaled
/// coordinates `u` (see the module documentation).
///
/// With a compliance model ([`Self::with_compliance`]) the unknowns are the selected geometric
/// parameters followed by the compliances of the selected joints, and every point is predicted
/// at the joint angles its load deflects the arm to.
#[derive(Debug, Clone)]
pub struct CalibrationProblem<'a> {
    pub(super) robot: Robot,
    x0: Vec<f64>,
    pub(super) selected: Vec<usize>,
    /// One per unknown: geometric parameters first, then compliances.
    pub(super) scale: Vec<f64>,
    pub(super) compliance: Option<ComplianceFit>,
    pub(super) obs: &'a Observations,
    /// The observations with a measured orientation: their three rotation residuals follow
    /// the `3m` position residuals, in this order.
    pub(super) oriented: Vec<usize>,
    /// Square roots of the points' weights (none: every point weighs 1); the iteratively
    /// reweighted least squares of a robust loss set them.
    pub(super) root_weights: Option<Vec<f64>>,
    /// Zero-mean Gaussian priors on joint-error coefficients: `(coefficient, weight)`, each a
    /// residual row `weight × value` (mm-equivalent) that the least-squares view appends.
    pub(super) prior: Vec<(ErrorParam, f64)>,
    /// The priors' spreads (their standard deviations, internal units), by group.
    pub(super) prior_spread: PriorSpreads,
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
pub(crate) struct ComplianceFit {
    /// The model at `u = 0` (and gravity and payload).
    pub(super) start: JointErrors,
    /// Its coefficients that are identified.
    pub(super) params: Vec<ErrorParam>,
    /// The bases of its waves at every row.
    pub(super) waves: RowWaves,
}

/// The bases of a model's waves at every row's readings ([`JointErrors::wave_bases`]): the
/// same at every `u`, where only coefficients change, so computed once per problem (shared by
/// its restrictions) rather than at every evaluation.
#[derive(Debug, Clone)]
pub(crate) struct RowWaves {
    /// Row after row, `per_row` each.
    pub(super) bases: Arc<[(f64, f64)]>,
    pub(super) per_row: usize,
}

impl RowWaves {
    /// `model`'s wave bases at every row of `obs`.
    pub(super) fn of(model: &JointErrors, obs: &Observations) -> Self {
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
    pub(super) fn row(&self, i: usize) -> &[(f64, f64)] {
        &self.bases[i * self.per_row..(i + 1) * self.per_row]
    }
}

/// Scale of each column from its RMS length per point: `1 / norm`, or 1 for a column that is
/// round-off next to the largest (so that the identifiability analysis sees it as having no
/// effect).
pub(crate) fn column_scales(norms: &[f64]) -> Vec<f64> {
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
            root_weights: (!obs.weights.is_empty())
                .then(|| obs.weights.iter().map(|w| w.max(0.0).sqrt()).collect()),
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

    /// The root weight of residual row `row` (a position row's point, or a rotation row's).
    pub(super) fn row_weight(&self, row: usize) -> f64 {
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
    ///
    /// [`LeastSquares`]: crate::problem::LeastSquares
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
    pub(super) fn prior_rows(&self, u: &[f64]) -> Vec<(f64, usize, f64)> {
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

    /// Weights each point's residual by `weights` (one per point, ≥ 0) times the row's own
    /// weight ([`Observations::weights`]): least squares on `Σ wᵢ |rᵢ|²`.
    pub fn set_point_weights(&mut self, weights: &[f64]) {
        let own = |i: usize| self.obs.weights.get(i).copied().unwrap_or(1.0);
        self.root_weights = Some(
            (weights.iter().enumerate())
                .map(|(i, w)| (w * own(i)).max(0.0).sqrt())
                .collect(),
        );
    }

    /// The weight root of point `i` (1 without weights).
    pub(super) fn root_weight(&self, i: usize) -> f64 {
        self.root_weights.as_ref().map_or(1.0, |w| w[i])
    }

    /// The bases of `compliance`'s waves at every row, computed with the problem, where its
    /// waves are the start's (the same bases: [`JointErrors::same_waves`]); none where it has no
    /// wave or others.
    pub(super) fn row_waves(&self, compliance: &Compliance) -> Option<&RowWaves> {
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
