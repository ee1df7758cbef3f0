//! The URDF export against the model's own forward kinematics (read back by `urdf-rs`), and the
//! JSON table against the model's values.

use std::path::Path;

use robocal_model::CalibratedModel;
use robocal_model::export::{PARITY_TOLERANCE_MM, json_table, urdf_parity, urdf_text};
use robocal_robot::Robot;

fn robot() -> Robot {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    let mut r = Robot::load(root.join("configs/robots/pmc6va030.toml")).unwrap();
    // A calibrated-looking table: every parameter moved, β on joint 3, a turned base.
    let x: Vec<f64> = (r.params().iter().enumerate())
        .map(|(i, v)| v + 1e-3 * ((i * 37 % 11) as f64 - 5.0))
        .collect();
    r = r.with_params(&x).unwrap();
    r.base.rpy = nalgebra::Vector3::new(0.01, -0.02, -1.7);
    r
}

#[test]
fn the_urdf_reproduces_the_table_and_a_changed_one_does_not() {
    let robot = robot();
    let text = urdf_text(&robot).unwrap();
    assert!(text.contains("<robot") && text.contains("joint_6") && text.contains("tool0"));
    let worst = urdf_parity(&robot, &text).unwrap();
    assert!(worst < PARITY_TOLERANCE_MM, "{worst} mm");
    // One origin moved by 0.1 mm (1e-4 m) is seen.
    let mut back = urdf_rs::read_from_string(&text).unwrap();
    back.joints[3].origin.xyz.0[1] += 1e-4;
    let moved = urdf_rs::write_to_string(&back).unwrap();
    let worst = urdf_parity(&robot, &moved).unwrap();
    assert!(worst > 0.05, "{worst} mm");
}

#[test]
fn the_json_table_holds_the_values_their_sigmas_and_what_it_leaves_out() {
    let robot = robot();
    let model = CalibratedModel::kinematic(robot.clone());
    let report = serde_json::json!({"kinematic": {"parameters": [
        {"name": "j2.a", "std": 0.004}, {"name": "base.rz", "std": 0.001}
    ]}});
    let t = json_table(&model, Some(&report));
    assert_eq!(t["joints"][1]["a"].as_f64().unwrap(), robot.joints[1].a);
    assert_eq!(t["joints"][1]["std"]["a"].as_f64().unwrap(), 0.004);
    assert!(t["joints"][1]["std"]["d"].is_null());
    let beta = t["joints"][2]["beta"].as_f64().unwrap();
    assert!((beta - robot.joints[2].beta.unwrap().to_degrees()).abs() < 1e-12);
    assert_eq!(t["base"]["std"][5].as_f64().unwrap(), 0.001);
    assert!(t["not_carried"].as_array().unwrap().is_empty());
    // Joint errors a table cannot carry are named: the backlash of the joints that have one, the
    // weights of the links identified.
    let mut errors = robocal_robot::JointErrors::new(
        vec![0.0; 6],
        nalgebra::Vector3::new(0.0, 0.0, -9.8),
        nalgebra::Vector3::zeros(),
    )
    .with_backlash(&[0, 3, 4])
    .with_link_weights(&[2, 3]);
    errors.backlash[1].value = 0.001;
    // Link 3's mass identified, link 4's held at zero.
    errors.link_weights[0].value = 12.0;
    let with_errors = CalibratedModel {
        joint_errors: Some(errors),
        ..model
    };
    let t = json_table(&with_errors, Some(&report));
    let said: Vec<&str> = (t["not_carried"].as_array().unwrap().iter())
        .map(|v| v.as_str().unwrap())
        .collect();
    assert_eq!(
        said,
        [
            "the weights of 1 link deflecting the joints",
            "the backlash of 1 joint"
        ]
    );
}

/// Named points travel as fixed frames of their own, each checked like the measured point; a
/// moved point is seen; the JSON table lists them.
#[test]
fn named_points_export_as_frames_of_their_own() {
    let mut robot = robot();
    robot.points = vec![
        ("smr2".into(), nalgebra::Vector3::new(80.0, 0.5, 60.0)),
        ("smr3".into(), nalgebra::Vector3::new(-40.0, 70.0, 61.0)),
    ];
    let text = urdf_text(&robot).unwrap();
    assert!(
        text.contains("point_smr2") && text.contains("point_smr3"),
        "{text}"
    );
    let worst = urdf_parity(&robot, &text).unwrap();
    assert!(worst < PARITY_TOLERANCE_MM, "{worst} mm");
    let mut back = urdf_rs::read_from_string(&text).unwrap();
    let j = back
        .joints
        .iter_mut()
        .find(|j| j.name == "point_smr3")
        .unwrap();
    j.origin.xyz.0[2] += 1e-4;
    let moved = urdf_rs::write_to_string(&back).unwrap();
    assert!(urdf_parity(&robot, &moved).unwrap() > 0.05);
    let table = json_table(&CalibratedModel::kinematic(robot), None);
    assert_eq!(table["points"]["smr3"]["xyz"][1], 70.0);
}

/// A 6-DoF probe's frame (`[tool] rpy`) turns `tool0`: the parity check sees its orientation
/// (a turned frame is detected), and the JSON table gives its angles.
#[test]
fn a_probe_frame_exports_as_tool0s_orientation() {
    let mut robot = robot();
    robot.tool_rpy = Some(nalgebra::Vector3::new(0.1, -0.2, 0.5));
    let text = urdf_text(&robot).unwrap();
    let worst = urdf_parity(&robot, &text).unwrap();
    assert!(worst < PARITY_TOLERANCE_MM, "{worst} mm");
    let mut back = urdf_rs::read_from_string(&text).unwrap();
    let j = back.joints.iter_mut().find(|j| j.name == "tool").unwrap();
    j.origin.rpy.0[0] += 1e-3;
    let turned = urdf_rs::write_to_string(&back).unwrap();
    assert!(urdf_parity(&robot, &turned).unwrap() > 0.5);
    let table = json_table(&CalibratedModel::kinematic(robot), None);
    let yaw = table["tool"]["rpy"][2].as_f64().unwrap();
    assert!((yaw - 0.5f64.to_degrees()).abs() < 1e-9, "{table}");
}

/// Every bundled arm (6-, 7- and 5-axis, β on parallel joints, heavy and small six-axis), its
/// table moved as a calibration moves it and its base tilted: the URDF reproduces it within
/// the tolerance.
#[test]
fn the_urdf_of_every_bundled_arm_reproduces_its_table() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../configs/robots");
    let mut arms = 0;
    for entry in std::fs::read_dir(&dir).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_none_or(|e| e != "toml") {
            continue;
        }
        let mut r = Robot::load(&path).unwrap();
        let x: Vec<f64> = (r.params().iter().enumerate())
            .map(|(i, v)| v + 1e-3 * ((i * 37 % 11) as f64 - 5.0))
            .collect();
        r = r.with_params(&x).unwrap();
        r.base.rpy = nalgebra::Vector3::new(0.2, -0.15, 2.9);
        let text = urdf_text(&r).unwrap();
        let worst = urdf_parity(&r, &text).unwrap();
        assert!(
            worst < PARITY_TOLERANCE_MM,
            "{}: {worst} mm",
            path.display()
        );
        arms += 1;
    }
    assert!(arms >= 5, "{arms} robot files");
}
