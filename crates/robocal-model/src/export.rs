//! A calibrated model in other tools' terms: a URDF whose joint origins reproduce the identified
//! table exactly (checked by reading it back with `urdf-rs` and comparing forward kinematics),
//! and a plain JSON table with standard deviations for controllers' own calibration tables.
//!
//! Modified DH with Hayati's β: joint `i` moves its frame by `RotX(α) TransX(a) RotY(β)
//! RotZ(θ + q) TransZ(d)`. The translation along z commutes with the rotation about z, so the
//! URDF joint's fixed origin is `RotX(α) TransX(a) RotY(β) RotZ(θ) TransZ(d)` and its axis z:
//! exact, not an approximation. The base is a fixed joint from `world`, the measured point a
//! fixed joint to `tool0`, each named point (`[tool.points]`) a fixed joint `point_NAME` to a link
//! `point_NAME`. URDF lengths are metres.

use nalgebra::{Matrix3, Rotation3, Vector3};
use robocal_robot::{Robot, matrix_to_rpy};
use urdf_rs::{Axis, Joint, JointLimit, JointType, Link, LinkName, Pose, Vec3};

use crate::model::CalibratedModel;

/// Largest difference (mm) between the URDF's forward kinematics and the model's table that an
/// export accepts.
pub const PARITY_TOLERANCE_MM: f64 = 1e-6;

/// Configurations the parity check compares.
pub const PARITY_CONFIGURATIONS: usize = 1000;

fn rot_x(a: f64) -> Matrix3<f64> {
    *Rotation3::from_axis_angle(&Vector3::x_axis(), a).matrix()
}
fn rot_y(a: f64) -> Matrix3<f64> {
    *Rotation3::from_axis_angle(&Vector3::y_axis(), a).matrix()
}
fn rot_z(a: f64) -> Matrix3<f64> {
    *Rotation3::from_axis_angle(&Vector3::z_axis(), a).matrix()
}

/// A URDF pose (metres, rad) of a rotation and a translation in mm.
fn pose(r: &Matrix3<f64>, t_mm: &Vector3<f64>) -> Pose {
    let rpy = matrix_to_rpy(r);
    Pose {
        xyz: Vec3([t_mm.x * 1e-3, t_mm.y * 1e-3, t_mm.z * 1e-3]),
        rpy: Vec3([rpy.x, rpy.y, rpy.z]),
    }
}

fn link(name: &str) -> Link {
    Link {
        name: name.into(),
        inertial: Default::default(),
        visual: Vec::new(),
        collision: Vec::new(),
    }
}

fn joint(name: String, kind: JointType, parent: &str, child: &str, origin: Pose) -> Joint {
    Joint {
        name,
        joint_type: kind,
        origin,
        parent: LinkName {
            link: parent.into(),
        },
        child: LinkName { link: child.into() },
        axis: Axis {
            xyz: Vec3([0.0, 0.0, 1.0]),
        },
        limit: JointLimit::default(),
        calibration: None,
        dynamics: None,
        mimic: None,
        safety_controller: None,
    }
}

/// The model's kinematic table as a URDF robot: links `world`, `base_link`, `link_1` …,
/// `tool0`; joints `base`, `joint_1` … (revolute with the table's limits, continuous without),
/// `tool`.
pub fn urdf_robot(robot: &Robot) -> urdf_rs::Robot {
    let mut links = vec![link("world"), link("base_link")];
    let mut joints = vec![joint(
        "base".into(),
        JointType::Fixed,
        "world",
        "base_link",
        pose(&robot.base_rotation(), &robot.base.xyz),
    )];
    let mut parent = "base_link".to_string();
    for (i, j) in robot.joints.iter().enumerate() {
        let child = format!("link_{}", i + 1);
        let r = rot_x(j.alpha) * rot_y(j.beta.unwrap_or(0.0)) * rot_z(j.theta);
        // RotX(α) TransX(a) RotY(β) RotZ(θ) TransZ(d): the origin is a along x of the parent,
        // then d along the rotated z.
        let t = Vector3::new(j.a, 0.0, 0.0) + r * Vector3::new(0.0, 0.0, j.d);
        let (kind, limit) = match j.limits {
            Some((lower, upper)) => (
                JointType::Revolute,
                JointLimit {
                    lower,
                    upper,
                    effort: 0.0,
                    velocity: 0.0,
                },
            ),
            None => (JointType::Continuous, JointLimit::default()),
        };
        let mut jt = joint(
            format!("joint_{}", i + 1),
            kind,
            &parent,
            &child,
            pose(&r, &t),
        );
        jt.limit = limit;
        joints.push(jt);
        links.push(link(&child));
        parent = child;
    }
    links.push(link("tool0"));
    joints.push(joint(
        "tool".into(),
        JointType::Fixed,
        &parent,
        "tool0",
        // A 6-DoF probe's frame (`[tool] rpy`) turns `tool0`; without one it is the flange's.
        pose(&robot.tool_frame_rotation(), &robot.tool),
    ));
    for (name, p) in &robot.points {
        let leaf = point_link(name);
        links.push(link(&leaf));
        joints.push(joint(
            leaf.clone(),
            JointType::Fixed,
            &parent,
            &leaf,
            pose(&Matrix3::identity(), p),
        ));
    }
    urdf_rs::Robot {
        name: robot.name.clone(),
        links,
        joints,
        materials: Vec::new(),
    }
}

/// The URDF link (and fixed joint) of the named point `name`.
pub fn point_link(name: &str) -> String {
    format!("point_{name}")
}

/// The URDF text of the model's kinematic table.
pub fn urdf_text(robot: &Robot) -> Result<String, String> {
    urdf_rs::write_to_string(&urdf_robot(robot)).map_err(|e| e.to_string())
}

/// The measured point (mm, world frame) of a URDF robot at the readings `q` (rad) of its
/// movable joints in chain order from `world`: the origin of link `leaf` (`tool0`, or a named
/// point's link), each joint on the way applying its origin, then its rotation about its axis.
pub fn urdf_point(robot: &urdf_rs::Robot, q: &[f64], leaf: &str) -> Result<Vector3<f64>, String> {
    urdf_frame(robot, q, leaf).map(|(_, t)| t)
}

/// The frame of link `leaf` (rotation, origin mm; world frame) of a URDF robot at the readings
/// `q` (rad) of its movable joints, as [`urdf_point`] walks it.
pub fn urdf_frame(
    robot: &urdf_rs::Robot,
    q: &[f64],
    leaf: &str,
) -> Result<(Matrix3<f64>, Vector3<f64>), String> {
    // The chain from `leaf` back to `world`, each link's one parent joint.
    let mut path = Vec::new();
    let mut link = leaf.to_string();
    while link != "world" {
        let j = (robot.joints.iter())
            .find(|j| j.child.link == link)
            .ok_or_else(|| format!("no joint leads to link `{link}`"))?;
        if path.len() > robot.joints.len() {
            return Err("the URDF's joints form a loop".into());
        }
        path.push(j);
        link = j.parent.link.clone();
    }
    let mut r = Matrix3::identity();
    let mut t = Vector3::zeros();
    let mut k = 0;
    for j in path.into_iter().rev() {
        let o = &j.origin;
        let jr = robocal_robot::rpy_to_matrix(&Vector3::new(o.rpy[0], o.rpy[1], o.rpy[2]));
        t += r * Vector3::new(o.xyz[0], o.xyz[1], o.xyz[2]) * 1e3;
        r *= jr;
        if matches!(j.joint_type, JointType::Revolute | JointType::Continuous) {
            let angle = *q.get(k).ok_or("more movable joints than readings")?;
            let axis = nalgebra::Unit::new_normalize(Vector3::new(
                j.axis.xyz[0],
                j.axis.xyz[1],
                j.axis.xyz[2],
            ));
            r *= Rotation3::from_axis_angle(&axis, angle).matrix();
            k += 1;
        }
    }
    if k != q.len() {
        return Err(format!(
            "the URDF chain has {k} movable joints, the model {}",
            q.len()
        ));
    }
    Ok((r, t))
}

/// How far an orientation difference counts in [`urdf_parity`], mm per rad: the displacement
/// it gives a point 1 m out.
pub const PARITY_LEVER_MM: f64 = 1000.0;

/// Reads `text` back (`urdf-rs`) and compares its forward kinematics with `robot`'s at
/// [`PARITY_CONFIGURATIONS`] configurations spread over the joint limits (±180° without), at the
/// measured point and every named point: the largest difference, mm (with a 6-DoF probe's
/// frame, `tool0`'s orientation too, counted at [`PARITY_LEVER_MM`]).
pub fn urdf_parity(robot: &Robot, text: &str) -> Result<f64, String> {
    let back = urdf_rs::read_from_string(text).map_err(|e| e.to_string())?;
    let mut worst: f64 = 0.0;
    for i in 0..PARITY_CONFIGURATIONS {
        // A low-discrepancy sequence: one irrational step per joint.
        let q: Vec<f64> = (robot.joints.iter().enumerate())
            .map(|(j, joint)| {
                let (lo, hi) = joint
                    .limits
                    .unwrap_or((-std::f64::consts::PI, std::f64::consts::PI));
                let step = ((j + 2) as f64).sqrt().fract();
                lo + (hi - lo) * ((i as f64 + 0.5) * step).fract()
            })
            .collect();
        let (r, t) = urdf_frame(&back, &q, "tool0")?;
        worst = worst.max((t - robot.point(&q)).norm());
        if robot.tool_rpy.is_some() {
            // A 6-DoF probe's frame: its orientation too.
            let turn = robocal_robot::rotation_vector(&(r * robot.tool_rotation(&q).transpose()));
            worst = worst.max(turn.norm() * PARITY_LEVER_MM);
        }
        for (k, (name, _)) in robot.points.iter().enumerate() {
            let model = robot.for_target(k + 1).point(&q);
            worst = worst.max((urdf_point(&back, &q, &point_link(name))? - model).norm());
        }
    }
    Ok(worst)
}

/// The model's table as plain JSON: per joint `a`, `alpha`, `beta`, `d`, `theta` (mm, deg) with
/// the standard deviations calibrate reported (`report`'s `kinematic.parameters`, where given),
/// the base and the tool, and what the table leaves out.
pub fn json_table(
    model: &CalibratedModel,
    report: Option<&serde_json::Value>,
) -> serde_json::Value {
    use serde_json::json;
    let robot = &model.robot;
    let sigma = |name: &str| -> Option<f64> {
        report?
            .pointer("/kinematic/parameters")?
            .as_array()?
            .iter()
            .find(|p| p.get("name").and_then(|n| n.as_str()) == Some(name))?
            .get("std")?
            .as_f64()
    };
    let joints: Vec<serde_json::Value> = (robot.joints.iter().enumerate())
        .map(|(i, j)| {
            let n = i + 1;
            json!({
                "joint": n,
                "a": j.a, "alpha": j.alpha.to_degrees(), "beta": j.beta.map(f64::to_degrees),
                "d": j.d, "theta": j.theta.to_degrees(),
                "limits": j.limits.map(|(lo, hi)| [lo.to_degrees(), hi.to_degrees()]),
                "std": {
                    "a": sigma(&format!("j{n}.a")), "alpha": sigma(&format!("j{n}.alpha")),
                    "beta": sigma(&format!("j{n}.beta")), "d": sigma(&format!("j{n}.d")),
                    "theta": sigma(&format!("j{n}.theta")),
                },
            })
        })
        .collect();
    let rpy = robot.base.rpy;
    let base_std = [
        "base.x", "base.y", "base.z", "base.rx", "base.ry", "base.rz",
    ]
    .map(sigma);
    let tool_std = ["tool.x", "tool.y", "tool.z"].map(sigma);
    let points: serde_json::Map<String, serde_json::Value> = (robot.points.iter().enumerate())
        .map(|(k, (name, p))| {
            let std = ["x", "y", "z"].map(|a| sigma(&format!("point{}.{a}", k + 1)));
            (name.clone(), json!({"xyz": [p.x, p.y, p.z], "std": std}))
        })
        .collect();
    json!({
        "format": "robocal MDH table",
        "units": {"length": "mm", "angle": "deg"},
        "convention": "modified DH: RotX(alpha) TransX(a) RotY(beta) RotZ(theta + q) TransZ(d); base: world -> frame {0}, fixed-axis rpy R = Rz(yaw) Ry(pitch) Rx(roll); tool: the measured point in the flange frame, and (rpy, when given) the 6-DoF probe's frame in the flange frame",
        "name": robot.name,
        "joints": joints,
        "base": {
            "xyz": [robot.base.xyz.x, robot.base.xyz.y, robot.base.xyz.z],
            "rpy": [rpy.x.to_degrees(), rpy.y.to_degrees(), rpy.z.to_degrees()],
            "std": base_std,
        },
        "tool": {
            "xyz": [robot.tool.x, robot.tool.y, robot.tool.z],
            "std": tool_std,
            "rpy": robot.tool_rpy.map(|r| [r.x.to_degrees(), r.y.to_degrees(), r.z.to_degrees()]),
            "rpy_std": robot.tool_rpy.map(|_| ["tool.rx", "tool.ry", "tool.rz"].map(sigma)),
        },
        "points": points,
        "not_carried": not_carried(model),
    })
}

/// What a kinematic table cannot carry of `model`: its joint-error blocks and its residual.
pub fn not_carried(model: &CalibratedModel) -> Vec<String> {
    let mut out = Vec::new();
    if let Some(e) = &model.joint_errors {
        if e.values.iter().any(|v| *v != 0.0) {
            out.push("joint compliances under the payload".to_string());
        }
        if !e.harmonics.is_empty() {
            out.push(format!("{} transmission harmonics", e.harmonics.len()));
        }
        if !e.self_weight.is_empty() {
            out.push(format!("{} self-weight terms", e.self_weight.len()));
        }
        let links: std::collections::BTreeSet<usize> = (e.link_weights.iter())
            .filter(|w| w.value != 0.0)
            .map(|w| w.body)
            .collect();
        if !links.is_empty() {
            let which = if links.len() == 1 { "link" } else { "links" };
            out.push(format!(
                "the weights of {} {which} deflecting the joints",
                links.len()
            ));
        }
        let backlash = e.backlash.iter().filter(|b| b.value != 0.0).count();
        if backlash > 0 {
            let joints = if backlash == 1 { "joint" } else { "joints" };
            out.push(format!("the backlash of {backlash} {joints}"));
        }
    }
    if let Some(r) = &model.residual {
        out.push(format!("the {} residual model", r.kind().name()));
    }
    out
}
