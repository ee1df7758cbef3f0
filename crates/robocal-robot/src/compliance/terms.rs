//! Each effect's terms at one command: the gravity torques the compliances meet, the backlash
//! flanks, the turns across the axes, the self-weight and link-weight bases; the arm's frames
//! computed once per row for them all.

use std::cell::OnceCell;

use nalgebra::Vector3;

use super::backlash::{Backlash, Flank, side, torque_side, torque_side_at};
use super::gravity::{Pose, across, torque_features_at, unit_moment, unit_torque};
use super::model::{ErrorParam, JointErrors, Turns};
use super::self_weight::{LinkUnits, LinkWeight};
use crate::kinematics::{Axis, Frame};
use crate::table::Robot;

/// The arm's joint axes and link frames at command `q`, computed on first use and once: the
/// payload's torques, the links' weights, the self-weight terms, the torque flanks and the
/// centre of mass's columns of one row share them. With them the bases of the model's waves at
/// `q` ([`JointErrors::wave_bases`]): the caller's, or computed on first use.
pub(super) struct PoseCache<'a> {
    pub(super) robot: &'a Robot,
    pub(super) q: &'a [f64],
    pub(super) g: Vector3<f64>,
    pub(super) pose: OnceCell<(Vec<Axis>, Vec<Frame>)>,
    pub(super) given_waves: Option<&'a [(f64, f64)]>,
    pub(super) waves: OnceCell<Vec<(f64, f64)>>,
}

impl PoseCache<'_> {
    pub(super) fn get(&self) -> Pose<'_> {
        let (axes, frames) = self.pose.get_or_init(|| self.robot.axes_and_frames(self.q));
        Pose {
            axes,
            frames,
            g: &self.g,
        }
    }

    /// The bases of `model`'s waves at the command ([`JointErrors::wave_bases`]).
    pub(super) fn waves(&self, model: &JointErrors) -> &[(f64, f64)] {
        match self.given_waves {
            Some(waves) => waves,
            None => self.waves.get_or_init(|| model.wave_bases(self.q)),
        }
    }
}

/// Which of a block's terms (their `values`, in order) a row computes the basis of: those not at
/// zero, and those among `params` (`index` picks the block's own parameters out of them).
pub(super) fn not_zero_or_identified(
    values: impl Iterator<Item = f64>,
    params: &[ErrorParam],
    index: impl Fn(ErrorParam) -> Option<usize>,
) -> Vec<bool> {
    let mut wanted: Vec<bool> = values.map(|v| v != 0.0).collect();
    for i in params.iter().filter_map(|&p| index(p)) {
        wanted[i] = true;
    }
    wanted
}

impl JointErrors {
    /// A lazily computed [`Pose`] of `robot` at command `q` (rad), for this model's gravity.
    pub(super) fn pose<'a>(&self, robot: &'a Robot, q: &'a [f64]) -> PoseCache<'a> {
        self.pose_on(robot, q, None)
    }

    /// [`Self::pose`] with the bases of the model's waves at `q` given ([`Self::wave_bases`]),
    /// or computed on first use.
    pub(super) fn pose_on<'a>(
        &self,
        robot: &'a Robot,
        q: &'a [f64],
        waves: Option<&'a [(f64, f64)]>,
    ) -> PoseCache<'a> {
        debug_assert!(
            waves.is_none_or(|w| w.len() == self.harmonics.len() + self.runouts.len()),
            "one basis per wave"
        );
        PoseCache {
            robot,
            q,
            g: self.gravity_world(robot),
            pose: OnceCell::new(),
            given_waves: waves,
            waves: OnceCell::new(),
        }
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

    /// The runouts' turns among `turns`, this model's ([`Self::turns`]: the tilting joints'
    /// first, then one per runout in the order of `runouts`), each with the origin it turns
    /// about. Panics where `turns` are not this model's (a count that does not match).
    pub fn runout_turns<'t>(
        &self,
        turns: &'t [(Vector3<f64>, Vector3<f64>)],
    ) -> &'t [(Vector3<f64>, Vector3<f64>)] {
        let runouts = &turns[self.tilts.len().min(turns.len())..];
        assert_eq!(
            (turns.len(), runouts.len()),
            (self.tilts.len() + self.runouts.len(), self.runouts.len()),
            "the turns of another model"
        );
        runouts
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
    ///
    /// [`TORQUE_FEATURES_PER_LINK`]: crate::compliance::TORQUE_FEATURES_PER_LINK
    pub fn torque_features(&self, robot: &Robot, q: &[f64], load: f64, joint: usize) -> Vec<f64> {
        let pose = self.pose(robot, q);
        let Pose { axes, frames, g } = pose.get();
        torque_features_at(&axes[joint], &frames[joint..], g, load)
    }

    /// The flank (`±1`) backlash `b` rests on at command `q` (rad) under `load` kg.
    pub fn flank(&self, b: &Backlash, robot: &Robot, q: &[f64], load: f64) -> f64 {
        match &b.flank {
            Flank::Approach { home } => side(q[b.joint] >= *home),
            Flank::Torque { weights } => {
                torque_side(weights, &self.torque_features(robot, q, load, b.joint))
            }
        }
    }

    /// The flank (`±1`) of every backlash term at command `q` (rad) under `load` kg, the arm's
    /// frames computed once for all the torque flanks.
    pub(super) fn flanks(&self, pose: &PoseCache, load: f64) -> Vec<f64> {
        (self.backlash.iter())
            .map(|b| match &b.flank {
                Flank::Approach { home } => side(pose.q[b.joint] >= *home),
                Flank::Torque { weights } => {
                    let Pose { axes, frames, g } = pose.get();
                    torque_side_at(weights, &axes[b.joint], &frames[b.joint..], g, load)
                }
            })
            .collect()
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
            .map(|(t, wanted)| if wanted { t.basis_at(&pose.get()) } else { 0.0 })
            .collect()
    }

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
}
