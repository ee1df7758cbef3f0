//! A robot table from a maker's description: the serial chain of a URDF, or a DH table typed
//! from a manual (standard or modified), converted exactly to robocal's modified DH with
//! Hayati's β.
//!
//! The URDF's chain at its zero configuration gives every revolute joint's axis as a line in the
//! base link's frame. Link frame `i` has its z along joint `i`'s axis and its x toward joint
//! `i + 1`'s axis: along their common normal where the two axes are skew or meet (`α`, `a`; no
//! β), and, where they are parallel or within [`PARALLEL_DEG`] of it, to the point where the
//! next axis crosses the plane through frame `i`'s origin normal to its axis (`α`, `a` and a β;
//! `d` of the next joint 0) — where the common normal would lie far off or nowhere. Each joint's
//! `θ` is the angle its frame's x makes at the URDF's zero with the x that `α`, `a` and `β`
//! bring along, so a joint reads the same angles as in the URDF; `d` is the distance along the
//! axis between the two feet. Robocal's base is frame 1 at zero (joint 1's `a`, `α`, `θ`, `d`
//! all 0) in the base link's frame, and the tool is the tip link's origin (or a point given in
//! its frame) in frame `n`, whose x is the one its `α`, `a`, `β` bring along (`θₙ` 0) and whose
//! origin is the foot of the perpendicular from the tool point on the last axis.

use std::collections::HashSet;

use nalgebra::{Matrix3, Rotation3, Unit, Vector3};
use robocal_robot::{Base, Joint, Robot, matrix_to_rpy, rpy_to_matrix};
use urdf_rs::JointType;

/// Consecutive axes within this angle (deg) of parallel get a Hayati β instead of a common
/// normal.
pub const PARALLEL_DEG: f64 = 1.0;

/// A frame: rotation (columns x, y, z) and origin, mm, in the base link's frame.
#[derive(Debug, Clone, Copy)]
struct Frame {
    r: Matrix3<f64>,
    o: Vector3<f64>,
}

/// A revolute joint of the chain at the URDF's zero: its axis line and its limits.
#[derive(Debug, Clone)]
struct Axis {
    /// A point of the axis, mm.
    point: Vector3<f64>,
    /// Unit direction (positive rotation about it).
    dir: Vector3<f64>,
    /// Limits, rad; `None` for a continuous joint.
    limits: Option<(f64, f64)>,
}

/// What the chain of a URDF gives: the revolute joints' axes in order and the tip's frame,
/// all at the zero configuration in the base link's frame.
struct Chain {
    axes: Vec<Axis>,
    tip: Frame,
}

/// The origin of a URDF joint as a frame (URDF lengths in metres, returned in mm).
fn origin_of(j: &urdf_rs::Joint) -> Frame {
    let o = &j.origin;
    Frame {
        r: rpy_to_matrix(&Vector3::new(o.rpy[0], o.rpy[1], o.rpy[2])),
        o: Vector3::new(o.xyz[0], o.xyz[1], o.xyz[2]) * 1e3,
    }
}

/// The chain of `urdf` from link `base` (default: the root, the one link no joint leads to) to
/// link `tip` (default: the one leaf), checked: every joint on it revolute, continuous or fixed
/// and no mimic, and no movable joint branching off it between base and tip.
fn chain(urdf: &urdf_rs::Robot, base: Option<&str>, tip: Option<&str>) -> Result<Chain, String> {
    let children: HashSet<&str> = urdf.joints.iter().map(|j| j.child.link.as_str()).collect();
    let parents: HashSet<&str> = urdf.joints.iter().map(|j| j.parent.link.as_str()).collect();
    let names: Vec<&str> = urdf.links.iter().map(|l| l.name.as_str()).collect();
    let known = |link: &str, what: &str| {
        if names.contains(&link) {
            Ok(())
        } else {
            Err(format!("{what} `{link}` is no link of the URDF"))
        }
    };
    let base = match base {
        Some(b) => {
            known(b, "the base link")?;
            b.to_string()
        }
        None => {
            let roots: Vec<&str> = (names.iter().copied())
                .filter(|l| !children.contains(l))
                .collect();
            match roots.as_slice() {
                [one] => one.to_string(),
                _ => {
                    return Err(format!(
                        "the URDF has {} root links ({}): name the base (`--base LINK`)",
                        roots.len(),
                        roots.join(", ")
                    ));
                }
            }
        }
    };
    let tip = match tip {
        Some(t) => {
            known(t, "the tip link")?;
            t.to_string()
        }
        None => {
            let leaves: Vec<&str> = (names.iter().copied())
                .filter(|l| !parents.contains(l) && children.contains(l))
                .collect();
            match leaves.as_slice() {
                [one] => one.to_string(),
                _ => {
                    return Err(format!(
                        "the URDF has {} leaf links ({}): name the tip (`--tip LINK`)",
                        leaves.len(),
                        leaves.join(", ")
                    ));
                }
            }
        }
    };
    // From the tip back to the base, each link's one parent joint.
    let mut path: Vec<&urdf_rs::Joint> = Vec::new();
    let mut link = tip.clone();
    while link != base {
        let j = (urdf.joints.iter())
            .find(|j| j.child.link == link)
            .ok_or_else(|| {
                format!(
                    "link `{link}` has no parent joint: the tip `{tip}` does not hang from the base `{base}`"
                )
            })?;
        if path.len() > urdf.joints.len() {
            return Err("the URDF's joints form a loop".to_string());
        }
        path.push(j);
        link = j.parent.link.clone();
    }
    path.reverse();
    let on_path: HashSet<&str> = path.iter().map(|j| j.name.as_str()).collect();
    let chain_links: HashSet<&str> = std::iter::once(base.as_str())
        .chain(path.iter().map(|j| j.child.link.as_str()))
        .filter(|l| *l != tip)
        .collect();
    for j in &urdf.joints {
        let movable = !matches!(j.joint_type, JointType::Fixed);
        if movable
            && chain_links.contains(j.parent.link.as_str())
            && !on_path.contains(j.name.as_str())
        {
            return Err(format!(
                "joint `{}` branches off the chain at link `{}`: a serial chain from `{base}` to `{tip}` has no branches (name another tip with `--tip`)",
                j.name, j.parent.link
            ));
        }
    }
    let mut at = Frame {
        r: Matrix3::identity(),
        o: Vector3::zeros(),
    };
    let mut axes = Vec::new();
    for j in &path {
        if j.mimic.is_some() {
            return Err(format!(
                "joint `{}` mimics another joint: robocal's joints are independent",
                j.name
            ));
        }
        let origin = origin_of(j);
        at = Frame {
            r: at.r * origin.r,
            o: at.o + at.r * origin.o,
        };
        match j.joint_type {
            JointType::Fixed => {}
            JointType::Revolute | JointType::Continuous => {
                let a = Vector3::new(j.axis.xyz[0], j.axis.xyz[1], j.axis.xyz[2]);
                if !(a.norm() > 0.0 && a.iter().all(|v| v.is_finite())) {
                    return Err(format!(
                        "joint `{}`: its axis {:?} has no direction",
                        j.name, j.axis.xyz.0
                    ));
                }
                let limits = match j.joint_type {
                    JointType::Revolute if j.limit.lower < j.limit.upper => {
                        Some((j.limit.lower, j.limit.upper))
                    }
                    _ => None,
                };
                axes.push(Axis {
                    point: at.o,
                    dir: at.r * a.normalize(),
                    limits,
                });
                // The joint turns about its axis; at zero the frame stays.
            }
            ref other => {
                return Err(format!(
                    "joint `{}` is {}: robocal's joints are revolute",
                    j.name,
                    match other {
                        JointType::Prismatic => "prismatic",
                        JointType::Floating => "floating",
                        JointType::Planar => "planar",
                        JointType::Spherical => "spherical",
                        _ => "of another kind",
                    }
                ));
            }
        }
    }
    if axes.is_empty() {
        return Err(format!("no revolute joint between `{base}` and `{tip}`"));
    }
    Ok(Chain { axes, tip: at })
}

/// The signed angle from `a` to `b` about the unit axis `n` (both perpendicular to it), rad.
fn angle_about(a: &Vector3<f64>, b: &Vector3<f64>, n: &Vector3<f64>) -> f64 {
    a.cross(b).dot(n).atan2(a.dot(b))
}

/// A frame with z along `z` and x along the part of `x` normal to it.
fn frame_of(o: Vector3<f64>, x: Vector3<f64>, z: Vector3<f64>) -> Frame {
    let z = z.normalize();
    let x = (x - z * x.dot(&z)).normalize();
    Frame {
        r: Matrix3::from_columns(&[x, z.cross(&x), z]),
        o,
    }
}

/// Any unit vector normal to `z`.
fn normal_to(z: &Vector3<f64>) -> Vector3<f64> {
    let pick = if z.x.abs() < 0.9 {
        Vector3::x()
    } else {
        Vector3::y()
    };
    (pick - z * pick.dot(z)).normalize()
}

/// How link frame `i` (z along `from`'s axis, origin `o` on it) reaches the next axis: its x,
/// `α`, `a`, `β` (where the axes are near parallel), and the point of the next axis it reaches.
struct Reach {
    x: Vector3<f64>,
    alpha: f64,
    a: f64,
    beta: Option<f64>,
    /// Where the x line (turned by `α` and, with `β`, tilted) meets the next axis.
    foot: Vector3<f64>,
}

/// The step from axis `from` to axis `to`: the common normal where they are skew or meet (its
/// foot on `from` is frame `i`'s origin), or, near parallel, the plane through `o` normal to
/// `from`. Returns the origin of frame `i` and the reach.
fn reach(from: &Axis, o: Option<Vector3<f64>>, to: &Axis) -> (Vector3<f64>, Reach) {
    let (u, v) = (from.dir, to.dir);
    let sin = u.cross(&v).norm();
    if sin > PARALLEL_DEG.to_radians().sin() {
        // Closest points of the two lines.
        let w = from.point - to.point;
        let (b, d, e) = (u.dot(&v), u.dot(&w), v.dot(&w));
        let den = 1.0 - b * b;
        let s = (b * e - d) / den;
        let t = (e - b * d) / den;
        let p = from.point + u * s;
        let q = to.point + v * t;
        let gap = q - p;
        let x = if gap.norm() > 1e-9 {
            (gap - u * gap.dot(&u)).normalize()
        } else {
            u.cross(&v).normalize()
        };
        let a = gap.dot(&x);
        let alpha = angle_about(&u, &v, &x);
        (
            p,
            Reach {
                x,
                alpha,
                a,
                beta: None,
                foot: q,
            },
        )
    } else {
        // The next axis crosses the plane through `o` normal to this one at `p`.
        let o = o.unwrap_or(from.point);
        let s = (o - to.point).dot(&u) / v.dot(&u);
        let p = to.point + v * s;
        let gap = p - o;
        let x = if gap.norm() > 1e-9 {
            gap.normalize()
        } else {
            normal_to(&u)
        };
        let a = gap.dot(&x);
        // In frame i: v = RotX(α) RotY(β) z = (sin β, −sin α cos β, cos α cos β).
        let y = u.cross(&x);
        let (vx, vy, vz) = (v.dot(&x), v.dot(&y), v.dot(&u));
        let beta = vx.clamp(-1.0, 1.0).asin();
        let alpha = (-vy).atan2(vz);
        (
            o,
            Reach {
                x,
                alpha,
                a,
                beta: Some(beta),
                foot: p,
            },
        )
    }
}

/// The frame `RotX(α) TransX(a) RotY(β)` brings `f` to.
fn carried(f: &Frame, alpha: f64, a: f64, beta: Option<f64>) -> Frame {
    let rx = Rotation3::from_axis_angle(&Vector3::x_axis(), alpha);
    let ry = Rotation3::from_axis_angle(&Vector3::y_axis(), beta.unwrap_or(0.0));
    Frame {
        r: f.r * rx.matrix() * ry.matrix(),
        o: f.o + f.r * Vector3::new(a, 0.0, 0.0),
    }
}

/// The robot table of a chain, with the tool point `tool` (mm, in the tip's frame).
fn table(name: &str, chain: &Chain, tool: Vector3<f64>) -> Robot {
    let axes = &chain.axes;
    let n = axes.len();
    let tool_point = chain.tip.o + chain.tip.r * tool;
    let mut joints: Vec<Joint> = Vec::with_capacity(n);
    // Frame 1: its origin and x from the step to axis 2 (or, alone, toward the tool).
    let mut steps: Vec<(Vector3<f64>, Reach)> = Vec::with_capacity(n);
    let mut origin: Option<Vector3<f64>> = None;
    for i in 0..n.saturating_sub(1) {
        let (o, r) = reach(&axes[i], origin, &axes[i + 1]);
        // A near-parallel step from the next axis starts where this one reached it (`d = 0`).
        origin = Some(r.foot);
        steps.push((o, r));
    }
    let first = match steps.first() {
        Some((o, r)) => frame_of(*o, r.x, axes[0].dir),
        None => {
            let u = axes[0].dir;
            let foot = axes[0].point + u * (tool_point - axes[0].point).dot(&u);
            let toward = tool_point - foot;
            let x = if (toward - u * toward.dot(&u)).norm() > 1e-9 {
                toward
            } else {
                normal_to(&u)
            };
            frame_of(foot, x, u)
        }
    };
    joints.push(Joint {
        a: 0.0,
        alpha: 0.0,
        beta: None,
        d: 0.0,
        theta: 0.0,
        limits: axes[0].limits,
    });
    let mut frame = first;
    for i in 1..n {
        let (_, r) = &steps[i - 1];
        let g = carried(&frame, r.alpha, r.a, r.beta);
        // Frame i + 1: its origin and x from the step to the next axis, or the last frame:
        // the foot of the tool point's perpendicular, x as carried.
        let next = match steps.get(i) {
            Some((o, s)) => frame_of(*o, s.x, axes[i].dir),
            None => {
                let u = axes[i].dir;
                let foot = g.o + u * (tool_point - g.o).dot(&u);
                frame_of(foot, g.r.column(0).into_owned(), u)
            }
        };
        let theta = angle_about(
            &g.r.column(0).into_owned(),
            &next.r.column(0).into_owned(),
            &axes[i].dir,
        );
        let d = (next.o - g.o).dot(&axes[i].dir);
        joints.push(Joint {
            a: r.a,
            alpha: r.alpha,
            beta: r.beta,
            d,
            theta,
            limits: axes[i].limits,
        });
        frame = next;
    }
    Robot {
        name: name.to_string(),
        joints,
        base: Base {
            xyz: first.o,
            rpy: matrix_to_rpy(&first.r),
        },
        tool: frame.r.transpose() * (tool_point - frame.o),
        points: Vec::new(),
        tool_rpy: None,
    }
}

/// The robot table of a URDF's serial chain from link `base` to link `tip` (defaults: the root
/// and the one leaf), with the measured point at the tip link's origin or at `tool` (mm, in
/// the tip link's frame): the same forward kinematics, at the same joint readings, in the base
/// link's frame. Errors name the joint or link at fault and why.
pub fn robot_from_urdf(
    urdf: &urdf_rs::Robot,
    base: Option<&str>,
    tip: Option<&str>,
    tool: Option<Vector3<f64>>,
) -> Result<Robot, String> {
    let chain = chain(urdf, base, tip)?;
    Ok(table(
        &urdf.name,
        &chain,
        tool.unwrap_or_else(Vector3::zeros),
    ))
}

/// How a DH table typed from a manual is meant.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Convention {
    /// Standard (distal) DH: joint `i` moves by `RotZ(θ + q) TransZ(d) TransX(a) RotX(α)`.
    Standard,
    /// Modified (proximal, Craig's) DH: `RotX(α) TransX(a) RotZ(θ + q) TransZ(d)`, robocal's own.
    Modified,
}

/// One row of a DH table: `d`, `a` (mm), `alpha`, `theta` (deg).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DhRow {
    /// mm.
    pub d: f64,
    /// mm.
    pub a: f64,
    /// deg.
    pub alpha: f64,
    /// deg.
    pub theta: f64,
}

/// The robot table of a DH table: a modified one row by row; a standard one with each row's `a`
/// and `α` moved to the next joint (`TransX(a) RotX(α)` commute and begin the next modified
/// step) and the last row's to the tool, whose point is then `(aₙ, 0, 0)` plus `tool` (mm, in
/// the last standard frame) turned by `αₙ`. The base is the DH table's frame 0. A joint whose
/// axis is parallel (or within [`PARALLEL_DEG`]) to the one before gets a Hayati β of 0; joint
/// 1 has none (its axis is the base's z).
pub fn robot_from_dh(
    name: &str,
    rows: &[DhRow],
    convention: Convention,
    tool: Vector3<f64>,
) -> Robot {
    let rad = f64::to_radians;
    // Where a joint's axis is parallel to the one before (or within `PARALLEL_DEG`), a Hayati β
    // (0) is declared, as the URDF import gives it; joint 1's axis is the base's z.
    let joint = |i: usize, a: f64, alpha: f64, r: &DhRow| Joint {
        a,
        alpha: rad(alpha),
        beta: (i > 0 && rad(alpha).sin().abs() < rad(PARALLEL_DEG).sin()).then_some(0.0),
        d: r.d,
        theta: rad(r.theta),
        limits: None,
    };
    let (joints, tool) = match convention {
        Convention::Modified => (
            (rows.iter().enumerate())
                .map(|(i, r)| joint(i, r.a, r.alpha, r))
                .collect(),
            tool,
        ),
        Convention::Standard => {
            let mut joints = Vec::with_capacity(rows.len());
            let mut carry = (0.0, 0.0);
            for (i, r) in rows.iter().enumerate() {
                joints.push(joint(i, carry.0, carry.1, r));
                carry = (r.a, r.alpha);
            }
            let turn = Rotation3::from_axis_angle(&Unit::new_normalize(Vector3::x()), rad(carry.1));
            (joints, Vector3::new(carry.0, 0.0, 0.0) + turn * tool)
        }
    };
    Robot {
        name: name.to_string(),
        joints,
        base: Base {
            xyz: Vector3::zeros(),
            rpy: Vector3::zeros(),
        },
        tool,
        points: Vec::new(),
        tool_rpy: None,
    }
}

/// The DH table of a CSV typed from a manual: a header naming `d`, `a`, `alpha` and `theta` in
/// any order (other columns ignored), one row per joint, base to tip (mm, deg). Errors name the
/// file, the line and the column.
pub fn read_dh(path: &std::path::Path) -> Result<Vec<DhRow>, String> {
    let file = path.display();
    let text = std::fs::read_to_string(path).map_err(|e| format!("{file}: cannot read: {e}"))?;
    let mut reader = csv::ReaderBuilder::new()
        .trim(csv::Trim::All)
        .from_reader(text.as_bytes());
    let header = reader
        .headers()
        .map_err(|e| format!("{file}: line 1: {e}"))?
        .clone();
    let column = |name: &str| {
        (header.iter().position(|h| h == name)).ok_or_else(|| {
            format!("{file}: no column `{name}` (a DH table has d, a, alpha, theta)")
        })
    };
    let at = [
        column("d")?,
        column("a")?,
        column("alpha")?,
        column("theta")?,
    ];
    let names = ["d", "a", "alpha", "theta"];
    let mut rows = Vec::new();
    for (k, record) in reader.records().enumerate() {
        let line = k + 2;
        let record = record.map_err(|e| format!("{file}: line {line}: {e}"))?;
        let mut v = [0.0; 4];
        for (i, (&c, name)) in at.iter().zip(names).enumerate() {
            let cell = record.get(c).unwrap_or("");
            v[i] = cell
                .parse::<f64>()
                .ok()
                .filter(|x| x.is_finite())
                .ok_or_else(|| {
                    format!("{file}: line {line}, column `{name}`: `{cell}` is not a finite number")
                })?;
        }
        rows.push(DhRow {
            d: v[0],
            a: v[1],
            alpha: v[2],
            theta: v[3],
        });
    }
    if rows.is_empty() {
        return Err(format!("{file}: no joint rows"));
    }
    Ok(rows)
}

/// [`robot_from_urdf`] of the URDF file `path`; errors name the file.
pub fn robot_from_urdf_file(
    path: &std::path::Path,
    base: Option<&str>,
    tip: Option<&str>,
    tool: Option<Vector3<f64>>,
) -> Result<Robot, String> {
    let file = path.display();
    let urdf = urdf_rs::read_file(path).map_err(|e| format!("{file}: not a URDF robot: {e}"))?;
    let mut robot = robot_from_urdf(&urdf, base, tip, tool).map_err(|e| format!("{file}: {e}"))?;
    if robot.name.is_empty() {
        robot.name = path
            .file_stem()
            .map_or("robot".into(), |s| s.to_string_lossy().into());
    }
    Ok(robot)
}
