//! Kinematics checked against independent computations: hand-worked chains, a plain 4×4
//! homogeneous-matrix product, central differences, and IK round trips.

use std::f64::consts::FRAC_PI_2;

use nalgebra::{Matrix4, Vector3, Vector4};
use proptest::prelude::*;
use robocal_robot::{Base, IkOptions, IkTarget, Joint, ParamId, Robot, RobotError};

const PMC6: &str = include_str!("../../../configs/robots/pmc6va030.toml");

fn pmc6() -> Robot {
    Robot::from_toml_str(PMC6, "pmc6va030.toml").expect("the bundled robot parses")
}

// ---- an independent implementation: 4x4 homogeneous matrices, one elementary factor at a time

fn h_rot_x(t: f64) -> Matrix4<f64> {
    let (s, c) = t.sin_cos();
    Matrix4::new(1., 0., 0., 0., 0., c, -s, 0., 0., s, c, 0., 0., 0., 0., 1.)
}
fn h_rot_y(t: f64) -> Matrix4<f64> {
    let (s, c) = t.sin_cos();
    Matrix4::new(c, 0., s, 0., 0., 1., 0., 0., -s, 0., c, 0., 0., 0., 0., 1.)
}
fn h_rot_z(t: f64) -> Matrix4<f64> {
    let (s, c) = t.sin_cos();
    Matrix4::new(c, -s, 0., 0., s, c, 0., 0., 0., 0., 1., 0., 0., 0., 0., 1.)
}
fn h_trans(x: f64, y: f64, z: f64) -> Matrix4<f64> {
    Matrix4::new(1., 0., 0., x, 0., 1., 0., y, 0., 0., 1., z, 0., 0., 0., 1.)
}

fn reference_point(robot: &Robot, q: &[f64]) -> Vector3<f64> {
    let b = &robot.base;
    let mut t =
        h_trans(b.xyz.x, b.xyz.y, b.xyz.z) * h_rot_z(b.rpy.z) * h_rot_y(b.rpy.y) * h_rot_x(b.rpy.x);
    for (j, &qi) in robot.joints.iter().zip(q) {
        t = t
            * h_rot_x(j.alpha)
            * h_trans(j.a, 0., 0.)
            * h_rot_y(j.beta.unwrap_or(0.0))
            * h_rot_z(j.theta + qi)
            * h_trans(0., 0., j.d);
    }
    let p = t * Vector4::new(robot.tool.x, robot.tool.y, robot.tool.z, 1.0);
    Vector3::new(p.x, p.y, p.z)
}

// ---- random robots

fn joint_strategy() -> impl Strategy<Value = Joint> {
    (
        -600.0..600.0f64,
        -3.2..3.2f64,
        prop::option::weighted(0.3, -0.2..0.2f64),
        -600.0..600.0f64,
        -3.2..3.2f64,
    )
        .prop_map(|(a, alpha, beta, d, theta)| Joint {
            a,
            alpha,
            beta,
            d,
            theta,
            limits: None,
        })
}

fn robot_strategy() -> impl Strategy<Value = (Robot, Vec<f64>)> {
    (
        prop::collection::vec(joint_strategy(), 1..=7),
        prop::array::uniform3(-3000.0..3000.0f64),
        (-3.1..3.1f64, -1.5..1.5f64, -3.1..3.1f64),
        prop::array::uniform3(-200.0..200.0f64),
        prop::collection::vec(prop::array::uniform3(-200.0..200.0f64), 0..=2),
        prop::option::of((-3.1..3.1f64, -1.5..1.5f64, -3.1..3.1f64)),
    )
        .prop_flat_map(|(joints, xyz, (r, p, y), tool, points, tool_rpy)| {
            let n = joints.len();
            let robot = Robot {
                name: "random".into(),
                joints,
                base: Base {
                    xyz: Vector3::from(xyz),
                    rpy: Vector3::new(r, p, y),
                },
                tool: Vector3::from(tool),
                points: points
                    .iter()
                    .enumerate()
                    .map(|(k, p)| (format!("smr{}", k + 2), Vector3::from(*p)))
                    .collect(),
                tool_rpy: tool_rpy.map(|(r, p, y)| Vector3::new(r, p, y)),
            };
            (Just(robot), prop::collection::vec(-3.2..3.2f64, n))
        })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(200))]

    #[test]
    fn fk_matches_plain_matrix_product((robot, q) in robot_strategy()) {
        let p = robot.point(&q);
        let r = reference_point(&robot, &q);
        prop_assert!((p - r).norm() < 1e-9, "{p} vs {r}");
    }

    #[test]
    fn parameter_jacobian_matches_central_differences((robot, q) in robot_strategy()) {
        let (p, jac) = robot.param_jacobian(&q);
        prop_assert!((p - robot.point(&q)).norm() < 1e-12);
        let x = robot.params();
        let h = 1e-5;
        for (k, id) in robot.param_ids().iter().enumerate() {
            let mut plus = x.clone();
            plus[k] += h;
            let mut minus = x.clone();
            minus[k] -= h;
            let fd = (robot.with_params(&plus).unwrap().point(&q)
                - robot.with_params(&minus).unwrap().point(&q)) / (2.0 * h);
            let an = jac.column(k);
            prop_assert!((fd - an).norm() < 1e-5 * (1.0 + fd.norm()), "{id}: analytic {an} vs fd {fd}");
        }
        // Every named point: its own offset's columns, the others' zero.
        let last = robot.points.len();
        for t in 0..=last {
            let mut out = nalgebra::DMatrix::zeros(3, robot.param_count());
            let p = robot.write_param_jacobian_at(&q, t, &mut out, 0);
            // A buffer reused across rows of other targets holds the same block.
            let mut reused = nalgebra::DMatrix::from_element(3, robot.param_count(), 7.0);
            robot.write_param_jacobian_at(&q, last - t, &mut reused, 0);
            robot.write_param_jacobian_at(&q, t, &mut reused, 0);
            prop_assert_eq!(&reused, &out, "target {} after target {}", t, last - t);
            let point = |r: &Robot| r.for_target(t).point(&q);
            prop_assert!((p - point(&robot)).norm() < 1e-12);
            for (k, id) in robot.param_ids().iter().enumerate() {
                let mut plus = x.clone();
                plus[k] += h;
                let mut minus = x.clone();
                minus[k] -= h;
                let fd = (point(&robot.with_params(&plus).unwrap())
                    - point(&robot.with_params(&minus).unwrap())) / (2.0 * h);
                let an = Vector3::new(out[(0, k)], out[(1, k)], out[(2, k)]);
                prop_assert!((fd - an).norm() < 1e-5 * (1.0 + fd.norm()), "target {t}, {id}: analytic {an} vs fd {fd}");
            }
        }
    }

    /// Each parameter's twist against central differences of the joint axes and link frames
    /// (world frame): a joint's parameter moves its own axis and every frame from its own
    /// outwards by `ω × y + v` (points) and `ω × u` (directions), and nothing before; the
    /// base's move every axis and frame; the tool's and the points' none (`None`). And the
    /// point's column of a parameter with a twist is `ω × p + v`.
    #[test]
    fn parameter_twists_match_central_differences((robot, q) in robot_strategy()) {
        let twists = robot.param_twists(&q);
        prop_assert_eq!(twists.len(), robot.param_count());
        let (p, jac) = robot.param_jacobian(&q);
        let x = robot.params();
        let h = 1e-5;
        let (axes, frames) = robot.axes_and_frames(&q);
        for (k, id) in robot.param_ids().iter().enumerate() {
            let mut plus = x.clone();
            plus[k] += h;
            let mut minus = x.clone();
            minus[k] -= h;
            let (ap, fp) = robot.with_params(&plus).unwrap().axes_and_frames(&q);
            let (am, fm) = robot.with_params(&minus).unwrap().axes_and_frames(&q);
            let rate = |a: Vector3<f64>, b: Vector3<f64>| (a - b) / (2.0 * h);
            let (first, own, w, v, origin) = match twists[k] {
                Some(t) => (t.joint.unwrap_or(0), t.joint, t.w, t.v, t.origin),
                None => (usize::MAX, None, Vector3::zeros(), Vector3::zeros(), Vector3::zeros()),
            };
            if first != usize::MAX {
                let column = Vector3::new(jac[(0, k)], jac[(1, k)], jac[(2, k)]);
                let e = w.cross(&p) + v;
                prop_assert!((column - e).norm() < 1e-9 * (1.0 + e.norm()), "{id}: column {column} vs {e}");
            }
            for j in 0..robot.dof() {
                let moved = j >= first;
                let (ew, ea) = if own == Some(j) {
                    (w.cross(&axes[j].0), origin)
                } else if moved {
                    (w.cross(&axes[j].0), w.cross(&axes[j].1) + v)
                } else {
                    (Vector3::zeros(), Vector3::zeros())
                };
                let dw = rate(ap[j].0, am[j].0);
                prop_assert!((dw - ew).norm() < 1e-5 * (1.0 + ew.norm()), "{id}, axis {j}: {dw} vs {ew}");
                let da = rate(ap[j].1, am[j].1);
                prop_assert!((da - ea).norm() < 1e-5 * (1.0 + ea.norm()), "{id}, axis {j} origin: {da} vs {ea}");
                let (m, o) = &frames[j];
                let eo = if moved { w.cross(o) + v } else { Vector3::zeros() };
                let d_o = rate(fp[j].1, fm[j].1);
                prop_assert!((d_o - eo).norm() < 1e-5 * (1.0 + eo.norm()), "{id}, frame {j}: {d_o} vs {eo}");
                for c in 0..3 {
                    let u = m.column(c).into_owned();
                    let eu = if moved { w.cross(&u) } else { Vector3::zeros() };
                    let du = rate(fp[j].0.column(c).into_owned(), fm[j].0.column(c).into_owned());
                    prop_assert!((du - eu).norm() < 1e-5, "{id}, frame {j} column {c}: {du} vs {eu}");
                }
            }
        }
    }

    /// The orientation Jacobian against central differences of the tool frame's rotation
    /// (rotation vector of `R(x + h) R(x − h)ᵀ` over 2h), and the tool frame against the plain
    /// matrix product.
    #[test]
    fn orientation_jacobian_matches_central_differences((robot, q) in robot_strategy()) {
        let mut out = nalgebra::DMatrix::from_element(3, robot.param_count(), 7.0);
        let r = robot.write_orientation_jacobian(&q, &mut out, 0);
        let flange = robot.flange_pose(&q).rotation.into_inner();
        let tool = robot.tool_rpy.map_or_else(nalgebra::Matrix3::identity, |v| robocal_robot::rpy_to_matrix(&v));
        prop_assert!((r - flange * tool).norm() < 1e-12);
        prop_assert!((r - robot.tool_rotation(&q)).norm() < 1e-12);
        let x = robot.params();
        let h = 1e-6;
        for (k, id) in robot.param_ids().iter().enumerate() {
            let mut plus = x.clone();
            plus[k] += h;
            let mut minus = x.clone();
            minus[k] -= h;
            let rp = robot.with_params(&plus).unwrap().tool_rotation(&q);
            let rm = robot.with_params(&minus).unwrap().tool_rotation(&q);
            // The skew part of a small rotation is its rotation vector (sin θ ≈ θ), precisely.
            let d = rp * rm.transpose();
            let fd = Vector3::new(d[(2, 1)] - d[(1, 2)], d[(0, 2)] - d[(2, 0)], d[(1, 0)] - d[(0, 1)]) / (4.0 * h);
            let an = Vector3::new(out[(0, k)], out[(1, k)], out[(2, k)]);
            prop_assert!((fd - an).norm() < 1e-6, "{id}: analytic {an} vs fd {fd}");
        }
    }

    #[test]
    fn joint_jacobian_matches_central_differences((robot, q) in robot_strategy()) {
        let jac = robot.joint_jacobian(&q);
        let h = 1e-6;
        for i in 0..q.len() {
            let mut plus = q.clone();
            plus[i] += h;
            let mut minus = q.clone();
            minus[i] -= h;
            let fd = (robot.point(&plus) - robot.point(&minus)) / (2.0 * h);
            prop_assert!((fd - jac.column(i)).norm() < 1e-5 * (1.0 + fd.norm()), "q{}", i + 1);
        }
    }

    #[test]
    fn joint1_axis_is_the_walks_first_axis_at_any_reading((robot, q) in robot_strategy()) {
        let (axes, _) = robot.axes_and_frames(&q);
        let axis = robot.joint1_axis().expect("a joint");
        prop_assert!((axis - axes[0].0).norm() < 1e-12, "{axis} vs {}", axes[0].0);
    }

    #[test]
    fn batch_jacobian_stacks_single_ones((robot, q) in robot_strategy()) {
        let mut qs = q.clone();
        qs.extend(q.iter().map(|v| v * 0.5));
        let (points, jac) = robot.param_jacobian_batch(&qs);
        prop_assert_eq!(points.len(), 2);
        let half: Vec<f64> = q.iter().map(|v| v * 0.5).collect();
        let (p1, j1) = robot.param_jacobian(&half);
        prop_assert_eq!(points[1], p1);
        prop_assert_eq!(jac.rows(3, 3).into_owned(), nalgebra::DMatrix::from_column_slice(3, j1.ncols(), j1.as_slice()));
    }

    #[test]
    fn params_round_trip((robot, _q) in robot_strategy()) {
        let x = robot.params();
        prop_assert_eq!(x.len(), robot.param_count());
        prop_assert_eq!(&robot.with_params(&x).unwrap(), &robot);
        for id in robot.param_ids() {
            prop_assert_eq!(robot.param_by_name(&id.to_string()).unwrap(), id);
        }
    }

    #[test]
    fn toml_round_trip((robot, q) in robot_strategy()) {
        let text = robot.to_toml_string();
        let back = Robot::from_toml_str(&text, "round-trip.toml").unwrap();
        prop_assert_eq!(back.param_ids(), robot.param_ids());
        prop_assert!((back.point(&q) - robot.point(&q)).norm() < 1e-9);
        prop_assert_eq!(&back.points, &robot.points);
        let rot = |r: &Robot| r.tool_rotation(&q);
        prop_assert!((rot(&back) - rot(&robot)).norm() < 1e-12);
        prop_assert_eq!(back.tool_rpy.is_some(), robot.tool_rpy.is_some());
    }
}

/// Angles the user wrote come back as written (shortest decimals that read back exactly), not
/// as the noise of a degree → radian → degree round trip.
#[test]
fn written_angles_come_back_as_written() {
    let text = "name = \"w\"\n[base]\nxyz = [0, 0, 0]\nrpy = [0.1, -33.3, -120]\n[tool]\nxyz = [0, 0, 50]\n\
                [[joint]]\na = 0\nalpha = 179.99\nd = 0\ntheta = -120\nlimits = [-170.5, 170.5]\n\
                [[joint]]\na = 300\nalpha = 0\nbeta = 0.012\nd = 0\ntheta = 33.3\n";
    let robot = Robot::from_toml_str(text, "w.toml").unwrap();
    let out = robot.to_toml_string();
    for written in [
        "rpy = [0.1, -33.3, -120.0]",
        "alpha = 179.99",
        "theta = -120.0",
        "limits = [-170.5, 170.5]",
        "beta = 0.012",
        "theta = 33.3",
    ] {
        assert!(out.contains(written), "{written} not in\n{out}");
    }
    assert!(!out.contains("9999999"), "{out}");
}

// ---- hand-worked chains

fn one_joint(a: f64, alpha_deg: f64, beta_deg: Option<f64>, d: f64, tool: [f64; 3]) -> Robot {
    Robot {
        points: Vec::new(),
        tool_rpy: None,
        name: "one".into(),
        joints: vec![Joint {
            a,
            alpha: alpha_deg.to_radians(),
            beta: beta_deg.map(f64::to_radians),
            d,
            theta: 0.0,
            limits: None,
        }],
        base: Base {
            xyz: Vector3::zeros(),
            rpy: Vector3::zeros(),
        },
        tool: Vector3::from(tool),
    }
}

#[test]
fn planar_two_link_arm() {
    let mut robot = one_joint(0.0, 0.0, None, 0.0, [300.0, 0.0, 0.0]);
    robot.joints.push(Joint {
        a: 500.0,
        alpha: 0.0,
        beta: None,
        d: 0.0,
        theta: 0.0,
        limits: None,
    });
    for (q1, q2) in [(0.3, -1.1), (2.0, 0.4), (-0.7, 2.9)] {
        let p = robot.point(&[q1, q2]);
        let x = 500.0 * f64::cos(q1) + 300.0 * f64::cos(q1 + q2);
        let y = 500.0 * f64::sin(q1) + 300.0 * f64::sin(q1 + q2);
        assert!((p - Vector3::new(x, y, 0.0)).norm() < 1e-10, "{p}");
    }
}

#[test]
fn twist_offset_and_beta_by_hand() {
    // RotX(90°) turns z into -y: d = 100 along the new z lands at (0, -100, 0).
    let p = one_joint(0.0, 90.0, None, 100.0, [0.0; 3]).point(&[0.0]);
    assert!((p - Vector3::new(0.0, -100.0, 0.0)).norm() < 1e-12);
    // RotY(90°) turns z into x: d = 50 lands at (50, 0, 0) after a = 20 along x.
    let p = one_joint(20.0, 0.0, Some(90.0), 50.0, [0.0; 3]).point(&[0.0]);
    assert!((p - Vector3::new(70.0, 0.0, 0.0)).norm() < 1e-12);
    // Base: yaw 90° and an offset.
    let mut robot = one_joint(0.0, 0.0, None, 0.0, [100.0, 0.0, 0.0]);
    robot.base.xyz = Vector3::new(1000.0, 0.0, 0.0);
    robot.base.rpy = Vector3::new(0.0, 0.0, FRAC_PI_2);
    assert!((robot.point(&[0.0]) - Vector3::new(1000.0, 100.0, 0.0)).norm() < 1e-12);
}

#[test]
fn pmc6_at_zero_by_hand() {
    // Worked through Table 1 frame by frame: shoulder at z = 601, upper arm 270 + 800 + 140
    // along x, forearm 737.5 down, flange 227.3 further down with z6 pointing down, reflector
    // 100 mm along z6.
    let mut robot = pmc6();
    robot.base.xyz = Vector3::zeros();
    robot.base.rpy = Vector3::zeros();
    let flange = robot.flange_pose(&[0.0; 6]);
    let o = flange.translation.vector;
    assert!(
        (o - Vector3::new(1210.0, 0.0, 601.0 - 737.5 - 227.3)).norm() < 1e-9,
        "{o}"
    );
    assert!((flange.rotation * Vector3::z() - Vector3::new(0.0, 0.0, -1.0)).norm() < 1e-12);
    assert!((robot.point(&[0.0; 6]) - Vector3::new(1210.0, 0.0, -463.8)).norm() < 1e-9);
}

#[test]
fn pmc6_has_34_parameters_with_stable_names() {
    let robot = pmc6();
    assert_eq!(robot.param_count(), 34);
    let names: Vec<String> = robot.param_ids().iter().map(ToString::to_string).collect();
    assert_eq!(
        &names[..6],
        ["j1.a", "j1.alpha", "j1.d", "j1.theta", "j2.a", "j2.alpha"]
    );
    assert_eq!(names[10], "j3.beta");
    assert_eq!(
        &names[25..],
        [
            "base.x", "base.y", "base.z", "base.rx", "base.ry", "base.rz", "tool.x", "tool.y",
            "tool.z"
        ]
    );
    assert!(matches!(
        robot.param_by_name("j2.beta"),
        Err(RobotError::UnknownParameter { .. })
    ));
    assert!(matches!(
        robot.param_by_name("j7.a"),
        Err(RobotError::UnknownParameter { .. })
    ));
    assert!(matches!(
        robot.param_by_name("base.q"),
        Err(RobotError::UnknownParameter { .. })
    ));
    let id = robot.param_by_name("j3.beta").unwrap();
    assert!((id.to_file_units(id.from_file_units(0.25)) - 0.25).abs() < 1e-15);
    assert_eq!(ParamId::Tool(2).file_unit_name(), "mm");
}

// ---- inverse kinematics

struct Lcg(u64);
impl Lcg {
    fn uniform(&mut self, lo: f64, hi: f64) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        lo + (hi - lo) * ((self.0 >> 11) as f64 / (1u64 << 53) as f64)
    }
}

#[test]
fn ik_round_trip_on_random_reachable_poses() {
    let robot = pmc6();
    let mut rng = Lcg(7);
    let options = IkOptions::default();
    let (mut solved, mut tried) = (0, 0);
    for _ in 0..200 {
        let q: Vec<f64> = robot
            .joints
            .iter()
            .map(|j| {
                let (lo, hi) = j.limits.unwrap();
                rng.uniform(lo.max(-2.5), hi.min(2.5))
            })
            .collect();
        let seed: Vec<f64> = q.iter().map(|v| v + rng.uniform(-0.25, 0.25)).collect();
        let (rotation, origin) = robot.flange_frame(&q);
        let point = origin + rotation * robot.tool;
        let target = IkTarget::Pose { point, rotation };
        tried += 1;
        if let Ok(sol) = robot.inverse_kinematics(&target, &seed, &options) {
            solved += 1;
            let (r, o) = robot.flange_frame(&sol);
            assert!((o + r * robot.tool - point).norm() < 1e-6);
            assert!(
                (r - rotation).norm() < 1e-8,
                "{} {:?} {:?}",
                (r - rotation).norm(),
                q,
                sol
            );
            assert!(robot.within_limits(&sol));
        }
        // Position only: the 6-axis arm is redundant for a point, the answer stays near the seed.
        let sol = robot
            .inverse_kinematics(&IkTarget::Point(point), &seed, &options)
            .expect("a point target near the seed converges");
        assert!((robot.point(&sol) - point).norm() < 1e-6);
    }
    assert!(
        solved * 100 >= tried * 95,
        "pose IK solved {solved} of {tried}"
    );
}

#[test]
fn ik_reports_unreachable_targets() {
    let robot = pmc6();
    let err = robot
        .inverse_kinematics(
            &IkTarget::Point(Vector3::new(5000.0, 0.0, 0.0)),
            &[0.0; 6],
            &IkOptions::default(),
        )
        .unwrap_err();
    match err {
        RobotError::IkNotConverged { position_error, .. } => assert!(position_error > 1000.0),
        other => panic!("unexpected {other}"),
    }
    assert!(matches!(
        robot.inverse_kinematics(
            &IkTarget::Point(Vector3::zeros()),
            &[0.0; 5],
            &IkOptions::default()
        ),
        Err(RobotError::JointCountMismatch {
            expected: 6,
            found: 5
        })
    ));
}

#[test]
fn ik_respects_joint_limits() {
    // A single joint limited to ±30° cannot reach a point at 90°.
    let mut robot = one_joint(0.0, 0.0, None, 0.0, [100.0, 0.0, 0.0]);
    robot.joints[0].limits = Some((-30f64.to_radians(), 30f64.to_radians()));
    let target = IkTarget::Point(Vector3::new(0.0, 100.0, 0.0));
    assert!(
        robot
            .inverse_kinematics(&target, &[0.0], &IkOptions::default())
            .is_err()
    );
    let inside = IkTarget::Point(robot.point(&[20f64.to_radians()]));
    let q = robot
        .inverse_kinematics(&inside, &[0.0], &IkOptions::default())
        .unwrap();
    assert!((q[0] - 20f64.to_radians()).abs() < 1e-9);
}

/// The payload's gravity torque about each joint axis, computed here from the definition with
/// the joint axes and the flange frame; and the compliance model's file round trip.
#[test]
fn compliance_torques_jacobian_and_file_round_trip() {
    use robocal_robot::{Compliance, DEG_PER_KNM};
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    let robot = Robot::load(root.join("configs/robots/pmc6va030.toml")).unwrap();
    let c = Compliance::new(
        [0.0, 0.08, 0.14, 0.38, 0.48, 0.57]
            .iter()
            .map(|v| v * DEG_PER_KNM)
            .collect(),
        Vector3::new(0.1, -0.2, -9.8),
        Vector3::new(100.0, -20.0, 60.0),
    );
    let q: Vec<f64> = [10.0f64, -40.0, 25.0, 30.0, 50.0, -15.0]
        .iter()
        .map(|d| d.to_radians())
        .collect();
    let load = 12.0;
    let torques = c.torques(&robot, &q, load);
    // Independently: the moment of the payload's weight about each axis, by finite rotation of
    // the joint (work done by gravity per radian).
    let (r, o) = robot.flange_frame(&q);
    let com = o + r * c.payload_com;
    let g = robot.base_rotation() * c.gravity * load;
    for j in 0..6 {
        let h = 1e-6;
        let mut qp = q.clone();
        qp[j] += h;
        let (rp, op) = robot.flange_frame(&qp);
        let moved = (op + rp * c.payload_com - com) / h;
        // τ = dW/dθ: gravity's work on the payload when the joint turns, N·mm → N·m.
        let expected = g.dot(&moved) * 1e-3;
        assert!(
            (torques[j] - expected).abs() < 1e-5 * (1.0 + expected.abs()),
            "joint {}: {} vs {expected}",
            j + 1,
            torques[j]
        );
    }
    // No load, no deflection.
    assert_eq!(c.deflected(&robot, &q, 0.0), q);
    // Jacobian column = d point / d compliance, against central differences.
    let (p, jac) = c.jacobian(&robot, &q, load);
    assert!((p - c.point(&robot, &q, load)).norm() < 1e-12);
    for j in 1..6 {
        let h = 1e-9;
        let (mut up, mut down) = (c.clone(), c.clone());
        up.values[j] += h;
        down.values[j] -= h;
        let fd = (up.point(&robot, &q, load) - down.point(&robot, &q, load)) / (2.0 * h);
        assert!(
            (fd - jac.column(j)).norm() < 1e-5 * fd.norm().max(1.0),
            "joint {}",
            j + 1
        );
    }
    let text = c.to_toml_string();
    let back = Compliance::from_toml_str(&text, "compliance.toml", 6).unwrap();
    assert_eq!(back.gravity, c.gravity);
    assert_eq!(back.payload_com, c.payload_com);
    for (a, b) in back.values.iter().zip(&c.values) {
        assert!((a - b).abs() <= 1e-15 * b.abs(), "{a} vs {b}");
    }
    let err = Compliance::from_toml_str(&text, "m/compliance.toml", 5)
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("m/compliance.toml") && err.contains("compliance"),
        "{err}"
    );
    let err = Compliance::from_toml_str("gravity = [0, 0, -9.8]\n", "c.toml", 6)
        .unwrap_err()
        .to_string();
    assert!(err.contains("c.toml") && err.contains("line"), "{err}");
}

/// The joint-error family: the self-weight basis is gravity's work per radian on a unit mass at a
/// link frame's origin (or a unit first moment along a frame axis), computed here by turning the
/// joint; the Jacobian of every coefficient (compliance, harmonic sine and cosine, self-weight,
/// backlash, link weight, tilt, runout sine and cosine) against central differences; harmonics
/// and runouts act with no load, a runout turning the point about its joint's origin across
/// the axis; the file round trip keeps every term, and a term on a joint the robot lacks, or a
/// second runout of one joint, order and axis, is refused with its key.
#[test]
fn joint_errors_basis_jacobian_and_file_round_trip() {
    use robocal_robot::{DEG_PER_KNM, ErrorParam, JointErrors, MomentPart};
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    let robot = Robot::load(root.join("configs/robots/pmc6va030.toml")).unwrap();
    let mut e = JointErrors::new(
        [0.0, 0.08, 0.14, 0.38, 0.48, 0.57]
            .iter()
            .map(|v| v * DEG_PER_KNM)
            .collect(),
        Vector3::new(0.1, -0.2, -9.8),
        Vector3::new(100.0, -20.0, 60.0),
    )
    .with_harmonics(&[0, 1, 3], 2)
    .with_self_weight(&[1, 2], 6)
    .with_backlash(&[0, 3])
    .with_link_weights(&[1, 2, 4, 5])
    .with_tilts(&[0, 1, 2, 4])
    .with_runouts(&[0, 2, 5], 2);
    // One runout held beyond a reach the command lies outside of.
    e.runouts[3].wave.reach = Some([0.5, 0.8]);
    for (k, p) in e.params().into_iter().enumerate() {
        let v = match p {
            // Links of kilograms, first moments of a fraction of a kg·m.
            ErrorParam::LinkWeight(_) => 3.0 - 0.7 * (k % 5) as f64,
            // Tilting compliances a few times stiffer than the joints turn.
            ErrorParam::Tilt(_) => (0.02 + 0.01 * (k % 3) as f64) * DEG_PER_KNM,
            // Runouts of a thousandth of a degree (the columns leave out their turn of the
            // other columns, as the tilts'; `JointErrors::param_jacobian`).
            ErrorParam::RunoutSin(_) | ErrorParam::RunoutCos(_) => 1e-5 * ((k % 7) as f64 - 3.0),
            _ => e.param(p) + 1e-4 * ((k % 7) as f64 - 3.0),
        };
        e.set_param(p, v);
    }
    let q: Vec<f64> = [10.0f64, -40.0, 25.0, 30.0, 50.0, -15.0]
        .iter()
        .map(|d| d.to_radians())
        .collect();
    let load = 7.0;
    let g = robot.base_rotation() * e.gravity;
    let sw: Vec<ErrorParam> = (0..e.self_weight.len())
        .map(ErrorParam::SelfWeight)
        .collect();
    let basis = e.basis(&robot, &q, load, &sw);
    assert_eq!(basis.len(), sw.len());
    for &(i, joint, phi) in &basis {
        let t = e.self_weight[i];
        let phi = &phi;
        assert_eq!(joint, t.joint);
        let h = 1e-6;
        let at = |q: &[f64]| {
            let (r, o) = robot.link_frames(q)[t.body];
            match t.part {
                MomentPart::Mass => o * 1e-3, // a kg at the origin: N·m per (m/s² · m)
                MomentPart::X => r.column(0).into_owned(),
                MomentPart::Y => r.column(1).into_owned(),
                MomentPart::Z => r.column(2).into_owned(),
            }
        };
        let mut qp = q.clone();
        qp[t.joint] += h;
        let mut qm = q.clone();
        qm[t.joint] -= h;
        let expected = g.dot(&((at(&qp) - at(&qm)) / (2.0 * h)));
        assert!(
            (phi - expected).abs() < 1e-6 * (1.0 + expected.abs()),
            "{}: {phi} vs {expected}",
            e.param_name(ErrorParam::SelfWeight(i))
        );
    }
    // Harmonics act without a load.
    assert_ne!(e.deflected(&robot, &q, 0.0), q);
    // A runout alone, by hand: joint 3's order-1 cosine about its frame's y turns the parts
    // beyond it about its origin by `cos · cos(q3)` about that axis, with no load, and turns no
    // joint.
    let mut alone = JointErrors::new(vec![0.0; 6], e.gravity, e.payload_com).with_runouts(&[2], 1);
    let c = 2e-4;
    alone.runouts[1].wave.cos = c;
    assert_eq!(alone.runouts[1].across, robocal_robot::Across::Y);
    let (axes, frames) = robot.axes_and_frames(&q);
    let turn = frames[2].0.column(1) * c * q[2].cos();
    let p = robot.point(&q);
    let expected = p + turn.cross(&(p - axes[2].1));
    assert!((alone.point(&robot, &q, 0.0) - expected).norm() < 1e-12);
    assert!((alone.point(&robot, &q, 0.0) - p).norm() > 1e-2);
    assert_eq!(alone.deflected(&robot, &q, 0.0), q);
    // The runouts' turns among a model's turns (the tilting joints' first): those of the same
    // runouts without the tilts; joint 3's order-1 cosine alone, the turn by hand.
    let turns = e.turns(&robot, &q, load);
    assert_eq!(turns.len(), e.tilts.len() + e.runouts.len());
    let mut without_tilts = e.clone();
    without_tilts.tilts.clear();
    assert_eq!(
        e.runout_turns(&turns),
        without_tilts.turns(&robot, &q, load).as_slice()
    );
    let turns = alone.turns(&robot, &q, 0.0);
    assert_eq!(alone.runout_turns(&turns).len(), 2);
    assert!((alone.runout_turns(&turns)[1].0 - turn).norm() < 1e-15);
    let params = e.params();
    let (p, jac) = e.param_jacobian(&robot, &q, load, &params);
    assert!((p - e.point(&robot, &q, load)).norm() < 1e-12);
    for (k, &param) in params.iter().enumerate() {
        let h = match param {
            ErrorParam::Compliance(_) => 1e-9,
            _ => 1e-7,
        };
        let (mut up, mut down) = (e.clone(), e.clone());
        up.set_param(param, e.param(param) + h);
        down.set_param(param, e.param(param) - h);
        let fd = (up.point(&robot, &q, load) - down.point(&robot, &q, load)) / (2.0 * h);
        assert!(
            (fd - jac.column(k)).norm() < 1e-4 * fd.norm().max(1.0),
            "{}: {fd} vs {}",
            e.param_name(param),
            jac.column(k)
        );
    }
    // The orientation columns (a 6-DoF probe's tool frame, tilted on the flange) likewise.
    let probe = Robot {
        tool_rpy: Some(Vector3::new(0.3, -0.2, 1.1)),
        ..robot.clone()
    };
    // The rotation vector between the tool frames of two models, over their parameters' step.
    let orientation_fd = |up: &JointErrors, down: &JointErrors, h: f64| {
        rotation_difference(&probe, &q, load, (up, down), h)
    };
    let (rot, ojac) = e.orientation_param_jacobian(&probe, &q, load, &params);
    assert!((rot - e.rotation(&probe, &q, load)).norm() < 1e-12);
    for (k, &param) in params.iter().enumerate() {
        let h = match param {
            ErrorParam::Compliance(_) => 1e-9,
            _ => 1e-7,
        };
        let (mut up, mut down) = (e.clone(), e.clone());
        up.set_param(param, e.param(param) + h);
        down.set_param(param, e.param(param) - h);
        let fd = orientation_fd(&up, &down, h);
        assert!(
            (fd - ojac.column(k)).norm() < 1e-4 * fd.norm().max(1e-3),
            "orientation {}: {fd} vs {}",
            e.param_name(param),
            ojac.column(k)
        );
    }
    the_payload_centre_of_mass_columns_match_differences(&robot, &e, &q, load, &probe);
}

/// The payload's centre of mass moves the payload's torque on every joint: its columns
/// (small, a compliance times a load times a lever) against central differences, tightly
/// with rigid bearings; with tilting ones to the order of the tilts (the columns leave out
/// the tilts' turn of the joints' deflections, micro-radians of them).
fn the_payload_centre_of_mass_columns_match_differences(
    robot: &Robot,
    e: &robocal_robot::JointErrors,
    q: &[f64],
    load: f64,
    probe: &Robot,
) {
    use robocal_robot::{ErrorParam, JointErrors};
    let orientation_fd = |up: &JointErrors, down: &JointErrors, h: f64| {
        rotation_difference(probe, q, load, (up, down), h)
    };
    let com: Vec<ErrorParam> = (0..3).map(ErrorParam::PayloadCom).collect();
    let rigid_bearings = JointErrors {
        tilts: Vec::new(),
        runouts: Vec::new(),
        ..e.clone()
    };
    for (e, tolerance) in [(&rigid_bearings, 1e-6), (e, 5e-4)] {
        let (_, cjac) = e.param_jacobian(robot, q, load, &com);
        let (_, cojac) = e.orientation_param_jacobian(probe, q, load, &com);
        for (k, &param) in com.iter().enumerate() {
            let h = 1e-2;
            let (mut up, mut down) = (e.clone(), e.clone());
            up.set_param(param, e.param(param) + h);
            down.set_param(param, e.param(param) - h);
            let fd = (up.point(robot, q, load) - down.point(robot, q, load)) / (2.0 * h);
            assert!(
                fd.norm() > 1e-5 && (fd - cjac.column(k)).norm() < tolerance * fd.norm(),
                "{}: {fd} vs {}",
                e.param_name(param),
                cjac.column(k)
            );
            let fd = orientation_fd(&up, &down, h);
            assert!(
                (fd - cojac.column(k)).norm() < tolerance * fd.norm(),
                "orientation {}: {fd} vs {}",
                e.param_name(param),
                cojac.column(k)
            );
        }
    }
    // The tilts' part of those columns matters: without it they would miss the differences
    // by several times the tolerance.
    let (_, without) = rigid_bearings.param_jacobian(robot, q, load, &com);
    let (_, with) = e.param_jacobian(robot, q, load, &com);
    let ratio = (with - &without).norm() / without.norm();
    assert!(ratio > 2e-3, "{ratio}");
    assert_eq!(e.param_name(ErrorParam::PayloadCom(2)), "payload_com.z");
    // Without a load the payload's centre of mass moves nothing.
    let (_, unloaded) = e.param_jacobian(robot, q, 0.0, &com);
    assert_eq!(unloaded.norm(), 0.0);
    shared_link_weights_deflect_as_per_joint_terms_and_the_file_reads_back(robot, e, q, load);
}

/// The shared link weights are the per-joint self-weight terms with coefficient
/// `compliance × weight` for every joint up to the link: the same deflection.
fn shared_link_weights_deflect_as_per_joint_terms_and_the_file_reads_back(
    robot: &Robot,
    e: &robocal_robot::JointErrors,
    q: &[f64],
    load: f64,
) {
    use robocal_robot::JointErrors;
    let mut shared = JointErrors::new(e.values.clone(), e.gravity, e.payload_com);
    shared.link_weights = e.link_weights.clone();
    let mut per_joint = JointErrors::new(e.values.clone(), e.gravity, e.payload_com);
    for w in &e.link_weights {
        for joint in 0..=w.body {
            per_joint.self_weight.push(robocal_robot::SelfWeight {
                joint,
                body: w.body,
                part: w.part,
                value: e.values[joint] * w.value,
            });
        }
    }
    let (a, b) = (
        shared.deflection(robot, q, load),
        per_joint.deflection(robot, q, load),
    );
    assert!(
        a.iter().zip(&b).all(|(a, b)| (a - b).abs() < 1e-15),
        "{a:?} vs {b:?}"
    );
    assert!(
        a[1].abs() > 1e-6,
        "the links' weights deflect joint 2: {a:?}"
    );
    let text = e.to_toml_string();
    assert!(
        text.contains("[[harmonic]]")
            && text.contains("[[self_weight]]")
            && text.contains("[[backlash]]")
            && text.contains("[[link_weight]]")
            && text.contains("[[tilt]]")
            && text.contains("[[runout]]")
    );
    let back = JointErrors::from_toml_str(&text, "compliance.toml", 6).unwrap();
    assert_eq!(back.params(), e.params());
    for p in e.params() {
        let (a, b) = (back.param(p), e.param(p));
        assert!((a - b).abs() <= 1e-15 * b.abs().max(1e-300), "{a} vs {b}");
    }
    let point = |m: &JointErrors| m.point(robot, q, load);
    assert!((point(&back) - point(e)).norm() < 1e-9);
    let bad = text.replacen("joint = 4", "joint = 9", 1);
    let err = JointErrors::from_toml_str(&bad, "m/compliance.toml", 6)
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("m/compliance.toml") && err.contains("harmonic[5]"),
        "{err}"
    );
    let bad = text.replacen("order = 1\nacross = \"y\"", "order = 1\nacross = \"x\"", 1);
    assert_ne!(bad, text);
    let err = JointErrors::from_toml_str(&bad, "m/compliance.toml", 6)
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("runout[2]") && err.contains("about x already"),
        "{err}"
    );
    let bad = text.replacen("[[link_weight]]\nbody = 2", "[[link_weight]]\nbody = 7", 1);
    assert_ne!(bad, text);
    let err = JointErrors::from_toml_str(&bad, "m/compliance.toml", 6)
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("link_weight[1]") && err.contains("body 7"),
        "{err}"
    );
}

/// A tilting compliance, by hand: a vertical joint holding 10 kg one metre out feels 98 N·m
/// across its axis (none about it); at 1e-5 rad/(N·m) the arm tilts about its origin by
/// 0.98 mrad, so the point sinks by 0.98 mm, with no load not at all, and the tool frame turns
/// by the same angle about the horizontal across the arm. The links' weights add their moment
/// (a 2 kg link half-way out: 9.8 N·m more); a joint's own turn (its compliance about the
/// axis) meets none of this moment. The file keeps it; a second tilt of one joint is refused.
#[test]
fn a_tilting_joint_sinks_by_its_compliance_times_the_moment_across_its_axis() {
    use robocal_robot::{ErrorParam, JointErrors, LinkWeight, MomentPart};
    let robot = Robot::from_toml_str(
        "name = \"arm\"\n[base]\nxyz = [0, 0, 0]\nrpy = [0, 0, 0]\n[tool]\nxyz = [1000, 0, 0]\n\
         rpy = [0, 0, 0]\n[[joint]]\na = 0\nalpha = 0\nd = 0\ntheta = 0\n",
        "arm.toml",
    )
    .unwrap();
    let g = Vector3::new(0.0, 0.0, -9.80665);
    let payload = Vector3::new(1000.0, 0.0, 0.0);
    let mut e = JointErrors::new(vec![0.0], g, payload).with_tilts(&[0]);
    e.set_param(ErrorParam::Tilt(0), 1e-5);
    let q = [0.3];
    let rigid = robot.point(&q);
    let sag = rigid.z - e.point(&robot, &q, 10.0).z;
    assert!((sag - 0.980665).abs() < 1e-9, "{sag}");
    assert!((e.point(&robot, &q, 10.0).xy() - rigid.xy()).norm() < 1e-9);
    assert_eq!(e.point(&robot, &q, 0.0), rigid);
    // The tool frame turns by 0.98 mrad about the horizontal across the arm.
    let turn = robocal_robot::rotation_vector(
        &(e.rotation(&robot, &q, 10.0) * robot.tool_rotation(&q).transpose()),
    );
    let across = Vector3::new(-q[0].sin(), q[0].cos(), 0.0);
    assert!((turn - across * 9.80665e-4).norm() < 1e-12, "{turn}");
    // A 2 kg link whose weight acts 500 mm out (its first moment along its frame's x).
    e.link_weights.push(LinkWeight {
        body: 0,
        part: MomentPart::X,
        value: 1.0,
    });
    let sag = rigid.z - e.point(&robot, &q, 10.0).z;
    assert!((sag - 1.0787315).abs() < 1e-9, "{sag}");
    // A compliance about the axis: gravity has no torque about a vertical axis.
    e.values[0] = 1e-3;
    assert!((rigid.z - e.point(&robot, &q, 10.0).z - 1.0787315).abs() < 1e-9);
    let text = e.to_toml_string();
    assert!(text.contains("[[tilt]]\njoint = 1\n"), "{text}");
    let back = JointErrors::from_toml_str(&text, "c.toml", 1).unwrap();
    assert_eq!(back.tilts, e.tilts);
    let twice = format!("{text}\n[[tilt]]\njoint = 1\ncompliance = 0.1\n");
    let err = JointErrors::from_toml_str(&twice, "m/c.toml", 1)
        .unwrap_err()
        .to_string();
    assert!(err.contains("m/c.toml") && err.contains("tilt[2]"), "{err}");
}

/// Backlash on the flank of the approach from home: `+value` at or above home, `−value` below,
/// whatever the load; the coefficient's column is the joint's column times that sign; the file
/// round trip keeps home and value; bad entries are refused with their key.
#[test]
fn backlash_rests_on_the_flank_of_the_approach_from_home() {
    use robocal_robot::{ErrorParam, JointErrors};
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    let robot = Robot::load(root.join("configs/robots/pmc6va030.toml")).unwrap();
    let mut e = JointErrors::new(vec![0.0; 6], Vector3::new(0.0, 0.0, -9.8), Vector3::zeros())
        .with_backlash(&[0, 4]);
    assert_eq!(
        e.params()[6..],
        [ErrorParam::Backlash(0), ErrorParam::Backlash(1)]
    );
    assert_eq!(e.param_name(ErrorParam::Backlash(1)), "j5.backlash");
    e.backlash[0].value = 0.02f64.to_radians();
    e.backlash[1].value = (-0.05f64).to_radians();
    e.backlash[1].flank = robocal_robot::Flank::Approach {
        home: 10f64.to_radians(),
    };
    for (q1, q5) in [
        (-30.0f64, 40.0f64),
        (0.0, 10.0),
        (-1e-9, 9.999),
        (75.0, -80.0),
    ] {
        let mut q = vec![0.0, -0.5, 0.3, 0.2, 0.0, 0.1];
        (q[0], q[4]) = (q1.to_radians(), q5.to_radians());
        for load in [0.0, 12.0] {
            let d = e.deflected(&robot, &q, load);
            let want1 = if q1 >= 0.0 { 0.02 } else { -0.02 };
            let want5 = if q5 >= 10.0 { -0.05 } else { 0.05 };
            assert!(((d[0] - q[0]).to_degrees() - want1).abs() < 1e-12, "{q1}");
            assert!(((d[4] - q[4]).to_degrees() - want5).abs() < 1e-12, "{q5}");
            assert_eq!([d[1], d[2], d[3], d[5]], [q[1], q[2], q[3], q[5]]);
            let params = [ErrorParam::Backlash(0), ErrorParam::Backlash(1)];
            let (_, jac) = e.param_jacobian(&robot, &q, load, &params);
            let joint = robot.joint_jacobian(&d);
            let sign = |x: bool| if x { 1.0 } else { -1.0 };
            assert!((jac.column(0) - joint.column(0) * sign(q1 >= 0.0)).norm() < 1e-12);
            assert!((jac.column(1) - joint.column(4) * sign(q5 >= 10.0)).norm() < 1e-12);
        }
    }
    let text = e.to_toml_string();
    assert!(text.contains("[[backlash]]"), "{text}");
    let back = JointErrors::from_toml_str(&text, "compliance.toml", 6).unwrap();
    for (a, b) in back.backlash.iter().zip(&e.backlash) {
        assert_eq!(a.joint, b.joint);
        let (ha, hb) = (a.home().unwrap(), b.home().unwrap());
        assert!((ha - hb).abs() < 1e-15 && (a.value - b.value).abs() < 1e-17);
    }
    assert_eq!(back.backlash.len(), 2);
    for (from, to) in [
        ("joint = 5", "joint = 7"),
        ("joint = 5", "joint = 1"),
        ("home = 10.0", "home = nan"),
    ] {
        assert!(text.contains(from), "{text}");
        let err = JointErrors::from_toml_str(&text.replacen(from, to, 1), "m/c.toml", 6)
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("m/c.toml") && err.contains("backlash[2]"),
            "{err}"
        );
    }
}

/// Backlash on the flank the torque presses: the flank is the sign of the joint's gravity torque
/// of the weights' links, payload and preload, computed here independently (gravity's work on
/// each mass point per unit turn of the joint, by central differences); the coefficient's
/// column is the joint's column times the flank; the file keeps the weights, and a wrong
/// number of them, or both a home and weights, is refused with the key.
#[test]
fn backlash_rests_on_the_flank_the_torque_presses() {
    use robocal_robot::{ErrorParam, Flank, JointErrors};
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    let robot = Robot::load(root.join("configs/robots/pmc6va030.toml")).unwrap();
    let gravity = Vector3::new(0.0, 0.0, -9.80665);
    let mut e = JointErrors::new(vec![0.0; 6], gravity, Vector3::zeros()).with_backlash(&[1]);
    // Joint 2: links 2..6 (4 features each), the payload's 4, the preload.
    let mut weights = vec![0.0; JointErrors::torque_feature_count(6, 1)];
    assert_eq!(weights.len(), 25);
    weights[4] = 10.0; // 10 kg at link 3's frame origin
    weights[4 * 3 + 2] = 0.5; // link 5: 0.5 kg·m along its frame's y axis
    let com = Vector3::new(0.1, -0.05, 0.2); // payload centre of mass, m, flange frame
    weights[20..24].copy_from_slice(&[1.0, com.x, com.y, com.z]);
    weights[24] = 30.0; // preload, N·m
    e.backlash[0].flank = Flank::Torque {
        weights: weights.clone(),
    };
    e.backlash[0].value = 0.04f64.to_radians();
    let g = robot.base_rotation() * gravity;
    let torque = |q: &[f64], load: f64| {
        // Gravity's work per unit turn of joint 2 on every mass point (positions in m).
        let points = |q: &[f64]| {
            let frames = robot.link_frames(q);
            let (r4, _) = frames[4];
            let (r6, o6) = frames[5];
            [
                (10.0, frames[2].1 * 1e-3),
                (1.0, r4.column(1) * 0.5),
                (load, o6 * 1e-3 + r6 * com),
            ]
        };
        let h = 1e-6;
        let (mut up, mut down) = (q.to_vec(), q.to_vec());
        up[1] += h;
        down[1] -= h;
        let work: f64 = (points(&up).iter().zip(points(&down)))
            .map(|((m, a), (_, b))| m * g.dot(&((a - b) / (2.0 * h))))
            .sum();
        work + 30.0
    };
    let mut seen = [0, 0];
    for k in 0..60 {
        let q: Vec<f64> = (0..6)
            .map(|j| ((k * 7 + j * 13) % 23) as f64 / 23.0 * 3.0 - 1.5)
            .collect();
        for load in [0.0, 8.0, 20.0] {
            let t = torque(&q, load);
            if t.abs() < 0.05 {
                continue;
            }
            let want = if t >= 0.0 { 1.0 } else { -1.0 };
            seen[usize::from(t >= 0.0)] += 1;
            assert_eq!(
                e.flank(&e.backlash[0], &robot, &q, load),
                want,
                "{q:?} {load}: {t}"
            );
            let d = e.deflected(&robot, &q, load);
            assert!(((d[1] - q[1]) - want * 0.04f64.to_radians()).abs() < 1e-15);
            let (_, jac) = e.param_jacobian(&robot, &q, load, &[ErrorParam::Backlash(0)]);
            assert!((jac.column(0) - robot.joint_jacobian(&d).column(1) * want).norm() < 1e-12);
        }
    }
    assert!(seen[0] > 10 && seen[1] > 10, "{seen:?}");
    let text = e.to_toml_string();
    let back = JointErrors::from_toml_str(&text, "compliance.toml", 6).unwrap();
    assert_eq!(back.backlash[0].flank, Flank::Torque { weights });
    assert!(!text.lines().any(|l| l.starts_with("home")), "{text}");
    let list = text.lines().find(|l| l.starts_with("torque = ")).unwrap();
    for bad in [
        "torque = [1.0, 2.0]".to_string(),
        format!("home = 0.0\n{list}"),
        String::new(),
    ] {
        let err = JointErrors::from_toml_str(&text.replacen(list, &bad, 1), "m/c.toml", 6)
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("m/c.toml") && err.contains("backlash[1]"),
            "{err}"
        );
    }
}

/// Joint errors of the paper's arm with compliances alone (joints 2–6, 8e-7 to 5.7e-6 rad/N·m),
/// standard gravity, the payload's centre of mass 100 mm along the flange's x and 60 along z.
fn compliant_pmc6() -> robocal_robot::JointErrors {
    let compliances = [0.0, 0.08, 0.14, 0.38, 0.48, 0.57]
        .map(|c| c * 1e-5)
        .to_vec();
    robocal_robot::JointErrors::new(
        compliances,
        Vector3::new(0.0, 0.0, -9.80665),
        Vector3::new(100.0, 0.0, 60.0),
    )
}

/// A link weight held at zero adds nothing to the deflection (its unit torques are not
/// computed): the same points, deflections and rows as without it, bit for bit. Where it is
/// identified, its basis is there all the same: the same as with any value, since a link
/// weight's basis is each joint's compliance times its unit torque.
#[test]
fn a_link_weight_at_zero_adds_nothing_and_keeps_its_basis() {
    use robocal_robot::ErrorParam;
    let robot = pmc6();
    // Every link's mass and moments; a few of them loaded, the rest at zero.
    let mut all = compliant_pmc6()
        .with_link_weights(&[0, 1, 2, 3, 4, 5])
        .with_backlash(&[2]);
    let loaded = [(9, 6.8), (10, 11.75), (13, -0.27), (17, 0.21), (22, -0.03)];
    for (i, v) in loaded {
        all.link_weights[i].value = v;
    }
    all.backlash[0].value = 0.01f64.to_radians();
    let mut few = all.clone();
    few.link_weights.retain(|w| w.value != 0.0);
    assert_eq!(few.link_weights.len(), loaded.len());
    let zero = (all.link_weights.iter()).position(|w| w.value == 0.0 && w.body == 4);
    let zero = zero.expect("a link weight at zero");
    let mut one = all.clone();
    one.link_weights[zero].value = 1.0;
    let params = [ErrorParam::Compliance(3), ErrorParam::LinkWeight(zero)];
    for k in 0..40 {
        let q: Vec<f64> = (0..6)
            .map(|j| ((k * 7 + j * 13) % 23) as f64 / 23.0 * 3.0 - 1.5)
            .collect();
        for load in [0.0, 8.0, 20.0] {
            let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
            assert_eq!(
                bits(&all.deflected(&robot, &q, load)),
                bits(&few.deflected(&robot, &q, load)),
                "{q:?} {load}"
            );
            let p = all.point(&robot, &q, load);
            assert_eq!(
                bits(p.as_slice()),
                bits(few.point(&robot, &q, load).as_slice())
            );
            let basis = all.basis(&robot, &q, load, &params);
            let unit = one.basis(&robot, &q, load, &params);
            // Joints 2–5 (those up to link 5 with a compliance) each turn by the weight.
            let of_weight = |b: &[(usize, usize, f64)]| {
                (b.iter().filter(|(k, _, _)| *k == 1))
                    .map(|(_, j, phi)| (*j, phi.to_bits()))
                    .collect::<Vec<_>>()
            };
            assert_eq!(of_weight(&basis).len(), 4, "{basis:?}");
            assert_eq!(of_weight(&basis), of_weight(&unit));
            assert!(
                of_weight(&basis)
                    .iter()
                    .any(|(_, b)| f64::from_bits(*b) != 0.0)
            );
        }
    }
}

/// A self-weight term at zero adds nothing to the deflection (its basis is not computed: most
/// of a fit's terms are held there): the deflection is the sum over every term in order,
/// `compliance × torque + Σ value × φ`, to the bit — the sign of a zero too (a joint whose
/// compliance is negative deflects by −0 without a load, and a term at zero with `φ > 0` turns
/// that +0) — with `φ` read from the joint's torque features. A term at zero that is
/// identified keeps its basis.
#[test]
fn a_self_weight_term_at_zero_adds_nothing_and_keeps_its_basis() {
    use robocal_robot::{ErrorParam, MomentPart};
    let robot = pmc6();
    let mut errors = compliant_pmc6().with_self_weight(&[0, 1, 2, 3, 4, 5], 6);
    // Joint 4's compliance negative: under no load it deflects by −0 before its terms.
    errors.values[3] = -0.2e-5;
    let loaded = [
        (5, 1.2e-4),
        (9, -3.1e-5),
        (30, 2.2e-5),
        (41, -7.0e-6),
        (75, 4.0e-6),
    ];
    for (i, v) in loaded {
        errors.self_weight[i].value = v;
    }
    // A term at −0 beside the +0 ones.
    errors.self_weight[60].value = -0.0;
    let sw = errors.self_weight.clone();
    assert!(sw.iter().filter(|t| t.joint == 3).all(|t| t.value == 0.0));
    let zero = (sw.iter()).position(|t| t.value == 0.0 && t.joint == 1 && t.body == 4);
    let zero = zero.expect("a term at zero");
    let params = [ErrorParam::SelfWeight(zero), ErrorParam::SelfWeight(5)];
    let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    let mut signs = 0;
    for k in 0..40 {
        let q: Vec<f64> = (0..6)
            .map(|j| ((k * 7 + j * 13) % 23) as f64 / 23.0 * 3.0 - 1.5)
            .collect();
        for load in [0.0, 8.0] {
            let phi = |t: &robocal_robot::SelfWeight| {
                let part = (MomentPart::ALL.iter()).position(|p| *p == t.part).unwrap();
                errors.torque_features(&robot, &q, load, t.joint)[4 * (t.body - t.joint) + part]
            };
            let torques = errors.load_torques(&robot, &q, load);
            let mut expected: Vec<f64> = (errors.values.iter().zip(&torques))
                .map(|(c, t)| c * t)
                .collect();
            let before = expected.clone();
            for t in &sw {
                expected[t.joint] += t.value * phi(t);
            }
            signs += (0..6)
                .filter(|&j| before[j].to_bits() != expected[j].to_bits() && before[j] == 0.0)
                .count();
            let deflection = errors.deflection(&robot, &q, load);
            assert_eq!(bits(&deflection), bits(&expected), "{q:?} {load}");
            let basis = errors.basis(&robot, &q, load, &params);
            let got: Vec<(usize, usize, u64)> = (basis.iter())
                .map(|&(k, j, v)| (k, j, v.to_bits()))
                .collect();
            let want = vec![
                (0, 1, phi(&sw[zero]).to_bits()),
                (1, sw[5].joint, phi(&sw[5]).to_bits()),
            ];
            assert_eq!(got, want);
        }
    }
    // The sign of a zero was decided by a term at zero (−0 turned +0) on some of the rows.
    assert!(signs > 0);
}

/// The bases of a model's waves at a command, computed once ([`JointErrors::wave_bases`]: each
/// harmonic's and each runout's `(sin k q', cos k q')` at the held angle, checked here against
/// the sines computed directly) and handed back: the same point and the same row terms to the
/// bit as the model computing them itself; another command's bases move the point (they are
/// read, not recomputed). The same waves with other coefficients share the bases; another
/// reach, order or wave does not. Row terms written into one buffer row after row
/// ([`JointErrors::write_row_terms`], as a fit's Jacobian writes them, the bases given or not)
/// are each row's alone, to the bit.
#[test]
fn wave_bases_handed_back_give_the_same_rows_to_the_bit() {
    use robocal_robot::{ErrorParam, Harmonic, RowTerms};
    let robot = pmc6();
    let mut e = compliant_pmc6()
        .with_harmonics(&[0, 1, 4], 2)
        .with_runouts(&[1, 2], 2)
        .with_link_weights(&[1, 2]);
    let mut next = 0.0f64;
    for h in e.waves_mut() {
        next += 1.0;
        h.sin = (0.01 * next).to_radians();
        h.cos = (-0.007 * next).to_radians();
    }
    // Joint 2's harmonics held beyond −60°..−20°.
    e.harmonics[2].reach = Some([(-60.0f64).to_radians(), (-20.0f64).to_radians()]);
    e.harmonics[3].reach = e.harmonics[2].reach;
    e.link_weights[1].value = 6.8;
    let params = e.params();
    let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    let other = [0.3, -0.4, 0.2, 0.0, 1.0, -0.5];
    let mut reused = RowTerms::default();
    for k in 0..30 {
        let q: Vec<f64> = (0..6)
            .map(|j| ((k * 7 + j * 13) % 23) as f64 / 23.0 * 3.0 - 1.5)
            .collect();
        let waves = e.wave_bases(&q);
        assert_eq!(waves.len(), e.harmonics.len() + e.runouts.len());
        let every = (e.harmonics.iter()).chain(e.runouts.iter().map(|r| &r.wave));
        for (h, &(s, c)) in every.zip(&waves) {
            let held = h
                .reach
                .map_or(q[h.joint], |[lo, hi]| q[h.joint].clamp(lo, hi));
            let angle = f64::from(h.order) * held;
            assert_eq!((s, c), (angle.sin(), angle.cos()), "{q:?}");
        }
        for load in [0.0, 12.0] {
            let p = e.point(&robot, &q, load);
            let given = e.point_on_waves(&robot, &q, load, &waves);
            assert_eq!(bits(p.as_slice()), bits(given.as_slice()), "{q:?} {load}");
            let moved = e.point_on_waves(&robot, &q, load, &e.wave_bases(&other));
            assert!((moved - p).norm() > 1e-4, "{q:?} {load}");
            let row = e.row_terms(&robot, &q, load, &params);
            let row_given = e.row_terms_on_waves(&robot, &q, load, &params, &waves);
            assert_eq!(bits(&row.deflected), bits(&row_given.deflected));
            let flat = |b: &[(usize, usize, f64)]| {
                (b.iter())
                    .map(|&(k, j, v)| (k, j, v.to_bits()))
                    .collect::<Vec<_>>()
            };
            assert_eq!(flat(&row.basis), flat(&row_given.basis));
            assert!(
                (row.basis.iter()).any(|&(k, _, v)| {
                    matches!(params[k], ErrorParam::HarmonicCos(_)) && v != 0.0
                })
            );
            let turn_bits = |t: &[(Vector3<f64>, Vector3<f64>)]| {
                (t.iter())
                    .flat_map(|(a, b)| bits(a.as_slice()).into_iter().chain(bits(b.as_slice())))
                    .collect::<Vec<_>>()
            };
            let basis_bits = |b: &[(usize, Vector3<f64>, Vector3<f64>)]| {
                (b.iter())
                    .map(|&(k, o, t)| (k, turn_bits(&[(o, t)])))
                    .collect::<Vec<_>>()
            };
            assert_eq!(turn_bits(&row.turns), turn_bits(&row_given.turns));
            assert_eq!(
                row.turn_basis.len(),
                2 * 2 * 2 * 2,
                "two joints, orders, axes, sin/cos"
            );
            assert_eq!(
                basis_bits(&row.turn_basis),
                basis_bits(&row_given.turn_basis)
            );
            // The buffer holds the row before this one (the other load, or the last command).
            let given = (k % 2 == 0).then_some(waves.as_slice());
            e.write_row_terms(&robot, &q, load, &params, given, &mut reused);
            assert_eq!(
                bits(&row.deflected),
                bits(&reused.deflected),
                "{q:?} {load}"
            );
            assert_eq!(flat(&row.basis), flat(&reused.basis), "{q:?} {load}");
            assert_eq!(turn_bits(&row.turns), turn_bits(&reused.turns));
            assert_eq!(basis_bits(&row.turn_basis), basis_bits(&reused.turn_basis));
        }
    }
    // Other coefficients: the same bases; another reach, order or wave: not.
    let mut scaled = e.clone();
    scaled.waves_mut().for_each(|h| h.sin *= 3.0);
    assert!(e.same_waves(&scaled) && scaled.same_waves(&e));
    let mut reach = e.clone();
    reach.runouts[1].wave.reach = Some([-1.0, 1.0]);
    assert!(!e.same_waves(&reach));
    let mut order = e.clone();
    order.harmonics[0].order = 3;
    assert!(!e.same_waves(&order));
    assert!(!e.same_waves(&e.clone().with_harmonics(&[5], 1)));
    let mut free = e.harmonics[3];
    assert!(!Harmonic::zero(1, 2).same_basis(&free));
    free.reach = None;
    assert!(Harmonic::zero(1, 2).same_basis(&free));
}

/// A harmonic's reach: inside it the joint error is the Fourier term of the joint angle itself,
/// beyond it the term's value at the nearer end (computed here from the coefficients); the
/// deflected angles and the coefficient Jacobian follow it; the file round trip keeps it; a
/// reach that is not two ordered finite angles is refused with its key.
#[test]
fn harmonic_reach_holds_the_term_beyond_the_readings() {
    use robocal_robot::{ErrorParam, HARMONIC_REACH, Harmonic, JointErrors};
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    let robot = Robot::load(root.join("configs/robots/pmc6va030.toml")).unwrap();
    // Readings of joint 2 from -60° to -20°, widened at each end.
    let [lo, hi] = Harmonic::reach_of((-60.0f64).to_radians(), (-20.0f64).to_radians());
    let margin = 40.0 * HARMONIC_REACH;
    assert!(
        (lo.to_degrees() - (-60.0 - margin)).abs() < 1e-12,
        "{}",
        lo.to_degrees()
    );
    assert!(
        (hi.to_degrees() - (-20.0 + margin)).abs() < 1e-12,
        "{}",
        hi.to_degrees()
    );
    let mut e = JointErrors::new(vec![0.0; 6], Vector3::new(0.0, 0.0, -9.8), Vector3::zeros())
        .with_harmonics(&[1], 2);
    for (h, (s, c)) in e
        .harmonics
        .iter_mut()
        .zip([(0.03f64, -0.02f64), (0.01, 0.015)])
    {
        h.sin = s.to_radians();
        h.cos = c.to_radians();
        h.reach = Some([lo, hi]);
    }
    let term = |order: f64, s: f64, c: f64, q: f64| {
        s.to_radians() * (order * q).sin() + c.to_radians() * (order * q).cos()
    };
    let expected = |q: f64| {
        let held = q.clamp(lo, hi);
        term(1.0, 0.03, -0.02, held) + term(2.0, 0.01, 0.015, held)
    };
    let (lo_d, hi_d) = (lo.to_degrees(), hi.to_degrees());
    for deg in [
        lo_d - 90.0,
        lo_d - 1.0,
        lo_d,
        -45.0,
        hi_d - 1.0,
        hi_d,
        hi_d + 35.0,
        hi_d + 120.0,
    ] {
        let mut q = vec![0.2, 0.0, 0.3, -0.1, 0.4, 0.0];
        q[1] = deg.to_radians();
        let d = e.deflected(&robot, &q, 0.0);
        let want = expected(q[1]);
        assert!(
            (d[1] - q[1] - want).abs() < 1e-15,
            "{deg}°: {} vs {want}",
            d[1] - q[1]
        );
        if !(lo_d..=hi_d).contains(&deg) {
            // Beyond the reach: the value at the nearer end.
            let end = if deg < lo_d { lo } else { hi };
            assert!((d[1] - q[1] - expected(end)).abs() < 1e-15, "{deg}°");
        }
        // The coefficient columns against central differences, inside and beyond the reach.
        let params = e.params();
        let (_, jac) = e.param_jacobian(&robot, &q, 3.0, &params);
        for (k, &p) in params.iter().enumerate() {
            if matches!(p, ErrorParam::Compliance(_)) {
                continue;
            }
            let (mut up, mut down) = (e.clone(), e.clone());
            up.set_param(p, e.param(p) + 1e-7);
            down.set_param(p, e.param(p) - 1e-7);
            let fd = (up.point(&robot, &q, 3.0) - down.point(&robot, &q, 3.0)) / 2e-7;
            assert!(
                (fd - jac.column(k)).norm() < 1e-4 * fd.norm().max(1.0),
                "{deg}° {p:?}"
            );
        }
    }
    // Without a reach the term is periodic everywhere.
    let mut free = e.clone();
    free.harmonics.iter_mut().for_each(|h| h.reach = None);
    let q = [0.0, 2.5, 0.0, 0.0, 0.0, 0.0];
    let d = free.deflected(&robot, &q, 0.0)[1] - 2.5;
    assert!((d - term(1.0, 0.03, -0.02, 2.5) - term(2.0, 0.01, 0.015, 2.5)).abs() < 1e-15);
    // File round trip, and bad reaches named by key.
    let text = e.to_toml_string();
    assert!(text.contains("reach = ["), "{text}");
    let back = JointErrors::from_toml_str(&text, "compliance.toml", 6).unwrap();
    for (a, b) in back.harmonics.iter().zip(&e.harmonics) {
        let (ra, rb) = (a.reach.unwrap(), b.reach.unwrap());
        assert!((ra[0] - rb[0]).abs() < 1e-14 && (ra[1] - rb[1]).abs() < 1e-14);
    }
    assert!(
        JointErrors::from_toml_str(&free.to_toml_string(), "c.toml", 6)
            .unwrap()
            .harmonics
            .iter()
            .all(|h| h.reach.is_none())
    );
    let written = format!("reach = [{:?}, {:?}]", lo.to_degrees(), hi.to_degrees());
    assert!(text.contains(&written), "{text}");
    for bad in ["reach = [10.0, -10.0]", "reach = [nan, 1.0]"] {
        let err = JointErrors::from_toml_str(&text.replacen(&written, bad, 1), "m/c.toml", 6)
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("m/c.toml") && err.contains("harmonic[1].reach"),
            "{err}"
        );
    }
}

/// `[tool.points]`: named points read, written back, looked up by name; bad ones name their key
/// (a point given twice is a TOML error naming its line).
#[test]
fn named_points_in_robot_files() {
    let base = std::fs::read_to_string(
        std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../../configs/robots/pmc6va030.toml"),
    )
    .unwrap();
    let text =
        format!("{base}\n[tool.points]\nsmr2 = [10.0, 0.0, 50.0]\nsmr3 = [0.0, 10.0, 50.0]\n");
    let robot = Robot::from_toml_str(&text, "r.toml").unwrap();
    assert_eq!(robot.points.len(), 2);
    assert_eq!(robot.target_index(""), Some(0));
    assert_eq!(robot.target_index("smr3"), Some(2));
    assert_eq!(robot.target_index("smr9"), None);
    assert_eq!(robot.target_point(1), Vector3::new(10.0, 0.0, 50.0));
    assert_eq!(robot.param_count(), 34 + 6);
    assert_eq!(robot.param_ids()[34].to_string(), "point1.x");
    let back = Robot::from_toml_str(&robot.to_toml_string(), "back.toml").unwrap();
    assert_eq!(back, robot);
    // One-point files write no [tool.points].
    assert!(!pmc6().to_toml_string().contains("points"));
    let bad = |extra: &str| {
        Robot::from_toml_str(&format!("{base}\n[tool.points]\n{extra}\n"), "bad.toml")
            .unwrap_err()
            .to_string()
    };
    let twice = bad("smr2 = [1.0, 2.0, 3.0]\nsmr2 = [1.0, 2.0, 4.0]");
    assert!(
        twice.contains("bad.toml: line") && twice.contains("duplicate"),
        "{twice}"
    );
    let short = bad("smr2 = [1.0, 2.0]");
    assert!(short.contains("expected 3 numbers"), "{short}");
    let inf = bad("smr2 = [1.0, 2.0, inf]");
    assert!(inf.contains("key `tool.points.smr2`"), "{inf}");
    let name = bad("\"smr 2\" = [1.0, 2.0, 3.0]");
    assert!(name.contains("key `tool.points.smr 2`"), "{name}");
}

/// Numbers of every magnitude a calibration gives, from a seeded generator: `count` values in
/// ±[1e-9, 1e3).
fn scattered(count: usize, seed: u64) -> Vec<f64> {
    let mut state = seed;
    (0..count)
        .map(|_| {
            // xorshift64*: a mantissa in [0, 1) and a decade from 1e-9 to 1e2.
            state ^= state >> 12;
            state ^= state << 25;
            state ^= state >> 27;
            let r = state.wrapping_mul(0x2545_F491_4F6C_DD1D);
            let unit = (r >> 11) as f64 / (1u64 << 53) as f64;
            let sign = if r & 1 == 0 { 1.0 } else { -1.0 };
            sign * (1.0 + 9.0 * unit) * 10f64.powi((r >> 3) as i32 % 12 - 9)
        })
        .collect()
}

/// Whether some double within 64 units in the last place of `write(v)` reads back to exactly
/// `v` (brute force, wider than the writer's own search).
fn reachable(v: f64, write: impl Fn(f64) -> f64, read: impl Fn(f64) -> f64) -> bool {
    let (mut below, mut above) = (write(v), write(v));
    for _ in 0..=64 {
        if read(below) == v || read(above) == v {
            return true;
        }
        below = below.next_down();
        above = above.next_up();
    }
    false
}

/// A saved table and joint-error file read back bit for bit wherever the file's units allow:
/// each conversion (radians to degrees, rad/N·m to deg/kN·m) rounds, and some doubles have no
/// number in degrees that reads back onto them — those (about one in ten) come back within one
/// unit in the last place; every other one exactly (written as computed, about one in twenty of
/// those came back a unit off).
#[test]
fn saved_tables_and_joint_errors_read_back_bit_for_bit() {
    let v = scattered(600, 2026);
    let rad = |x: f64| reachable(x, f64::to_degrees, f64::to_radians);
    let same = |back: f64, x: f64, exact: bool| {
        if exact {
            back == x
        } else {
            (back - x).abs() <= f64::EPSILON * x.abs()
        }
    };
    let mut robot = Robot::from_toml_str(
        "name = \"r\"\n[base]\nxyz = [0, 0, 0]\nrpy = [0, 0, 0]\n[tool]\nxyz = [0, 0, 50]\nrpy = [0, 0, 0]\n\
         [[joint]]\na = 0\nalpha = 0\nd = 0\ntheta = 0\n",
        "r.toml",
    )
    .unwrap();
    let mut unreachable = 0;
    for chunk in v.chunks(6) {
        robot.joints[0].alpha = chunk[0];
        robot.joints[0].theta = chunk[1];
        robot.base.rpy = Vector3::new(chunk[2], chunk[3], chunk[4]);
        let back = Robot::from_toml_str(&robot.to_toml_string(), "r.toml").unwrap();
        let pairs = [
            (back.joints[0].alpha, chunk[0]),
            (back.joints[0].theta, chunk[1]),
            (back.base.rpy.x, chunk[2]),
            (back.base.rpy.y, chunk[3]),
            (back.base.rpy.z, chunk[4]),
        ];
        for (b, x) in pairs {
            unreachable += usize::from(!rad(x));
            assert!(same(b, x, rad(x)), "{x:e} read back as {b:e}");
        }
    }
    // The file's units leave most doubles reachable; the test means something only then.
    assert!(unreachable < 100, "{unreachable} of 500 angles unreachable");
    let mut e = robocal_robot::JointErrors::new(Vec::new(), Vector3::z() * -9.8, Vector3::zeros());
    e.values = v[..6].iter().map(|c| c.abs() * 1e-6).collect();
    e.harmonics = (v.chunks(4).enumerate())
        .map(|(i, c)| robocal_robot::Harmonic {
            joint: i % 6,
            order: 1 + (i / 6) as u32,
            sin: c[0] * 1e-3,
            cos: c[1] * 1e-3,
            reach: Some([-c[2].abs(), c[3].abs()]),
        })
        .collect();
    let back = robocal_robot::JointErrors::from_toml_str(&e.to_toml_string(), "c.toml", 6).unwrap();
    let knm = |x: f64| {
        reachable(
            x,
            |c| c / robocal_robot::DEG_PER_KNM,
            |c| c * robocal_robot::DEG_PER_KNM,
        )
    };
    for (b, x) in back.values.iter().zip(&e.values) {
        assert!(same(*b, *x, knm(*x)), "{x:e} read back as {b:e}");
    }
    assert_eq!(back.harmonics.len(), e.harmonics.len());
    for (b, h) in back.harmonics.iter().zip(&e.harmonics) {
        let reach = h.reach.unwrap();
        let back_reach = b.reach.unwrap();
        for (b, x) in [
            (b.sin, h.sin),
            (b.cos, h.cos),
            (back_reach[0], reach[0]),
            (back_reach[1], reach[1]),
        ] {
            assert!(same(b, x, rad(x)), "{x:e} read back as {b:e}");
        }
    }
}

/// The rotation vector between the tool frames of two models (`up`, `down`) of `probe` at `q`
/// under `load`, over their parameters' step `2 h`.
fn rotation_difference(
    probe: &Robot,
    q: &[f64],
    load: f64,
    (up, down): (&robocal_robot::JointErrors, &robocal_robot::JointErrors),
    h: f64,
) -> Vector3<f64> {
    let d = up.rotation(probe, q, load) * down.rotation(probe, q, load).transpose();
    Vector3::new(
        d[(2, 1)] - d[(1, 2)],
        d[(0, 2)] - d[(2, 0)],
        d[(1, 0)] - d[(0, 1)],
    ) / (4.0 * h)
}
