//! Kinematics benchmarks: FK of one pose (target < 1 µs) and the 168-pose × all-parameter
//! Jacobian (target < 100 µs) on the PMC6VA030 nominal table.

use divan::{Bencher, black_box};
use robocal_robot::{IkOptions, IkTarget, Robot};

fn main() {
    divan::main();
}

fn robot() -> Robot {
    Robot::from_toml_str(
        include_str!("../../../configs/robots/pmc6va030.toml"),
        "pmc6va030.toml",
    )
    .expect("bundled robot")
}

/// 168 spread configurations, rad, row-major.
fn configurations() -> Vec<f64> {
    (0..168)
        .flat_map(|k| {
            let t = k as f64;
            [
                (0.37 * t).sin() * 1.2,
                (0.21 * t).cos() * 0.8,
                (0.13 * t).sin() * 0.9,
                (0.41 * t).cos() * 1.5,
                0.3 + (0.17 * t).sin() * 0.8,
                (0.29 * t).cos() * 2.0,
            ]
        })
        .collect()
}

#[divan::bench]
fn fk_one_pose(b: Bencher) {
    let robot = robot();
    let q = [0.2, -0.4, 0.6, 0.1, 0.9, -0.3];
    b.bench(|| black_box(&robot).point(black_box(&q)));
}

#[divan::bench]
fn jacobian_168_poses_34_params(b: Bencher) {
    let robot = robot();
    let qs = configurations();
    let mut jac = nalgebra::DMatrix::zeros(3 * 168, robot.param_count());
    b.bench_local(|| {
        for (k, q) in qs.chunks_exact(6).enumerate() {
            black_box(robot.write_param_jacobian(q, &mut jac, 3 * k));
        }
    });
}

#[divan::bench]
fn ik_pose_from_nearby_seed(b: Bencher) {
    let robot = robot();
    let q = [0.2, -0.4, 0.6, 0.1, 0.9, -0.3];
    let (rotation, origin) = robot.flange_frame(&q);
    let target = IkTarget::Pose {
        point: origin + rotation * robot.tool,
        rotation,
    };
    let seed = [0.3, -0.3, 0.5, 0.2, 0.8, -0.2];
    let options = IkOptions::default();
    b.bench(|| robot.inverse_kinematics(black_box(&target), black_box(&seed), &options));
}
