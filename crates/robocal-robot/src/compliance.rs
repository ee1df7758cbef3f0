//! Joint errors: how far each joint really turns from its reading, the non-geometric physics of
//! a calibrated model. One family, [`JointErrors`], of terms that are each a known function of
//! the command and the load times an identified coefficient:
//!
//! - **compliance under the payload** (below);
//! - **transmission error**: Fourier harmonics of the joint's own angle,
//!   `Δq_i = Σ_k s_ik sin(k q_i) + c_ik cos(k q_i)` ([`Harmonic`]);
//! - **self-weight compliance**: the joint's deflection under the gravity torque of the links
//!   beyond it. The links' masses and centres of mass and the joint's compliance combine into
//!   coefficients of the torques that a unit mass at each link frame's origin, and a unit first
//!   moment along each of its axes, would put on the joint ([`SelfWeight`]); which of these the
//!   poses can separate (from each other and from the geometry) the identifiability analysis
//!   decides. It needs no payload: one load is enough;
//! - **backlash**: a joint with play rests on one flank, `Δq_i = ±b_i` (`b_i` half the play,
//!   [`Backlash`]): on the flank of its approach from home (`+b_i` at or above the home reading,
//!   `−b_i` below), or on the flank its gravity torque presses (the sign of a linear function of
//!   the joint's gravity-torque features: the link weights', the payload's and a constant
//!   preload, [`Flank::Torque`]);
//! - **tilting compliance**: a joint's bearing and reducer tilt, about the joint's origin and
//!   across its axis, by a compliance times the gravity moment across the axis of the payload
//!   and of the links' weights beyond it ([`Tilt`]). Not a turn of the joint: the parts beyond
//!   it turn about an axis perpendicular to the joint's, so the point moves by
//!   `t × (p − a)` (`t` the tilt, rad, `a` the joint's origin) after the joint angles' errors;
//! - **axis runout** (tilt error motion): a bearing's races and a reducer's output are not
//!   perfectly round nor square to the axis, so the parts beyond the joint turn across its axis
//!   by Fourier harmonics of the joint's angle ([`Runout`]), moving the point like a tilt.
//!
//! A joint whose gear and bearings give under torque turns by `compliance × torque`. The torque
//! that changes with the payload is gravity's on the payload's centre of mass,
//! `τ_i = w_i · ((c − a_i) × m g)`, with `w_i` the joint axis through `a_i` and `c` the payload's
//! centre of mass (world frame). The model's point for a command `q` under `m` kg is the rigid
//! table's point at `q + compliance ∘ τ(q, m)`: with no load it is the rigid table.
//!
//! Every term is evaluated at the command `q`, and the model's point is the rigid table's at
//! `q + Δq(q, m)`, moved by the tilts where there are any.
//!
//! ```
//! use robocal_robot::{Compliance, Robot};
//! let robot = Robot::from_toml_str(
//!     "name = \"arm\"\n[base]\nxyz = [0, 0, 0]\nrpy = [0, 0, 0]\n[tool]\nxyz = [1000, 0, 0]\n\
//!      [[joint]]\na = 0\nalpha = 90\nd = 0\ntheta = 0\n",
//!     "arm.toml",
//! )?;
//! // A horizontal joint holding 10 kg one metre out: 98 N·m, turning it by 98 × 1e-5 rad, so
//! // the point sinks by about 0.98 mm.
//! let payload = [1000.0, 0.0, 0.0].into(); // centre of mass at the point, flange frame
//! let c = Compliance::new(vec![1e-5], [0.0, 0.0, -9.80665].into(), payload);
//! let t = c.torques(&robot, &[0.0], 10.0);
//! assert!((t[0].abs() - 98.0665).abs() < 1e-9);
//! let sag = robot.point(&[0.0]).z - c.point(&robot, &[0.0], 10.0).z;
//! assert!((sag - 0.980665).abs() < 1e-3);
//! # Ok::<(), robocal_robot::RobotError>(())
//! ```

use std::cell::OnceCell;
use std::path::Path;

use nalgebra::{Matrix3, Matrix3xX, Vector3};
use serde::{Deserialize, Serialize};

use crate::error::{Result, RobotError};
use crate::kinematics::{Axis, Frame};
use crate::table::{Robot, file_value, toml_error};

/// Degrees per kN·m in radians per N·m: the file unit of a compliance.
pub const DEG_PER_KNM: f64 = std::f64::consts::PI / 180.0 / 1000.0;

/// The joint-error model: compliances under the payload's gravity torque, transmission
/// harmonics and self-weight terms.
#[derive(Debug, Clone, PartialEq)]
pub struct JointErrors {
    /// Compliance of each joint under the payload, rad/(N·m); 0 for a joint taken as rigid.
    pub values: Vec<f64>,
    /// Gravity in the robot's base frame {0}, m/s².
    pub gravity: Vector3<f64>,
    /// The payload's centre of mass in the flange frame, mm.
    pub payload_com: Vector3<f64>,
    /// Transmission harmonics.
    pub harmonics: Vec<Harmonic>,
    /// Self-weight terms.
    pub self_weight: Vec<SelfWeight>,
    /// Backlash terms.
    pub backlash: Vec<Backlash>,
    /// The links' weights (masses and first moments), shared by every joint they load: each
    /// joint deflects by its compliance (`values`) times the gravity torque of the payload and
    /// of these weights.
    pub link_weights: Vec<LinkWeight>,
    /// Tilting compliances: the turn of the parts beyond a joint across its axis under the
    /// gravity moment there.
    pub tilts: Vec<Tilt>,
    /// Axis runouts: the turn of the parts beyond a joint across its axis, periodic in the
    /// joint's angle.
    pub runouts: Vec<Runout>,
}

/// One joint's tilting compliance: the parts beyond joint `joint` turn about its origin by
/// `value × M⊥`, with `M⊥` the gravity moment (N·m, world frame) about the joint's origin of the
/// payload and of the links' weights beyond it ([`JointErrors::link_weights`]; none: the
/// payload's alone), less its component along the joint's axis (which turns the joint:
/// [`JointErrors::values`]). A bearing is round: one compliance for every direction across the
/// axis.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Tilt {
    /// 0-based joint.
    pub joint: usize,
    /// Tilting compliance, rad/(N·m).
    pub value: f64,
}

/// One order of one joint's axis runout (the tilt error motion of a rotary axis, ISO 230-7):
/// the parts beyond the joint turn about the joint's origin, across its axis, by `wave`'s value
/// at the joint angle (rad; a harmonic like a transmission error's, held beyond its reach like
/// one) about `across`, an axis of the link frame that turns with the joint. Order `k` in that
/// frame is order `k + 1` turning with the joint and `k − 1` against it, seen from the link
/// before; a constant turn in either frame is geometry (the identifiability analysis holds what
/// the table already takes).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Runout {
    /// The axis of the joint's link frame it turns about.
    pub across: Across,
    /// Its joint, order and coefficients (rad of turn).
    pub wave: Harmonic,
}

impl Runout {
    /// The unit axis it turns about (world frame), from the arm's link `frames`.
    pub fn axis(&self, frames: &[Frame]) -> Vector3<f64> {
        frames[self.wave.joint]
            .0
            .column(self.across.column())
            .into_owned()
    }
}

/// An axis of a link frame across its joint's axis.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Across {
    /// The frame's x axis.
    X,
    /// Its y axis.
    Y,
}

impl Across {
    /// Both, in order.
    pub const BOTH: [Self; 2] = [Self::X, Self::Y];

    /// The frame's column.
    pub fn column(self) -> usize {
        match self {
            Self::X => 0,
            Self::Y => 1,
        }
    }

    /// Name in files and reports.
    pub fn name(self) -> &'static str {
        match self {
            Self::X => "x",
            Self::Y => "y",
        }
    }
}

/// The small turns (rad, world frame) of the parts beyond each tilting joint, each with the
/// point it turns about (the joint's origin, mm).
pub type Turns = Vec<(Vector3<f64>, Vector3<f64>)>;

/// What one row of an identification needs at one command and load
/// ([`JointErrors::row_terms`]).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct RowTerms {
    /// The joint angles the arm really takes, rad.
    pub deflected: Vec<f64>,
    /// Entries `(k, joint, value)`: coefficient `k` turns `joint` by `value` per unit.
    pub basis: Vec<(usize, usize, f64)>,
    /// The tilting joints' turns.
    pub turns: Turns,
    /// Entries `(k, origin, turn)`: coefficient `k` turns the parts beyond a tilting joint about
    /// its `origin` (mm) by `turn` (rad, world frame) per unit.
    pub turn_basis: Vec<(usize, Vector3<f64>, Vector3<f64>)>,
}

/// How each joint's deflection (rad) changes as the table moves the parts of the arm: entry
/// `[j][k]` is `(rω, rv)`, the rate of joint `j`'s deflection per unit twist of a parameter
/// of joint `k` (`ω`, `v`: world frame, about the world origin, [`Robot::param_twists`]):
/// `δd_j = rω · ω + rv · v`. The gravity torques the deflection holds are taken at the command,
/// where the table's joint `k` turns its axis and every link from its own outwards; gravity
/// stays. Empty when nothing deflects under the torques (no compliance, no self-weight term).
pub type DeflectionRates = Vec<Vec<(Vector3<f64>, Vector3<f64>)>>;

/// One link quantity a gravity torque acts through: a point (mm) that holds a mass, or a
/// direction along which a first moment lies.
#[derive(Clone, Copy)]
enum Quantity {
    Point(Vector3<f64>),
    Direction(Vector3<f64>),
}

impl Quantity {
    /// `part` of the link whose frame is `(r, o)`.
    fn of((r, o): &(Matrix3<f64>, Vector3<f64>), part: MomentPart) -> Self {
        match part {
            MomentPart::Mass => Self::Point(*o),
            MomentPart::X => Self::Direction(r.column(0).into_owned()),
            MomentPart::Y => Self::Direction(r.column(1).into_owned()),
            MomentPart::Z => Self::Direction(r.column(2).into_owned()),
        }
    }

    /// The rate of its unit torque (as [`unit_torque`]) about the axis `(w, a)` under gravity
    /// `g`, per unit twist `(ω, v)`: `(rω, rv)` when the axis and the quantity move together
    /// (`ω · ((w × r) × g)`: the same as gravity turning by `−ω`), and when the quantity moves
    /// alone (`ω · (r × (g × w)) + v · (g × w)` for a point `r`; a direction does not slide).
    fn rates(
        &self,
        (w, a): &(Vector3<f64>, Vector3<f64>),
        g: &Vector3<f64>,
    ) -> (Vector3<f64>, (Vector3<f64>, Vector3<f64>)) {
        let gw = g.cross(w);
        match self {
            Self::Point(x) => (
                w.cross(&(x - a)).cross(g) * 1e-3,
                (x.cross(&gw) * 1e-3, gw * 1e-3),
            ),
            Self::Direction(u) => (w.cross(u).cross(g), (u.cross(&gw), Vector3::zeros())),
        }
    }
}

/// `p` (mm) moved by `turns`, to first order (the turns are micro-radians): `p + Σ t × (p − a)`.
pub fn turned(turns: &[(Vector3<f64>, Vector3<f64>)], p: Vector3<f64>) -> Vector3<f64> {
    turned_by(turns.iter().copied(), p)
}

/// [`turned`] by turns as they come, none collected.
fn turned_by(
    turns: impl IntoIterator<Item = (Vector3<f64>, Vector3<f64>)>,
    p: Vector3<f64>,
) -> Vector3<f64> {
    (turns.into_iter()).fold(p, |moved, (t, a)| moved + t.cross(&(p - a)))
}

/// The rotation of every turn of `turns` together (the identity without any).
pub fn turn_rotation(turns: &[(Vector3<f64>, Vector3<f64>)]) -> Matrix3<f64> {
    if turns.is_empty() {
        return Matrix3::identity();
    }
    let sum: Vector3<f64> = turns.iter().map(|(t, _)| t).sum();
    nalgebra::Rotation3::new(sum).into_inner()
}

/// The former name of [`JointErrors`], when it held payload compliances only.
pub type Compliance = JointErrors;

/// One transmission harmonic of one joint: `Δq = sin · sin(k q) + cos · cos(k q)`, rad, with
/// `q` the joint angle held within [`Self::reach`] when it has one.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Harmonic {
    /// 0-based joint.
    pub joint: usize,
    /// Order `k` (1: once per turn of the joint).
    pub order: u32,
    /// Sine coefficient, rad.
    pub sin: f64,
    /// Cosine coefficient, rad.
    pub cos: f64,
    /// The joint angles (rad, `[lo, hi]`) over which the harmonic is continued periodically;
    /// beyond them it keeps its value at the nearer end. `None`: every angle. Identification
    /// sets it to the joint's readings widened by [`HARMONIC_REACH`] of their span at each end:
    /// over a narrow window a harmonic may be fitting an effect it does not model (backlash,
    /// a deflection), and continued far beyond the readings it would miss by millimetres. The
    /// default calibration lifts joint 1's where its blocks of joint 1 show the harmonics
    /// predicting beyond the readings better than held (`robocal-pipeline`'s selection).
    pub reach: Option<[f64; 2]>,
}

/// How far beyond a joint's readings its identified harmonics are continued periodically, as a
/// fraction of the readings' span (at each end); farther out they are held at the value they
/// reach there. A quarter is as far as the default calibration's blocks of joint 1 test
/// extrapolation: five blocks over the readings, each end block predicted from the other four,
/// a quarter of their span beyond them.
pub const HARMONIC_REACH: f64 = 0.25;

impl Harmonic {
    /// Order `order` of joint `joint` with zero coefficients, continued at every angle.
    pub fn zero(joint: usize, order: u32) -> Self {
        Self {
            joint,
            order,
            sin: 0.0,
            cos: 0.0,
            reach: None,
        }
    }

    /// The angle (rad) the harmonic is evaluated at for joint angle `q`: `q` held within
    /// [`Self::reach`].
    pub fn angle(&self, q: f64) -> f64 {
        self.reach.map_or(q, |[lo, hi]| q.clamp(lo, hi))
    }

    /// `(sin(k q'), cos(k q'))` at the held angle `q'` ([`Self::angle`]).
    pub fn basis(&self, q: f64) -> (f64, f64) {
        (f64::from(self.order) * self.angle(q)).sin_cos()
    }

    /// Its joint error at joint angle `q`, rad.
    pub fn value(&self, q: f64) -> f64 {
        self.value_on(self.basis(q))
    }

    /// Its joint error on its basis `(sin, cos)` at some joint angle ([`Self::basis`]), rad.
    pub fn value_on(&self, (s, c): (f64, f64)) -> f64 {
        self.sin * s + self.cos * c
    }

    /// Whether `other` is evaluated at the same angles with the same basis — same joint, order
    /// and reach —, whatever its coefficients: whether its [`Self::basis`] is this one's at every
    /// joint angle.
    pub fn same_basis(&self, other: &Harmonic) -> bool {
        (self.joint, self.order, self.reach) == (other.joint, other.order, other.reach)
    }

    /// What holding the harmonic beyond its reach may miss at joint angle `q`, as a variance
    /// (rad²): the mean square, over the harmonic's phase, of the difference between its value
    /// at `q` and at the held angle, `A² (1 − cos(k d))` with `A` its amplitude and `d` the
    /// distance from `q` to the held angle (0 within the reach). Beyond the reach the model
    /// claims nothing of the harmonic but its size: if it is a gear's, it moves on there, by a
    /// turn of phase the readings did not show.
    pub fn held_variance(&self, q: f64) -> f64 {
        let d = q - self.angle(q);
        (self.sin * self.sin + self.cos * self.cos) * (1.0 - (f64::from(self.order) * d).cos())
    }

    /// The reach for readings from `lo` to `hi` (rad): widened by [`HARMONIC_REACH`] of the
    /// span at each end.
    pub fn reach_of(lo: f64, hi: f64) -> [f64; 2] {
        let margin = HARMONIC_REACH * (hi - lo).max(0.0);
        [lo - margin, hi + margin]
    }
}

/// Which flank of its play a joint with backlash rests on.
#[derive(Debug, Clone, PartialEq)]
pub enum Flank {
    /// The flank of its approach from `home` (rad): the joint was moved out from home to each
    /// pose, so it rests on the flank its motion pressed, `+1` at a reading at or above home and
    /// `−1` below. A joint whose readings all lie on one side of home shows only a constant
    /// offset, which the geometry takes: the identifiability analysis holds the term at zero.
    Approach {
        /// The reading the joint moves out from, rad.
        home: f64,
    },
    /// The flank its torque presses: `+1` where `weights · f ≥ 0`, `−1` elsewhere, with `f` the
    /// joint's gravity-torque features ([`JointErrors::torque_features`]: the torques of a unit
    /// mass and unit first moments of every link from the joint's outwards, of the flange frame
    /// times the load, and 1). With the load's unit-mass weight 1, the others are the links'
    /// masses (kg) and first moments (kg·m), the payload's centre of mass (m) and a preload
    /// (N·m): the sign is that of the joint's torque.
    Torque {
        /// One per feature.
        weights: Vec<f64>,
    },
}

/// Backlash of one joint: `Δq = value × flank`, `value` half the play (signed by which flank
/// leads), the flank `±1` as [`Flank`] says.
#[derive(Debug, Clone, PartialEq)]
pub struct Backlash {
    /// 0-based joint.
    pub joint: usize,
    /// Which flank it rests on.
    pub flank: Flank,
    /// Half the play, rad (the joint error on the `+1` flank).
    pub value: f64,
}

impl Flank {
    /// A torque flank's preload, N·m: its last weight, when the weights are scaled to the
    /// payload's unit mass (data with several loads); `None` otherwise.
    pub fn preload(&self) -> Option<f64> {
        match self {
            Flank::Torque { weights }
                if weights.get(payload_mass_feature(weights.len())) == Some(&1.0) =>
            {
                weights.last().copied()
            }
            _ => None,
        }
    }
}

impl Backlash {
    /// The home reading of an approach flank (`None` for a torque flank).
    pub fn home(&self) -> Option<f64> {
        match self.flank {
            Flank::Approach { home } => Some(home),
            Flank::Torque { .. } => None,
        }
    }
}

/// Which unit quantity of a link a self-weight term weighs.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum MomentPart {
    /// A unit mass at the link frame's origin: basis N·m per kg.
    Mass,
    /// A unit first moment (1 kg·m) along the link frame's x axis: basis N·m per kg·m.
    X,
    /// Along y.
    Y,
    /// Along z.
    Z,
}

impl MomentPart {
    /// Every part, in the order of the self-weight terms and torque features.
    pub const ALL: [Self; 4] = [Self::Mass, Self::X, Self::Y, Self::Z];

    /// The unit of a link's quantity of this part: `kg` for its mass, `kg·m` for a first
    /// moment.
    pub fn weight_unit(self) -> &'static str {
        match self {
            Self::Mass => "kg",
            Self::X | Self::Y | Self::Z => "kg·m",
        }
    }

    /// Name in files and reports.
    pub fn name(self) -> &'static str {
        match self {
            Self::Mass => "mass",
            Self::X => "x",
            Self::Y => "y",
            Self::Z => "z",
        }
    }
}

/// One self-weight term: `Δq_joint = value × φ`, with `φ` the gravity torque about the joint's
/// axis of the unit quantity `part` of link `body` (N·m per kg, or per kg·m).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SelfWeight {
    /// 0-based joint that deflects.
    pub joint: usize,
    /// 0-based link (moved by joint `body`), `body >= joint`.
    pub body: usize,
    /// Which unit quantity.
    pub part: MomentPart,
    /// Coefficient, rad per basis unit (compliance × the link's mass or moment).
    pub value: f64,
}

impl SelfWeight {
    /// Its basis value `φ` at the command `pose` holds: the gravity torque about its joint's axis
    /// of its link's unit quantity.
    fn basis_at(&self, pose: &PoseCache) -> f64 {
        let Pose { axes, frames, g } = pose.get();
        unit_torque(&axes[self.joint], &frames[self.body], g, self.part)
    }
}

/// One quantity of one link's weight, in the shared model of the links' weights: every joint
/// at or before the link feels its gravity torque and deflects by that torque times its own
/// compliance (`JointErrors::values`), as under the payload. The per-joint self-weight terms
/// ([`SelfWeight`]) are the same physics with one coefficient per joint and link, `compliance ×
/// value`; shared, the links' weights are fewer unknowns, and the joint stiffness the payload
/// shows is the one their weight meets.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LinkWeight {
    /// 0-based link (moved by joint `body`).
    pub body: usize,
    /// Which quantity: its mass at the link frame's origin (kg) or a first moment (kg·m).
    pub part: MomentPart,
    /// kg for [`MomentPart::Mass`], kg·m for the moments.
    pub value: f64,
}

/// What every gravity term reads at one command: each joint's axis (unit, and a point on it,
/// mm), every link frame {1}..{n} (the last is the flange's) and gravity (m/s²), world frame.
struct Pose<'a> {
    axes: &'a [Axis],
    frames: &'a [Frame],
    g: &'a Vector3<f64>,
}

/// The terms of one row that the deflection and the basis share ([`JointErrors::row_terms`]).
struct RowShared {
    /// The gravity torque about every joint (N·m) that the compliances meet.
    torques: Vec<f64>,
    /// Each link weight's unit torque about every joint up to its link's.
    links: LinkUnits,
    /// The basis value of every self-weight term.
    self_weight: Vec<f64>,
    /// The flank (`±1`) of every backlash term.
    flanks: Vec<f64>,
}

/// Each link weight's unit torque about every joint up to its link's, one after the other in
/// one buffer ([`JointErrors::link_weights`] order).
struct LinkUnits {
    values: Vec<f64>,
    /// Where each weight's torques end in `values`.
    ends: Vec<usize>,
}

impl LinkUnits {
    /// Link weight `i`'s unit torques (entry `j` for joint `j`).
    fn of(&self, i: usize) -> &[f64] {
        let start = if i == 0 { 0 } else { self.ends[i - 1] };
        &self.values[start..self.ends[i]]
    }
}

/// The arm's joint axes and link frames at command `q`, computed on first use and once: the
/// payload's torques, the links' weights, the self-weight terms, the torque flanks and the
/// centre of mass's columns of one row share them. With them the bases of the model's waves at
/// `q` ([`JointErrors::wave_bases`]): the caller's, or computed on first use.
struct PoseCache<'a> {
    robot: &'a Robot,
    q: &'a [f64],
    g: Vector3<f64>,
    pose: OnceCell<(Vec<Axis>, Vec<Frame>)>,
    given_waves: Option<&'a [(f64, f64)]>,
    waves: OnceCell<Vec<(f64, f64)>>,
}

impl PoseCache<'_> {
    fn get(&self) -> Pose<'_> {
        let (axes, frames) = self.pose.get_or_init(|| self.robot.axes_and_frames(self.q));
        Pose {
            axes,
            frames,
            g: &self.g,
        }
    }

    /// The bases of `model`'s waves at the command ([`JointErrors::wave_bases`]).
    fn waves(&self, model: &JointErrors) -> &[(f64, f64)] {
        match self.given_waves {
            Some(waves) => waves,
            None => self.waves.get_or_init(|| model.wave_bases(self.q)),
        }
    }
}

/// The gravity moment (N·m per unit, world frame) about the point `a` (mm) of the unit quantity
/// `part` of the link whose frame is `(r, o)`, gravity `g` (m/s²): the vector whose component
/// along an axis through `a` is [`unit_torque`].
fn unit_moment(
    a: &Vector3<f64>,
    (r, o): &(Matrix3<f64>, Vector3<f64>),
    g: &Vector3<f64>,
    part: MomentPart,
) -> Vector3<f64> {
    match part {
        MomentPart::Mass => (o - a).cross(g) * 1e-3,
        MomentPart::X => r.column(0).cross(g),
        MomentPart::Y => r.column(1).cross(g),
        MomentPart::Z => r.column(2).cross(g),
    }
}

/// `m` less its component along the unit vector `w`.
fn across(w: &Vector3<f64>, m: Vector3<f64>) -> Vector3<f64> {
    m - w * w.dot(&m)
}

/// Which of a block's terms (their `values`, in order) a row computes the basis of: those not at
/// zero, and those among `params` (`index` picks the block's own parameters out of them).
fn not_zero_or_identified(
    values: impl Iterator<Item = f64>,
    params: &[ErrorParam],
    index: impl Fn(ErrorParam) -> Option<usize>,
) -> Vec<bool> {
    let mut wanted: Vec<bool> = values.map(|v| v != 0.0).collect();
    for i in params.iter().filter_map(|&p| index(p)) {
        wanted[i] = true;
    }
    wanted
}

/// The gravity torque (N·m per unit) about the joint axis `(w, a)` (unit vector, point, mm) of
/// the unit quantity `part` of the link whose frame is `(r, o)`, gravity `g` (m/s²): `w ·`
/// [`unit_moment`], kept in its own order of operations so that the torques, and every model
/// identified before the tilts, stay the same to the last bit.
fn unit_torque(
    (w, a): &(Vector3<f64>, Vector3<f64>),
    (r, o): &(Matrix3<f64>, Vector3<f64>),
    g: &Vector3<f64>,
    part: MomentPart,
) -> f64 {
    match part {
        MomentPart::Mass => w.dot(&(o - a).cross(g)) * 1e-3,
        MomentPart::X => w.dot(&r.column(0).cross(g)),
        MomentPart::Y => w.dot(&r.column(1).cross(g)),
        MomentPart::Z => w.dot(&r.column(2).cross(g)),
    }
}

/// The gravity-torque features about the joint axis `axis` (see
/// [`JointErrors::torque_features`]) of the links whose frames are `frames` (the joint's own
/// and every one beyond it; the last is the flange's), gravity `g`, under `load` kg.
fn torque_features_at(
    axis: &(Vector3<f64>, Vector3<f64>),
    frames: &[(Matrix3<f64>, Vector3<f64>)],
    g: &Vector3<f64>,
    load: f64,
) -> Vec<f64> {
    let mut f = Vec::with_capacity(TORQUE_FEATURES_PER_LINK * (frames.len() + 1) + 1);
    visit_torque_features(axis, frames, g, load, |v| {
        f.push(v);
        true
    });
    f
}

/// Hands [`torque_features_at`]'s features to `visit` one by one, in their order, until it
/// returns false: the links' (the joint's own outwards, each link's parts in
/// [`MomentPart::ALL`] order), the payload's (`load` times the flange's, whose unit torques are
/// computed once for both), the preload's constant 1.
fn visit_torque_features(
    axis: &(Vector3<f64>, Vector3<f64>),
    frames: &[(Matrix3<f64>, Vector3<f64>)],
    g: &Vector3<f64>,
    load: f64,
    mut visit: impl FnMut(f64) -> bool,
) {
    let Some((flange, links)) = frames.split_last() else {
        visit(1.0);
        return;
    };
    for frame in links {
        for part in MomentPart::ALL {
            if !visit(unit_torque(axis, frame, g, part)) {
                return;
            }
        }
    }
    let at_flange = MomentPart::ALL.map(|part| unit_torque(axis, flange, g, part));
    for t in at_flange {
        if !visit(t) {
            return;
        }
    }
    for t in at_flange {
        if !visit(load * t) {
            return;
        }
    }
    visit(1.0);
}

/// `q` (rad) turned by the deflection `d` (rad), in `d`'s buffer (`d + q` is `q + d` to the bit).
fn deflected_by(q: &[f64], mut d: Vec<f64>) -> Vec<f64> {
    deflect(q, &mut d);
    d
}

/// The deflection `d` (rad) turned into the angles the arm takes from `q` (rad), in place.
fn deflect(q: &[f64], d: &mut [f64]) {
    for (d, q) in d.iter_mut().zip(q) {
        *d += q;
    }
}

/// `+1` for the positive flank, `−1` for the other.
fn side(positive: bool) -> f64 {
    if positive { 1.0 } else { -1.0 }
}

/// The flank (`±1`) a torque flank's `weights` give for the gravity-torque `features`: `+1`
/// where their product is at least 0.
pub fn torque_side(weights: &[f64], features: &[f64]) -> f64 {
    torque_side_of(weights, features.iter().copied())
}

/// [`torque_side`] of features given one by one.
fn torque_side_of(weights: &[f64], features: impl Iterator<Item = f64>) -> f64 {
    side(
        weights
            .iter()
            .zip(features)
            .map(|(w, f)| w * f)
            .sum::<f64>()
            >= 0.0,
    )
}

/// [`torque_side`] of the features [`torque_features_at`] gives for `axis`, `frames`, `g` and
/// `load`, without collecting them: each summed with its weight in the same order, so the same
/// flank (the sum may start from a zero of the other sign than a float `sum()`'s, which changes
/// no sum but one of zeros, and `±0 ≥ 0` alike; it stops where the weights do, as a zip). The
/// nested iterators this replaced cost a quarter of a residual evaluation with five torque
/// flanks.
fn torque_side_at(
    weights: &[f64],
    axis: &(Vector3<f64>, Vector3<f64>),
    frames: &[(Matrix3<f64>, Vector3<f64>)],
    g: &Vector3<f64>,
    load: f64,
) -> f64 {
    let mut weights = weights.iter();
    let mut sum = 0.0;
    visit_torque_features(axis, frames, g, load, |f| match weights.next() {
        Some(w) => {
            sum += w * f;
            true
        }
        None => false,
    });
    side(sum >= 0.0)
}

/// The position, among `count` gravity-torque features, of the payload's unit mass (the
/// weight a torque flank's weights are scaled to; the preload's is the last).
pub fn payload_mass_feature(count: usize) -> usize {
    count.saturating_sub(TORQUE_FEATURES_PER_LINK + 1)
}

/// The name of joint `joint`'s (0-based) payload compliance: `j2.compliance`.
pub fn compliance_name(joint: usize) -> String {
    format!("j{}.compliance", joint + 1)
}

/// The name of a harmonic's sine or cosine coefficient: `j3.h2.sin`, `j3.h2.cos`.
pub fn harmonic_name(joint: usize, order: u32, cos: bool) -> String {
    let which = if cos { "cos" } else { "sin" };
    format!("j{}.h{order}.{which}", joint + 1)
}

/// The name of a self-weight coefficient: `j2.sw4.mass` (joint and link 0-based here).
pub fn self_weight_name(joint: usize, body: usize, part: MomentPart) -> String {
    format!("j{}.sw{}.{}", joint + 1, body + 1, part.name())
}

/// The name of a shared link weight: `link3.mass`, `link3.x` (link 0-based here).
pub fn link_weight_name(body: usize, part: MomentPart) -> String {
    format!("link{}.{}", body + 1, part.name())
}

/// The name of a coordinate (0: x, 1: y, 2: z) of the payload's centre of mass in the flange
/// frame: `payload_com.x`.
pub fn payload_com_name(axis: usize) -> String {
    format!("payload_com.{}", ["x", "y", "z"][axis])
}

/// The name of a joint's backlash (half its play): `j1.backlash`.
pub fn backlash_name(joint: usize) -> String {
    format!("j{}.backlash", joint + 1)
}

/// The name of a joint's tilting compliance: `j2.tilt`.
pub fn tilt_name(joint: usize) -> String {
    format!("j{}.tilt", joint + 1)
}

/// The name of a runout coefficient: `j1.r2y.cos` (joint 0-based here).
pub fn runout_name(joint: usize, order: u32, across: Across, cos: bool) -> String {
    let which = if cos { "cos" } else { "sin" };
    format!("j{}.r{order}{}.{which}", joint + 1, across.name())
}

/// One coefficient of a [`JointErrors`] model, as an unknown of an identification.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum ErrorParam {
    /// The payload compliance of a joint (0-based).
    Compliance(usize),
    /// The sine coefficient of `harmonics[i]`.
    HarmonicSin(usize),
    /// The cosine coefficient of `harmonics[i]`.
    HarmonicCos(usize),
    /// The coefficient of `self_weight[i]`.
    SelfWeight(usize),
    /// The half play of `backlash[i]`.
    Backlash(usize),
    /// The value of `link_weights[i]`.
    LinkWeight(usize),
    /// Coordinate `axis` (0: x, 1: y, 2: z) of the payload's centre of mass in the flange frame,
    /// mm: it moves the payload's gravity torque on every joint, each deflecting by its
    /// compliance.
    PayloadCom(usize),
    /// The tilting compliance of `tilts[i]`.
    Tilt(usize),
    /// The sine coefficient of `runouts[i]`.
    RunoutSin(usize),
    /// The cosine coefficient of `runouts[i]`.
    RunoutCos(usize),
}

impl Robot {
    /// The target point for command `q` (rad) under `load` kg, mm, world frame: the table's
    /// point, at the angles `compliance` deflects the arm to when there is a compliance model.
    pub fn point_under_load(
        &self,
        compliance: Option<&Compliance>,
        q: &[f64],
        load: f64,
    ) -> Vector3<f64> {
        match compliance {
            Some(c) => c.point(self, q, load),
            None => self.point(q),
        }
    }

    /// The tool frame's orientation for command `q` (rad) under `load` kg, world frame: at the
    /// angles `compliance` deflects the arm to when there is a compliance model.
    pub fn rotation_under_load(
        &self,
        compliance: Option<&Compliance>,
        q: &[f64],
        load: f64,
    ) -> Matrix3<f64> {
        match compliance {
            Some(c) => c.rotation(self, q, load),
            None => self.tool_rotation(q),
        }
    }
}

/// `compliance.toml` as written: compliances in deg/(kN·m).
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawCompliance {
    /// Gravity in the robot's base frame {0}, m/s².
    #[serde(deserialize_with = "crate::exact::array")]
    pub gravity: [f64; 3],
    /// The payload's centre of mass in the flange frame, mm.
    #[serde(deserialize_with = "crate::exact::array")]
    pub payload_com: [f64; 3],
    /// One per joint, deg per kN·m (0: rigid).
    pub compliance: Vec<f64>,
    /// Transmission harmonics.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub harmonic: Vec<RawHarmonic>,
    /// Self-weight terms.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub self_weight: Vec<RawSelfWeight>,
    /// Backlash terms.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub backlash: Vec<RawBacklash>,
    /// The links' shared weights.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub link_weight: Vec<RawLinkWeight>,
    /// Tilting compliances.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub tilt: Vec<RawTilt>,
    /// Axis runouts.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub runout: Vec<RawRunout>,
}

/// `[[runout]]` as written.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawRunout {
    /// Joint, counted from 1.
    pub joint: usize,
    /// Order k.
    pub order: u32,
    /// `x` or `y`: the axis of the joint's link frame (turning with the joint) it turns about.
    pub across: Across,
    /// Sine coefficient, deg of turn.
    pub sin: f64,
    /// Cosine coefficient, deg of turn.
    pub cos: f64,
    /// `[lo, hi]`, deg, as a harmonic's.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reach: Option<[f64; 2]>,
}

/// `[[tilt]]` as written.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawTilt {
    /// Joint, counted from 1.
    pub joint: usize,
    /// Tilting compliance, deg per kN·m of the gravity moment across the joint's axis.
    pub compliance: f64,
}

/// `[[link_weight]]` as written.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawLinkWeight {
    /// Link, counted from 1 (link i moves with joint i).
    pub body: usize,
    /// `mass` (kg, at the link frame's origin), or `x`, `y`, `z` (first moments, kg·m).
    pub part: MomentPart,
    /// kg or kg·m.
    pub value: f64,
}

/// `[[backlash]]` as written: `home` (the flank of the approach from home) or `torque` (the flank
/// the torque presses), not both.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawBacklash {
    /// Joint, counted from 1.
    pub joint: usize,
    /// The reading the joint moves out from, deg.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub home: Option<f64>,
    /// The weights of the joint's gravity-torque features ([`Flank::Torque`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub torque: Option<Vec<f64>>,
    /// Half the play, deg: the joint error on the `+1` flank (at or above home; where the
    /// weighted torque is at least 0), its negative on the other.
    pub value: f64,
}

/// `[[harmonic]]` as written.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawHarmonic {
    /// Joint, counted from 1.
    pub joint: usize,
    /// Order k.
    pub order: u32,
    /// Sine coefficient, deg.
    pub sin: f64,
    /// Cosine coefficient, deg.
    pub cos: f64,
    /// `[lo, hi]`, deg: the joint angles over which the harmonic is continued periodically
    /// (beyond them, held at its value at the nearer end); absent: every angle.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reach: Option<[f64; 2]>,
}

/// `[[self_weight]]` as written.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawSelfWeight {
    /// Joint that deflects, counted from 1.
    pub joint: usize,
    /// Link whose weight, counted from 1 (link i moves with joint i), at least `joint`.
    pub body: usize,
    /// `mass`, `x`, `y` or `z`.
    pub part: MomentPart,
    /// Coefficient, deg per basis unit (N·m per kg for `mass`, per kg·m for the moments).
    pub value: f64,
}

/// Gravity-torque features per link (and for the payload): a unit mass and three unit first
/// moments.
pub const TORQUE_FEATURES_PER_LINK: usize = 4;

/// Highest harmonic order a file may give.
pub const MAX_HARMONIC_ORDER: u32 = 64;

impl JointErrors {
    /// A compliance model; `values` in rad/(N·m), one per joint; no other term.
    pub fn new(values: Vec<f64>, gravity: Vector3<f64>, payload_com: Vector3<f64>) -> Self {
        Self {
            values,
            gravity,
            payload_com,
            harmonics: Vec::new(),
            self_weight: Vec::new(),
            backlash: Vec::new(),
            link_weights: Vec::new(),
            tilts: Vec::new(),
            runouts: Vec::new(),
        }
    }

    /// Whether there is any term besides the payload compliances.
    pub fn has_configuration_terms(&self) -> bool {
        !self.harmonics.is_empty()
            || !self.self_weight.is_empty()
            || !self.backlash.is_empty()
            || !self.link_weights.is_empty()
            || !self.tilts.is_empty()
            || !self.runouts.is_empty()
    }

    /// Whether any term turns the parts beyond a joint across its axis (tilts, runouts).
    pub fn has_turns(&self) -> bool {
        !self.tilts.is_empty() || !self.runouts.is_empty()
    }

    /// The value of one coefficient (internal units).
    pub fn param(&self, p: ErrorParam) -> f64 {
        match p {
            ErrorParam::Compliance(j) => self.values[j],
            ErrorParam::HarmonicSin(i) => self.harmonics[i].sin,
            ErrorParam::HarmonicCos(i) => self.harmonics[i].cos,
            ErrorParam::SelfWeight(i) => self.self_weight[i].value,
            ErrorParam::Backlash(i) => self.backlash[i].value,
            ErrorParam::LinkWeight(i) => self.link_weights[i].value,
            ErrorParam::PayloadCom(axis) => self.payload_com[axis],
            ErrorParam::Tilt(i) => self.tilts[i].value,
            ErrorParam::RunoutSin(i) => self.runouts[i].wave.sin,
            ErrorParam::RunoutCos(i) => self.runouts[i].wave.cos,
        }
    }

    /// Sets one coefficient (internal units).
    pub fn set_param(&mut self, p: ErrorParam, v: f64) {
        match p {
            ErrorParam::Compliance(j) => self.values[j] = v,
            ErrorParam::HarmonicSin(i) => self.harmonics[i].sin = v,
            ErrorParam::HarmonicCos(i) => self.harmonics[i].cos = v,
            ErrorParam::SelfWeight(i) => self.self_weight[i].value = v,
            ErrorParam::Backlash(i) => self.backlash[i].value = v,
            ErrorParam::LinkWeight(i) => self.link_weights[i].value = v,
            ErrorParam::PayloadCom(axis) => self.payload_com[axis] = v,
            ErrorParam::Tilt(i) => self.tilts[i].value = v,
            ErrorParam::RunoutSin(i) => self.runouts[i].wave.sin = v,
            ErrorParam::RunoutCos(i) => self.runouts[i].wave.cos = v,
        }
    }

    /// The joint a coefficient turns (a link weight turns every joint up to its link's: its
    /// link's; the payload's centre of mass every joint: the last).
    pub fn joint_of(&self, p: ErrorParam) -> usize {
        match p {
            ErrorParam::Compliance(j) => j,
            ErrorParam::HarmonicSin(i) | ErrorParam::HarmonicCos(i) => self.harmonics[i].joint,
            ErrorParam::SelfWeight(i) => self.self_weight[i].joint,
            ErrorParam::Backlash(i) => self.backlash[i].joint,
            ErrorParam::LinkWeight(i) => self.link_weights[i].body,
            ErrorParam::PayloadCom(_) => self.values.len().saturating_sub(1),
            ErrorParam::Tilt(i) => self.tilts[i].joint,
            ErrorParam::RunoutSin(i) | ErrorParam::RunoutCos(i) => self.runouts[i].wave.joint,
        }
    }

    /// A stable name for a coefficient: `j2.compliance`, `j3.h2.sin`, `j2.sw4.mass`,
    /// `j1.backlash`, `link3.x`, `payload_com.z`.
    pub fn param_name(&self, p: ErrorParam) -> String {
        match p {
            ErrorParam::Compliance(j) => compliance_name(j),
            ErrorParam::HarmonicSin(i) | ErrorParam::HarmonicCos(i) => {
                let h = &self.harmonics[i];
                harmonic_name(h.joint, h.order, matches!(p, ErrorParam::HarmonicCos(_)))
            }
            ErrorParam::SelfWeight(i) => {
                let t = &self.self_weight[i];
                self_weight_name(t.joint, t.body, t.part)
            }
            ErrorParam::Backlash(i) => backlash_name(self.backlash[i].joint),
            ErrorParam::LinkWeight(i) => {
                let w = &self.link_weights[i];
                link_weight_name(w.body, w.part)
            }
            ErrorParam::PayloadCom(axis) => payload_com_name(axis),
            ErrorParam::Tilt(i) => tilt_name(self.tilts[i].joint),
            ErrorParam::RunoutSin(i) | ErrorParam::RunoutCos(i) => {
                let r = &self.runouts[i];
                let cos = matches!(p, ErrorParam::RunoutCos(_));
                runout_name(r.wave.joint, r.wave.order, r.across, cos)
            }
        }
    }

    /// Every coefficient of the model, in order: compliances of every joint, then each
    /// harmonic's sine and cosine, then the self-weight terms, then the backlash terms, then the
    /// link weights, then the tilting compliances, then each runout's sine and cosine (the
    /// payload's centre of mass, a setting unless identified, is not listed).
    pub fn params(&self) -> Vec<ErrorParam> {
        let mut out: Vec<ErrorParam> = (0..self.values.len()).map(ErrorParam::Compliance).collect();
        for i in 0..self.harmonics.len() {
            out.push(ErrorParam::HarmonicSin(i));
            out.push(ErrorParam::HarmonicCos(i));
        }
        out.extend((0..self.self_weight.len()).map(ErrorParam::SelfWeight));
        out.extend((0..self.backlash.len()).map(ErrorParam::Backlash));
        out.extend((0..self.link_weights.len()).map(ErrorParam::LinkWeight));
        out.extend((0..self.tilts.len()).map(ErrorParam::Tilt));
        for i in 0..self.runouts.len() {
            out.push(ErrorParam::RunoutSin(i));
            out.push(ErrorParam::RunoutCos(i));
        }
        out
    }

    /// Every harmonic of the model, the transmission errors' and the runouts' waves: what is
    /// continued periodically within its reach and held beyond it.
    pub fn waves_mut(&mut self) -> impl Iterator<Item = &mut Harmonic> {
        (self.harmonics.iter_mut()).chain(self.runouts.iter_mut().map(|r| &mut r.wave))
    }

    /// Every harmonic of the model, in [`Self::waves_mut`]'s order.
    fn waves(&self) -> impl Iterator<Item = &Harmonic> {
        (self.harmonics.iter()).chain(self.runouts.iter().map(|r| &r.wave))
    }

    /// The basis `(sin, cos)` of every wave of the model ([`Self::waves_mut`]'s order: the
    /// harmonics', then the runouts') at command `q` (rad), [`Harmonic::basis`]: all the model
    /// reads of the readings beside the arm's frames and the flanks. It stays the same while only
    /// coefficients change, so that a fit computes it once per row and hands it to
    /// [`Self::point_on_waves`] and [`Self::row_terms_on_waves`] (the same values to the bit).
    pub fn wave_bases(&self, q: &[f64]) -> Vec<(f64, f64)> {
        self.waves().map(|h| h.basis(q[h.joint])).collect()
    }

    /// Whether `other`'s [`Self::wave_bases`] are this model's at every command: the same waves
    /// (joints, orders, reaches; [`Harmonic::same_basis`]) in the same order, whatever their
    /// coefficients.
    pub fn same_waves(&self, other: &JointErrors) -> bool {
        (self.harmonics.len(), self.runouts.len()) == (other.harmonics.len(), other.runouts.len())
            && self
                .waves()
                .zip(other.waves())
                .all(|(a, b)| a.same_basis(b))
    }

    /// Adds runouts of orders `1..=orders` about both axes across (coefficients 0) for `joints`.
    pub fn with_runouts(mut self, joints: &[usize], orders: u32) -> Self {
        for &joint in joints {
            for order in 1..=orders {
                for across in Across::BOTH {
                    self.runouts.push(Runout {
                        across,
                        wave: Harmonic::zero(joint, order),
                    });
                }
            }
        }
        self
    }

    /// Adds tilting compliances (0) for `joints`.
    pub fn with_tilts(mut self, joints: &[usize]) -> Self {
        self.tilts
            .extend(joints.iter().map(|&joint| Tilt { joint, value: 0.0 }));
        self
    }

    /// The gravity moment (N·m, world frame) about joint `joint`'s origin of the payload and of
    /// the links' weights beyond it, less its component along the joint's axis, at the command
    /// `pose` holds under `load` kg.
    fn moment_across(&self, pose: &PoseCache, load: f64, joint: usize) -> Vector3<f64> {
        let Pose { axes, frames, g } = pose.get();
        let (w, a) = &axes[joint];
        let mut m = Vector3::zeros();
        if load != 0.0 {
            let (r, o) = frames.last().expect("an arm has a joint");
            let com = o + r * self.payload_com;
            m += (com - a).cross(&(g * load)) * 1e-3;
        }
        for lw in self.link_weights.iter().filter(|lw| lw.body >= joint) {
            m += lw.value * unit_moment(a, &frames[lw.body], g, lw.part);
        }
        across(w, m)
    }

    /// The turns of the tilting joints and of the runouts at the command `pose` holds under
    /// `load` kg.
    fn turns_at(&self, pose: &PoseCache, load: f64) -> Turns {
        let mut out = Vec::new();
        self.turns_into(pose, load, &mut out);
        out
    }

    /// [`Self::turns_at`] written into `out` (emptied first, its capacity kept: a fit's rows
    /// fill one buffer in turn).
    fn turns_into(&self, pose: &PoseCache, load: f64, out: &mut Turns) {
        out.clear();
        out.extend(self.each_turn(pose, load));
    }

    /// The turns of [`Self::turns_at`] as they come, in their order (the tilting joints', then
    /// the runouts'), each with the origin it turns about.
    fn each_turn<'s>(
        &'s self,
        pose: &'s PoseCache,
        load: f64,
    ) -> impl Iterator<Item = (Vector3<f64>, Vector3<f64>)> + 's {
        let tilts = self.tilts.iter().map(move |t| {
            let origin = pose.get().axes[t.joint].1;
            (t.value * self.moment_across(pose, load, t.joint), origin)
        });
        let runouts = self.runouts.iter().enumerate().map(move |(n, r)| {
            let Pose { axes, frames, .. } = pose.get();
            let basis = pose.waves(self)[self.harmonics.len() + n];
            (
                r.axis(frames) * r.wave.value_on(basis),
                axes[r.wave.joint].1,
            )
        });
        tilts.chain(runouts)
    }

    /// The turns of the tilting joints and of the runouts (rad, world frame, each with the
    /// joint's origin it turns about, mm) at command `q` (rad) under `load` kg: empty without
    /// tilting compliances and runouts.
    pub fn turns(&self, robot: &Robot, q: &[f64], load: f64) -> Turns {
        self.turns_at(&self.pose(robot, q), load)
    }

    /// The runouts' turns among `turns`, this model's ([`Self::turns`]: the tilting joints'
    /// first, then one per runout in the order of `runouts`), each with the origin it turns
    /// about. Panics where `turns` are not this model's (a count that does not match).
    pub fn runout_turns<'t>(
        &self,
        turns: &'t [(Vector3<f64>, Vector3<f64>)],
    ) -> &'t [(Vector3<f64>, Vector3<f64>)] {
        let runouts = &turns[self.tilts.len().min(turns.len())..];
        assert_eq!(
            (turns.len(), runouts.len()),
            (self.tilts.len() + self.runouts.len(), self.runouts.len()),
            "the turns of another model"
        );
        runouts
    }

    /// For each of `params` (by position `k`) that turns the parts beyond a tilting joint, the
    /// turn per unit (rad, world frame) and the joint's origin it turns about, as entries
    /// `(k, origin, turn)`: a tilting compliance its moment across the axis; a link weight and
    /// a coordinate of the payload's centre of mass, for every tilting joint they load, the
    /// joint's compliance times the moment across its axis of the unit quantity; a runout's
    /// coefficient its axis across times its basis value.
    ///
    /// Written into `out` (emptied first, its capacity kept).
    fn turn_basis_into(
        &self,
        pose: &PoseCache,
        load: f64,
        params: &[ErrorParam],
        out: &mut Vec<(usize, Vector3<f64>, Vector3<f64>)>,
    ) {
        out.clear();
        if !self.has_turns() {
            return;
        }
        let Pose { axes, frames, g } = pose.get();
        for (k, &p) in params.iter().enumerate() {
            match p {
                ErrorParam::Tilt(i) => {
                    let joint = self.tilts[i].joint;
                    out.push((k, axes[joint].1, self.moment_across(pose, load, joint)));
                }
                ErrorParam::LinkWeight(i) => {
                    let lw = &self.link_weights[i];
                    for t in self.tilts.iter().filter(|t| t.joint <= lw.body) {
                        let (w, a) = &axes[t.joint];
                        let unit = unit_moment(a, &frames[lw.body], g, lw.part);
                        out.push((k, *a, t.value * across(w, unit)));
                    }
                }
                ErrorParam::PayloadCom(axis) if load != 0.0 => {
                    let (r, _) = frames.last().expect("an arm has a joint");
                    let unit = r.column(axis).cross(&(g * load)) * 1e-3;
                    for t in &self.tilts {
                        let (w, a) = &axes[t.joint];
                        out.push((k, *a, t.value * across(w, unit)));
                    }
                }
                ErrorParam::RunoutSin(i) | ErrorParam::RunoutCos(i) => {
                    let r = &self.runouts[i];
                    let j = r.wave.joint;
                    let (sin, cos) = pose.waves(self)[self.harmonics.len() + i];
                    let b = if matches!(p, ErrorParam::RunoutCos(_)) {
                        cos
                    } else {
                        sin
                    };
                    out.push((k, axes[j].1, r.axis(frames) * b));
                }
                _ => {}
            }
        }
    }

    /// Adds the shared weights (0) of links `bodies` (0-based): each one's mass and its three
    /// first moments.
    pub fn with_link_weights(mut self, bodies: &[usize]) -> Self {
        for &body in bodies {
            for part in MomentPart::ALL {
                self.link_weights.push(LinkWeight {
                    body,
                    part,
                    value: 0.0,
                });
            }
        }
        self
    }

    /// For each link weight ([`Self::link_weights`]) that loads the joints (a value not zero)
    /// or is among `params`, the gravity torque (N·m per kg or per kg·m) of its unit quantity
    /// about every joint axis up to its link's (entry `j` for joint `j`), at command `q` (rad);
    /// none for the others (held at zero and not identified: most of a fit's, whose poses tell
    /// few of the links' masses from the geometry); empty without any link weight.
    fn link_weight_basis(&self, pose: &PoseCache, params: &[ErrorParam]) -> LinkUnits {
        if self.link_weights.is_empty() {
            return LinkUnits {
                values: Vec::new(),
                ends: Vec::new(),
            };
        }
        let wanted = not_zero_or_identified(
            self.link_weights.iter().map(|w| w.value),
            params,
            |p| match p {
                ErrorParam::LinkWeight(i) => Some(i),
                _ => None,
            },
        );
        // Sized once: each wanted weight's torques on the joints up to its link's.
        let size = (self.link_weights.iter().zip(&wanted))
            .filter(|(_, wanted)| **wanted)
            .map(|(w, _)| w.body + 1)
            .sum();
        let mut units = LinkUnits {
            values: Vec::with_capacity(size),
            ends: Vec::with_capacity(self.link_weights.len()),
        };
        let Pose { axes, frames, g } = pose.get();
        for (w, wanted) in self.link_weights.iter().zip(wanted) {
            if wanted {
                (units.values).extend(
                    (axes[..=w.body].iter())
                        .map(|axis| unit_torque(axis, &frames[w.body], g, w.part)),
                );
            }
            units.ends.push(units.values.len());
        }
        units
    }

    /// The payload's gravity torques (`torques`) plus the links' weights', N·m: `unit(i, w, j)`
    /// is link weight `i`'s (`w`'s) unit quantity's torque about joint `j` (for every joint up to
    /// its link's), read from [`Self::link_weight_basis`] or computed as it is summed.
    fn with_link_torques(
        &self,
        mut torques: Vec<f64>,
        unit: impl Fn(usize, &LinkWeight, usize) -> f64,
    ) -> Vec<f64> {
        if self.link_weights.is_empty() {
            return torques;
        }
        let mut links = vec![0.0; torques.len()];
        for (i, w) in self.link_weights.iter().enumerate() {
            // A weight at zero adds nothing, and its unit torques are not asked for: the same
            // sums to the bit (`links` starts at +0 and a sum of products never turns −0, so
            // adding ±0 leaves every entry as it is).
            if w.value == 0.0 {
                continue;
            }
            for (j, t) in links.iter_mut().enumerate().take(w.body + 1) {
                *t += w.value * unit(i, w, j);
            }
        }
        for (t, l) in torques.iter_mut().zip(links) {
            *t += l;
        }
        torques
    }

    /// The gravity torque about every joint axis (N·m) at command `q` (rad) under `load` kg that
    /// the compliances meet: the payload's, and the links' weights' when the model has them.
    pub fn load_torques(&self, robot: &Robot, q: &[f64], load: f64) -> Vec<f64> {
        self.load_torques_at(&self.pose(robot, q), load)
    }

    /// [`Self::load_torques`] at the command `pose` holds.
    fn load_torques_at(&self, pose: &PoseCache, load: f64) -> Vec<f64> {
        let torques = self.torques_at(pose, load);
        if self.link_weights.is_empty() {
            return torques;
        }
        // The links' unit torques as they are summed, without collecting the basis.
        let Pose { axes, frames, g } = pose.get();
        self.with_link_torques(torques, |_, w, j| {
            unit_torque(&axes[j], &frames[w.body], g, w.part)
        })
    }

    /// Adds backlash terms (half play 0) for `joints`, each on the flank of its approach from
    /// home reading 0.
    pub fn with_backlash(mut self, joints: &[usize]) -> Self {
        for &joint in joints {
            self.backlash.push(Backlash {
                joint,
                flank: Flank::Approach { home: 0.0 },
                value: 0.0,
            });
        }
        self
    }

    /// The gravity-torque features of `joint` at command `q` (rad) under `load` kg: for every
    /// link from the joint's outwards, the torque about its axis of a unit mass at the link
    /// frame's origin (N·m per kg) and of a unit first moment along each frame axis (N·m per
    /// kg·m) — the self-weight basis —; then the same four of the flange frame times the load
    /// (the payload's torque is the first plus its centre of mass, m, times the other three,
    /// wherever that centre lies); then 1. [`TORQUE_FEATURES_PER_LINK`] per link and as many
    /// for the payload, plus one.
    pub fn torque_features(&self, robot: &Robot, q: &[f64], load: f64, joint: usize) -> Vec<f64> {
        let pose = self.pose(robot, q);
        let Pose { axes, frames, g } = pose.get();
        torque_features_at(&axes[joint], &frames[joint..], g, load)
    }

    /// How many gravity-torque features joint `joint` (0-based) of a `dof`-joint arm has.
    pub fn torque_feature_count(dof: usize, joint: usize) -> usize {
        TORQUE_FEATURES_PER_LINK * (dof - joint + 1) + 1
    }

    /// The flank (`±1`) backlash `b` rests on at command `q` (rad) under `load` kg.
    pub fn flank(&self, b: &Backlash, robot: &Robot, q: &[f64], load: f64) -> f64 {
        match &b.flank {
            Flank::Approach { home } => side(q[b.joint] >= *home),
            Flank::Torque { weights } => {
                torque_side(weights, &self.torque_features(robot, q, load, b.joint))
            }
        }
    }

    /// The flank (`±1`) of every backlash term at command `q` (rad) under `load` kg, the arm's
    /// frames computed once for all the torque flanks.
    fn flanks(&self, pose: &PoseCache, load: f64) -> Vec<f64> {
        (self.backlash.iter())
            .map(|b| match &b.flank {
                Flank::Approach { home } => side(pose.q[b.joint] >= *home),
                Flank::Torque { weights } => {
                    let Pose { axes, frames, g } = pose.get();
                    torque_side_at(weights, &axes[b.joint], &frames[b.joint..], g, load)
                }
            })
            .collect()
    }

    /// Adds harmonics of orders `1..=orders` (coefficients 0) for `joints`.
    pub fn with_harmonics(mut self, joints: &[usize], orders: u32) -> Self {
        for &joint in joints {
            for order in 1..=orders {
                self.harmonics.push(Harmonic::zero(joint, order));
            }
        }
        self
    }

    /// Adds self-weight terms (coefficients 0) for `joints`: every link from the joint's own
    /// outwards, its mass and its three first moments.
    pub fn with_self_weight(mut self, joints: &[usize], dof: usize) -> Self {
        for &joint in joints {
            for body in joint..dof {
                for part in MomentPart::ALL {
                    self.self_weight.push(SelfWeight {
                        joint,
                        body,
                        part,
                        value: 0.0,
                    });
                }
            }
        }
        self
    }

    /// The basis value `φ` of the self-weight terms at the command `pose` holds, one entry per
    /// term: computed for each term whose coefficient is not zero or that is among `params`,
    /// 0 for the others (held at zero and not identified: most of a fit's, whose poses tell few
    /// of the links' masses and moments from the geometry), which nothing reads —
    /// [`Self::add_joint_terms`] passes over a term at zero, and [`Self::basis_into`] reads
    /// `params`' alone. (A deflection alone needs none of it: [`Self::add_joint_terms`] computes
    /// the terms not at zero as it sums them.)
    fn self_weight_basis(&self, pose: &PoseCache, params: &[ErrorParam]) -> Vec<f64> {
        if self.self_weight.is_empty() {
            return Vec::new();
        }
        let wanted = not_zero_or_identified(
            self.self_weight.iter().map(|t| t.value),
            params,
            |p| match p {
                ErrorParam::SelfWeight(i) => Some(i),
                _ => None,
            },
        );
        (self.self_weight.iter().zip(wanted))
            .map(|(t, wanted)| if wanted { t.basis_at(pose) } else { 0.0 })
            .collect()
    }

    /// For each of `params` (by position `k`), the joints it turns and its basis value there at
    /// command `q` (rad) under `load` kg, as entries `(k, joint, value)`: the coefficient's
    /// deflection of the joint per unit. Every term turns its one joint, except a link weight,
    /// which turns every joint up to its link's by the joint's compliance times its torque, and
    /// a coordinate of the payload's centre of mass, which turns every joint so.
    pub fn basis(
        &self,
        robot: &Robot,
        q: &[f64],
        load: f64,
        params: &[ErrorParam],
    ) -> Vec<(usize, usize, f64)> {
        self.basis_at(&self.pose(robot, q), load, params)
    }

    /// [`Self::basis`] at the command `pose` holds.
    fn basis_at(
        &self,
        pose: &PoseCache,
        load: f64,
        params: &[ErrorParam],
    ) -> Vec<(usize, usize, f64)> {
        let mut out = Vec::new();
        let shared = self.shared_at(pose, load, params);
        self.basis_into(pose, load, params, &shared, &mut out);
        out
    }

    /// What the deflection and the basis at the command `pose` holds under `load` kg share,
    /// each computed once: the gravity torques the compliances meet, the links' unit torques,
    /// the self-weight basis and the backlash flanks.
    fn shared_at(&self, pose: &PoseCache, load: f64, params: &[ErrorParam]) -> RowShared {
        let links = self.link_weight_basis(pose, params);
        let torques = self.with_link_torques(self.torques_at(pose, load), |i, _, j| links.of(i)[j]);
        RowShared {
            torques,
            links,
            self_weight: self.self_weight_basis(pose, params),
            flanks: self.flanks(pose, load),
        }
    }

    /// [`Self::basis`] at the command `pose` holds, from its `shared` terms, written into `out`
    /// (emptied first, its capacity kept: a fit's rows fill one buffer in turn).
    fn basis_into(
        &self,
        pose: &PoseCache,
        load: f64,
        params: &[ErrorParam],
        shared: &RowShared,
        out: &mut Vec<(usize, usize, f64)>,
    ) {
        let RowShared {
            torques,
            links,
            self_weight: sw,
            flanks,
        } = shared;
        out.clear();
        out.reserve(params.len());
        for (k, &p) in params.iter().enumerate() {
            match p {
                ErrorParam::Compliance(j) => out.push((k, j, torques[j])),
                ErrorParam::HarmonicSin(i) => {
                    out.push((k, self.harmonics[i].joint, pose.waves(self)[i].0));
                }
                ErrorParam::HarmonicCos(i) => {
                    out.push((k, self.harmonics[i].joint, pose.waves(self)[i].1));
                }
                ErrorParam::SelfWeight(i) => out.push((k, self.self_weight[i].joint, sw[i])),
                ErrorParam::Backlash(i) => out.push((k, self.backlash[i].joint, flanks[i])),
                ErrorParam::LinkWeight(i) => {
                    for (j, phi) in links.of(i).iter().enumerate() {
                        if self.values[j] != 0.0 {
                            out.push((k, j, self.values[j] * phi));
                        }
                    }
                }
                // The payload's torque per mm of its centre of mass along the flange's axis,
                // on every joint (none without a load).
                ErrorParam::PayloadCom(axis) if load != 0.0 => {
                    let Pose { axes, frames, g } = pose.get();
                    let flange = frames.last().expect("an arm has a joint");
                    let part = [MomentPart::X, MomentPart::Y, MomentPart::Z][axis];
                    for (j, axis) in axes.iter().enumerate() {
                        if self.values[j] != 0.0 {
                            let phi = load * 1e-3 * unit_torque(axis, flange, g, part);
                            out.push((k, j, self.values[j] * phi));
                        }
                    }
                }
                // A tilt or a runout turns no joint ([`Self::turn_basis_into`]), nor a coordinate
                // of the payload's centre of mass without a load.
                ErrorParam::PayloadCom(_)
                | ErrorParam::Tilt(_)
                | ErrorParam::RunoutSin(_)
                | ErrorParam::RunoutCos(_) => {}
            }
        }
    }

    /// Gravity in the world frame of `robot`, m/s².
    pub fn gravity_world(&self, robot: &Robot) -> Vector3<f64> {
        robot.base_rotation() * self.gravity
    }

    /// Gravity torque of `load` kg at the payload's centre of mass about every joint axis, N·m,
    /// at command `q` (rad).
    pub fn torques(&self, robot: &Robot, q: &[f64], load: f64) -> Vec<f64> {
        self.torques_at(&self.pose(robot, q), load)
    }

    /// [`Self::torques`] at the command `pose` holds.
    fn torques_at(&self, pose: &PoseCache, load: f64) -> Vec<f64> {
        if load == 0.0 {
            return vec![0.0; pose.q.len()];
        }
        let Pose { axes, frames, g } = pose.get();
        let (r, o) = frames.last().expect("an arm has a joint");
        let com = o + r * self.payload_com;
        let force = g * load;
        axes.iter()
            .map(|(w, a)| w.dot(&(com - a).cross(&force)) * 1e-3)
            .collect()
    }

    /// A lazily computed [`Pose`] of `robot` at command `q` (rad), for this model's gravity.
    fn pose<'a>(&self, robot: &'a Robot, q: &'a [f64]) -> PoseCache<'a> {
        self.pose_on(robot, q, None)
    }

    /// [`Self::pose`] with the bases of the model's waves at `q` given ([`Self::wave_bases`]),
    /// or computed on first use.
    fn pose_on<'a>(
        &self,
        robot: &'a Robot,
        q: &'a [f64],
        waves: Option<&'a [(f64, f64)]>,
    ) -> PoseCache<'a> {
        debug_assert!(
            waves.is_none_or(|w| w.len() == self.harmonics.len() + self.runouts.len()),
            "one basis per wave"
        );
        PoseCache {
            robot,
            q,
            g: self.gravity_world(robot),
            pose: OnceCell::new(),
            given_waves: waves,
            waves: OnceCell::new(),
        }
    }

    /// How far each joint turns from command `q` (rad) under `load` kg, rad: compliance ×
    /// torque of the payload and of the links' weights, plus the harmonics, the self-weight
    /// terms and the backlash.
    pub fn deflection(&self, robot: &Robot, q: &[f64], load: f64) -> Vec<f64> {
        self.deflection_at(&self.pose(robot, q), load)
    }

    /// [`Self::deflection`] at the command `pose` holds.
    fn deflection_at(&self, pose: &PoseCache, load: f64) -> Vec<f64> {
        self.deflection_of(
            pose,
            &self.load_torques_at(pose, load),
            &self.flanks(pose, load),
        )
    }

    /// How far each joint turns from the command `pose` holds (rad): compliance × the gravity
    /// `torques`, plus the harmonics, the self-weight terms and the backlash on its `flanks`.
    fn deflection_of(&self, pose: &PoseCache, torques: &[f64], flanks: &[f64]) -> Vec<f64> {
        let mut d: Vec<f64> = (self.values.iter().zip(torques))
            .map(|(c, t)| c * t)
            .collect();
        self.add_joint_terms(pose, None, flanks, &mut d);
        d
    }

    /// [`Self::deflection_of`] written into `d` (emptied first, its capacity kept), from the
    /// row's gravity torques, self-weight basis and flanks.
    fn deflection_into(
        &self,
        pose: &PoseCache,
        (torques, sw, flanks): (&[f64], &[f64], &[f64]),
        d: &mut Vec<f64>,
    ) {
        d.clear();
        d.extend((self.values.iter().zip(torques)).map(|(c, t)| c * t));
        self.add_joint_terms(pose, Some(sw), flanks, d);
    }

    /// Adds to the compliances' deflection `d` (rad) the harmonics at the command `pose` holds,
    /// the self-weight terms on their basis (`sw`, [`Self::self_weight_basis`]; computed here
    /// without it) and the backlash on its `flanks`.
    fn add_joint_terms(&self, pose: &PoseCache, sw: Option<&[f64]>, flanks: &[f64], d: &mut [f64]) {
        if !self.harmonics.is_empty() {
            for (h, &basis) in self.harmonics.iter().zip(pose.waves(self)) {
                d[h.joint] += h.value_on(basis);
            }
        }
        for (i, t) in self.self_weight.iter().enumerate() {
            if t.value != 0.0 {
                d[t.joint] += t.value * sw.map_or_else(|| t.basis_at(pose), |sw| sw[i]);
            } else if d[t.joint] == 0.0 && d[t.joint].is_sign_negative() {
                // A term at zero adds ±0: that leaves every sum as it is but −0, which +0 turns
                // +0 — the one case its basis (not computed: `sw` holds 0 for it) decides.
                d[t.joint] += t.value * t.basis_at(pose);
            }
        }
        for (b, s) in self.backlash.iter().zip(flanks) {
            d[b.joint] += b.value * s;
        }
    }

    /// The joint angles the arm really takes for command `q` (rad) under `load` kg, rad.
    pub fn deflected(&self, robot: &Robot, q: &[f64], load: f64) -> Vec<f64> {
        self.deflected_at(&self.pose(robot, q), load)
    }

    /// [`Self::deflected`] at the command `pose` holds.
    fn deflected_at(&self, pose: &PoseCache, load: f64) -> Vec<f64> {
        if self.holds_still(load) {
            return pose.q.to_vec();
        }
        deflected_by(pose.q, self.deflection_at(pose, load))
    }

    /// Whether no joint turns under `load` kg: no load and no term that acts without one.
    fn holds_still(&self, load: f64) -> bool {
        load == 0.0 && !self.has_configuration_terms()
    }

    /// What one row of an identification needs at command `q` (rad) under `load` kg, the arm's
    /// frames at `q` computed once for all: the joint angles the arm really takes
    /// ([`Self::deflected`]), the basis of `params` there ([`Self::basis`]), the tilting joints'
    /// turns ([`Self::turns`]) and the turns of `params` per unit.
    pub fn row_terms(
        &self,
        robot: &Robot,
        q: &[f64],
        load: f64,
        params: &[ErrorParam],
    ) -> RowTerms {
        let mut out = RowTerms::default();
        self.row_terms_into(&self.pose(robot, q), load, params, &mut out);
        out
    }

    /// [`Self::row_terms`] with the bases of the model's waves at `q` given, as
    /// [`Self::wave_bases`] computes them (the same terms to the bit; none computed again).
    pub fn row_terms_on_waves(
        &self,
        robot: &Robot,
        q: &[f64],
        load: f64,
        params: &[ErrorParam],
        waves: &[(f64, f64)],
    ) -> RowTerms {
        let mut out = RowTerms::default();
        self.write_row_terms(robot, q, load, params, Some(waves), &mut out);
        out
    }

    /// [`Self::row_terms`] (with the bases of the model's waves at `q` given, as
    /// [`Self::row_terms_on_waves`], or computed) written into `out`, whose vectors are emptied
    /// and filled again, their capacity kept: a fit's rows, one after the other, allocate none
    /// of them again. The same terms to the bit.
    pub fn write_row_terms(
        &self,
        robot: &Robot,
        q: &[f64],
        load: f64,
        params: &[ErrorParam],
        waves: Option<&[(f64, f64)]>,
        out: &mut RowTerms,
    ) {
        self.row_terms_into(&self.pose_on(robot, q, waves), load, params, out);
    }

    /// [`Self::row_terms`] at the command `pose` holds, written into `out`.
    fn row_terms_into(
        &self,
        pose: &PoseCache,
        load: f64,
        params: &[ErrorParam],
        out: &mut RowTerms,
    ) {
        let q = pose.q;
        let shared = self.shared_at(pose, load, params);
        if self.holds_still(load) {
            out.deflected.clear();
            out.deflected.extend_from_slice(q);
        } else {
            let RowShared {
                torques,
                self_weight,
                flanks,
                ..
            } = &shared;
            self.deflection_into(pose, (torques, self_weight, flanks), &mut out.deflected);
            deflect(q, &mut out.deflected);
        }
        self.basis_into(pose, load, params, &shared, &mut out.basis);
        self.turns_into(pose, load, &mut out.turns);
        self.turn_basis_into(pose, load, params, &mut out.turn_basis);
    }

    /// How each joint's deflection at command `q` (rad) under `load` kg changes with the
    /// table's parameters, through the gravity torques it holds ([`DeflectionRates`]): the
    /// payload's and the links' weights' times the joint's compliance, and the self-weight
    /// terms. The harmonics and the backlash (a flank is constant between its switches) do not
    /// move with the table.
    pub fn deflection_rates(&self, robot: &Robot, q: &[f64], load: f64) -> DeflectionRates {
        let compliant = self.values.iter().any(|&c| c != 0.0);
        if !compliant && self.self_weight.is_empty() {
            return Vec::new();
        }
        let pose = self.pose(robot, q);
        let Pose { axes, frames, g } = pose.get();
        let dof = axes.len();
        let zero = (Vector3::zeros(), Vector3::zeros());
        let mut out = vec![vec![zero; dof]; dof];
        for (j, row) in out.iter_mut().enumerate() {
            // Every torque term joint `j` deflects by: (its link, quantity, coefficient).
            let mut terms: Vec<(usize, Quantity, f64)> = Vec::new();
            let c = self.values[j];
            if c != 0.0 {
                if load != 0.0 {
                    let (r, o) = frames.last().expect("an arm has a joint");
                    let com = o + r * self.payload_com;
                    terms.push((dof - 1, Quantity::Point(com), c * load));
                }
                for lw in self.link_weights.iter().filter(|lw| lw.body >= j) {
                    let quantity = Quantity::of(&frames[lw.body], lw.part);
                    terms.push((lw.body, quantity, c * lw.value));
                }
            }
            for t in self.self_weight.iter().filter(|t| t.joint == j) {
                terms.push((t.body, Quantity::of(&frames[t.body], t.part), t.value));
            }
            if terms.is_empty() {
                continue;
            }
            // A parameter of joint `k <= j` moves the axis and every term together; one of
            // `k > j` moves the terms on links `k` and beyond alone.
            let mut together = Vector3::zeros();
            let mut alone = vec![zero; dof];
            for (body, quantity, coefficient) in terms {
                let (t, (aw, av)) = quantity.rates(&axes[j], g);
                together += t * coefficient;
                alone[body].0 += aw * coefficient;
                alone[body].1 += av * coefficient;
            }
            for entry in row.iter_mut().take(j + 1) {
                *entry = (together, Vector3::zeros());
            }
            let mut from = zero;
            for k in (j + 1..dof).rev() {
                from.0 += alone[k].0;
                from.1 += alone[k].1;
                row[k] = from;
            }
        }
        out
    }

    /// Jacobian of the point with respect to each of `params` (mm per internal unit), and the
    /// point, at command `q` under `load`: column `k` is the sum, over the joints the coefficient
    /// turns, of the joint Jacobian's column at the deflected angles times its basis value there,
    /// plus, over the tilting joints it turns the parts beyond, `t × (p − a)` (`t` its turn per
    /// unit, `a` the joint's origin; the tilts' and runouts' own effect on the other columns,
    /// micro-radians times the column, is left out).
    pub fn param_jacobian(
        &self,
        robot: &Robot,
        q: &[f64],
        load: f64,
        params: &[ErrorParam],
    ) -> (Vector3<f64>, Matrix3xX<f64>) {
        let row = self.row_terms(robot, q, load, params);
        let joint = robot.joint_jacobian(&row.deflected);
        let p = robot.point(&row.deflected);
        let mut jac = Matrix3xX::zeros(params.len());
        for (k, j, phi) in row.basis {
            let mut column = jac.column_mut(k);
            column += joint.column(j) * phi;
        }
        for (k, a, t) in row.turn_basis {
            let mut column = jac.column_mut(k);
            column += t.cross(&(p - a));
        }
        (turned(&row.turns, p), jac)
    }

    /// Jacobian of the tool frame's orientation with respect to each of `params` (rad per
    /// internal unit, world-frame rotation vectors), and the tool frame's rotation, at command
    /// `q` under `load`: column `k` is the sum, over the joints the coefficient turns, of the
    /// joint's axis at the deflected angles times its basis value there, plus its turns per unit
    /// of the tilting joints.
    pub fn orientation_param_jacobian(
        &self,
        robot: &Robot,
        q: &[f64],
        load: f64,
        params: &[ErrorParam],
    ) -> (Matrix3<f64>, Matrix3xX<f64>) {
        let row = self.row_terms(robot, q, load, params);
        let axes = robot.joint_axes(&row.deflected);
        let mut jac = Matrix3xX::zeros(params.len());
        for (k, j, phi) in row.basis {
            let mut column = jac.column_mut(k);
            column += axes.axes[j].0 * phi;
        }
        for (k, _, t) in row.turn_basis {
            let mut column = jac.column_mut(k);
            column += t;
        }
        (
            turn_rotation(&row.turns) * axes.flange_rotation * robot.tool_frame_rotation(),
            jac,
        )
    }

    /// The tool frame's orientation for command `q` (rad) under `load` kg, world frame.
    pub fn rotation(&self, robot: &Robot, q: &[f64], load: f64) -> Matrix3<f64> {
        let pose = self.pose(robot, q);
        let r = robot.tool_rotation(&self.deflected_at(&pose, load));
        if !self.has_turns() {
            return r;
        }
        turn_rotation(&self.turns_at(&pose, load)) * r
    }

    /// The model's target point for command `q` (rad) under `load` kg, mm, world frame.
    pub fn point(&self, robot: &Robot, q: &[f64], load: f64) -> Vector3<f64> {
        self.point_at(&self.pose(robot, q), load)
    }

    /// [`Self::point`] with the bases of the model's waves at `q` given, as [`Self::wave_bases`]
    /// computes them (the same point to the bit; none computed again).
    pub fn point_on_waves(
        &self,
        robot: &Robot,
        q: &[f64],
        load: f64,
        waves: &[(f64, f64)],
    ) -> Vector3<f64> {
        self.point_at(&self.pose_on(robot, q, Some(waves)), load)
    }

    /// [`Self::point`] at the command `pose` holds.
    fn point_at(&self, pose: &PoseCache, load: f64) -> Vector3<f64> {
        let p = pose.robot.point(&self.deflected_at(pose, load));
        if !self.has_turns() {
            return p;
        }
        turned_by(self.each_turn(pose, load), p)
    }

    /// Jacobian of the point with respect to each joint's compliance (mm per rad/(N·m)), and
    /// the point, at command `q` under `load`: column `i` is the joint Jacobian's column at the
    /// deflected angles times the torque on joint `i`.
    pub fn jacobian(&self, robot: &Robot, q: &[f64], load: f64) -> (Vector3<f64>, Matrix3xX<f64>) {
        let every: Vec<ErrorParam> = (0..self.values.len()).map(ErrorParam::Compliance).collect();
        self.param_jacobian(robot, q, load, &every)
    }

    /// Parses `compliance.toml` for a robot with `dof` joints.
    pub fn from_toml_str(text: &str, path: impl AsRef<Path>, dof: usize) -> Result<Self> {
        let path = path.as_ref();
        let raw: RawCompliance = toml::from_str(text).map_err(|e| toml_error(path, text, &e))?;
        let invalid = |key: &str, message: String| RobotError::InvalidValue {
            path: path.to_path_buf(),
            key: key.into(),
            message,
        };
        if raw.compliance.len() != dof {
            return Err(invalid(
                "compliance",
                format!(
                    "{} values for a robot with {dof} joints",
                    raw.compliance.len()
                ),
            ));
        }
        for (key, values) in [
            ("gravity", &raw.gravity[..]),
            ("payload_com", &raw.payload_com[..]),
            ("compliance", &raw.compliance[..]),
        ] {
            if values.iter().any(|v| !v.is_finite()) {
                return Err(invalid(key, "every value must be a finite number".into()));
            }
        }
        if raw.gravity.iter().all(|g| *g == 0.0) {
            return Err(invalid("gravity", "must not be zero".into()));
        }
        // Entry `key`'s joint (counted from 1) as 0-based, when the robot has it.
        let joint_of = |key: &str, joint: usize| -> Result<usize> {
            if (1..=dof).contains(&joint) {
                Ok(joint - 1)
            } else {
                Err(invalid(
                    key,
                    format!("joint {joint} of a robot with {dof} joints"),
                ))
            }
        };
        // A term a joint may have once: refused for `joint` (0-based) when it has one `already`.
        let once = |key: &str, joint: usize, already: bool, what: &str| -> Result<()> {
            if !already {
                Ok(())
            } else {
                Err(invalid(
                    key,
                    format!("joint {} has {what} already", joint + 1),
                ))
            }
        };
        // A harmonic (a transmission error's, or a runout's wave) as written, checked.
        let wave = |key: &str, h: &RawHarmonic| -> Result<Harmonic> {
            let joint = joint_of(key, h.joint)?;
            if !(1..=MAX_HARMONIC_ORDER).contains(&h.order) {
                return Err(invalid(
                    key,
                    format!("order must lie in 1..={MAX_HARMONIC_ORDER}"),
                ));
            }
            if !(h.sin.is_finite() && h.cos.is_finite()) {
                return Err(invalid(key, "sin and cos must be finite numbers".into()));
            }
            if let Some([lo, hi]) = h.reach
                && !(lo.is_finite() && hi.is_finite() && lo <= hi)
            {
                return Err(invalid(
                    &format!("{key}.reach"),
                    format!(
                        "[{lo}, {hi}]: two finite angles (deg), the first not above the second"
                    ),
                ));
            }
            Ok(Harmonic {
                joint,
                order: h.order,
                sin: h.sin.to_radians(),
                cos: h.cos.to_radians(),
                reach: h.reach.map(|r| r.map(f64::to_radians)),
            })
        };
        let harmonics = (raw.harmonic.iter().enumerate())
            .map(|(i, h)| wave(&format!("harmonic[{}]", i + 1), h))
            .collect::<Result<Vec<_>>>()?;
        let mut runouts: Vec<Runout> = Vec::with_capacity(raw.runout.len());
        for (i, r) in raw.runout.iter().enumerate() {
            let key = format!("runout[{}]", i + 1);
            let h = RawHarmonic {
                joint: r.joint,
                order: r.order,
                sin: r.sin,
                cos: r.cos,
                reach: r.reach,
            };
            let wave = wave(&key, &h)?;
            if (runouts.iter()).any(|o| {
                (o.wave.joint, o.wave.order, o.across) == (wave.joint, wave.order, r.across)
            }) {
                return Err(invalid(
                    &key,
                    format!(
                        "joint {} has a runout of order {} about {} already",
                        r.joint,
                        r.order,
                        r.across.name()
                    ),
                ));
            }
            runouts.push(Runout {
                across: r.across,
                wave,
            });
        }
        let mut self_weight = Vec::with_capacity(raw.self_weight.len());
        for (i, t) in raw.self_weight.iter().enumerate() {
            let key = format!("self_weight[{}]", i + 1);
            if !(1..=dof).contains(&t.joint) || !(t.joint..=dof).contains(&t.body) {
                return Err(invalid(
                    &key,
                    format!(
                        "joint {} and body {}: both 1..={dof}, the body at or beyond the joint",
                        t.joint, t.body
                    ),
                ));
            }
            if !t.value.is_finite() {
                return Err(invalid(&key, "value must be a finite number".into()));
            }
            self_weight.push(SelfWeight {
                joint: t.joint - 1,
                body: t.body - 1,
                part: t.part,
                value: t.value.to_radians(),
            });
        }
        let mut backlash: Vec<Backlash> = Vec::with_capacity(raw.backlash.len());
        for (i, b) in raw.backlash.iter().enumerate() {
            let key = format!("backlash[{}]", i + 1);
            let joint = joint_of(&key, b.joint)?;
            once(
                &key,
                joint,
                backlash.iter().any(|b| b.joint == joint),
                "a backlash term",
            )?;
            if !b.value.is_finite() {
                return Err(invalid(&key, "value must be a finite number".into()));
            }
            let features = Self::torque_feature_count(dof, joint);
            let flank = match (b.home, &b.torque) {
                (Some(home), None) if home.is_finite() => Flank::Approach {
                    home: home.to_radians(),
                },
                (None, Some(w)) if w.len() == features && w.iter().all(|w| w.is_finite()) => {
                    Flank::Torque { weights: w.clone() }
                }
                (Some(_), None) => {
                    return Err(invalid(&key, "home must be a finite number (deg)".into()));
                }
                (None, Some(w)) => {
                    return Err(invalid(
                        &key,
                        format!(
                            "torque lists {} weights: joint {} of a robot with {dof} joints has {features} finite ones (4 per link from the joint's outwards, 4 for the payload, the preload's)",
                            w.len(),
                            b.joint
                        ),
                    ));
                }
                _ => {
                    return Err(invalid(
                        &key,
                        "give home (the flank of the approach from home) or torque (the flank the torque presses), one of them".into(),
                    ));
                }
            };
            backlash.push(Backlash {
                joint,
                flank,
                value: b.value.to_radians(),
            });
        }
        let mut link_weights = Vec::with_capacity(raw.link_weight.len());
        for (i, w) in raw.link_weight.iter().enumerate() {
            let key = format!("link_weight[{}]", i + 1);
            if !(1..=dof).contains(&w.body) {
                return Err(invalid(
                    &key,
                    format!("body {} of a robot with {dof} links", w.body),
                ));
            }
            if !w.value.is_finite() {
                return Err(invalid(&key, "value must be a finite number".into()));
            }
            link_weights.push(LinkWeight {
                body: w.body - 1,
                part: w.part,
                value: w.value,
            });
        }
        let mut tilts: Vec<Tilt> = Vec::with_capacity(raw.tilt.len());
        for (i, t) in raw.tilt.iter().enumerate() {
            let key = format!("tilt[{}]", i + 1);
            let joint = joint_of(&key, t.joint)?;
            once(
                &key,
                joint,
                tilts.iter().any(|t| t.joint == joint),
                "a tilting compliance",
            )?;
            if !t.compliance.is_finite() {
                return Err(invalid(&key, "compliance must be a finite number".into()));
            }
            tilts.push(Tilt {
                joint,
                value: t.compliance * DEG_PER_KNM,
            });
        }
        Ok(Self {
            values: raw.compliance.iter().map(|c| c * DEG_PER_KNM).collect(),
            gravity: Vector3::from(raw.gravity),
            payload_com: Vector3::from(raw.payload_com),
            harmonics,
            self_weight,
            backlash,
            link_weights,
            tilts,
            runouts,
        })
    }

    /// Reads `compliance.toml` for a robot with `dof` joints.
    pub fn load(path: impl AsRef<Path>, dof: usize) -> Result<Self> {
        let path = path.as_ref();
        let text = std::fs::read_to_string(path).map_err(|source| RobotError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        Self::from_toml_str(&text, path, dof)
    }

    /// The file form, with a header saying what the numbers mean.
    pub fn to_toml_string(&self) -> String {
        // Every number as the one that reads back exactly (the loader's conversions inverted).
        let deg = |v: f64| file_value(v, f64::to_degrees, f64::to_radians);
        let knm = |c: f64| file_value(c, |c| c / DEG_PER_KNM, |c| c * DEG_PER_KNM);
        let raw = RawCompliance {
            gravity: self.gravity.into(),
            payload_com: self.payload_com.into(),
            compliance: self.values.iter().map(|&c| knm(c)).collect(),
            harmonic: (self.harmonics.iter())
                .map(|h| RawHarmonic {
                    joint: h.joint + 1,
                    order: h.order,
                    sin: deg(h.sin),
                    cos: deg(h.cos),
                    reach: h.reach.map(|r| r.map(deg)),
                })
                .collect(),
            self_weight: (self.self_weight.iter())
                .map(|t| RawSelfWeight {
                    joint: t.joint + 1,
                    body: t.body + 1,
                    part: t.part,
                    value: deg(t.value),
                })
                .collect(),
            backlash: (self.backlash.iter())
                .map(|b| RawBacklash {
                    joint: b.joint + 1,
                    home: b.home().map(deg),
                    torque: match &b.flank {
                        Flank::Torque { weights } => Some(weights.clone()),
                        Flank::Approach { .. } => None,
                    },
                    value: deg(b.value),
                })
                .collect(),
            link_weight: (self.link_weights.iter())
                .map(|w| RawLinkWeight {
                    body: w.body + 1,
                    part: w.part,
                    value: w.value,
                })
                .collect(),
            tilt: (self.tilts.iter())
                .map(|t| RawTilt {
                    joint: t.joint + 1,
                    compliance: knm(t.value),
                })
                .collect(),
            runout: (self.runouts.iter())
                .map(|r| RawRunout {
                    joint: r.wave.joint + 1,
                    order: r.wave.order,
                    across: r.across,
                    sin: deg(r.wave.sin),
                    cos: deg(r.wave.cos),
                    reach: r.wave.reach.map(|v| v.map(deg)),
                })
                .collect(),
        };
        let body = toml::to_string(&raw).unwrap_or_default();
        let more = if self.has_configuration_terms() {
            "# harmonic: transmission error of a joint, sin · sin(order q) + cos · cos(order q), deg;\n\
             # reach = [lo, hi] (deg): beyond it, q is held at the nearer end (the readings it was\n\
             # identified on, widened by a quarter of their span at each end); without a reach the\n\
             # harmonic is continued at every angle.\n\
             # self_weight: value (deg per unit) × the gravity torque about the joint of a unit mass\n\
             # (part = mass, N·m per kg) or first moment (x, y, z: N·m per kg·m) of link `body`.\n\
             # backlash: the joint rests on one flank of its play, error +value (deg, half the\n\
             # play) on one, -value on the other: with `home` (deg), the flank of its approach\n\
             # from home (+ at or above it); with `torque`, the flank its torque presses (+ where\n\
             # the weights times the features are at least 0: for each link from the joint's\n\
             # outwards the gravity torques of a unit mass at its frame's origin and of unit first\n\
             # moments along x, y, z, then the same of the flange frame times the load, then 1).\n\
             # link_weight: the weight of link `body` shared by every joint up to it: its mass\n\
             # (part = mass, kg, at the link frame's origin) or first moment (x, y, z: kg·m along\n\
             # the link frame's axes); each joint deflects by its compliance × the gravity torque\n\
             # of the payload and of these weights.\n"
        } else {
            ""
        };
        let tilt = if self.tilts.is_empty() {
            ""
        } else {
            "# tilt: the parts beyond the joint turn about its origin, across its axis, by\n\
             # compliance (deg per kN·m) × the gravity moment across the axis of the payload and\n\
             # of the link weights beyond it.\n"
        };
        let runout = if self.runouts.is_empty() {
            ""
        } else {
            "# runout: the parts beyond the joint turn about its origin, across its axis, by\n\
             # sin · sin(order q) + cos · cos(order q) (deg) about the axis `across` (x or y) of\n\
             # the joint's link frame, which turns with the joint; reach as a harmonic's.\n"
        };
        format!(
            "# Joint compliance under the payload, identified by robocal: joint deflection =\n\
             # compliance × gravity torque of the payload (deg per kN·m, one per joint; 0 = rigid).\n\
             # gravity: m/s² in the robot base frame {{0}}; payload_com: mm in the flange frame.\n{more}{tilt}{runout}{body}"
        )
    }
}
