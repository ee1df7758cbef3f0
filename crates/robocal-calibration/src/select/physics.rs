//! The physics of a candidate: the effects it holds beside the table, the name and the
//! identification settings they give, and the model they make.

use super::settings::AutoSettings;
use crate::fit::physical_model;
use robocal_ident::{
    ComplianceSettings, JointErrorSettings, KinematicCalibration, KinematicSettings,
};
use robocal_model::CalibratedModel;

/// The physical part of a candidate.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Physics {
    /// Only base and tool fitted to the nominal table.
    pub(super) aligned: bool,
    /// Joint compliances under the payload.
    pub(super) compliance: bool,
    /// Transmission harmonics up to this order.
    pub(super) harmonics: u32,
    /// Self-weight terms.
    pub(super) self_weight: bool,
    /// Backlash (each joint on the flank of its approach from home or on the one its torque
    /// presses).
    pub(super) backlash: bool,
    /// Tilting compliances.
    pub(super) tilt: bool,
    /// Axis runouts up to this order.
    pub(super) runout: u32,
    /// The axis runouts started from the model without them (its first fit's compliances and
    /// its flanks, which the candidates before made): the cheaper fit the chain tries where the
    /// budget cut the runouts' own (`JointErrorSettings::runout_from_without`).
    pub(super) runout_from_without: bool,
    /// Backlash flanks by the search beyond the joint's own terms (`flank_search`).
    pub(super) flank_search: bool,
}

impl Physics {
    pub(super) const ALIGNED: Self = Self {
        aligned: true,
        compliance: false,
        harmonics: 0,
        self_weight: false,
        backlash: false,
        tilt: false,
        runout: 0,
        runout_from_without: false,
        flank_search: false,
    };
    pub(super) const RIGID: Self = Self {
        aligned: false,
        ..Self::ALIGNED
    };

    pub(super) fn name(self) -> String {
        if self.aligned {
            return "nominal (base and tool fitted)".into();
        }
        let mut name = String::from("kinematic");
        if self.compliance {
            name += " + compliance";
        }
        if self.harmonics > 0 {
            name += &format!(" + harmonics {}", self.harmonics);
        }
        if self.self_weight {
            name += " + self-weight";
        }
        if self.backlash {
            name += " + backlash";
            if self.flank_search {
                name += " (flank search)";
            }
        }
        if self.runout > 0 {
            name += &format!(" + runout {}", self.runout);
            if self.runout_from_without {
                name += " (from the fit without)";
            }
        }
        if self.tilt {
            name += " + tilt";
        }
        name
    }

    /// Whether it holds any of the joint-error blocks of the stepwise selection.
    pub(super) fn has_blocks(self) -> bool {
        self.harmonics > 0 || self.self_weight || self.backlash
    }

    /// Whether it holds any joint-error term (a block, the runouts or the tilts).
    pub(super) fn has_joint_errors(self) -> bool {
        self.has_blocks() || self.tilt || self.runout > 0
    }

    /// Every block of `self` and of `other`.
    pub(super) fn union(self, other: Self) -> Self {
        Self {
            harmonics: self.harmonics.max(other.harmonics),
            self_weight: self.self_weight || other.self_weight,
            backlash: self.backlash || other.backlash,
            tilt: self.tilt || other.tilt,
            runout: self.runout.max(other.runout),
            runout_from_without: self.runout_from_without || other.runout_from_without,
            flank_search: self.flank_search || other.flank_search,
            ..self
        }
    }

    /// Its joint-error terms in words, e.g. `transmission harmonics (orders 1 to 2) identified
    /// with the geometry`.
    pub(super) fn joint_error_terms(self) -> String {
        let mut parts = Vec::new();
        if self.harmonics > 0 {
            parts.push(format!(
                "transmission harmonics (orders 1 to {})",
                self.harmonics
            ));
        }
        if self.self_weight && self.compliance {
            parts.push("the links' weights and the payload's centre of mass (each joint deflecting by its compliance under their torques)".to_string());
        } else if self.self_weight {
            parts.push("self-weight terms".to_string());
        }
        if self.backlash {
            parts.push("backlash (each joint on the flank of its approach from home or on the one its torque presses)".to_string());
        }
        if self.runout > 0 {
            parts.push(format!(
                "axis runouts ({}: the parts beyond each joint turning across its axis periodically in its angle)",
                orders_words(self.runout)
            ));
        }
        if self.tilt {
            parts.push("tilting compliances (the parts beyond each joint turning across its axis under the gravity moment there)".to_string());
        }
        let parts = match parts.split_last() {
            Some((last, rest)) if !rest.is_empty() => format!("{} and {last}", rest.join(", ")),
            _ => parts.concat(),
        };
        format!("{parts} identified with the geometry")
    }

    /// The kinematic settings of this physics, with `auto`'s 6-DoF probe `angle_weight` (mm per
    /// deg; `None`: the default) and gravity (`None`: the base's −z, the tracker's tried where
    /// the base is far from upright).
    pub(super) fn settings(self, auto: &AutoSettings) -> KinematicSettings {
        let gravity = auto
            .gravity
            .unwrap_or(ComplianceSettings::default().gravity);
        KinematicSettings {
            angle_weight: auto.angle_weight,
            // The payload's centre of mass is rarely known to the millimetre: identified with
            // the links' weights (the mass properties the compliances meet; both after a first
            // fit that gives the compliances they start from).
            compliance: self.compliance.then(|| ComplianceSettings {
                gravity,
                plausible_only: true,
                detect_mounting: auto.gravity.is_none(),
                identify_payload_com: self.self_weight,
                ..ComplianceSettings::default()
            }),
            // With the compliances identified, the deflection under the links' own weight is
            // theirs too: the links' weights shared by the joints (a few masses and moments)
            // rather than a coefficient per joint and link, which the poses determine less
            // well and which extrapolate worse.
            joint_errors: self.has_joint_errors().then(|| JointErrorSettings {
                harmonics: self.harmonics,
                self_weight: self.self_weight && !self.compliance,
                link_weights: self.self_weight && self.compliance,
                backlash: self.backlash,
                flank_search: self.flank_search,
                tilt: self.tilt,
                runout: self.runout,
                runout_from_without: self.runout_from_without,
                gravity,
                ..JointErrorSettings::default()
            }),
            ..KinematicSettings::default()
        }
    }

    /// The model of this physics from the identification that made it.
    pub(super) fn model(self, fit: &KinematicCalibration) -> CalibratedModel {
        if self.aligned {
            CalibratedModel::kinematic(fit.aligned.clone())
        } else {
            physical_model(fit)
        }
    }
}

/// `order 1`, or `orders 1 to N`.
pub(super) fn orders_words(orders: u32) -> String {
    if orders == 1 {
        "order 1".into()
    } else {
        format!("orders 1 to {orders}")
    }
}
