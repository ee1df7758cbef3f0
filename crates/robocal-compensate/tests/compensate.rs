//! Compensation checked through the model it inverts, and against the twin's true robot: the
//! compensated commands, executed by the twin without noise, land nearer the targets.

use std::path::{Path, PathBuf};

use nalgebra::Vector3;
use robocal_compensate::{CompensationOptions, Failure, compensate};
use robocal_data::MeasurementSet;
use robocal_ident::{ComplianceSettings, KinematicSettings, Observations, calibrate_kinematics};
use robocal_model::CalibratedModel;
use robocal_robot::{IkOptions, IkTarget, Robot};
use robocal_twin::TwinConfig;

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

fn rad(deg: &[f64]) -> Vec<f64> {
    deg.iter().map(|d| d.to_radians()).collect()
}

/// The twin, its nominal table registered to the tracker (what a program's commands come from)
/// and the LM calibration on the unloaded bundled rows.
fn setup() -> (TwinConfig, MeasurementSet, Robot, Robot) {
    let twin = TwinConfig::load(root().join("configs/twin/pmc6va030.toml")).unwrap();
    let data = MeasurementSet::read(root().join("datasets/pmc6va030/measurements.csv"), 6).unwrap();
    let obs = Observations::from_rows(6, data.rows.iter().filter(|r| r.sample.load == 0.0));
    let cal = calibrate_kinematics(&twin.nominal, &obs, &KinematicSettings::default()).unwrap();
    (twin, data, cal.aligned, cal.robot)
}

fn mean(v: &[f64]) -> f64 {
    v.iter().sum::<f64>() / v.len() as f64
}

#[test]
fn compensated_commands_put_the_model_on_the_target_and_the_twin_near_it() {
    let (twin, data, nominal, calibrated) = setup();
    let options = CompensationOptions::default();
    let mut poses: Vec<&[f64]> = data
        .rows
        .iter()
        .map(|r| r.sample.joints.as_slice())
        .collect();
    poses.dedup();
    let (mut before, mut after) = (Vec::new(), Vec::new());
    for (k, seed) in poses.iter().step_by(6).enumerate() {
        let load = [0.0, 10.0][k % 2];
        // The program's command for this target: the nominal table puts the point there.
        let target = nominal.point(&rad(seed));
        let c = compensate(
            &CalibratedModel::kinematic(calibrated.clone()),
            &target,
            load,
            seed,
            &options,
        )
        .unwrap();
        let q = rad(&c.joints_deg);
        // Round trip through the model, computed here independently of compensate's own check.
        assert!(
            (calibrated.point(&q) - target).norm() < 1e-3,
            "model misses at {seed:?}"
        );
        assert!(calibrated.within_limits(&q));
        // The flange orientation the calibrated kinematics give at the seed is kept.
        let (r0, _) = calibrated.flange_frame(&rad(seed));
        let (r1, _) = calibrated.flange_frame(&q);
        assert!((r0 - r1).norm() < 1e-6);
        before.push((twin.true_point(&rad(seed), load) - target).norm());
        after.push((twin.true_point(&q, load) - target).norm());
    }
    let (b, a) = (mean(&before), mean(&after));
    let max_a = after.iter().copied().fold(0.0, f64::max);
    eprintln!(
        "twin, {} targets at 0 and 10 kg: mean {b:.3} → {a:.3} mm, max after {max_a:.3}",
        before.len()
    );
    // Measured: about 3.9 → 0.5 mm (the kinematic model leaves the load's deflection).
    assert!(a < 0.2 * b, "{b} → {a}");
    assert!(a < 0.8, "mean after {a}");
}

/// Mean error (before, after) under the twin's truth of a straight 11-point path compensated
/// through `model` at `load`, each seed the nominal table's IK from the previous point.
fn path(
    twin: &TwinConfig,
    data: &MeasurementSet,
    nominal: &Robot,
    model: &CalibratedModel,
    load: f64,
) -> (f64, f64) {
    let start = rad(&data.rows[0].sample.joints);
    let a = nominal.point(&start);
    let b = a + Vector3::new(150.0, -100.0, 80.0);
    let options = CompensationOptions::default();
    let (mut before, mut after) = (Vec::new(), Vec::new());
    let mut seed = start.clone();
    for i in 0..=10 {
        let target = a + (b - a) * (i as f64 / 10.0);
        // The program: nominal IK along the path, each point from the previous one.
        seed = nominal
            .inverse_kinematics(
                &IkTarget::Pose {
                    point: target,
                    rotation: nominal.flange_frame(&start).0,
                },
                &seed,
                &IkOptions::default(),
            )
            .unwrap();
        let seed_deg: Vec<f64> = seed.iter().map(|v| v.to_degrees()).collect();
        let c = compensate(model, &target, load, &seed_deg, &options).unwrap();
        let q = rad(&c.joints_deg);
        assert!((model.point(&q, load) - target).norm() < 1e-3);
        before.push((twin.true_point(&seed, load) - target).norm());
        after.push((twin.true_point(&q, load) - target).norm());
    }
    (mean(&before), mean(&after))
}

#[test]
fn the_compliance_model_takes_the_loads_deflection_out_of_a_compensated_path() {
    let (twin, data, nominal, rigid) = setup();
    // Elasto-geometric LM on every bundled row of every second configuration, the payload's
    // centre of mass where the twin's bracket holds it (a user knows where the load hangs).
    let mut poses: Vec<&str> = data.rows.iter().map(|r| r.sample.pose.as_str()).collect();
    poses.dedup();
    let kept: Vec<&str> = poses.iter().step_by(2).copied().collect();
    let obs = Observations::from_rows(
        6,
        (data.rows.iter()).filter(|r| kept.contains(&r.sample.pose.as_str())),
    );
    let settings = KinematicSettings {
        compliance: Some(ComplianceSettings {
            payload_com: Some(twin.masses.payload_com),
            ..ComplianceSettings::default()
        }),
        ..KinematicSettings::default()
    };
    let cal = calibrate_kinematics(&twin.nominal, &obs, &settings).unwrap();
    let elastic = CalibratedModel::new(cal.robot.clone(), cal.compliance.clone(), None);
    assert!(elastic.joint_errors.is_some());
    for load in [5.0, 15.0] {
        let (b, r) = path(
            &twin,
            &data,
            &nominal,
            &CalibratedModel::kinematic(rigid.clone()),
            load,
        );
        let (_, e) = path(&twin, &data, &nominal, &elastic, load);
        eprintln!(
            "path at {load} kg: before {b:.3}, rigid model {r:.3}, with compliance {e:.3} mm"
        );
        // Measured: 5 kg 5.61 → 0.76 (rigid); 15 kg 5.44 → 0.89 (rigid).
        assert!(e < 0.7 * r, "{load} kg: rigid {r}, with compliance {e}");
    }
}

#[test]
fn a_straight_path_at_several_loads_is_compensated_point_by_point() {
    let (twin, data, nominal, calibrated) = setup();
    let model = CalibratedModel::kinematic(calibrated.clone());
    for load in [0.0, 5.0, 15.0] {
        let (mb, ma) = path(&twin, &data, &nominal, &model, load);
        eprintln!("path at {load} kg: mean {mb:.3} → {ma:.3} mm");
        assert!(ma < 0.3 * mb, "{load} kg: {mb} → {ma}");
    }
}

#[test]
fn unreachable_targets_and_bad_seeds_are_refused() {
    let (_, _, _, calibrated) = setup();
    let options = CompensationOptions::default();
    let far = Vector3::new(1.0e5, 0.0, 0.0);
    let seed = [0.0, 10.0, 10.0, 0.0, 30.0, 0.0];
    assert!(matches!(
        compensate(
            &CalibratedModel::kinematic(calibrated.clone()),
            &far,
            0.0,
            &seed,
            &options
        ),
        Err(Failure::Unreachable { .. })
    ));
    // Said as the robot file has it: with joint limits, within them; without, plainly.
    let limited = calibrated.joints.iter().any(|j| j.limits.is_some());
    let mut free = calibrated.clone();
    for j in &mut free.joints {
        j.limits = None;
    }
    let said = |robot: &robocal_robot::Robot| {
        compensate(
            &CalibratedModel::kinematic(robot.clone()),
            &far,
            0.0,
            &seed,
            &options,
        )
        .unwrap_err()
        .to_string()
    };
    assert!(limited, "the test's arm has joint limits");
    assert!(said(&calibrated).contains("within the joint limits"));
    let plain = said(&free);
    assert!(
        plain.starts_with("not reachable: the kinematic solve") && !plain.contains("limits"),
        "{plain}"
    );
    assert!(matches!(
        compensate(
            &CalibratedModel::kinematic(calibrated.clone()),
            &far,
            0.0,
            &seed[..5],
            &options
        ),
        Err(Failure::BadSeed(_))
    ));
    let q = rad(&seed);
    let near = calibrated.point(&q);
    assert!(matches!(
        compensate(
            &CalibratedModel::kinematic(calibrated.clone()),
            &near,
            f64::NAN,
            &seed,
            &options
        ),
        Err(Failure::BadSeed(_))
    ));
    // A target the robot already reaches needs no change.
    let c = compensate(
        &CalibratedModel::kinematic(calibrated.clone()),
        &near,
        0.0,
        &seed,
        &options,
    )
    .unwrap();
    assert!(
        (CalibratedModel::kinematic(calibrated.clone()).point(&rad(&c.joints_deg), 0.0) - near)
            .norm()
            < 1e-3
    );
    for (a, b) in c.joints_deg.iter().zip(seed) {
        assert!((a - b).abs() < 1e-6, "{a} vs {b}");
    }
}

#[test]
fn a_seed_at_the_wrist_singularity_still_gets_a_command() {
    // PMC6VA030 (nominal table): with q5 = 0 the axes of joints 4 and 6 are collinear, so the
    // 6 × 6 pose Jacobian the solve starts from has rank 5. Check that first, independently.
    let robot = &Robot::load(root().join("configs/robots/pmc6va030.toml")).unwrap();
    let seed = [10.0, 15.0, 5.0, 30.0, 0.0, -20.0];
    let axes = robot.joint_axes(&rad(&seed));
    assert!(axes.axes[3].0.cross(&axes.axes[5].0).norm() < 1e-12);
    let model = CalibratedModel::kinematic(robot.clone());
    let options = CompensationOptions::default();
    let start = robot.point(&rad(&seed));
    // Small moves in every direction, one of them along the lost direction's neighbourhood:
    // damped least squares must step off the singularity, never return NaN or a wrong command.
    for offset in [
        Vector3::new(1.0, 0.0, 0.0),
        Vector3::new(0.0, 1.0, 0.0),
        Vector3::new(0.0, 0.0, 1.0),
        Vector3::new(-2.0, 3.0, -1.0),
    ] {
        let target = start + offset;
        let c = compensate(&model, &target, 0.0, &seed, &options)
            .unwrap_or_else(|why| panic!("{offset:?}: {why}"));
        let q = rad(&c.joints_deg);
        assert!(q.iter().all(|v| v.is_finite()));
        assert!((robot.point(&q) - target).norm() < options.tolerance);
        // The flange orientation of the seed is kept: the wrist turns about the collinear
        // axes, the arm does not swing round.
        let (r0, _) = robot.flange_frame(&rad(&seed));
        let (r1, _) = robot.flange_frame(&q);
        assert!((r0 - r1).norm() < 1e-6, "{offset:?}: orientation moved");
        for (a, b) in c.joints_deg.iter().zip(seed).take(3) {
            assert!((a - b).abs() < 5.0, "{offset:?}: {a} vs {b}");
        }
    }
}

/// The bundled arm's joint compliances (of the size a stiff arm has), gravity down, the payload's
/// centre of mass on the flange: the joint errors the tests below add their terms to.
fn stiff_arm() -> robocal_robot::JointErrors {
    robocal_robot::JointErrors::new(
        [0.0, 0.08, 0.14, 0.38, 0.48, 0.57]
            .iter()
            .map(|c| c * robocal_robot::DEG_PER_KNM)
            .collect(),
        Vector3::new(0.0, 0.0, -9.80665),
        Vector3::new(100.0, 0.0, 60.0),
    )
}

/// Every twelfth configuration of the bundled rows as a seed, at 0, 10 and 20 kg in turn, its
/// nominal point the target: each compensated through `model`, whose whole point (computed
/// here through the model) must lie within the tolerance of the target. The commands and loads.
fn lands_on_the_targets(model: &CalibratedModel) -> Vec<(Vec<f64>, f64)> {
    let (_, data, nominal, _) = setup();
    let options = CompensationOptions::default();
    let mut poses: Vec<&[f64]> = (data.rows.iter())
        .map(|r| r.sample.joints.as_slice())
        .collect();
    poses.dedup();
    (poses.iter().step_by(12).enumerate())
        .map(|(k, seed)| {
            let load = [0.0, 10.0, 20.0][k % 3];
            let target = nominal.point(&rad(seed));
            let c = compensate(model, &target, load, seed, &options).unwrap();
            let q = rad(&c.joints_deg);
            let miss = (model.point(&q, load) - target).norm();
            assert!(miss < options.tolerance, "{miss} mm at {load} kg");
            (q, load)
        })
        .collect()
}

/// A model whose bearings tilt (compliances, the links' weights and tilting compliances of the
/// size a stiff arm has): the compensated commands put the whole model's point — tilts included —
/// on the target, at several loads; the tilts move the point there by more than ten times the
/// tolerance, so commands that left them out of the aim would miss.
#[test]
fn compensation_takes_the_bearings_tilt_into_account() {
    use robocal_robot::{DEG_PER_KNM, MomentPart};
    let (_, _, _, calibrated) = setup();
    let mut errors = stiff_arm()
        .with_link_weights(&[1, 2, 3])
        .with_tilts(&[0, 1, 2, 3, 4]);
    for w in &mut errors.link_weights {
        w.value = match w.part {
            MomentPart::Mass => 30.0,
            _ => 3.0,
        };
    }
    for (t, c) in errors.tilts.iter_mut().zip([0.01, 0.02, 0.03, 0.08, 0.1]) {
        t.value = c * DEG_PER_KNM;
    }
    let model = CalibratedModel::new(calibrated, Some(errors), None);
    let tilted = (lands_on_the_targets(&model).iter())
        .map(|(q, load)| model.turn_offset(q, *load).norm())
        .fold(0.0, f64::max);
    assert!(
        tilted > 10.0 * CompensationOptions::default().tolerance,
        "{tilted}"
    );
}

/// A model with axis runouts (orders 1 and 2 on every joint, turns of 0.003–0.012°, the size
/// the development twins' runouts are identified at) and its compliances: the compensated
/// commands put the whole model's point — runouts included — on the target, at several loads;
/// the runouts move the point there by more than ten times the tolerance (the same model
/// without them, at the same commands), so commands that left them out of the aim would miss.
#[test]
fn compensation_takes_the_axis_runouts_into_account() {
    let (_, _, _, calibrated) = setup();
    let mut errors = stiff_arm().with_runouts(&[0, 1, 2, 3, 4, 5], 2);
    for (k, r) in errors.runouts.iter_mut().enumerate() {
        let size = (0.003 + 0.003 * (k % 4) as f64).to_radians();
        r.wave.sin = size * if k % 2 == 0 { 1.0 } else { -0.6 };
        r.wave.cos = size * if k % 3 == 0 { -0.8 } else { 0.5 };
    }
    let mut rigid = errors.clone();
    rigid.runouts.clear();
    let model = CalibratedModel::new(calibrated.clone(), Some(errors), None);
    let without = CalibratedModel::new(calibrated, Some(rigid), None);
    let moved = (lands_on_the_targets(&model).iter())
        .map(|(q, load)| (model.point(q, *load) - without.point(q, *load)).norm())
        .fold(0.0, f64::max);
    assert!(
        moved > 10.0 * CompensationOptions::default().tolerance,
        "{moved}"
    );
}
