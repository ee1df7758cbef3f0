//! Tilting compliance: the parts beyond a joint turn across its axis under the gravity moment
//! there; with the runouts, the turns that move the point without turning a joint.

use nalgebra::Vector3;

use super::gravity::{Pose, PoseCache, across, unit_moment};
use super::{ErrorParam, JointErrors, Turns};
use crate::table::Robot;

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

/// The name of a joint's tilting compliance: `j2.tilt`.
pub fn tilt_name(joint: usize) -> String {
    format!("j{}.tilt", joint + 1)
}

impl JointErrors {
    /// Adds tilting compliances (0) for `joints`.
    pub fn with_tilts(mut self, joints: &[usize]) -> Self {
        self.tilts
            .extend(joints.iter().map(|&joint| Tilt { joint, value: 0.0 }));
        self
    }

    /// The gravity moment (N·m, world frame) about joint `joint`'s origin of the payload and of
    /// the links' weights beyond it, less its component along the joint's axis, at the command
    /// `pose` holds under `load` kg.
    pub(super) fn moment_across(&self, pose: &PoseCache, load: f64, joint: usize) -> Vector3<f64> {
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
    pub(super) fn turns_at(&self, pose: &PoseCache, load: f64) -> Turns {
        let mut out = Vec::new();
        self.turns_into(pose, load, &mut out);
        out
    }

    /// [`Self::turns_at`] written into `out` (emptied first, its capacity kept: a fit's rows
    /// fill one buffer in turn).
    pub(super) fn turns_into(&self, pose: &PoseCache, load: f64, out: &mut Turns) {
        out.clear();
        out.extend(self.each_turn(pose, load));
    }

    /// The turns of [`Self::turns_at`] as they come, in their order (the tilting joints', then
    /// the runouts'), each with the origin it turns about.
    pub(super) fn each_turn<'s>(
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

    /// For each of `params` (by position `k`) that turns the parts beyond a tilting joint, the
    /// turn per unit (rad, world frame) and the joint's origin it turns about, as entries
    /// `(k, origin, turn)`: a tilting compliance its moment across the axis; a link weight and
    /// a coordinate of the payload's centre of mass, for every tilting joint they load, the
    /// joint's compliance times the moment across its axis of the unit quantity; a runout's
    /// coefficient its axis across times its basis value.
    ///
    /// Written into `out` (emptied first, its capacity kept).
    pub(super) fn turn_basis_into(
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
}
