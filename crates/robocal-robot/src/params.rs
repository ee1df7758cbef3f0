//! Every model parameter by a stable name (`j3.beta`, `base.rz`, `tool.x`) and as one flat vector.

use std::fmt;
use std::str::FromStr;

use crate::error::{Result, RobotError};
use crate::table::Robot;

/// A parameter of one joint's MDH row.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum JointField {
    /// a_{i-1}, mm.
    A,
    /// alpha_{i-1}, rad.
    Alpha,
    /// beta_{i-1}, rad (only for joints that declare a β).
    Beta,
    /// d_i, mm.
    D,
    /// theta_i offset, rad.
    Theta,
}

/// One scalar parameter of a robot model.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum ParamId {
    /// A field of joint `index` (0-based; named from 1, `j1.a`).
    Joint {
        /// 0-based joint index.
        index: usize,
        /// Which MDH quantity.
        field: JointField,
    },
    /// Base position x, y, z (axis 0..3, mm) or roll, pitch, yaw (axis 3..6, rad).
    Base(usize),
    /// Tool point x, y, z in the flange frame (axis 0..3, mm).
    Tool(usize),
    /// Named point `index` (0-based, in [`Robot::points`] order; named from 1, `point1.x`) x, y,
    /// z in the flange frame (axis 0..3, mm).
    Point {
        /// 0-based point index.
        index: usize,
        /// 0..3.
        axis: usize,
    },
    /// Tool frame roll, pitch, yaw in the flange frame (axis 0..3, rad; `tool.rx|ry|rz`): only
    /// in a table that declares `[tool] rpy`.
    ToolRot(usize),
}

/// Whether a parameter is a length or an angle.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Unit {
    /// Millimetres (internally and in files).
    Mm,
    /// Radians internally, degrees in files and reports.
    Rad,
}

const BASE_NAMES: [&str; 6] = ["x", "y", "z", "rx", "ry", "rz"];
const AXES: [&str; 3] = ["x", "y", "z"];

impl JointField {
    fn name(self) -> &'static str {
        match self {
            Self::A => "a",
            Self::Alpha => "alpha",
            Self::Beta => "beta",
            Self::D => "d",
            Self::Theta => "theta",
        }
    }
}

impl ParamId {
    /// Length or angle.
    pub fn unit(self) -> Unit {
        match self {
            Self::Joint {
                field: JointField::A | JointField::D,
                ..
            }
            | Self::Tool(_)
            | Self::Point { .. } => Unit::Mm,
            Self::Base(axis) if axis < 3 => Unit::Mm,
            Self::Base(_) | Self::Joint { .. } | Self::ToolRot(_) => Unit::Rad,
        }
    }

    /// Value in file units (mm or degrees) from an internal value (mm or radians).
    pub fn to_file_units(self, value: f64) -> f64 {
        match self.unit() {
            Unit::Mm => value,
            Unit::Rad => value.to_degrees(),
        }
    }

    /// Internal value (mm or radians) from file units (mm or degrees).
    pub fn from_file_units(self, value: f64) -> f64 {
        match self.unit() {
            Unit::Mm => value,
            Unit::Rad => value.to_radians(),
        }
    }

    /// The unit's name in files: `mm` or `deg`.
    pub fn file_unit_name(self) -> &'static str {
        match self.unit() {
            Unit::Mm => "mm",
            Unit::Rad => "deg",
        }
    }
}

impl fmt::Display for ParamId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            Self::Joint { index, field } => write!(f, "j{}.{}", index + 1, field.name()),
            Self::Base(axis) => write!(f, "base.{}", BASE_NAMES[axis]),
            Self::Tool(axis) => write!(f, "tool.{}", AXES[axis]),
            Self::Point { index, axis } => write!(f, "point{}.{}", index + 1, AXES[axis]),
            Self::ToolRot(axis) => write!(f, "tool.{}", BASE_NAMES[axis + 3]),
        }
    }
}

impl FromStr for ParamId {
    type Err = RobotError;

    /// Parses a name such as `j2.d`, `base.rz` or `tool.x` (not checked against a table).
    fn from_str(name: &str) -> Result<Self> {
        let unknown = || RobotError::UnknownParameter {
            name: name.to_string(),
        };
        let (head, tail) = name.split_once('.').ok_or_else(unknown)?;
        match head {
            "base" => BASE_NAMES
                .iter()
                .position(|n| *n == tail)
                .map(Self::Base)
                .ok_or_else(unknown),
            "tool" => match BASE_NAMES.iter().position(|n| *n == tail) {
                Some(axis) if axis < 3 => Ok(Self::Tool(axis)),
                Some(axis) => Ok(Self::ToolRot(axis - 3)),
                None => Err(unknown()),
            },
            _ if head.starts_with("point") => {
                let index = head["point".len()..]
                    .parse::<usize>()
                    .ok()
                    .filter(|&k| k >= 1)
                    .ok_or_else(unknown)?;
                let axis = AXES.iter().position(|n| *n == tail).ok_or_else(unknown)?;
                Ok(Self::Point {
                    index: index - 1,
                    axis,
                })
            }
            _ => {
                let number: usize = head
                    .strip_prefix('j')
                    .and_then(|n| n.parse().ok())
                    .filter(|&n| n >= 1)
                    .ok_or_else(unknown)?;
                let field = match tail {
                    "a" => JointField::A,
                    "alpha" => JointField::Alpha,
                    "beta" => JointField::Beta,
                    "d" => JointField::D,
                    "theta" => JointField::Theta,
                    _ => return Err(unknown()),
                };
                Ok(Self::Joint {
                    index: number - 1,
                    field,
                })
            }
        }
    }
}

impl Robot {
    /// Every parameter of this model in canonical order: for each joint `a, alpha, [beta,] d, theta`,
    /// then `base.x, base.y, base.z, base.rx, base.ry, base.rz`, then `tool.x, tool.y, tool.z`,
    /// then `x, y, z` of each named point, then `tool.rx, tool.ry, tool.rz` when the table
    /// declares `[tool] rpy`.
    ///
    /// For a 6-joint arm with one β this is 25 + 6 + 3 = 34 parameters.
    pub fn param_ids(&self) -> Vec<ParamId> {
        let mut ids = Vec::with_capacity(self.param_count());
        for (index, joint) in self.joints.iter().enumerate() {
            ids.push(ParamId::Joint {
                index,
                field: JointField::A,
            });
            ids.push(ParamId::Joint {
                index,
                field: JointField::Alpha,
            });
            if joint.beta.is_some() {
                ids.push(ParamId::Joint {
                    index,
                    field: JointField::Beta,
                });
            }
            ids.push(ParamId::Joint {
                index,
                field: JointField::D,
            });
            ids.push(ParamId::Joint {
                index,
                field: JointField::Theta,
            });
        }
        ids.extend((0..6).map(ParamId::Base));
        ids.extend((0..3).map(ParamId::Tool));
        for index in 0..self.points.len() {
            ids.extend((0..3).map(|axis| ParamId::Point { index, axis }));
        }
        if self.tool_rpy.is_some() {
            ids.extend((0..3).map(ParamId::ToolRot));
        }
        ids
    }

    /// Number of parameters, `4 n + (joints with β) + 9 + 3 (named points) + 3 (tool rpy)`.
    pub fn param_count(&self) -> usize {
        4 * self.joints.len()
            + self.joints.iter().filter(|j| j.beta.is_some()).count()
            + 9
            + 3 * self.points.len()
            + if self.tool_rpy.is_some() { 3 } else { 0 }
    }

    /// Checks that `id` exists in this table (joint in range, β declared).
    pub fn has_param(&self, id: ParamId) -> bool {
        match id {
            ParamId::Joint { index, field } => self
                .joints
                .get(index)
                .is_some_and(|j| field != JointField::Beta || j.beta.is_some()),
            ParamId::Base(axis) => axis < 6,
            ParamId::Tool(axis) => axis < 3,
            ParamId::Point { index, axis } => index < self.points.len() && axis < 3,
            ParamId::ToolRot(axis) => self.tool_rpy.is_some() && axis < 3,
        }
    }

    /// Looks a parameter up by name, checking it exists in this table.
    pub fn param_by_name(&self, name: &str) -> Result<ParamId> {
        let id: ParamId = name.parse()?;
        if self.has_param(id) {
            Ok(id)
        } else {
            Err(RobotError::UnknownParameter {
                name: name.to_string(),
            })
        }
    }

    /// Value of one parameter, internal units (mm, rad). Parameters not in the table read as 0.
    pub fn param(&self, id: ParamId) -> f64 {
        match id {
            ParamId::Joint { index, field } => {
                self.joints.get(index).map_or(0.0, |j| match field {
                    JointField::A => j.a,
                    JointField::Alpha => j.alpha,
                    JointField::Beta => j.beta.unwrap_or(0.0),
                    JointField::D => j.d,
                    JointField::Theta => j.theta,
                })
            }
            ParamId::Base(axis) if axis < 3 => self.base.xyz[axis],
            ParamId::Base(axis) => self.base.rpy.get(axis - 3).copied().unwrap_or(0.0),
            ParamId::Tool(axis) => self.tool.get(axis).copied().unwrap_or(0.0),
            ParamId::Point { index, axis } => self
                .points
                .get(index)
                .and_then(|p| p.1.get(axis).copied())
                .unwrap_or(0.0),
            ParamId::ToolRot(axis) => self
                .tool_rpy
                .and_then(|r| r.get(axis).copied())
                .unwrap_or(0.0),
        }
    }

    /// Sets one parameter, internal units. Errors when the table has no such parameter.
    pub fn set_param(&mut self, id: ParamId, value: f64) -> Result<()> {
        if !self.has_param(id) {
            return Err(RobotError::UnknownParameter {
                name: id.to_string(),
            });
        }
        match id {
            ParamId::Joint { index, field } => {
                let j = &mut self.joints[index];
                match field {
                    JointField::A => j.a = value,
                    JointField::Alpha => j.alpha = value,
                    JointField::Beta => j.beta = Some(value),
                    JointField::D => j.d = value,
                    JointField::Theta => j.theta = value,
                }
            }
            ParamId::Base(axis) if axis < 3 => self.base.xyz[axis] = value,
            ParamId::Base(axis) => self.base.rpy[axis - 3] = value,
            ParamId::Tool(axis) => self.tool[axis] = value,
            ParamId::Point { index, axis } => self.points[index].1[axis] = value,
            ParamId::ToolRot(axis) => {
                if let Some(r) = self.tool_rpy.as_mut() {
                    r[axis] = value;
                }
            }
        }
        Ok(())
    }

    /// All parameters as one flat vector in [`Robot::param_ids`] order, internal units.
    pub fn params(&self) -> Vec<f64> {
        self.param_ids()
            .into_iter()
            .map(|id| self.param(id))
            .collect()
    }

    /// A copy of this robot with every parameter replaced by `values` ([`Robot::param_ids`] order).
    pub fn with_params(&self, values: &[f64]) -> Result<Self> {
        let ids = self.param_ids();
        if values.len() != ids.len() {
            return Err(RobotError::ParameterCount {
                expected: ids.len(),
                found: values.len(),
            });
        }
        let mut robot = self.clone();
        for (id, &v) in ids.iter().zip(values) {
            robot.set_param(*id, v)?;
        }
        Ok(robot)
    }
}
