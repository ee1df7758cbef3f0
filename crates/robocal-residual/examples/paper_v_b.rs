//! Section V-B of the paper on the bundled twin data (`just table5`): the GA/GB splits of
//! section IV-E, kinematic calibration (LM, and BFGS for its Table 6 row) on the unloaded rows of
//! the trained configurations, then SOMM, MOSM and CA-SOMM with the paper's settings; Table 5
//! (SOMM train/validation/test) and Table 6 (on the GB10 + GB30 rows) beside the paper's numbers,
//! training times and the classifier's accuracy.
//!
//! Twin data, not the paper's robot. Seed: 2020 for the splits and the networks.

use std::collections::HashSet;
use std::time::Instant;

use rand::SeedableRng;
use rand::seq::SliceRandom;
use rand_chacha::ChaCha8Rng;
use robocal_data::{ErrorStats, Measurement, MeasurementSet};
use robocal_ident::{KinematicSettings, Observations, SolverKind, calibrate_kinematics};
use robocal_residual::{ResidualKind, ResidualModel, ResidualSettings, Samples};
use robocal_robot::Robot;
use robocal_twin::TwinConfig;

const SEED: u64 = 2020;

fn samples(robot: &Robot, rows: &[&Measurement]) -> Samples {
    Samples::from_measurements(robot, rows.iter().copied())
}

fn stats(s: &Samples, predicted: Option<&[[f64; 3]]>) -> ErrorStats {
    ErrorStats::from_errors(&s.remaining(predicted))
}

fn row(label: &str, s: &ErrorStats, paper: &str) {
    println!(
        "  {label:<36} mean {:.3}  std {:.3}  max {:.3}   paper: {paper}",
        s.mean, s.std, s.max
    );
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let twin = TwinConfig::load("configs/twin/pmc6va030.toml")?;
    let nominal = twin.nominal.clone();
    let data = MeasurementSet::read("datasets/pmc6va030/measurements.csv", 6)?;
    let mut rng = ChaCha8Rng::seed_from_u64(SEED);
    let mut poses: Vec<&str> = data.rows.iter().map(|r| r.sample.pose.as_str()).collect();
    poses.dedup();
    poses.shuffle(&mut rng);
    let trained_cfg: HashSet<&str> = poses[..112].iter().copied().collect();
    let mut trained_loads = twin.loads.trained.clone();
    trained_loads.shuffle(&mut rng);
    let gb20_loads: Vec<f64> = trained_loads[..6].to_vec();
    let untrained = &twin.loads.untrained;
    let is_untrained = |l: f64| untrained.contains(&l);
    let set = |cfg: bool, pick: &dyn Fn(f64) -> bool| -> Vec<&Measurement> {
        data.rows
            .iter()
            .filter(|r| trained_cfg.contains(r.sample.pose.as_str()) == cfg && pick(r.sample.load))
            .collect()
    };
    let ga10 = set(true, &|l| !is_untrained(l));
    let ga20 = set(true, &is_untrained);
    let gb20 = set(false, &|l| gb20_loads.contains(&l));
    let gb10 = set(false, &|l| !is_untrained(l) && !gb20_loads.contains(&l));
    let gb30 = set(false, &is_untrained);
    println!(
        "Twin data (twin seed {}), not the paper's robot. Splits (seed {SEED}): GA10 {} train, GB20 {} validation, GA20 {} + GB10 {} + GB30 {} test",
        twin.seed,
        ga10.len(),
        gb20.len(),
        ga20.len(),
        gb10.len(),
        gb30.len()
    );
    let unloaded = Observations::from_rows(
        6,
        data.rows
            .iter()
            .filter(|r| r.sample.load == 0.0 && trained_cfg.contains(r.sample.pose.as_str())),
    );
    let lm = calibrate_kinematics(&nominal, &unloaded, &KinematicSettings::default())?;
    let bfgs = calibrate_kinematics(
        &nominal,
        &unloaded,
        &KinematicSettings {
            solver: SolverKind::Bfgs,
            max_iterations: 500,
            ..Default::default()
        },
    )?;
    let robot = &lm.robot;
    let train = samples(robot, &ga10);
    let val = samples(robot, &gb20);
    let test_rows: Vec<&Measurement> = ga20.iter().chain(&gb10).chain(&gb30).copied().collect();
    let test = samples(robot, &test_rows);
    let gb_rows: Vec<&Measurement> = gb10.iter().chain(&gb30).copied().collect();
    let gb = samples(robot, &gb_rows);

    let mut models = Vec::new();
    // The paper's three models, then CA-SOMM with a deeper tree (8 levels, 20 samples per leaf).
    let mut deep = ResidualSettings::paper(ResidualKind::CaSomm, SEED);
    deep.classifier.max_depth = 8;
    deep.classifier.min_samples_leaf = 20;
    let runs = [
        ResidualSettings::paper(ResidualKind::Somm, SEED),
        ResidualSettings::paper(ResidualKind::Mosm, SEED),
        ResidualSettings::paper(ResidualKind::CaSomm, SEED),
        deep,
    ];
    for settings in runs {
        let kind = settings.kind;
        let t = Instant::now();
        let model = ResidualModel::fit(&settings, &train, &val, None)?;
        let secs = t.elapsed().as_secs_f64();
        let epochs: Vec<String> = model
            .nets
            .iter()
            .map(|n| format!("{}/{}", n.report.best_epoch, n.report.epochs))
            .collect();
        println!(
            "{}: trained in {secs:.1} s ({} networks; best/last epoch {})",
            kind.name(),
            model.nets.len(),
            epochs.join(" ")
        );
        models.push(model);
    }

    println!("\nTable 5 — after LM + SOMM (mm)");
    let somm = &models[0];
    let with = |m: &ResidualModel, s: &Samples| stats(s, Some(&m.predict(&s.inputs)));
    row(
        "training (GA10)",
        &with(somm, &train),
        "0.376 / 0.204 / 0.954",
    );
    row(
        "validation (GB20)",
        &with(somm, &val),
        "0.397 / 0.223 / 1.010",
    );
    row(
        "test (GA20+GB10+GB30)",
        &with(somm, &test),
        "0.381 / 0.213 / 0.991",
    );

    println!("\nTable 6 — the {} GB10 + GB30 rows (mm)", gb.len());
    let before = Observations::from_rows(6, gb_rows.iter().copied());
    row(
        "before (nominal, base+tool fitted)",
        &ErrorStats::from_errors(&before.errors(&lm.aligned)),
        "2.613 / 1.015 / 6.294",
    );
    row(
        "after BFGS kinematic",
        &ErrorStats::from_errors(&before.errors(&bfgs.robot)),
        "0.618 / 0.275 / 1.609",
    );
    row("after LM kinematic", &stats(&gb, None), "-");
    row(
        "after LM + SOMM",
        &with(somm, &gb),
        "0.389 / 0.991 (sic) / 0.991 (BFGS+SOMM)",
    );
    row("after LM + MOSM", &with(&models[1], &gb), "-");
    row(
        "after LM + CA-SOMM",
        &with(&models[2], &gb),
        "0.310 / 0.213 / 1.255 (BFGS+CA-SOMM)",
    );
    row(
        "after LM + CA-SOMM (tree depth 8)",
        &with(&models[3], &gb),
        "-",
    );
    for (name, model) in [("CA-SOMM", &models[2]), ("CA-SOMM depth 8", &models[3])] {
        if let Some(c) = &model.classifier {
            println!(
                "{name} classifier: X split at {:.3} mm; accuracy training {:.1} %, validation {:.1} %, test {:.1} % (paper: 93 %)",
                c.threshold,
                100.0 * c.accuracy(&train),
                100.0 * c.accuracy(&val),
                100.0 * c.accuracy(&test)
            );
        }
    }
    for (name, model) in ["SOMM", "MOSM", "CA-SOMM", "CA-SOMM d8"]
        .iter()
        .zip(&models)
    {
        let p = model.predict(&test.inputs);
        let rms = |a: usize, with: bool| {
            (test
                .errors
                .iter()
                .zip(&p)
                .map(|(e, p)| (e[a] - if with { p[a] } else { 0.0 }).powi(2))
                .sum::<f64>()
                / test.len() as f64)
                .sqrt()
        };
        println!(
            "{name:<8} test RMS per axis X {:.3}→{:.3}  Y {:.3}→{:.3}  Z {:.3}→{:.3} mm",
            rms(0, false),
            rms(0, true),
            rms(1, false),
            rms(1, true),
            rms(2, false),
            rms(2, true)
        );
    }
    Ok(())
}
