//! Gravity's torques and moments on the arm at one command: the joint axes and link frames every
//! gravity term reads, computed once per row, and the torque of a unit mass or first moment of a
//! link about a joint.

use nalgebra::{Matrix3, Vector3};
use serde::{Deserialize, Serialize};

use crate::kinematics::{Axis, Frame};

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

/// One link quantity a gravity torque acts through: a point (mm) that holds a mass, or a
/// direction along which a first moment lies.
#[derive(Clone, Copy)]
pub(super) enum Quantity {
    Point(Vector3<f64>),
    Direction(Vector3<f64>),
}

impl Quantity {
    /// `part` of the link whose frame is `(r, o)`.
    pub(super) fn of((r, o): &(Matrix3<f64>, Vector3<f64>), part: MomentPart) -> Self {
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
    pub(super) fn rates(
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

/// What every gravity term reads at one command: each joint's axis (unit, and a point on it,
/// mm), every link frame {1}..{n} (the last is the flange's) and gravity (m/s²), world frame.
pub(super) struct Pose<'a> {
    pub(super) axes: &'a [Axis],
    pub(super) frames: &'a [Frame],
    pub(super) g: &'a Vector3<f64>,
}

/// The gravity moment (N·m per unit, world frame) about the point `a` (mm) of the unit quantity
/// `part` of the link whose frame is `(r, o)`, gravity `g` (m/s²): the vector whose component
/// along an axis through `a` is [`unit_torque`].
pub(super) fn unit_moment(
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
pub(super) fn across(w: &Vector3<f64>, m: Vector3<f64>) -> Vector3<f64> {
    m - w * w.dot(&m)
}

/// The gravity torque (N·m per unit) about the joint axis `(w, a)` (unit vector, point, mm) of
/// the unit quantity `part` of the link whose frame is `(r, o)`, gravity `g` (m/s²): `w ·`
/// [`unit_moment`], kept in its own order of operations so that the torques, and every model
/// identified before the tilts, stay the same to the last bit.
pub(super) fn unit_torque(
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
pub(super) fn torque_features_at(
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
pub(super) fn visit_torque_features(
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

/// Gravity-torque features per link (and for the payload): a unit mass and three unit first
/// moments.
pub const TORQUE_FEATURES_PER_LINK: usize = 4;
