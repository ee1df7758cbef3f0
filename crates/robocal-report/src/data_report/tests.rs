use nalgebra::Vector3;

use super::stats::{rank_correlation, ranks};
use super::*;
use robocal_data::Sample;
use robocal_robot::Robot;

/// Errors drawn as the deviations say (isotropic, three axes): the check's shares near the
/// χ²₃ values it states; a ranking by hand; σ of none is no check.
#[test]
fn the_sigma_check_states_what_errors_drawn_as_sigma_says_give() {
    use rand::SeedableRng;
    use rand_distr::{Distribution, Normal};
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
    let unit = Normal::new(0.0, 1.0).unwrap();
    let sigmas: Vec<f64> = (0..20000)
        .map(|i| 0.01 + 0.0001 * (i % 100) as f64)
        .collect();
    let errors: Vec<f64> = (sigmas.iter())
        .map(|s| {
            let v: f64 = (0..3).map(|_| f64::powi(unit.sample(&mut rng), 2)).sum();
            s * (v / 3.0).sqrt()
        })
        .collect();
    let c = sigma_check(&errors, &sigmas).unwrap();
    assert!((c.ratio_rms - 1.0).abs() < 0.02, "{c:?}");
    assert!((c.within_one - 0.608).abs() < 0.01, "{c:?}");
    assert!((c.within_two - 0.9926).abs() < 0.003, "{c:?}");
    assert!(
        c.rank_correlation > 0.1 && c.rank_correlation < 0.6,
        "{c:?}"
    );
    // Ranks with a tie, and correlations of ±1.
    assert_eq!(ranks(&[3.0, 1.0, 3.0, 2.0]), vec![2.5, 0.0, 2.5, 1.0]);
    let up = [0.1, 0.2, 0.5, 0.9];
    assert!((rank_correlation(&up, &[1.0, 2.0, 3.0, 40.0]) - 1.0).abs() < 1e-12);
    assert!((rank_correlation(&up, &[4.0, 3.0, 2.0, 1.0]) + 1.0).abs() < 1e-12);
    let c = sigma_check(&[0.1, 0.3], &[0.2, 0.1]).unwrap();
    assert_eq!((c.within_one, c.within_two), (0.5, 0.5));
    assert!((c.ratio_rms - ((0.25f64 + 9.0) / 2.0).sqrt()).abs() < 1e-12);
    assert!(sigma_check(&[0.1], &[0.0]).is_none());
}

fn rows(robot: &Robot) -> Vec<Measurement> {
    (0..12)
        .flat_map(|i| {
            let joints: Vec<f64> = (0..robot.dof())
                .map(|j| 10.0 * ((i * 7 + j * 3) % 9) as f64 - 40.0)
                .collect();
            [0.0, 5.0].map(|load| {
                let q: Vec<f64> = joints.iter().map(|d| d.to_radians()).collect();
                Measurement {
                    position: robot.point(&q) + Vector3::new(0.1 * i as f64, 0.0, 0.02),
                    orientation: None,
                    sample: Sample {
                        pose: format!("p{i}"),
                        joints: joints.clone(),
                        load,
                        line: 2 + i as u64,
                        target: String::new(),
                        seq: None,
                        last_move: Vec::new(),
                    },
                }
            })
        })
        .collect()
}

/// The model's parts name the payload compliance only where a joint has one: a model whose
/// compliance stage was skipped (one load) holds joint errors without it.
#[test]
fn the_parts_name_the_payload_compliance_only_where_a_joint_has_one() {
    let robot = Robot::load(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../../configs/robots/pmc6va030.toml"),
    )
    .unwrap();
    let mut model = CalibratedModel::kinematic(robot);
    let mut errors = robocal_robot::JointErrors::new(
        vec![0.0; 6],
        Vector3::new(0.0, 0.0, -9.80665),
        Vector3::zeros(),
    );
    errors.harmonics.push(robocal_robot::Harmonic::zero(0, 1));
    model.joint_errors = Some(errors.clone());
    assert_eq!(parts(&model)[1], "joint errors: transmission harmonics");
    errors.values[1] = 1e-6;
    model.joint_errors = Some(errors);
    assert_eq!(
        parts(&model)[1],
        "joint errors: payload compliance, transmission harmonics"
    );
}

#[test]
fn a_model_without_its_nominal_table_is_reported_after_calibration_only() {
    let robot = Robot::load(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../../configs/robots/pmc6va030.toml"),
    )
    .unwrap();
    let rows = rows(&robot);
    let refs: Vec<&Measurement> = rows.iter().collect();
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("r");
    let model = CalibratedModel::kinematic(robot);
    let r = write_data_report(
        &model,
        "m",
        Path::new("d.csv"),
        &refs,
        DataRole::HeldOut,
        &out,
    )
    .unwrap();
    assert!(r.before.is_none() && r.kinematic.is_none());
    assert_eq!(
        (r.rows, r.configurations, r.loads.clone()),
        (24, 12, vec![0.0, 5.0])
    );
    // The offsets put in: x grows with the pose, z is a constant bias of 0.02.
    assert!((r.axes[2].mean - 0.02).abs() < 1e-9 && r.axes[2].std < 1e-9);
    assert!((r.worst[0].error - (1.1f64.powi(2) + 0.02f64.powi(2)).sqrt()).abs() < 1e-9);
    assert_eq!(r.figures.len(), 5);
    assert!(r.figures.iter().any(|f| f.stem == "load"));
    // The same rows at one load: no figure against the load (one stripe on an axis around it).
    let light: Vec<&Measurement> = rows.iter().filter(|m| m.sample.load == 0.0).collect();
    let one = dir.path().join("one");
    let r1 = write_data_report(
        &model,
        "m",
        Path::new("d.csv"),
        &light,
        DataRole::HeldOut,
        &one,
    )
    .unwrap();
    let stems: Vec<&str> = r1.figures.iter().map(|f| f.stem.as_str()).collect();
    assert_eq!(stems, ["histogram", "per-pose", "axes-joints", "workspace"]);
    assert!(!one.join("load.png").exists());
    let md = std::fs::read_to_string(out.join("report.md")).unwrap();
    assert!(md.contains("shown after calibration only"), "{md}");
    assert!(
        r.by_target.is_empty() && !md.contains("Per reflector"),
        "{md}"
    );
    // Nothing is written for no rows.
    let empty = dir.path().join("e");
    assert!(
        write_data_report(
            &model,
            "m",
            Path::new("d.csv"),
            &[],
            DataRole::HeldOut,
            &empty
        )
        .is_err()
    );
    assert!(!empty.exists());
}
