//! Several reflectors per pose: a twin that measures three, a robot file that names them,
//! calibrate, predict and evaluate by `target`, and the bad targets that write nothing.

use std::path::Path;

use crate::common::{bundled_twin, robocal, s, write};

/// The bundled twin with two more reflectors on its truth, 40 configurations at 0 and 20 kg.
fn twin_text() -> String {
    bundled_twin(
        40,
        "\n[truth.tool.points]\nsmr2 = [83.1, 1.2, 62.0]\nsmr3 = [-37.0, 71.5, 63.1]\n",
    )
}

fn robot_text(points: &str) -> String {
    std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("configs/robots/pmc6va030.toml"),
    )
    .unwrap()
        + points
}

#[test]
fn three_reflectors_are_simulated_calibrated_and_predicted_by_target() {
    let dir = tempfile::tempdir().unwrap();
    let twin = write(dir.path(), "twin.toml", &twin_text());
    let data = dir.path().join("data");
    let o = robocal(&["simulate", "--twin", s(&twin), "--out", s(&data)]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let measured = std::fs::read_to_string(data.join("measurements.csv")).unwrap();
    assert!(measured.starts_with("pose,target,q1"), "{measured}");
    assert_eq!(measured.lines().count(), 1 + 40 * 2 * 3);
    let robot = write(
        dir.path(),
        "robot.toml",
        &robot_text("\n[tool.points]\nsmr2 = [80.0, 0.0, 60.0]\nsmr3 = [-40.0, 70.0, 60.0]\n"),
    );
    let model = dir.path().join("model");
    let o = robocal(&[
        "calibrate",
        "--robot",
        s(&robot),
        "--data",
        s(&data.join("measurements.csv")),
        "--out",
        s(&model),
        "--config",
        "configs/stages/kinematic-lm.toml",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    // The identified table carries the points; every point's offset is in the report.
    let table = std::fs::read_to_string(model.join("kinematics.toml")).unwrap();
    assert!(
        table.contains("[tool.points]") && table.contains("smr3 = ["),
        "{table}"
    );
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(model.join("report.json")).unwrap()).unwrap();
    let names: Vec<&str> = report["kinematic"]["parameters"]
        .as_array()
        .unwrap()
        .iter()
        .filter_map(|p| p["name"].as_str())
        .collect();
    assert!(names.contains(&"point2.z"), "{names:?}");
    // Predict writes the target of each row; the points differ as the plate does.
    let pred = dir.path().join("pred.csv");
    let o = robocal(&[
        "predict",
        "--model",
        s(&model),
        "--data",
        s(&data.join("truth.csv")),
        "--out",
        s(&pred),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let text = std::fs::read_to_string(&pred).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    assert_eq!(lines[0], "pose,target,load,x,y,z");
    assert!(
        lines[1].starts_with("g") && lines[2].contains(",smr2,"),
        "{text}"
    );
    // Rigid LM on a twin with compliance, gears and backlash: well under a millimetre at every
    // reflector against the noise-free points.
    let per_pose = dir.path().join("errors.csv");
    let o = robocal(&[
        "evaluate",
        "--model",
        s(&model),
        "--data",
        s(&data.join("truth.csv")),
        "--json",
        "--per-pose",
        s(&per_pose),
    ]);
    let errors = std::fs::read_to_string(&per_pose).unwrap();
    assert!(
        errors.starts_with("pose,target,line,load,dx,dy,dz,error\n") && errors.contains(",smr3,"),
        "{errors}"
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let stats: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(stats["count"], 240);
    assert!(stats["mean"].as_f64().unwrap() < 1.0, "{stats}");

    compensation_puts_the_rows_point_on_the_target(&dir, &data, &model, &lines);
}

/// Compensation puts the row's target point on the target: smr2's predicted points as
/// targets, seeds half a degree off; the commands bring smr2 back onto them.
fn compensation_puts_the_rows_point_on_the_target(
    dir: &tempfile::TempDir,
    data: &Path,
    model: &Path,
    lines: &[&str],
) {
    let truth = std::fs::read_to_string(data.join("truth.csv")).unwrap();
    let rows: Vec<Vec<&str>> = (truth.lines().skip(1))
        .map(|l| l.split(',').collect())
        .filter(|f: &Vec<&str>| f[1] == "smr2")
        .take(5)
        .collect();
    let predicted: Vec<Vec<&str>> = (lines.iter().skip(1))
        .map(|l| l.split(',').collect())
        .filter(|f: &Vec<&str>| f[1] == "smr2")
        .take(5)
        .collect();
    let mut targets = "id,target,q1,q2,q3,q4,q5,q6,load,x,y,z\n".to_string();
    for (i, (r, p)) in rows.iter().zip(&predicted).enumerate() {
        let seed: Vec<String> = (r[2..8].iter())
            .map(|v| (v.parse::<f64>().unwrap() + 0.5).to_string())
            .collect();
        targets += &format!(
            "t{i},smr2,{},{},{},{},{}\n",
            seed.join(","),
            r[8],
            p[3],
            p[4],
            p[5]
        );
    }
    let targets_file = write(dir.path(), "targets.csv", &targets);
    let commands = dir.path().join("commands.csv");
    let o = robocal(&[
        "compensate",
        "--model",
        s(model),
        "--targets",
        s(&targets_file),
        "--out",
        s(&commands),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let mut check = "pose,target,q1,q2,q3,q4,q5,q6,load\n".to_string();
    for (line, r) in (std::fs::read_to_string(&commands).unwrap().lines().skip(1)).zip(&rows) {
        let f: Vec<&str> = line.split(',').collect();
        check += &format!("{},smr2,{},{}\n", f[0], f[1..].join(","), r[8]);
    }
    let check_file = write(dir.path(), "check.csv", &check);
    let reached = dir.path().join("reached.csv");
    let o = robocal(&[
        "predict",
        "--model",
        s(model),
        "--data",
        s(&check_file),
        "--out",
        s(&reached),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let reached = std::fs::read_to_string(&reached).unwrap();
    for (line, p) in reached.lines().skip(1).zip(&predicted) {
        let f: Vec<f64> = line
            .split(',')
            .skip(3)
            .map(|v| v.parse().unwrap())
            .collect();
        let want: Vec<f64> = p[3..6].iter().map(|v| v.parse().unwrap()).collect();
        let d =
            ((f[0] - want[0]).powi(2) + (f[1] - want[1]).powi(2) + (f[2] - want[2]).powi(2)).sqrt();
        assert!(d < 2e-3, "{line}: {d} mm from the target");
    }
}

#[test]
fn a_target_naming_no_point_is_refused_and_nothing_is_written() {
    let dir = tempfile::tempdir().unwrap();
    let header = "pose,target,q1,q2,q3,q4,q5,q6,load,x,y,z\n";
    let row = |target: &str| format!("p1,{target},10,-60,-20,5,60,7,0,-1000.5,1500.25,900.125\n");
    let data = write(
        dir.path(),
        "m.csv",
        &format!("{header}{}{}", row(""), row("smr9")),
    );
    let robot = write(
        dir.path(),
        "robot.toml",
        &robot_text("\n[tool.points]\nsmr2 = [80.0, 0.0, 60.0]\n"),
    );
    let out = dir.path().join("model");
    let o = robocal(&[
        "calibrate",
        "--robot",
        s(&robot),
        "--data",
        s(&data),
        "--out",
        s(&out),
    ]);
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains(
            "m.csv: line 3, column `target`: no point `smr9`; the robot file's points are smr2"
        ),
        "{err}"
    );
    assert!(!out.exists());
    // A plain robot file: no point may be named.
    let pred = dir.path().join("pred.csv");
    let o = robocal(&[
        "predict",
        "--robot",
        "configs/robots/pmc6va030.toml",
        "--data",
        s(&data),
        "--out",
        s(&pred),
    ]);
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("the robot file names no points"), "{err}");
    assert!(!pred.exists());
}
