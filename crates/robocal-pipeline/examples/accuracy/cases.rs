//! The suite's cases: the arms and their twin families, the effect sets, the splits.

use nalgebra::Vector3;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use robocal_data::Measurement;
use robocal_robot::{JointField, ParamId};
use robocal_twin::TwinConfig;
use std::path::{Path, PathBuf};

/// The twins: name, file.
pub(super) const ARMS: [(&str, &str); 14] = [
    ("pmc6va030", "configs/twin/pmc6va030.toml"),
    ("arm7", "configs/twin/arm7.toml"),
    ("arm5", "configs/twin/arm5.toml"),
    ("arm5w", "configs/twin/arm5w.toml"),
    ("arm5t", "configs/twin/arm5t.toml"),
    ("arm6s", "configs/twin/arm6s.toml"),
    ("arm6h", "configs/twin/arm6h.toml"),
    ("arm6c", "configs/twin/arm6c.toml"),
    ("arm6m", "configs/twin/arm6m.toml"),
    ("arm6n", "configs/twin/arm6n.toml"),
    ("arm6u", "configs/twin/arm6u.toml"),
    ("arm6k", "configs/twin/arm6k.toml"),
    ("arm6w", "configs/twin/arm6w.toml"),
    ("arm6t", "configs/twin/arm6t.toml"),
];
/// Families kept aside: never run while tuning, only to report a change once it is decided.
pub(super) const ASIDE: [&str; 9] = [
    "arm6s", "arm6h", "arm6c", "arm6m", "arm6n", "arm6u", "arm6k", "arm6w", "arm6t",
];

pub(super) fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// A member of a twin family: the file's twin with its truth, masses, stiffnesses and gear
/// errors drawn again around the file's values (seed 0 is the file's twin itself).
pub(super) fn member(base: &TwinConfig, seed: u64) -> TwinConfig {
    let mut twin = base.clone();
    if seed == 0 {
        return twin;
    }
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut gauss = |s: f64| -> f64 {
        // Box–Muller from two uniforms.
        let (u, v): (f64, f64) = (rng.random::<f64>().max(1e-12), rng.random());
        s * (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
    };
    for id in twin.nominal.param_ids() {
        let sd = match id {
            ParamId::Joint {
                field: JointField::A | JointField::D,
                ..
            } => 0.3,
            ParamId::Joint { .. } => 0.04f64.to_radians(),
            _ => continue,
        };
        let v = twin.nominal.param(id) + gauss(sd);
        // The nominal table has every parameter the truth has.
        let _ = twin.truth.set_param(id, v);
    }
    for m in &mut twin.masses.link_mass {
        *m *= 1.0 + 0.15 * gauss(1.0).clamp(-2.0, 2.0);
    }
    if let Some(c) = &mut twin.compliance {
        for k in &mut c.stiffness {
            *k *= (0.25 * gauss(1.0)).exp();
        }
    }
    if let Some(g) = &mut twin.gear {
        for a in g.amplitude_1.iter_mut().chain(g.amplitude_2.iter_mut()) {
            *a *= (0.3 * gauss(1.0)).exp();
        }
        for p in g.phase_1.iter_mut().chain(g.phase_2.iter_mut()) {
            *p += gauss(1.0);
        }
    }
    twin.seed = twin.seed.wrapping_add(seed.wrapping_mul(7919));
    twin
}

/// Which of the twin's effects are on.
#[derive(Clone, Copy, PartialEq)]
pub(super) enum Effects {
    /// Everything the file has.
    All,
    /// Geometry, joint compliance under the payload and noise: what the physical model holds.
    Modelled,
    /// Everything the file has and effects beyond robocal's model family ([`beyond`]): what a
    /// real arm holds besides, for the learned residual models.
    Beyond,
}

impl Effects {
    pub(super) const EVERY: [Self; 3] = [Self::All, Self::Modelled, Self::Beyond];

    /// The table's words.
    pub(super) fn label(self) -> &'static str {
        match self {
            Self::All => "all",
            Self::Modelled => "modelled only",
            Self::Beyond => "beyond the model",
        }
    }

    /// The exported case's word (and `--effects`'s).
    pub(super) fn key(self) -> &'static str {
        match self {
            Self::All => "all",
            Self::Modelled => "modelled",
            Self::Beyond => "beyond",
        }
    }
}

/// Effects beyond robocal's model family for a twin without a `[beyond]` section, sized from
/// the twin's own numbers (robocal's invention, not a real robot's): each bearing's tilting
/// stiffness 5× its joint's torsional stiffness (reducer catalogues give 10–30×: this tilts more
/// than most), axis runout at twice the joint angle of a quarter of the joint's first gear
/// harmonic, a third gear harmonic of 0.4× its second, and the wrist's last two joints' gears
/// driven through the joint before them at half their first harmonic; every phase drawn from
/// the twin's seed and the member's.
///
/// `scale` multiplies every one of them (the tilts' compliance, the runout, the third harmonic,
/// the coupled error): `--beyond-scale K`, for arms where what the physics lacks is most of what
/// the kinematic table leaves (as on real arms where a network on the joints halves it).
pub(super) fn beyond(twin: &TwinConfig, seed: u64, scale: f64) -> robocal_twin::Beyond {
    let n = twin.truth.dof();
    let mut rng = ChaCha8Rng::seed_from_u64(twin.seed ^ seed.wrapping_mul(0xBE70));
    let mut phases = || -> Vec<f64> {
        (0..n)
            .map(|_| rng.random_range(-std::f64::consts::PI..std::f64::consts::PI))
            .collect()
    };
    let (a1, a2) = twin.gear.as_ref().map_or_else(
        || (vec![0.0; n], vec![0.0; n]),
        |g| (g.amplitude_1.clone(), g.amplitude_2.clone()),
    );
    robocal_twin::Beyond {
        tilt_stiffness: twin.compliance.as_ref().map_or(vec![0.0; n], |c| {
            c.stiffness.iter().map(|k| 5.0 * k / scale).collect()
        }),
        wobble: a1.iter().map(|a| 0.25 * a * scale).collect(),
        wobble_phase: phases(),
        harmonic_3: a2.iter().map(|a| 0.4 * a * scale).collect(),
        phase_3: phases(),
        coupling: (0..n)
            .map(|i| {
                if i + 2 >= n && i > 0 {
                    0.5 * a1[i] * scale
                } else {
                    0.0
                }
            })
            .collect(),
        coupling_phase: phases(),
    }
}

/// Test rows: a random quarter of the configurations, or the quarter with the highest joint-1
/// reading (the test poses lie outside the trained range of joint 1), or — on the twin's poses
/// laid around its base ([`ring`]) — every configuration outside a 90° window of joint 1.
#[derive(Clone, Copy, PartialEq)]
pub(super) enum Split {
    Configurations,
    Extrapolation,
    /// Trained on the configurations whose joint 1 lies within [`WINDOW`], tested on every
    /// other: up to 150° beyond the readings on one side and 120° on the other.
    Window,
}

/// The joint-1 readings (deg) the window split trains on.
pub(super) const WINDOW: [f64; 2] = [-60.0, 30.0];

/// The twin with its pose grid laid all around its base (x and y each over ± the grid's largest
/// reach along them) and three times its configurations (at most 300), for the window split:
/// joint 1 then spans its whole turn.
pub(super) fn ring(twin: &TwinConfig) -> TwinConfig {
    let mut ringed = twin.clone();
    ringed.poses = twin.poses.around_base((3 * twin.poses.count).min(300));
    ringed
}

pub(super) fn split<'a>(
    rows: &[&'a Measurement],
    how: Split,
    seed: u64,
) -> (Vec<&'a Measurement>, Vec<&'a Measurement>) {
    let mut poses: Vec<(&str, f64)> = rows
        .iter()
        .map(|r| (r.sample.pose.as_str(), r.sample.joints[0]))
        .collect();
    poses.sort_by(|a, b| a.0.cmp(b.0));
    poses.dedup_by(|a, b| a.0 == b.0);
    match how {
        Split::Configurations => {
            let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0xACC);
            for i in (1..poses.len()).rev() {
                let j = rng.random_range(0..=i);
                poses.swap(i, j);
            }
        }
        Split::Extrapolation => poses.sort_by(|a, b| b.1.total_cmp(&a.1)),
        Split::Window => {
            let [lo, hi] = WINDOW;
            let test: std::collections::HashSet<&str> = (poses.iter())
                .filter(|p| !(lo..=hi).contains(&p.1))
                .map(|p| p.0)
                .collect();
            return rows
                .iter()
                .partition(|r| !test.contains(r.sample.pose.as_str()));
        }
    }
    let test: std::collections::HashSet<&str> =
        poses[..poses.len() / 4].iter().map(|p| p.0).collect();
    rows.iter()
        .partition(|r| !test.contains(r.sample.pose.as_str()))
}

/// The twin's noise-free point of every measured row: (pose, load bits) → point.
pub(super) fn truth_of(
    data: &robocal_twin::TwinDataset,
) -> std::collections::HashMap<(String, u64), Vector3<f64>> {
    (data.truth.rows.iter())
        .map(|r| ((r.sample.pose.clone(), r.sample.load.to_bits()), r.position))
        .collect()
}

/// The member of `base`'s family for `seed` with the effect set `effects`, at `poses`
/// configurations where given (its grid made finer by the cube root of the ratio so that
/// enough points are measurable), the effects beyond the model `beyond_scale` times as large.
pub(super) fn case_twin(
    base: &TwinConfig,
    seed: u64,
    effects: Effects,
    poses: Option<usize>,
    beyond_scale: f64,
) -> TwinConfig {
    let mut twin = member(base, seed);
    if let Some(count) = poses {
        let ratio = count as f64 / twin.poses.count as f64;
        if ratio > 1.0 {
            twin.poses.step /= ratio.cbrt();
        }
        twin.poses.count = count;
    }
    match effects {
        Effects::All => twin.beyond = None,
        Effects::Modelled => {
            twin.gear = None;
            twin.backlash.clear();
            twin.beyond = None;
        }
        Effects::Beyond => {
            if twin.beyond.is_none() {
                twin.beyond = Some(beyond(&twin, seed, beyond_scale));
            }
        }
    }
    twin
}
