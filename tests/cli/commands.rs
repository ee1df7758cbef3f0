//! End-to-end tests of the `robocal` binary on real files.

use std::path::{Path, PathBuf};

use crate::common::{calibrate_with, report, robocal, s, select_rows, twin_rows, write};

use robocal_robot::Robot;

const ROBOT: &str = "configs/robots/pmc6va030.toml";

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
    // A missing file is named, and the operating system's reason is said once.
    let missing = dir.path().join("missing.csv");
    for args in [
        vec!["evaluate", "--robot", ROBOT, "--data", s(&missing)],
        vec!["run", s(&missing)],
    ] {
        let o = robocal(&args);
        let stderr = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(1), "{stderr}");
        assert!(stderr.contains("missing.csv"), "{stderr}");
        assert_eq!(stderr.matches("os error").count(), 1, "{stderr}");
    }
}

/// Rows of the bundled twin data: small and fast to calibrate.
fn twin_subset(dir: &Path, keep: impl Fn(usize, f64) -> bool) -> PathBuf {
    let out = select_rows(&twin_rows(), keep);
    write(dir, &format!("subset-{}.csv", out.len()), &out)
}

#[test]
fn calibrate_writes_a_model_that_predicts_like_its_kinematics_file() {
    let dir = tempfile::tempdir().unwrap();
    let train = twin_subset(dir.path(), |pose, load| {
        pose % 3 != 2 && (load == 0.0 || load == 20.0)
    });
    let test = twin_subset(dir.path(), |pose, load| pose % 3 == 2 && load == 0.0);
    let model = dir.path().join("model");
    let o = robocal(&[
        "calibrate",
        "--robot",
        ROBOT,
        "--data",
        s(&train),
        "--validate",
        s(&test),
        "--out",
        s(&model),
        "--config",
        "configs/stages/kinematic-lm.toml",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let report: serde_json::Value =
        serde_json::from_slice(&std::fs::read(model.join("report.json")).unwrap()).unwrap();
    let k = &report["kinematic"];
    assert_eq!(k["solver"], "lm");
    assert_eq!(k["points"], 112);
    assert!(k["iterations"].as_u64().unwrap() > 0);
    assert!(k["termination"].as_str().unwrap().contains("converged"));
    let before = k["before"]["mean"].as_f64().unwrap();
    let after = k["after"]["mean"].as_f64().unwrap();
    assert!(
        before > 2.0 && after < 0.6 && after < before / 5.0,
        "{before} → {after}"
    );
    let validated = report["validation"]["after"]["mean"].as_f64().unwrap();
    assert!(validated < 0.6, "held-out error {validated}");
    assert!(k["condition_number"].as_f64().unwrap().is_finite());
    let params = k["parameters"].as_array().unwrap();
    assert_eq!(params.len(), 34);
    let beta = params.iter().find(|p| p["name"] == "j3.beta").unwrap();
    assert!(beta["std"].as_f64().unwrap() > 0.0 && beta["unit"] == "deg");
    let fixed: Vec<&str> = k["fixed"]
        .as_array()
        .unwrap()
        .iter()
        .map(|f| f["name"].as_str().unwrap())
        .collect();
    assert!(
        fixed.contains(&"j1.theta") && fixed.contains(&"j6.d"),
        "{fixed:?}"
    );
    assert_eq!(report["model_format"], 1);

    // kinematics.toml is a robot file: it predicts exactly as the model directory does.
    let a = dir.path().join("a.csv");
    let b = dir.path().join("b.csv");
    let kin = model.join("kinematics.toml");
    assert!(
        robocal(&[
            "predict",
            "--robot",
            s(&kin),
            "--data",
            s(&test),
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
            s(&test),
            "--out",
            s(&b)
        ])
        .status
        .success()
    );
    assert_eq!(std::fs::read(&a).unwrap(), std::fs::read(&b).unwrap());
    let o = robocal(&[
        "evaluate",
        "--model",
        s(&model),
        "--data",
        s(&test),
        "--json",
    ]);
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert!((v["mean"].as_f64().unwrap() - validated).abs() < 1e-9);

    // BFGS through a stage config.
    let bfgs = dir.path().join("bfgs");
    let o = robocal(&[
        "calibrate",
        "--robot",
        ROBOT,
        "--data",
        s(&train),
        "--out",
        s(&bfgs),
        "--config",
        "configs/stages/kinematic-bfgs.toml",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let report: serde_json::Value =
        serde_json::from_slice(&std::fs::read(bfgs.join("report.json")).unwrap()).unwrap();
    assert_eq!(report["kinematic"]["solver"], "bfgs");
}

#[test]
fn calibrate_failures_leave_the_old_model_alone() {
    let dir = tempfile::tempdir().unwrap();
    let train = twin_subset(dir.path(), |pose, load| pose < 30 && load == 0.0);
    let model = dir.path().join("model");
    assert!(
        robocal(&[
            "calibrate",
            "--robot",
            ROBOT,
            "--data",
            s(&train),
            "--out",
            s(&model)
        ])
        .status
        .success()
    );
    let before = std::fs::read(model.join("report.json")).unwrap();
    let bad_cfg = write(
        dir.path(),
        "stage.toml",
        "[kinematic]\nsolver = \"newton\"\n",
    );
    let unknown = write(
        dir.path(),
        "unknown.toml",
        "[kinematic]\nsolver = \"lm\"\nspeed = 3\n",
    );
    let bad_data = write(
        dir.path(),
        "bad.csv",
        "pose,q1,q2,q3,q4,q5,q6,load,x,y,z\np,0,0,0,0,0,0,0,1,2,nan\n",
    );
    for (args, needle) in [
        (
            vec!["--data", s(&train), "--config", s(&bad_cfg)],
            "kinematic.solver",
        ),
        (vec!["--data", s(&train), "--config", s(&unknown)], "speed"),
        (vec!["--data", s(&bad_data)], "line 2, column `z`"),
    ] {
        let mut all = vec!["calibrate", "--robot", ROBOT, "--out", s(&model)];
        all.extend(args);
        let o = robocal(&all);
        let stderr = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(1), "{stderr}");
        assert!(stderr.contains(needle), "{stderr}");
        assert!(!stderr.contains("panicked"));
        assert_eq!(std::fs::read(model.join("report.json")).unwrap(), before);
    }
    // A model directory from another format version, or without its report, is refused.
    let report = std::fs::read_to_string(model.join("report.json")).unwrap();
    std::fs::write(
        model.join("report.json"),
        report.replace("\"model_format\": 1", "\"model_format\": 99"),
    )
    .unwrap();
    let o = robocal(&["evaluate", "--model", s(&model), "--data", s(&train)]);
    assert_eq!(o.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&o.stderr).contains("model_format"));
    std::fs::remove_file(model.join("report.json")).unwrap();
    let o = robocal(&["evaluate", "--model", s(&model), "--data", s(&train)]);
    assert_eq!(o.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&o.stderr).contains("report.json"));
}

/// A CA-SOMM stage with three 8-unit networks of 3 epochs (Y's activation `y`) and the given
/// `[residual.classifier]` lines.
fn ca_somm_stage(y: &str, classifier: &str) -> String {
    let net = |axis: &str, act: &str| {
        format!(
            "[residual.{axis}]\nhidden = [8]\nactivation = \"{act}\"\nlearning_rate = 1e-2\nmax_epochs = 3\n"
        )
    };
    format!(
        "[residual]\nmodel = \"ca-somm\"\nseed = 7\n{}{}{}[residual.classifier]\n{classifier}",
        net("x", "tanh"),
        net("y", y),
        net("z", "tanh")
    )
}

#[test]
fn robocals_ca_somm_reads_physics_reports_its_gate_and_says_whether_two_classes_paid() {
    let dir = tempfile::tempdir().unwrap();
    let train = twin_subset(dir.path(), |pose, load| pose < 60 && load <= 8.0);
    let stage = write(
        dir.path(),
        "stage.toml",
        &ca_somm_stage("tanh", "payload_com = [100.0, 0.0, 60.0]\n"),
    );
    let model = dir.path().join("model");
    let o = calibrate_with(&train, &model, &stage);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(
        err.contains("robocal: CA-SOMM: ") && err.contains("kept"),
        "{err}"
    );
    let report = report(&model);
    let gate = &report["residual"]["gate"];
    assert_eq!(gate["inputs"], "physics");
    assert_eq!(gate["classes"], "routed");
    assert!(gate["tree_searched"].as_u64().unwrap() > 1);
    assert!(
        gate["decision"]
            .as_str()
            .unwrap()
            .contains("validation rows")
    );
    let manifest: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(model.join("residual.json")).unwrap())
            .unwrap();
    assert!(manifest["gate_decision"]["one_class"].as_f64().unwrap() > 0.0);
    // Whichever it kept, the saved model predicts (a kept gate computes its physics again).
    let out = dir.path().join("pred.csv");
    let o = robocal(&[
        "predict",
        "--model",
        s(&model),
        "--data",
        s(&train),
        "--out",
        s(&out),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}

#[test]
fn a_residual_stage_trains_saves_and_predicts_through_the_model() {
    let dir = tempfile::tempdir().unwrap();
    let train = twin_subset(dir.path(), |pose, load| {
        pose < 60 && pose % 4 != 3 && load <= 6.0
    });
    let held = twin_subset(dir.path(), |pose, load| {
        pose < 60 && pose % 4 == 3 && load <= 6.0
    });
    let stage = write(
        dir.path(),
        "stage.toml",
        &ca_somm_stage("relu", "min_samples_leaf = 10\nfallback = false\n"),
    );
    let model = dir.path().join("model");
    let o = calibrate_with(&train, &model, &stage);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    for file in [
        "kinematics.toml",
        "report.json",
        "residual.json",
        "residual-a-x.bpk",
        "residual-b-z.bpk",
    ] {
        assert!(model.join(file).is_file(), "{file}");
    }
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(model.join("report.json")).unwrap()).unwrap();
    let r = &report["residual"];
    assert_eq!(r["model"], "ca-somm");
    assert_eq!(r["networks"].as_array().unwrap().len(), 6);
    assert!(
        r["validation_source"]
            .as_str()
            .unwrap()
            .contains("held out")
    );
    assert!(r["classifier_accuracy_validation"].as_f64().is_some());
    // The model directory predicts kinematics + residual: not what its kinematics file alone does,
    // and the same on every run.
    let (a, b, k) = (
        dir.path().join("a.csv"),
        dir.path().join("b.csv"),
        dir.path().join("k.csv"),
    );
    for (src, flag, out) in [(s(&model), "--model", &a), (s(&model), "--model", &b)] {
        let o = robocal(&["predict", flag, src, "--data", s(&held), "--out", s(out)]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    }
    let kin = model.join("kinematics.toml");
    let o = robocal(&[
        "predict",
        "--robot",
        s(&kin),
        "--data",
        s(&held),
        "--out",
        s(&k),
    ]);
    assert!(o.status.success());
    let read = |p: &Path| std::fs::read_to_string(p).unwrap();
    assert_eq!(read(&a), read(&b));
    assert_ne!(read(&a), read(&k));

    compensation_through_the_model_lands_on_targets(&dir, &model, &held, &a);
    a_bad_residual_setting_writes_nothing(&dir, &train);
}

/// Compensation through the whole model (kinematics + CA-SOMM): targets 1 mm off what the model
/// predicts at the held-out rows; the commands, fed back through `predict --model`, land on
/// the targets to 0.001 mm.
fn compensation_through_the_model_lands_on_targets(
    dir: &tempfile::TempDir,
    model: &Path,
    held: &Path,
    a: &Path,
) {
    let read = |p: &Path| std::fs::read_to_string(p).unwrap();
    let predicted: Vec<Vec<f64>> = read(a)
        .lines()
        .skip(1)
        .map(|l| l.split(',').skip(2).map(|v| v.parse().unwrap()).collect())
        .collect();
    let held_rows: Vec<Vec<String>> = read(held)
        .lines()
        .skip(1)
        .take(12)
        .map(|l| l.split(',').map(str::to_string).collect())
        .collect();
    let mut targets = String::from("id,q1,q2,q3,q4,q5,q6,load,x,y,z\n");
    let mut aims = Vec::new();
    for (i, (row, p)) in held_rows.iter().zip(&predicted).enumerate() {
        let aim = [p[0] + 1.0, p[1] - 0.5, p[2] + 0.7];
        targets += &format!(
            "t{i},{},{},{},{}\n",
            row[1..7].join(","),
            row[7],
            aim[0],
            format_args!("{},{}", aim[1], aim[2])
        );
        aims.push((row[7].clone(), aim));
    }
    let targets = write(dir.path(), "targets.csv", &targets);
    let commands = dir.path().join("commands.csv");
    let compensate = |targets: &Path| {
        robocal(&[
            "compensate",
            "--model",
            s(model),
            "--targets",
            s(targets),
            "--out",
            s(&commands),
        ])
    };
    let o = compensate(&targets);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let mut replay = String::from("pose,q1,q2,q3,q4,q5,q6,load\n");
    for (line, (load, _)) in read(&commands).lines().skip(1).zip(&aims) {
        replay += &format!("{line},{load}\n");
    }
    assert_eq!(read(&commands).lines().count(), aims.len() + 1);
    let replay = write(dir.path(), "replay.csv", &replay);
    let landed = dir.path().join("landed.csv");
    let o = robocal(&[
        "predict",
        "--model",
        s(model),
        "--data",
        s(&replay),
        "--out",
        s(&landed),
    ]);
    assert!(o.status.success());
    for (line, (_, aim)) in read(&landed).lines().skip(1).zip(&aims) {
        let p: Vec<f64> = line
            .split(',')
            .skip(2)
            .map(|v| v.parse().unwrap())
            .collect();
        let miss =
            ((p[0] - aim[0]).powi(2) + (p[1] - aim[1]).powi(2) + (p[2] - aim[2]).powi(2)).sqrt();
        assert!(miss < 1.5e-3, "{line}: {miss} mm from {aim:?}");
    }
    // A target out of reach is named, the others are still written, and the exit is non-zero.
    let mut text = read(&targets);
    text += "far,0,10,10,0,30,0,0,100000,0,0\n";
    let targets = write(dir.path(), "targets.csv", &text);
    let o = compensate(&targets);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(
        err.contains("far") && err.contains("not reachable"),
        "{err}"
    );
    assert_eq!(read(&commands).lines().count(), aims.len() + 1);
}

/// A bad residual setting is refused with its key, and nothing is written.
fn a_bad_residual_setting_writes_nothing(dir: &tempfile::TempDir, train: &Path) {
    let bad = write(
        dir.path(),
        "bad.toml",
        "[residual]\nmodel = \"somm\"\n[residual.y]\nhidden = [4]\nactivation = \"relu\"\nlearning_rate = -1.0\n",
    );
    let out = dir.path().join("never");
    let o = robocal(&[
        "calibrate",
        "--robot",
        ROBOT,
        "--data",
        s(train),
        "--out",
        s(&out),
        "--config",
        s(&bad),
    ]);
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("residual.y.learning_rate") && err.contains("bad.toml"),
        "{err}"
    );
    assert!(!out.exists());
}

#[test]
fn an_experiment_runs_through_the_binary_and_writes_every_report_file() {
    let dir = tempfile::tempdir().unwrap();
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let net = |act: &str| {
        format!("{{ hidden = [6], activation = \"{act}\", learning_rate = 1e-2, max_epochs = 2 }}")
    };
    let exp = write(
        dir.path(),
        "small.toml",
        &format!(
            "name = \"small\"\nseed = 11\n\
             [data]\ntwin = \"{twin}\"\nmeasurements = \"{data}\"\n\
             [split]\ntrained_configurations = 100\nvalidation_loads = 3\n\
             [[model]]\nname = \"LM\"\n\
             [[model]]\nname = \"BFGS + CA-SOMM\"\nkinematic = {{ solver = \"bfgs\", max_iterations = 60 }}\n\
             [model.residual]\nmodel = \"ca-somm\"\nx = {x}\ny = {y}\nz = {x}\n",
            twin = root.join("configs/twin/pmc6va030.toml").display(),
            data = root.join("datasets/pmc6va030/measurements.csv").display(),
            x = net("tanh"),
            y = net("relu"),
        ),
    );
    let out = dir.path().join("reports");
    let o = robocal(&["run", s(&exp), "--out", s(&out)]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(!err.contains("panicked"), "{err}");
    let report = out.join("small");
    let mut files: Vec<String> = std::fs::read_dir(&report)
        .unwrap()
        .map(|e| e.unwrap().file_name().into_string().unwrap())
        .collect();
    files.sort();
    let mut want: Vec<String> = ["report.md", "results.json", "experiment.toml"]
        .iter()
        .map(|s| s.to_string())
        .collect();
    for stem in [
        "fig11-12-configurations",
        "fig13-load",
        "fig26-stages",
        "axes-lm",
        "axes-bfgs-ca-somm",
        "classes-bfgs-ca-somm",
    ] {
        want.push(format!("{stem}.png"));
        want.push(format!("{stem}.svg"));
    }
    want.sort();
    assert_eq!(files, want);
    for f in &files {
        let bytes = std::fs::read(report.join(f)).unwrap();
        assert!(bytes.len() > 500, "{f} is {} bytes", bytes.len());
        if f.ends_with(".png") {
            assert_eq!(&bytes[1..4], b"PNG", "{f}");
        }
        if f.ends_with(".svg") {
            assert!(String::from_utf8_lossy(&bytes).contains("<svg"), "{f}");
        }
    }
    // The CA-SOMM figure shows the X error by the gate's classes, before and after.
    let classes = std::fs::read_to_string(report.join("classes-bfgs-ca-somm.svg")).unwrap();
    assert!(
        classes.contains("class A") && classes.contains("X error after BFGS + CA-SOMM"),
        "classes-bfgs-ca-somm.svg"
    );
    // The per-axis plots say which rows and which frame (the model is in the legend).
    let axes = std::fs::read_to_string(report.join("axes-lm.svg")).unwrap();
    assert!(
        axes.contains("X error, 1224 GB10+GB30 rows, world frame"),
        "axes-lm.svg"
    );
    assert!(axes.contains("after LM"), "axes-lm.svg");
    let results: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(report.join("results.json")).unwrap())
            .unwrap();
    // 168 configurations, 100 trained: the untrained 68 × (21 − 6 untrained − 3 validation) loads
    // in GB10, × 6 in GB30.
    assert_eq!(results["split"]["sizes"]["GB10"], 68 * 12);
    assert_eq!(results["split"]["sizes"]["GB30"], 68 * 6);
    assert_eq!(results["split"]["sizes"]["GA10"], 100 * 15);
    assert_eq!(results["models"].as_array().unwrap().len(), 2);
    assert_eq!(
        results["models"][1]["networks"].as_array().unwrap().len(),
        6
    );
    let lm_after = results["models"][0]["after"]["table6"]["mean"]
        .as_f64()
        .unwrap();
    let before = results["before"]["table6"]["mean"].as_f64().unwrap();
    assert!(lm_after < 0.3 * before, "{lm_after} vs {before}");
    let md = std::fs::read_to_string(report.join("report.md")).unwrap();
    for needle in [
        "digital twin, not from a real robot",
        "Table 4",
        "Table 6",
        "fig26-stages.png",
    ] {
        assert!(md.contains(needle), "report.md lacks `{needle}`");
    }
    // The tables are printed too.
    assert!(String::from_utf8_lossy(&o.stdout).contains("Table 6"));
    // The resolved experiment is itself a valid experiment file, describing the same experiment.
    let resolved = robocal_pipeline::Experiment::load(&report.join("experiment.toml")).unwrap();
    let original = robocal_pipeline::Experiment::load(&exp).unwrap();
    assert_eq!(resolved.seed, 11);
    assert_eq!(resolved.models, original.models);
    assert_eq!(resolved.split.validation_loads, 3);
    assert_eq!(resolved.data.twin(), original.data.twin());

    the_same_experiment_again_gives_the_same_files_and_a_bad_one_leaves_them(
        &dir, &exp, &report, &files, &md, &out,
    );
}

/// The same experiment again: the same numbers and the same plots, byte for byte (only the
/// wall-clock fields may differ).
fn the_same_experiment_again_gives_the_same_files_and_a_bad_one_leaves_them(
    dir: &tempfile::TempDir,
    exp: &Path,
    report: &Path,
    files: &[String],
    md: &str,
    out: &Path,
) {
    let again = dir.path().join("again");
    let o = robocal(&["run", s(exp), "--out", s(&again)]);
    assert!(o.status.success());
    fn without_clock(v: &mut serde_json::Value) {
        match v {
            serde_json::Value::Object(map) => {
                for k in ["timings", "seconds", "residual_seconds"] {
                    map.remove(k);
                }
                map.values_mut().for_each(without_clock);
            }
            serde_json::Value::Array(items) => items.iter_mut().for_each(without_clock),
            _ => {}
        }
    }
    let json = |p: &Path| -> serde_json::Value {
        let mut v = serde_json::from_str(&std::fs::read_to_string(p).unwrap()).unwrap();
        without_clock(&mut v);
        v
    };
    assert_eq!(
        json(&report.join("results.json")),
        json(&again.join("small/results.json"))
    );
    for f in files
        .iter()
        .filter(|f| f.ends_with(".png") || f.ends_with(".svg"))
    {
        assert!(
            std::fs::read(report.join(f)).unwrap()
                == std::fs::read(again.join("small").join(f)).unwrap(),
            "{f} differs between two runs"
        );
    }

    // A bad experiment fails with its key and leaves the report as it was.
    let before_md = md.to_string();
    let bad = write(
        dir.path(),
        "small.toml",
        &std::fs::read_to_string(exp)
            .unwrap()
            .replace("validation_loads = 3", "validation_loads = 15"),
    );
    let o = robocal(&["run", s(&bad), "--out", s(out)]);
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("small.toml") && err.contains("split.validation_loads"),
        "{err}"
    );
    assert_eq!(
        std::fs::read_to_string(report.join("report.md")).unwrap(),
        before_md
    );
}

/// Simulates a twin into `dir` and returns its measurement file.
fn simulate(twin: &str, dir: &Path) -> PathBuf {
    let o = robocal(&["simulate", "--twin", twin, "--out", s(dir)]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    dir.join("measurements.csv")
}

/// The rows of `csv` whose configuration (in order of appearance) and load `keep` accepts.
fn subset(csv: &Path, name: &str, keep: impl Fn(usize, f64) -> bool) -> PathBuf {
    let text = std::fs::read_to_string(csv).unwrap();
    write(csv.parent().unwrap(), name, &select_rows(&text, keep))
}

/// Decision `stage` of a default calibration's report: (kept, reason).
fn decision(report: &serde_json::Value, stage: &str) -> (bool, String) {
    let d = report["selection"]["decisions"]
        .as_array()
        .unwrap()
        .iter()
        .find(|d| d["stage"] == stage)
        .unwrap_or_else(|| panic!("no decision on {stage}: {report}"));
    (
        d["kept"].as_bool().unwrap(),
        d["reason"].as_str().unwrap().to_string(),
    )
}

#[test]
fn default_calibrate_on_a_seven_axis_twin_keeps_compliance_and_compensates_through_it() {
    let dir = tempfile::tempdir().unwrap();
    let data = simulate("configs/twin/arm7.toml", &dir.path().join("sim"));
    let train = subset(&data, "train.csv", |pose, _| pose < 30);
    let val = subset(&data, "val.csv", |pose, _| (30..40).contains(&pose));
    let model = dir.path().join("model");
    let o = robocal(&[
        "calibrate",
        "--robot",
        "configs/robots/arm7.toml",
        "--data",
        s(&train),
        "--validate",
        s(&val),
        "--out",
        s(&model),
    ]);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{stderr}");
    let r = report(&model);
    assert!(r["stages_from"].as_str().unwrap().starts_with("default"));
    assert_eq!(r["selection"]["refitted_on_every_row"], false);
    assert!(
        r["selection"]["held_out"]
            .as_str()
            .unwrap()
            .ends_with("val.csv")
    );
    let (kin, why) = decision(&r, "kinematic");
    assert!(kin, "{why}");
    let (compliance, why) = decision(&r, "compliance");
    assert!(compliance && why.contains("held-out score"), "{why}");
    let (residual, why) = decision(&r, "residual");
    // 30 configurations: the residual models are tried (10 or more) and judged on the held-out
    // rows, where the physics leaves nothing they can take.
    assert!(
        !residual && why.contains("held-out score") && why.contains("residual model"),
        "{why}"
    );
    assert!(stderr.contains("stage compliance: kept"), "{stderr}");
    // Joint 1 stands vertical: no payload torque, held rigid by default.
    let joints = r["kinematic"]["compliance"]["joints"].as_array().unwrap();
    assert_eq!(joints.len(), 7);
    assert_eq!(joints[0]["identified"], false);
    assert!(joints[1]["identified"].as_bool().unwrap());
    assert!(!model.join("residual.json").exists());

    // predict --model is the calibrated table deflected by the compliance file, computed here.
    let robot = Robot::load(model.join("kinematics.toml")).unwrap();
    let compliance = robocal_robot::Compliance::load(model.join("compliance.toml"), 7).unwrap();
    let pred = dir.path().join("pred.csv");
    let o = robocal(&[
        "predict",
        "--model",
        s(&model),
        "--data",
        s(&val),
        "--out",
        s(&pred),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let input = std::fs::read_to_string(&val).unwrap();
    let output = std::fs::read_to_string(&pred).unwrap();
    let mut errors = Vec::new();
    for (i, o) in input.lines().skip(1).zip(output.lines().skip(1)) {
        let v: Vec<f64> = i.split(',').skip(1).map(|x| x.parse().unwrap()).collect();
        let q: Vec<f64> = v[..7].iter().map(|d| d.to_radians()).collect();
        let p = compliance.point(&robot, &q, v[7]);
        let w: Vec<f64> = o.split(',').skip(2).map(|x| x.parse().unwrap()).collect();
        assert!((p - nalgebra::Vector3::new(w[0], w[1], w[2])).norm() < 2e-6);
        errors.push((p - nalgebra::Vector3::new(v[8], v[9], v[10])).norm());
    }
    let held = r["validation"]["after"]["mean"].as_f64().unwrap();
    let mean = errors.iter().sum::<f64>() / errors.len() as f64;
    assert!((mean - held).abs() < 1e-6, "{mean} vs {held}");
    assert!(held < 0.5 * r["validation"]["before"]["mean"].as_f64().unwrap());

    // Compensate targets under load through the elastic model, back through predict.
    let mut targets = String::from("id,q1,q2,q3,q4,q5,q6,q7,load,x,y,z\n");
    for (k, line) in input.lines().skip(1).step_by(7).take(8).enumerate() {
        let v: Vec<f64> = line
            .split(',')
            .skip(1)
            .map(|x| x.parse().unwrap())
            .collect();
        let seed: Vec<String> = v[..7].iter().map(|x| x.to_string()).collect();
        let load = [0.0, 6.0, 14.0][k % 3];
        // The measured point, nudged: a target near where the arm went.
        targets += &format!(
            "t{k},{},{load},{},{},{}\n",
            seed.join(","),
            v[8] + 0.5,
            v[9] - 0.3,
            v[10] + 0.2
        );
    }
    let targets = write(dir.path(), "targets.csv", &targets);
    let commands = dir.path().join("commands.csv");
    let o = robocal(&[
        "compensate",
        "--model",
        s(&model),
        "--targets",
        s(&targets),
        "--out",
        s(&commands),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let wanted = std::fs::read_to_string(&targets).unwrap();
    let got = std::fs::read_to_string(&commands).unwrap();
    for (t, c) in wanted.lines().skip(1).zip(got.lines().skip(1)) {
        let t: Vec<f64> = t.split(',').skip(1).map(|x| x.parse().unwrap()).collect();
        let q: Vec<f64> = (c.split(',').skip(1))
            .map(|x| x.parse::<f64>().unwrap().to_radians())
            .collect();
        let p = compliance.point(&robot, &q, t[7]);
        let aim = nalgebra::Vector3::new(t[8], t[9], t[10]);
        assert!((p - aim).norm() < 2e-3, "{}", (p - aim).norm());
    }
}

#[test]
fn default_calibrate_on_one_load_of_a_five_axis_twin_skips_compliance_and_says_why() {
    let dir = tempfile::tempdir().unwrap();
    let data = simulate("configs/twin/arm5.toml", &dir.path().join("sim"));
    let unloaded = subset(&data, "unloaded.csv", |pose, load| pose < 36 && load == 0.0);
    // The default calibration of those rows into `out` within `budget` seconds (and `more`).
    let calibrate_with = |out: &Path, budget: &str, more: &[&str]| {
        let mut args = vec![
            "calibrate",
            "--robot",
            "configs/robots/arm5.toml",
            "--data",
            s(&unloaded),
            "--out",
            s(out),
            "--budget",
            budget,
        ];
        args.extend_from_slice(more);
        robocal(&args)
    };
    let calibrate = |out: &Path, budget: &str| calibrate_with(out, budget, &[]);
    let model = dir.path().join("model");
    let o = calibrate(&model, "90");
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{stderr}");
    let r = report(&model);
    // The budget given, kept with what the selection took, by the clock.
    assert_eq!(r["selection"]["budget_seconds"], 90.0);
    assert!(r["selection"]["seconds"].as_f64().unwrap() <= 90.0);
    assert_eq!(r["selection"]["reproducible"], false);
    assert!(r["selection"].get("counted_seconds").is_none());
    // Kept by counted work instead: the report says so and what the work came to; far under
    // the budget, the same model as by the clock.
    let counted = dir.path().join("counted");
    let o = calibrate_with(&counted, "90", &["--reproducible"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let c = report(&counted);
    assert_eq!(c["selection"]["reproducible"], true);
    let seconds = c["selection"]["counted_seconds"].as_f64().unwrap();
    assert!(seconds > 0.0 && seconds <= 90.0, "{seconds}");
    let table = |m: &Path| std::fs::read_to_string(m.join("kinematics.toml")).unwrap();
    assert_eq!(table(&counted), table(&model));
    // The same options in a stage file's [default]: the same model, and the report says where
    // the options came from.
    let options = dir.path().join("default.toml");
    std::fs::write(&options, "[default]\nbudget = 90\nreproducible = true\n").unwrap();
    let from_file = dir.path().join("from-file");
    let o = robocal(&[
        "calibrate",
        "--robot",
        "configs/robots/arm5.toml",
        "--data",
        s(&unloaded),
        "--out",
        s(&from_file),
        "--config",
        s(&options),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let f = report(&from_file);
    assert_eq!(table(&from_file), table(&counted));
    assert_eq!(f["selection"]["reproducible"], true);
    assert_eq!(f["selection"]["budget_seconds"], 90.0);
    assert!(
        (f["stages_from"].as_str().unwrap()).starts_with("default with the options of config"),
        "{}",
        f["stages_from"]
    );
    assert_eq!(r["selection"]["refitted_on_every_row"], true);
    assert!(
        r["selection"]["held_out"]
            .as_str()
            .unwrap()
            .contains("5-fold cross-validation over 36 configurations (seed 2020)")
    );
    assert!(decision(&r, "kinematic").0);
    let (kept, why) = decision(&r, "compliance");
    assert!(!kept && why.contains("one load"), "{why}");
    let (kept, why) = decision(&r, "residual");
    // 36 configurations: the residual models are tried and judged on the held-out rows.
    assert!(
        !kept && why.contains("held-out score") && why.contains("residual model"),
        "{why}"
    );
    // Refitted on every row; the β of the parallel joints are identified.
    assert_eq!(r["kinematic"]["points"], 36);
    let params = r["kinematic"]["parameters"].as_array().unwrap();
    for name in ["j3.beta", "j4.beta"] {
        let p = params.iter().find(|p| p["name"] == name).unwrap();
        assert_eq!(p["identified_flag"], true, "{name}");
    }
    // No payload compliance: a joint-error file only when harmonics or self-weight terms were
    // chosen, and then every compliance in it is zero.
    let (errors_kept, why) = decision(&r, "joint_errors");
    assert!(why.contains("held-out score"), "{why}");
    assert_eq!(model.join("compliance.toml").exists(), errors_kept);
    if errors_kept {
        let c = robocal_robot::Compliance::load(model.join("compliance.toml"), 5).unwrap();
        assert!(c.values.iter().all(|v| *v == 0.0));
        assert!(!c.harmonics.is_empty());
    }
    assert!(r["kinematic"]["after"]["mean"].as_f64().unwrap() < 0.2);
    // 90 s scored every candidate: no word of the budget. A budget spent before the first
    // joint-error candidate cuts the search, and calibrate says so, naming what it cut, on
    // stderr and in report.json; the model is still written.
    assert!(!stderr.contains("ended the search"), "{stderr}");
    let cut = dir.path().join("cut");
    let o = calibrate(&cut, "0.001");
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{stderr}");
    assert!(
        stderr.contains("robocal: warning: the time budget (0.001 s) ended the search before")
            && stderr.contains("kinematic + harmonics 2"),
        "{stderr}"
    );
    let warnings = report(&cut)["kinematic"]["warnings"].clone();
    assert!(
        (warnings.as_array().unwrap().iter())
            .any(|w| w.as_str().unwrap().contains("ended the search before")),
        "{warnings}"
    );
}

#[test]
fn default_calibrate_works_for_a_single_joint_from_an_identity_base() {
    let dir = tempfile::tempdir().unwrap();
    let nominal = "name = \"turntable\"\n[base]\nxyz = [0, 0, 0]\nrpy = [0, 0, 0]\n[tool]\nxyz = [300, 0, 40]\n\
                   [[joint]]\na = 0\nalpha = 0\nd = 100\ntheta = 0\n";
    let robot_file = write(dir.path(), "turntable.toml", nominal);
    let mut truth = Robot::from_toml_str(nominal, "truth").unwrap();
    truth.tool = nalgebra::Vector3::new(301.2, 0.4, 39.1);
    truth.joints[0].theta = 0.3f64.to_radians();
    truth.base.xyz = nalgebra::Vector3::new(2000.0, 500.0, -300.0);
    truth.base.rpy = nalgebra::Vector3::new(0.01, -0.02, 1.1);
    let mut text = String::from("pose,q1,load,x,y,z\n");
    for i in 0..24 {
        let q = -170.0 + 15.0 * i as f64;
        let p = truth.point(&[q.to_radians()]);
        text += &format!("p{i},{q},0,{},{},{}\n", p.x, p.y, p.z);
    }
    let data = write(dir.path(), "turntable.csv", &text);
    let model = dir.path().join("model");
    let o = robocal(&[
        "calibrate",
        "--robot",
        s(&robot_file),
        "--data",
        s(&data),
        "--out",
        s(&model),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let r = report(&model);
    assert!(decision(&r, "kinematic").0);
    assert!(r["kinematic"]["after"]["max"].as_f64().unwrap() < 1e-3);
    assert!(!r["kinematic"]["fixed"].as_array().unwrap().is_empty());
}

#[test]
fn predict_sigma_comes_from_a_gp_model_and_is_refused_for_a_table_alone() {
    let dir = tempfile::tempdir().unwrap();
    let data = simulate("configs/twin/arm5.toml", &dir.path().join("sim"));
    let train = subset(&data, "train.csv", |pose, _| pose < 30);
    let test = subset(&data, "test.csv", |pose, _| pose >= 30);
    let model = dir.path().join("model");
    let o = robocal(&[
        "calibrate",
        "--robot",
        "configs/robots/arm5.toml",
        "--data",
        s(&train),
        "--out",
        s(&model),
        "--config",
        "configs/stages/gp.toml",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let r = report(&model);
    assert_eq!(r["residual"]["model"], "gp");
    assert_eq!(r["residual"]["gp"].as_array().unwrap().len(), 3);
    let (plain, with) = (dir.path().join("plain.csv"), dir.path().join("sigma.csv"));
    for (out, extra) in [(&plain, None), (&with, Some("--sigma"))] {
        let mut args = vec![
            "predict",
            "--model",
            s(&model),
            "--data",
            s(&test),
            "--out",
            s(out),
        ];
        args.extend(extra);
        let o = robocal(&args);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    }
    let plain = std::fs::read_to_string(&plain).unwrap();
    let with = std::fs::read_to_string(&with).unwrap();
    assert!(with.starts_with("pose,load,x,y,z,sigma\n"), "{with}");
    for (p, w) in plain.lines().skip(1).zip(with.lines().skip(1)) {
        let (head, sigma) = w.rsplit_once(',').unwrap();
        assert_eq!(head, p);
        let sigma: f64 = sigma.parse().unwrap();
        assert!(sigma > 0.0 && sigma < 1.0, "{sigma}");
    }
    // A table alone has no standard deviation to give (no covariance): exit 1, nothing written.
    let out = dir.path().join("none.csv");
    let o = robocal(&[
        "predict",
        "--robot",
        "configs/robots/arm5.toml",
        "--data",
        s(&test),
        "--out",
        s(&out),
        "--sigma",
    ]);
    assert_eq!(o.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&o.stderr).contains("--sigma"));
    assert!(!out.exists());
}

/// calibrate with backlash (a stage config giving the home readings) says, per joint, the
/// identified half play and its home, as compliance.toml saves them; a home list that does not
/// match the robot's joints is refused naming the key, and no model is written.
#[test]
fn calibrate_prints_and_saves_the_backlash() {
    let dir = tempfile::tempdir().unwrap();
    let text = select_rows(&twin_rows(), |c, load| c < 60 && load == 0.0);
    let data = write(dir.path(), "data.csv", &text);
    let stage = write(
        dir.path(),
        "b.toml",
        "[kinematic]\nsolver = \"lm\"\n[joint_errors]\nharmonics = 0\nbacklash = true\nbacklash_torque = false\nbacklash_home = [0.0, 0.0, 0.0, 5.0, 0.0, 0.0]\n",
    );
    let model = dir.path().join("model");
    let o = calibrate_with(&data, &model, &stage);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{stderr}");
    let c = robocal_robot::Compliance::load(model.join("compliance.toml"), 6).unwrap();
    assert_eq!(c.backlash.len(), 6);
    assert_eq!(c.backlash[3].home(), Some(5f64.to_radians()));
    // The twin's joint 1 rests on the flank of its approach from 0.
    let j1 = c.backlash[0].value.to_degrees();
    assert!(j1.abs() > 0.005, "{j1}");
    let line = format!("robocal: joint 1 backlash: {:+.4}° at or above 0.0°", j1);
    assert!(stderr.contains(&line), "{line} not in {stderr}");
    // The play with its σ: twice the half-play's in report.json.
    let std = (report(&model)["kinematic"]["joint_errors"]
        .as_array()
        .unwrap()
        .iter())
    .find(|t| t["name"] == "j1.backlash")
    .and_then(|t| t["std"].as_f64())
    .expect("j1.backlash's σ in report.json");
    let play = format!("a play of {:.4}° ± {:.4}", 2.0 * j1.abs(), 2.0 * std);
    assert!(stderr.contains(&play), "{play} not in {stderr}");
    for b in c.backlash.iter().filter(|b| b.value == 0.0) {
        assert!(!stderr.contains(&format!("joint {} backlash", b.joint + 1)));
    }
    let bad = write(
        dir.path(),
        "bad.toml",
        "[joint_errors]\nbacklash = true\nbacklash_home = [0.0, 0.0]\n",
    );
    let other = dir.path().join("other");
    let o = calibrate_with(&data, &other, &bad);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(
        !o.status.success() && stderr.contains("backlash_home"),
        "{stderr}"
    );
    assert!(!other.exists());
    let unasked = write(
        dir.path(),
        "unasked.toml",
        "[joint_errors]\nbacklash_home = [0.0]\n",
    );
    let o = calibrate_with(&data, &other, &unasked);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(
        !o.status.success()
            && stderr.contains("joint_errors.backlash_home")
            && stderr.contains("unasked.toml"),
        "{stderr}"
    );
    assert!(!other.exists());
}

/// calibrate with harmonics says, per joint, each order's amplitude and the reach over which the
/// harmonics are continued; the reach in compliance.toml is the data file's readings of the
/// joint widened by a quarter of their span at each end (recomputed here from the CSV), and
/// the printed one equals it.
#[test]
fn calibrate_prints_and_saves_the_harmonics_reach() {
    let dir = tempfile::tempdir().unwrap();
    let text = select_rows(&twin_rows(), |c, load| c < 60 && load == 0.0);
    let data = write(dir.path(), "data.csv", &text);
    let stage = write(
        dir.path(),
        "h.toml",
        "[kinematic]\nsolver = \"lm\"\n[joint_errors]\nharmonics = 2\n",
    );
    let model = dir.path().join("model");
    let o = calibrate_with(&data, &model, &stage);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{stderr}");
    let c = robocal_robot::Compliance::load(model.join("compliance.toml"), 6).unwrap();
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let rows: Vec<Vec<&str>> = lines.map(|l| l.split(',').collect()).collect();
    let mut printed = 0;
    for joint in 0..6 {
        let col = header
            .iter()
            .position(|h| *h == format!("q{}", joint + 1))
            .unwrap();
        let q: Vec<f64> = rows.iter().map(|r| r[col].parse().unwrap()).collect();
        let lo = q.iter().copied().fold(f64::INFINITY, f64::min);
        let hi = q.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        let (a, b) = (lo - 0.25 * (hi - lo), hi + 0.25 * (hi - lo));
        let terms: Vec<_> = c.harmonics.iter().filter(|h| h.joint == joint).collect();
        for h in &terms {
            let [ra, rb] = h.reach.unwrap();
            assert!((ra.to_degrees() - a).abs() < 1e-9 && (rb.to_degrees() - b).abs() < 1e-9);
        }
        if terms.iter().any(|h| h.sin != 0.0 || h.cos != 0.0) {
            let line = format!(
                "robocal: joint {} transmission harmonics: order ",
                joint + 1
            );
            let said = stderr
                .lines()
                .find(|l| l.starts_with(&line))
                .unwrap_or_else(|| panic!("no line for joint {}: {stderr}", joint + 1));
            assert!(
                said.contains(&format!("continued over {a:.1}..{b:.1}°")),
                "{said}"
            );
            printed += 1;
        }
    }
    assert!(printed >= 3, "{stderr}");
    // The harmonics' prior: its spread printed as report.json keeps it.
    let report: serde_json::Value =
        serde_json::from_slice(&std::fs::read(model.join("report.json")).unwrap()).unwrap();
    let spread = report["kinematic"]["harmonic_prior_deg"].as_f64().unwrap();
    assert!(
        spread > 0.0 && spread < robocal_ident::HARMONIC_BOUND_DEG,
        "{spread}"
    );
    let line = format!("robocal: transmission harmonics under a prior of spread {spread:.4}°");
    assert!(stderr.contains(&line), "{line} not in {stderr}");
    // Without it: no spread, no line; asked for without harmonics: refused, naming the key.
    for (name, text, ok) in [
        (
            "free.toml",
            "[joint_errors]\nharmonics = 2\nharmonic_prior = false\n",
            true,
        ),
        (
            "none.toml",
            "[joint_errors]\nharmonics = 0\nharmonic_prior = true\n",
            false,
        ),
    ] {
        let other = dir.path().join(name.replace(".toml", ""));
        let o = calibrate_with(&data, &other, &write(dir.path(), name, text));
        let stderr = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.success(), ok, "{stderr}");
        assert!(!stderr.contains("under a prior"), "{stderr}");
        if ok {
            let report: serde_json::Value =
                serde_json::from_slice(&std::fs::read(other.join("report.json")).unwrap()).unwrap();
            assert!(report["kinematic"].get("harmonic_prior_deg").is_none());
        } else {
            assert!(stderr.contains("joint_errors.harmonic_prior"), "{stderr}");
            assert!(!other.exists());
        }
    }
}

/// The names of a calibration report's joint-error terms given in `unit`, in order.
fn joint_error_names<'a>(report: &'a serde_json::Value, unit: &str) -> Vec<&'a str> {
    (report["kinematic"]["joint_errors"]
        .as_array()
        .unwrap()
        .iter())
    .filter(|t| t["unit"] == unit)
    .map(|t| t["name"].as_str().unwrap())
    .collect()
}

/// The bundled twin at 40 configurations, 0 and 20 kg, with only its joints' compliance on
/// (geometry errors, no noise).
fn compliance_only_twin() -> String {
    crate::common::bundled_twin(40, "")
        .replace("enabled = true", "enabled = false")
        .replace(
            "[compliance]\nenabled = false",
            "[compliance]\nenabled = true",
        )
}

/// A stage config with tilting compliances on a twin whose bearings tilt (its `[beyond]` tilt,
/// 5× stiffer across the axes than the joints about them; compliance on, every other effect
/// off, noise-free, 0 and 20 kg): calibrate prints each identified tilt, saves them in
/// compliance.toml (`[[tilt]]`), names them in report.json with their unit, and the saved
/// model, read back by `evaluate`, leaves a fraction of what the same stages without tilts
/// leave. The default calibration with `--tilt` tries them and keeps them.
#[test]
fn a_stage_config_with_tilts_identifies_prints_and_saves_them() {
    let dir = tempfile::tempdir().unwrap();
    let twin = compliance_only_twin();
    let twin = format!(
        "{twin}\n[beyond]\nenabled = true\ntilt_stiffness = [2.0e7, 3.75e6, 2.1e6, 7.5e5, 6.0e5, 5.0e5]\n\
         wobble = [0, 0, 0, 0, 0, 0]\nwobble_phase = [0, 0, 0, 0, 0, 0]\nharmonic_3 = [0, 0, 0, 0, 0, 0]\n\
         phase_3 = [0, 0, 0, 0, 0, 0]\ncoupling = [0, 0, 0, 0, 0, 0]\ncoupling_phase = [0, 0, 0, 0, 0, 0]\n"
    );
    let twin = write(dir.path(), "twin.toml", &twin);
    let sim = dir.path().join("sim");
    simulate(s(&twin), &sim);
    let truth = sim.join("truth.csv");
    let stages = "[kinematic]\nsolver = \"lm\"\n[compliance]\npayload_com = [100.0, 0.0, 60.0]\n\
                  [joint_errors]\nharmonics = 0\nlink_weights = true\n";
    let upright = write(dir.path(), "upright.toml", stages);
    let tilted = write(dir.path(), "tilted.toml", &format!("{stages}tilt = true\n"));
    let (plain, model) = (dir.path().join("plain"), dir.path().join("model"));
    let o = calibrate_with(&truth, &plain, &upright);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let o = calibrate_with(&truth, &model, &tilted);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{stderr}");
    let c = robocal_robot::Compliance::load(model.join("compliance.toml"), 6).unwrap();
    assert_eq!(c.tilts.len(), 6);
    let shoulder = c.tilts[1].value / robocal_robot::DEG_PER_KNM;
    assert!(
        stderr.contains(&format!(
            "joint 2 tilting compliance {shoulder:.4} deg/kN·m"
        )),
        "{stderr}"
    );
    let r = report(&model);
    let tilts = joint_error_names(&r, "deg per kN·m");
    assert_eq!(
        tilts,
        [
            "j1.tilt", "j2.tilt", "j3.tilt", "j4.tilt", "j5.tilt", "j6.tilt"
        ]
    );
    let mean = |model: &Path| {
        let o = robocal(&[
            "evaluate",
            "--model",
            s(model),
            "--data",
            s(&truth),
            "--json",
        ]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
        v["mean"].as_f64().unwrap()
    };
    let (with, without) = (mean(&model), mean(&plain));
    assert!(
        with < 0.2 * without && without > 0.005,
        "{with} vs {without}"
    );
    // The default with `--tilt` tries them last, on the physics it chose, and keeps them only
    // where the held-out error says so: here, where they are the one effect left, it does.
    let chosen = dir.path().join("default");
    let o = robocal(&[
        "calibrate",
        "--robot",
        "configs/robots/pmc6va030.toml",
        "--data",
        s(&truth),
        "--out",
        s(&chosen),
        "--tilt",
    ]);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{stderr}");
    let r = report(&chosen);
    let tried: Vec<&str> = (r["selection"]["candidates"].as_array().unwrap().iter())
        .map(|c| c["name"].as_str().unwrap())
        .filter(|n| n.ends_with(" + tilt"))
        .collect();
    assert_eq!(tried.len(), 1, "{stderr}");
    let (kept, reason) = decision(&r, "tilt");
    assert!(kept && reason.contains("tilting compliances"), "{reason}");
    assert!(
        stderr.contains(&format!("chosen: {}", tried[0])),
        "{stderr}"
    );
    let c = robocal_robot::Compliance::load(chosen.join("compliance.toml"), 6).unwrap();
    assert!(!c.tilts.is_empty());
}

/// calibrate with `identify_payload_com` (a stage config) on the bundled twin with only its
/// geometry errors and compliances (noise-free points, 0 and 20 kg, the links' weights in the
/// model too: every effect of this twin in the model family) finds the twin's payload centre of
/// mass, on a bracket 100 mm off the flange's axis, starting from the measured point; it prints
/// it with its σ, saves it in compliance.toml and names its coordinates in report.json.
#[test]
fn calibrate_identifies_prints_and_saves_the_payload_centre_of_mass() {
    let dir = tempfile::tempdir().unwrap();
    let twin = compliance_only_twin();
    let twin = write(dir.path(), "twin.toml", &twin);
    let sim = dir.path().join("sim");
    simulate(s(&twin), &sim);
    let truth = sim.join("truth.csv");
    let stage = write(
        dir.path(),
        "com.toml",
        "[kinematic]\nsolver = \"lm\"\n[compliance]\nidentify_payload_com = true\n[joint_errors]\nharmonics = 0\nlink_weights = true\n",
    );
    let model = dir.path().join("model");
    let o = calibrate_with(&truth, &model, &stage);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{stderr}");
    let c = robocal_robot::Compliance::load(model.join("compliance.toml"), 6).unwrap();
    // The flange frame is known up to what the tool point takes (the last link's length and the
    // tool's z are one parameter): the centre of mass from the measured point is what the data
    // fix. The twin's: [masses] payload_com = [100.0, 0.0, 60.0], [truth.tool] xyz = [2.14,
    // -1.37, 98.26].
    let tool = Robot::load(model.join("kinematics.toml")).unwrap().tool;
    let expected = nalgebra::Vector3::new(100.0 - 2.14, 0.0 + 1.37, 60.0 - 98.26);
    assert!(
        (c.payload_com - tool - expected).norm() < 0.5,
        "{} vs {expected}",
        c.payload_com - tool
    );
    // It started from the measured point, 100 mm away.
    let start = Robot::load("configs/robots/pmc6va030.toml").unwrap().tool;
    assert!((c.payload_com - start).norm() > 50.0);
    let line = stderr
        .lines()
        .find(|l| l.starts_with("robocal: payload centre of mass x "))
        .unwrap_or_else(|| panic!("no payload line in {stderr}"));
    assert!(
        line.contains(&format!("x {:.1} ± ", c.payload_com.x))
            && line.contains(&format!("z {:.1} ± ", c.payload_com.z))
            && line.contains("identified with the compliances (3 of 3 coordinates"),
        "{line}"
    );
    let r = report(&model);
    let names = joint_error_names(&r, "mm");
    assert_eq!(names, ["payload_com.x", "payload_com.y", "payload_com.z"]);
}

/// A reader that goes away before the output is written (`robocal evaluate … | head -1` after
/// `head` has its line) ends the output quietly: exit 0, nothing on stderr, no panic.
#[test]
fn a_closed_stdout_is_no_panic() {
    let dir = tempfile::tempdir().unwrap();
    let data = hand_file(dir.path(), &[1.0, 2.0, 3.0]);
    let (reader, writer) = std::io::pipe().unwrap();
    drop(reader);
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_robocal"))
        .args(["evaluate", "--robot", ROBOT, "--data", s(&data)])
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .stdout(writer)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{:?}: {stderr}", o.status);
    assert!(!stderr.contains("panicked"), "{stderr}");
}
