//! Bad input across every command and input file: each case ends with exit 1, a short error on
//! stderr naming the file and the line/column or key, no panic, and no output written or
//! changed.

use std::path::{Path, PathBuf};

use crate::common::{robocal, s, select_rows, twin_rows, write};

const ROBOT: &str = "configs/robots/pmc6va030.toml";
const HEADER: &str = "pose,q1,q2,q3,q4,q5,q6,load,x,y,z";

/// Every file and directory under `dir` with its contents (directories as a marker).
fn snapshot(dir: &Path) -> Vec<(PathBuf, Vec<u8>)> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                out.push((p.clone(), b"<dir>".to_vec()));
                stack.push(p);
            } else {
                out.push((p.clone(), std::fs::read(&p).unwrap()));
            }
        }
    }
    out.sort();
    out
}

/// Runs `args`; asserts exit 1, no panic, every needle in stderr, and `outputs` unchanged.
fn fails(label: &str, args: &[&str], needles: &[&str], outputs: &Path) {
    let before = snapshot(outputs);
    let o = robocal(args);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{label}: {args:?}\n{stderr}");
    assert!(!stderr.contains("panicked"), "{label}: {stderr}");
    for n in needles {
        assert!(stderr.contains(n), "{label}: `{n}` not in\n{stderr}");
    }
    assert!(
        stderr.lines().count() <= 12,
        "{label}: long error\n{stderr}"
    );
    assert_eq!(snapshot(outputs), before, "{label}: outputs changed");
}

/// Rows from the nominal table at a few configurations (enough for `predict`).
fn good_rows() -> String {
    let robot =
        robocal_robot::Robot::load(Path::new(env!("CARGO_MANIFEST_DIR")).join(ROBOT)).unwrap();
    let mut text = format!("{HEADER}\n");
    for (i, q) in [
        [0.0, -60.0, -20.0, 0.0, 60.0, 0.0],
        [12.5, -30.0, 45.25, 0.0, 60.0, -12.0],
        [-40.0, 20.0, -10.0, 90.0, -45.0, 30.0],
        [30.0, -45.0, 10.0, -30.0, 30.0, 60.0],
    ]
    .iter()
    .enumerate()
    {
        let rad: Vec<f64> = q.iter().map(|d: &f64| d.to_radians()).collect();
        let p = robot.point(&rad);
        let joints: Vec<String> = q.iter().map(|v| v.to_string()).collect();
        text += &format!("p{i},{},0,{},{},{}\n", joints.join(","), p.x, p.y, p.z);
    }
    text
}

#[test]
fn every_command_refuses_bad_input_cleanly() {
    let f = fixture();
    bad_measurement_files(&f);
    unreadable_files(&f);
    bad_robot_tables(&f);
    bad_stage_configs(&f);
    stages_the_data_cannot_fit(&f);
    options_of_the_default(&f);
    bad_model_directories(&f);
    bad_target_files(&f);
    bad_twin_and_experiment_files(&f);
}

/// The files every refusal is checked against: outputs that must be left as they were, a good
/// measurement file, and a good model to break copies of.
struct Fixture {
    _dir: tempfile::TempDir,
    d: PathBuf,
    outs: PathBuf,
    pred: PathBuf,
    commands: PathBuf,
    model_out: PathBuf,
    sim_out: PathBuf,
    good: PathBuf,
    model: PathBuf,
}

/// Makes the [`Fixture`].
fn fixture() -> Fixture {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path().to_path_buf();
    let d = d.as_path();
    let outs = d.join("outputs");
    std::fs::create_dir_all(&outs).unwrap();
    let pred = write(&outs, "pred.csv", "previous prediction\n");
    let commands = write(&outs, "commands.csv", "previous commands\n");
    let model_out = outs.join("model");
    write(&model_out, "report.json", "{\"previous\": true}\n");
    let sim_out = outs.join("sim");
    write(&sim_out, "measurements.csv", "previous\n");
    let good = write(d, "good.csv", &good_rows());

    // A good model to break copies of.
    let model = d.join("model");
    let o = robocal(&[
        "calibrate",
        "--robot",
        ROBOT,
        "--data",
        "datasets/pmc6va030/measurements.csv",
        "--out",
        s(&model),
        "--config",
        "configs/stages/kinematic-lm.toml",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));

    Fixture {
        d: d.to_path_buf(),
        outs,
        pred,
        commands,
        model_out,
        sim_out,
        good,
        model,
        _dir: dir,
    }
}

/// Measurement CSV: predict, evaluate and calibrate read it the same way.
fn bad_measurement_files(f: &Fixture) {
    let Fixture {
        d,
        outs,
        pred,
        model_out,
        good,
        model,
        ..
    } = f;
    let csv_cases: &[(&str, String, &[&str])] = &[
        ("empty.csv", String::new(), &["empty.csv", "empty"]),
        (
            "header.csv",
            format!("{HEADER}\n"),
            &["header.csv", "no data"],
        ),
        (
            "missing-column.csv",
            "pose,q1,q2,q4,q5,q6,load,x,y,z\np,0,0,0,0,0,0,1,2,3\n".into(),
            &["missing-column.csv", "`q3`"],
        ),
        (
            "duplicate-column.csv",
            format!("{HEADER},q2\np,0,0,0,0,0,0,0,1,2,3,4\n"),
            &["duplicate-column.csv", "`q2`"],
        ),
        (
            "text.csv",
            format!("{HEADER}\np,0,two,0,0,0,0,0,1,2,3\n"),
            &["text.csv", "line 2", "`q2`"],
        ),
        (
            "nan.csv",
            format!("{HEADER}\np,0,0,NaN,0,0,0,0,1,2,3\n"),
            &["nan.csv", "line 2", "`q3`"],
        ),
        (
            "inf.csv",
            format!("{HEADER}\np,0,0,0,0,0,0,inf,1,2,3\n"),
            &["inf.csv", "line 2", "`load`"],
        ),
        (
            "overflow.csv",
            format!("{HEADER}\np,0,0,0,0,1e400,0,0,1,2,3\n"),
            &["overflow.csv", "line 2", "`q5`"],
        ),
        (
            "negative-load.csv",
            format!("{HEADER}\np,0,0,0,0,0,0,-5,1,2,3\n"),
            &["negative-load.csv", "line 2", "`load`"],
        ),
        (
            "five-joints.csv",
            "pose,q1,q2,q3,q4,q5,load,x,y,z\np,0,0,0,0,0,0,1,2,3\n".into(),
            &["five-joints.csv", "6 joints"],
        ),
        (
            "duplicate-pose.csv",
            format!("{HEADER}\np,0,0,0,0,0,0,0,1,2,3\np,0,0,0,0,0,9,5,1,2,3\n"),
            &["duplicate-pose.csv", "line 3", "`p`"],
        ),
    ];
    for (name, text, needles) in csv_cases {
        let data = write(d, name, text);
        let m = s(model_out);
        for args in [
            vec![
                "predict",
                "--robot",
                ROBOT,
                "--data",
                s(&data),
                "--out",
                s(pred),
            ],
            vec!["evaluate", "--model", s(model), "--data", s(&data)],
            vec![
                "calibrate",
                "--robot",
                ROBOT,
                "--data",
                s(&data),
                "--out",
                m,
            ],
            vec![
                "calibrate",
                "--robot",
                ROBOT,
                "--data",
                s(good),
                "--validate",
                s(&data),
                "--out",
                m,
            ],
        ] {
            fails(name, &args, needles, outs);
        }
    }
}

/// Unreadable: a directory where a file should be, and a missing file.
fn unreadable_files(f: &Fixture) {
    let Fixture { d, outs, .. } = f;
    for (label, path) in [
        ("directory", d.to_path_buf()),
        ("missing", d.join("nope.csv")),
    ] {
        fails(
            label,
            &["evaluate", "--robot", ROBOT, "--data", s(&path)],
            &[s(&path)],
            outs,
        );
    }
}

/// Robot TOML.
fn bad_robot_tables(f: &Fixture) {
    let Fixture {
        d,
        outs,
        pred,
        model_out,
        good,
        ..
    } = f;
    let joint = "[[joint]]\na = 0.0\nalpha = 0.0\nd = 0.0\ntheta = 0.0\n";
    let frames =
        "[base]\nxyz = [0.0, 0.0, 0.0]\nrpy = [0.0, 0.0, 0.0]\n[tool]\nxyz = [0.0, 0.0, 0.0]\n";
    let robot_cases: &[(&str, String, &[&str])] = &[
        (
            "empty.toml",
            String::new(),
            &["empty.toml", "line 1", "name"],
        ),
        (
            "wrong-type.toml",
            format!(
                "name = \"r\"\n{frames}[[joint]]\na = \"long\"\nalpha = 0.0\nd = 0.0\ntheta = 0.0\n"
            ),
            &["wrong-type.toml", "line 8"],
        ),
        (
            "missing-key.toml",
            format!("name = \"r\"\n{frames}[[joint]]\na = 0.0\nalpha = 0.0\ntheta = 0.0\n"),
            &["missing-key.toml", "`d`"],
        ),
        (
            "unknown-key.toml",
            format!("name = \"r\"\n{frames}{joint}length = 3.0\n"),
            &["unknown-key.toml", "line 12", "length"],
        ),
        (
            "rpy.toml",
            format!(
                "name = \"r\"\n[base]\nxyz = [0.0, 0.0, 0.0]\nrpy = [0.0, 0.0]\n[tool]\nxyz = [0.0, 0.0, 0.0]\n{joint}"
            ),
            &["rpy.toml", "line 4"],
        ),
        (
            "nan.toml",
            format!(
                "name = \"r\"\n{frames}[[joint]]\na = nan\nalpha = 0.0\nd = 0.0\ntheta = 0.0\n"
            ),
            &["nan.toml", "joint[1].a"],
        ),
        (
            "huge.toml",
            format!(
                "name = \"r\"\n{frames}[[joint]]\na = 1e400\nalpha = 0.0\nd = 0.0\ntheta = 0.0\n"
            ),
            &["huge.toml", "line 8"],
        ),
        (
            "no-joint.toml",
            format!("name = \"r\"\n{frames}"),
            &["no-joint.toml", "[[joint]]"],
        ),
    ];
    for (name, text, needles) in robot_cases {
        let robot = write(d, name, text);
        fails(
            name,
            &[
                "predict",
                "--robot",
                s(&robot),
                "--data",
                s(good),
                "--out",
                s(pred),
            ],
            needles,
            outs,
        );
        fails(
            name,
            &[
                "calibrate",
                "--robot",
                s(&robot),
                "--data",
                s(good),
                "--out",
                s(model_out),
            ],
            needles,
            outs,
        );
    }
}

/// Stage configs.
fn bad_stage_configs(f: &Fixture) {
    let Fixture {
        d,
        outs,
        model_out,
        good,
        ..
    } = f;
    let stage_cases: &[(&str, &str, &[&str])] = &[
        (
            "stage-type.toml",
            "[kinematic]\nmax_iterations = \"many\"\n",
            &["stage-type.toml", "line 2"],
        ),
        (
            "stage-unknown.toml",
            "[kinematic]\nsolver = \"lm\"\nspeed = 3\n",
            &["stage-unknown.toml", "speed"],
        ),
        (
            "stage-missing.toml",
            "[residual]\nseed = 3\n",
            &["stage-missing.toml", "model"],
        ),
        (
            "stage-joint.toml",
            "[compliance]\njoints = [0, 2]\n",
            &["stage-joint.toml", "compliance.joints"],
        ),
        (
            "stage-gravity.toml",
            "[compliance]\ngravity = [0.0, 0.0, 0.0]\n",
            &["stage-gravity.toml", "compliance.gravity"],
        ),
        (
            "stage-rate.toml",
            "[residual]\nmodel = \"somm\"\n[residual.x]\nhidden = [3]\nactivation = \"tanh\"\nlearning_rate = -1.0\n",
            &["stage-rate.toml", "residual.x.learning_rate"],
        ),
        (
            "stage-members.toml",
            "[residual]\nmodel = \"gp\"\nmembers = 3\n",
            &["stage-members.toml", "residual.members", "only a somm"],
        ),
        (
            "stage-tilt.toml",
            "[kinematic]\nsolver = \"lm\"\n[joint_errors]\nharmonics = 0\ntilt = true\n",
            &["stage-tilt.toml", "joint_errors.tilt", "[compliance]"],
        ),
    ];
    for (name, text, needles) in stage_cases {
        let config = write(d, name, text);
        fails(
            name,
            &[
                "calibrate",
                "--robot",
                ROBOT,
                "--data",
                s(good),
                "--out",
                s(model_out),
                "--config",
                s(&config),
            ],
            needles,
            outs,
        );
    }
}

/// A compliance stage on one load, and too few poses for the parameters.
fn stages_the_data_cannot_fit(f: &Fixture) {
    let Fixture {
        d,
        outs,
        model_out,
        good,
        ..
    } = f;
    let compliance = write(d, "compliance.toml", "[compliance]\n");
    fails(
        "one load",
        &[
            "calibrate",
            "--robot",
            ROBOT,
            "--data",
            s(good),
            "--out",
            s(model_out),
            "--config",
            s(&compliance),
        ],
        &["good.csv", "two or more loads"],
        outs,
    );
    let two = write(
        d,
        "two.csv",
        &good_rows().lines().take(3).collect::<Vec<_>>().join("\n"),
    );
    fails(
        "too few poses",
        &[
            "calibrate",
            "--robot",
            ROBOT,
            "--data",
            s(&two),
            "--out",
            s(model_out),
        ],
        &["two.csv", "too few"],
        outs,
    );
}

/// The default calibration's time budget: a positive number of seconds, and not for a
/// stage config (which runs what it names); the bearings' tilt is the default's to try too
/// (a stage config asks for it itself).
fn options_of_the_default(f: &Fixture) {
    let Fixture {
        d,
        outs,
        model_out,
        good,
        ..
    } = f;
    let compliance = write(d, "compliance.toml", "[compliance]\n");
    for (name, option, config, needles) in [
        (
            "zero budget",
            &["--budget", "0"][..],
            None,
            &["`--budget`", "0 is not a positive number"][..],
        ),
        (
            "NaN budget",
            &["--budget", "NaN"][..],
            None,
            &["`--budget`", "NaN is not a positive"][..],
        ),
        (
            "budget with a stage config",
            &["--budget", "60"][..],
            Some(s(&compliance)),
            &["`--budget`", "compliance.toml", "takes none"][..],
        ),
        (
            "tilt with a stage config",
            &["--tilt"][..],
            Some(s(&compliance)),
            &["`--tilt`", "compliance.toml", "tilt = true"][..],
        ),
        (
            "flank search with a stage config",
            &["--flank-search"][..],
            Some(s(&compliance)),
            &["`--flank-search`", "compliance.toml", "flank_search = true"][..],
        ),
        (
            "residual frame with a stage config",
            &["--residual-frame", "joint1"][..],
            Some(s(&compliance)),
            &[
                "`--residual-frame`",
                "compliance.toml",
                "frame = \"joint1\"",
            ][..],
        ),
        (
            "unknown residual frame",
            &["--residual-frame", "tool"][..],
            None,
            &["--residual-frame", "`tool` is not a frame", "joint1"][..],
        ),
    ] {
        let mut args = vec![
            "calibrate",
            "--robot",
            ROBOT,
            "--data",
            s(good),
            "--out",
            s(model_out),
        ];
        args.extend(option);
        if let Some(c) = config {
            args.extend(["--config", c]);
        }
        fails(name, &args, needles, outs);
    }
}

/// Model directories.
fn bad_model_directories(f: &Fixture) {
    let Fixture {
        d,
        outs,
        pred,
        good,
        model,
        ..
    } = f;
    let copy = |name: &str| -> PathBuf {
        let to = d.join(name);
        std::fs::create_dir_all(&to).unwrap();
        for e in std::fs::read_dir(model).unwrap() {
            let p = e.unwrap().path();
            std::fs::copy(&p, to.join(p.file_name().unwrap())).unwrap();
        }
        to
    };
    let version = copy("version");
    let report = std::fs::read_to_string(version.join("report.json")).unwrap();
    std::fs::write(
        version.join("report.json"),
        report.replacen("\"model_format\": 1", "\"model_format\": 99", 1),
    )
    .unwrap();
    let no_kinematics = copy("no-kinematics");
    std::fs::remove_file(no_kinematics.join("kinematics.toml")).unwrap();
    let no_report = copy("no-report");
    std::fs::remove_file(no_report.join("report.json")).unwrap();
    let bad_compliance = copy("bad-compliance");
    write(
        &bad_compliance,
        "compliance.toml",
        "gravity = [0.0, 0.0, -9.8]\npayload_com = [0.0, 0.0, 0.0]\ncompliance = [1.0, 2.0]\n",
    );
    let bad_residual = copy("bad-residual");
    write(&bad_residual, "residual.json", "{\"residual_format\": 1}\n");
    let model_cases: &[(&PathBuf, &[&str])] = &[
        (&version, &["report.json", "model_format", "99"]),
        (&no_kinematics, &["kinematics.toml"]),
        (&no_report, &["report.json"]),
        (
            &bad_compliance,
            &["compliance.toml", "compliance", "6 joints"],
        ),
        (&bad_residual, &["residual.json"]),
    ];
    for (dir, needles) in model_cases {
        let label = s(dir);
        fails(
            label,
            &[
                "predict",
                "--model",
                s(dir),
                "--data",
                s(good),
                "--out",
                s(pred),
            ],
            needles,
            outs,
        );
        fails(
            label,
            &["evaluate", "--model", s(dir), "--data", s(good)],
            needles,
            outs,
        );
    }
}

/// Targets CSV.
fn bad_target_files(f: &Fixture) {
    let Fixture {
        d,
        outs,
        commands,
        model,
        ..
    } = f;
    let target_header = "id,q1,q2,q3,q4,q5,q6,load,x,y,z";
    let target_cases: &[(&str, String, &[&str])] = &[
        (
            "targets-missing.csv",
            "id,q1,q2,q3,q4,q5,q6,load,x,y\nt,0,0,0,0,0,0,0,1,2\n".into(),
            &["targets-missing.csv", "`z`"],
        ),
        (
            "targets-text.csv",
            format!("{target_header}\nt,0,0,0,0,0,zero,0,1,2,3\n"),
            &["targets-text.csv", "line 2", "`q6`"],
        ),
        (
            "targets-nan.csv",
            format!("{target_header}\nt,0,0,0,0,0,0,nan,1,2,3\n"),
            &["targets-nan.csv", "line 2", "`load`"],
        ),
        (
            "targets-twice.csv",
            format!("{target_header}\nt,0,0,0,0,0,0,0,1,2,3\nt,0,0,0,0,0,0,0,1,2,3\n"),
            &["targets-twice.csv", "line 3", "`t`"],
        ),
    ];
    for (name, text, needles) in target_cases {
        let targets = write(d, name, text);
        fails(
            name,
            &[
                "compensate",
                "--model",
                s(model),
                "--targets",
                s(&targets),
                "--out",
                s(commands),
            ],
            needles,
            outs,
        );
    }
}

/// Twin and experiment configs.
fn bad_twin_and_experiment_files(f: &Fixture) {
    let Fixture {
        d, outs, sim_out, ..
    } = f;
    let twin_cases: &[(&str, &str, &[&str])] = &[
        ("twin-empty.toml", "", &["twin-empty.toml", "line 1"]),
        (
            "twin-type.toml",
            "name = 3\n",
            &["twin-type.toml", "line 1"],
        ),
    ];
    for (name, text, needles) in twin_cases {
        let twin = write(d, name, text);
        fails(
            name,
            &["simulate", "--twin", s(&twin), "--out", s(sim_out)],
            needles,
            outs,
        );
    }
    let experiment_cases: &[(&str, &str, &[&str])] = &[
        (
            "exp-unknown.toml",
            "name = \"e\"\ncolour = \"red\"\n",
            &["exp-unknown.toml", "colour"],
        ),
        (
            "exp-type.toml",
            "name = \"e\"\nseed = \"x\"\n",
            &["exp-type.toml", "line 2"],
        ),
        (
            "exp-model.toml",
            "name = \"e\"\n[data]\ntwin = \"twin.toml\"\n[[model]]\nname = \"m\"\ncompliance = { joints = [0] }\n",
            &["exp-model.toml", "model[1].compliance.joints"],
        ),
    ];
    for (name, text, needles) in experiment_cases {
        let experiment = write(d, name, text);
        fails(
            name,
            &["run", s(&experiment), "--out", s(&outs.join("reports"))],
            needles,
            outs,
        );
    }
}

#[test]
fn the_same_inputs_give_byte_identical_models_predictions_and_commands() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // 30 configurations at 0 and 20 kg of the bundled twin rows.
    let data = select_rows(&twin_rows(), |pose, load| {
        pose < 30 && (load == 0.0 || load == 20.0)
    });
    let data = write(d, "data.csv", &data);
    let stage = write(
        d,
        "stage.toml",
        "[kinematic]\nsolver = \"lm\"\n[compliance]\npayload_com = [100.0, 0.0, 60.0]\n\
         [residual]\nmodel = \"ca-somm\"\nseed = 7\n\
         [residual.x]\nhidden = [6]\nactivation = \"tanh\"\nlearning_rate = 1e-3\nmax_epochs = 4\n\
         [residual.y]\nhidden = [6]\nactivation = \"tanh\"\nlearning_rate = 1e-3\nmax_epochs = 4\n\
         [residual.z]\nhidden = [6]\nactivation = \"tanh\"\nlearning_rate = 1e-3\nmax_epochs = 4\n\
         [residual.classifier]\nmin_samples_leaf = 5\n",
    );
    let targets = {
        let mut t = String::from("id,q1,q2,q3,q4,q5,q6,load,x,y,z\n");
        for (k, line) in std::fs::read_to_string(&data)
            .unwrap()
            .lines()
            .skip(1)
            .step_by(9)
            .enumerate()
        {
            let v: Vec<&str> = line.split(',').collect();
            t += &format!(
                "t{k},{},{},{},{},{}\n",
                v[1..7].join(","),
                v[7],
                v[8],
                v[9],
                v[10]
            );
        }
        write(d, "targets.csv", &t)
    };
    let run = |tag: &str| -> Vec<(String, Vec<u8>)> {
        let model = d.join(format!("model-{tag}"));
        let pred = d.join(format!("pred-{tag}.csv"));
        let commands = d.join(format!("commands-{tag}.csv"));
        for args in [
            vec![
                "calibrate",
                "--robot",
                ROBOT,
                "--data",
                s(&data),
                "--out",
                s(&model),
                "--config",
                s(&stage),
            ],
            vec![
                "predict",
                "--model",
                s(&model),
                "--data",
                s(&data),
                "--out",
                s(&pred),
            ],
            vec![
                "compensate",
                "--model",
                s(&model),
                "--targets",
                s(&targets),
                "--out",
                s(&commands),
            ],
        ] {
            let o = robocal(&args);
            assert!(
                o.status.success(),
                "{args:?}: {}",
                String::from_utf8_lossy(&o.stderr)
            );
        }
        let mut files: Vec<(String, Vec<u8>)> = snapshot(&model)
            .into_iter()
            .map(|(p, b)| (p.file_name().unwrap().to_string_lossy().into_owned(), b))
            .collect();
        files.push(("pred".into(), std::fs::read(&pred).unwrap()));
        files.push(("commands".into(), std::fs::read(&commands).unwrap()));
        files
    };
    let (a, b) = (run("a"), run("b"));
    let names: Vec<&str> = a.iter().map(|(n, _)| n.as_str()).collect();
    for wanted in [
        "kinematics.toml",
        "compliance.toml",
        "residual.json",
        "report.json",
        "pred",
        "commands",
    ] {
        assert!(names.contains(&wanted), "{names:?}");
    }
    assert_eq!(a.len(), b.len());
    for ((na, ba), (nb, bb)) in a.iter().zip(&b) {
        assert_eq!(na, nb);
        assert!(ba == bb, "{na} differs between two runs");
    }
}

/// The default calibration on a small case (every 4th configuration of the bundled twin at two
/// loads, far under its time budget) writes the same model files on one core as on every core:
/// its folds are fitted and trained in fold order and reduced in that order.
#[test]
fn the_default_writes_the_same_model_on_one_core_as_on_all() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let data = select_rows(&twin_rows(), |pose, load| {
        pose % 4 == 0 && (load == 0.0 || load == 20.0)
    });
    let data = write(d, "data.csv", &data);
    let run = |threads: Option<&str>| -> Vec<(PathBuf, Vec<u8>)> {
        let model = d.join(format!("model-{}", threads.unwrap_or("all")));
        let mut command = std::process::Command::new(env!("CARGO_BIN_EXE_robocal"));
        command.current_dir(env!("CARGO_MANIFEST_DIR")).args([
            "calibrate",
            "--robot",
            ROBOT,
            "--data",
            s(&data),
            "--out",
            s(&model),
        ]);
        match threads {
            Some(n) => command.env("RAYON_NUM_THREADS", n),
            None => command.env_remove("RAYON_NUM_THREADS"),
        };
        let o = command.output().unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        // report.json holds the seconds each candidate took.
        (snapshot(&model).into_iter())
            .filter(|(p, _)| p.file_name().is_some_and(|n| n != "report.json"))
            .collect()
    };
    let (one, all) = (run(Some("1")), run(None));
    let names: Vec<_> = one.iter().map(|(p, _)| p.file_name().unwrap()).collect();
    assert!(names.iter().any(|n| *n == "kinematics.toml"), "{names:?}");
    assert_eq!(one.len(), all.len(), "{names:?}");
    for ((a, x), (b, y)) in one.iter().zip(&all) {
        assert_eq!(a.file_name(), b.file_name());
        assert!(x == y, "{} differs between one core and all", a.display());
    }
}
