//! The twin description (TOML): raw form with `deny_unknown_fields`, validated once into
//! [`TwinConfig`]. Units: mm, deg, kg, N·m/rad, m/s².

use std::path::{Path, PathBuf};

use nalgebra::Vector3;
use robocal_robot::{Robot, RobotTable, TomlFault};
use serde::Deserialize;

use crate::error::{Result, TwinError};

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawTwin {
    name: String,
    seed: u64,
    nominal: PathBuf,
    truth: RobotTable,
    #[serde(deserialize_with = "robocal_robot::exact::array")]
    gravity: [f64; 3],
    masses: RawMasses,
    compliance: RawCompliance,
    gear: RawGear,
    #[serde(default)]
    backlash: Vec<RawBacklash>,
    #[serde(default)]
    beyond: Option<RawBeyond>,
    #[serde(default)]
    motion: Option<RawMotion>,
    noise: RawNoise,
    poses: RawPoses,
    loads: RawLoads,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawMasses {
    link_mass: Vec<f64>,
    #[serde(deserialize_with = "robocal_robot::exact::arrays")]
    link_com: Vec<[f64; 3]>,
    #[serde(deserialize_with = "robocal_robot::exact::array")]
    payload_com: [f64; 3],
}

/// Play that follows the order of motion: `[motion] play = [deg, …]`, one per joint.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawMotion {
    play: Vec<f64>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawCompliance {
    enabled: bool,
    stiffness: Vec<f64>,
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
    side: String,
    home: Option<f64>,
    preload: Option<f64>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawBeyond {
    enabled: bool,
    tilt_stiffness: Vec<f64>,
    wobble: Vec<f64>,
    wobble_phase: Vec<f64>,
    harmonic_3: Vec<f64>,
    phase_3: Vec<f64>,
    coupling: Vec<f64>,
    coupling_phase: Vec<f64>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawNoise {
    enabled: bool,
    tracker_base: f64,
    tracker_per_metre: f64,
    repeatability: f64,
    #[serde(default)]
    probe_deg: Option<f64>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawPoses {
    #[serde(deserialize_with = "robocal_robot::exact::array")]
    x: [f64; 2],
    #[serde(deserialize_with = "robocal_robot::exact::array")]
    y: [f64; 2],
    #[serde(deserialize_with = "robocal_robot::exact::array")]
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

/// The links' masses: what gravity pulls on besides the payload.
#[derive(Debug, Clone, PartialEq)]
pub struct Masses {
    /// Mass of link i (moved by joint i), kg.
    pub link_mass: Vec<f64>,
    /// Centre of mass of link i in its frame {i}, mm.
    pub link_com: Vec<Vector3<f64>>,
    /// Centre of mass of the payload in the flange frame {n}, mm.
    pub payload_com: Vector3<f64>,
}

/// The twin's true joint stiffness: deflection = gravity torque / stiffness (robocal identifies
/// its inverse, the compliance, as `robocal_robot::Compliance`).
#[derive(Debug, Clone, PartialEq)]
pub struct Stiffness {
    /// Joint stiffness, N·m/rad, one per joint (> 0).
    pub stiffness: Vec<f64>,
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

/// What decides the flank a joint with backlash rests on.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum BacklashSide {
    /// The side of `home` (rad) the joint moved out to: `+width/2` at or above it.
    Approach {
        /// Home reading the joint moves out from, rad.
        home: f64,
    },
    /// The sense of the torque on the joint: a constant `preload` (N·m: cable harness, motor
    /// offsets) plus the gravity torque of the links and the payload. `+width/2` when it is
    /// positive or zero. Unloaded, the preload decides; a payload held on the other side can
    /// flip it.
    Torque {
        /// Torque on the joint besides gravity's, N·m.
        preload: f64,
    },
}

/// Backlash of one joint: the joint rests on one flank of its play, `±width/2`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Backlash {
    /// 0-based joint index.
    pub joint: usize,
    /// Total play, rad.
    pub width: f64,
    /// Which flank.
    pub side: BacklashSide,
}

/// Effects a real arm has and robocal's physical model family does not hold: what a learned
/// residual model is there for. Each is zero (off) for a joint whose value is 0.
#[derive(Debug, Clone, PartialEq)]
pub struct Beyond {
    /// Tilting (moment) stiffness of each joint's bearing and reducer, N·m/rad (0: rigid): the
    /// gravity moment of the links and payload beyond the joint, across its axis, tilts them by
    /// moment / stiffness about the joint's origin. robocal's compliances turn joints about
    /// their axes only.
    pub tilt_stiffness: Vec<f64>,
    /// Axis runout at twice the joint angle, rad: the parts beyond joint i tilt across its axis
    /// by `wobble_i` in the direction `2 q_i + φ_i` of the link frame's x–y plane.
    pub wobble: Vec<f64>,
    /// Phase of the runout, rad.
    pub wobble_phase: Vec<f64>,
    /// Third harmonic of the transmission error, rad: `A3 sin(3q + φ3)` (robocal's default
    /// identifies orders 1 and 2).
    pub harmonic_3: Vec<f64>,
    /// Phase of the third harmonic, rad.
    pub phase_3: Vec<f64>,
    /// Transmission error of joint i driven through joint i−1 (a wrist's coupled gearing),
    /// rad: `C_i sin(q_i + q_(i−1) + ψ_i)`; joint 1's must be 0.
    pub coupling: Vec<f64>,
    /// Phase of the coupled error, rad.
    pub coupling_phase: Vec<f64>,
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
    /// A 6-DoF probe's angular noise, deg (1σ about each world axis); used when the truth
    /// declares `[tool] rpy` (the probe's frame). Default [`DEFAULT_PROBE_DEG`].
    pub probe_deg: f64,
}

/// A 6-DoF probe's angular noise when the twin file gives none, deg (1σ per axis): the order of
/// a tracker's 6-DoF probe.
pub const DEFAULT_PROBE_DEG: f64 = 0.01;

impl Noise {
    /// Per-coordinate standard deviation of a measurement of a point `distance_mm` from the
    /// tracker, mm.
    pub fn sigma(&self, distance_mm: f64) -> f64 {
        let (tracker, robot) = (self.tracker_sigma(distance_mm), self.robot_sigma());
        (tracker * tracker + robot * robot).sqrt()
    }

    /// The tracker's part of [`Self::sigma`], mm.
    pub fn tracker_sigma(&self, distance_mm: f64) -> f64 {
        self.tracker_base + self.tracker_per_metre * distance_mm / 1000.0
    }

    /// The robot's repeatability part of [`Self::sigma`], mm per coordinate.
    pub fn robot_sigma(&self) -> f64 {
        self.repeatability / 3.6
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

impl PoseGrid {
    /// The grid laid all around the base: x and y each over ± the grid's largest reach along
    /// either, the other settings kept, `count` configurations. Joint 1 then spans its whole
    /// turn (the accuracy suite's window split, and the tests of how far a model carries beyond
    /// joint 1's readings).
    pub fn around_base(&self, count: usize) -> Self {
        let r = [self.x[0], self.x[1], self.y[0], self.y[1]]
            .iter()
            .fold(0.0f64, |m, v| m.max(v.abs()));
        Self {
            x: [-r, r],
            y: [-r, r],
            count,
            ..self.clone()
        }
    }
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
    /// The links' masses (gravity torques exist whether or not the joints give under them).
    pub masses: Masses,
    /// Joint compliance, if enabled.
    pub compliance: Option<Stiffness>,
    /// Gear transmission error, if enabled.
    pub gear: Option<Gear>,
    /// Backlash of the joints that have play (enabled entries, one per joint at most).
    pub backlash: Vec<Backlash>,
    /// Effects beyond robocal's model family, if enabled.
    pub beyond: Option<Beyond>,
    /// Play that follows the order of motion, deg per joint (`[motion] play`): the poses are
    /// measured in the order generated, each row's joints standing this far behind their
    /// readings in the direction of their last move, and the rows carry their `seq`.
    pub motion: Option<Vec<f64>>,
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

    /// The links' masses and the payload's centre of mass.
    fn masses(&self, m: &RawMasses, n: usize) -> Result<Masses> {
        self.per_joint("masses.link_mass", &m.link_mass, n)?;
        self.non_negative("masses.link_mass", &m.link_mass)?;
        if m.link_com.len() != n {
            return self.fail(
                "masses.link_com",
                format!("needs one [x, y, z] per joint ({n})"),
            );
        }
        self.finite("masses.link_com", &m.link_com.concat())?;
        self.finite("masses.payload_com", &m.payload_com)?;
        Ok(Masses {
            link_mass: m.link_mass.clone(),
            link_com: m.link_com.iter().map(|v| Vector3::from(*v)).collect(),
            payload_com: Vector3::from(m.payload_com),
        })
    }

    /// The joints' stiffness, where enabled.
    fn compliance(&self, r: &RawCompliance, n: usize) -> Result<Option<Stiffness>> {
        if r.enabled {
            self.per_joint("compliance.stiffness", &r.stiffness, n)?;
            if r.stiffness.iter().any(|k| *k <= 0.0) {
                return self.fail(
                    "compliance.stiffness",
                    "stiffness must be positive (N·m/rad)",
                );
            }
            Ok(Some(Stiffness {
                stiffness: r.stiffness.clone(),
            }))
        } else {
            Ok(None)
        }
    }

    /// The gears' transmission error, where enabled.
    fn gear(&self, g: &RawGear, n: usize) -> Result<Option<Gear>> {
        Ok(if g.enabled {
            self.per_joint("gear.amplitude_1", &g.amplitude_1, n)?;
            self.per_joint("gear.phase_1", &g.phase_1, n)?;
            self.per_joint("gear.amplitude_2", &g.amplitude_2, n)?;
            self.per_joint("gear.phase_2", &g.phase_2, n)?;
            Some(Gear {
                amplitude_1: rad(&g.amplitude_1),
                phase_1: rad(&g.phase_1),
                amplitude_2: rad(&g.amplitude_2),
                phase_2: rad(&g.phase_2),
            })
        } else {
            None
        })
    }

    /// The joints' backlash, each joint once.
    fn backlash(&self, raw: &[RawBacklash], n: usize) -> Result<Vec<Backlash>> {
        let mut backlash: Vec<Backlash> = Vec::new();
        for (i, b) in raw.iter().enumerate() {
            if !b.enabled {
                continue;
            }
            let key = |field: &str| format!("backlash[{}].{field}", i + 1);
            if b.joint < 1 || b.joint > n {
                return self.fail(&key("joint"), format!("must be a joint number 1..{n}"));
            }
            self.non_negative(&key("width"), &[b.width])?;
            let side = match (b.side.as_str(), b.home, b.preload) {
                ("approach", Some(home), None) => {
                    self.finite(&key("home"), &[home])?;
                    BacklashSide::Approach {
                        home: home.to_radians(),
                    }
                }
                ("torque", None, Some(preload)) => {
                    self.finite(&key("preload"), &[preload])?;
                    BacklashSide::Torque { preload }
                }
                ("approach", _, _) => {
                    return self.fail(
                        &key("side"),
                        "side = \"approach\" needs `home` (deg) and no `preload`",
                    );
                }
                ("torque", _, _) => {
                    return self.fail(
                        &key("side"),
                        "side = \"torque\" needs `preload` (N·m) and no `home`",
                    );
                }
                (other, _, _) => {
                    return self.fail(
                        &key("side"),
                        format!("unknown side rule `{other}`: use \"approach\" or \"torque\""),
                    );
                }
            };
            if backlash.iter().any(|other| other.joint == b.joint - 1) {
                return self.fail(&key("joint"), "this joint already has a backlash entry");
            }
            backlash.push(Backlash {
                joint: b.joint - 1,
                width: b.width.to_radians(),
                side,
            });
        }
        Ok(backlash)
    }

    /// The effects beyond the model's family, where enabled.
    fn beyond(&self, raw: Option<&RawBeyond>, n: usize) -> Result<Option<Beyond>> {
        Ok(match raw {
            Some(b) if b.enabled => {
                self.per_joint("beyond.tilt_stiffness", &b.tilt_stiffness, n)?;
                self.non_negative("beyond.tilt_stiffness", &b.tilt_stiffness)?;
                for (key, values) in [
                    ("beyond.wobble", &b.wobble),
                    ("beyond.wobble_phase", &b.wobble_phase),
                    ("beyond.harmonic_3", &b.harmonic_3),
                    ("beyond.phase_3", &b.phase_3),
                    ("beyond.coupling", &b.coupling),
                    ("beyond.coupling_phase", &b.coupling_phase),
                ] {
                    self.per_joint(key, values, n)?;
                }
                if b.coupling.first().is_some_and(|v| *v != 0.0) {
                    return self.fail(
                        "beyond.coupling",
                        "joint 1 has no joint before it to be driven through: its value must be 0",
                    );
                }
                Some(Beyond {
                    tilt_stiffness: b.tilt_stiffness.clone(),
                    wobble: rad(&b.wobble),
                    wobble_phase: rad(&b.wobble_phase),
                    harmonic_3: rad(&b.harmonic_3),
                    phase_3: rad(&b.phase_3),
                    coupling: rad(&b.coupling),
                    coupling_phase: rad(&b.coupling_phase),
                })
            }
            _ => None,
        })
    }

    /// The tracker's noise and the arm's repeatability, where enabled.
    fn noise(&self, z: &RawNoise) -> Result<Option<Noise>> {
        Ok(if z.enabled {
            self.non_negative("noise.tracker_base", &[z.tracker_base])?;
            self.non_negative("noise.tracker_per_metre", &[z.tracker_per_metre])?;
            self.non_negative("noise.repeatability", &[z.repeatability])?;
            let probe_deg = z.probe_deg.unwrap_or(DEFAULT_PROBE_DEG);
            self.non_negative("noise.probe_deg", &[probe_deg])?;
            Some(Noise {
                tracker_base: z.tracker_base,
                tracker_per_metre: z.tracker_per_metre,
                repeatability: z.repeatability,
                probe_deg,
            })
        } else {
            None
        })
    }

    /// The grid of poses.
    fn poses(&self, p: &RawPoses, n: usize) -> Result<PoseGrid> {
        for (key, range) in [("poses.x", p.x), ("poses.y", p.y), ("poses.z", p.z)] {
            self.finite(key, &range)?;
            if range[0] > range[1] {
                return self.fail(key, "the lower end must not exceed the upper end");
            }
        }
        self.finite("poses.step", &[p.step])?;
        if p.step <= 0.0 {
            return self.fail("poses.step", "must be positive (mm)");
        }
        if p.count == 0 {
            return self.fail("poses.count", "must be at least 1");
        }
        self.per_joint("poses.home", &p.home, n)?;
        self.non_negative("poses.tilt", &[p.tilt])?;
        self.non_negative("poses.spin", &[p.spin])?;
        self.non_negative("poses.min_conditioning", &[p.min_conditioning])?;
        Ok(PoseGrid {
            x: p.x,
            y: p.y,
            z: p.z,
            step: p.step,
            count: p.count,
            home: rad(&p.home),
            tilt: p.tilt.to_radians(),
            spin: p.spin.to_radians(),
            min_conditioning: p.min_conditioning,
        })
    }

    /// The loads, trained and untrained, none twice.
    fn loads(&self, l: &RawLoads) -> Result<Loads> {
        if l.trained.is_empty() {
            return self.fail("loads.trained", "needs at least one load");
        }
        self.non_negative("loads.trained", &l.trained)?;
        self.non_negative("loads.untrained", &l.untrained)?;
        let loads = Loads {
            trained: l.trained.clone(),
            untrained: l.untrained.clone(),
        };
        if loads.all().windows(2).any(|w| w[0] == w[1]) {
            return self.fail(
                "loads",
                "a load is listed twice (trained and untrained must be disjoint)",
            );
        }
        Ok(loads)
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
            toml::from_str(&text).map_err(|e| TwinError::Toml(TomlFault::of(path, &text, &e)))?;
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
        let masses = c.masses(&raw.masses, n)?;
        let compliance = c.compliance(&raw.compliance, n)?;
        let gear = c.gear(&raw.gear, n)?;
        let backlash = c.backlash(&raw.backlash, n)?;
        let beyond = c.beyond(raw.beyond.as_ref(), n)?;
        let motion = match &raw.motion {
            Some(m) if m.play.len() != n => {
                return c.fail(
                    "motion.play",
                    format!("{} values for a robot with {n} joints", m.play.len()),
                );
            }
            Some(m) => {
                c.finite("motion.play", &m.play)?;
                Some(m.play.clone())
            }
            None => None,
        };
        let noise = c.noise(&raw.noise)?;
        let poses = c.poses(&raw.poses, n)?;
        let loads = c.loads(&raw.loads)?;
        Ok(Self {
            name: raw.name.clone(),
            seed: raw.seed,
            source: path.to_path_buf(),
            nominal_path: raw.nominal.clone(),
            nominal,
            truth,
            gravity: Vector3::from(raw.gravity),
            masses,
            compliance,
            gear,
            backlash,
            beyond,
            motion,
            noise,
            poses,
            loads,
        })
    }

    /// The same twin with every non-geometric effect and the noise switched off.
    pub fn geometry_only(&self) -> Self {
        Self {
            compliance: None,
            gear: None,
            backlash: Vec::new(),
            beyond: None,
            motion: None,
            noise: None,
            ..self.clone()
        }
    }
}
