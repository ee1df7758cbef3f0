//! What an identification fits and how: the solver, the loss, the compliances and the joint
//! errors, with their bounds.

use crate::problem::{DEFAULT_NOISE_DEG, DEFAULT_NOISE_MM, angle_weight};
use nalgebra::Vector3;
use robocal_robot::Flank;
use serde::Serialize;

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
    /// Weights of the rows of named points (`target`: a `[tool.points]` name, empty for the
    /// default point) on their squared errors, position and orientation alike; a point not
    /// named weighs 1. Empty: every row weighs 1.
    pub target_weights: Vec<(String, f64)>,
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
            target_weights: Vec::new(),
            noise_mm: DEFAULT_NOISE_MM,
            noise_deg: DEFAULT_NOISE_DEG,
            deadline: None,
            work: None,
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

/// Settings of the compliance part of an elasto-geometric identification.
#[derive(Debug, Clone, PartialEq)]
pub struct ComplianceSettings {
    /// Joints (0-based) whose compliance is identified; `None`: the joints that carry the
    /// payload's gravity torque in these data ([`default_compliance_joints`]).
    ///
    /// [`default_compliance_joints`]: super::default_compliance_joints
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

/// The tilting compliances' start, as a share of the joints' compliances
/// ([`JointErrorSettings::tilt`]): small (bearings are several times stiffer across their axes
/// than reducers about them, and a far start costs LM its way back), and only so that the
/// identifiability analysis at the start sees the links' weights tilt the joints; a tilt it
/// holds fixed is held at zero.
pub const TILT_START_SHARE: f64 = 0.02;
