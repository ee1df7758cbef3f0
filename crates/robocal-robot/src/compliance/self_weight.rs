//! Self-weight compliance: the joints deflect under the gravity torque of the links beyond them,
//! as per-joint coefficients ([`SelfWeight`]) or as the links' weights shared by every joint
//! ([`LinkWeight`]).

use serde::{Deserialize, Serialize};

use super::gravity::{Pose, PoseCache, not_zero_or_identified, unit_torque};
use super::{ErrorParam, JointErrors};

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
    pub(super) fn basis_at(&self, pose: &PoseCache) -> f64 {
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

impl JointErrors {
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
    pub(super) fn link_weight_basis(&self, pose: &PoseCache, params: &[ErrorParam]) -> LinkUnits {
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
    pub(super) fn with_link_torques(
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
    pub(super) fn self_weight_basis(&self, pose: &PoseCache, params: &[ErrorParam]) -> Vec<f64> {
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
}
