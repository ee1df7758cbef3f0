//! `robocal export`: a URDF that reproduces the model's table, a JSON table, what neither
//! carries.

use std::path::Path;

use crate::common::{calibrate_with, robocal, s};

const DATA: &str = "datasets/pmc6va030/measurements.csv";

#[test]
fn a_calibrated_model_exports_to_urdf_and_json_and_names_what_they_leave_out() {
    let dir = tempfile::tempdir().unwrap();
    let model = dir.path().join("model");
    let o = calibrate_with(
        Path::new(DATA),
        &model,
        Path::new("configs/stages/compliance.toml"),
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let urdf = dir.path().join("out/robot.urdf");
    let o = robocal(&[
        "export",
        "--model",
        s(&model),
        "--format",
        "urdf",
        "--out",
        s(&urdf),
        "--data",
        DATA,
    ]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(
        err.contains("largest difference") && err.contains("e-"),
        "{err}"
    );
    assert!(
        err.contains("cannot carry joint compliances") && err.contains("the table alone leaves"),
        "{err}"
    );
    let text = std::fs::read_to_string(&urdf).unwrap();
    assert!(
        text.contains("<joint name=\"joint_6\" type=\"revolute\">"),
        "{text}"
    );
    let json = dir.path().join("table.json");
    let o = robocal(&[
        "export",
        "--model",
        s(&model),
        "--format",
        "json",
        "--out",
        s(&json),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let t: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    assert_eq!(t["joints"].as_array().unwrap().len(), 6);
    assert!(t["joints"][1]["std"]["a"].as_f64().unwrap() > 0.0);
    assert_eq!(t["not_carried"][0], "joint compliances under the payload");
    // A model directory that is not one: an error, nothing written.
    let none = dir.path().join("none.urdf");
    let o = robocal(&[
        "export",
        "--model",
        s(dir.path()),
        "--format",
        "urdf",
        "--out",
        s(&none),
    ]);
    assert!(!o.status.success() && !none.exists());
}
