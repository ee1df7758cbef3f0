//! `robocal plan`, and the twin measuring a planned pose file: plan → simulate → calibrate.

use std::path::Path;

use crate::common::{calibrate_with, robocal, s, write};

const ROBOT: &str = "configs/robots/pmc6va030.toml";
const TWIN: &str = "configs/twin/pmc6va030.toml";

#[test]
fn a_plan_is_measured_on_the_twin_and_calibrated() {
    let dir = tempfile::tempdir().unwrap();
    let config = write(
        dir.path(),
        "plan.toml",
        "seed = 3\npool = 300\ncheck = 40\nloads = [0.0, 10.0]\n\
         [workspace]\nmin = [-1500.0, -1500.0, -800.0]\nmax = [1500.0, 1500.0, 1500.0]\n",
    );
    let poses = dir.path().join("plan/poses.csv");
    let o = robocal(&[
        "plan",
        "--robot",
        ROBOT,
        "--count",
        "20,40",
        "--out",
        s(&poses),
        "--config",
        s(&config),
    ]);
    let out = String::from_utf8_lossy(&o.stdout);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(
        out.contains("| 20 |") && out.contains("| 40 |") && out.contains("j2.a"),
        "{out}"
    );
    let text = std::fs::read_to_string(&poses).unwrap();
    let mut lines = text.lines();
    assert_eq!(lines.next(), Some("pose,q1,q2,q3,q4,q5,q6,load"));
    assert_eq!(
        lines.count(),
        40 * 2,
        "the largest set, every configuration at both loads"
    );
    let plan: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("plan/plan.json")).unwrap())
            .unwrap();
    let p = &plan["plans"][1];
    assert_eq!(p["count"], 40);
    let (planned, random) = (
        p["planned"]["o1"].as_f64().unwrap(),
        p["random"]["o1"].as_f64().unwrap(),
    );
    assert!(planned > random, "O1 planned {planned} vs random {random}");
    assert!(p["predicted"][0].as_f64().unwrap() > 0.0);

    // The twin measures the planned rows; calibrate takes them as they come.
    let data = dir.path().join("measured");
    let o = robocal(&[
        "simulate",
        "--twin",
        TWIN,
        "--out",
        s(&data),
        "--poses",
        s(&poses),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let measured = std::fs::read_to_string(data.join("measurements.csv")).unwrap();
    assert_eq!(measured.lines().count(), 40 * 2 + 1);
    let model = dir.path().join("model");
    let o = calibrate_with(
        &data.join("measurements.csv"),
        &model,
        Path::new("configs/stages/kinematic-lm.toml"),
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}

#[test]
fn bad_plans_are_refused_naming_the_file_and_key() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("poses.csv");
    // `plan` with the bundled robot and `--out`, then `extra`: must fail; its stderr.
    let run = |extra: &[&str]| {
        let mut args = vec!["plan", "--robot", ROBOT, "--out", s(&out)];
        args.extend_from_slice(extra);
        let o = robocal(&args);
        assert!(!o.status.success());
        String::from_utf8_lossy(&o.stderr).to_string()
    };
    let empty = write(
        dir.path(),
        "empty.toml",
        "[workspace]\nmin = [0, 0, 0]\nmax = [0, 10, 10]\n",
    );
    let e = run(&["--count", "20", "--config", s(&empty)]);
    assert!(
        e.contains("empty.toml") && e.contains("workspace.min"),
        "{e}"
    );
    let e = run(&["--count", "2"]);
    assert!(e.contains("--count") && e.contains("parameters"), "{e}");
    let wrong = write(dir.path(), "cand.csv", "pose,q1,q2,q3,load\np1,0,0,0,0\n");
    let e = run(&["--count", "20", "--candidates", s(&wrong)]);
    assert!(e.contains("cand.csv"), "{e}");
    assert!(!out.exists(), "nothing written");
}
