//! The twin description (TOML): raw form with `deny_unknown_fields`, validated once into
//! [`TwinConfig`]. Units: mm, deg, kg, N·m/rad, m/s².

use std::path::{Path, PathBuf};

use nalgebra::Vector3;
use robocal_robot::{Robot, RobotTable, toml_error};
use serde::Deserialize;

use crate::error::{Result, TwinError};

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawTwin {
    name: String,
    seed: u64,
    nominal: PathBuf,
    truth: RobotTable,
    gravity: [f64; 3],
    compliance: RawCompliance,
    gear: RawGear,
    backlash: RawBacklash,
    noise: RawNoise,
    poses: RawPoses,
    loads: RawLoads,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawCompliance {
    enabled: bool,
    stiffness: Vec<f64>,
    link_mass: Vec<f64>,
    link_com: Vec<[f64; 3]>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawGear {
    enabled: bool,
    amplitude_1: Vec<f64>,
    phase_1: Vec<f64>,
    amplitude_2: Vec<f64>,
    phase_2: Vec<f64>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawBacklash {
    enabled: bool,
    joint: usize,
    width: f64,
    home: f64,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawNoise {
    enabled: bool,
    tracker_base: f64,
    tracker_per_metre: f64,
    repeatability: f64,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawPoses {
    x: [f64; 2],
    y: [f64; 2],
    z: [f64; 2],
    step: f64,
    count: usize,
    home: Vec<f64>,
    tilt: f64,
    spin: f64,
    min_conditioning: f64,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawLoads {
    trained: Vec<f64>,
    untrained: Vec<f64>,
}

/// Joint compliance: deflection = gravity torque / stiffness.
#[derive(Debug, Clone, PartialEq)]
pub struct Compliance {
    /// Joint stiffness, N·m/rad, one per joint (> 0).
    pub stiffness: Vec<f64>,
    /// Mass of link i (moved by joint i), kg.
    pub link_mass: Vec<f64>,
    /// Centre of mass of link i in its frame {i}, mm.
    pub link_com: Vec<Vector3<f64>>,
}

/// Gear transmission error, per joint: `A1 sin(q + φ1) + A2 sin(2q + φ2)`.
#[derive(Debug, Clone, PartialEq)]
pub struct Gear {
    /// First-harmonic amplitude, rad.
    pub amplitude_1: Vec<f64>,
    /// First-harmonic phase, rad.
    pub phase_1: Vec<f64>,
    /// Second-harmonic amplitude, rad.
    pub amplitude_2: Vec<f64>,
    /// Second-harmonic phase, rad.
    pub phase_2: Vec<f64>,
}

/// Backlash of one joint: the joint rests on the flank on the side of its approach from home,
/// `±width/2`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Backlash {
    /// 0-based joint index.
    pub joint: usize,
    /// Total play, rad.
    pub width: f64,
    /// Home reading the joint moves out from, rad.
    pub home: f64,
}

/// Measurement noise, each world coordinate independent Gaussian.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Noise {
    /// Tracker accuracy, constant part, mm (1σ per coordinate).
    pub tracker_base: f64,
    /// Tracker accuracy growing with distance from the tracker, mm per metre (1σ).
    pub tracker_per_metre: f64,
    /// Robot repeatability (ISO 9283 RP), mm; per-coordinate σ = RP / 3.6 (the RP of an
    /// isotropic 3-D Gaussian is about 3.6 σ).
    pub repeatability: f64,
}

impl Noise {
    /// Per-coordinate standard deviation of a measurement of a point `distance_mm` from the
    /// tracker, mm.
    pub fn sigma(&self, distance_mm: f64) -> f64 {
        let tracker = self.tracker_base + self.tracker_per_metre * distance_mm / 1000.0;
        let robot = self.repeatability / 3.6;
        (tracker * tracker + robot * robot).sqrt()
    }
}

/// Section IV-A pose design: a grid in the robot base frame and a wrist-orientation policy.
#[derive(Debug, Clone, PartialEq)]
pub struct PoseGrid {
    /// Ranges, mm, robot base frame.
    pub x: [f64; 2],
    /// y range, mm.
    pub y: [f64; 2],
    /// z range, mm.
    pub z: [f64; 2],
    /// Grid spacing, mm.
    pub step: f64,
    /// Configurations kept (seeded choice when more are measurable).
    pub count: usize,
    /// IK seed for every grid point (joint 1 turned towards the point), rad.
    pub home: Vec<f64>,
    /// Largest tilt of the tool axis about base x and y, rad (drawn uniformly).
    pub tilt: f64,
    /// Largest spin about the tool axis, rad (drawn uniformly).
    pub spin: f64,
    /// Smallest accepted ratio of smallest to largest singular value of the pose Jacobian.
    pub min_conditioning: f64,
}

/// Load conditions, kg.
#[derive(Debug, Clone, PartialEq)]
pub struct Loads {
    /// Loads used for training in the GA/GB design.
    pub trained: Vec<f64>,
    /// Loads never trained on.
    pub untrained: Vec<f64>,
}

impl Loads {
    /// All loads, ascending.
    pub fn all(&self) -> Vec<f64> {
        let mut all: Vec<f64> = self
            .trained
            .iter()
            .chain(&self.untrained)
            .copied()
            .collect();
        all.sort_by(f64::total_cmp);
        all
    }
}

/// A validated twin description.
#[derive(Debug, Clone, PartialEq)]
pub struct TwinConfig {
    /// Free-form name.
    pub name: String,
    /// Seed of every random draw (pose choice, wrist policy, noise).
    pub seed: u64,
    /// The file it was read from.
    pub source: PathBuf,
    /// The nominal robot file's path, as written in the twin file.
    pub nominal_path: PathBuf,
    /// The nominal table: what the controller believes; IK of the pose design uses it.
    pub nominal: Robot,
    /// The true robot: geometry, base in the tracker frame, reflector on the flange.
    pub truth: Robot,
    /// Gravity in the robot base frame, m/s².
    pub gravity: Vector3<f64>,
    /// Joint compliance, if enabled.
    pub compliance: Option<Compliance>,
    /// Gear transmission error, if enabled.
    pub gear: Option<Gear>,
    /// Backlash, if enabled.
    pub backlash: Option<Backlash>,
    /// Measurement noise, if enabled.
    pub noise: Option<Noise>,
    /// Pose design.
    pub poses: PoseGrid,
    /// Loads.
    pub loads: Loads,
}

struct Checker<'a> {
    path: &'a Path,
}

impl Checker<'_> {
    fn fail<T>(&self, key: &str, message: impl Into<String>) -> Result<T> {
        Err(TwinError::InvalidValue {
            path: self.path.to_path_buf(),
            key: key.to_string(),
            message: message.into(),
        })
    }

    fn finite(&self, key: &str, values: &[f64]) -> Result<()> {
        if values.iter().all(|v| v.is_finite()) {
            Ok(())
        } else {
            self.fail(key, "must be finite numbers")
        }
    }

    fn per_joint(&self, key: &str, values: &[f64], n: usize) -> Result<()> {
        self.finite(key, values)?;
        if values.len() == n {
            Ok(())
        } else {
            self.fail(
                key,
                format!("needs one value per joint ({n}), found {}", values.len()),
            )
        }
    }

    fn non_negative(&self, key: &str, values: &[f64]) -> Result<()> {
        self.finite(key, values)?;
        if values.iter().all(|v| *v >= 0.0) {
            Ok(())
        } else {
            self.fail(key, "must not be negative")
        }
    }
}

fn rad(values: &[f64]) -> Vec<f64> {
    values.iter().map(|v| v.to_radians()).collect()
}

impl TwinConfig {
    /// Reads and validates a twin file; the nominal robot path is relative to the twin file.
    pub fn load(path: impl AsRef<Path>) -> Result<Self> {
        let path = path.as_ref();
        let text = std::fs::read_to_string(path).map_err(|source| TwinError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        let raw: RawTwin =
            toml::from_str(&text).map_err(|e| TwinError::Robot(toml_error(path, &text, &e)))?;
        let dir = path.parent().unwrap_or(Path::new("."));
        let nominal = Robot::load(dir.join(&raw.nominal))?;
        let truth = raw.truth.clone().validate(path, "truth.")?;
        Self::validate(path, nominal, truth, raw)
    }

    fn validate(path: &Path, nominal: Robot, truth: Robot, raw: RawTwin) -> Result<Self> {
        let c = Checker { path };
        let n = truth.dof();
        if nominal.dof() != n {
            return c.fail(
                "truth.joint",
                format!(
                    "the true robot has {n} joints, the nominal robot {}",
                    nominal.dof()
                ),
            );
        }
        c.finite("gravity", &raw.gravity)?;
        let compliance = if raw.compliance.enabled {
            let r = &raw.compliance;
            c.per_joint("compliance.stiffness", &r.stiffness, n)?;
            if r.stiffness.iter().any(|k| *k <= 0.0) {
                return c.fail(
                    "compliance.stiffness",
                    "stiffness must be positive (N·m/rad)",
                );
            }
            c.per_joint("compliance.link_mass", &r.link_mass, n)?;
            c.non_negative("compliance.link_mass", &r.link_mass)?;
            if r.link_com.len() != n {
                return c.fail(
                    "compliance.link_com",
                    format!("needs one [x, y, z] per joint ({n})"),
                );
            }
            c.finite("compliance.link_com", &r.link_com.concat())?;
            Some(Compliance {
                stiffness: r.stiffness.clone(),
                link_mass: r.link_mass.clone(),
                link_com: r.link_com.iter().map(|v| Vector3::from(*v)).collect(),
            })
        } else {
            None
        };
        let gear = if raw.gear.enabled {
            let g = &raw.gear;
            c.per_joint("gear.amplitude_1", &g.amplitude_1, n)?;
            c.per_joint("gear.phase_1", &g.phase_1, n)?;
            c.per_joint("gear.amplitude_2", &g.amplitude_2, n)?;
            c.per_joint("gear.phase_2", &g.phase_2, n)?;
            Some(Gear {
                amplitude_1: rad(&g.amplitude_1),
                phase_1: rad(&g.phase_1),
                amplitude_2: rad(&g.amplitude_2),
                phase_2: rad(&g.phase_2),
            })
        } else {
            None
        };
        let backlash = if raw.backlash.enabled {
            let b = &raw.backlash;
            if b.joint < 1 || b.joint > n {
                return c.fail("backlash.joint", format!("must be a joint number 1..{n}"));
            }
            c.non_negative("backlash.width", &[b.width])?;
            c.finite("backlash.home", &[b.home])?;
            Some(Backlash {
                joint: b.joint - 1,
                width: b.width.to_radians(),
                home: b.home.to_radians(),
            })
        } else {
            None
        };
        let noise = if raw.noise.enabled {
            let z = &raw.noise;
            c.non_negative("noise.tracker_base", &[z.tracker_base])?;
            c.non_negative("noise.tracker_per_metre", &[z.tracker_per_metre])?;
            c.non_negative("noise.repeatability", &[z.repeatability])?;
            Some(Noise {
                tracker_base: z.tracker_base,
                tracker_per_metre: z.tracker_per_metre,
                repeatability: z.repeatability,
            })
        } else {
            None
        };
        let p = &raw.poses;
        for (key, range) in [("poses.x", p.x), ("poses.y", p.y), ("poses.z", p.z)] {
            c.finite(key, &range)?;
            if range[0] > range[1] {
                return c.fail(key, "the lower end must not exceed the upper end");
            }
        }
        c.finite("poses.step", &[p.step])?;
        if p.step <= 0.0 {
            return c.fail("poses.step", "must be positive (mm)");
        }
        if p.count == 0 {
            return c.fail("poses.count", "must be at least 1");
        }
        c.per_joint("poses.home", &p.home, n)?;
        c.non_negative("poses.tilt", &[p.tilt])?;
        c.non_negative("poses.spin", &[p.spin])?;
        c.non_negative("poses.min_conditioning", &[p.min_conditioning])?;
        let l = &raw.loads;
        if l.trained.is_empty() {
            return c.fail("loads.trained", "needs at least one load");
        }
        c.non_negative("loads.trained", &l.trained)?;
        c.non_negative("loads.untrained", &l.untrained)?;
        let loads = Loads {
            trained: l.trained.clone(),
            untrained: l.untrained.clone(),
        };
        if loads.all().windows(2).any(|w| w[0] == w[1]) {
            return c.fail(
                "loads",
                "a load is listed twice (trained and untrained must be disjoint)",
            );
        }
        Ok(Self {
            name: raw.name.clone(),
            seed: raw.seed,
            source: path.to_path_buf(),
            nominal_path: raw.nominal.clone(),
            nominal,
            truth,
            gravity: Vector3::from(raw.gravity),
            compliance,
            gear,
            backlash,
            noise,
            poses: PoseGrid {
                x: p.x,
                y: p.y,
                z: p.z,
                step: p.step,
                count: p.count,
                home: rad(&p.home),
                tilt: p.tilt.to_radians(),
                spin: p.spin.to_radians(),
                min_conditioning: p.min_conditioning,
            },
            loads,
        })
    }

    /// The same twin with every non-geometric effect and the noise switched off.
    pub fn geometry_only(&self) -> Self {
        Self {
            compliance: None,
            gear: None,
            backlash: None,
            noise: None,
            ..self.clone()
        }
    }
}
