//! The true robot's physics: what the arm really does for a joint reading and a payload.
//!
//! The controller's reading `q` is the motor/encoder side. The arm's real joint angle is
//! `q + compliance + gear error + backlash`; the true geometry then places the reflector.

use nalgebra::Vector3;
use rand::Rng;
use rand_distr::{Distribution, Normal};

use crate::config::TwinConfig;

impl TwinConfig {
    /// Gravity in the world (tracker) frame, m/s².
    pub fn gravity_world(&self) -> Vector3<f64> {
        self.truth.base_rotation() * self.gravity
    }

    /// Gravity torque about every joint axis, N·m, at reading `q` (rad) with `load` kg at the
    /// reflector; zero without a compliance model.
    ///
    /// `τ_i = w_i · Σ_{j ≥ i} (c_j − a_i) × m_j g`, with `w_i` the joint axis through `a_i`,
    /// `c_j` the centre of mass of link j (or the payload at the tool point).
    pub fn gravity_torques(&self, q: &[f64], load: f64) -> Vec<f64> {
        let Some(c) = &self.compliance else {
            return vec![0.0; q.len()];
        };
        let g = self.gravity_world();
        let frames = self.truth.link_frames(q);
        let axes = self.truth.joint_axes(q);
        let coms: Vec<Vector3<f64>> = frames
            .iter()
            .zip(&c.link_com)
            .map(|((r, o), com)| o + r * com)
            .collect();
        axes.axes
            .iter()
            .enumerate()
            .map(|(i, (w, a))| {
                // The payload and every link from joint i outwards load joint i.
                let mut moment = (axes.point - a).cross(&(g * load));
                for (com, mass) in coms[i..].iter().zip(&c.link_mass[i..]) {
                    moment += (com - a).cross(&(g * *mass));
                }
                w.dot(&moment) * 1e-3 // mm·N → N·m
            })
            .collect()
    }

    /// Joint deflection under gravity, rad: torque / stiffness.
    pub fn compliance_deflection(&self, q: &[f64], load: f64) -> Vec<f64> {
        match &self.compliance {
            Some(c) => self
                .gravity_torques(q, load)
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

    /// Backlash offset of every joint at reading `q`, rad: the joint that has play rests on the
    /// flank of its approach from home, `+width/2` when it moved out in the positive sense
    /// (or stayed at home), `−width/2` otherwise.
    pub fn backlash_offset(&self, q: &[f64]) -> Vec<f64> {
        let mut offset = vec![0.0; q.len()];
        if let Some(b) = &self.backlash {
            let side = if q[b.joint] >= b.home { 1.0 } else { -1.0 };
            offset[b.joint] = side * b.width / 2.0;
        }
        offset
    }

    /// The real joint angles for reading `q` (rad) under `load` kg.
    pub fn actual_joints(&self, q: &[f64], load: f64) -> Vec<f64> {
        let deflection = self.compliance_deflection(q, load);
        let gear = self.gear_error(q);
        let backlash = self.backlash_offset(q);
        (0..q.len())
            .map(|i| q[i] + deflection[i] + gear[i] + backlash[i])
            .collect()
    }

    /// Where the reflector really is, mm, world (tracker) frame, without measurement noise.
    pub fn true_point(&self, q: &[f64], load: f64) -> Vector3<f64> {
        self.truth.point(&self.actual_joints(q, load))
    }

    /// A tracker measurement of the true point: noise as configured (or none).
    pub fn measure(&self, q: &[f64], load: f64, rng: &mut impl Rng) -> Vector3<f64> {
        let p = self.true_point(q, load);
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
