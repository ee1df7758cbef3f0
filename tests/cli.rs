//! End-to-end tests of the `robocal` binary on real files.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use robocal_robot::Robot;

const ROBOT: &str = "configs/robots/pmc6va030.toml";

fn robocal(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_robocal"))
        .args(args)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .expect("the binary runs")
}

fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, text).unwrap();
    path
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// Rows written by hand, positions from the nominal table plus known offsets.
fn hand_file(dir: &Path, offsets: &[f64]) -> PathBuf {
    let robot = Robot::load(Path::new(env!("CARGO_MANIFEST_DIR")).join(ROBOT)).unwrap();
    let configs = [
        [0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
        [12.5, -30.0, 45.25, 0.0, 60.0, -12.0],
        [-40.0, 20.0, -10.0, 90.0, -45.0, 30.0],
    ];
    let mut text = String::from("pose,q1,q2,q3,q4,q5,q6,load,x,y,z\n");
    for (i, (q, off)) in configs.iter().zip(offsets).enumerate() {
        let rad: Vec<f64> = q.iter().map(|d: &f64| d.to_radians()).collect();
        let p = robot.point(&rad);
        text += &format!(
            "p{i},{},{},{},{},{},{},{},{},{},{}\n",
            q[0],
            q[1],
            q[2],
            q[3],
            q[4],
            q[5],
            i * 5,
            p.x + off,
            p.y,
            p.z
        );
    }
    write(dir, "hand.csv", &text)
}

#[test]
fn predict_writes_every_row_in_order_with_six_decimals() {
    let dir = tempfile::tempdir().unwrap();
    let data = hand_file(dir.path(), &[0.0, 0.0, 0.0]);
    let out = dir.path().join("pred.csv");
    let o = robocal(&[
        "predict",
        "--robot",
        ROBOT,
        "--data",
        s(&data),
        "--out",
        s(&out),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let text = std::fs::read_to_string(&out).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    assert_eq!(lines[0], "pose,load,x,y,z");
    assert_eq!(lines.len(), 4);
    // With the base at identity, the zero configuration is worked out by hand in the robot
    // crate's tests: the reflector at (1210, 0, -463.8).
    let local = dir.path().join("local.toml");
    let table = std::fs::read_to_string(ROBOT).unwrap();
    let table = table.replace("xyz = [-800.0, 2500.0, -400.0]", "xyz = [0.0, 0.0, 0.0]");
    std::fs::write(
        &local,
        table.replace("rpy = [0.0, 0.0, -95.0]", "rpy = [0.0, 0.0, 0.0]"),
    )
    .unwrap();
    let zero = dir.path().join("zero.csv");
    let o = robocal(&[
        "predict",
        "--robot",
        s(&local),
        "--data",
        s(&data),
        "--out",
        s(&zero),
    ]);
    assert!(o.status.success());
    let first = std::fs::read_to_string(&zero).unwrap();
    assert_eq!(
        first.lines().nth(1),
        Some("p0,0,1210.000000,0.000000,-463.800000")
    );
    assert!(lines[3].starts_with("p2,10,"));
    let measured = std::fs::read_to_string(&data).unwrap();
    for (pred, meas) in lines[1..].iter().zip(measured.lines().skip(1)) {
        let p: Vec<f64> = pred
            .split(',')
            .skip(2)
            .map(|v| v.parse().unwrap())
            .collect();
        let m: Vec<f64> = meas
            .split(',')
            .skip(8)
            .map(|v| v.parse().unwrap())
            .collect();
        for (a, b) in p.iter().zip(&m) {
            assert!((a - b).abs() < 1e-6, "{pred} vs {meas}");
        }
        let decimals = pred
            .rsplit(',')
            .next()
            .unwrap()
            .split('.')
            .nth(1)
            .unwrap()
            .len();
        assert_eq!(decimals, 6);
    }
}

#[test]
fn evaluate_reports_known_errors() {
    let dir = tempfile::tempdir().unwrap();
    let data = hand_file(dir.path(), &[1.0, 2.0, 3.0]);
    let o = robocal(&["evaluate", "--robot", ROBOT, "--data", s(&data), "--json"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(v["count"], 3);
    let close = |key: &str, want: f64| {
        let got = v[key].as_f64().unwrap();
        assert!((got - want).abs() < 1e-6, "{key}: {got} vs {want}");
    };
    close("mean", 2.0);
    close("std", 1.0);
    close("rms", (14.0f64 / 3.0).sqrt());
    close("max", 3.0);
    let o = robocal(&["evaluate", "--robot", ROBOT, "--data", s(&data)]);
    let text = String::from_utf8(o.stdout).unwrap();
    assert!(
        text.contains("count 3") && text.contains("mean  2.000000 mm"),
        "{text}"
    );
}

#[test]
fn a_model_directory_predicts_like_its_table() {
    let dir = tempfile::tempdir().unwrap();
    let model = dir.path().join("model");
    std::fs::create_dir(&model).unwrap();
    std::fs::copy(ROBOT, model.join("kinematics.toml")).unwrap();
    let data = hand_file(dir.path(), &[0.0, 0.0, 0.0]);
    let a = dir.path().join("a.csv");
    let b = dir.path().join("b.csv");
    assert!(
        robocal(&[
            "predict",
            "--robot",
            ROBOT,
            "--data",
            s(&data),
            "--out",
            s(&a)
        ])
        .status
        .success()
    );
    assert!(
        robocal(&[
            "predict",
            "--model",
            s(&model),
            "--data",
            s(&data),
            "--out",
            s(&b)
        ])
        .status
        .success()
    );
    assert_eq!(std::fs::read(&a).unwrap(), std::fs::read(&b).unwrap());
    let empty = dir.path().join("empty-model");
    std::fs::create_dir(&empty).unwrap();
    let o = robocal(&["evaluate", "--model", s(&empty), "--data", s(&data)]);
    assert_eq!(o.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&o.stderr).contains("kinematics.toml"));
}

#[test]
fn bad_input_fails_cleanly_and_leaves_outputs_alone() {
    let dir = tempfile::tempdir().unwrap();
    let out = write(dir.path(), "pred.csv", "previous result\n");
    let cases = [
        (
            "text.csv",
            "pose,q1,q2,q3,q4,q5,q6,load,x,y,z\np,0,0,0,0,0,0,0,1,2,3\np,0,0,0,0,0,0,zero,1,2,3\n",
            "line 3, column `load`",
        ),
        (
            "joints.csv",
            "pose,q1,q2,q3,load\np,0,0,0,0\n",
            "robot has 6 joints",
        ),
        ("empty.csv", "", "empty"),
    ];
    for (name, text, needle) in cases {
        let data = write(dir.path(), name, text);
        for args in [
            vec![
                "predict",
                "--robot",
                ROBOT,
                "--data",
                s(&data),
                "--out",
                s(&out),
            ],
            vec!["evaluate", "--robot", ROBOT, "--data", s(&data)],
        ] {
            let o = robocal(&args);
            let stderr = String::from_utf8_lossy(&o.stderr);
            assert_eq!(o.status.code(), Some(1), "{name}: {stderr}");
            assert!(
                stderr.contains(name) && stderr.contains(needle),
                "{name}: {stderr}"
            );
            assert!(!stderr.contains("panicked"));
        }
        assert_eq!(std::fs::read_to_string(&out).unwrap(), "previous result\n");
    }
    let robot = write(dir.path(), "robot.toml", "name = \"r\"\n[[joint]]\na = 0\n");
    let data = write(dir.path(), "ok.csv", "pose,q1,load\np,0,0\n");
    let o = robocal(&[
        "predict",
        "--robot",
        s(&robot),
        "--data",
        s(&data),
        "--out",
        s(&out),
    ]);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1));
    assert!(
        stderr.contains("robot.toml") && stderr.contains("line"),
        "{stderr}"
    );
    let o = robocal(&["predict", "--data", s(&data), "--out", s(&out)]);
    assert_eq!(o.status.code(), Some(2), "clap reports a usage error");
}
