//! What an identification reports: every parameter with its change and deviation, the
//! compliances and joint errors in their file units, what was held and why.

use robocal_data::ErrorStats;
use robocal_robot::{Compliance, ParameterCovariance, Robot};
use serde::Serialize;

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
    /// How many of its coordinates were identified with the compliances (0: given, or taken
    /// from the measured point).
    #[serde(skip)]
    pub payload_com_identified: usize,
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
    /// Why it is held.
    #[serde(skip)]
    pub why: Fixed,
    /// Human-readable reason.
    pub reason: String,
}

/// Why a parameter is held fixed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Fixed {
    /// The poses cannot determine it: no effect on the measured points, or redundant with the
    /// identified parameters.
    Unidentifiable,
    /// It came out beyond what its effect can be (a harmonic or a backlash beyond a gear's, a
    /// payload's centre of mass beyond reach), or the data cannot tell it from an offset.
    Bound,
    /// A compliance or tilting compliance no joint can have (negative, beyond the bound, or
    /// within its own uncertainty).
    Implausible,
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
    ///
    /// [`JointErrorSettings::harmonic_prior`]: super::JointErrorSettings::harmonic_prior
    #[serde(skip_serializing_if = "Option::is_none")]
    pub harmonic_prior_deg: Option<f64>,
    /// The spread (standard deviation, deg) of the axis runouts' prior the data chose, when the
    /// runouts were identified under one (their own, beside the harmonics').
    #[serde(skip_serializing_if = "Option::is_none")]
    pub runout_prior_deg: Option<f64>,
    /// What the user should know about the data's ability to determine the parameters.
    pub warnings: Vec<String>,
    /// The warning among `warnings` that gravity was taken along the tracker's −z (an arm on a
    /// wall or a ceiling), when it was.
    #[serde(skip)]
    pub mounting_warning: Option<String>,
}

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
