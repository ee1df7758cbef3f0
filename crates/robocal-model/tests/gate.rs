//! The physics a CA-SOMM gate reads, against an independent computation: the work of gravity
//! (τ dq = F · dp, so a joint's torque per kg is g · ∂c/∂q) and finite differences of the point.

use robocal_model::{gate_physics_row, resolve_gate_physics};
use robocal_residual::{ClassifierSettings, GatePhysics, PHYSICS_PER_JOINT};
use robocal_robot::{JointErrors, Robot};

const ARM: &str = "name = \"arm\"\n[base]\nxyz = [100, -50, 20]\nrpy = [0, 0, 30]\n[tool]\nxyz = [20, 10, 120]\n\
    [[joint]]\na = 0\nalpha = 0\nd = 400\ntheta = 0\n\
    [[joint]]\na = 50\nalpha = -90\nd = 0\ntheta = -90\n\
    [[joint]]\na = 500\nalpha = 0\nd = 0\ntheta = 0\n\
    [[joint]]\na = 80\nalpha = -90\nd = 420\ntheta = 0\n";

#[test]
fn gate_physics_is_the_work_of_gravity_and_the_motion_of_the_point() {
    let robot = Robot::from_toml_str(ARM, "arm.toml").unwrap();
    let p = GatePhysics {
        gravity: [0.0, 0.0, -9.80665],
        payload_com: [60.0, -30.0, 90.0],
    };
    let q = [0.3, -0.7, 1.1, 0.4];
    let load = 7.5;
    let row = gate_physics_row(&robot, &p, &q, load);
    let n = robot.dof();
    assert_eq!(row.len(), PHYSICS_PER_JOINT * n);
    // The payload's centre of mass in the world: the point of the same robot with the payload
    // as its tool.
    let mut at_payload = robot.clone();
    at_payload.tool = p.payload_com.into();
    let g = robot.base_rotation() * nalgebra::Vector3::from(p.gravity);
    let h = 1e-6;
    for j in 0..n {
        let diff = |r: &Robot| {
            let (mut a, mut b) = (q.to_vec(), q.to_vec());
            a[j] += h;
            b[j] -= h;
            (r.point(&a) - r.point(&b)) / (2.0 * h)
        };
        let lever = g.dot(&diff(&at_payload)) * 1e-3;
        assert!(
            (row[j] - lever).abs() < 1e-6,
            "lever j{}: {} vs {lever}",
            j + 1,
            row[j]
        );
        assert!(
            (row[n + j] - lever * load).abs() < 1e-5,
            "torque j{}",
            j + 1
        );
        let motion = diff(&robot) * std::f64::consts::PI / 180.0;
        for axis in 0..3 {
            let got = row[(2 + axis) * n + j];
            assert!(
                (got - motion[axis]).abs() < 1e-6,
                "motion {axis} j{}: {got} vs {}",
                j + 1,
                motion[axis]
            );
        }
    }
}

#[test]
fn the_gate_takes_its_payload_and_gravity_from_settings_then_joint_errors_then_the_tool() {
    let robot = Robot::from_toml_str(ARM, "arm.toml").unwrap();
    let none = ClassifierSettings::default();
    let p = resolve_gate_physics(&none, &robot, None);
    assert_eq!(p.payload_com, [20.0, 10.0, 120.0]);
    assert_eq!(p.gravity, [0.0, 0.0, -9.80665]);
    let errors = JointErrors::new(
        vec![0.0; 4],
        [0.0, -9.8, 0.0].into(),
        [1.0, 2.0, 3.0].into(),
    );
    let p = resolve_gate_physics(&none, &robot, Some(&errors));
    assert_eq!(
        (p.payload_com, p.gravity),
        ([1.0, 2.0, 3.0], [0.0, -9.8, 0.0])
    );
    let given = ClassifierSettings {
        payload_com: Some([5.0, 6.0, 7.0]),
        gravity: Some([9.8, 0.0, 0.0]),
        ..ClassifierSettings::default()
    };
    let p = resolve_gate_physics(&given, &robot, Some(&errors));
    assert_eq!(
        (p.payload_com, p.gravity),
        ([5.0, 6.0, 7.0], [9.8, 0.0, 0.0])
    );
}
