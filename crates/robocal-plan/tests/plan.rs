//! Planning against independent computations: the information against finite differences of
//! the measured point, exchanges that never lower `log det`, indices of a known matrix, bad
//! settings named by key.

use std::path::Path;

use nalgebra::DMatrix;
use robocal_data::Silent;
use robocal_plan::design::indices_of;
use robocal_plan::{Criterion, PlanError, PlanSettings, Pool, candidates_from_limits, plan};
use robocal_robot::Robot;

fn robot() -> Robot {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    Robot::load(root.join("configs/robots/pmc6va030.toml")).unwrap()
}

fn pool(robot: &Robot, settings: &PlanSettings, n: usize) -> (Vec<Vec<f64>>, Vec<Vec<f64>>) {
    let file = Path::new("pmc6va030.toml");
    (
        candidates_from_limits(robot, file, settings, n, 1, &Silent).unwrap(),
        candidates_from_limits(robot, file, settings, 20, 2, &Silent).unwrap(),
    )
}

#[test]
fn the_information_is_that_of_finite_differences_of_the_point() {
    let robot = robot();
    let settings = PlanSettings::default();
    let (candidates, checks) = pool(&robot, &settings, 40);
    let p = Pool::new(&robot, &candidates, &checks, &settings).unwrap();
    assert!(p.parameters() > 10 && !p.fixed.is_empty());
    let ids = robot.param_ids();
    let x0 = robot.params();
    let h = 1e-6;
    let set: Vec<usize> = (0..candidates.len()).step_by(3).collect();
    let mut fd_info = DMatrix::zeros(p.parameters(), p.parameters());
    for &c in &set {
        let q = &candidates[c];
        let mut b = DMatrix::zeros(3, p.parameters());
        for (j, name) in p.names.iter().enumerate() {
            let id = robot.param_by_name(name).unwrap();
            let at = ids.iter().position(|i| *i == id).unwrap();
            let moved = |sign: f64| {
                let mut x = x0.clone();
                x[at] += sign * h * p.scale[j];
                robot.with_params(&x).unwrap().point(q)
            };
            let d = (moved(1.0) - moved(-1.0)) / (2.0 * h);
            for a in 0..3 {
                b[(a, j)] = d[a];
            }
        }
        fd_info += b.transpose() * &b;
    }
    let info = p.information(&set);
    let scale = info.abs().max();
    assert!(
        (info - fd_info).abs().max() < 1e-5 * scale,
        "the information differs from the finite differences'"
    );
}

#[test]
fn exchanges_never_lower_the_criterion_and_a_seed_gives_the_same_plan() {
    let robot = robot();
    let settings = PlanSettings::default();
    let (candidates, checks) = pool(&robot, &settings, 150);
    let p = Pool::new(&robot, &candidates, &checks, &settings).unwrap();
    let d = p.d_optimal(12);
    assert_eq!(d.chosen.len(), 12);
    let mut last = d.greedy_log_det;
    for &(_, _, after) in &d.exchanges {
        assert!(
            after >= last - 1e-9,
            "an exchange lowered log det: {last} → {after}"
        );
        last = after;
    }
    assert!((d.log_det - last).abs() < 1e-9 && d.log_det >= d.greedy_log_det);
    // Better than any of 20 random sets of the same size.
    for s in 0..20 {
        let set: Vec<usize> = (0..12)
            .map(|i| (i * 11 + s * 7) % candidates.len())
            .collect();
        assert!(robocal_plan::log_det(&p.information(&set)) < d.log_det);
    }
    // I-optimal: the mean predicted variance at the check poses, lower than D-optimal's.
    let i = p.select(12, Criterion::IOptimal);
    let variance = |set: &[usize]| {
        let inv = p.information(set).try_inverse().unwrap();
        (inv * p.check_moment()).trace()
    };
    assert!(variance(&i.chosen) <= variance(&d.chosen) * (1.0 + 1e-9));
    let a = plan(
        &robot,
        candidates.clone(),
        "pool".into(),
        &checks,
        &[12],
        &settings,
        &Silent,
    )
    .unwrap();
    let b = plan(
        &robot,
        candidates,
        "pool".into(),
        &checks,
        &[12],
        &settings,
        &Silent,
    )
    .unwrap();
    assert_eq!(a.plans[0].chosen, b.plans[0].chosen);
    assert_eq!(a.plans[0].predicted, b.plans[0].predicted);
}

#[test]
fn indices_of_a_known_information() {
    // Singular values 2, 1, 0.5 over 4 points.
    let m = DMatrix::from_diagonal(&nalgebra::DVector::from_vec(vec![4.0, 1.0, 0.25]));
    let i = indices_of(&m, 4);
    assert!((i.o1 - 1.0 / 2.0).abs() < 1e-12, "O1 {}", i.o1);
    assert!((i.o3 - 0.5).abs() < 1e-12);
    assert!((i.o4 - 0.125).abs() < 1e-12);
    assert!((i.condition_number - 4.0).abs() < 1e-12);
}

#[test]
fn bad_settings_and_counts_are_named() {
    let path = Path::new("plan.toml");
    let err = |text: &str| {
        PlanSettings::from_toml_str(text, path)
            .unwrap_err()
            .to_string()
    };
    let e = err("[workspace]\nmin = [0, 0, 500]\nmax = [100, 100, 400]\n");
    assert!(
        e.contains("plan.toml") && e.contains("workspace.min") && e.contains("empty"),
        "{e}"
    );
    let e = err("seed = 1\nloadz = [0]\n");
    assert!(
        e.contains("plan.toml")
            && (e.contains("line 2") || e.contains(":2:"))
            && e.contains("loadz"),
        "{e}"
    );
    assert!(err("noise_mm = -1\n").contains("noise_mm"));
    assert!(err("[model]\ncompliance = true\n").contains("model.compliance"));
    // Too few configurations for the parameters.
    let robot = robot();
    let settings = PlanSettings::default();
    let (candidates, checks) = pool(&robot, &settings, 30);
    let e = plan(
        &robot,
        candidates,
        "pool".into(),
        &checks,
        &[3],
        &settings,
        &Silent,
    )
    .unwrap_err();
    assert!(
        matches!(e, PlanError::Invalid { ref key, .. } if key == "--count"),
        "{e}"
    );
    // A robot without limits cannot draw candidates.
    let mut free = robot.clone();
    free.joints[2].limits = None;
    let e = candidates_from_limits(&free, Path::new("arm.toml"), &settings, 10, 1, &Silent)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("arm.toml") && e.contains("joint[2].limits"),
        "{e}"
    );
}

/// Several reflectors: every point is measured at every pose, so the plan's information holds
/// their rows; the wrist offsets one point leaves to the nominal are identified with three.
#[test]
fn a_plan_for_three_reflectors_identifies_what_one_cannot() {
    let one = robot();
    let mut three = one.clone();
    three.points = vec![
        (
            "smr2".into(),
            one.tool + nalgebra::Vector3::new(80.0, 0.0, -35.0),
        ),
        (
            "smr3".into(),
            one.tool + nalgebra::Vector3::new(-40.0, 70.0, -35.0),
        ),
    ];
    let settings = PlanSettings::default();
    let (candidates, checks) = pool(&one, &settings, 60);
    let p1 = Pool::new(&one, &candidates, &checks, &settings).unwrap();
    let p3 = Pool::new(&three, &candidates, &checks, &settings).unwrap();
    assert!(p1.fixed.iter().any(|f| f == "j6.a"), "{:?}", p1.fixed);
    assert!(!p3.fixed.iter().any(|f| f == "j6.a"), "{:?}", p3.fixed);
    assert!(p3.names.iter().any(|n| n == "point2.z"));
    assert_eq!(p3.parameters(), p1.parameters() + 2 + 6);
}
