//! The information a set of configurations carries about the parameters `calibrate` will
//! identify, D-optimal selection, observability indices and noise propagation.
//!
//! A configuration measured at `L` loads gives `3L` rows of the scaled identification
//! Jacobian `B_c` (the rows `calibrate` would build: the same parameter set after the
//! identifiability analysis, the same column scaling). The information of a set `S` is
//! `M(S) = Σ_{c∈S} B_cᵀ B_c`; the D-optimal set maximises `log det M(S)`. With tracker noise
//! `σ` per coordinate, the parameters' covariance is `σ² M⁻¹` (scaled units), and a pose's
//! predicted point has covariance `C σ² M⁻¹ Cᵀ`, `C` its own rows.

use nalgebra::DMatrix;
use robocal_ident::{CalibrationProblem, Column, Observations, analyse, select};
use robocal_robot::{ErrorParam, JointErrors, Robot, Unit};
use serde::Serialize;

use crate::error::Result;
use crate::settings::{Criterion, PlanSettings};

/// Rank tolerance of the identifiability analysis (calibrate's default).
pub const RANK_TOLERANCE: f64 = 1e-6;

/// The candidates' and the check poses' rows of the scaled identification Jacobian.
#[derive(Debug, Clone)]
pub struct Pool {
    /// Names of the identified parameters (`j2.a`, `base.x`, `j3.compliance`, …).
    pub names: Vec<String>,
    /// Each parameter's file unit (`mm`, `deg`, `deg/kN·m`, …) and the factor from its
    /// internal unit to it.
    pub units: Vec<(&'static str, f64)>,
    /// Each parameter's column scale: internal value = scale × scaled value.
    pub scale: Vec<f64>,
    /// Parameters that the candidates cannot identify (held fixed, as calibrate would).
    pub fixed: Vec<String>,
    /// One block per candidate configuration: `3LT × k` (L loads, T reflectors).
    pub blocks: Vec<DMatrix<f64>>,
    /// One block per check pose.
    pub checks: Vec<DMatrix<f64>>,
}

/// A selected set and how it was found.
#[derive(Debug, Clone, Serialize)]
pub struct Design {
    /// Candidate indices, in the order chosen.
    pub chosen: Vec<usize>,
    /// `log det` of the set's information (scaled units) after the greedy pass.
    pub greedy_log_det: f64,
    /// `log det` after the exchanges.
    pub log_det: f64,
    /// Exchanges made: (candidate out, candidate in, `log det` after).
    pub exchanges: Vec<(usize, usize, f64)>,
}

/// Observability indices of a set's scaled Jacobian (singular values `σ`, `m` points).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Indices {
    /// O1 (Borm & Menq): `(Π σ)^(1/k) / √m`.
    pub o1: f64,
    /// O3: the smallest singular value.
    pub o3: f64,
    /// O4 (noise amplification, Nahvi & Hollerbach): `σ_min² / σ_max`.
    pub o4: f64,
    /// `σ_max / σ_min`.
    pub condition_number: f64,
}

/// `log det` of a symmetric positive semi-definite matrix (`-∞` when it is singular).
pub fn log_det(m: &DMatrix<f64>) -> f64 {
    match m.clone().cholesky() {
        Some(c) => 2.0 * c.l().diagonal().iter().map(|d| d.ln()).sum::<f64>(),
        None => f64::NEG_INFINITY,
    }
}

impl Pool {
    /// The rows of every candidate (`candidates`, joint angles in rad) and check pose at
    /// every load of `settings` and every reflector of `robot` (the default point and each
    /// `[tool.points]` point), for the parameters calibrate would identify from the
    /// candidates with `robot` (its table, base and tool; joint-error blocks as `settings`
    /// ask).
    pub fn new(
        robot: &Robot,
        candidates: &[Vec<f64>],
        checks: &[Vec<f64>],
        settings: &PlanSettings,
    ) -> Result<Self> {
        let loads = &settings.loads;
        let mut obs = Observations::new(robot.dof());
        // Every reflector of the robot file is measured at every pose and load: the default
        // point, then each named point (`[tool.points]`).
        let targets = robot.target_names();
        for q in candidates.iter().chain(checks) {
            for &load in loads {
                for (t, name) in targets.iter().enumerate() {
                    obs.q.extend_from_slice(q);
                    obs.loads.push(load);
                    obs.points.push(robot.for_target(t).point(q));
                    obs.targets.push(name.to_string());
                }
            }
        }
        let selected = select(robot, None)?;
        let ids = robot.param_ids();
        let mut columns: Vec<Column> = selected.iter().map(|&i| ids[i].into()).collect();
        let mut problem = CalibrationProblem::new(robot, selected.clone(), &obs);
        let errors = joint_error_model(robot, settings);
        if let Some((model, params)) = &errors {
            columns.extend(params.iter().map(|&p| Column::of_error(model, p)));
            problem = problem.with_joint_errors(model.clone(), params.clone());
        }
        let (_, jac) = problem.residuals_and_jacobian(&vec![0.0; problem.unknowns()]);
        // Identifiability from the candidates' rows alone (the check poses are not measured).
        let per = 3 * loads.len() * targets.len();
        let rows = per * candidates.len();
        let candidate_rows = faer::Mat::from_fn(rows, jac.ncols(), |i, j| jac[(i, j)]);
        let ident = analyse(&candidate_rows, &columns, RANK_TOLERANCE);
        let keep = &ident.identifiable;
        let block =
            |c: usize| DMatrix::from_fn(per, keep.len(), |r, k| jac[(c * per + r, keep[k])]);
        Ok(Self {
            names: keep.iter().map(|&p| columns[p].to_string()).collect(),
            units: keep
                .iter()
                .map(|&p| match columns[p] {
                    Column::Param(id) => match id.unit() {
                        Unit::Mm => ("mm", 1.0),
                        Unit::Rad => ("deg", 180.0 / std::f64::consts::PI),
                    },
                    Column::Compliance(_) | Column::Tilt(_) => {
                        ("deg/kN·m", 180.0 / std::f64::consts::PI * 1000.0)
                    }
                    Column::Harmonic { .. } | Column::Backlash(_) | Column::Runout { .. } => {
                        ("deg", 180.0 / std::f64::consts::PI)
                    }
                    Column::SelfWeight { .. } => ("deg/unit", 180.0 / std::f64::consts::PI),
                    Column::LinkWeight { part, .. } => (part.weight_unit(), 1.0),
                    Column::PayloadCom(_) => ("mm", 1.0),
                })
                .collect(),
            scale: keep.iter().map(|&p| problem.scale()[p]).collect(),
            fixed: ident
                .unidentifiable
                .iter()
                .map(|&(p, _)| columns[p].to_string())
                .collect(),
            blocks: (0..candidates.len()).map(block).collect(),
            checks: (0..checks.len())
                .map(|c| block(candidates.len() + c))
                .collect(),
        })
    }

    /// Identified parameters.
    pub fn parameters(&self) -> usize {
        self.names.len()
    }

    /// The information of a set of candidates.
    pub fn information(&self, set: &[usize]) -> DMatrix<f64> {
        let k = self.parameters();
        let mut m = DMatrix::zeros(k, k);
        for &c in set {
            m += self.blocks[c].transpose() * &self.blocks[c];
        }
        m
    }

    /// Greedy D-optimal choice of `count` candidates, then exchanges (a chosen one for one
    /// not chosen) while one raises `log det`.
    pub fn d_optimal(&self, count: usize) -> Design {
        self.select(count, Criterion::DOptimal)
    }

    /// The mean over the check points of `CᵀC`: `trace(M⁻¹ A)` is the mean predicted variance
    /// (per unit noise) of a check point's position.
    pub fn check_moment(&self) -> DMatrix<f64> {
        let k = self.parameters();
        let mut a = DMatrix::zeros(k, k);
        let mut points = 0;
        for c in &self.checks {
            a += c.transpose() * c;
            points += c.nrows() / 3;
        }
        a / points.max(1) as f64
    }

    /// Greedy choice of `count` candidates by `criterion`, then exchanges (a chosen one for
    /// one not chosen) while one improves it.
    pub fn select(&self, count: usize, criterion: Criterion) -> Design {
        let k = self.parameters();
        let n = self.blocks.len();
        let count = count.min(n);
        // A small ridge makes the first steps (a singular information) well defined.
        let mean_trace =
            (0..n).map(|c| self.blocks[c].norm_squared()).sum::<f64>() / n.max(1) as f64;
        let ridge = DMatrix::identity(k, k) * (1e-9 * mean_trace / k.max(1) as f64);
        let moment = match criterion {
            Criterion::DOptimal => None,
            Criterion::IOptimal => Some(self.check_moment()),
        };
        // For the I criterion, `P = M⁻¹ A M⁻¹`, made once per inverse (see [`Self::gain_of`]).
        let p_of = |inv: &DMatrix<f64>| moment.as_ref().map(|a| inv * a * inv);
        // The best candidate not taken, and its gain.
        let best = |inv: &DMatrix<f64>, p: Option<&DMatrix<f64>>, taken: &[bool]| {
            (0..n)
                .filter(|&c| !taken[c])
                .map(|c| (c, self.gain_of(c, inv, p)))
                .fold(None, |best: Option<(usize, f64)>, (c, g)| match best {
                    // The first of equals stays.
                    Some((_, b)) if g > b => Some((c, g)),
                    Some(_) => best,
                    None => Some((c, g)),
                })
        };
        let mut m = ridge.clone();
        let mut chosen: Vec<usize> = Vec::with_capacity(count);
        let mut taken = vec![false; n];
        for _ in 0..count {
            let Some(inv) = m.clone().try_inverse() else {
                break;
            };
            let Some((c, _)) = best(&inv, p_of(&inv).as_ref(), &taken) else {
                break;
            };
            m += self.blocks[c].transpose() * &self.blocks[c];
            taken[c] = true;
            chosen.push(c);
        }
        let greedy_log_det = log_det(&self.information(&chosen));
        let mut exchanges = Vec::new();
        for _pass in 0..5 {
            let mut swapped = false;
            for slot in 0..chosen.len() {
                let out = chosen[slot];
                let without = &m - self.blocks[out].transpose() * &self.blocks[out];
                let Some(inv) = without.clone().try_inverse() else {
                    continue;
                };
                let p = p_of(&inv);
                let own = self.gain_of(out, &inv, p.as_ref());
                if let Some((c, g)) = best(&inv, p.as_ref(), &taken)
                    && g > own + 1e-9 * own.abs().max(1e-12)
                {
                    m = without + self.blocks[c].transpose() * &self.blocks[c];
                    taken[out] = false;
                    taken[c] = true;
                    chosen[slot] = c;
                    exchanges.push((out, c, log_det(&self.information(&chosen))));
                    swapped = true;
                }
            }
            if !swapped {
                break;
            }
        }
        Design {
            log_det: log_det(&self.information(&chosen)),
            greedy_log_det,
            chosen,
            exchanges,
        }
    }

    /// What adding candidate `c` to an information with inverse `inv` gains: the rise of
    /// `log det` (D, `p` none) or the fall of `trace(M⁻¹ A)` (I, `p = M⁻¹ A M⁻¹`, by the
    /// Woodbury identity: `trace((I + B M⁻¹ Bᵀ)⁻¹ B P Bᵀ)`).
    fn gain_of(&self, c: usize, inv: &DMatrix<f64>, p: Option<&DMatrix<f64>>) -> f64 {
        match p {
            None => gain(&self.blocks[c], inv),
            Some(p) => i_gain(&self.blocks[c], inv, p),
        }
    }

    /// Observability indices of a set.
    pub fn indices(&self, set: &[usize]) -> Indices {
        let points = set
            .iter()
            .map(|&c| self.blocks[c].nrows() / 3)
            .sum::<usize>();
        indices_of(&self.information(set), points)
    }

    /// Standard deviation of every parameter (file units) after measuring `set` with
    /// `noise_mm` per coordinate; infinite for a set that cannot identify them.
    pub fn parameter_sigmas(&self, set: &[usize], noise_mm: f64) -> Vec<f64> {
        let Some(cov) = self.information(set).try_inverse() else {
            return vec![f64::INFINITY; self.parameters()];
        };
        (0..self.parameters())
            .map(|j| noise_mm * cov[(j, j)].max(0.0).sqrt() * self.scale[j] * self.units[j].1)
            .collect()
    }

    /// Predicted position error at each check pose and load (the root of the trace of the
    /// propagated 3 × 3 covariance, mm) after measuring `set`.
    pub fn predicted_errors(&self, set: &[usize], noise_mm: f64) -> Vec<f64> {
        let Some(cov) = self.information(set).try_inverse() else {
            return vec![f64::INFINITY; self.checks.iter().map(|c| c.nrows() / 3).sum()];
        };
        let mut out = Vec::new();
        for c in &self.checks {
            let p = c * &cov * c.transpose();
            for point in 0..c.nrows() / 3 {
                let trace: f64 = (0..3).map(|a| p[(3 * point + a, 3 * point + a)]).sum();
                out.push(noise_mm * trace.max(0.0).sqrt());
            }
        }
        out
    }
}

/// `trace((I + B M⁻¹ Bᵀ)⁻¹ B P Bᵀ)` with `P = M⁻¹ A M⁻¹`: how much adding the rows `B` lowers
/// `trace(M⁻¹ A)`.
fn i_gain(b: &DMatrix<f64>, inv: &DMatrix<f64>, p: &DMatrix<f64>) -> f64 {
    let s = DMatrix::identity(b.nrows(), b.nrows()) + b * inv * b.transpose();
    let q = b * p * b.transpose();
    match s.cholesky() {
        Some(c) => c.solve(&q).trace(),
        None => 0.0,
    }
}

/// `log det(I + B M⁻¹ Bᵀ)`: how much adding the rows `B` raises `log det M`.
fn gain(b: &DMatrix<f64>, inv: &DMatrix<f64>) -> f64 {
    let s = DMatrix::identity(b.nrows(), b.nrows()) + b * inv * b.transpose();
    log_det(&s)
}

/// Indices of an information matrix `m = JᵀJ` of `points` measured points.
pub fn indices_of(m: &DMatrix<f64>, points: usize) -> Indices {
    let eig = m.clone().symmetric_eigenvalues();
    let sv: Vec<f64> = eig.iter().map(|e| e.max(0.0).sqrt()).collect();
    let k = sv.len().max(1) as f64;
    let (max, min) = sv
        .iter()
        .fold((0.0f64, f64::INFINITY), |(a, b), &s| (a.max(s), b.min(s)));
    let o1 = (sv.iter().map(|s| s.max(1e-300).ln()).sum::<f64>() / k).exp()
        / (points.max(1) as f64).sqrt();
    Indices {
        o1,
        o3: min,
        o4: if max > 0.0 { min * min / max } else { 0.0 },
        condition_number: if min > 0.0 { max / min } else { f64::INFINITY },
    }
}

/// The joint-error model and its coefficients that `settings` ask calibrate to identify.
fn joint_error_model(
    robot: &Robot,
    settings: &PlanSettings,
) -> Option<(JointErrors, Vec<ErrorParam>)> {
    if !settings.compliance && settings.harmonics == 0 && !settings.self_weight {
        return None;
    }
    let n = robot.dof();
    let joints: Vec<usize> = (0..n).collect();
    let mut model = JointErrors::new(
        vec![0.0; n],
        settings.gravity,
        settings.payload_com.unwrap_or(robot.tool),
    );
    if settings.harmonics > 0 {
        model = model.with_harmonics(&joints, settings.harmonics);
    }
    if settings.self_weight {
        model = model.with_self_weight(&joints, n);
    }
    let params = model
        .params()
        .into_iter()
        .filter(|p| settings.compliance || !matches!(p, ErrorParam::Compliance(_)))
        .collect();
    Some((model, params))
}
