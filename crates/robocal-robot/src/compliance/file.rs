//! The file form of a joint-error model, `compliance.toml`.

use std::path::Path;

use nalgebra::Vector3;
use serde::{Deserialize, Serialize};

use super::backlash::{Backlash, Flank};
use super::gravity::MomentPart;
use super::harmonic::{Harmonic, MAX_HARMONIC_ORDER};
use super::model::{DEG_PER_KNM, JointErrors};
use super::runout::{Across, Runout};
use super::self_weight::{LinkWeight, SelfWeight};
use super::tilt::Tilt;
use crate::error::{Result, RobotError};
use crate::table::{file_value, toml_error};

/// `compliance.toml` as written: compliances in deg/(kN·m).
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawCompliance {
    /// Gravity in the robot's base frame {0}, m/s².
    #[serde(deserialize_with = "crate::exact::array")]
    pub gravity: [f64; 3],
    /// The payload's centre of mass in the flange frame, mm.
    #[serde(deserialize_with = "crate::exact::array")]
    pub payload_com: [f64; 3],
    /// One per joint, deg per kN·m (0: rigid).
    pub compliance: Vec<f64>,
    /// Transmission harmonics.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub harmonic: Vec<RawHarmonic>,
    /// Self-weight terms.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub self_weight: Vec<RawSelfWeight>,
    /// Backlash terms.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub backlash: Vec<RawBacklash>,
    /// The links' shared weights.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub link_weight: Vec<RawLinkWeight>,
    /// Tilting compliances.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub tilt: Vec<RawTilt>,
    /// Axis runouts.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub runout: Vec<RawRunout>,
}

/// `[[runout]]` as written.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawRunout {
    /// Joint, counted from 1.
    pub joint: usize,
    /// Order k.
    pub order: u32,
    /// `x` or `y`: the axis of the joint's link frame (turning with the joint) it turns about.
    pub across: Across,
    /// Sine coefficient, deg of turn.
    pub sin: f64,
    /// Cosine coefficient, deg of turn.
    pub cos: f64,
    /// `[lo, hi]`, deg, as a harmonic's.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reach: Option<[f64; 2]>,
}

/// `[[tilt]]` as written.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawTilt {
    /// Joint, counted from 1.
    pub joint: usize,
    /// Tilting compliance, deg per kN·m of the gravity moment across the joint's axis.
    pub compliance: f64,
}

/// `[[link_weight]]` as written.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawLinkWeight {
    /// Link, counted from 1 (link i moves with joint i).
    pub body: usize,
    /// `mass` (kg, at the link frame's origin), or `x`, `y`, `z` (first moments, kg·m).
    pub part: MomentPart,
    /// kg or kg·m.
    pub value: f64,
}

/// `[[backlash]]` as written: `home` (the flank of the approach from home) or `torque` (the flank
/// the torque presses), not both.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawBacklash {
    /// Joint, counted from 1.
    pub joint: usize,
    /// The reading the joint moves out from, deg.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub home: Option<f64>,
    /// The weights of the joint's gravity-torque features ([`Flank::Torque`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub torque: Option<Vec<f64>>,
    /// Half the play, deg: the joint error on the `+1` flank (at or above home; where the
    /// weighted torque is at least 0), its negative on the other.
    pub value: f64,
}

/// `[[harmonic]]` as written.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawHarmonic {
    /// Joint, counted from 1.
    pub joint: usize,
    /// Order k.
    pub order: u32,
    /// Sine coefficient, deg.
    pub sin: f64,
    /// Cosine coefficient, deg.
    pub cos: f64,
    /// `[lo, hi]`, deg: the joint angles over which the harmonic is continued periodically
    /// (beyond them, held at its value at the nearer end); absent: every angle.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reach: Option<[f64; 2]>,
}

/// `[[self_weight]]` as written.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawSelfWeight {
    /// Joint that deflects, counted from 1.
    pub joint: usize,
    /// Link whose weight, counted from 1 (link i moves with joint i), at least `joint`.
    pub body: usize,
    /// `mass`, `x`, `y` or `z`.
    pub part: MomentPart,
    /// Coefficient, deg per basis unit (N·m per kg for `mass`, per kg·m for the moments).
    pub value: f64,
}

/// The checks of a `compliance.toml` read for a robot with `dof` joints, each entry turned into
/// its term with the file's units converted.
pub(super) struct Check<'a> {
    pub(super) path: &'a Path,
    pub(super) dof: usize,
}

impl Check<'_> {
    /// The error for entry `key` of the file.
    fn invalid(&self, key: &str, message: String) -> RobotError {
        RobotError::InvalidValue {
            path: self.path.to_path_buf(),
            key: key.into(),
            message,
        }
    }

    /// One compliance per joint, gravity not zero, every value finite.
    fn compliances(&self, raw: &RawCompliance) -> Result<()> {
        let dof = self.dof;
        if raw.compliance.len() != dof {
            return Err(self.invalid(
                "compliance",
                format!(
                    "{} values for a robot with {dof} joints",
                    raw.compliance.len()
                ),
            ));
        }
        for (key, values) in [
            ("gravity", &raw.gravity[..]),
            ("payload_com", &raw.payload_com[..]),
            ("compliance", &raw.compliance[..]),
        ] {
            if values.iter().any(|v| !v.is_finite()) {
                return Err(self.invalid(key, "every value must be a finite number".into()));
            }
        }
        if raw.gravity.iter().all(|g| *g == 0.0) {
            return Err(self.invalid("gravity", "must not be zero".into()));
        }
        Ok(())
    }

    /// Entry `key`'s joint (counted from 1) as 0-based, when the robot has it.
    fn joint_of(&self, key: &str, joint: usize) -> Result<usize> {
        if (1..=self.dof).contains(&joint) {
            Ok(joint - 1)
        } else {
            Err(self.invalid(
                key,
                format!("joint {joint} of a robot with {} joints", self.dof),
            ))
        }
    }

    /// A term a joint may have once: refused for `joint` (0-based) when it has one `already`.
    fn once(&self, key: &str, joint: usize, already: bool, what: &str) -> Result<()> {
        if !already {
            Ok(())
        } else {
            Err(self.invalid(key, format!("joint {} has {what} already", joint + 1)))
        }
    }

    /// A harmonic (a transmission error's, or a runout's wave) as written, checked.
    fn wave(&self, key: &str, h: &RawHarmonic) -> Result<Harmonic> {
        let joint = self.joint_of(key, h.joint)?;
        if !(1..=MAX_HARMONIC_ORDER).contains(&h.order) {
            return Err(self.invalid(key, format!("order must lie in 1..={MAX_HARMONIC_ORDER}")));
        }
        if !(h.sin.is_finite() && h.cos.is_finite()) {
            return Err(self.invalid(key, "sin and cos must be finite numbers".into()));
        }
        if let Some([lo, hi]) = h.reach
            && !(lo.is_finite() && hi.is_finite() && lo <= hi)
        {
            return Err(self.invalid(
                &format!("{key}.reach"),
                format!("[{lo}, {hi}]: two finite angles (deg), the first not above the second"),
            ));
        }
        Ok(Harmonic {
            joint,
            order: h.order,
            sin: h.sin.to_radians(),
            cos: h.cos.to_radians(),
            reach: h.reach.map(|r| r.map(f64::to_radians)),
        })
    }

    /// The runouts, each order and axis across once per joint.
    fn runouts(&self, raw: &[RawRunout]) -> Result<Vec<Runout>> {
        let mut runouts: Vec<Runout> = Vec::with_capacity(raw.len());
        for (i, r) in raw.iter().enumerate() {
            let key = format!("runout[{}]", i + 1);
            let h = RawHarmonic {
                joint: r.joint,
                order: r.order,
                sin: r.sin,
                cos: r.cos,
                reach: r.reach,
            };
            let wave = self.wave(&key, &h)?;
            if (runouts.iter()).any(|o| {
                (o.wave.joint, o.wave.order, o.across) == (wave.joint, wave.order, r.across)
            }) {
                return Err(self.invalid(
                    &key,
                    format!(
                        "joint {} has a runout of order {} about {} already",
                        r.joint,
                        r.order,
                        r.across.name()
                    ),
                ));
            }
            runouts.push(Runout {
                across: r.across,
                wave,
            });
        }
        Ok(runouts)
    }

    /// The self-weight terms, each link at or beyond its joint.
    fn self_weight(&self, raw: &[RawSelfWeight]) -> Result<Vec<SelfWeight>> {
        let dof = self.dof;
        let mut self_weight = Vec::with_capacity(raw.len());
        for (i, t) in raw.iter().enumerate() {
            let key = format!("self_weight[{}]", i + 1);
            if !(1..=dof).contains(&t.joint) || !(t.joint..=dof).contains(&t.body) {
                return Err(self.invalid(
                    &key,
                    format!(
                        "joint {} and body {}: both 1..={dof}, the body at or beyond the joint",
                        t.joint, t.body
                    ),
                ));
            }
            if !t.value.is_finite() {
                return Err(self.invalid(&key, "value must be a finite number".into()));
            }
            self_weight.push(SelfWeight {
                joint: t.joint - 1,
                body: t.body - 1,
                part: t.part,
                value: t.value.to_radians(),
            });
        }
        Ok(self_weight)
    }

    /// The backlash terms, one per joint, each on one kind of flank.
    fn backlash(&self, raw: &[RawBacklash]) -> Result<Vec<Backlash>> {
        let mut backlash: Vec<Backlash> = Vec::with_capacity(raw.len());
        for (i, b) in raw.iter().enumerate() {
            let key = format!("backlash[{}]", i + 1);
            let joint = self.joint_of(&key, b.joint)?;
            let already = backlash.iter().any(|b| b.joint == joint);
            self.once(&key, joint, already, "a backlash term")?;
            if !b.value.is_finite() {
                return Err(self.invalid(&key, "value must be a finite number".into()));
            }
            backlash.push(Backlash {
                joint,
                flank: self.flank(&key, b, joint)?,
                value: b.value.to_radians(),
            });
        }
        Ok(backlash)
    }

    /// The flank of backlash entry `b` of joint `joint` (0-based): its home or its torque
    /// weights, one of them.
    fn flank(&self, key: &str, b: &RawBacklash, joint: usize) -> Result<Flank> {
        let features = JointErrors::torque_feature_count(self.dof, joint);
        match (b.home, &b.torque) {
            (Some(home), None) if home.is_finite() => Ok(Flank::Approach {
                home: home.to_radians(),
            }),
            (None, Some(w)) if w.len() == features && w.iter().all(|w| w.is_finite()) => {
                Ok(Flank::Torque { weights: w.clone() })
            }
            (Some(_), None) => Err(self.invalid(key, "home must be a finite number (deg)".into())),
            (None, Some(w)) => Err(self.invalid(
                key,
                format!(
                    "torque lists {} weights: joint {} of a robot with {} joints has {features} finite ones (4 per link from the joint's outwards, 4 for the payload, the preload's)",
                    w.len(),
                    b.joint,
                    self.dof
                ),
            )),
            _ => Err(self.invalid(
                key,
                "give home (the flank of the approach from home) or torque (the flank the torque presses), one of them".into(),
            )),
        }
    }

    /// The shared link weights.
    fn link_weights(&self, raw: &[RawLinkWeight]) -> Result<Vec<LinkWeight>> {
        let mut link_weights = Vec::with_capacity(raw.len());
        for (i, w) in raw.iter().enumerate() {
            let key = format!("link_weight[{}]", i + 1);
            if !(1..=self.dof).contains(&w.body) {
                return Err(self.invalid(
                    &key,
                    format!("body {} of a robot with {} links", w.body, self.dof),
                ));
            }
            if !w.value.is_finite() {
                return Err(self.invalid(&key, "value must be a finite number".into()));
            }
            link_weights.push(LinkWeight {
                body: w.body - 1,
                part: w.part,
                value: w.value,
            });
        }
        Ok(link_weights)
    }

    /// The tilting compliances, one per joint.
    fn tilts(&self, raw: &[RawTilt]) -> Result<Vec<Tilt>> {
        let mut tilts: Vec<Tilt> = Vec::with_capacity(raw.len());
        for (i, t) in raw.iter().enumerate() {
            let key = format!("tilt[{}]", i + 1);
            let joint = self.joint_of(&key, t.joint)?;
            let already = tilts.iter().any(|t| t.joint == joint);
            self.once(&key, joint, already, "a tilting compliance")?;
            if !t.compliance.is_finite() {
                return Err(self.invalid(&key, "compliance must be a finite number".into()));
            }
            tilts.push(Tilt {
                joint,
                value: t.compliance * DEG_PER_KNM,
            });
        }
        Ok(tilts)
    }
}

impl JointErrors {
    /// Parses `compliance.toml` for a robot with `dof` joints.
    pub fn from_toml_str(text: &str, path: impl AsRef<Path>, dof: usize) -> Result<Self> {
        let path = path.as_ref();
        let raw: RawCompliance = toml::from_str(text).map_err(|e| toml_error(path, text, &e))?;
        let check = Check { path, dof };
        check.compliances(&raw)?;
        let harmonics = (raw.harmonic.iter().enumerate())
            .map(|(i, h)| check.wave(&format!("harmonic[{}]", i + 1), h))
            .collect::<Result<Vec<_>>>()?;
        // One order of checks, so that a file with several faults names the same one first.
        let runouts = check.runouts(&raw.runout)?;
        let self_weight = check.self_weight(&raw.self_weight)?;
        let backlash = check.backlash(&raw.backlash)?;
        let link_weights = check.link_weights(&raw.link_weight)?;
        let tilts = check.tilts(&raw.tilt)?;
        Ok(Self {
            values: raw.compliance.iter().map(|c| c * DEG_PER_KNM).collect(),
            gravity: Vector3::from(raw.gravity),
            payload_com: Vector3::from(raw.payload_com),
            harmonics,
            self_weight,
            backlash,
            link_weights,
            tilts,
            runouts,
        })
    }

    /// Reads `compliance.toml` for a robot with `dof` joints.
    pub fn load(path: impl AsRef<Path>, dof: usize) -> Result<Self> {
        let path = path.as_ref();
        let text = std::fs::read_to_string(path).map_err(|source| RobotError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        Self::from_toml_str(&text, path, dof)
    }

    /// The file form, with a header saying what the numbers mean.
    pub fn to_toml_string(&self) -> String {
        // Every number as the one that reads back exactly (the loader's conversions inverted).
        let deg = |v: f64| file_value(v, f64::to_degrees, f64::to_radians);
        let knm = |c: f64| file_value(c, |c| c / DEG_PER_KNM, |c| c * DEG_PER_KNM);
        let raw = RawCompliance {
            gravity: self.gravity.into(),
            payload_com: self.payload_com.into(),
            compliance: self.values.iter().map(|&c| knm(c)).collect(),
            harmonic: (self.harmonics.iter())
                .map(|h| RawHarmonic {
                    joint: h.joint + 1,
                    order: h.order,
                    sin: deg(h.sin),
                    cos: deg(h.cos),
                    reach: h.reach.map(|r| r.map(deg)),
                })
                .collect(),
            self_weight: (self.self_weight.iter())
                .map(|t| RawSelfWeight {
                    joint: t.joint + 1,
                    body: t.body + 1,
                    part: t.part,
                    value: deg(t.value),
                })
                .collect(),
            backlash: (self.backlash.iter())
                .map(|b| RawBacklash {
                    joint: b.joint + 1,
                    home: b.home().map(deg),
                    torque: match &b.flank {
                        Flank::Torque { weights } => Some(weights.clone()),
                        Flank::Approach { .. } => None,
                    },
                    value: deg(b.value),
                })
                .collect(),
            link_weight: (self.link_weights.iter())
                .map(|w| RawLinkWeight {
                    body: w.body + 1,
                    part: w.part,
                    value: w.value,
                })
                .collect(),
            tilt: (self.tilts.iter())
                .map(|t| RawTilt {
                    joint: t.joint + 1,
                    compliance: knm(t.value),
                })
                .collect(),
            runout: (self.runouts.iter())
                .map(|r| RawRunout {
                    joint: r.wave.joint + 1,
                    order: r.wave.order,
                    across: r.across,
                    sin: deg(r.wave.sin),
                    cos: deg(r.wave.cos),
                    reach: r.wave.reach.map(|v| v.map(deg)),
                })
                .collect(),
        };
        let body = toml::to_string(&raw).unwrap_or_default();
        let more = if self.has_configuration_terms() {
            "# harmonic: transmission error of a joint, sin · sin(order q) + cos · cos(order q), deg;\n\
             # reach = [lo, hi] (deg): beyond it, q is held at the nearer end (the readings it was\n\
             # identified on, widened by a quarter of their span at each end); without a reach the\n\
             # harmonic is continued at every angle.\n\
             # self_weight: value (deg per unit) × the gravity torque about the joint of a unit mass\n\
             # (part = mass, N·m per kg) or first moment (x, y, z: N·m per kg·m) of link `body`.\n\
             # backlash: the joint rests on one flank of its play, error +value (deg, half the\n\
             # play) on one, -value on the other: with `home` (deg), the flank of its approach\n\
             # from home (+ at or above it); with `torque`, the flank its torque presses (+ where\n\
             # the weights times the features are at least 0: for each link from the joint's\n\
             # outwards the gravity torques of a unit mass at its frame's origin and of unit first\n\
             # moments along x, y, z, then the same of the flange frame times the load, then 1).\n\
             # link_weight: the weight of link `body` shared by every joint up to it: its mass\n\
             # (part = mass, kg, at the link frame's origin) or first moment (x, y, z: kg·m along\n\
             # the link frame's axes); each joint deflects by its compliance × the gravity torque\n\
             # of the payload and of these weights.\n"
        } else {
            ""
        };
        let tilt = if self.tilts.is_empty() {
            ""
        } else {
            "# tilt: the parts beyond the joint turn about its origin, across its axis, by\n\
             # compliance (deg per kN·m) × the gravity moment across the axis of the payload and\n\
             # of the link weights beyond it.\n"
        };
        let runout = if self.runouts.is_empty() {
            ""
        } else {
            "# runout: the parts beyond the joint turn about its origin, across its axis, by\n\
             # sin · sin(order q) + cos · cos(order q) (deg) about the axis `across` (x or y) of\n\
             # the joint's link frame, which turns with the joint; reach as a harmonic's.\n"
        };
        format!(
            "# Joint compliance under the payload, identified by robocal: joint deflection =\n\
             # compliance × gravity torque of the payload (deg per kN·m, one per joint; 0 = rigid).\n\
             # gravity: m/s² in the robot base frame {{0}}; payload_com: mm in the flange frame.\n{more}{tilt}{runout}{body}"
        )
    }
}
