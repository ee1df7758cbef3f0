//! The true robot's physics: what the arm really does for a joint reading and a payload.
//!
//! The controller's reading `q` is the motor/encoder side. The arm's real joint angle is
//! `q + compliance + gear error + backlash`; the true geometry then places the reflector.

use nalgebra::{Matrix3, Rotation3, Vector3};
use rand::Rng;
use rand_distr::{Distribution, Normal};

use crate::config::{BacklashSide, TwinConfig};

impl TwinConfig {
    /// Gravity in the world (tracker) frame, m/s².
    pub fn gravity_world(&self) -> Vector3<f64> {
        self.truth.base_rotation() * self.gravity
    }

    /// Centres of mass of the links and of the payload in the world frame, mm, at real joint
    /// angles `q` (rad).
    fn mass_points(&self, q: &[f64]) -> (Vec<Vector3<f64>>, Vector3<f64>) {
        self.mass_points_in(&self.truth.link_frames(q))
    }

    /// [`Self::mass_points`] from the truth's link frames {1}..{n} (world frame) already made.
    fn mass_points_in(
        &self,
        frames: &[(Matrix3<f64>, Vector3<f64>)],
    ) -> (Vec<Vector3<f64>>, Vector3<f64>) {
        let coms = frames
            .iter()
            .zip(&self.masses.link_com)
            .map(|((r, o), com)| o + r * com)
            .collect();
        let payload = frames.last().map_or(self.masses.payload_com, |(r, o)| {
            o + r * self.masses.payload_com
        });
        (coms, payload)
    }

    /// Gravity moment (N·m vector, world frame) about point `a` of the links from `first`
    /// outwards and of `load` kg at `payload`.
    fn gravity_moment(
        &self,
        (coms, payload): &(Vec<Vector3<f64>>, Vector3<f64>),
        first: usize,
        a: &Vector3<f64>,
        load: f64,
    ) -> Vector3<f64> {
        let g = self.gravity_world();
        let mut moment = (payload - a).cross(&(g * load));
        for (com, mass) in coms[first..].iter().zip(&self.masses.link_mass[first..]) {
            moment += (com - a).cross(&(g * *mass));
        }
        moment * 1e-3 // mm·N → N·m
    }

    /// Gravity torque about every joint axis, N·m, at reading `q` (rad) with `load` kg on the
    /// flange.
    ///
    /// `τ_i = w_i · Σ_{j ≥ i} (c_j − a_i) × m_j g`, with `w_i` the joint axis through `a_i`,
    /// `c_j` the centre of mass of link j (or of the payload).
    pub fn gravity_torques(&self, q: &[f64], load: f64) -> Vec<f64> {
        let masses = self.mass_points(q);
        self.truth
            .joint_axes(q)
            .axes
            .iter()
            .enumerate()
            .map(|(i, (w, a))| w.dot(&self.gravity_moment(&masses, i, a, load)))
            .collect()
    }

    /// The payload's centre of mass in the world frame, mm, at reading `q` (rad).
    pub fn payload_point(&self, q: &[f64]) -> Vector3<f64> {
        self.mass_points(q).1
    }

    /// Joint deflection under gravity, rad: torque / stiffness; zero without a compliance model.
    pub fn compliance_deflection(&self, q: &[f64], load: f64) -> Vec<f64> {
        self.deflection_with(q, load, &mut None)
    }

    /// [`Self::compliance_deflection`], with the gravity torques computed into (or taken from)
    /// `torques`, so one evaluation serves compliance and torque-side backlash.
    fn deflection_with(&self, q: &[f64], load: f64, torques: &mut Option<Vec<f64>>) -> Vec<f64> {
        match &self.compliance {
            Some(c) => torques
                .get_or_insert_with(|| self.gravity_torques(q, load))
                .iter()
                .zip(&c.stiffness)
                .map(|(t, k)| t / k)
                .collect(),
            None => vec![0.0; q.len()],
        }
    }

    /// Gear transmission error of every joint at reading `q`, rad.
    pub fn gear_error(&self, q: &[f64]) -> Vec<f64> {
        match &self.gear {
            Some(g) => q
                .iter()
                .enumerate()
                .map(|(i, &qi)| {
                    g.amplitude_1[i] * (qi + g.phase_1[i]).sin()
                        + g.amplitude_2[i] * (2.0 * qi + g.phase_2[i]).sin()
                })
                .collect(),
            None => vec![0.0; q.len()],
        }
    }

    /// Backlash offset of every joint at reading `q` (rad) under `load` kg: a joint that has
    /// play rests on one flank, `+width/2` or `−width/2`, as its side rule says.
    pub fn backlash_offset(&self, q: &[f64], load: f64) -> Vec<f64> {
        self.backlash_with(q, load, &mut None)
    }

    /// [`Self::backlash_offset`], sharing the gravity torques as [`Self::deflection_with`] does.
    fn backlash_with(&self, q: &[f64], load: f64, torques: &mut Option<Vec<f64>>) -> Vec<f64> {
        let mut offset = vec![0.0; q.len()];
        for b in &self.backlash {
            let positive = match b.side {
                BacklashSide::Approach { home } => q[b.joint] >= home,
                BacklashSide::Torque { preload } => {
                    let t = torques.get_or_insert_with(|| self.gravity_torques(q, load));
                    preload + t[b.joint] >= 0.0
                }
            };
            offset[b.joint] = if positive { 1.0 } else { -1.0 } * b.width / 2.0;
        }
        offset
    }

    /// Joint errors beyond robocal's model family at reading `q`, rad: the third harmonic of
    /// each joint's transmission error and joint i's error driven through joint i−1 (zero
    /// without `[beyond]`).
    pub fn beyond_joint_error(&self, q: &[f64]) -> Vec<f64> {
        let Some(b) = &self.beyond else {
            return vec![0.0; q.len()];
        };
        (0..q.len())
            .map(|i| {
                let coupled = match i.checked_sub(1) {
                    Some(before) => b.coupling[i] * (q[i] + q[before] + b.coupling_phase[i]).sin(),
                    None => 0.0,
                };
                b.harmonic_3[i] * (3.0 * q[i] + b.phase_3[i]).sin() + coupled
            })
            .collect()
    }

    /// The small rotations (rad, world frame) that the effects beyond robocal's model family
    /// give the parts beyond each joint, with the point each turns about (the joint's origin,
    /// mm), at real joint angles `q` (rad) under `load` kg: the tilt under the gravity moment
    /// across the joint's axis, and the runout at twice its angle. Empty without `[beyond]`.
    pub fn beyond_turns(&self, q: &[f64], load: f64) -> Vec<(Vector3<f64>, Vector3<f64>)> {
        let Some(b) = &self.beyond else {
            return Vec::new();
        };
        let (axes, frames) = self.truth.axes_and_frames(q);
        let masses = self.mass_points_in(&frames);
        (axes.iter().zip(&frames).enumerate())
            .map(|(i, ((w, a), (r, _)))| {
                let mut turn = Vector3::zeros();
                if b.tilt_stiffness[i] > 0.0 {
                    let m = self.gravity_moment(&masses, i, a, load);
                    turn += (m - w * w.dot(&m)) / b.tilt_stiffness[i];
                }
                if b.wobble[i] != 0.0 {
                    // The link frame's x across the axis (a Hayati β leaves it a hair off).
                    let x = r.column(0).into_owned();
                    let x = (x - w * w.dot(&x)).normalize();
                    let angle = 2.0 * q[i] + b.wobble_phase[i];
                    turn += b.wobble[i] * (x * angle.cos() + w.cross(&x) * angle.sin());
                }
                (turn, *a)
            })
            .collect()
    }

    /// The real joint angles for reading `q` (rad) under `load` kg.
    pub fn actual_joints(&self, q: &[f64], load: f64) -> Vec<f64> {
        let mut torques = None;
        let deflection = self.deflection_with(q, load, &mut torques);
        let gear = self.gear_error(q);
        let backlash = self.backlash_with(q, load, &mut torques);
        let beyond = self.beyond_joint_error(q);
        (0..q.len())
            .map(|i| q[i] + deflection[i] + gear[i] + backlash[i] + beyond[i])
            .collect()
    }

    /// `point` (mm, world frame, on the arm beyond every joint at real angles `actual`) moved by
    /// [`Self::beyond_turns`] (to first order: the turns are micro-radians).
    fn turned(&self, actual: &[f64], load: f64, point: Vector3<f64>) -> Vector3<f64> {
        (self.beyond_turns(actual, load).iter())
            .fold(point, |p, (turn, a)| p + turn.cross(&(point - a)))
    }

    /// Where the reflector really is, mm, world (tracker) frame, without measurement noise.
    pub fn true_point(&self, q: &[f64], load: f64) -> Vector3<f64> {
        let actual = self.actual_joints(q, load);
        self.turned(&actual, load, self.truth.point(&actual))
    }

    /// The true position of the truth's target `target` (a `[tool.points]` name; empty or
    /// unknown: the default point), mm.
    pub fn true_point_of(&self, q: &[f64], load: f64, target: &str) -> Vector3<f64> {
        let t = self.truth.target_index(target).unwrap_or(0);
        let actual = self.actual_joints(q, load);
        self.turned(&actual, load, self.truth.for_target(t).point(&actual))
    }

    /// The true orientation of the tool frame (the probe's), world frame, when the truth
    /// declares `[tool] rpy` (a 6-DoF probe); `None` otherwise.
    pub fn true_rotation(&self, q: &[f64], load: f64) -> Option<Matrix3<f64>> {
        self.truth.tool_rpy?;
        let actual = self.actual_joints(q, load);
        let turn: Vector3<f64> = (self.beyond_turns(&actual, load).iter())
            .map(|(t, _)| t)
            .sum();
        Some(Rotation3::new(turn).into_inner() * self.truth.tool_rotation(&actual))
    }

    /// What a 6-DoF probe reads for the true orientation `r`: `r` turned by a small random
    /// rotation, normal about each world axis with σ = the probe's angular noise (none without
    /// noise).
    pub fn add_probe_noise(&self, r: Matrix3<f64>, rng: &mut impl Rng) -> Matrix3<f64> {
        let sigma = self.noise.map_or(0.0, |n| n.probe_deg.to_radians());
        let w = gaussian(sigma, rng);
        Rotation3::new(w).into_inner() * r
    }

    /// A tracker measurement of the true point: noise as configured (or none).
    pub fn measure(&self, q: &[f64], load: f64, rng: &mut impl Rng) -> Vector3<f64> {
        self.add_noise(self.true_point(q, load), rng)
    }

    /// The robot's repeatability error of one pose and load, mm (zero without noise): shared
    /// by every reflector measured there ([`Self::add_tracker_noise`]).
    pub fn draw_repeatability(&self, rng: &mut impl Rng) -> Vector3<f64> {
        gaussian(self.noise.map_or(0.0, |n| n.robot_sigma()), rng)
    }

    /// What the tracker reads for the true point `p` of a pose whose repeatability error is
    /// `robot`: `p + robot` plus the tracker's own noise.
    pub fn add_tracker_noise(
        &self,
        p: Vector3<f64>,
        robot: Vector3<f64>,
        rng: &mut impl Rng,
    ) -> Vector3<f64> {
        let tracker = self.noise.map_or(0.0, |n| n.tracker_sigma(p.norm()));
        p + robot + gaussian(tracker, rng)
    }

    /// What the tracker reads for the true point `p`: `p` plus noise as configured (or none).
    pub fn add_noise(&self, p: Vector3<f64>, rng: &mut impl Rng) -> Vector3<f64> {
        match &self.noise {
            Some(noise) => {
                let sigma = noise.sigma(p.norm());
                match Normal::new(0.0, sigma) {
                    Ok(normal) => p + Vector3::from_fn(|_, _| normal.sample(rng)),
                    Err(_) => p,
                }
            }
            None => p,
        }
    }
}

/// Three independent normal draws of standard deviation `sigma` (zeros for `sigma` ≤ 0).
fn gaussian(sigma: f64, rng: &mut impl Rng) -> Vector3<f64> {
    match Normal::new(0.0, sigma) {
        Ok(normal) if sigma > 0.0 => Vector3::from_fn(|_, _| normal.sample(rng)),
        _ => Vector3::zeros(),
    }
}
