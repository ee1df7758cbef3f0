//! Kinematic calibration end to end: registration, best-fit alignment ("before"),
//! identifiability, the chosen solver, statistics and parameter uncertainties.

use robocal_data::ErrorStats;
use robocal_robot::{ParamId, Robot};
use serde::Serialize;

use crate::bfgs::run_bfgs;
use crate::error::{IdentError, Result};
use crate::identifiability::{analyse, standard_deviations};
use crate::lm::run_lm;
use crate::problem::{CalibrationProblem, LeastSquares, Observations, select};
use crate::registration::register_base;

/// Which optimiser identifies the parameters.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum SolverKind {
    /// Levenberg–Marquardt on the sum of squared errors.
    Lm,
    /// The paper's BFGS on the mean Euclidean distance, eq. (15).
    Bfgs,
}

impl SolverKind {
    /// Name used in configs and reports.
    pub fn name(self) -> &'static str {
        match self {
            Self::Lm => "lm",
            Self::Bfgs => "bfgs",
        }
    }
}

/// Settings of a kinematic identification.
#[derive(Debug, Clone, PartialEq)]
pub struct KinematicSettings {
    /// Optimiser.
    pub solver: SolverKind,
    /// Parameter names to identify; `None`: every parameter of the table.
    pub parameters: Option<Vec<String>>,
    /// Iteration limit of the optimiser.
    pub max_iterations: u64,
    /// Relative column norm below which a parameter counts as unidentifiable.
    pub rank_tolerance: f64,
}

impl Default for KinematicSettings {
    fn default() -> Self {
        Self {
            solver: SolverKind::Lm,
            parameters: None,
            max_iterations: 200,
            rank_tolerance: 1e-6,
        }
    }
}

/// One parameter in the report (file units: mm or deg).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ParameterReport {
    /// Stable name, e.g. `j2.beta`.
    pub name: String,
    /// `mm` or `deg`.
    pub unit: &'static str,
    /// Value in the robot file given to `calibrate`.
    pub nominal: f64,
    /// Identified value (for base and tool: relative to the registration, see `fitted_frame`).
    pub identified: f64,
    /// identified − nominal.
    pub delta: f64,
    /// Standard deviation from the covariance and the residual; absent when not identified.
    pub std: Option<f64>,
    /// Whether the parameter was identified (false: held at its registered/nominal value).
    pub identified_flag: bool,
}

/// A parameter held fixed because the data cannot determine it.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FixedParameter {
    /// Stable name.
    pub name: String,
    /// Fraction of its Jacobian column not explained by the identified parameters.
    pub independent_fraction: f64,
    /// Human-readable reason.
    pub reason: String,
}

/// What a kinematic identification did and found.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct KinematicReport {
    /// `lm` or `bfgs`.
    pub solver: &'static str,
    /// What it minimised.
    pub cost: &'static str,
    /// Optimiser iterations.
    pub iterations: u64,
    /// Why the optimiser stopped.
    pub termination: String,
    /// Measured points used.
    pub points: usize,
    /// Nominal table with only base and tool fitted (best-fit alignment).
    pub before: ErrorStats,
    /// Identified model on the same points.
    pub after: ErrorStats,
    /// Every parameter of the table.
    pub parameters: Vec<ParameterReport>,
    /// Parameters held fixed as unidentifiable with this pose set.
    pub fixed: Vec<FixedParameter>,
    /// Condition number of the scaled Jacobian of the identified parameters.
    pub condition_number: f64,
    /// Observability index O1 (Borm & Menq) of the scaled Jacobian.
    pub observability_index: f64,
}

/// A calibrated kinematic model and its report.
#[derive(Debug, Clone)]
pub struct KinematicCalibration {
    /// The identified table (a valid robot file when written out).
    pub robot: Robot,
    /// The nominal table with only base and tool fitted.
    pub aligned: Robot,
    /// Report.
    pub report: KinematicReport,
}

/// Indices of the parameters of `robot` that satisfy `keep`.
fn indices(robot: &Robot, keep: impl Fn(ParamId) -> bool) -> Vec<usize> {
    (robot.param_ids().into_iter().enumerate())
        .filter(|&(_, id)| keep(id))
        .map(|(i, _)| i)
        .collect()
}

/// Fits only the base and tool of `robot` (after a closed-form registration of the base):
/// the "before calibration" model of a tracker's best-fit alignment.
pub fn align(robot: &Robot, obs: &Observations) -> Result<Robot> {
    let registered = register_base(robot, obs)?;
    // Tool first (base held), then base and tool together.
    let tool = indices(&registered, |id| matches!(id, ParamId::Tool(_)));
    let frame = indices(&registered, |id| {
        matches!(id, ParamId::Base(_) | ParamId::Tool(_))
    });
    let mut current = registered;
    for sel in [tool, frame] {
        let problem = CalibrationProblem::new(&current, sel, obs);
        let k = problem.selected().len();
        let (u, _, _) = run_lm(LeastSquares(&problem), vec![0.0; k], 100)?;
        current = problem.robot_at(&u);
    }
    Ok(current)
}

/// Identifies the kinematic parameters of `nominal` from `obs`.
pub fn calibrate_kinematics(
    nominal: &Robot,
    obs: &Observations,
    settings: &KinematicSettings,
) -> Result<KinematicCalibration> {
    if obs.dof != nominal.dof() {
        return Err(IdentError::JointCountMismatch {
            expected: nominal.dof(),
            found: obs.dof,
        });
    }
    let selected = select(nominal, settings.parameters.as_deref())?;
    if 3 * obs.len() < selected.len().min(9) || obs.len() < 3 {
        return Err(IdentError::TooFewMeasurements {
            points: obs.len(),
            equations: 3 * obs.len(),
            parameters: selected.len(),
        });
    }
    let aligned = align(nominal, obs)?;
    let before = ErrorStats::from_errors(&obs.errors(&aligned));

    // Identifiability at the aligned model (the neighbourhood of the solution).
    let ids = aligned.param_ids();
    let problem = CalibrationProblem::new(&aligned, selected.clone(), obs);
    let (_, jac) = problem.residuals_and_jacobian(&vec![0.0; selected.len()]);
    let sel_ids: Vec<ParamId> = selected.iter().map(|&i| ids[i]).collect();
    let ident = analyse(&jac, &sel_ids, settings.rank_tolerance);
    let problem = problem.restricted(&ident.identifiable);
    let kept = problem.selected().to_vec();
    let fixed: Vec<FixedParameter> = ident
        .unidentifiable
        .iter()
        .map(|&(p, fraction)| FixedParameter {
            name: sel_ids[p].to_string(),
            independent_fraction: fraction,
            reason: if fraction == 0.0 {
                "no effect on the measured points with these poses".into()
            } else {
                "redundant with the identified parameters for these poses".into()
            },
        })
        .collect();

    let u0 = vec![0.0; kept.len()];
    let (u, iterations, termination) = if kept.is_empty() {
        (u0, 0, "nothing to identify".to_string())
    } else {
        match settings.solver {
            SolverKind::Lm => run_lm(LeastSquares(&problem), u0, settings.max_iterations)?,
            SolverKind::Bfgs => run_bfgs(&problem, u0, settings.max_iterations)?,
        }
    };
    let robot = problem.robot_at(&u);
    let after = ErrorStats::from_errors(&obs.errors(&robot));
    let (r, jac) = problem.residuals_and_jacobian(&u);
    let std_u = standard_deviations(&jac, &r);

    let nominal_values = nominal.params();
    let identified_values = robot.params();
    let parameters = ids
        .iter()
        .enumerate()
        .map(|(i, id)| {
            let pos = kept.iter().position(|&k| k == i);
            let std = match (pos, &std_u) {
                (Some(p), Some(s)) => Some(id.to_file_units(s[p] * problem.scale()[p]).abs()),
                _ => None,
            };
            let nominal = id.to_file_units(nominal_values[i]);
            let identified = id.to_file_units(identified_values[i]);
            ParameterReport {
                name: id.to_string(),
                unit: id.file_unit_name(),
                nominal,
                identified,
                delta: identified - nominal,
                std,
                identified_flag: pos.is_some(),
            }
        })
        .collect();
    Ok(KinematicCalibration {
        robot,
        aligned,
        report: KinematicReport {
            solver: settings.solver.name(),
            cost: match settings.solver {
                SolverKind::Lm => "sum of squared errors",
                SolverKind::Bfgs => "mean Euclidean distance (paper eq. 15)",
            },
            iterations,
            termination,
            points: obs.len(),
            before,
            after,
            parameters,
            fixed,
            condition_number: ident.condition_number,
            observability_index: ident.observability_index,
        },
    })
}
