//! The model directory: a round trip keeps every prediction, and directories written by
//! another layout version, or whose parts do not fit, are refused with the file named.

use std::path::{Path, PathBuf};

use nalgebra::Vector3;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use robocal_data::{Sample, Silent};
use robocal_model::{CalibratedModel, JointErrors, ModelError};
use robocal_residual::{ResidualModel, ResidualSettings, Samples};
use robocal_robot::Robot;

fn robot() -> Robot {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    Robot::load(root.join("configs/robots/pmc6va030.toml")).unwrap()
}

fn samples(n: usize, seed: u64) -> Vec<Sample> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    (0..n)
        .map(|i| Sample {
            pose: format!("p{i}"),
            joints: (0..6).map(|_| rng.random_range(-60.0..60.0)).collect(),
            load: rng.random_range(0.0..20.0),
            line: 0,
            target: String::new(),
        })
        .collect()
}

/// A model with every part: compliance, harmonics and self-weight terms, and a GP residual
/// trained on a smooth made-up error.
fn full_model() -> CalibratedModel {
    let robot = robot();
    let values = [0.0, 0.08, 0.14, 0.38, 0.48, 0.57]
        .iter()
        .map(|c| c * robocal_robot::DEG_PER_KNM)
        .collect();
    let mut errors = JointErrors::new(
        values,
        Vector3::new(0.0, 0.0, -9.80665),
        Vector3::new(100.0, 0.0, 60.0),
    )
    .with_harmonics(&[0, 3], 2);
    for (i, p) in errors.params().into_iter().enumerate() {
        if errors.param_name(p).contains(".h") {
            errors.set_param(p, 1e-4 * (i as f64 + 1.0));
        }
    }
    let train = samples(60, 1);
    let set = Samples {
        inputs: train.iter().map(robocal_residual::inputs_of).collect(),
        errors: train
            .iter()
            .map(|s| {
                let q = s.joints_rad();
                [0.05 * q[0].sin(), 0.03 * q[1].cos(), 0.01 * s.load]
            })
            .collect(),
        physics: Vec::new(),
    };
    let mut settings = ResidualSettings::gp(7);
    settings.gp.iterations = 10;
    let residual = ResidualModel::fit(&settings, &set, &Samples::default(), &Silent).unwrap();
    CalibratedModel::new(robot, Some(errors), Some(residual))
}

fn dir() -> (tempfile::TempDir, PathBuf) {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("model");
    (tmp, out)
}

#[test]
fn a_saved_model_predicts_what_it_predicted_before() {
    let mut model = full_model();
    // The registered nominal table travels with the model, unchanged.
    let mut nominal = robot();
    nominal.base.xyz.x += 12.5;
    model.nominal = Some(nominal);
    let (_tmp, out) = dir();
    model
        .save(&out, &serde_json::json!({"note": "a test"}))
        .unwrap();
    let back = CalibratedModel::load(&out).unwrap();
    let poses = samples(25, 2);
    let (a, sa) = model.predict_with_sigma(&poses, true);
    let (b, sb) = back.predict_with_sigma(&poses, true);
    assert_eq!(a, b);
    assert_eq!(sa.unwrap(), sb.unwrap());
    // The single-point path (compensation's) is the batch path.
    for (s, p) in poses.iter().zip(&a) {
        assert!((back.point(&s.joints_rad(), s.load) - p).norm() < 1e-9);
        let q = s.joints_rad();
        let (n0, n1) = (model.nominal.as_ref(), back.nominal.as_ref());
        assert!((n0.unwrap().point(&q) - n1.unwrap().point(&q)).norm() < 1e-9);
    }
    // The report carries the layout version first, then the caller's fields.
    let report = std::fs::read_to_string(out.join("report.json")).unwrap();
    let keys: Vec<&str> = report.lines().skip(1).take(3).collect();
    assert_eq!(
        keys,
        [
            "  \"model_format\": 1,",
            &format!("  \"robocal_version\": \"{}\",", env!("CARGO_PKG_VERSION")),
            "  \"note\": \"a test\""
        ]
    );
}

#[test]
fn a_table_alone_writes_no_joint_error_or_residual_files() {
    let (_tmp, out) = dir();
    CalibratedModel::kinematic(robot())
        .save(&out, &serde_json::json!({}))
        .unwrap();
    let mut files: Vec<String> = std::fs::read_dir(&out)
        .unwrap()
        .map(|e| e.unwrap().file_name().into_string().unwrap())
        .collect();
    files.sort();
    assert_eq!(files, ["kinematics.toml", "report.json"]);
    let back = CalibratedModel::load(&out).unwrap();
    assert!(back.joint_errors.is_none() && back.residual.is_none());
}

#[test]
fn another_layout_version_and_misfitting_parts_are_refused() {
    let (_tmp, out) = dir();
    full_model().save(&out, &serde_json::json!({})).unwrap();
    let report = out.join("report.json");
    let text = std::fs::read_to_string(&report).unwrap();
    std::fs::write(
        &report,
        text.replace("\"model_format\": 1", "\"model_format\": 2"),
    )
    .unwrap();
    let err = CalibratedModel::load(&out).unwrap_err();
    assert!(matches!(err, ModelError::Format { found: 2, .. }), "{err}");
    assert!(err.to_string().contains("report.json: key `model_format`"));
    std::fs::write(&report, text.replace("\"model_format\": 1,", "")).unwrap();
    assert!(matches!(
        CalibratedModel::load(&out).unwrap_err(),
        ModelError::NoFormat { .. }
    ));
    std::fs::write(&report, &text).unwrap();
    // A 5-joint table with the 6-joint residual model.
    let kin = out.join("kinematics.toml");
    let table = std::fs::read_to_string(&kin).unwrap();
    let last = table.rfind("[[joint]]").unwrap();
    let end = table[last + 9..]
        .find("\n[")
        .map_or(table.len(), |e| last + 9 + e + 1);
    std::fs::write(&kin, format!("{}{}", &table[..last], &table[end..])).unwrap();
    std::fs::remove_file(out.join("compliance.toml")).unwrap();
    let err = CalibratedModel::load(&out).unwrap_err();
    assert!(
        matches!(
            err,
            ModelError::Inputs {
                inputs: 7,
                joints: 5,
                ..
            }
        ),
        "{err}"
    );
    assert!(matches!(
        CalibratedModel::load(&out.join("nothing")).unwrap_err(),
        ModelError::NotFound { .. }
    ));
}
