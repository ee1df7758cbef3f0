//! What a 6-DoF probe buys (`just probe`): the bundled twin with a probe on the flange (its
//! truth's `[tool] rpy`, the robot file's drawing a few tenths of a degree off), K random
//! configurations calibrated from the probe's positions alone and from positions and
//! orientations (`rx, ry, rz`, angular noise 0.01° per axis), and the error left on 48
//! configurations never measured, against the twin's noise-free position and orientation. Two
//! twins: geometry and tracker noise only, at 0 kg, LM (`configs/stages/kinematic-lm.toml`:
//! every effect is in the model); and every effect (compliance, gears, backlash) at 0, 10 and
//! 20 kg with the default calibrate (backlash stays unmodelled). The default angle weight
//! (0.02 mm / 0.01° = 2 mm per degree). Twin numbers, not a real robot's.
//!
//! ```sh
//! cargo run --release -p robocal-pipeline --example probe -- [--seeds N]
//! ```

use std::collections::BTreeSet;
use std::path::Path;

use nalgebra::Vector3;
use rand::SeedableRng;
use rand::seq::SliceRandom;
use rand_chacha::ChaCha8Rng;
use robocal_calibration::Stages;
use robocal_calibration::{CalibrationInput, Checks, DefaultOptions, calibrate};
use robocal_data::{Measurement, MeasurementSet, Silent};
use robocal_twin::TwinConfig;

const TWIN: &str = "configs/twin/pmc6va030.toml";
const COUNTS: [usize; 4] = [12, 24, 48, 96];

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let seeds: u64 = (args.iter().position(|a| a == "--seeds"))
        .and_then(|i| args.get(i + 1))
        .map_or(Ok(3), |s| s.parse())?;
    let full = TwinConfig::load(TWIN)?;
    let geometry = TwinConfig {
        noise: full.noise,
        ..full.geometry_only()
    };
    println!("## Geometry and tracker noise, 0 kg, LM\n");
    run(
        geometry,
        Some("configs/stages/kinematic-lm.toml"),
        &[0.0],
        seeds,
    )?;
    println!("\n## Every effect, 0, 10 and 20 kg, default calibrate\n");
    run(full, None, &[0.0, 10.0, 20.0], seeds)
}

fn run(
    mut twin: TwinConfig,
    stages: Option<&str>,
    loads: &[f64],
    seeds: u64,
) -> Result<(), Box<dyn std::error::Error>> {
    // The probe's frame on the flange: the drawing says 30° about z; the truth is off by a few
    // tenths of a degree about every axis.
    twin.truth.tool_rpy = Some(Vector3::new(0.4, -0.3, 30.2).map(f64::to_radians));
    let mut nominal = twin.nominal.clone();
    nominal.tool_rpy = Some(Vector3::new(0.0, 0.0, 30.0).map(f64::to_radians));
    let noise_deg = twin.noise.map_or(0.0, |n| n.probe_deg);
    let data = twin.generate()?;
    let at_loads = |m: &&Measurement| loads.contains(&m.sample.load);
    let mut poses: Vec<String> = Vec::new();
    for m in &data.measurements.rows {
        if !poses.contains(&m.sample.pose) {
            poses.push(m.sample.pose.clone());
        }
    }
    let (pool, test) = poses.split_at(poses.len() - 48);
    let test: BTreeSet<&String> = test.iter().collect();
    let test_rows: Vec<&Measurement> = (data.truth.rows.iter())
        .filter(at_loads)
        .filter(|m| test.contains(&m.sample.pose))
        .collect();
    let stages = stages.map(|p| Stages::load(Path::new(p)).map(|s| (s, Path::new(p))));
    let stages = stages.transpose()?;
    println!(
        "| K configurations | seed | positions only: held-out mm | held-out deg | with orientations: held-out mm | held-out deg |"
    );
    println!("|---|---|---|---|---|---|");
    let mut sums = vec![[0.0; 4]; COUNTS.len()];
    for seed in 0..seeds {
        let mut order: Vec<&String> = pool.iter().collect();
        order.shuffle(&mut ChaCha8Rng::seed_from_u64(seed));
        for (k, &count) in COUNTS.iter().enumerate() {
            let chosen: BTreeSet<&String> = order[..count].iter().copied().collect();
            let fit = |angles: bool| -> Result<(f64, f64), Box<dyn std::error::Error>> {
                let rows: Vec<Measurement> = (data.measurements.rows.iter())
                    .filter(at_loads)
                    .filter(|m| chosen.contains(&m.sample.pose))
                    .map(|m| Measurement {
                        orientation: m.orientation.filter(|_| angles),
                        ..m.clone()
                    })
                    .collect();
                let set = MeasurementSet {
                    source: "twin".into(),
                    joint_count: twin.truth.dof(),
                    rows,
                };
                let c = calibrate(
                    &CalibrationInput {
                        nominal: &nominal,
                        robot_file: Path::new(TWIN),
                        data: &set,
                        validation: None,
                        stages: stages.as_ref().map(|(s, p)| (s, *p)),
                        checks: Checks {
                            force: true,
                            keep_outliers: true,
                        },
                        options: &DefaultOptions::default(),
                    },
                    &Silent,
                )?;
                let angle = c.model.orientation_errors(&test_rows);
                let angle = angle.iter().sum::<f64>() / angle.len() as f64;
                Ok((c.model.stats(&test_rows).mean, angle))
            };
            let (p3, a3) = fit(false)?;
            let (p6, a6) = fit(true)?;
            for (s, v) in sums[k].iter_mut().zip([p3, a3, p6, a6]) {
                *s += v;
            }
            println!("| {count} | {seed} | {p3:.4} | {a3:.4} | {p6:.4} | {a6:.4} |");
        }
    }
    println!(
        "\nMean over {seeds} seeds ({} test rows; the probe's angular noise {noise_deg}° per axis):\n",
        test_rows.len()
    );
    println!(
        "| K | positions only: mm | deg | with orientations: mm | deg |\n|---|---|---|---|---|"
    );
    for (k, &count) in COUNTS.iter().enumerate() {
        let n = seeds as f64;
        let s = sums[k];
        println!(
            "| {count} | {:.4} | {:.4} | {:.4} | {:.4} |",
            s[0] / n,
            s[1] / n,
            s[2] / n,
            s[3] / n
        );
    }
    Ok(())
}
