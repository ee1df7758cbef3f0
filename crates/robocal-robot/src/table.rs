//! The robot table (modified DH with optional Hayati β), its TOML form and validation.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use nalgebra::Vector3;
use serde::{Deserialize, Serialize};

use crate::error::{Result, RobotError};

/// One revolute joint of a modified-DH table.
///
/// The transform from link frame {i-1} to {i} is
/// `RotX(alpha) * TransX(a) * RotY(beta) * RotZ(theta + q) * TransZ(d)`.
#[derive(Debug, Clone, PartialEq)]
pub struct Joint {
    /// a_{i-1}, mm.
    pub a: f64,
    /// alpha_{i-1}, rad.
    pub alpha: f64,
    /// beta_{i-1} (Hayati), rad; `None` means the joint has no β parameter (fixed at 0).
    pub beta: Option<f64>,
    /// d_i, mm.
    pub d: f64,
    /// theta_i offset added to the joint reading, rad.
    pub theta: f64,
    /// Joint limits `(lower, upper)` on the joint reading, rad.
    pub limits: Option<(f64, f64)>,
}

/// Measurement (world / tracker) frame to robot base frame {0}.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Base {
    /// Position of the base origin in the world frame, mm.
    pub xyz: Vector3<f64>,
    /// Fixed-axis roll, pitch, yaw, rad: `R = RotZ(yaw) * RotY(pitch) * RotX(roll)`.
    pub rpy: Vector3<f64>,
}

/// A robot: a kinematic table, its base in the world frame and the measured point on the flange.
///
/// A `Robot` is a plain value; kinematics are pure functions of `(robot, joints)`.
#[derive(Debug, Clone, PartialEq)]
pub struct Robot {
    /// Free-form name.
    pub name: String,
    /// Joints, base to tip (at least one).
    pub joints: Vec<Joint>,
    /// World frame to base frame.
    pub base: Base,
    /// Measured target point in the flange frame {n}, mm: the default point, which rows
    /// without a `target` measure.
    pub tool: Vector3<f64>,
    /// Further named points on the flange (reflectors), flange frame, mm, in name order
    /// (`[tool.points]`): a row whose `target` names one measures it.
    pub points: Vec<(String, Vector3<f64>)>,
    /// Orientation of the tool frame in the flange frame, fixed-axis roll, pitch, yaw, rad
    /// (`[tool] rpy`): the frame a 6-DoF probe reports. `None`: the table says nothing of it (the
    /// tool frame is the flange's, and its angles are no parameters).
    pub tool_rpy: Option<Vector3<f64>>,
}

/// The robot file as written (mm, degrees), before validation. Other configuration files embed
/// it (e.g. a twin's true robot) and validate it with [`RobotTable::validate`].
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RobotTable {
    /// Free-form name.
    pub name: String,
    /// Joints, base to tip.
    #[serde(default)]
    pub joint: Vec<RawJoint>,
    /// `[base]`.
    pub base: RawBase,
    /// `[tool]`.
    pub tool: RawTool,
}

/// One `[[joint]]` as written.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawJoint {
    /// a_{i-1}, mm.
    pub a: f64,
    /// alpha_{i-1}, deg.
    pub alpha: f64,
    /// Optional Hayati beta_{i-1}, deg.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub beta: Option<f64>,
    /// d_i, mm.
    pub d: f64,
    /// theta_i offset, deg.
    pub theta: f64,
    /// Optional limits, deg.
    #[serde(
        default,
        skip_serializing_if = "Option::is_none",
        deserialize_with = "crate::exact::option"
    )]
    pub limits: Option<[f64; 2]>,
}

/// `[base]` as written.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawBase {
    /// mm.
    #[serde(deserialize_with = "crate::exact::array")]
    pub xyz: [f64; 3],
    /// Roll, pitch, yaw, deg.
    #[serde(deserialize_with = "crate::exact::array")]
    pub rpy: [f64; 3],
}

/// `[tool]` as written.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawTool {
    /// mm, flange frame.
    #[serde(deserialize_with = "crate::exact::array")]
    pub xyz: [f64; 3],
    /// Tool frame orientation in the flange frame, roll, pitch, yaw, deg (6-DoF probe).
    #[serde(
        default,
        skip_serializing_if = "Option::is_none",
        deserialize_with = "crate::exact::option"
    )]
    pub rpy: Option<[f64; 3]>,
    /// `[tool.points]`: named points, mm, flange frame.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub points: BTreeMap<String, RawPoint>,
}

/// One named point as written: `[x, y, z]`, mm.
#[derive(Debug, Clone, Copy, Serialize, Deserialize)]
pub struct RawPoint(#[serde(deserialize_with = "crate::exact::array")] pub [f64; 3]);

/// Converts a byte offset in `text` to a 1-based (line, column).
pub(crate) fn line_column(text: &str, offset: usize) -> (usize, usize) {
    let offset = offset.min(text.len());
    let before = &text[..offset];
    let line = before.matches('\n').count() + 1;
    let column = before.rfind('\n').map_or(offset, |nl| offset - nl - 1) + 1;
    (line, column)
}

/// Where a TOML file went wrong, for any crate's error type (a variant that wraps it): the file,
/// the 1-based line and column of the offending text and the parser's message on one line.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{}: line {line}, column {column}: {message}", path.display())]
pub struct TomlFault {
    /// File at fault.
    pub path: PathBuf,
    /// 1-based line.
    pub line: usize,
    /// 1-based column.
    pub column: usize,
    /// What the TOML parser said.
    pub message: String,
}

impl TomlFault {
    /// The fault of a `toml` deserialisation error in `text`, the contents of `path`.
    pub fn of(path: &Path, text: &str, err: &toml::de::Error) -> Self {
        let (line, column) = err
            .span()
            .map_or((1, 1), |span| line_column(text, span.start));
        Self {
            path: path.to_path_buf(),
            line,
            column,
            message: err.message().trim().replace('\n', " "),
        }
    }
}

/// Turns a `toml` deserialisation error into a [`RobotError::Toml`] naming the file, line and column.
pub fn toml_error(path: &Path, text: &str, err: &toml::de::Error) -> RobotError {
    let TomlFault {
        path,
        line,
        column,
        message,
    } = TomlFault::of(path, text, err);
    RobotError::Toml {
        path,
        line,
        column,
        message,
    }
}

fn check_finite(path: &Path, key: String, values: &[f64]) -> Result<()> {
    if values.iter().all(|v| v.is_finite()) {
        Ok(())
    } else {
        Err(RobotError::InvalidValue {
            path: path.to_path_buf(),
            key,
            message: "must be a finite number (nan and inf are not accepted)".into(),
        })
    }
}

impl Robot {
    /// Reads and validates a robot file (`docs/formats.md`, "Robot table").
    pub fn load(path: impl AsRef<Path>) -> Result<Self> {
        let path = path.as_ref();
        let text = std::fs::read_to_string(path).map_err(|source| RobotError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        Self::from_toml_str(&text, path)
    }

    /// Parses and validates a robot table; `path` is only used to name the source in errors.
    pub fn from_toml_str(text: &str, path: impl AsRef<Path>) -> Result<Self> {
        let path = path.as_ref();
        let raw: RobotTable = toml::from_str(text).map_err(|e| toml_error(path, text, &e))?;
        raw.validate(path, "")
    }
}

impl RobotTable {
    /// Validates the table into a [`Robot`]; `prefix` is put before key names in errors (e.g.
    /// `truth.` when the table is embedded under `[truth]`).
    pub fn validate(self, path: &Path, prefix: &str) -> Result<Robot> {
        let raw = self;
        if raw.joint.is_empty() {
            return Err(RobotError::NoJoints {
                path: path.to_path_buf(),
            });
        }
        let mut joints = Vec::with_capacity(raw.joint.len());
        for (i, j) in raw.joint.iter().enumerate() {
            let key = |field: &str| format!("{prefix}joint[{}].{field}", i + 1);
            check_finite(path, key("a"), &[j.a])?;
            check_finite(path, key("alpha"), &[j.alpha])?;
            check_finite(path, key("d"), &[j.d])?;
            check_finite(path, key("theta"), &[j.theta])?;
            if let Some(b) = j.beta {
                check_finite(path, key("beta"), &[b])?;
            }
            let limits = match j.limits {
                Some([lo, hi]) => {
                    check_finite(path, key("limits"), &[lo, hi])?;
                    if lo >= hi {
                        return Err(RobotError::InvalidValue {
                            path: path.to_path_buf(),
                            key: key("limits"),
                            message: format!("lower limit {lo} must be below upper limit {hi}"),
                        });
                    }
                    Some((lo.to_radians(), hi.to_radians()))
                }
                None => None,
            };
            joints.push(Joint {
                a: j.a,
                alpha: j.alpha.to_radians(),
                beta: j.beta.map(f64::to_radians),
                d: j.d,
                theta: j.theta.to_radians(),
                limits,
            });
        }
        check_finite(path, format!("{prefix}base.xyz"), &raw.base.xyz)?;
        check_finite(path, format!("{prefix}base.rpy"), &raw.base.rpy)?;
        check_finite(path, format!("{prefix}tool.xyz"), &raw.tool.xyz)?;
        if let Some(rpy) = &raw.tool.rpy {
            check_finite(path, format!("{prefix}tool.rpy"), rpy)?;
        }
        let mut points = Vec::with_capacity(raw.tool.points.len());
        for (name, RawPoint(xyz)) in &raw.tool.points {
            let key = format!("{prefix}tool.points.{name}");
            check_finite(path, key.clone(), xyz)?;
            if !valid_point_name(name) {
                return Err(RobotError::InvalidValue {
                    path: path.to_path_buf(),
                    key,
                    message: "a point's name is letters, digits, `_` and `-` (it is a CSV `target` value)".into(),
                });
            }
            points.push((name.clone(), Vector3::from(*xyz)));
        }
        Ok(Robot {
            name: raw.name,
            joints,
            base: Base {
                xyz: Vector3::from(raw.base.xyz),
                rpy: Vector3::from(raw.base.rpy).map(f64::to_radians),
            },
            tool: Vector3::from(raw.tool.xyz),
            points,
            tool_rpy: raw.tool.rpy.map(|r| Vector3::from(r).map(f64::to_radians)),
        })
    }
}

/// Whether `name` can name a point: non-empty, letters, digits, `_` and `-`.
fn valid_point_name(name: &str) -> bool {
    !name.is_empty()
        && name
            .chars()
            .all(|c| c.is_alphanumeric() || c == '_' || c == '-')
}

/// `v` (rad) in degrees, as the shortest decimal that reads back to exactly `v`: an angle the
/// user wrote (-120) comes back as written, not as -119.99999999999999; where no decimal of up
/// to 15 places does, the double nearest `v.to_degrees()` that does ([`file_value`]).
pub fn degrees(v: f64) -> f64 {
    let d = v.to_degrees();
    for digits in 0..=15 {
        let scale = 10f64.powi(digits);
        let r = (d * scale).round() / scale;
        if r.to_radians() == v {
            return r;
        }
    }
    file_value(v, f64::to_degrees, f64::to_radians)
}

/// The number to write for the internal value `v` so that a file read back gives exactly `v`:
/// `write(v)` (e.g. radians to degrees), or where its reading (`read`, the loader's own
/// conversion) misses `v` by a rounding, the nearest double around it that `read` maps onto `v`.
/// Each conversion rounds once, so `read(write(v))` can be a unit in the last place off, and a
/// model saved and loaded again would predict a little differently from the one calibrated.
/// Not every double is reached: degrees to radians maps neighbouring doubles more than a unit
/// apart where the radian's binade is finer (about one angle in ten has no number in degrees
/// that reads back onto it); then `write(v)`, a unit in the last place off, and the caller that
/// needs the file and the model to agree takes the model as read back.
pub fn file_value(v: f64, write: impl Fn(f64) -> f64, read: impl Fn(f64) -> f64) -> f64 {
    let u = write(v);
    if read(u) == v || !u.is_finite() {
        return u;
    }
    let (mut below, mut above) = (u, u);
    for _ in 0..16 {
        below = below.next_down();
        above = above.next_up();
        if read(below) == v {
            return below;
        }
        if read(above) == v {
            return above;
        }
    }
    u
}

impl Robot {
    /// The table in the TOML schema of `docs/formats.md` ("Robot table") (mm, degrees; angles as the
    /// shortest decimals that read back exactly, see [`degrees`]).
    pub fn to_toml_string(&self) -> String {
        let raw = RobotTable {
            name: self.name.clone(),
            joint: self
                .joints
                .iter()
                .map(|j| RawJoint {
                    a: j.a,
                    alpha: degrees(j.alpha),
                    beta: j.beta.map(degrees),
                    d: j.d,
                    theta: degrees(j.theta),
                    limits: j.limits.map(|(lo, hi)| [degrees(lo), degrees(hi)]),
                })
                .collect(),
            base: RawBase {
                xyz: self.base.xyz.into(),
                rpy: self.base.rpy.map(degrees).into(),
            },
            tool: RawTool {
                xyz: self.tool.into(),
                rpy: self.tool_rpy.map(|r| r.map(degrees).into()),
                points: self
                    .points
                    .iter()
                    .map(|(n, p)| (n.clone(), RawPoint((*p).into())))
                    .collect(),
            },
        };
        // Serialising plain numbers, strings and arrays cannot fail.
        toml::to_string(&raw).unwrap_or_default()
    }

    /// The point a row with `target` measures: `None` for an unknown name; an empty name is
    /// the default point (index 0), point `k` of [`Self::points`] is index `k + 1`.
    pub fn target_index(&self, target: &str) -> Option<usize> {
        if target.is_empty() {
            return Some(0);
        }
        self.points
            .iter()
            .position(|(n, _)| n == target)
            .map(|k| k + 1)
    }

    /// The names of the named points, in [`Self::points`] order.
    pub fn point_names(&self) -> Vec<&str> {
        self.points.iter().map(|(n, _)| n.as_str()).collect()
    }

    /// Every target a row may name, in target-index order: the default point (an empty name),
    /// then each named point.
    pub fn target_names(&self) -> Vec<&str> {
        std::iter::once("").chain(self.point_names()).collect()
    }

    /// The point of target index `t` in the flange frame, mm (see [`Self::target_index`]).
    pub fn target_point(&self, t: usize) -> Vector3<f64> {
        match t {
            0 => self.tool,
            k => self.points[k - 1].1,
        }
    }

    /// This table measuring target `t`: its default point replaced by that point (every other
    /// value kept), so that every function of the default point serves any target.
    pub fn for_target(&self, t: usize) -> std::borrow::Cow<'_, Robot> {
        if t == 0 {
            std::borrow::Cow::Borrowed(self)
        } else {
            let mut r = self.clone();
            r.tool = self.target_point(t);
            std::borrow::Cow::Owned(r)
        }
    }

    /// Number of joints.
    pub fn dof(&self) -> usize {
        self.joints.len()
    }

    /// Checks that `q` has one value per joint.
    pub fn check_joints(&self, q: &[f64]) -> Result<()> {
        if q.len() == self.dof() {
            Ok(())
        } else {
            Err(RobotError::JointCountMismatch {
                expected: self.dof(),
                found: q.len(),
            })
        }
    }

    /// Whether `q` (rad) lies within every joint's limits (joints without limits always do).
    pub fn within_limits(&self, q: &[f64]) -> bool {
        self.joints.iter().zip(q).all(|(j, &v)| match j.limits {
            Some((lo, hi)) => v >= lo && v <= hi,
            None => true,
        })
    }
}

/// Label used for a table read from memory rather than a file.
pub fn memory_path() -> PathBuf {
    PathBuf::from("<memory>")
}
