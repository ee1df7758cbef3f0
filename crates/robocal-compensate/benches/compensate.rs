//! Compensation of one target on the paper's arm: kinematics alone, and kinematics + a SOMM of
//! the paper's architecture (target < 100 µs per target).

use divan::{Bencher, black_box};
use nalgebra::Vector3;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use robocal_compensate::{CompensationOptions, compensate};
use robocal_data::Silent;
use robocal_model::CalibratedModel;
use robocal_residual::{ResidualKind, ResidualModel, ResidualSettings, Samples};
use robocal_robot::{Compliance, Robot};

fn main() {
    divan::main();
}

fn robot() -> Robot {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    Robot::load(root.join("configs/robots/pmc6va030.toml")).expect("robot")
}

/// A SOMM with the paper's architecture, briefly trained on a smooth synthetic error (about
/// 0.5 mm), so that compensation has a real network to iterate through.
fn somm() -> ResidualModel {
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let inputs: Vec<Vec<f64>> = (0..400)
        .map(|_| {
            let mut r: Vec<f64> = (0..6).map(|_| rng.random_range(-60.0..60.0)).collect();
            r.push(rng.random_range(0.0..20.0));
            r
        })
        .collect();
    let errors = inputs
        .iter()
        .map(|r| {
            let s = r[1].to_radians().sin() * r[6] * 0.02;
            [s, 0.1 * r[2].to_radians().cos(), -0.02 * r[6]]
        })
        .collect();
    let train = Samples::new(inputs, errors);
    let mut settings = ResidualSettings::paper(ResidualKind::Somm, 1);
    for n in &mut settings.axes {
        n.max_epochs = 5;
    }
    ResidualModel::fit(&settings, &train, &train, &Silent).expect("fit")
}

const SEED: [f64; 6] = [10.0, 15.0, -20.0, 30.0, 40.0, -25.0];

fn target(robot: &Robot) -> Vector3<f64> {
    let q: Vec<f64> = SEED.iter().map(|d: &f64| d.to_radians()).collect();
    robot.point(&q) + Vector3::new(1.5, -0.8, 1.1)
}

#[divan::bench]
fn one_target_kinematics(b: Bencher) {
    let robot = robot();
    let t = target(&robot);
    let o = CompensationOptions::default();
    let m = CalibratedModel::kinematic(robot);
    b.bench_local(|| compensate(black_box(&m), &t, 5.0, &SEED, &o).expect("converges"));
}

#[divan::bench]
fn one_target_kinematics_plus_somm(b: Bencher) {
    let robot = robot();
    let model = somm();
    let t = target(&robot);
    let o = CompensationOptions::default();
    let m = CalibratedModel::new(robot, None, Some(model));
    b.bench_local(|| compensate(black_box(&m), &t, 5.0, &SEED, &o).expect("converges"));
}

#[divan::bench]
fn one_target_kinematics_plus_compliance(b: Bencher) {
    let robot = robot();
    // Compliances of the size the twin's joints have, deg per kN·m.
    let values = [0.0, 0.08, 0.14, 0.38, 0.48, 0.57]
        .iter()
        .map(|c| c * robocal_robot::DEG_PER_KNM)
        .collect();
    let compliance = Compliance::new(
        values,
        Vector3::new(0.0, 0.0, -9.80665),
        Vector3::new(100.0, 0.0, 60.0),
    );
    let t = target(&robot);
    let o = CompensationOptions::default();
    let m = CalibratedModel::new(robot, Some(compliance), None);
    b.bench_local(|| compensate(black_box(&m), &t, 15.0, &SEED, &o).expect("converges"));
}
