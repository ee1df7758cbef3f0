//! A 6-DoF probe: a twin whose truth declares the probe's frame (`[tool] rpy`) writes `rx, ry,
//! rz`; calibrate identifies the frame with the arm, predict writes the orientation, evaluate
//! reports it; orientation columns partly present, partly filled or out of range write nothing.

use std::path::Path;

use crate::common::{bundled_twin, robocal, s, write};

/// The bundled twin with a probe (frame turned about 30° on the flange, off the drawing by a
/// few tenths of a degree), 40 configurations at 0 and 20 kg. Backlash is no joint error robocal
/// models: off, so that every effect the twin holds is in the model family.
fn twin_text() -> String {
    bundled_twin(40, "rpy = [0.4, -0.3, 30.2]\n").replace(
        "[[backlash]]\nenabled = true",
        "[[backlash]]\nenabled = false",
    )
}

fn robot_text(tool_rpy: &str) -> String {
    std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("configs/robots/pmc6va030.toml"),
    )
    .unwrap()
    .replace("[tool]\n", &format!("[tool]\n{tool_rpy}"))
}

/// `evaluate --json` of a model on a file: (position mean mm, orientation mean deg).
fn evaluate(model: &Path, data: &Path) -> (f64, Option<f64>) {
    let o = robocal(&["evaluate", "--model", s(model), "--data", s(data), "--json"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    (
        v["mean"].as_f64().unwrap(),
        v["orientation_deg"]["mean"].as_f64(),
    )
}

/// Drops the orientation columns (the last three) of a measurement file.
fn positions_only(text: &str) -> String {
    text.lines()
        .map(|l| {
            let f: Vec<&str> = l.split(',').collect();
            f[..f.len() - 3].join(",") + "\n"
        })
        .collect()
}

#[test]
fn a_6dof_probe_is_simulated_calibrated_predicted_and_evaluated() {
    let dir = tempfile::tempdir().unwrap();
    let twin = write(dir.path(), "twin.toml", &twin_text());
    let data = dir.path().join("data");
    let o = robocal(&["simulate", "--twin", s(&twin), "--out", s(&data)]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let measured = std::fs::read_to_string(data.join("measurements.csv")).unwrap();
    assert!(
        measured
            .lines()
            .next()
            .unwrap()
            .ends_with(",load,x,y,z,rx,ry,rz"),
        "{measured}"
    );
    // Train on the first 30 configurations, hold the last 10 out (noise-free truth).
    let (train, test) = (dir.path().join("train.csv"), dir.path().join("test.csv"));
    let truth = std::fs::read_to_string(data.join("truth.csv")).unwrap();
    std::fs::write(&train, crate::common::select_rows(&measured, |c, _| c < 30)).unwrap();
    std::fs::write(&test, crate::common::select_rows(&truth, |c, _| c >= 30)).unwrap();
    let robot = write(
        dir.path(),
        "robot.toml",
        &robot_text("rpy = [0.0, 0.0, 30.0]\n"),
    );
    let calibrate = |data: &Path, model: &Path| {
        let o = robocal(&[
            "calibrate",
            "--robot",
            s(&robot),
            "--data",
            s(data),
            "--out",
            s(model),
        ]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        String::from_utf8_lossy(&o.stderr).to_string()
    };
    let model = dir.path().join("model");
    let said = calibrate(&train, &model);
    assert!(said.contains("orientation"), "{said}");
    let table = std::fs::read_to_string(model.join("kinematics.toml")).unwrap();
    assert!(
        table.contains("[tool]") && table.contains("rpy = ["),
        "{table}"
    );
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(model.join("report.json")).unwrap()).unwrap();
    let orientation = &report["kinematic"]["orientation"];
    assert_eq!(orientation["rows"].as_u64(), Some(60), "{orientation}");
    // --angle-weight weighs the orientations, over a stage config too.
    let weighted = dir.path().join("weighted");
    let o = robocal(&[
        "calibrate",
        "--robot",
        s(&robot),
        "--data",
        s(&train),
        "--out",
        s(&weighted),
        "--config",
        "configs/stages/kinematic-lm.toml",
        "--angle-weight",
        "0.5",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(weighted.join("report.json")).unwrap())
            .unwrap();
    let w = report["kinematic"]["orientation"]["angle_weight"].as_f64();
    assert!(w.is_some_and(|w| (w - 0.5).abs() < 1e-12), "{w:?}");
    assert_eq!(
        orientation["angle_weight"]
            .as_f64()
            .map(|w| (w * 1e9).round()),
        Some(2e9)
    );
    // Held out: the orientation within twice the probe's noise (0.01° per axis) of the truth,
    // the positions no worse than a calibration from the positions alone.
    let (position, angle) = evaluate(&model, &test);
    let angle = angle.expect("orientation statistics");
    assert!(angle < 2.0 * 0.01, "held-out orientation {angle} deg");
    let three = dir.path().join("train3.csv");
    std::fs::write(
        &three,
        positions_only(&std::fs::read_to_string(&train).unwrap()),
    )
    .unwrap();
    let model3 = dir.path().join("model3");
    calibrate(&three, &model3);
    let (position3, none) = evaluate(&model3, &test);
    assert!(none.is_some(), "the test file has orientations");
    eprintln!("held out: {position:.4} mm, {angle:.5} deg; positions alone {position3:.4} mm");
    assert!(
        position <= position3 * 1.05,
        "held-out position {position} mm with the probe's angles, {position3} without"
    );
    per_pose_errors_hold_the_angle(&dir, &model, &test, angle);
    the_report_states_the_orientation(&dir, &model, &test, angle);
    predict_writes_the_orientation(&dir, &model, &test);
}

/// Per row: the angle between measured and predicted tool frames beside the distance.
fn per_pose_errors_hold_the_angle(dir: &tempfile::TempDir, model: &Path, test: &Path, angle: f64) {
    let per_pose = dir.path().join("errors.csv");
    let o = robocal(&[
        "evaluate",
        "--model",
        s(model),
        "--data",
        s(test),
        "--per-pose",
        s(&per_pose),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let said = String::from_utf8_lossy(&o.stdout);
    assert!(
        said.contains("orientation") && said.contains(" deg"),
        "{said}"
    );
    let errors = std::fs::read_to_string(&per_pose).unwrap();
    assert!(
        errors.starts_with("pose,line,load,dx,dy,dz,error,angle_deg\n"),
        "{errors}"
    );
    let mean_angle = (errors.lines().skip(1))
        .map(|l| l.rsplit(',').next().unwrap().parse::<f64>().unwrap())
        .sum::<f64>()
        / 20.0;
    assert!((mean_angle - angle).abs() < 1e-5, "{mean_angle} vs {angle}");
}

/// The report states the orientation error beside the position error.
fn the_report_states_the_orientation(
    dir: &tempfile::TempDir,
    model: &Path,
    test: &Path,
    angle: f64,
) {
    let pictures = dir.path().join("report");
    let o = robocal(&[
        "report",
        "--model",
        s(model),
        "--data",
        s(test),
        "--out",
        s(&pictures),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let stats: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(pictures.join("statistics.json")).unwrap())
            .unwrap();
    let after = stats["orientation"]["after"]["mean"].as_f64().unwrap();
    assert!((after - angle).abs() < 1e-9, "{after} vs {angle}");
    assert!(stats["orientation"]["before"]["mean"].as_f64().unwrap() > after);
    let md = std::fs::read_to_string(pictures.join("report.md")).unwrap();
    assert!(md.contains("Orientation error (deg)"), "{md}");
}

/// Predict writes the tool frame's orientation for a file that has the columns.
fn predict_writes_the_orientation(dir: &tempfile::TempDir, model: &Path, test: &Path) {
    let pred = dir.path().join("pred.csv");
    let o = robocal(&[
        "predict",
        "--model",
        s(model),
        "--data",
        s(test),
        "--out",
        s(&pred),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let text = std::fs::read_to_string(&pred).unwrap();
    assert!(text.starts_with("pose,load,x,y,z,rx,ry,rz\n"), "{text}");
    // The last three fields of a row's line: rx, ry, rz.
    let angles = |line: &str| -> Vec<f64> {
        let f: Vec<&str> = line.split(',').collect();
        f[f.len() - 3..]
            .iter()
            .map(|v| v.parse().unwrap())
            .collect()
    };
    let truth_text = std::fs::read_to_string(test).unwrap();
    let want = angles(truth_text.lines().nth(1).unwrap());
    let got = angles(text.lines().nth(1).unwrap());
    for (g, w) in got.iter().zip(&want) {
        assert!((g - w).abs() < 0.05, "predicted {got:?}, truth {want:?}");
    }
}

#[test]
fn orientation_columns_partly_given_or_out_of_range_write_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let row = "p1,10,-60,-20,5,60,7,0,-1000.5,1500.25,900.125";
    let cases = [
        (
            format!("pose,q1,q2,q3,q4,q5,q6,load,x,y,z,rx,ry\n{row},1,2\n"),
            "line 1: orientation column `rx` without `rz`",
        ),
        (
            format!("pose,q1,q2,q3,q4,q5,q6,load,x,y,z,rx,ry,rz\n{row},1,2,3\n{row},1,,3\n"),
            "line 3, column `ry`: empty while the row's other orientation columns are given",
        ),
        (
            format!("pose,q1,q2,q3,q4,q5,q6,load,x,y,z,rx,ry,rz\n{row},1,2,3\n{row},1,95,3\n"),
            "line 3, column `ry`: 95 deg is out of range (pitch within ±90)",
        ),
        (
            format!("pose,q1,q2,q3,q4,q5,q6,load,x,y,z,rx,ry,rz\n{row},400,2,3\n"),
            "line 2, column `rx`: 400 deg is out of range (within ±360)",
        ),
        (
            format!("pose,q1,q2,q3,q4,q5,q6,load,x,y,z,rx,ry,rz\n{row},1,2,abc\n"),
            "line 2, column `rz`: `abc` is not a number",
        ),
    ];
    for (k, (text, want)) in cases.iter().enumerate() {
        let data = write(dir.path(), &format!("m{k}.csv"), text);
        let out = dir.path().join(format!("model{k}"));
        let o = robocal(&[
            "calibrate",
            "--robot",
            "configs/robots/pmc6va030.toml",
            "--data",
            s(&data),
            "--out",
            s(&out),
        ]);
        assert!(!o.status.success());
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(
            err.contains(&format!("m{k}.csv: {want}")),
            "case {k}: {err}"
        );
        assert!(!out.exists());
        let o = robocal(&[
            "evaluate",
            "--robot",
            "configs/robots/pmc6va030.toml",
            "--data",
            s(&data),
        ]);
        assert!(!o.status.success(), "evaluate, case {k}");
    }
    let out = dir.path().join("model");
    let o = robocal(&[
        "calibrate",
        "--robot",
        "configs/robots/pmc6va030.toml",
        "--data",
        "datasets/pmc6va030/measurements.csv",
        "--out",
        s(&out),
        "--angle-weight=-1",
    ]);
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains(
            "`--angle-weight` (or `angle_weight=` in Python): -1 is not a positive number"
        ),
        "{err}"
    );
    assert!(!out.exists());
}
