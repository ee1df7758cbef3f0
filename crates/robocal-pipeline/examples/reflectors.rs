//! What three reflectors per pose buy (`just reflectors`): the bundled twin with two more
//! reflectors on a tool plate (`[tool.points]` of its truth, their nominal positions in the
//! robot file off by a few millimetres), K random configurations calibrated from the default
//! reflector alone and from all three, and the error left at the default reflector on 48
//! configurations never measured, against the twin's noise-free points; and which parameters
//! each leaves unidentified. Two twins: geometry and tracker noise only, at 0 kg, calibrated by
//! LM (`configs/stages/kinematic-lm.toml`: the model holds everything the twin does, so the
//! error is what the poses leave); and every effect, at 0, 10 and 20 kg, LM + joint compliance
//! (`configs/stages/compliance.toml`: gear errors and backlash stay unmodelled). The twin's
//! noise as bundled: tracker noise per reflector, the robot's repeatability (0.05 mm) once per
//! pose and load, shared by its reflectors. Twin numbers, not a real robot's.
//!
//! ```sh
//! cargo run --release -p robocal-pipeline --example reflectors -- [--seeds N]
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
const COUNTS: [usize; 6] = [8, 12, 16, 24, 40, 80];

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
    run(geometry, "configs/kinematic-lm.toml", &[0.0], seeds)?;
    println!("\n## Every effect, 0, 10 and 20 kg, LM + joint compliance\n");
    run(full, "configs/compliance.toml", &[0.0, 10.0, 20.0], seeds)
}

fn run(
    mut twin: TwinConfig,
    stages: &str,
    loads: &[f64],
    seeds: u64,
) -> Result<(), Box<dyn std::error::Error>> {
    let stages_file = stages.replace("configs/", "configs/stages/");
    // Two more reflectors on a plate about 80 mm from the default one; the robot file's values
    // are the plate's drawing, the truth's a few millimetres off.
    let tool = twin.truth.tool;
    twin.truth.points = vec![
        ("smr2".into(), tool + Vector3::new(81.7, 2.4, -36.1)),
        ("smr3".into(), tool + Vector3::new(-38.2, 72.9, -34.4)),
    ];
    let mut nominal3 = twin.nominal.clone();
    let nominal_tool = nominal3.tool;
    nominal3.points = vec![
        ("smr2".into(), nominal_tool + Vector3::new(80.0, 0.0, -35.0)),
        (
            "smr3".into(),
            nominal_tool + Vector3::new(-40.0, 70.0, -35.0),
        ),
    ];
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
        .filter(|m| m.sample.target.is_empty() && test.contains(&m.sample.pose))
        .collect();
    let stages_path = Path::new(&stages_file);
    let stages = Stages::load(stages_path)?;
    println!(
        "| K configurations | seed | one reflector: rows | held-out mean (mm) | three reflectors: rows | held-out mean (mm) | held fixed with one, identified with three |"
    );
    println!("|---|---|---|---|---|---|---|");
    let mut sums = vec![(0.0, 0.0); COUNTS.len()];
    for seed in 0..seeds {
        let mut order: Vec<&String> = pool.iter().collect();
        order.shuffle(&mut ChaCha8Rng::seed_from_u64(seed));
        for (k, &count) in COUNTS.iter().enumerate() {
            let chosen: BTreeSet<&String> = order[..count].iter().copied().collect();
            let fit = |targets: bool| -> Result<_, Box<dyn std::error::Error>> {
                let rows: Vec<Measurement> = (data.measurements.rows.iter())
                    .filter(at_loads)
                    .filter(|m| chosen.contains(&m.sample.pose))
                    .filter(|m| targets || m.sample.target.is_empty())
                    .cloned()
                    .collect();
                let set = MeasurementSet {
                    source: "twin".into(),
                    joint_count: twin.truth.dof(),
                    rows,
                };
                let nominal = if targets { &nominal3 } else { &twin.nominal };
                let c = calibrate(
                    &CalibrationInput {
                        nominal,
                        robot_file: Path::new(TWIN),
                        data: &set,
                        validation: None,
                        stages: Some((&stages, stages_path)),
                        checks: Checks {
                            force: true,
                            keep_outliers: true,
                        },
                        options: &DefaultOptions::default(),
                    },
                    &Silent,
                )?;
                let fixed: BTreeSet<String> = (c.report.kinematic.fixed.iter())
                    .map(|f| f.name.clone())
                    .collect();
                Ok((set.len(), c.model.stats(&test_rows).mean, fixed))
            };
            let (n1, e1, f1) = fit(false)?;
            let (n3, e3, f3) = fit(true)?;
            let gained: Vec<&String> = f1.difference(&f3).collect();
            sums[k].0 += e1;
            sums[k].1 += e3;
            println!(
                "| {count} | {seed} | {n1} | {e1:.4} | {n3} | {e3:.4} | {} |",
                if gained.is_empty() {
                    "none".to_string()
                } else {
                    gained
                        .iter()
                        .map(|s| s.as_str())
                        .collect::<Vec<_>>()
                        .join(", ")
                }
            );
        }
    }
    println!(
        "\nMean over {seeds} seeds ({} test rows):\n",
        test_rows.len()
    );
    println!("| K | one reflector | three reflectors |\n|---|---|---|");
    for (k, &count) in COUNTS.iter().enumerate() {
        let n = seeds as f64;
        println!("| {count} | {:.4} | {:.4} |", sums[k].0 / n, sums[k].1 / n);
    }
    Ok(())
}
