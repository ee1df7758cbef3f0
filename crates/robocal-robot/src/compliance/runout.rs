//! Axis runout: the parts beyond a joint turn across its axis by harmonics of its angle.

use nalgebra::Vector3;
use serde::{Deserialize, Serialize};

use super::harmonic::Harmonic;
use crate::kinematics::Frame;

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

/// The name of a runout coefficient: `j1.r2y.cos` (joint 0-based here).
pub fn runout_name(joint: usize, order: u32, across: Across, cos: bool) -> String {
    let which = if cos { "cos" } else { "sin" };
    format!("j{}.r{order}{}.{which}", joint + 1, across.name())
}
