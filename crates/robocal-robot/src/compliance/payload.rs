//! Compliance under the payload: each joint turns by its compliance times the gravity torque of
//! the payload (and of the links' weights, [`super::LinkWeight`]) about its axis.

use super::JointErrors;
use super::gravity::{Pose, PoseCache, torque_features_at, unit_torque};
use crate::table::Robot;

/// The name of joint `joint`'s (0-based) payload compliance: `j2.compliance`.
pub fn compliance_name(joint: usize) -> String {
    format!("j{}.compliance", joint + 1)
}

/// The name of a coordinate (0: x, 1: y, 2: z) of the payload's centre of mass in the flange
/// frame: `payload_com.x`.
pub fn payload_com_name(axis: usize) -> String {
    format!("payload_com.{}", ["x", "y", "z"][axis])
}

/// The position, among `count` gravity-torque features, of the payload's unit mass (the
/// weight a torque flank's weights are scaled to; the preload's is the last).
pub fn payload_mass_feature(count: usize) -> usize {
    count.saturating_sub(TORQUE_FEATURES_PER_LINK + 1)
}

/// Gravity-torque features per link (and for the payload): a unit mass and three unit first
/// moments.
pub const TORQUE_FEATURES_PER_LINK: usize = 4;

impl JointErrors {
    /// Gravity torque of `load` kg at the payload's centre of mass about every joint axis, N·m,
    /// at command `q` (rad).
    pub fn torques(&self, robot: &Robot, q: &[f64], load: f64) -> Vec<f64> {
        self.torques_at(&self.pose(robot, q), load)
    }

    /// [`Self::torques`] at the command `pose` holds.
    pub(super) fn torques_at(&self, pose: &PoseCache, load: f64) -> Vec<f64> {
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

    /// The gravity torque about every joint axis (N·m) at command `q` (rad) under `load` kg that
    /// the compliances meet: the payload's, and the links' weights' when the model has them.
    pub fn load_torques(&self, robot: &Robot, q: &[f64], load: f64) -> Vec<f64> {
        self.load_torques_at(&self.pose(robot, q), load)
    }

    /// [`Self::load_torques`] at the command `pose` holds.
    pub(super) fn load_torques_at(&self, pose: &PoseCache, load: f64) -> Vec<f64> {
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
}
