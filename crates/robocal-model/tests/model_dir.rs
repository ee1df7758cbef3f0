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
            seq: None,
            last_move: Vec::new(),
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

/// The domain (the joint readings and loads calibrated on): computed from the rows, kept by the
/// directory's round trip, absent from a directory written without it; the warning counts the
/// rows outside, names each joint with its farthest reading and how far beyond (recomputed
/// here), the load, and the first row; none for rows inside; a bad `domain.toml` is refused with
/// its file and key.
#[test]
fn the_calibrated_domain_round_trips_and_warns_of_rows_outside() {
    use robocal_model::{DOMAIN_FILE, Domain};
    let rows = samples(40, 7);
    let domain = Domain::of(&rows).unwrap();
    for j in 0..6 {
        let lo = rows
            .iter()
            .map(|s| s.joints[j])
            .fold(f64::INFINITY, f64::min);
        let hi = (rows.iter().map(|s| s.joints[j])).fold(f64::NEG_INFINITY, f64::max);
        assert_eq!(domain.joints[j], [lo, hi]);
    }
    assert!(Domain::of(&[] as &[Sample]).is_none());
    let (_tmp, out) = dir();
    let mut model = CalibratedModel::kinematic(robot());
    model.domain = Some(domain.clone());
    model.save(&out, &serde_json::json!({})).unwrap();
    assert_eq!(
        CalibratedModel::load(&out).unwrap().domain,
        Some(domain.clone())
    );
    // Inside: no warning; nor within a compensation's correction of a range's end (a joint
    // held at one reading, then commanded a few thousandths of a degree off it).
    let file = Path::new("held.csv");
    assert_eq!(domain.warning(file, &rows), None);
    let mut near = rows[..3].to_vec();
    near[0].joints[4] = domain.joints[4][0] - 0.0009;
    near[2].joints[0] = domain.joints[0][1] + 0.9 * robocal_model::WARN_BEYOND_DEG;
    assert_eq!(domain.warning(file, &near), None);
    near[2].joints[0] = domain.joints[0][1] + 1.1 * robocal_model::WARN_BEYOND_DEG;
    let w = domain.warning(file, &near).unwrap();
    assert!(w.starts_with("held.csv: 1 of 3 rows lie outside"), "{w}");
    // Two rows beyond joint 2's range, one of them also beyond the loads.
    let [lo2, hi2] = domain.joints[1];
    let mut outside = rows[..5].to_vec();
    outside[1].joints[1] = hi2 + 12.5;
    outside[1].line = 17;
    outside[1].pose = "far".into();
    outside[3].joints[1] = lo2 - 3.0;
    outside[3].load = domain.load[1] + 2.0;
    let w = domain.warning(file, &outside).unwrap();
    assert!(w.starts_with("held.csv: 2 of 5 rows lie outside"), "{w}");
    assert!(
        w.contains(&format!(
            "q2 on 2 (up to {}°, 12.5° beyond",
            ((hi2 + 12.5) * 1e4).round() / 1e4
        )),
        "{w}"
    );
    assert!(
        w.contains("load on 1") && w.contains("2.000 kg beyond"),
        "{w}"
    );
    assert!(
        w.contains("first: line 17, pose `far`") && !w.contains("q1 on"),
        "{w}"
    );
    // A directory without the file loads with no domain; a reversed range is refused.
    std::fs::remove_file(out.join(DOMAIN_FILE)).unwrap();
    assert_eq!(CalibratedModel::load(&out).unwrap().domain, None);
    let mut bad = domain.clone();
    bad.joints[3] = [10.0, -10.0];
    std::fs::write(out.join(DOMAIN_FILE), bad.to_toml_string()).unwrap();
    let err = CalibratedModel::load(&out).unwrap_err().to_string();
    assert!(
        err.contains(DOMAIN_FILE) && err.contains("joints[4]"),
        "{err}"
    );
    bad.joints.pop();
    std::fs::write(out.join(DOMAIN_FILE), bad.to_toml_string()).unwrap();
    let err = CalibratedModel::load(&out).unwrap_err().to_string();
    assert!(err.contains("5 ranges for a robot with 6 joints"), "{err}");
    std::fs::write(out.join(DOMAIN_FILE), "joints = 3\n").unwrap();
    let err = CalibratedModel::load(&out).unwrap_err().to_string();
    assert!(err.contains(DOMAIN_FILE) && err.contains("line 1"), "{err}");
}

/// A physical model with a covariance over some table entries and joint-error coefficients.
fn physical_model_with_covariance() -> CalibratedModel {
    let CalibratedModel {
        robot,
        joint_errors,
        ..
    } = full_model();
    let names = ["j2.a", "j3.d", "base.x", "j2.compliance", "j4.h1.cos"];
    let k = names.len();
    // A positive definite matrix with correlations, internal units (mm², rad², ...).
    let sd = [0.02, 0.015, 0.05, 1e-8, 2e-5];
    let m = nalgebra::DMatrix::from_fn(k, k, |i, j| {
        let rho = if i == j { 1.0 } else { 0.3 };
        rho * sd[i] * sd[j]
    });
    CalibratedModel {
        covariance: Some(robocal_robot::ParameterCovariance::new(
            names.iter().map(|n| n.to_string()).collect(),
            &m,
        )),
        ..CalibratedModel::new(robot, joint_errors, None)
    }
}

#[test]
fn the_covariance_round_trips_and_a_bad_one_is_refused_with_its_key() {
    let model = physical_model_with_covariance();
    let poses = samples(12, 5);
    let (points, sigmas) = model.predict_with_sigma(&poses, true);
    let sigmas = sigmas.expect("a physical model with a covariance gives deviations");
    assert!(
        sigmas.iter().all(|s| s.is_finite() && *s > 0.0),
        "{sigmas:?}"
    );
    // Without `sigma`, none; without a covariance, none.
    assert!(model.predict_with_sigma(&poses, false).1.is_none());
    let bare = CalibratedModel {
        covariance: None,
        ..model.clone()
    };
    assert!(bare.predict_with_sigma(&poses, true).1.is_none());
    let (_tmp, out) = dir();
    model.save(&out, &serde_json::json!({})).unwrap();
    let back = CalibratedModel::load(&out).unwrap();
    assert_eq!(back.covariance, model.covariance);
    let (p, s) = back.predict_with_sigma(&poses, true);
    assert_eq!(p, points);
    assert_eq!(s.unwrap(), sigmas);
    // Faults, each named with the file and the key.
    let file = out.join("covariance.json");
    let text = std::fs::read_to_string(&file).unwrap();
    let refused = |text: &str, key: &str| {
        std::fs::write(&file, text).unwrap();
        let e = CalibratedModel::load(&out).unwrap_err().to_string();
        assert!(
            e.contains("covariance.json") && e.contains(&format!("key `{key}`")),
            "{e}"
        );
    };
    refused(&text.replace("\"j3.d\"", "\"j9.d\""), "parameters");
    refused(&text.replace("\"j2.a\"", "\"j3.d\""), "parameters");
    let mut asymmetric: robocal_robot::ParameterCovariance = serde_json::from_str(&text).unwrap();
    asymmetric.matrix[0][1] *= 2.0;
    refused(&serde_json::to_string(&asymmetric).unwrap(), "matrix");
    // Not JSON of its form: the file named.
    std::fs::write(&file, "{\"parameters\": [").unwrap();
    let e = CalibratedModel::load(&out).unwrap_err().to_string();
    assert!(e.contains("covariance.json"), "{e}");
    // A directory without it reads as before: no deviations for a physical model.
    std::fs::remove_file(&file).unwrap();
    let old = CalibratedModel::load(&out).unwrap();
    assert!(old.covariance.is_none());
    assert!(old.predict_with_sigma(&poses, true).1.is_none());
}

/// The standard deviation `model`'s residual model alone gives `s` (root sum of the axes'
/// variances, mm).
fn residual_sigma(model: &CalibratedModel, s: &Sample) -> f64 {
    let rows = model.residual_rows(&[s]);
    let sd = (model.residual.as_ref().unwrap())
        .predict_with_std(&rows, true)
        .1
        .unwrap()[0];
    sd.iter().map(|v| v * v).sum::<f64>().sqrt()
}

/// Beyond a harmonic's reach the model holds it; its deviation there adds what holding may miss,
/// checked against the mean square, over a grid of the harmonics' phases, of the point moved
/// from the held harmonics to the continued ones (each order's amplitude kept): 0 within the
/// reach, the same within 1 % beyond it, and in the deviation on top of the covariance's, or of
/// a GP residual's.
#[test]
fn beyond_a_harmonics_reach_the_deviation_adds_what_holding_may_miss() {
    let mut model = physical_model_with_covariance();
    let reach = [(-30.0f64).to_radians(), 30.0f64.to_radians()];
    let amplitude = [0.02f64.to_radians(), 0.012f64.to_radians()];
    let errors = model.joint_errors.as_mut().unwrap();
    errors.harmonics.retain(|h| h.joint != 0);
    for (k, a) in amplitude.iter().enumerate() {
        errors.harmonics.push(robocal_robot::Harmonic {
            joint: 0,
            order: k as u32 + 1,
            sin: a * 0.6,
            cos: a * 0.8,
            reach: Some(reach),
        });
    }
    let at = |q1: f64| Sample {
        joints: vec![q1, -40.0, 20.0, 35.0, 50.0, -20.0],
        ..samples(1, 3).remove(0)
    };
    let inside = at(25.0);
    assert_eq!(model.held_variance(&inside), 0.0);
    // With a GP residual on top: the GP's deviation (it learned nothing beyond its rows, and
    // knows nothing of the physics beneath it) and what holding may miss, in quadrature.
    let with_gp = CalibratedModel {
        residual: full_model().residual,
        ..model.clone()
    };
    let gp_sigma = |s: &Sample| residual_sigma(&with_gp, s);
    let stack_sigma = |s: &Sample| with_gp.predict_with_sigma([s], true).1.unwrap()[0];
    assert_eq!(stack_sigma(&inside), gp_sigma(&inside));
    let phases = 48;
    let turned = |s: &Sample, reach: Option<[f64; 2]>, p1: usize, p2: usize| {
        let mut m = model.clone();
        let hs = &mut m.joint_errors.as_mut().unwrap().harmonics;
        for h in hs.iter_mut().filter(|h| h.joint == 0) {
            let phi = std::f64::consts::TAU * [p1, p2][h.order as usize - 1] as f64 / phases as f64;
            let a = amplitude[h.order as usize - 1];
            (h.sin, h.cos, h.reach) = (a * phi.cos(), a * phi.sin(), reach);
        }
        m.base_point(s)
    };
    for q1 in [50.0, 100.0, 170.0] {
        let s = at(q1);
        let mut mean_square = 0.0;
        for p1 in 0..phases {
            for p2 in 0..phases {
                let miss = turned(&s, None, p1, p2) - turned(&s, Some(reach), p1, p2);
                mean_square += miss.norm_squared() / (phases * phases) as f64;
            }
        }
        let held = model.held_variance(&s);
        assert!(
            (held - mean_square).abs() < 0.01 * mean_square && held > 1e-4,
            "q1 {q1}°: {held} mm² against {mean_square}"
        );
        let (stack, gp) = (stack_sigma(&s), gp_sigma(&s));
        assert!(
            (stack * stack - gp * gp - held).abs() < 1e-9 * held,
            "q1 {q1}°: σ {stack} with a GP whose own is {gp}, held variance {held}"
        );
        let sigma = |m: &CalibratedModel| m.physics_sigmas(&[&s]).unwrap()[0];
        let mut unheld = model.clone();
        for h in &mut unheld.joint_errors.as_mut().unwrap().harmonics {
            h.reach = None;
        }
        let (with, without) = (sigma(&model), sigma(&unheld));
        assert!(
            (with * with - without * without - held).abs() < 0.01 * held,
            "q1 {q1}°: σ {with} with, {without} continued, held variance {held}"
        );
    }
}

/// A GP residual's deviation is calibrated within the readings and loads the model was fitted
/// on; outside them the physics' own deviation grows, and that growth is added: at a point
/// outside, `σ² − σ_GP²` is the physical model's variance there less that at the nearest point
/// inside (here a payload three times the heaviest, the compliance's spread carried further);
/// inside, the GP's deviation alone.
#[test]
fn outside_the_domain_a_gps_deviation_adds_the_growth_of_the_physics() {
    let physical = CalibratedModel {
        domain: Some(robocal_model::Domain {
            joints: vec![[-60.0, 60.0]; 6],
            load: [0.0, 20.0],
        }),
        ..physical_model_with_covariance()
    };
    let with_gp = CalibratedModel {
        residual: full_model().residual,
        ..physical.clone()
    };
    let gp_sigma = |s: &Sample| residual_sigma(&with_gp, s);
    let inside = Sample {
        joints: vec![25.0, -40.0, 20.0, 35.0, 50.0, -20.0],
        load: 15.0,
        ..samples(1, 3).remove(0)
    };
    let outside = Sample {
        joints: vec![25.0, -40.0, 20.0, 35.0, 50.0, -20.0],
        load: 60.0,
        ..inside.clone()
    };
    let nearest = Sample {
        load: 20.0,
        ..outside.clone()
    };
    let sigmas = with_gp
        .predict_with_sigma([&inside, &outside], true)
        .1
        .unwrap();
    // (The GP's batch of two and its single row agree to rounding.)
    assert!((sigmas[0] - gp_sigma(&inside)).abs() < 1e-12 * sigmas[0]);
    let phys = |s: &Sample| physical.physics_sigmas(&[s]).unwrap()[0];
    let growth = phys(&outside).powi(2) - phys(&nearest).powi(2);
    assert!(growth > 1e-6, "{growth}");
    let added = sigmas[1].powi(2) - gp_sigma(&outside).powi(2);
    assert!(
        (added - growth).abs() < 1e-9 * growth.max(1e-12) + 1e-15,
        "{added} added, growth {growth}"
    );
}
