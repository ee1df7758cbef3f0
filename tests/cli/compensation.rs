//! Compensation toward a robot program: targets in the world (tracker) frame, the robot base
//! frame or a user frame give the same commands; a production tool point other than the
//! reflector is put on the targets.

use std::path::Path;

use nalgebra::Vector3;
use robocal_robot::{Robot, rpy_to_matrix};

use crate::common::{robocal, s, select_rows, twin_rows, write};

/// The commands file as (id, joints deg).
fn commands(path: &Path) -> Vec<(String, Vec<f64>)> {
    let text = std::fs::read_to_string(path).unwrap();
    text.lines()
        .skip(1)
        .map(|l| {
            let mut f = l.split(',');
            let id = f.next().unwrap().to_string();
            (id, f.map(|v| v.parse().unwrap()).collect())
        })
        .collect()
}

#[test]
fn targets_in_any_frame_and_a_production_tool_give_the_commands_they_should() {
    let dir = tempfile::tempdir().unwrap();
    let data = write(
        dir.path(),
        "train.csv",
        &select_rows(&twin_rows(), |pose, load| pose % 3 == 0 && load == 0.0),
    );
    let model = dir.path().join("model");
    let o = robocal(&[
        "calibrate",
        "--robot",
        "configs/robots/pmc6va030.toml",
        "--data",
        s(&data),
        "--out",
        s(&model),
        "--config",
        "configs/stages/kinematic-lm.toml",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let robot = Robot::load(model.join("kinematics.toml")).unwrap();
    // Five targets near measured rows, in the world frame, each row's reading the seed.
    let rows: Vec<Vec<f64>> = std::fs::read_to_string(&data)
        .unwrap()
        .lines()
        .skip(1)
        .step_by(9)
        .take(5)
        .map(|l| l.split(',').skip(1).map(|v| v.parse().unwrap()).collect())
        .collect();
    let world: Vec<Vector3<f64>> = rows
        .iter()
        .map(|r| Vector3::new(r[7] + 1.5, r[8] - 2.0, r[9] + 1.0))
        .collect();
    let targets = |name: &str, points: &[Vector3<f64>]| {
        let mut text = String::from("id,q1,q2,q3,q4,q5,q6,load,x,y,z\n");
        for (i, (r, p)) in rows.iter().zip(points).enumerate() {
            let q: Vec<String> = r[..6].iter().map(|v| v.to_string()).collect();
            text += &format!("t{i},{},0,{},{},{}\n", q.join(","), p.x, p.y, p.z);
        }
        write(dir.path(), name, &text)
    };
    let run = |name: &str, file: &Path, extra: &[&str]| {
        let out = dir.path().join(name);
        let mut args = vec![
            "compensate",
            "--model",
            s(&model),
            "--targets",
            s(file),
            "--out",
            s(&out),
        ];
        args.extend(extra);
        let o = robocal(&args);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        commands(&out)
    };
    let in_world = run("world.csv", &targets("world-targets.csv", &world), &[]);
    // The same points in the calibrated base frame {0}.
    let (rb, tb) = (robot.base_rotation(), robot.base.xyz);
    let base: Vec<Vector3<f64>> = world.iter().map(|p| rb.transpose() * (p - tb)).collect();
    let in_base = run(
        "base.csv",
        &targets("base-targets.csv", &base),
        &["--frame", "base"],
    );
    // And in a user frame 100, -50, 20 mm and 30° about z from {0}.
    let ru = rpy_to_matrix(&Vector3::new(0.0, 0.0, 30f64.to_radians()));
    let tu = Vector3::new(100.0, -50.0, 20.0);
    let user: Vec<Vector3<f64>> = base.iter().map(|p| ru.transpose() * (p - tu)).collect();
    let frame = write(
        dir.path(),
        "user.toml",
        "xyz = [100.0, -50.0, 20.0]\nrpy = [0.0, 0.0, 30.0]\n",
    );
    let in_user = run(
        "user.csv",
        &targets("user-targets.csv", &user),
        &["--frame", s(&frame)],
    );
    assert_eq!(in_world.len(), 5);
    for other in [&in_base, &in_user] {
        for ((a, qa), (b, qb)) in in_world.iter().zip(other) {
            assert_eq!(a, b);
            for (x, y) in qa.iter().zip(qb) {
                assert!((x - y).abs() < 1e-4, "{qa:?} vs {qb:?}");
            }
        }
    }
    // A production tool 250 mm out along the flange z: its point lands on the targets.
    let with_tool = run(
        "tool.csv",
        &targets("tool-targets.csv", &world),
        &["--tool", "0,0,250"],
    );
    let mut tooled = robot.clone();
    tooled.tool = Vector3::new(0.0, 0.0, 250.0);
    for ((_, q), p) in with_tool.iter().zip(&world) {
        let rad: Vec<f64> = q.iter().map(|v| v.to_radians()).collect();
        assert!(
            (tooled.point(&rad) - p).norm() < 2e-3,
            "{}",
            (tooled.point(&rad) - p).norm()
        );
    }
    // A bad tool or frame is an error naming the option.
    let o = robocal(&[
        "compensate",
        "--model",
        s(&model),
        "--targets",
        s(&targets("t.csv", &world)),
        "--out",
        s(&dir.path().join("x.csv")),
        "--tool",
        "0,0",
    ]);
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("--tool 0,0"));
}
