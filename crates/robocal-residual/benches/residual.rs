//! Residual-learning benchmarks on synthetic data of the paper's size (1680 samples × 7 inputs):
//! training one axis network with the paper's settings for a fixed 200 epochs (target < 5 s),
//! one sample through kinematics + three MLPs (target < 20 µs), and a batch of 10 000; the GP:
//! a whole fit on 1000 rows (target: seconds), one prediction (target: microseconds).

use divan::{Bencher, black_box};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use robocal_data::Silent;
use robocal_residual::{
    GpOptimizer, NetSettings, ResidualKind, ResidualModel, ResidualSettings, Samples,
};
use robocal_robot::Robot;

fn main() {
    divan::main();
}

fn samples(n: usize, seed: u64) -> Samples {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let inputs: Vec<Vec<f64>> = (0..n)
        .map(|_| {
            let mut r: Vec<f64> = (0..6).map(|_| rng.random_range(-90.0..90.0)).collect();
            r.push(rng.random_range(0.0..20.0));
            r
        })
        .collect();
    let errors = inputs
        .iter()
        .map(|r| {
            let s = (r[1].to_radians()).sin() * r[6] * 0.05;
            [s, 0.1 * r[2].to_radians().cos(), -0.02 * r[6]]
        })
        .collect();
    Samples::new(inputs, errors)
}

/// The paper's settings, every network trained for exactly 200 epochs (no early stop).
fn fixed_epochs(kind: ResidualKind) -> ResidualSettings {
    let mut s = ResidualSettings::paper(kind, 1);
    for n in s.axes.iter_mut().chain(std::iter::once(&mut s.mosm)) {
        n.patience = usize::MAX;
    }
    s
}

#[divan::bench(args = ["x", "y", "z"], sample_count = 3, sample_size = 1)]
fn train_one_axis_1680x7_200_epochs(b: Bencher, axis: &str) {
    let (train, val) = (samples(1680, 1), samples(336, 2));
    let net = match axis {
        "x" => NetSettings::paper_x(),
        "y" => NetSettings::paper_y(),
        _ => NetSettings::paper_z(),
    };
    let settings = ResidualSettings {
        mosm: NetSettings {
            patience: usize::MAX,
            ..net
        },
        ..fixed_epochs(ResidualKind::Mosm)
    };
    b.bench_local(|| ResidualModel::fit(&settings, &train, &val, &Silent).expect("fit"));
}

fn model() -> (Robot, ResidualModel) {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    let robot = Robot::load(root.join("configs/robots/pmc6va030.toml")).expect("robot");
    let mut settings = fixed_epochs(ResidualKind::Somm);
    for n in &mut settings.axes {
        n.max_epochs = 2;
    }
    let model =
        ResidualModel::fit(&settings, &samples(400, 3), &samples(100, 4), &Silent).expect("fit");
    (robot, model)
}

#[divan::bench]
fn predict_one_sample_kinematics_plus_somm(b: Bencher) {
    let (robot, model) = model();
    let input = Samples::rows(vec![vec![10.0, -50.0, -20.0, 30.0, 45.0, -60.0, 5.0]]);
    let q: Vec<f64> = input.inputs[0][..6]
        .iter()
        .map(|d: &f64| d.to_radians())
        .collect();
    b.bench_local(|| {
        let p = robot.point(black_box(&q));
        let e = model.predict(black_box(&input))[0];
        [p.x + e[0], p.y + e[1], p.z + e[2]]
    });
}

#[divan::bench(sample_count = 20)]
fn predict_batch_10000_kinematics_plus_somm(b: Bencher) {
    let (robot, model) = model();
    let inputs = samples(10_000, 5);
    let qs: Vec<Vec<f64>> = inputs
        .inputs
        .iter()
        .map(|r| r[..6].iter().map(|d| d.to_radians()).collect())
        .collect();
    b.bench_local(|| {
        let e = model.predict(black_box(&inputs));
        qs.iter()
            .zip(e)
            .map(|(q, e)| robot.point(q).x + e[0])
            .sum::<f64>()
    });
}

/// The GP residual with its default settings on 1000 rows × 7 inputs (13 features after the
/// periodic encoding): the whole fit (hyper-parameters on 500 rows, 80 likelihood evaluations by
/// Adam, the default, or by L-BFGS; three axes).
#[divan::bench(args = ["adam", "lbfgs"], sample_count = 3, sample_size = 1)]
fn gp_fit_1000x7(b: Bencher, optimizer: &str) {
    let train = samples(1000, 6);
    let mut settings = ResidualSettings::gp(1);
    settings.gp.optimizer = match optimizer {
        "lbfgs" => GpOptimizer::Lbfgs,
        _ => GpOptimizer::Adam,
    };
    b.bench_local(|| {
        ResidualModel::fit(&settings, &train, &Samples::default(), &Silent).expect("fit")
    });
}

fn gp_model(rows: usize) -> ResidualModel {
    let mut settings = ResidualSettings::gp(1);
    settings.gp.iterations = 5;
    settings.gp.max_rows = rows;
    ResidualModel::fit(&settings, &samples(rows, 7), &Samples::default(), &Silent).expect("fit")
}

/// One sample's correction through a GP conditioned on 1000 and on 2500 rows (three axes).
#[divan::bench(args = [1000, 2500])]
fn gp_predict_one_sample(b: Bencher, rows: usize) {
    let model = gp_model(rows);
    let input = Samples::rows(vec![vec![10.0, -50.0, -20.0, 30.0, 45.0, -60.0, 5.0]]);
    b.bench_local(|| model.predict(black_box(&input))[0]);
}

/// One sample's correction with its standard deviation (the factor made before timing).
#[divan::bench(args = [1000, 2500])]
fn gp_predict_one_sample_with_sigma(b: Bencher, rows: usize) {
    let model = gp_model(rows);
    let input = Samples::rows(vec![vec![10.0, -50.0, -20.0, 30.0, 45.0, -60.0, 5.0]]);
    let _ = model.predict_with_std(&input, true);
    b.bench_local(|| model.predict_with_std(black_box(&input), true).1);
}

/// A thousand samples' corrections with their standard deviations, in one call (the factor made
/// before timing): what `predict --sigma` does with a file of poses.
#[divan::bench(args = [1000, 2500], sample_count = 5, sample_size = 1)]
fn gp_predict_1000_samples_with_sigma(b: Bencher, rows: usize) {
    let model = gp_model(rows);
    let input = Samples::rows(samples(1000, 8).inputs);
    let _ = model.predict_with_std(&Samples::rows(vec![input.inputs[0].clone()]), true);
    b.bench_local(|| model.predict_with_std(black_box(&input), true).1);
}
