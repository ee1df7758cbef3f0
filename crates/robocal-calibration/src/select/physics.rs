//! The physics of a candidate: the effects it holds beside the table, the name and the
//! identification settings they give, and the model they make.

use super::settings::AutoSettings;
use crate::fit::physical_model;
use robocal_ident::{
    ComplianceSettings, JointErrorSettings, KinematicCalibration, KinematicSettings,
};
use robocal_model::CalibratedModel;

/// One effect a candidate's physics holds beside the identified table.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Effect {
    /// Joint compliances under the payload.
    Compliance,
    /// Transmission harmonics of orders 1 to this one.
    Harmonics(u32),
    /// Self-weight terms (with the compliances: the links' weights they meet).
    SelfWeight,
    /// Backlash (each joint on the flank of its approach from home or on the one its torque
    /// presses).
    Backlash,
    /// Backlash flanks by the search beyond the joint's own terms (`flank_search`).
    FlankSearch,
    /// Axis runouts of orders 1 to this one.
    Runout(u32),
    /// The axis runouts started from the model without them (its first fit's compliances and
    /// its flanks, which the candidates before made): the cheaper fit the chain tries where the
    /// budget cut the runouts' own (`JointErrorSettings::runout_from_without`).
    RunoutFromWithout,
    /// Tilting compliances.
    Tilt,
}

impl Effect {
    /// How many kinds of effect there are.
    const KINDS: usize = 8;

    /// Its kind's place among a physics' effects: the order of a candidate's name.
    fn slot(self) -> usize {
        match self {
            Self::Compliance => 0,
            Self::Harmonics(_) => 1,
            Self::SelfWeight => 2,
            Self::Backlash => 3,
            Self::FlankSearch => 4,
            Self::Runout(_) => 5,
            Self::RunoutFromWithout => 6,
            Self::Tilt => 7,
        }
    }

    /// This effect and `other` of the same kind together: the higher order of two.
    fn with(self, other: Self) -> Self {
        match (self, other) {
            (Self::Harmonics(a), Self::Harmonics(b)) => Self::Harmonics(a.max(b)),
            (Self::Runout(a), Self::Runout(b)) => Self::Runout(a.max(b)),
            _ => self,
        }
    }

    /// Whether it adds joint-error terms of its own (the flank search and the runouts' start
    /// only change how the backlash and the runouts are fitted).
    fn adds_terms(self) -> bool {
        !matches!(
            self,
            Self::Compliance | Self::FlankSearch | Self::RunoutFromWithout
        )
    }
}

/// The physical part of a candidate: the nominal table with base and tool fitted, or the
/// identified table with a set of effects (each kind at most once).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Physics {
    /// Only base and tool fitted to the nominal table (no effect).
    pub(super) aligned: bool,
    /// Each kind of effect in its slot ([`Effect::slot`]).
    effects: [Option<Effect>; Effect::KINDS],
}

impl Physics {
    pub(super) const ALIGNED: Self = Self {
        aligned: true,
        effects: [None; Effect::KINDS],
    };
    pub(super) const RIGID: Self = Self {
        aligned: false,
        ..Self::ALIGNED
    };

    /// This physics with `effect` (in place of any of its kind).
    pub(super) fn with(mut self, effect: Effect) -> Self {
        self.effects[effect.slot()] = Some(effect);
        self
    }

    /// This physics without the effect of `kind`'s kind.
    pub(super) fn without(mut self, kind: Effect) -> Self {
        self.effects[kind.slot()] = None;
        self
    }

    /// Whether it holds an effect of `kind`'s kind (of any order).
    pub(super) fn has(self, kind: Effect) -> bool {
        self.effects[kind.slot()].is_some()
    }

    /// Its effects, in the order of its name.
    pub(super) fn effects(self) -> impl Iterator<Item = Effect> {
        self.effects.into_iter().flatten()
    }

    /// The highest order of its transmission harmonics (0: none).
    pub(super) fn harmonics(self) -> u32 {
        match self.effects[Effect::Harmonics(0).slot()] {
            Some(Effect::Harmonics(k)) => k,
            _ => 0,
        }
    }

    /// The highest order of its axis runouts (0: none).
    pub(super) fn runout(self) -> u32 {
        match self.effects[Effect::Runout(0).slot()] {
            Some(Effect::Runout(k)) => k,
            _ => 0,
        }
    }

    /// This physics without its joint-error terms: the table and its compliances.
    pub(super) fn without_joint_errors(self) -> Self {
        [
            Effect::Harmonics(0),
            Effect::SelfWeight,
            Effect::Backlash,
            Effect::Tilt,
            Effect::Runout(0),
        ]
        .into_iter()
        .fold(self, Self::without)
    }

    /// Its name: `kinematic + compliance + harmonics 2 + backlash (flank search)`, ….
    pub(super) fn name(self) -> String {
        if self.aligned {
            return "nominal (base and tool fitted)".into();
        }
        let mut name = String::from("kinematic");
        for effect in self.effects() {
            match effect {
                Effect::Compliance => name += " + compliance",
                Effect::Harmonics(k) => name += &format!(" + harmonics {k}"),
                Effect::SelfWeight => name += " + self-weight",
                Effect::Backlash => name += " + backlash",
                Effect::FlankSearch if self.has(Effect::Backlash) => name += " (flank search)",
                Effect::Runout(k) => name += &format!(" + runout {k}"),
                Effect::RunoutFromWithout if self.runout() > 0 => {
                    name += " (from the fit without)";
                }
                Effect::Tilt => name += " + tilt",
                Effect::FlankSearch | Effect::RunoutFromWithout => {}
            }
        }
        name
    }

    /// Whether it holds any joint-error term (a block, the runouts or the tilts).
    pub(super) fn has_joint_errors(self) -> bool {
        self.effects().any(Effect::adds_terms)
    }

    /// This physics with every joint-error term of `other` besides (the higher order where
    /// both hold one kind).
    pub(super) fn union(self, other: Self) -> Self {
        (other.effects())
            .filter(|e| *e != Effect::Compliance)
            .fold(self, |physics, e| {
                let joined = physics.effects[e.slot()].map_or(e, |mine| mine.with(e));
                physics.with(joined)
            })
    }

    /// Its joint-error terms in words, e.g. `transmission harmonics (orders 1 to 2) identified
    /// with the geometry`.
    pub(super) fn joint_error_terms(self) -> String {
        let mut parts = Vec::new();
        if self.harmonics() > 0 {
            parts.push(format!(
                "transmission harmonics (orders 1 to {})",
                self.harmonics()
            ));
        }
        if self.has(Effect::SelfWeight) && self.has(Effect::Compliance) {
            parts.push("the links' weights and the payload's centre of mass (each joint deflecting by its compliance under their torques)".to_string());
        } else if self.has(Effect::SelfWeight) {
            parts.push("self-weight terms".to_string());
        }
        if self.has(Effect::Backlash) {
            parts.push("backlash (each joint on the flank of its approach from home or on the one its torque presses)".to_string());
        }
        if self.runout() > 0 {
            parts.push(format!(
                "axis runouts ({}: the parts beyond each joint turning across its axis periodically in its angle)",
                orders_words(self.runout())
            ));
        }
        if self.has(Effect::Tilt) {
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
            target_weights: auto.target_weights.clone(),
            // The payload's centre of mass is rarely known to the millimetre: identified with
            // the links' weights (the mass properties the compliances meet; both after a first
            // fit that gives the compliances they start from).
            compliance: self.has(Effect::Compliance).then(|| ComplianceSettings {
                gravity,
                plausible_only: true,
                detect_mounting: auto.gravity.is_none(),
                identify_payload_com: self.has(Effect::SelfWeight),
                ..ComplianceSettings::default()
            }),
            // With the compliances identified, the deflection under the links' own weight is
            // theirs too: the links' weights shared by the joints (a few masses and moments)
            // rather than a coefficient per joint and link, which the poses determine less
            // well and which extrapolate worse.
            joint_errors: self.has_joint_errors().then(|| JointErrorSettings {
                harmonics: self.harmonics(),
                self_weight: self.has(Effect::SelfWeight) && !self.has(Effect::Compliance),
                link_weights: self.has(Effect::SelfWeight) && self.has(Effect::Compliance),
                backlash: self.has(Effect::Backlash),
                flank_search: self.has(Effect::FlankSearch),
                tilt: self.has(Effect::Tilt),
                runout: self.runout(),
                runout_from_without: self.has(Effect::RunoutFromWithout),
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
