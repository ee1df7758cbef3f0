//! Backlash: a joint with play rests on one flank, on its approach from home or where its
//! gravity torque presses.

use nalgebra::{Matrix3, Vector3};

use super::gravity::{TORQUE_FEATURES_PER_LINK, visit_torque_features};

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
    ///
    /// [`JointErrors::torque_features`]: crate::compliance::JointErrors::torque_features
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

/// `+1` for the positive flank, `−1` for the other.
pub(super) fn side(positive: bool) -> f64 {
    if positive { 1.0 } else { -1.0 }
}

/// The flank (`±1`) a torque flank's `weights` give for the gravity-torque `features`: `+1`
/// where their product is at least 0.
pub fn torque_side(weights: &[f64], features: &[f64]) -> f64 {
    torque_side_of(weights, features.iter().copied())
}

/// [`torque_side`] of features given one by one.
pub(super) fn torque_side_of(weights: &[f64], features: impl Iterator<Item = f64>) -> f64 {
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
pub(super) fn torque_side_at(
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

/// The name of a joint's backlash (half its play): `j1.backlash`.
pub fn backlash_name(joint: usize) -> String {
    format!("j{}.backlash", joint + 1)
}

/// The position, among `count` gravity-torque features, of the payload's unit mass (the
/// weight a torque flank's weights are scaled to; the preload's is the last).
pub fn payload_mass_feature(count: usize) -> usize {
    count.saturating_sub(TORQUE_FEATURES_PER_LINK + 1)
}
