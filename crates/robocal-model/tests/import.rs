//! Importing a URDF's chain and a DH table typed from a manual: the imported table's forward
//! kinematics against the URDF's own chain and the DH product, each computed here with 4×4
//! homogeneous matrices; and every refused chain named.

use nalgebra::{Matrix4, Vector3, Vector4};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use robocal_model::export::urdf_text;
use robocal_model::import::{Convention, DhRow, robot_from_dh, robot_from_urdf};
use robocal_robot::Robot;

/// A 4×4 rotation about the unit axis `k` by `angle` (Rodrigues).
fn turn(k: Vector3<f64>, angle: f64) -> Matrix4<f64> {
    let k = k.normalize();
    let (s, c) = angle.sin_cos();
    let mut m = Matrix4::identity();
    for i in 0..3 {
        for j in 0..3 {
            let delta = if i == j { 1.0 } else { 0.0 };
            m[(i, j)] = c * delta + (1.0 - c) * k[i] * k[j];
        }
    }
    m[(0, 1)] -= s * k.z;
    m[(0, 2)] += s * k.y;
    m[(1, 0)] += s * k.z;
    m[(1, 2)] -= s * k.x;
    m[(2, 0)] -= s * k.y;
    m[(2, 1)] += s * k.x;
    m
}

fn shift(t: Vector3<f64>) -> Matrix4<f64> {
    let mut m = Matrix4::identity();
    m[(0, 3)] = t.x;
    m[(1, 3)] = t.y;
    m[(2, 3)] = t.z;
    m
}

/// The URDF's own chain from `base` to `tip` at readings `q` (rad, movable joints in chain
/// order): each joint its origin (`xyz` in m, then `rpy` as `Rz(y) Ry(p) Rx(r)`), then its turn
/// about its axis; the tip's origin and `tool` (mm, tip frame), mm.
fn urdf_point(
    urdf: &urdf_rs::Robot,
    base: &str,
    tip: &str,
    q: &[f64],
    tool: Vector3<f64>,
) -> Vector3<f64> {
    let mut path = Vec::new();
    let mut link = tip.to_string();
    while link != base {
        let j = urdf.joints.iter().find(|j| j.child.link == link).unwrap();
        path.push(j);
        link = j.parent.link.clone();
    }
    let mut m = Matrix4::identity();
    let mut k = 0;
    for j in path.into_iter().rev() {
        let (x, r) = (j.origin.xyz, j.origin.rpy);
        m = m
            * shift(Vector3::new(x[0], x[1], x[2]) * 1e3)
            * turn(Vector3::z(), r[2])
            * turn(Vector3::y(), r[1])
            * turn(Vector3::x(), r[0]);
        if !matches!(j.joint_type, urdf_rs::JointType::Fixed) {
            let a = j.axis.xyz;
            m *= turn(Vector3::new(a[0], a[1], a[2]), q[k]);
            k += 1;
        }
    }
    assert_eq!(k, q.len());
    (m * Vector4::new(tool.x, tool.y, tool.z, 1.0)).xyz()
}

/// Six directions (axes, or origin turns as roll, pitch, yaw).
type Axes = [[f64; 3]; 6];

/// One URDF joint's text.
fn joint(
    name: &str,
    kind: &str,
    parent: &str,
    child: &str,
    xyz: [f64; 3],
    rpy: [f64; 3],
    axis: [f64; 3],
) -> String {
    let limit = if kind == "revolute" {
        r#"<limit lower="-2.5" upper="2.7" effort="10" velocity="1"/>"#
    } else {
        ""
    };
    format!(
        r#"<joint name="{name}" type="{kind}"><parent link="{parent}"/><child link="{child}"/><origin xyz="{} {} {}" rpy="{} {} {}"/><axis xyz="{} {} {}"/>{limit}</joint>"#,
        xyz[0], xyz[1], xyz[2], rpy[0], rpy[1], rpy[2], axis[0], axis[1], axis[2]
    )
}

fn urdf(joints: &[String], links: &[&str]) -> urdf_rs::Robot {
    let links: String = links
        .iter()
        .map(|l| format!(r#"<link name="{l}"/>"#))
        .collect();
    urdf_rs::read_from_string(&format!(
        r#"<robot name="test">{links}{}</robot>"#,
        joints.concat()
    ))
    .unwrap()
}

/// Six revolute joints with the given axes and origin turns, a fixed joint after the second
/// turned by `mid` (roll, pitch, yaw), offsets in every origin; links `base`, `l1` … `l6`,
/// `mid`, `tip`.
fn chain_of(
    axes: &[[f64; 3]; 6],
    turns: &[[f64; 3]; 6],
    mid: [f64; 3],
    rng: &mut ChaCha8Rng,
) -> urdf_rs::Robot {
    let mut joints = Vec::new();
    let names = ["base", "l1", "l2", "mid", "l3", "l4", "l5", "l6"];
    let mut k = 0;
    for i in 0..7 {
        let xyz = [
            rng.random_range(-0.3..0.3),
            rng.random_range(-0.3..0.3),
            rng.random_range(0.0..0.4),
        ];
        if i == 2 {
            joints.push(joint(
                "fixed_mid",
                "fixed",
                names[i],
                names[i + 1],
                xyz,
                mid,
                [0.0, 0.0, 1.0],
            ));
            continue;
        }
        let kind = if k % 2 == 0 { "revolute" } else { "continuous" };
        joints.push(joint(
            &format!("j{}", k + 1),
            kind,
            names[i],
            names[i + 1],
            xyz,
            turns[k],
            axes[k],
        ));
        k += 1;
    }
    joints.push(joint(
        "tool",
        "fixed",
        "l6",
        "tip",
        [0.01, 0.02, 0.1],
        [0.3, 0.0, -0.4],
        [1.0, 0.0, 0.0],
    ));
    urdf(
        &joints,
        &["base", "l1", "l2", "mid", "l3", "l4", "l5", "l6", "tip"],
    )
}

/// The largest distance (mm) between the imported table's point and the URDF's own chain's
/// over random readings.
fn worst(
    robot: &Robot,
    urdf: &urdf_rs::Robot,
    base: &str,
    tip: &str,
    tool: Vector3<f64>,
    rng: &mut ChaCha8Rng,
) -> f64 {
    (0..200)
        .map(|_| {
            let q: Vec<f64> = (0..robot.dof())
                .map(|_| rng.random_range(-3.0..3.0))
                .collect();
            (robot.point(&q) - urdf_point(urdf, base, tip, &q, tool)).norm()
        })
        .fold(0.0, f64::max)
}

/// Axes along ±x, ±y, ±z and tilted; consecutive axes parallel (UR's shoulder and elbow),
/// within a tenth of a degree of parallel, and perpendicular; turned and offset joint origins,
/// a fixed joint in between: the imported table's point is the URDF's to 1e-9 mm, through a
/// written robot file, with the tool at the tip's origin and at a point in the tip's frame.
#[test]
fn the_imported_table_moves_as_the_urdf_chain() {
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let z = [0.0, 0.0, 1.0];
    let cases: Vec<(Axes, Axes, [f64; 3])> = vec![
        // UR-like: z, then three parallel y axes, z, y.
        (
            [
                z,
                [0.0, 1.0, 0.0],
                [0.0, 1.0, 0.0],
                [0.0, 1.0, 0.0],
                [0.0, 0.0, -1.0],
                [0.0, 1.0, 0.0],
            ],
            [[0.0; 3]; 6],
            [0.0; 3],
        ),
        // Every direction, turned origins, a turned fixed joint.
        (
            [
                [1.0, 0.0, 0.0],
                [0.0, -1.0, 0.0],
                [0.0, 0.0, -1.0],
                [-1.0, 0.0, 0.0],
                [1.0, 2.0, 3.0],
                [0.0, 1.0, 0.0],
            ],
            [
                [0.2, 0.0, 0.0],
                [0.0, 0.4, 0.0],
                [0.0, 0.0, 0.5],
                [0.3, -0.2, 0.1],
                [0.0, 0.0, 0.0],
                [-0.5, 0.2, 0.9],
            ],
            [0.1, -0.2, 0.3],
        ),
        // Nearly parallel: the second pair 0.1° apart, the third 0.9°.
        (
            [
                z,
                [0.0, 1.0, 0.0],
                [0.0, 1.0, 0.0],
                [0.0, 1.0, 0.0],
                [0.0, 1.0, 0.0],
                z,
            ],
            [
                [0.0; 3],
                [0.0; 3],
                [0.1f64.to_radians(), 0.0, 0.0],
                [0.0, 0.0, 0.9f64.to_radians()],
                [0.0; 3],
                [0.0; 3],
            ],
            [0.0; 3],
        ),
    ];
    for (axes, turns, mid) in &cases {
        let urdf = chain_of(axes, turns, *mid, &mut rng);
        for tool in [Vector3::zeros(), Vector3::new(15.0, -20.0, 60.0)] {
            let robot = robot_from_urdf(&urdf, None, None, Some(tool)).unwrap();
            let back = Robot::from_toml_str(&robot.to_toml_string(), "imported.toml").unwrap();
            let e = worst(&back, &urdf, "base", "tip", tool, &mut rng);
            assert!(e < 1e-9, "{axes:?}: {e} mm");
        }
    }
}

/// Parallel and nearly parallel consecutive axes get a Hayati β; skew or meeting ones none;
/// the URDF's limits come over in degrees.
#[test]
fn a_beta_where_consecutive_axes_are_near_parallel_and_the_limits_carried() {
    let mut rng = ChaCha8Rng::seed_from_u64(4);
    let z = [0.0, 0.0, 1.0];
    let y = [0.0, 1.0, 0.0];
    let urdf = chain_of(
        &[z, y, y, y, z, y],
        &[
            [0.0; 3],
            [0.0; 3],
            [0.0; 3],
            [0.0, 0.0, 0.01],
            [0.0; 3],
            [0.0; 3],
        ],
        [0.0; 3],
        &mut rng,
    );
    let robot = robot_from_urdf(&urdf, None, None, None).unwrap();
    let has_beta: Vec<bool> = robot.joints.iter().map(|j| j.beta.is_some()).collect();
    assert_eq!(has_beta, [false, false, true, true, false, false]);
    assert_eq!(robot.joints[0].limits, Some((-2.5, 2.7)));
    assert_eq!(robot.joints[1].limits, None);
    let text = robot.to_toml_string();
    assert!(text.contains("limits = [-143.2394487"), "{text}");
}

/// The URDF `export` writes reads back as the same table's kinematics, at the measured point.
#[test]
fn importing_an_exported_urdf_gives_back_the_table() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    for file in [
        "configs/robots/pmc6va030.toml",
        "configs/robots/arm7.toml",
        "datasets/ur10-tmac/robot.toml",
    ] {
        let robot = Robot::load(root.join(file)).unwrap();
        let text = urdf_text(&robot).unwrap();
        let urdf = urdf_rs::read_from_string(&text).unwrap();
        let back = robot_from_urdf(&urdf, Some("world"), Some("tool0"), None).unwrap();
        for _ in 0..100 {
            let q: Vec<f64> = (0..robot.dof())
                .map(|_| rng.random_range(-3.0..3.0))
                .collect();
            let e = (back.point(&q) - robot.point(&q)).norm();
            assert!(e < 1e-9, "{file}: {e} mm");
        }
    }
}

fn refused(joints: &[String], links: &[&str], tip: Option<&str>) -> String {
    robot_from_urdf(&urdf(joints, links), None, tip, None).unwrap_err()
}

/// Prismatic, floating and planar joints, mimic joints, a movable branch off the chain and a
/// tree with several leaves are refused, each named with the reason.
#[test]
fn each_refused_chain_names_the_joint_and_the_reason() {
    let z = [0.0, 0.0, 1.0];
    let o = [0.0; 3];
    let links = ["a", "b", "c"];
    for kind in ["prismatic", "floating", "planar"] {
        let e = refused(
            &[
                joint("j1", "revolute", "a", "b", o, o, z),
                joint("slide", kind, "b", "c", o, o, z),
            ],
            &links,
            None,
        );
        assert!(e.contains("`slide`") && e.contains(kind), "{e}");
    }
    let mut mimic = joint("copy", "revolute", "b", "c", o, o, z);
    mimic = mimic.replace("</joint>", r#"<mimic joint="j1"/></joint>"#);
    let e = refused(
        &[joint("j1", "revolute", "a", "b", o, o, z), mimic],
        &links,
        None,
    );
    assert!(e.contains("`copy`") && e.contains("mimic"), "{e}");
    let branched = [
        joint("j1", "revolute", "a", "b", o, o, z),
        joint("j2", "revolute", "b", "c", o, o, z),
        joint("finger", "revolute", "b", "d", o, o, z),
    ];
    let e = refused(&branched, &["a", "b", "c", "d"], Some("c"));
    assert!(e.contains("`finger`") && e.contains("branches"), "{e}");
    let e = refused(&branched, &["a", "b", "c", "d"], None);
    assert!(
        e.contains("2 leaf links") && e.contains("c") && e.contains("d"),
        "{e}"
    );
    let e = refused(
        &[joint("fix", "fixed", "a", "b", o, o, z)],
        &["a", "b"],
        None,
    );
    assert!(e.contains("no revolute joint"), "{e}");
}

/// A standard DH table typed from a manual (UR10's): the imported table's point is the
/// product `Π RotZ(θ + q) TransZ(d) TransX(a) RotX(α)` times the tool, to 1e-9 mm; a modified
/// table's is `Π RotX(α) TransX(a) RotZ(θ + q) TransZ(d)`.
#[test]
fn a_dh_table_from_a_manual_moves_as_its_own_product() {
    let rows = [
        DhRow {
            d: 127.3,
            a: 0.0,
            alpha: 90.0,
            theta: 0.0,
        },
        DhRow {
            d: 0.0,
            a: -612.0,
            alpha: 0.0,
            theta: 10.0,
        },
        DhRow {
            d: 0.0,
            a: -572.3,
            alpha: 0.0,
            theta: 0.0,
        },
        DhRow {
            d: 163.941,
            a: 0.0,
            alpha: 90.0,
            theta: -5.0,
        },
        DhRow {
            d: 115.7,
            a: 0.0,
            alpha: -90.0,
            theta: 0.0,
        },
        DhRow {
            d: 92.2,
            a: 12.0,
            alpha: 30.0,
            theta: 0.0,
        },
    ];
    let tool = Vector3::new(5.0, -3.0, 40.0);
    let mut rng = ChaCha8Rng::seed_from_u64(6);
    for convention in [Convention::Standard, Convention::Modified] {
        let robot = robot_from_dh("ur10", &rows, convention, tool);
        let back = Robot::from_toml_str(&robot.to_toml_string(), "ur10.toml").unwrap();
        for _ in 0..200 {
            let q: Vec<f64> = (0..6).map(|_| rng.random_range(-3.0..3.0)).collect();
            let mut m = Matrix4::identity();
            for (r, qi) in rows.iter().zip(&q) {
                let step_x =
                    shift(Vector3::new(r.a, 0.0, 0.0)) * turn(Vector3::x(), r.alpha.to_radians());
                let step_z = turn(Vector3::z(), r.theta.to_radians() + qi)
                    * shift(Vector3::new(0.0, 0.0, r.d));
                m = match convention {
                    Convention::Standard => m * step_z * step_x,
                    Convention::Modified => {
                        m * turn(Vector3::x(), r.alpha.to_radians())
                            * shift(Vector3::new(r.a, 0.0, 0.0))
                            * step_z
                    }
                };
            }
            let expected = (m * Vector4::new(tool.x, tool.y, tool.z, 1.0)).xyz();
            let e = (back.point(&q) - expected).norm();
            assert!(e < 1e-9, "{convention:?}: {e} mm");
        }
    }
}
