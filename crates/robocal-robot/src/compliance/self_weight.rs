//! Self-weight compliance: the joints deflect under the gravity torque of the links beyond them,
//! as per-joint coefficients ([`SelfWeight`]) or as the links' weights shared by every joint
//! ([`LinkWeight`]).

use super::gravity::{MomentPart, Pose, unit_torque};

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
    /// Its basis value `φ` at the command `pose` is of: the gravity torque about its joint's axis
    /// of its link's unit quantity.
    pub(super) fn basis_at(&self, pose: &Pose) -> f64 {
        let Pose { axes, frames, g } = *pose;
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

/// Each link weight's unit torque about every joint up to its link's, one after the other in
/// one buffer ([`JointErrors::link_weights`] order).
pub(super) struct LinkUnits {
    pub(super) values: Vec<f64>,
    /// Where each weight's torques end in `values`.
    pub(super) ends: Vec<usize>,
}

impl LinkUnits {
    /// Link weight `i`'s unit torques (entry `j` for joint `j`).
    pub(super) fn of(&self, i: usize) -> &[f64] {
        let start = if i == 0 { 0 } else { self.ends[i - 1] };
        &self.values[start..self.ends[i]]
    }
}

/// The name of a self-weight coefficient: `j2.sw4.mass` (joint and link 0-based here).
pub fn self_weight_name(joint: usize, body: usize, part: MomentPart) -> String {
    format!("j{}.sw{}.{}", joint + 1, body + 1, part.name())
}

/// The name of a shared link weight: `link3.mass`, `link3.x` (link 0-based here).
pub fn link_weight_name(body: usize, part: MomentPart) -> String {
    format!("link{}.{}", body + 1, part.name())
}
