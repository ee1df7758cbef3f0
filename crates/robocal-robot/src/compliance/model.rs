//! The joint-error model: its coefficients by effect, the unknowns an identification sees
//! (`ErrorParam`), their names, and the terms each effect adds.

use nalgebra::{Matrix3, Vector3};

use super::backlash::{Backlash, Flank, backlash_name};
use super::gravity::{MomentPart, TORQUE_FEATURES_PER_LINK};
use super::harmonic::{Harmonic, harmonic_name};
use super::payload::{compliance_name, payload_com_name};
use super::runout::{Across, Runout, runout_name};
use super::self_weight::{LinkWeight, SelfWeight, link_weight_name, self_weight_name};
use super::tilt::{Tilt, tilt_name};
use crate::table::Robot;

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

/// `p` (mm) moved by `turns`, to first order (the turns are micro-radians): `p + Σ t × (p − a)`.
pub fn turned(turns: &[(Vector3<f64>, Vector3<f64>)], p: Vector3<f64>) -> Vector3<f64> {
    turned_by(turns.iter().copied(), p)
}

/// [`turned`] by turns as they come, none collected.
pub(super) fn turned_by(
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

    /// How many gravity-torque features joint `joint` (0-based) of a `dof`-joint arm has.
    pub fn torque_feature_count(dof: usize, joint: usize) -> usize {
        TORQUE_FEATURES_PER_LINK * (dof - joint + 1) + 1
    }

    /// Gravity in the world frame of `robot`, m/s².
    pub fn gravity_world(&self, robot: &Robot) -> Vector3<f64> {
        robot.base_rotation() * self.gravity
    }
}
