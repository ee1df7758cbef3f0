//! The calibrated model and its predictions.

use nalgebra::{Matrix3, Rotation3, Unit, Vector3};
use robocal_data::{ErrorStats, Measurement, Sample};
use robocal_residual::{
    ClassifierSettings, Frame, GatePhysics, PHYSICS_PER_JOINT, ResidualModel, Samples, inputs_of,
};
use robocal_robot::{
    JointErrors, ParameterCovariance, Robot, displaced, matrix_to_rpy, rotation_vector,
    rpy_to_matrix,
};

/// How much the two sides of a step along one of the covariance's directions may differ, as a
/// share of their sum, before the step is taken to have crossed a jump (a turned backlash flank)
/// rather than a slope: a smooth model's sides differ by the step's second-order term, a part in
/// a million on the accuracy suite's twins.
const JUMP_SHARE: f64 = 0.5;

/// What one step along a direction of the covariance adds to a point's variance (mm²), from the
/// point's moves `ahead` (the step forwards) and `behind` (the step backwards): the central
/// difference's square where the two agree; where they differ by more than [`JUMP_SHARE`] of
/// their sum, the smaller one's, with the jump (mm) between them, else 0.
fn step_variance(ahead: Vector3<f64>, behind: Vector3<f64>) -> (f64, f64) {
    let (na, nb) = (ahead.norm(), behind.norm());
    let jump = (ahead - behind).norm();
    if jump <= JUMP_SHARE * (na + nb) {
        (((ahead + behind) / 2.0).norm_squared(), 0.0)
    } else {
        (na.min(nb).powi(2), jump)
    }
}

/// A calibrated model: the identified table, the joint-error physics identified with it and the
/// residual model learned on what they leave. Each part beyond the table is optional; a nominal
/// robot file is a model with the table alone ([`Self::kinematic`]).
#[derive(Debug, Clone)]
pub struct CalibratedModel {
    /// Identified kinematic table (MDH, β, base, tool).
    pub robot: Robot,
    /// Joint errors: payload compliance, transmission harmonics, self-weight terms.
    pub joint_errors: Option<JointErrors>,
    /// What the table and the joint errors leave, learned.
    pub residual: Option<ResidualModel>,
    /// The nominal table registered in the tracker frame (its base and tool fitted to the
    /// training data): the arm before calibration, against which `robocal report` compares.
    /// Not used to predict.
    pub nominal: Option<Robot>,
    /// The joint readings and loads the model was calibrated on (`domain.toml`): rows outside
    /// are extrapolation, which `predict`, `evaluate` and `compensate` warn of. `None` for a
    /// table alone or a model directory written before it.
    pub domain: Option<crate::Domain>,
    /// The identified parameters' covariance (`covariance.json`): a physical model's predicted
    /// points' standard deviations ([`Self::physics_sigmas`]). `None` for a table alone, a
    /// fit without degrees of freedom left, or a directory written before it.
    pub covariance: Option<ParameterCovariance>,
    /// Play that follows the order of motion (`motion.toml`): where a row carries the
    /// direction of each joint's last move, the joints stand behind their readings by it
    /// ([`Self::read`]). `None` where the calibration found none that pays.
    pub motion: Option<crate::MotionPlay>,
}

impl CalibratedModel {
    /// A model of its parts.
    pub fn new(
        robot: Robot,
        joint_errors: Option<JointErrors>,
        residual: Option<ResidualModel>,
    ) -> Self {
        Self {
            robot,
            joint_errors,
            residual,
            nominal: None,
            domain: None,
            covariance: None,
            motion: None,
        }
    }

    /// The sample at the joint angles the model puts it at: its readings, less the play that
    /// follows its last move where the model has one and the sample an order
    /// ([`crate::MotionPlay::read`]). Reading a read sample again changes nothing.
    pub fn read<'a>(&self, s: &'a Sample) -> std::borrow::Cow<'a, Sample> {
        match &self.motion {
            Some(m) => m.read(s),
            None => std::borrow::Cow::Borrowed(s),
        }
    }

    /// [`Self::read`] of every sample.
    fn read_all<'a>(&self, samples: &[&'a Sample]) -> Vec<std::borrow::Cow<'a, Sample>> {
        samples.iter().map(|s| self.read(s)).collect()
    }

    /// The kinematic table alone.
    pub fn kinematic(robot: Robot) -> Self {
        Self::new(robot, None, None)
    }

    /// Joints of the robot.
    pub fn dof(&self) -> usize {
        self.robot.dof()
    }

    /// The joint deflection under `load` (kg) at command `q` (rad), rad (zeros without joint
    /// errors).
    pub fn deflection(&self, q: &[f64], load: f64) -> Vec<f64> {
        match &self.joint_errors {
            Some(e) => e.deflection(&self.robot, q, load),
            None => vec![0.0; q.len()],
        }
    }

    /// The table and joint-error part of the prediction at command `q` (rad) under `load`, mm,
    /// world frame.
    pub fn physical_point(&self, q: &[f64], load: f64) -> Vector3<f64> {
        self.robot
            .point_under_load(self.joint_errors.as_ref(), q, load)
    }

    /// What the joint errors move the point by besides the joint angles at command `q` (rad)
    /// under `load`, mm, world frame: the bearings' tilts ([`robocal_robot::Tilt`]) and the
    /// axis runouts ([`robocal_robot::Runout`]; zero without either) — the physical point less
    /// the table's at the deflected angles, computed without evaluating the table there twice.
    /// Without the runouts here, commands compensated through a model with them would miss their
    /// targets by what the runouts move the point.
    pub fn turn_offset(&self, q: &[f64], load: f64) -> Vector3<f64> {
        match &self.joint_errors {
            Some(e) if e.has_turns() => {
                let p = self.robot.point(&e.deflected(&self.robot, q, load));
                robocal_robot::turned(&e.turns(&self.robot, q, load), p) - p
            }
            _ => Vector3::zeros(),
        }
    }

    /// The residual model's predicted error at command `q` (rad) and `load`, mm, world frame
    /// (zero without one).
    pub fn residual_at(&self, q: &[f64], load: f64) -> Vector3<f64> {
        match &self.residual {
            Some(r) => {
                let mut row: Vec<f64> = q.iter().map(|v| v.to_degrees()).collect();
                row.push(load);
                let mut rows = Samples::rows(vec![row]);
                if let Some(p) = r.gate_physics() {
                    rows.physics = vec![gate_physics_row(&self.robot, &p, q, load)];
                }
                self.to_world(r.frame, q, Vector3::from(r.predict(&rows)[0]))
            }
            None => Vector3::zeros(),
        }
    }

    /// The turn of the frame that turns with joint 1 at command `q` (rad): about joint 1's axis
    /// (world frame, as this model's table has it) by its reading. A residual model in
    /// [`Frame::Joint1`] learns `turnᵀ e` of a world error `e` and predicts `turn f`.
    pub fn joint1_turn(&self, q: &[f64]) -> Rotation3<f64> {
        match (self.robot.joint1_axis(), q.first()) {
            (Some(axis), Some(&q1)) => Rotation3::from_axis_angle(&Unit::new_normalize(axis), q1),
            _ => Rotation3::identity(),
        }
    }

    /// A residual model's error `e` in `frame` at command `q` (rad), in the world frame.
    pub fn to_world(&self, frame: Frame, q: &[f64], e: Vector3<f64>) -> Vector3<f64> {
        match frame {
            Frame::World => e,
            Frame::Joint1 => self.joint1_turn(q) * e,
        }
    }

    /// A world error `e` at command `q` (rad), in `frame`: what a residual model in `frame`
    /// learns.
    pub fn from_world(&self, frame: Frame, q: &[f64], e: Vector3<f64>) -> Vector3<f64> {
        match frame {
            Frame::World => e,
            Frame::Joint1 => self.joint1_turn(q).inverse() * e,
        }
    }

    /// The residual model's rows for `samples`: their inputs and, when its gate reads physics,
    /// their physics rows ([`gate_physics_row`] with this model's table).
    pub fn residual_rows(&self, samples: &[&Sample]) -> Samples {
        let read = self.read_all(samples);
        let samples: Vec<&Sample> = read.iter().map(AsRef::as_ref).collect();
        let samples = samples.as_slice();
        let physics = self.residual.as_ref().and_then(ResidualModel::gate_physics);
        with_gate_physics(
            Samples::rows(samples.iter().map(|s| inputs_of(s)).collect()),
            &self.robot,
            physics.as_ref(),
            samples,
        )
    }

    /// The whole model's predicted point at command `q` (rad) and `load`, mm, world frame.
    pub fn point(&self, q: &[f64], load: f64) -> Vector3<f64> {
        self.physical_point(q, load) + self.residual_at(q, load)
    }

    /// The table and joint-error part of the prediction for a sample, mm, world frame: of the
    /// point its `target` names (the default point for an empty name, and for a name the table
    /// lacks — data are checked against the table when read, [`Self::check_targets`]).
    pub fn base_point(&self, s: &Sample) -> Vector3<f64> {
        let s = self.read(s);
        let t = self.robot.target_index(&s.target).unwrap_or(0);
        self.robot.for_target(t).point_under_load(
            self.joint_errors.as_ref(),
            &s.joints_rad(),
            s.load,
        )
    }

    /// This model measuring the point `target` names (a `[tool.points]` name; empty, or a name
    /// the table lacks: the default point): its table's default point replaced by that point,
    /// everything else kept — what compensation puts on a row's target.
    pub fn for_target(&self, target: &str) -> std::borrow::Cow<'_, CalibratedModel> {
        match self.robot.target_index(target).unwrap_or(0) {
            0 => std::borrow::Cow::Borrowed(self),
            t => {
                let mut m = self.clone();
                m.robot.tool = self.robot.target_point(t);
                std::borrow::Cow::Owned(m)
            }
        }
    }

    /// Checks that every sample's `target` names a point of the table: the first that does not
    /// is an error naming `source`, its line and the points there are.
    pub fn check_targets<'a>(
        &self,
        source: &std::path::Path,
        samples: impl IntoIterator<Item = &'a Sample>,
    ) -> std::result::Result<(), robocal_data::DataError> {
        robocal_data::check_targets(source, samples, &self.robot.point_names())
    }

    /// Predicted points for `samples`, mm, world frame (the residual model in one batch).
    pub fn predict<'a>(&self, samples: impl IntoIterator<Item = &'a Sample>) -> Vec<Vector3<f64>> {
        self.predict_with_sigma(samples, false).0
    }

    /// Predicted points for `samples` (mm, world frame) and, with `sigma`, each point's standard
    /// deviation (the root sum of the axes' variances, mm) where the model knows how sure it is:
    /// a residual model that gives one (the GP) gives it, with what holding a transmission
    /// harmonic beyond its reach may miss ([`Self::held_variance`]: the residual model learned
    /// nothing there, and the GP's prior knows nothing of the physics beneath it; 0 inside every
    /// reach) and how much the physics' own deviation grows outside the domain
    /// ([`Self::outside_variance`]); a network residual whose folds estimated its spread
    /// ([`ResidualModel::spread_mm`]) gives the physics' deviation and that spread in
    /// quadrature; a physical model without a residual model gives its parameters'
    /// ([`Self::physics_sigmas`]); otherwise `None`.
    pub fn predict_with_sigma<'a>(
        &self,
        samples: impl IntoIterator<Item = &'a Sample>,
        sigma: bool,
    ) -> (Vec<Vector3<f64>>, Option<Vec<f64>>) {
        let samples: Vec<&Sample> = samples.into_iter().collect();
        let read = self.read_all(&samples);
        let samples: Vec<&Sample> = read.iter().map(AsRef::as_ref).collect();
        let mut points: Vec<Vector3<f64>> = samples.iter().map(|s| self.base_point(s)).collect();
        let Some(residual) = &self.residual else {
            let sigmas = if sigma {
                self.physics_sigmas_about(&samples, &points)
            } else {
                None
            };
            return (points, sigmas);
        };
        // A network's spread beside the physics' deviation, about the physical points.
        let beside = match (sigma, residual.spread_mm) {
            (true, Some(spread)) if !residual.kind().gives_std() => self
                .physics_sigmas_about(&samples, &points)
                .map(|p| p.iter().map(|s| s.hypot(spread)).collect::<Vec<f64>>()),
            _ => None,
        };
        let (mean, std) = residual.predict_with_std(&self.residual_rows(&samples), sigma);
        for ((p, e), s) in points.iter_mut().zip(mean).zip(&samples) {
            *p += self.to_world(residual.frame, &s.joints_rad(), Vector3::from(e));
        }
        if beside.is_some() {
            return (points, beside);
        }
        let sigmas = std.map(|sd| {
            let outside = self.outside_variance(&samples);
            (sd.iter().zip(&samples).zip(outside))
                .map(|((s, sample), o)| {
                    (s[0] * s[0] + s[1] * s[1] + s[2] * s[2] + self.held_variance(sample) + o)
                        .sqrt()
                })
                .collect()
        });
        (points, sigmas)
    }

    /// The standard deviation (mm; the root sum of the three axes' variances) that the
    /// identified parameters' covariance gives each sample's predicted point — the table and
    /// the joint errors, to first order in the parameters' spread: `√tr(J C Jᵀ)` with `J` the
    /// point's derivative over the parameters, as `Σ_k |(p(x + a_k) − p(x − a_k)) / 2|²` over
    /// the columns `a_k` of `C = Σ a_k a_kᵀ` ([`ParameterCovariance::directions`]).
    ///
    /// A step that moves the point by much more on one side than on the other crossed a jump:
    /// a backlash flank that the parameters' spread can turn (the torque on the joint within
    /// it of zero). There the side without the jump is the slope, and the jump `J` itself is a
    /// two-valued uncertainty: the flank either holds or turns, whose variance is at most
    /// `|J|²/4` — added once (every direction that turns the same flank sees the same jump).
    /// Beyond a transmission harmonic's reach, where the model holds it, what the parameters
    /// cannot say is added too ([`Self::held_variance`]).
    /// `None` without a covariance, or one that names a parameter the model lacks (checked
    /// when a directory is read).
    pub fn physics_sigmas(&self, samples: &[&Sample]) -> Option<Vec<f64>> {
        let read = self.read_all(samples);
        let samples: Vec<&Sample> = read.iter().map(AsRef::as_ref).collect();
        let samples = samples.as_slice();
        let at: Vec<Vector3<f64>> = samples.iter().map(|s| self.base_point(s)).collect();
        self.physics_sigmas_about(samples, &at)
    }

    /// [`Self::physics_sigmas`] about the samples' points `at` ([`Self::base_point`]'s),
    /// already predicted.
    fn physics_sigmas_about(&self, samples: &[&Sample], at: &[Vector3<f64>]) -> Option<Vec<f64>> {
        let variances = self.parameter_variances(samples, at)?;
        Some(
            (variances.iter().zip(samples))
                .map(|(v, s)| (v + self.held_variance(s)).sqrt())
                .collect(),
        )
    }

    /// The variance (mm²) the identified parameters' covariance gives each sample's point,
    /// about `at`: the slopes' and a flank's jump ([`Self::physics_sigmas`]), without what
    /// holding a harmonic may miss.
    fn parameter_variances(&self, samples: &[&Sample], at: &[Vector3<f64>]) -> Option<Vec<f64>> {
        let cov = self.covariance.as_ref()?;
        let parameters = cov.resolve(&self.robot, self.joint_errors.as_ref()).ok()?;
        let mut variance = vec![0.0; samples.len()];
        let mut jump = vec![0.0f64; samples.len()];
        for a in cov.directions() {
            let minus: Vec<f64> = a.iter().map(|v| -v).collect();
            let shifted = |step: &[f64]| {
                let (robot, joint_errors) =
                    displaced(&self.robot, self.joint_errors.as_ref(), &parameters, step);
                CalibratedModel::new(robot, joint_errors, None)
            };
            let (up, down) = (shifted(&a), shifted(&minus));
            for (i, s) in samples.iter().enumerate() {
                let (v, j) = step_variance(up.base_point(s) - at[i], at[i] - down.base_point(s));
                variance[i] += v;
                jump[i] = jump[i].max(j);
            }
        }
        Some(
            (variance.iter().zip(&jump))
                .map(|(v, j)| v + j * j / 4.0)
                .collect(),
        )
    }

    /// How much the physical model's variance grows outside the readings and loads it was
    /// calibrated on, mm², per sample: its parameters' variance there (that of
    /// [`Self::physics_sigmas`], without [`Self::held_variance`]) less that at the nearest point
    /// of the domain
    /// ([`crate::Domain::clamped`]), floored at 0. A residual model's deviation, calibrated on
    /// the folds within the domain, holds the physics' uncertainty there but not its growth
    /// beyond. 0 inside the domain, and for a model without a domain or a covariance.
    pub fn outside_variance(&self, samples: &[&Sample]) -> Vec<f64> {
        let read = self.read_all(samples);
        let samples: Vec<&Sample> = read.iter().map(AsRef::as_ref).collect();
        let samples = samples.as_slice();
        let mut growth = vec![0.0; samples.len()];
        let Some(domain) = &self.domain else {
            return growth;
        };
        let (outside, clamped): (Vec<usize>, Vec<Sample>) = (samples.iter().enumerate())
            .filter_map(|(i, s)| domain.clamped(s).map(|c| (i, c)))
            .unzip();
        if outside.is_empty() {
            return growth;
        }
        let beyond: Vec<&Sample> = outside.iter().map(|&i| samples[i]).collect();
        let inside: Vec<&Sample> = clamped.iter().collect();
        let variances = |rows: &[&Sample]| {
            let at: Vec<Vector3<f64>> = rows.iter().map(|s| self.base_point(s)).collect();
            self.parameter_variances(rows, &at)
        };
        let (Some(there), Some(near)) = (variances(&beyond), variances(&inside)) else {
            return growth;
        };
        for (k, &i) in outside.iter().enumerate() {
            growth[i] = (there[k] - near[k]).max(0.0);
        }
        growth
    }

    /// What holding the transmission harmonics and the axis runouts beyond their reach may miss
    /// at `s`, mm²: each joint's [`robocal_robot::Harmonic::held_variance`] (rad²) summed over
    /// its harmonics, through the point's derivative in that joint (central differences of
    /// 10⁻³°), and each runout's, through the lever of its turn (`|u × (p − a)|²`, `u` the axis
    /// it turns about, `a` its joint's origin). 0 where every reading lies within the reach.
    pub fn held_variance(&self, s: &Sample) -> f64 {
        const STEP_DEG: f64 = 1e-3;
        let Some(errors) = &self.joint_errors else {
            return 0.0;
        };
        let s = self.read(s);
        let q = s.joints_rad();
        let mut total = 0.0;
        for (j, &qj) in q.iter().enumerate() {
            let v: f64 = (errors.harmonics.iter())
                .filter(|h| h.joint == j)
                .map(|h| h.held_variance(qj))
                .sum();
            if v <= 0.0 {
                continue;
            }
            let moved = |d: f64| {
                let mut t = s.clone().into_owned();
                t.joints[j] += d;
                self.base_point(&t)
            };
            let slope = (moved(STEP_DEG) - moved(-STEP_DEG)) / (2.0 * STEP_DEG.to_radians());
            total += slope.norm_squared() * v;
        }
        if errors
            .runouts
            .iter()
            .any(|r| r.wave.held_variance(q[r.wave.joint]) > 0.0)
        {
            let (axes, frames) = self.robot.axes_and_frames(&q);
            let p = self.robot.point(&q);
            for r in &errors.runouts {
                let j = r.wave.joint;
                let lever = r.axis(&frames).cross(&(p - axes[j].1));
                total += lever.norm_squared() * r.wave.held_variance(q[j]);
            }
        }
        total
    }

    /// Measured − predicted position of every row, mm, world frame.
    pub fn residuals<'a>(
        &self,
        rows: impl IntoIterator<Item = &'a Measurement>,
    ) -> Vec<Vector3<f64>> {
        let rows: Vec<&Measurement> = rows.into_iter().collect();
        let predicted = self.predict(rows.iter().map(|m| &m.sample));
        (predicted.iter().zip(rows))
            .map(|(p, m)| m.position - p)
            .collect()
    }

    /// Euclidean errors on measured rows, mm.
    pub fn errors(&self, rows: &[&Measurement]) -> Vec<f64> {
        (self.residuals(rows.iter().copied()).iter())
            .map(|r| r.norm())
            .collect()
    }

    /// Error statistics on measured rows.
    pub fn stats(&self, rows: &[&Measurement]) -> ErrorStats {
        ErrorStats::from_errors(&self.errors(rows))
    }

    /// The tool frame's predicted orientation for a sample, world frame: the table and the
    /// joint errors (the residual model corrects positions only). Its target does not matter:
    /// every point rides on the one tool frame.
    pub fn rotation(&self, s: &Sample) -> Matrix3<f64> {
        let s = self.read(s);
        self.robot
            .rotation_under_load(self.joint_errors.as_ref(), &s.joints_rad(), s.load)
    }

    /// The predicted orientation of a sample as fixed-axis roll, pitch, yaw, deg (the `rx, ry,
    /// rz` of a measurement file).
    pub fn orientation_deg(&self, s: &Sample) -> Vector3<f64> {
        matrix_to_rpy(&self.rotation(s)).map(f64::to_degrees)
    }

    /// Angle between the measured and the predicted tool frame of every row that has a
    /// measured orientation, deg (rows without one are left out).
    pub fn orientation_errors(&self, rows: &[&Measurement]) -> Vec<f64> {
        rows.iter()
            .filter_map(|m| self.orientation_error(m))
            .collect()
    }

    /// Angle between the measured and the predicted tool frame of a row, deg; `None` for a row
    /// without a measured orientation.
    pub fn orientation_error(&self, m: &Measurement) -> Option<f64> {
        let measured = rpy_to_matrix(&m.orientation?.map(f64::to_radians));
        Some(rotation_angle(&(measured * self.rotation(&m.sample).transpose())).to_degrees())
    }
}

/// The angle of a rotation matrix, rad in [0, π] (precise for small and large angles alike).
pub fn rotation_angle(r: &Matrix3<f64>) -> f64 {
    rotation_vector(r).norm()
}

/// What a CA-SOMM gate reading physics sees of command `q` (rad) under `load` kg, besides the
/// angles, from `robot`'s table: per joint, the gravity torque that one kilogram at the
/// payload's centre of mass puts on the joint's axis (N·m per kg: the payload's lever); the
/// torque of the row's load (N·m); then the world X, Y and Z motion of the measured point per
/// degree of the joint (mm/deg). A joint with play rests on the flank such a torque presses it
/// to, and the point jumps along that joint's motion: a class of the error along one world axis
/// is the sign of a torque times the sign of a motion.
pub fn gate_physics_row(robot: &Robot, p: &GatePhysics, q: &[f64], load: f64) -> Vec<f64> {
    let unit = JointErrors::new(
        vec![0.0; robot.dof()],
        p.gravity.into(),
        p.payload_com.into(),
    );
    let lever = unit.torques(robot, q, 1.0);
    let jacobian = robot.joint_jacobian(q);
    let mut row = lever.clone();
    row.extend(lever.iter().map(|l| l * load));
    for axis in 0..3 {
        row.extend((0..robot.dof()).map(|j| jacobian[(axis, j)].to_radians()));
    }
    debug_assert_eq!(row.len(), PHYSICS_PER_JOINT * robot.dof());
    row
}

/// The gravity and payload a gate reading physics uses: the classifier settings' own, else the
/// joint-error model's (`joint_errors`), else gravity along −z of the base frame and the
/// payload at the measured point (`robot`'s tool).
pub fn resolve_gate_physics(
    settings: &ClassifierSettings,
    robot: &Robot,
    joint_errors: Option<&JointErrors>,
) -> GatePhysics {
    let gravity = settings
        .gravity
        .unwrap_or_else(|| joint_errors.map_or([0.0, 0.0, -9.80665], |e| e.gravity.into()));
    let payload_com = settings
        .payload_com
        .unwrap_or_else(|| joint_errors.map_or(robot.tool, |e| e.payload_com).into());
    GatePhysics {
        gravity,
        payload_com,
    }
}

/// `samples` (made of `rows`, in order) with each row's physics features from `robot`'s table
/// when a gate reads `physics`; unchanged without.
pub fn with_gate_physics(
    samples: Samples,
    robot: &Robot,
    physics: Option<&GatePhysics>,
    rows: &[&Sample],
) -> Samples {
    match physics {
        Some(p) => samples.with_physics(gate_physics_rows(robot, p, rows)),
        None => samples,
    }
}

/// [`gate_physics_row`] of every sample.
pub fn gate_physics_rows(robot: &Robot, p: &GatePhysics, samples: &[&Sample]) -> Vec<Vec<f64>> {
    samples
        .iter()
        .map(|s| gate_physics_row(robot, p, &s.joints_rad(), s.load))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A slope: the central difference, and no jump (the sides differ by a second-order term).
    /// A jump on one side (a backlash flank the step turned): the other side's slope, and the
    /// jump between the two, whichever side it lies on.
    #[test]
    fn a_step_across_a_jump_is_told_from_a_slope() {
        let slope = Vector3::new(0.010, -0.004, 0.002);
        let (v, j) = step_variance(slope * 1.001, slope * 0.999);
        assert!(
            (v - slope.norm_squared()).abs() < 1e-12 * v && j == 0.0,
            "{v} {j}"
        );
        let turn = Vector3::new(0.0, 1.1, 0.0);
        for (ahead, behind) in [(slope + turn, slope), (slope, slope - turn)] {
            let (v, j) = step_variance(ahead, behind);
            assert!((v - slope.norm_squared()).abs() < 1e-15, "{v}");
            assert!((j - 1.1).abs() < 1e-12, "{j}");
        }
        // No move at all: nothing.
        assert_eq!(
            step_variance(Vector3::zeros(), Vector3::zeros()),
            (0.0, 0.0)
        );
    }
}
