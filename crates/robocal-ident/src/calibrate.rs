//! Kinematic calibration end to end: registration, best-fit alignment ("before"),
//! identifiability, the chosen solver, statistics and parameter uncertainties.

use faer::Mat;
use nalgebra::Vector3;
use robocal_data::{ErrorStats, robust_std};
use robocal_robot::{
    Compliance, DEG_PER_KNM, ErrorParam, Flank, Harmonic, JointErrors, ParamId,
    ParameterCovariance, Robot, Unit,
};
use serde::Serialize;

use crate::bfgs::run_bfgs;
use crate::error::{IdentError, Result};
use crate::identifiability::{
    Column, Identifiability, analyse, deviations_of, null_ridged_standard_deviations,
    standard_deviations,
};
use crate::lm::{run_lm, run_lm_until};
use crate::problem::{
    CalibrationProblem, DEFAULT_NOISE_DEG, DEFAULT_NOISE_MM, LeastSquares, Observations,
    PriorSpreads, angle_weight, select,
};
use crate::registration::{register_base, register_tool_rotation};

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
    /// Every solver.
    pub const ALL: [Self; 2] = [Self::Lm, Self::Bfgs];

    /// The solver a config names.
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|s| s.name() == name)
    }

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
    /// Joint compliances identified with the geometry (elasto-geometric calibration).
    pub compliance: Option<ComplianceSettings>,
    /// Transmission harmonics and self-weight terms identified with the geometry.
    pub joint_errors: Option<JointErrorSettings>,
    /// How the points' errors are weighed.
    pub loss: Loss,
    /// Weight of a measured orientation's residual, mm per deg (`[kinematic] angle_weight`);
    /// `None`: `noise_mm / noise_deg`.
    pub angle_weight: Option<f64>,
    /// The tracker's position noise, mm per coordinate (1σ).
    pub noise_mm: f64,
    /// The 6-DoF probe's angular noise, deg per axis (1σ).
    pub noise_deg: f64,
    /// When the fit must have ended (the default calibration's share of its time budget for a
    /// fold of a candidate): a Levenberg–Marquardt solve still running then stops, and the fit
    /// with [`crate::IdentError::Deadline`]; BFGS (the paper's) runs on. `None`: no limit.
    pub deadline: Option<std::time::Instant>,
    /// The count of the fit's work (every Levenberg–Marquardt solve's, [`crate::Work`]), with
    /// its limit: past it the fit stops with [`crate::IdentError::Deadline`] at the same
    /// evaluation on every machine (the default calibration's deterministic share of its budget
    /// for a fold). `None`: not counted.
    pub work: Option<crate::Work>,
}

impl KinematicSettings {
    /// The settings of the first identification that gives the compliances the fit starts
    /// from, where it has one: with the links' weights, the bearings' tilts or the payload's
    /// centre of mass (at zero compliance they move nothing), the same fit without them, nor
    /// backlash (whose flanks are chosen with the whole model), nor — with
    /// [`JointErrorSettings::runout_from_without`] — the axis runouts; `None` where the
    /// compliances start from given values or from zero.
    pub fn first_fit(&self) -> Option<KinematicSettings> {
        let c = self.compliance.as_ref()?;
        let je = self.joint_errors.as_ref();
        let link_weights = je.is_some_and(|je| je.link_weights);
        let tilt = je.is_some_and(|je| je.tilt);
        if c.start.is_some() || !(link_weights || tilt || c.identify_payload_com) {
            return None;
        }
        let mut first = self.clone();
        first
            .compliance
            .as_mut()
            .expect("compliance")
            .identify_payload_com = false;
        if let Some(je_first) = first.joint_errors.as_mut() {
            je_first.link_weights = false;
            je_first.backlash = false;
            je_first.tilt = false;
            // Started from the model without them, the runouts take no part in the first fit:
            // it is that model's, which the memo may hold.
            if je_first.runout_from_without {
                je_first.runout = 0;
            }
            je_first.runout_from_without = false;
            if !(je_first.harmonics > 0 || je_first.self_weight) {
                first.joint_errors = None;
            }
        }
        Some(first)
    }

    /// Whether [`JointErrorSettings::runout_from_without`] makes other fits than these settings
    /// without it: only where the compliances' first fit ([`Self::first_fit`]) would hold the
    /// axis runouts (the flanks come from the model without them either way).
    pub fn runouts_in_first_fit(&self) -> bool {
        let mut full = self.clone();
        if let Some(je) = full.joint_errors.as_mut() {
            je.runout_from_without = false;
        }
        (full.first_fit())
            .and_then(|first| first.joint_errors)
            .is_some_and(|je| je.runout > 0)
    }

    /// The weight of an orientation residual, mm per rad (see [`Self::angle_weight`]).
    pub fn angle_weight_per_rad(&self) -> f64 {
        match self.angle_weight {
            Some(w) => w.to_degrees(),
            None => angle_weight(self.noise_mm, self.noise_deg),
        }
    }
}

/// How the identification weighs the points' errors.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Loss {
    /// Least squares: every point weighs the same (the paper's, and every stage config's).
    #[default]
    Squared,
    /// Huber: squared up to [`HUBER_K`] robust standard deviations of the error components
    /// (1.4826 × their median absolute deviation), linear beyond, by iteratively reweighted
    /// least squares (weight `min(1, k σ / |rᵢ|)` per point, at most [`IRLS_ROUNDS`] solves):
    /// a few wild points cannot pull the fit towards themselves.
    Huber,
}

/// Where the Huber loss turns linear, in robust standard deviations of the error components.
pub const HUBER_K: f64 = 3.0;

/// Most reweighted solves of the Huber loss.
pub const IRLS_ROUNDS: usize = 8;

/// Which configuration-dependent joint errors are identified with the geometry.
#[derive(Debug, Clone, PartialEq)]
pub struct JointErrorSettings {
    /// Highest transmission-harmonic order per joint (0: none).
    pub harmonics: u32,
    /// Joints (0-based) with harmonics; `None`: every joint.
    pub harmonic_joints: Option<Vec<usize>>,
    /// Self-weight terms (every joint; those the poses cannot separate are held at zero).
    pub self_weight: bool,
    /// The links' weights shared by the joints they load ([`robocal_robot::LinkWeight`]: each
    /// joint deflects by its payload compliance times the gravity torque of the payload and of
    /// the links beyond it). Needs the compliance settings; identified after a first fit
    /// without them, from that fit's compliances (at zero compliance a weight moves nothing).
    pub link_weights: bool,
    /// Backlash of every joint (a joint whose flanks the poses do not separate from its offset
    /// is held at zero: at the start, and at the fit where its rows all rest on one flank),
    /// each on the flank of its approach from home, or (with
    /// `backlash_torque`) on the flank its gravity torque presses where that explains more.
    pub backlash: bool,
    /// The home readings, rad, one per joint (`None`: 0 for every joint).
    pub backlash_home: Option<Vec<f64>>,
    /// Whether a joint's backlash may rest on the flank its torque presses: the identification
    /// is run twice, first with the approach flanks, then with each joint's flank chosen from
    /// what the first left (the `flank` module).
    pub backlash_torque: bool,
    /// Each joint's flank, when already chosen (the second run).
    pub flanks: Option<Vec<Flank>>,
    /// A torque flank's preload searched where its step explains most beyond the joint's own
    /// terms (offset, compliance, harmonics, self-weight), its direction fitted again without
    /// them (the `flank` module); `false`: the logistic regression's alone, whose boundary the
    /// compliance pulls toward the rows' middle torque. The default calibration tries it as one
    /// candidate more where its chosen physics holds backlash (`docs/method.md`).
    pub flank_search: bool,
    /// The tilting compliance of every joint ([`robocal_robot::Tilt`]: the parts beyond it turn
    /// across its axis under the gravity moment of the payload and of the links' weights; a
    /// joint whose tilt the poses do not separate from the rest is held rigid, and, where the
    /// compliance settings ask for plausible values only, so is one that comes out negative or
    /// no larger than its σ; elsewhere a negative one is warned of).
    pub tilt: bool,
    /// Axis runouts of orders 1 up to this one, about both axes across every joint
    /// ([`robocal_robot::Runout`]; 0: none), each reaching as far as its joint's readings allow,
    /// as a harmonic does; those the poses do not separate from the geometry are held at zero.
    pub runout: u32,
    /// The axis runouts started from the compliances of the model without them: the first fit
    /// of the compliances (with the links' weights or the payload's centre of mass) leaves them
    /// out, and the backlash flanks they start from are that model's own — fits a memo that
    /// has made the model without the runouts holds, so that only the runouts' own fits remain
    /// (a third of the work on the paper's arm). Other fits than with the runouts in the first
    /// fit: the default calibration tries it only where the budget cut that candidate.
    pub runout_from_without: bool,
    /// The transmission harmonics under a zero-mean Gaussian prior whose spread the data choose
    /// (marginal likelihood over the harmonics of the fit without it; empirical Bayes): a
    /// harmonic the poses barely determine is drawn toward the spread of the others (LM only);
    /// the axis runouts likewise, under a prior of their own spread.
    pub harmonic_prior: bool,
    /// Gravity in the robot base frame {0}, m/s² (for the self-weight torques; the compliance
    /// settings' when both are given).
    pub gravity: Vector3<f64>,
}

impl Default for JointErrorSettings {
    fn default() -> Self {
        Self {
            harmonics: 2,
            harmonic_joints: None,
            self_weight: false,
            link_weights: false,
            backlash: false,
            backlash_home: None,
            backlash_torque: true,
            flanks: None,
            flank_search: false,
            tilt: false,
            runout: 0,
            runout_from_without: false,
            harmonic_prior: true,
            gravity: Vector3::new(0.0, 0.0, -9.80665),
        }
    }
}

/// One joint-error coefficient besides the payload compliances, in the report.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ErrorTermReport {
    /// Stable name: `j2.h1.sin`, `j3.sw4.mass`.
    pub name: String,
    /// `deg` for harmonics, `deg per basis unit` for self-weight terms.
    pub unit: &'static str,
    /// Identified value (0 when held).
    pub value: f64,
    /// Standard deviation.
    pub std: Option<f64>,
    /// Whether it was identified (false: the poses cannot separate it; held at 0).
    pub identified: bool,
}

impl Default for KinematicSettings {
    fn default() -> Self {
        Self {
            solver: SolverKind::Lm,
            parameters: None,
            max_iterations: 200,
            rank_tolerance: 1e-6,
            compliance: None,
            joint_errors: None,
            loss: Loss::Squared,
            angle_weight: None,
            noise_mm: DEFAULT_NOISE_MM,
            noise_deg: DEFAULT_NOISE_DEG,
            deadline: None,
            work: None,
        }
    }
}

/// Settings of the compliance part of an elasto-geometric identification.
#[derive(Debug, Clone, PartialEq)]
pub struct ComplianceSettings {
    /// Joints (0-based) whose compliance is identified; `None`: the joints that carry the
    /// payload's gravity torque in these data ([`default_compliance_joints`]).
    pub joints: Option<Vec<usize>>,
    /// Gravity in the robot base frame {0}, m/s².
    pub gravity: Vector3<f64>,
    /// The payload's centre of mass in the flange frame, mm; `None`: the measured point.
    pub payload_com: Option<Vector3<f64>>,
    /// Hold a joint rigid, and solve again, when its compliance comes out impossible: negative,
    /// beyond [`COMPLIANCE_BOUND`], or less than its own standard deviation (the default
    /// calibration sets it; stage files and experiments keep every value, with a warning).
    pub plausible_only: bool,
    /// When the registered base is more than [`MOUNTING_ANGLE_DEG`] from upright in the
    /// tracker frame (an arm on a wall or a ceiling), also identify with gravity along the
    /// tracker's −z (a levelled tracker) and keep the fit with the lower sum of squares; the
    /// report's warnings say when that one was kept. `gravity` is the base-frame guess (the
    /// default calibration sets it; stage files and experiments take `gravity` as given).
    pub detect_mounting: bool,
    /// Identify the payload's centre of mass (flange frame) with the compliances, starting
    /// from `payload_com` (or the measured point): the payload's torque on every joint moves
    /// with it, each joint deflecting by its compliance. Like the links' weights, identified
    /// after a first fit without it, from that fit's compliances (at zero compliance it moves
    /// nothing); a coordinate identified beyond [`PAYLOAD_COM_BOUND`] is held at its start.
    pub identify_payload_com: bool,
    /// The compliances (rad/(N·m), one per joint) an identification with the links' weights or
    /// the payload's centre of mass starts from (the first fit's; set by the identification
    /// itself).
    pub start: Option<Vec<f64>>,
}

/// Farthest (mm) an identified coordinate of the payload's centre of mass may lie from the
/// flange: a payload's centre of mass lies within a metre of the flange it hangs on; beyond, the
/// coordinate fits something else and is held at its start.
pub const PAYLOAD_COM_BOUND: f64 = 1000.0;

/// How far (deg) the registered base's −z may lie from the tracker's −z before the default
/// calibration also tries gravity along the tracker's −z ([`ComplianceSettings::detect_mounting`]).
pub const MOUNTING_ANGLE_DEG: f64 = 30.0;

impl Default for ComplianceSettings {
    fn default() -> Self {
        Self {
            joints: None,
            gravity: Vector3::new(0.0, 0.0, -9.80665),
            payload_com: None,
            plausible_only: false,
            detect_mounting: false,
            identify_payload_com: false,
            start: None,
        }
    }
}

/// The largest joint compliance the default calibration accepts, deg per kN·m (a stiffness of
/// 5.7 kN·m/rad: softer than the wrist of a small arm; a value beyond it is the stage
/// absorbing an effect it does not model).
pub const COMPLIANCE_BOUND: f64 = 10.0;

/// Share of the largest joint's payload torque (RMS over the loaded points) below which a joint
/// counts as carrying none, for the default choice of compliant joints.
pub const TORQUE_SHARE: f64 = 0.05;

/// The joints that carry the payload's gravity torque at the loaded points of `obs`: those whose
/// RMS torque is at least [`TORQUE_SHARE`] of the largest joint's (a vertical first axis, or a
/// flange roll with the payload on its axis, carries none). Returns the joints and each joint's
/// RMS torque per kg (N·m/kg).
pub fn default_compliance_joints(
    robot: &Robot,
    obs: &Observations,
    gravity: &Vector3<f64>,
    payload_com: &Vector3<f64>,
) -> (Vec<usize>, Vec<f64>) {
    let unit = Compliance::new(vec![0.0; robot.dof()], *gravity, *payload_com);
    let mut sums = vec![0.0; robot.dof()];
    let mut loaded = 0usize;
    for i in (0..obs.len()).filter(|&i| obs.loads[i] > 0.0) {
        loaded += 1;
        for (s, t) in sums.iter_mut().zip(unit.torques(robot, obs.joints(i), 1.0)) {
            *s += t * t;
        }
    }
    let rms: Vec<f64> = sums
        .iter()
        .map(|s| (s / loaded.max(1) as f64).sqrt())
        .collect();
    let largest = rms.iter().copied().fold(0.0, f64::max);
    let joints = (0..robot.dof())
        .filter(|&j| largest > 0.0 && rms[j] >= TORQUE_SHARE * largest)
        .collect();
    (joints, rms)
}

/// One joint's compliance in the report.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct JointCompliance {
    /// Joint, counted from 1.
    pub joint: usize,
    /// Identified compliance, deg per kN·m (0 when not identified).
    pub compliance: f64,
    /// Its standard deviation, deg per kN·m.
    pub std: Option<f64>,
    /// RMS payload torque on the joint over the loaded points, N·m per kg.
    pub torque_per_kg: f64,
    /// Whether it was identified.
    pub identified: bool,
    /// Why it was or was not.
    pub reason: String,
}

/// The compliance part of a kinematic report.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ComplianceReport {
    /// Gravity in the base frame, m/s².
    pub gravity: [f64; 3],
    /// Payload centre of mass in the flange frame, mm.
    pub payload_com: [f64; 3],
    /// Where the payload centre of mass came from.
    pub payload_com_source: String,
    /// How the joints were chosen.
    pub joints_source: String,
    /// Every joint.
    pub joints: Vec<JointCompliance>,
    /// Distinct loads in the data, kg.
    pub loads: Vec<f64>,
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

/// The orientation part of a kinematic report (a 6-DoF probe's rows).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct OrientationReport {
    /// Rows with a measured orientation.
    pub rows: usize,
    /// Weight of an orientation residual, mm per deg.
    pub angle_weight: f64,
    /// Angle between measured and predicted tool frames, deg: the aligned nominal table.
    pub before: ErrorStats,
    /// The same, identified model.
    pub after: ErrorStats,
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
    /// With a 6-DoF probe's rows: the angle between measured and predicted tool frames, deg,
    /// of the aligned nominal table and of the identified model.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub orientation: Option<OrientationReport>,
    /// Every parameter of the table.
    pub parameters: Vec<ParameterReport>,
    /// Parameters held fixed as unidentifiable with this pose set.
    pub fixed: Vec<FixedParameter>,
    /// With several reflectors: the parameters identified that the default reflector's rows
    /// alone would leave fixed (the points' own offsets aside).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub identified_by_reflectors: Vec<String>,
    /// Condition number of the scaled Jacobian of the identified parameters.
    pub condition_number: f64,
    /// Observability index O1 (Borm & Menq) of the scaled Jacobian.
    pub observability_index: f64,
    /// Joint compliances, when identified with the geometry.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub compliance: Option<ComplianceReport>,
    /// Transmission harmonics and self-weight terms, when identified with the geometry.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub joint_errors: Vec<ErrorTermReport>,
    /// The spread (standard deviation, deg) of the harmonics' prior the data chose
    /// ([`JointErrorSettings::harmonic_prior`]), when the harmonics were identified under one.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub harmonic_prior_deg: Option<f64>,
    /// The spread (standard deviation, deg) of the axis runouts' prior the data chose, when the
    /// runouts were identified under one (their own, beside the harmonics').
    #[serde(skip_serializing_if = "Option::is_none")]
    pub runout_prior_deg: Option<f64>,
    /// What the user should know about the data's ability to determine the parameters.
    pub warnings: Vec<String>,
}

/// The tilting compliances' start, as a share of the joints' compliances
/// ([`JointErrorSettings::tilt`]): small (bearings are several times stiffer across their axes
/// than reducers about them, and a far start costs LM its way back), and only so that the
/// identifiability analysis at the start sees the links' weights tilt the joints; a tilt it
/// holds fixed is held at zero.
pub const TILT_START_SHARE: f64 = 0.02;

/// Largest amplitude (deg) a transmission harmonic may take: gear reducers' kinematic errors
/// are hundredths of a degree; a harmonic identified beyond this is held at zero.
pub const HARMONIC_BOUND_DEG: f64 = 0.2;

/// Largest half play (deg) a backlash term may take: reducers' backlash is arc-minutes (0.017°
/// each), a worn or cheap gear's a few tenths of a degree of play; a term identified beyond this
/// is held at zero (it fits something else, or the poses barely move the point with the joint).
pub const BACKLASH_BOUND_DEG: f64 = 0.2;

/// Most choices of the backlash flanks in one identification (each followed by a fit).
pub const FLANK_ROUNDS: usize = 2;

/// Most choices of the backlash flanks in one identification with the flank search
/// ([`JointErrorSettings::flank_search`]): two torque-pressed joints' steps trade in what each
/// choice is made from, and the choices settle over more rounds.
pub const SEARCH_FLANK_ROUNDS: usize = 6;

/// Condition number of the scaled Jacobian above which the report warns.
pub const ILL_CONDITIONED: f64 = 1e5;

/// How far (mm, and 10 % of the nominal value) an identified link length may move from the
/// robot file before the report warns.
pub const FAR_FROM_NOMINAL: f64 = 10.0;

/// Mean error (mm) the identified model may leave before the report warns that the data and
/// the robot file do not describe the same arm: a kinematic calibration leaves well under a
/// millimetre on a real arm, elastic and gear effects a few tenths.
pub const POOR_FIT: f64 = 5.0;

/// A calibrated kinematic model and its report.
#[derive(Debug, Clone)]
pub struct KinematicCalibration {
    /// The identified table (a valid robot file when written out).
    pub robot: Robot,
    /// The identified joint compliances, when the settings asked for them.
    pub compliance: Option<Compliance>,
    /// The nominal table with only base and tool fitted.
    pub aligned: Robot,
    /// The identified parameters' covariance (the posterior's under the harmonics' prior), when
    /// the fit leaves degrees of freedom.
    pub covariance: Option<ParameterCovariance>,
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

/// The tracker's −z with the length of `gravity`, in the base frame `nominal` registers to from
/// `obs` ([`align`]), and its angle (degrees) from `gravity` (base frame): how far from upright
/// the arm stands if the tracker is levelled. Beyond [`MOUNTING_ANGLE_DEG`] the arm is taken
/// to hang on a wall or a ceiling, and the data decide which of the two gravity is.
pub fn tracker_down(
    nominal: &Robot,
    obs: &Observations,
    gravity: &Vector3<f64>,
) -> Result<(Vector3<f64>, f64)> {
    Ok(down_of_aligned(&align(nominal, obs)?, gravity))
}

/// [`tracker_down`] from the aligned table.
fn down_of_aligned(aligned: &Robot, gravity: &Vector3<f64>) -> (Vector3<f64>, f64) {
    let down = aligned.base_rotation().transpose() * -Vector3::z() * gravity.norm();
    (down, down.angle(gravity).to_degrees())
}

/// Fits only the base and tool of `robot` (after a closed-form registration of the base):
/// the "before calibration" model of a tracker's best-fit alignment.
pub fn align(robot: &Robot, obs: &Observations) -> Result<Robot> {
    let registered = register_tool_rotation(&register_base(robot, obs)?, obs)?;
    // Tool (and the named points) first (base held), then base and tool together.
    let tool = indices(&registered, |id| {
        matches!(
            id,
            ParamId::Tool(_) | ParamId::ToolRot(_) | ParamId::Point { .. }
        )
    });
    let frame = indices(&registered, |id| {
        matches!(
            id,
            ParamId::Base(_) | ParamId::Tool(_) | ParamId::ToolRot(_) | ParamId::Point { .. }
        )
    });
    let mut current = registered;
    for sel in [tool, frame] {
        let problem = CalibrationProblem::new(&current, sel, obs);
        let k = problem.unknowns();
        let (u, _, _) = run_lm(LeastSquares(&problem), vec![0.0; k], 100)?;
        current = problem.robot_at(&u);
    }
    Ok(current)
}

/// The compliance part of a problem: the start model, the joints to identify and what the
/// report says of how they were chosen.
struct ComplianceChoice {
    start: Compliance,
    joints: Vec<usize>,
    torque_per_kg: Vec<f64>,
    joints_source: String,
    payload_com_source: String,
}

fn choose_compliance(
    settings: &ComplianceSettings,
    robot: &Robot,
    obs: &Observations,
) -> Result<ComplianceChoice> {
    let loads = obs.distinct_loads();
    if loads.len() < 2 {
        return Err(IdentError::Compliance(format!(
            "needs points at two or more loads to separate joint deflection from geometry; these data hold {}",
            match loads.first() {
                Some(l) => format!("only {l} kg"),
                None => "none".into(),
            }
        )));
    }
    let (payload_com, payload_com_source) = match settings.payload_com {
        Some(c) => (c, "settings".to_string()),
        None => (
            robot.tool,
            "the measured point (tool), as no payload_com was given".to_string(),
        ),
    };
    let (default, torque_per_kg) =
        default_compliance_joints(robot, obs, &settings.gravity, &payload_com);
    let (joints, joints_source) = match &settings.joints {
        Some(j) => {
            if let Some(&bad) = j.iter().find(|&&j| j >= robot.dof()) {
                return Err(IdentError::Compliance(format!(
                    "joint {} does not exist: the robot has {} joints",
                    bad + 1,
                    robot.dof()
                )));
            }
            (j.clone(), "settings".to_string())
        }
        None => (
            default,
            format!(
                "default: the joints whose RMS payload torque is at least {:.0} % of the largest joint's",
                100.0 * TORQUE_SHARE
            ),
        ),
    };
    if joints.is_empty() {
        return Err(IdentError::Compliance(
            "no joint carries the payload's gravity torque in these data (check gravity)".into(),
        ));
    }
    Ok(ComplianceChoice {
        start: Compliance::new(vec![0.0; robot.dof()], settings.gravity, payload_com),
        joints,
        torque_per_kg,
        joints_source,
        payload_com_source,
    })
}

/// Warnings about the data and the fit: too few distinct poses for the parameters, an
/// ill-conditioned problem, a model that still misses the points by more than a calibration
/// should.
fn fit_warnings(
    obs: &Observations,
    parameters: usize,
    condition_number: f64,
    mean_after: f64,
) -> Vec<String> {
    let mut warnings = Vec::new();
    let distinct = |rows: &mut dyn Iterator<Item = usize>| {
        let mut d: Vec<&[f64]> = rows.map(|i| obs.joints(i)).collect();
        d.sort_by(|a, b| a.partial_cmp(b).unwrap_or(std::cmp::Ordering::Equal));
        d.dedup();
        d.len()
    };
    let configurations = distinct(&mut (0..obs.len()));
    // A 6-DoF probe's orientation adds three equations per configuration that has one.
    let equations = 3 * configurations + 3 * distinct(&mut obs.oriented().into_iter());
    if equations < parameters {
        warnings.push(format!(
            "only {configurations} distinct joint configurations ({equations} equations) for {parameters} parameters: most cannot be determined; measure more, and more varied, poses"
        ));
    }
    if condition_number > ILL_CONDITIONED {
        warnings.push(format!(
            "ill-conditioned: the scaled Jacobian's condition number is {:.1e}; the identified values are sensitive to noise (spread the poses over the joint ranges)",
            condition_number
        ));
    }
    if mean_after > POOR_FIT {
        warnings.push(format!(
            "the identified model still misses the measured points by {:.4} mm on average (more than {POOR_FIT} mm): the data and the robot file do not describe the same arm; check the units (mm, deg), the joint order and signs, the measured point (the robot file's tool point) and the tracker frame",
            mean_after
        ));
    }
    warnings
}

/// Standard deviations a far move must exceed to count as determined by the data.
pub const FAR_SIGMAS: f64 = 3.0;

/// Identified link lengths that moved more than [`FAR_FROM_NOMINAL`] mm and 10 % from the
/// robot file, by more than [`FAR_SIGMAS`] standard deviations: the data are in other units (a
/// table scaled with them fits exactly), or the robot file is not this arm's. A move within its
/// uncertainty says only that the poses barely determine the parameter
/// ([`poorly_determined`]). Base, tool and named points are frames whose nominal values are
/// guesses, so they are left out. `ids` are the table's parameters, in the order of
/// `parameters`.
pub fn far_from_nominal<'a>(
    parameters: &'a [ParameterReport],
    ids: &[ParamId],
) -> Vec<&'a ParameterReport> {
    far_moves(parameters, ids)
        .filter(|p| p.std.is_none_or(|s| p.delta.abs() > FAR_SIGMAS * s))
        .collect()
}

/// Identified link lengths that moved as far as [`far_from_nominal`] says, but within
/// [`FAR_SIGMAS`] standard deviations: the poses barely determine them.
pub fn poorly_determined<'a>(
    parameters: &'a [ParameterReport],
    ids: &[ParamId],
) -> Vec<&'a ParameterReport> {
    far_moves(parameters, ids)
        .filter(|p| p.std.is_some_and(|s| p.delta.abs() <= FAR_SIGMAS * s))
        .collect()
}

/// Identified link lengths (not frames) more than [`FAR_FROM_NOMINAL`] mm and 10 % from the
/// robot file.
fn far_moves<'a>(
    parameters: &'a [ParameterReport],
    ids: &[ParamId],
) -> impl Iterator<Item = &'a ParameterReport> {
    parameters
        .iter()
        .zip(ids)
        .filter(|(p, id)| {
            p.identified_flag
                && id.unit() == Unit::Mm
                && !matches!(
                    id,
                    ParamId::Base(_)
                        | ParamId::Tool(_)
                        | ParamId::ToolRot(_)
                        | ParamId::Point { .. }
                )
                && p.delta.abs() > FAR_FROM_NOMINAL.max(0.1 * p.nominal.abs())
        })
        .map(|(p, _)| p)
}

/// The compliance part of the report: each joint's identified compliance (deg per kN·m), σ,
/// payload torque and why it was held (rigid, or at a first fit's value).
fn compliance_report(
    choice: Option<&ComplianceChoice>,
    compliance: Option<&JointErrors>,
    obs: &Observations,
    kept: &[Column],
    fixed: &[FixedParameter],
    std_of: &dyn Fn(Column) -> Option<f64>,
) -> Option<ComplianceReport> {
    match (choice, compliance) {
        (Some(choice), Some(model)) => Some(ComplianceReport {
            gravity: model.gravity.into(),
            payload_com: model.payload_com.into(),
            payload_com_source: match (0..3)
                .filter(|&axis| kept.contains(&Column::PayloadCom(axis)))
                .count()
            {
                0 => choice.payload_com_source.clone(),
                n => format!(
                    "identified with the compliances ({n} of 3 coordinates; started from {})",
                    choice.payload_com_source
                ),
            },
            joints_source: choice.joints_source.clone(),
            loads: obs.distinct_loads(),
            joints: (0..model.values.len())
                .map(|j| {
                    let column = Column::Compliance(j);
                    let identified = kept.contains(&column);
                    let reason = if identified && model.values[j] < 0.0 {
                        "identified, NEGATIVE: no joint stiffens under load; the stage is absorbing an effect it does not model (backlash whose side the torque sets, a wrong payload_com, link deflection); consider leaving this joint out".to_string()
                    } else if identified {
                        "identified".to_string()
                    } else if let Some(f) = fixed.iter().find(|f| f.name == column.to_string()) {
                        // Rigid, or at the first fit's value when the gate held it in the fit
                        // that started there (its reason says which).
                        if model.values[j] == 0.0 {
                            format!("held rigid: {}", f.reason)
                        } else {
                            format!("held: {}", f.reason)
                        }
                    } else {
                        "held rigid: not selected".to_string()
                    };
                    JointCompliance {
                        joint: j + 1,
                        compliance: model.values[j] / DEG_PER_KNM,
                        std: std_of(column).map(|s| s / DEG_PER_KNM),
                        torque_per_kg: choice.torque_per_kg[j],
                        identified,
                        reason,
                    }
                })
                .collect(),
        }),
        _ => None,
    }
}

/// The joint-error terms besides the compliances in the report (harmonics, self-weight, backlash,
/// the links' weights, the payload's centre of mass): value in its unit, σ, whether identified.
fn joint_error_reports(
    model: &JointErrors,
    params: &[ErrorParam],
    kept: &[Column],
    std_of: &dyn Fn(Column) -> Option<f64>,
) -> Vec<ErrorTermReport> {
    params
        .iter()
        .filter(|p| !matches!(p, ErrorParam::Compliance(_)))
        .map(|&p| {
            let column = Column::of_error(model, p);
            ErrorTermReport {
                name: model.param_name(p),
                unit: match p {
                    ErrorParam::SelfWeight(_) => "deg per basis unit",
                    ErrorParam::LinkWeight(i) => model.link_weights[i].part.weight_unit(),
                    ErrorParam::PayloadCom(_) => "mm",
                    ErrorParam::Tilt(_) => "deg per kN·m",
                    _ => "deg",
                },
                value: in_file_unit(p, model.param(p)),
                std: std_of(column).map(|s| in_file_unit(p, s)),
                identified: kept.contains(&column),
            }
        })
        .collect()
}

/// A joint-error coefficient (internal units) in its report's: a link weight's kg or kg·m and
/// the payload's centre of mass's mm as they are, a tilting compliance in deg per kN·m, the rest
/// from radians to degrees.
fn in_file_unit(p: ErrorParam, value: f64) -> f64 {
    match p {
        ErrorParam::LinkWeight(_) | ErrorParam::PayloadCom(_) => value,
        ErrorParam::Tilt(_) => value / DEG_PER_KNM,
        _ => value.to_degrees(),
    }
}

/// The joint-error model identification starts from — the compliance choice's, with the
/// harmonics, self-weight and backlash terms `settings` ask for at zero, each harmonic reaching as far as
/// its joint's readings in `obs` allow ([`Harmonic::reach_of`]) — and its unknowns.
fn joint_error_start(
    settings: &KinematicSettings,
    aligned: &Robot,
    choice: Option<&ComplianceChoice>,
    obs: &Observations,
) -> Result<(Option<JointErrors>, Vec<ErrorParam>)> {
    let mut start: Option<JointErrors> = choice.map(|c| c.start.clone());
    let mut params: Vec<ErrorParam> = choice.map_or_else(Vec::new, |c| {
        c.joints
            .iter()
            .map(|&j| ErrorParam::Compliance(j))
            .collect()
    });
    if let Some(je) = &settings.joint_errors {
        let dof = aligned.dof();
        let mut model = start
            .take()
            .unwrap_or_else(|| JointErrors::new(vec![0.0; dof], je.gravity, aligned.tool));
        let first_harmonic = model.harmonics.len();
        let joints: Vec<usize> = je
            .harmonic_joints
            .clone()
            .unwrap_or_else(|| (0..dof).collect());
        if let Some(&bad) = joints.iter().find(|&&j| j >= dof) {
            return Err(IdentError::Compliance(format!(
                "harmonics: joint {} does not exist: the robot has {dof} joints",
                bad + 1
            )));
        }
        model = model.with_harmonics(&joints, je.harmonics);
        let ranges = obs.joint_ranges();
        for i in first_harmonic..model.harmonics.len() {
            let joint = model.harmonics[i].joint;
            model.harmonics[i].reach = (ranges.as_ref())
                .map(|r| r[joint])
                .map(|[lo, hi]| Harmonic::reach_of(lo, hi));
            params.push(ErrorParam::HarmonicSin(i));
            params.push(ErrorParam::HarmonicCos(i));
        }
        if je.self_weight {
            let first = model.self_weight.len();
            model = model.with_self_weight(&(0..dof).collect::<Vec<_>>(), dof);
            params.extend((first..model.self_weight.len()).map(ErrorParam::SelfWeight));
        }
        if je.link_weights {
            let first = model.link_weights.len();
            model = model.with_link_weights(&(0..dof).collect::<Vec<_>>());
            params.extend((first..model.link_weights.len()).map(ErrorParam::LinkWeight));
        }
        if je.backlash {
            let first = model.backlash.len();
            model = model.with_backlash(&(0..dof).collect::<Vec<_>>());
            if let Some(home) = &je.backlash_home {
                if home.len() != dof {
                    return Err(IdentError::Compliance(format!(
                        "backlash_home: {} readings for a robot with {dof} joints",
                        home.len()
                    )));
                }
                for b in &mut model.backlash[first..] {
                    b.flank = Flank::Approach {
                        home: home[b.joint],
                    };
                }
            }
            if let Some(flanks) = &je.flanks {
                for b in &mut model.backlash[first..] {
                    if let Some(f) = flanks.get(b.joint) {
                        b.flank = f.clone();
                    }
                }
            }
            params.extend((first..model.backlash.len()).map(ErrorParam::Backlash));
        }
        if je.tilt {
            let first = model.tilts.len();
            model = model.with_tilts(&(0..dof).collect::<Vec<_>>());
            params.extend((first..model.tilts.len()).map(ErrorParam::Tilt));
        }
        if je.runout > 0 {
            let first = model.runouts.len();
            model = model.with_runouts(&(0..dof).collect::<Vec<_>>(), je.runout);
            for i in first..model.runouts.len() {
                let joint = model.runouts[i].wave.joint;
                model.runouts[i].wave.reach = (ranges.as_ref())
                    .map(|r| r[joint])
                    .map(|[lo, hi]| Harmonic::reach_of(lo, hi));
                params.push(ErrorParam::RunoutSin(i));
                params.push(ErrorParam::RunoutCos(i));
            }
        }
        start = Some(model);
    }
    // The compliances a first fit found, and the payload's centre of mass, which moves nothing
    // at zero compliance.
    if let (Some(model), Some(c)) = (start.as_mut(), &settings.compliance) {
        if let Some(values) = &c.start {
            for &p in &params {
                if let ErrorParam::Compliance(j) = p {
                    model.values[j] = values[j];
                }
            }
        }
        if c.identify_payload_com {
            params.extend((0..3).map(ErrorParam::PayloadCom));
        }
        // The tilts start at a small share of the compliances, each joint without one at their
        // mean: at zero tilt the links' weights would tilt nothing, and the identifiability
        // analysis, made at the start, would hold a weight the geometry absorbs for the torsion
        // alone at zero.
        let positive: Vec<f64> = model.values.iter().copied().filter(|v| *v > 0.0).collect();
        if !positive.is_empty() && c.start.is_some() {
            let mean = positive.iter().sum::<f64>() / positive.len() as f64;
            for t in &mut model.tilts {
                let own = model.values[t.joint];
                t.value = TILT_START_SHARE * if own > 0.0 { own } else { mean };
            }
        }
    }
    Ok((start, params))
}

/// Solves `problem` from zero (the start the problem was built at); a transmission harmonic
/// identified beyond what a gear can have is not one (the term fits an effect it does not model,
/// or the poses barely determine it, and it would not extrapolate): it is held at zero (moved
/// from `kept` to `fixed`) and the rest solved again, from zero too — not from where the first
/// solve left them: with backlash flanks the cost has several minima, and the harmonic held at
/// zero pulls the rest toward one that extrapolates worse (started there, on the development
/// twins the held-out scores are the same, but two rows lower and four higher against the truth,
/// the joint-1 extrapolation 0.0286 → 0.0543 mm on the paper's arm and 0.0112 → 0.0144 on ARM7).
/// Returns the solution, the iterations (every solve's) and why the last solve
/// stopped.
fn solve_gated(
    problem: &mut CalibrationProblem<'_>,
    kept: &mut Vec<Column>,
    fixed: &mut Vec<FixedParameter>,
    settings: &KinematicSettings,
) -> Result<(Vec<f64>, u64, String)> {
    let mut iterations = 0;
    Ok(loop {
        let u0 = vec![0.0; problem.unknowns()];
        let mut solved = if kept.is_empty() {
            (u0, 0, "nothing to identify".to_string())
        } else {
            match settings.solver {
                SolverKind::Lm => run_lm_until(
                    LeastSquares(problem),
                    u0,
                    settings.max_iterations,
                    settings.deadline,
                    settings.work.as_ref(),
                )?,
                SolverKind::Bfgs => run_bfgs(problem, u0, settings.max_iterations)?,
            }
        };
        iterations += solved.1;
        solved.1 = iterations;
        let Some(model) = problem.compliance_at(&solved.0) else {
            break solved;
        };
        // A harmonic's amplitude, deg.
        let amplitude = |joint: usize, order: u32| {
            (model.harmonics.iter())
                .find(|h| h.joint == joint && h.order == order)
                .map_or(0.0, |h| h.sin.hypot(h.cos).to_degrees())
        };
        let too_large = |joint: usize, order: u32| amplitude(joint, order) > HARMONIC_BOUND_DEG;
        // A joint's backlash, half its play, deg.
        let half_play = |joint: usize| {
            (model.backlash.iter())
                .find(|b| b.joint == joint)
                .map_or(0.0, |b| b.value.abs().to_degrees())
        };
        // Why a joint's compliance is impossible, when the settings ask (deg per kN·m).
        let gate = settings
            .compliance
            .as_ref()
            .is_some_and(|c| c.plausible_only);
        // The harmonics' prior, on an LM fit that has none yet.
        let prior_wanted = !problem.has_prior()
            && settings.solver == SolverKind::Lm
            && (settings.joint_errors.as_ref()).is_some_and(|je| je.harmonic_prior);
        // The fit's residuals and standard deviations, once, for the gate and the prior. Where
        // the data's covariance is singular (at the fit, a backlash whose rows all rest on one
        // flank is its joint's offset), the prior's spread comes from the deviations under a
        // vanishing ridge ([`null_ridged_standard_deviations`]): a fit without a prior would
        // be compared by the flank rounds with fits under one.
        let has_backlash = kept.iter().any(|c| matches!(c, Column::Backlash(_)));
        let fitted = (gate || prior_wanted || has_backlash).then(|| {
            let (r, jac) = problem.residuals_and_jacobian(&solved.0);
            let std = standard_deviations(&jac, &r);
            let for_prior = if prior_wanted && std.is_none() {
                null_ridged_standard_deviations(&jac, &r)
            } else {
                std.clone()
            };
            (r, std, for_prior)
        });
        let std_u = fitted
            .as_ref()
            .filter(|_| gate)
            .and_then(|(_, std, _)| std.as_ref());
        let implausible = |p: usize| -> Option<String> {
            let value = match kept[p] {
                Column::Compliance(j) => model.values[j],
                Column::Tilt(j) => (model.tilts.iter())
                    .find(|t| t.joint == j)
                    .map_or(0.0, |t| t.value),
                _ => return None,
            };
            if !gate {
                return None;
            }
            let value = value / DEG_PER_KNM;
            let std = std_u
                .as_ref()
                .map(|s| (s[p] * problem.scale()[p] / DEG_PER_KNM).abs());
            if value < 0.0 {
                Some(format!(
                    "came out negative ({value:.4} deg/kN·m): no joint stiffens under load"
                ))
            } else if value > COMPLIANCE_BOUND {
                Some(format!(
                    "came out at {value:.4} deg/kN·m, beyond the {COMPLIANCE_BOUND} deg/kN·m the default accepts"
                ))
            } else {
                std.filter(|s| *s >= value).map(|s| {
                    format!(
                        "came out at {value:.4} ± {s:.4} deg/kN·m: no larger than its own uncertainty"
                    )
                })
            }
        };
        // A backlash whose rows all rest on one flank at the fit is its joint's offset there (a
        // torque flank's boundary turns with the identified geometry, so the analysis at the
        // start, which saw both flanks, cannot tell): its split with the offset is left where
        // the solver's path put it, and a pose on the other flank, which the data never showed,
        // would move by twice that. The flank (`±1`) all rows rest on, where they do; looked
        // for only where the data's covariance is singular, which such a term makes it.
        let singular = fitted.as_ref().is_some_and(|(_, std, _)| std.is_none());
        let one_flank: Vec<(usize, f64)> = if singular && has_backlash {
            let robot = problem.robot_at(&solved.0);
            let obs = problem.observations();
            kept.iter()
                .filter_map(|c| match c {
                    Column::Backlash(j) => model.backlash.iter().find(|b| b.joint == *j),
                    _ => None,
                })
                .filter_map(|b| {
                    let mut sides =
                        (0..obs.len()).map(|i| model.flank(b, &robot, obs.joints(i), obs.loads[i]));
                    let first = sides.next()?;
                    sides.all(|s| s == first).then_some((b.joint, first))
                })
                .collect()
        } else {
            Vec::new()
        };
        let flank_of = |joint: usize| one_flank.iter().find(|(j, _)| *j == joint).map(|f| f.1);
        // A coordinate of the payload's centre of mass beyond where a payload can hang.
        let com_too_far = |axis: usize| {
            let c = model.payload_com[axis];
            !c.is_finite() || c.abs() > PAYLOAD_COM_BOUND
        };
        let (keep, drop): (Vec<usize>, Vec<usize>) = (0..kept.len()).partition(|&p| {
            !matches!(kept[p], Column::Harmonic { joint, order, .. } if too_large(joint, order))
                && !matches!(kept[p], Column::Backlash(j) if half_play(j) > BACKLASH_BOUND_DEG)
                && !matches!(kept[p], Column::Backlash(j) if flank_of(j).is_some())
                && !matches!(kept[p], Column::PayloadCom(axis) if com_too_far(axis))
                && implausible(p).is_none()
        });
        if drop.is_empty() {
            // The harmonics' prior, once the gate holds none of them: its spread comes from the
            // plausible ones (a term beyond a gear's bound is no gear's), and every coefficient
            // is solved again under it from zero, like any other re-solve.
            if let Some((r, _, Some(std))) = fitted.as_ref().filter(|_| prior_wanted)
                && let Some((prior, spread)) = harmonic_prior(problem, &model, r, std)
            {
                problem.set_prior(prior, spread);
                continue;
            }
            break solved;
        }
        for &p in &drop {
            let reason = match kept[p] {
                Column::Harmonic { joint, order, .. } => format!(
                    "held at zero: its harmonic came out at {:.3}° amplitude, beyond the {HARMONIC_BOUND_DEG}° a gear's transmission error can have (an effect it does not model, such as backlash, or poses that barely determine it)",
                    amplitude(joint, order)
                ),
                Column::Backlash(j) => {
                    match flank_of(j).filter(|_| half_play(j) <= BACKLASH_BOUND_DEG) {
                        Some(side) => format!(
                            "held at zero: at the fit every row rests on its {} flank, where it is its joint's offset (its flank's boundary turned with the identified geometry): the data cannot tell its play",
                            if side > 0.0 { "+" } else { "−" }
                        ),
                        None => format!(
                            "held at zero: its backlash came out at {:.3}° half play, beyond the {BACKLASH_BOUND_DEG}° a reducer's can have (an effect it does not model, or poses that barely move the point with the joint)",
                            half_play(j)
                        ),
                    }
                }
                Column::PayloadCom(axis) => format!(
                    "held at its start: it came out at {:.0} mm, beyond the {PAYLOAD_COM_BOUND} mm from the flange a payload's centre of mass can lie (an effect it does not model, or loads that barely determine it)",
                    model.payload_com[axis]
                ),
                Column::Tilt(_) => format!(
                    "implausible: its tilting compliance {}; held rigid",
                    implausible(p).unwrap_or_default()
                ),
                Column::Compliance(j) => format!(
                    "implausible: its compliance {}; the stage was absorbing an effect it does not model (backlash whose side the torque sets, a wrong payload_com, link deflection), {}",
                    implausible(p).unwrap_or_default(),
                    held_compliance(problem, j)
                ),
                _ => format!(
                    "implausible: {}; held at its start",
                    implausible(p).unwrap_or_default()
                ),
            };
            fixed.push(FixedParameter {
                name: kept[p].to_string(),
                independent_fraction: 1.0,
                reason,
            });
        }
        *problem = problem.restricted(&keep);
        *kept = keep.iter().map(|&p| kept[p]).collect();
    })
}

/// Where a compliance the gate holds stays, in words: rigid where the problem starts it at zero,
/// else at the value it starts from (the first fit's, without the links' weights, the payload's
/// centre of mass and backlash, which a restricted problem keeps).
fn held_compliance(problem: &CalibrationProblem<'_>, joint: usize) -> String {
    let start =
        (problem.compliance_at(&vec![0.0; problem.unknowns()])).map_or(0.0, |m| m.values[joint]);
    if start == 0.0 {
        "held rigid".to_string()
    } else {
        format!(
            "held at {:.4} deg/kN·m, the value the first fit (without the links' weights, the payload's centre of mass and backlash) found",
            start / DEG_PER_KNM
        )
    }
}

/// Zero-mean Gaussian priors on the transmission harmonics' coefficients (empirical Bayes), their
/// variance `τ²` by marginal likelihood over the coefficients of the fit without them at `u`
/// (each estimate `â ~ N(0, τ² + s²)`, `s` its standard error; [`prior_spread`]): a coefficient
/// the poses determine well keeps its value, one they barely determine (a harmonic of a joint
/// seen over a narrow window, trading with the geometry) is drawn toward the spread of the rest
/// instead of growing to whatever fits. Each prior's row weight is the fit's residual σ over
/// `τ`. The axis runouts' coefficients, waves of the joint angles too, get a prior of their own
/// the same way (their own `τ`: a turn across an axis is not a gear's error). `model`, `r` and
/// `std` are the fit's joint errors, residuals and unknowns' standard deviations. Returns the
/// priors and each group's `τ` (rad; none for a group without two coefficients); none where
/// neither group has two.
fn harmonic_prior(
    problem: &CalibrationProblem<'_>,
    model: &Compliance,
    r: &[f64],
    std: &[f64],
) -> Option<(Priors, PriorSpreads)> {
    let ng = problem.selected().len();
    let params = problem.error_params().to_vec();
    let dof = (r.len().checked_sub(problem.unknowns())).filter(|&d| d > 0)?;
    let sigma = (r.iter().map(|v| v * v).sum::<f64>() / dof as f64).sqrt();
    // One group's priors and spread, `None` with fewer than two coefficients.
    let group = |member: fn(&ErrorParam) -> bool| {
        let members: Vec<usize> = (0..params.len()).filter(|&k| member(&params[k])).collect();
        if members.len() < 2 {
            return None;
        }
        let est: Vec<(f64, f64)> = (members.iter())
            .map(|&k| {
                let s = std[ng + k] * problem.scale()[ng + k];
                (model.param(params[k]), s * s)
            })
            .collect();
        let tau = prior_spread(&est).max(HARMONIC_PRIOR_FLOOR);
        let prior: Priors = members.iter().map(|&k| (params[k], sigma / tau)).collect();
        Some((prior, tau))
    };
    let harmonics = group(|p| matches!(p, ErrorParam::HarmonicSin(_) | ErrorParam::HarmonicCos(_)));
    let runouts = group(|p| matches!(p, ErrorParam::RunoutSin(_) | ErrorParam::RunoutCos(_)));
    if harmonics.is_none() && runouts.is_none() {
        return None;
    }
    let spread = PriorSpreads {
        harmonics: harmonics.as_ref().map(|(_, tau)| *tau),
        runouts: runouts.as_ref().map(|(_, tau)| *tau),
    };
    let prior = (harmonics.into_iter().chain(runouts))
        .flat_map(|(p, _)| p)
        .collect();
    Some((prior, spread))
}

/// Priors on joint-error coefficients: each with its row weight.
type Priors = Vec<(ErrorParam, f64)>;

/// The spread `τ` that maximises the marginal likelihood of estimates `â_j ~ N(0, τ² + s_j²)`,
/// given as `(â_j, s_j²)`: `L(τ) = −½ Σ ln(τ² + s_j²) + â_j² / (τ² + s_j²)`, searched over
/// `τ = 0` and a logarithmic grid up to twice the largest `|â_j|` (8 points per factor of two,
/// down to 10⁻⁹ of it), the best point's bracket refined by bisection on the sign of `dL/dτ`.
/// `L` can have a maximum at zero and one inside, or rise, fall and rise again where a few
/// estimates are far less certain than the rest; the fixed-point iteration of `Σ w_j² (â_j² − s_j² − τ²) = 0`
/// (`w_j = 1/(τ² + s_j²)`) started from the estimates' mean square, where the uncertain ones make
/// the right side negative, jumps to zero and stops there (ARM5's joint-1 extrapolation split:
/// five of its first ten fits held at the floor, 0.001°, where the maximum lies near 0.005°).
pub fn prior_spread(estimates: &[(f64, f64)]) -> f64 {
    let log_likelihood = |tau: f64| -> f64 {
        let t2 = tau * tau;
        -0.5 * (estimates.iter())
            .map(|(a, s2)| {
                let v = t2 + s2;
                if v > 0.0 {
                    v.ln() + a * a / v
                } else if *a == 0.0 {
                    f64::NEG_INFINITY
                } else {
                    f64::INFINITY
                }
            })
            .sum::<f64>()
    };
    let top = 2.0 * estimates.iter().fold(0.0f64, |m, (a, _)| m.max(a.abs()));
    if !(top.is_finite() && top > 0.0) {
        return 0.0;
    }
    // τ = 0, then the grid from 10⁻⁹ of the top upward; a tie keeps the smaller spread.
    const PER_OCTAVE: usize = 8;
    const OCTAVES: usize = 30;
    let grid: Vec<f64> = std::iter::once(0.0)
        .chain(
            (0..=PER_OCTAVE * OCTAVES)
                .map(|i| top * (2f64).powf(i as f64 / PER_OCTAVE as f64 - OCTAVES as f64)),
        )
        .collect();
    let values: Vec<f64> = grid.iter().map(|&t| log_likelihood(t)).collect();
    let best = (0..grid.len()).fold(0, |b, i| if values[i] > values[b] { i } else { b });
    if best == 0 {
        return 0.0;
    }
    // Between the best point's neighbours, the root of `dL/dτ = τ h(τ)`,
    // `h(τ) = Σ (â_j² − s_j² − τ²) / (τ² + s_j²)²`, by bisection (its sign is exact where `L`'s
    // differences are round-off).
    let h = |tau: f64| -> f64 {
        let t2 = tau * tau;
        (estimates.iter())
            .map(|(a, s2)| (a * a - s2 - t2) / ((t2 + s2) * (t2 + s2)))
            .sum::<f64>()
    };
    let (mut lo, mut hi) = (
        grid[best.saturating_sub(1)],
        grid[(best + 1).min(grid.len() - 1)],
    );
    if !(h(lo) > 0.0 && h(hi) < 0.0) {
        return grid[best];
    }
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if mid <= lo || mid >= hi {
            break;
        }
        if h(mid) > 0.0 {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    let tau = 0.5 * (lo + hi);
    if log_likelihood(tau) >= values[best] {
        tau
    } else {
        grid[best]
    }
}

/// The smallest spread of the harmonics' prior, rad (a thousandth of a degree, 17 µm a metre
/// out): where the harmonics spread no more than their own errors the prior holds them near
/// zero, not at it.
const HARMONIC_PRIOR_FLOOR: f64 = 1e-3 * std::f64::consts::PI / 180.0;

/// The parameters `ident` identifies that the rows of the default reflector alone (`jac`'s rows
/// of observations without a target) would not: what the extra reflectors buy. Empty when no
/// row names a target.
fn by_reflectors(
    obs: &Observations,
    jac: &Mat<f64>,
    columns: &[Column],
    ident: &Identifiability,
    settings: &KinematicSettings,
) -> Vec<String> {
    if obs.targets.iter().all(String::is_empty) {
        return Vec::new();
    }
    let rows: Vec<usize> = (0..obs.len())
        .filter(|&i| obs.targets[i].is_empty())
        .flat_map(|i| 3 * i..3 * i + 3)
        .collect();
    let alone = Mat::from_fn(rows.len(), jac.ncols(), |r, c| jac[(rows[r], c)]);
    let alone = analyse(&alone, columns, settings.rank_tolerance);
    (ident.identifiable.iter())
        .filter(|p| !alone.identifiable.contains(p))
        .filter(|&&p| !matches!(columns[p], Column::Param(ParamId::Point { .. })))
        .map(|&p| columns[p].to_string())
        .collect()
}

/// Identifies the kinematic parameters of `nominal` from `obs` (and, when the settings ask for
/// it, the joint compliances with them: then the points of every load take part).
///
/// Tilting compliances multiply the links' weights and the payload's centre of mass, which may
/// take either sign: LM can end in a minimum worse than the same model without them (measured
/// on the paper's twin beyond the model family: 0.216 against 0.075 mm on the fitted rows, the
/// tilts far from the twin's and some negative). With tilts asked for, the model without them
/// is fitted too, and the one that fits the rows better (RMS) is kept.
pub fn calibrate_kinematics(
    nominal: &Robot,
    obs: &Observations,
    settings: &KinematicSettings,
) -> Result<KinematicCalibration> {
    calibrate_kinematics_with(nominal, obs, settings, &FitMemo::default())
}

/// [`calibrate_kinematics`], remembering in `memo` every alignment and identification it makes
/// and taking any `memo` already holds: callers that identify several models of the same rows
/// (the default calibration's candidates on one fold) share their common fits — the first fit
/// of a model with the links' weights is the fit of the same model without them, and every
/// model starts from the same alignment. The results are those of [`calibrate_kinematics`],
/// bit for bit (each identification is a function of its table, rows and settings).
pub fn calibrate_kinematics_with(
    nominal: &Robot,
    obs: &Observations,
    settings: &KinematicSettings,
    memo: &FitMemo,
) -> Result<KinematicCalibration> {
    let Some(je) = settings.joint_errors.as_ref().filter(|je| je.tilt) else {
        return identify(nominal, obs, settings, memo);
    };
    let mut upright = settings.clone();
    upright.joint_errors = Some(JointErrorSettings {
        tilt: false,
        ..je.clone()
    });
    if upright
        .joint_errors
        .as_ref()
        .is_some_and(|je| je.harmonics == 0 && !je.self_weight && !je.link_weights && !je.backlash)
    {
        upright.joint_errors = None;
    }
    let without = identify(nominal, obs, &upright, memo)?;
    Ok(match identify(nominal, obs, settings, memo) {
        Ok(with) if with.report.after.rms <= without.report.after.rms => with,
        _ => without,
    })
}

/// Alignments ([`align`]) and identifications already made, each with the table, rows and
/// settings it was made from ([`calibrate_kinematics_with`]): one calibration's identifications
/// (the first fit of the links' weights, the backlash flank rounds, the comparison of the tilts)
/// and the default calibration's candidates on one fold share them. Only what succeeded is
/// kept; each set of rows is kept once. Safe to share between threads (the lock is held for a
/// lookup or an insertion, never while fitting).
#[derive(Default)]
pub struct FitMemo(std::sync::Mutex<MemoEntries>);

/// What a [`FitMemo`] holds.
#[derive(Default)]
struct MemoEntries {
    /// Every set of rows an entry was made from.
    rows: Vec<Observations>,
    /// Alignments: the table, its rows (index into `rows`) and the aligned table.
    aligned: Vec<(Robot, usize, Robot)>,
    /// Identifications: the table, its rows, the settings and the result.
    fits: Vec<(Robot, usize, KinematicSettings, KinematicCalibration)>,
}

impl MemoEntries {
    /// The index of `obs` in `rows`, if held.
    fn rows_of(&self, obs: &Observations) -> Option<usize> {
        self.rows.iter().position(|o| o == obs)
    }

    /// The index of `obs` in `rows`, added if not held.
    fn keep_rows(&mut self, obs: &Observations) -> usize {
        self.rows_of(obs).unwrap_or_else(|| {
            self.rows.push(obs.clone());
            self.rows.len() - 1
        })
    }
}

impl FitMemo {
    /// Its entries, locked (a panic elsewhere while it was held leaves them usable: every
    /// entry is pushed whole).
    fn entries(&self) -> std::sync::MutexGuard<'_, MemoEntries> {
        self.0.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// [`align`]`(robot, obs)`, remembered.
    fn align(&self, robot: &Robot, obs: &Observations) -> Result<Robot> {
        {
            let e = self.entries();
            if let Some(k) = e.rows_of(obs)
                && let Some((_, _, aligned)) =
                    (e.aligned.iter()).find(|(r, o, _)| *o == k && r == robot)
            {
                return Ok(aligned.clone());
            }
        }
        let aligned = align(robot, obs)?;
        let mut e = self.entries();
        let k = e.keep_rows(obs);
        e.aligned.push((robot.clone(), k, aligned.clone()));
        Ok(aligned)
    }

    /// The identification of `nominal` from `obs` with `settings`, if remembered.
    fn fit(
        &self,
        nominal: &Robot,
        obs: &Observations,
        settings: &KinematicSettings,
    ) -> Option<KinematicCalibration> {
        let settings = undated(settings);
        let e = self.entries();
        let k = e.rows_of(obs)?;
        (e.fits.iter())
            .find(|(r, o, s, _)| *o == k && *s == settings && r == nominal)
            .map(|(_, _, _, fit)| fit.clone())
    }

    /// Remembers `fit`, the identification of `nominal` from `obs` with `settings`.
    fn remember(
        &self,
        nominal: &Robot,
        obs: &Observations,
        settings: &KinematicSettings,
        fit: &KinematicCalibration,
    ) {
        let mut e = self.entries();
        let k = e.keep_rows(obs);
        (e.fits).push((nominal.clone(), k, undated(settings), fit.clone()));
    }

    /// How many identifications it remembers.
    pub fn fits(&self) -> usize {
        self.entries().fits.len()
    }
}

/// `settings` as a [`FitMemo`] tells identifications apart: without their deadline and work count (a fit that
/// ended is the same whatever time it had to end by, so the candidates' folds, each with its own
/// deadline, share it), and without the flank search where no flank is chosen (no backlash, the
/// approach flanks alone, or the flanks given): the search candidate's folds share the fits its
/// rounds start from — the first fit without the links' weights and the fit on the approach
/// flanks — with the candidate without the search.
fn undated(settings: &KinematicSettings) -> KinematicSettings {
    let mut key = KinematicSettings {
        deadline: None,
        work: None,
        ..settings.clone()
    };
    if let Some(je) = key.joint_errors.as_mut()
        && (!je.backlash || !je.backlash_torque || je.flanks.is_some())
    {
        je.flank_search = false;
    }
    key
}

/// [`identify_anew`], or the identification `memo` remembers for the same table, rows and
/// settings.
fn identify(
    nominal: &Robot,
    obs: &Observations,
    settings: &KinematicSettings,
    memo: &FitMemo,
) -> Result<KinematicCalibration> {
    if let Some(fit) = memo.fit(nominal, obs, settings) {
        return Ok(fit);
    }
    let fit = identify_anew(nominal, obs, settings, memo)?;
    memo.remember(nominal, obs, settings, &fit);
    Ok(fit)
}

/// [`calibrate_kinematics`] without its comparison of the tilts: the identification itself
/// (the identifications it starts from taken from `memo` where it holds them).
fn identify_anew(
    nominal: &Robot,
    obs: &Observations,
    settings: &KinematicSettings,
    memo: &FitMemo,
) -> Result<KinematicCalibration> {
    if obs.dof != nominal.dof() {
        return Err(IdentError::JointCountMismatch {
            expected: nominal.dof(),
            found: obs.dof,
        });
    }
    // A 6-DoF probe's rows weigh as the settings say; its tool frame is identified (from the
    // flange's when the table declares none).
    let weighted;
    let obs = if obs.oriented().is_empty() {
        obs
    } else {
        let mut o = obs.clone();
        o.angle_weight = settings.angle_weight_per_rad();
        weighted = o;
        &weighted
    };
    let probe;
    let nominal = if obs.oriented().is_empty() || nominal.tool_rpy.is_some() {
        nominal
    } else {
        probe = Robot {
            tool_rpy: Some(Vector3::zeros()),
            ..nominal.clone()
        };
        &probe
    };
    // An arm hung on a wall or a ceiling: gravity is not along its base's −z. With a levelled
    // tracker it is along the tracker's; the data tell which of the two fits.
    if let Some(c) = &settings.compliance
        && c.detect_mounting
    {
        let mut given = settings.clone();
        let gc = given.compliance.as_mut().expect("compliance");
        gc.detect_mounting = false;
        // Gravity along the tracker's −z in the base frame of `robot`.
        let down_of = |robot: &Robot| {
            robot.base_rotation().transpose() * Vector3::new(0.0, 0.0, -c.gravity.norm())
        };
        // The settings with gravity `g` for the compliances and the joint errors alike.
        let with_gravity = |mut s: KinematicSettings, g: Vector3<f64>| {
            s.compliance.as_mut().expect("compliance").gravity = g;
            if let Some(je) = s.joint_errors.as_mut() {
                je.gravity = g;
            }
            s
        };
        // The alignment every identification below starts from, made once.
        let (down, angle) = down_of_aligned(&memo.align(nominal, obs)?, &c.gravity);
        if angle <= MOUNTING_ANGLE_DEG {
            return identify(nominal, obs, &given, memo);
        }
        let upright = identify(nominal, obs, &given, memo);
        // The registration's base is a first guess of the base's rotation: once more with the
        // identified one.
        let tracker =
            identify(nominal, obs, &with_gravity(given.clone(), down), memo).and_then(|fit| {
                let levelled = with_gravity(given.clone(), down_of(&fit.robot));
                identify(nominal, obs, &levelled, memo)
            });
        return match (upright, tracker) {
            (Ok(u), Ok(mut t)) if t.report.after.rms < u.report.after.rms => {
                let g = t.compliance.as_ref().map_or(down, |c| c.gravity);
                t.report.warnings.push(format!(
                    "gravity taken along the tracker's -z, [{:.3}, {:.3}, {:.3}] m/s² in the robot base frame: the registered base is {angle:.0}° from upright (an arm on a wall or a ceiling), and the fit with gravity along the base's -z was worse (RMS {:.4} against {:.4} mm); give gravity in a stage config's [compliance] if neither is right",
                    g.x,
                    g.y,
                    g.z,
                    u.report.after.rms,
                    t.report.after.rms
                ));
                Ok(t)
            }
            (Ok(u), _) => Ok(u),
            (Err(_), Ok(t)) => Ok(t),
            (Err(e), Err(_)) => Err(e),
        };
    }
    // The links' weights and the payload's centre of mass act through the joints' compliances:
    // a first identification without them (nor backlash, whose flanks are chosen below with the
    // whole model) gives the compliances the one with them starts from (at zero compliance they
    // move nothing, and the identifiability analysis would hold them at zero).
    let link_weights = (settings.joint_errors.as_ref()).is_some_and(|je| je.link_weights);
    if link_weights && settings.compliance.is_none() {
        return Err(IdentError::Compliance(
            "link weights act through the joint compliances: identify the compliances too".into(),
        ));
    }
    if let Some(first) = settings.first_fit() {
        let fit = identify(nominal, obs, &first, memo)?;
        let Some(values) = fit.compliance.as_ref().map(|c| c.values.clone()) else {
            return Ok(fit);
        };
        let mut next = settings.clone();
        next.compliance.as_mut().expect("compliance").start = Some(values);
        return identify(nominal, obs, &next, memo);
    }
    // Backlash that may rest on the flank its torque presses: a first identification on the
    // flanks of the approach from home, each joint's flank chosen from what it leaves, then the
    // identification on those flanks; the choice made again from that fit (a flank chosen from
    // a fit that lacked it is blurred where the first fit absorbed the step), until the rows'
    // flanks stay as they were or FLANK_ROUNDS (SEARCH_FLANK_ROUNDS with the search) choices
    // have been made.
    if let Some(je) = &settings.joint_errors
        && je.backlash
        && je.backlash_torque
        && je.flanks.is_none()
    {
        let mut round = settings.clone();
        let start = round.joint_errors.as_mut().expect("joint errors");
        start.backlash_torque = false;
        let home = (start.backlash_home.clone()).unwrap_or_else(|| vec![0.0; nominal.dof()]);
        // With axis runouts, the rounds start from the flanks chosen on the model without them
        // (that model's own rounds had the fit on the approach flanks competing): a runout can
        // take part of a step on a fit that lacks it, and the choice made from what that fit
        // leaves goes wrong (the paper's arm beyond the model); the rounds then choose again
        // with the runouts in the model, and the lowest sum of squares of their fits is kept.
        // No fit on the approach flanks with the runouts: it would be the dearest identification
        // of the candidate (a third to two fifths of its time on the paper's arm, hundreds of
        // iterations from zero), and its sum of squares was never the lowest on the cases
        // traced.
        let chosen_flanks = if je.runout > 0 {
            let mut plain = settings.clone();
            let je_plain = plain.joint_errors.as_mut().expect("joint errors");
            je_plain.runout = 0;
            je_plain.runout_from_without = false;
            let chosen = identify(nominal, obs, &plain, memo)?;
            chosen.compliance.as_ref().map(|errors| {
                let mut flanks: Vec<Flank> = (home.iter())
                    .map(|&h| Flank::Approach { home: h })
                    .collect();
                for b in &errors.backlash {
                    flanks[b.joint] = b.flank.clone();
                }
                flanks
            })
        } else {
            None
        };
        if let Some(flanks) = chosen_flanks {
            round.joint_errors.as_mut().expect("joint errors").flanks = Some(flanks);
        }
        let mut fit = identify(nominal, obs, &round, memo)?;
        // Without runouts, the fit on the approach flanks competes too: flanks chosen from a fit
        // that lacked them can leave more than it did (a joint's flank chosen nearly constant,
        // its step then absorbed by its offset and bent into its harmonics).
        let mut best = fit.clone();
        // The identification on `flanks`, kept as the best when its sum of squares (the
        // identification's own objective) is the lowest yet (of equal ones, the later).
        let mut on_flanks = |flanks: Vec<Flank>, best: &mut KinematicCalibration| {
            round.joint_errors.as_mut().expect("joint errors").flanks = Some(flanks);
            let next = identify(nominal, obs, &round, memo)?;
            if next.report.after.rms <= best.report.after.rms {
                *best = next.clone();
            }
            Ok::<_, IdentError>(next)
        };
        let mut signs: Option<Vec<f64>> = None;
        let rounds = if je.flank_search {
            SEARCH_FLANK_ROUNDS
        } else {
            FLANK_ROUNDS
        };
        for _ in 0..rounds {
            let Some(errors) = fit.compliance.as_ref() else {
                break;
            };
            let flanks =
                crate::flank::choose_flanks(&fit.robot, errors, obs, &home, je.flank_search);
            if signs.is_none() && flanks.iter().all(|f| matches!(f, Flank::Approach { .. })) {
                break;
            }
            fit = on_flanks(flanks, &mut best)?;
            let now =
                (fit.compliance.as_ref()).map(|e| crate::flank::flank_signs(&fit.robot, e, obs));
            let settled = now.is_some() && now == signs;
            signs = now;
            if settled {
                break;
            }
        }
        return Ok(best);
    }
    let selected = select(nominal, settings.parameters.as_deref())?;
    if 3 * obs.len() < selected.len().min(9) || obs.len() < 3 {
        return Err(IdentError::TooFewMeasurements {
            points: obs.len(),
            equations: 3 * obs.len(),
            parameters: selected.len(),
        });
    }
    let aligned = memo.align(nominal, obs)?;
    let before = ErrorStats::from_errors(&obs.errors(&aligned));
    let choice = settings
        .compliance
        .as_ref()
        .map(|c| choose_compliance(c, &aligned, obs))
        .transpose()?;

    // Identifiability at the aligned model (the neighbourhood of the solution).
    let ids = aligned.param_ids();
    let mut problem = CalibrationProblem::new(&aligned, selected.clone(), obs);
    let mut columns: Vec<Column> = selected.iter().map(|&i| ids[i].into()).collect();
    let (start, params) = joint_error_start(settings, &aligned, choice.as_ref(), obs)?;
    if let Some(model) = &start {
        columns.extend(params.iter().map(|&p| Column::of_error(model, p)));
        problem = problem.with_joint_errors(model.clone(), params.clone());
    }
    let jac = problem.first_order_jacobian(&vec![0.0; problem.unknowns()]);
    let ident = analyse(&jac, &columns, settings.rank_tolerance);
    let identified_by_reflectors = by_reflectors(obs, &jac, &columns, &ident, settings);
    let mut problem = problem.restricted(&ident.identifiable);
    let mut kept: Vec<Column> = ident.identifiable.iter().map(|&p| columns[p]).collect();
    let mut fixed: Vec<FixedParameter> = ident
        .unidentifiable
        .iter()
        .map(|&(p, fraction)| FixedParameter {
            name: columns[p].to_string(),
            independent_fraction: fraction,
            reason: if fraction == 0.0 {
                "no effect on the measured points with these poses".into()
            } else {
                "redundant with the identified parameters for these poses".into()
            },
        })
        .collect();

    let (mut u, mut iterations, mut termination) =
        solve_gated(&mut problem, &mut kept, &mut fixed, settings)?;
    if settings.loss == Loss::Huber {
        let mut previous: Option<Vec<f64>> = None;
        for _ in 0..IRLS_ROUNDS {
            let errors = problem.point_errors(&u);
            let components: Vec<f64> = errors.iter().flat_map(|e| [e.x, e.y, e.z]).collect();
            let corner = HUBER_K * robust_std(&components);
            if corner <= 0.0 {
                break;
            }
            let weights: Vec<f64> = (errors.iter())
                .map(|e| (corner / e.norm()).min(1.0))
                .collect();
            if previous
                .as_ref()
                .is_some_and(|p| p.iter().zip(&weights).all(|(a, b)| (a - b).abs() < 1e-3))
            {
                break;
            }
            problem.set_point_weights(&weights);
            let solved = solve_gated(&mut problem, &mut kept, &mut fixed, settings)?;
            (u, iterations, termination) = (solved.0, iterations + solved.1, solved.2);
            previous = Some(weights);
        }
    }
    let robot = problem.robot_at(&u);
    let compliance = problem.compliance_at(&u);
    let finite = robot.params().iter().all(|v| v.is_finite())
        && compliance
            .as_ref()
            .is_none_or(|c| c.params().iter().all(|&p| c.param(p).is_finite()));
    if !finite {
        return Err(IdentError::Solver {
            solver: settings.solver.name(),
            message: "the identification diverged to non-finite values (check the data's units and the robot table)".into(),
        });
    }
    let after = ErrorStats::from_errors(&obs.errors_with(&robot, compliance.as_ref()));
    let degrees = |errors: Vec<f64>| {
        ErrorStats::from_errors(&errors.iter().map(|e| e.to_degrees()).collect::<Vec<_>>())
    };
    let orientation = (!obs.oriented().is_empty()).then(|| OrientationReport {
        rows: obs.oriented().len(),
        angle_weight: obs.angle_weight.to_radians(),
        before: degrees(obs.orientation_errors_with(&aligned, None)),
        after: degrees(obs.orientation_errors_with(&robot, compliance.as_ref())),
    });
    let mut warnings = fit_warnings(obs, selected.len(), ident.condition_number, after.mean);
    // A negative tilting compliance is no bearing's: the tilts traded with the links' weights
    // (whose sign is free) or took an effect the model lacks.
    let negative: Vec<String> = (compliance.iter())
        .flat_map(|c| c.tilts.iter())
        .filter(|t| t.value < 0.0)
        .map(|t| format!("j{}", t.joint + 1))
        .collect();
    if !negative.is_empty() {
        warnings.push(format!(
            "tilting compliance NEGATIVE on {}: no bearing stiffens under a moment; the tilts traded with the links' weights or took an effect the model does not hold; consider leaving tilt out",
            negative.join(", ")
        ));
    }
    // Under the harmonics' prior, the posterior's: a coefficient the poses barely determine is
    // as sure as the prior makes it, not as unsure as the data alone leave it.
    let cov_u = problem.covariance(&u);
    let std_u = cov_u.as_ref().and_then(deviations_of);
    // The same covariance in internal units, by the parameters' names: what a predicted
    // point's standard deviation is made of.
    let covariance = std_u.as_ref().and(cov_u.as_ref()).map(|c| {
        let scale = problem.scale();
        let names = kept.iter().map(Column::to_string).collect();
        let m = nalgebra::DMatrix::from_fn(c.nrows(), c.ncols(), |i, j| {
            c[(i, j)] * scale[i] * scale[j]
        });
        ParameterCovariance::new(names, &m)
    });
    // What is written must read back: a fit so ill-conditioned that round-off leaves a negative
    // variance keeps no covariance (and its points no deviation).
    let covariance = covariance.filter(|c| c.check().is_ok());
    // Standard deviation of the unknown for `column`, internal units.
    let std_of = |column: Column| {
        let p = kept.iter().position(|&k| k == column)?;
        std_u.as_ref().map(|s| (s[p] * problem.scale()[p]).abs())
    };

    let nominal_values = nominal.params();
    let identified_values = robot.params();
    let parameters: Vec<ParameterReport> = ids
        .iter()
        .enumerate()
        .map(|(i, id)| {
            let flag = kept.contains(&Column::Param(*id));
            let nominal = id.to_file_units(nominal_values[i]);
            let identified = id.to_file_units(identified_values[i]);
            ParameterReport {
                name: id.to_string(),
                unit: id.file_unit_name(),
                nominal,
                identified,
                delta: identified - nominal,
                std: std_of(Column::Param(*id)).map(|s| id.to_file_units(s).abs()),
                identified_flag: flag,
            }
        })
        .collect();
    let far: Vec<String> = far_from_nominal(&parameters, &ids)
        .iter()
        .map(|p| format!("{} {:.3} → {:.3} mm", p.name, p.nominal, p.identified))
        .collect();
    if !far.is_empty() {
        warnings.push(format!(
            "identified link lengths far from the nominal table (more than {FAR_FROM_NOMINAL} mm and 10 %): {}; check the units of the data (mm) and that the robot file describes this arm",
            far.join(", ")
        ));
    }
    let poor: Vec<String> = poorly_determined(&parameters, &ids)
        .iter()
        .map(|p| {
            format!(
                "{} {:.1} → {:.1} ± {:.1} mm",
                p.name,
                p.nominal,
                p.identified,
                p.std.unwrap_or(f64::NAN)
            )
        })
        .collect();
    if !poor.is_empty() {
        warnings.push(format!(
            "link lengths the poses barely determine (moved far, within {FAR_SIGMAS} standard deviations): {}; measure more configurations, or plan them (`robocal plan`), before trusting the model",
            poor.join(", ")
        ));
    }
    let compliance_report = compliance_report(
        choice.as_ref(),
        compliance.as_ref(),
        obs,
        &kept,
        &fixed,
        &std_of,
    );
    let spread = problem.prior_spread();
    let joint_errors = match &compliance {
        Some(model)
            if settings.joint_errors.is_some()
                || (settings.compliance.as_ref()).is_some_and(|c| c.identify_payload_com) =>
        {
            joint_error_reports(model, &params, &kept, &std_of)
        }
        _ => Vec::new(),
    };
    Ok(KinematicCalibration {
        robot,
        compliance,
        aligned,
        covariance,
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
            orientation,
            parameters,
            fixed,
            identified_by_reflectors,
            condition_number: ident.condition_number,
            observability_index: ident.observability_index,
            compliance: compliance_report,
            joint_errors,
            harmonic_prior_deg: spread.harmonics.map(f64::to_degrees),
            runout_prior_deg: spread.runouts.map(f64::to_degrees),
            warnings,
        },
    })
}
