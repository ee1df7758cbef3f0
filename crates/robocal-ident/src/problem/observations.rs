//! The measured rows an identification fits: joints, loads, points, a 6-DoF probe's
//! orientations, with what the model predicts for them.

use nalgebra::{DMatrix, Matrix3, Vector3};
use robocal_data::MeasurementSet;
use robocal_robot::{Compliance, Robot, rotation_vector, rpy_to_matrix};

/// Rows of a residual or Jacobian evaluation per parallel task: enough that a task outweighs
/// its scheduling, few enough that the rows of one fit spread over the cores.
pub(super) const ROWS_PER_TASK: usize = 64;

/// Consecutive rows of the residuals and of their Jacobian
/// ([`CalibrationProblem::jacobian_blocks`]).
pub(super) struct RowBlock {
    /// The first row's index in the whole residual vector.
    pub(super) first: usize,
    /// The rows' residuals.
    pub(super) r: Vec<f64>,
    /// The rows' entries of every table parameter's column.
    pub(super) full: DMatrix<f64>,
    /// The rows' entries of every joint-error coefficient's column.
    pub(super) cjac: DMatrix<f64>,
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
    /// Each row's weight on its squared errors (position and orientation); empty: every row
    /// weighs 1.
    pub weights: Vec<f64>,
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
            weights: Vec::new(),
        }
    }

    /// Every row weighed by the weight `weights` gives its target (1 for a target not named);
    /// no weights where every row would weigh 1.
    pub fn weigh_targets(&mut self, weights: &[(String, f64)]) {
        let of = |i: usize| {
            let target = self.targets.get(i).map_or("", String::as_str);
            (weights.iter())
                .find(|(name, _)| name == target)
                .map_or(1.0, |(_, w)| *w)
        };
        let w: Vec<f64> = (0..self.len()).map(of).collect();
        self.weights = if w.iter().all(|&v| v == 1.0) {
            Vec::new()
        } else {
            w
        };
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
