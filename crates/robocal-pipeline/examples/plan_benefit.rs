//! What a plan buys (`just plan-benefit`): on twins of three arms, K = 30 and 60 configurations
//! chosen by `robocal plan` against 10 random sets of the same size from the same candidates,
//! each measured on the twin and calibrated (the kinematic stage, LM), the error left on check
//! poses never measured, against the twin's noise-free points; and the plan's predicted error
//! beside what the twin measures, for a twin holding only what the kinematic model holds
//! (geometry and tracker noise) and for the twin with every effect (the geometry calibrated
//! alone, and with transmission harmonics and self-weight terms planned for and calibrated);
//! D- and I-optimal plans. Twin numbers, not a real robot's.
//!
//! ```sh
//! cargo run --release -p robocal-pipeline --example plan_benefit -- [--seeds N] [--arms a,b]
//! ```

use std::path::Path;

use robocal_data::{Measurement, Sample, Silent};
use robocal_ident::{JointErrorSettings, KinematicSettings, Observations, calibrate_kinematics};
use robocal_plan::{Criterion, PlanSettings, candidates_from_limits, plan};
use robocal_twin::TwinConfig;

const ARMS: [(&str, &str); 3] = [
    ("pmc6va030", "configs/twin/pmc6va030.toml"),
    ("arm7", "configs/twin/arm7.toml"),
    ("arm5", "configs/twin/arm5.toml"),
];

fn samples(configs: &[Vec<f64>], tag: &str) -> Vec<Sample> {
    (configs.iter().enumerate())
        .map(|(i, q)| Sample {
            pose: format!("{tag}{i}"),
            joints: q.iter().map(|v| v.to_degrees()).collect(),
            load: 0.0,
            line: 0,
            target: String::new(),
            seq: None,
            last_move: Vec::new(),
        })
        .collect()
}

/// Mean error on the check poses after calibrating on `set` measured by `twin` (the
/// geometry alone, or with harmonics of order 2 and self-weight terms: `physics`).
fn held_out(
    twin: &TwinConfig,
    set: &[Vec<f64>],
    checks: &[Sample],
    check_truth: &[Measurement],
    physics: bool,
) -> Result<f64, Box<dyn std::error::Error>> {
    let (measured, _) = twin.measure_samples(&samples(set, "c"));
    let obs = Observations::from_set(&measured);
    let settings = KinematicSettings {
        joint_errors: physics.then(|| JointErrorSettings {
            harmonics: 2,
            self_weight: true,
            ..JointErrorSettings::default()
        }),
        ..KinematicSettings::default()
    };
    let fit = calibrate_kinematics(&twin.nominal, &obs, &settings)?;
    let e: f64 = (checks.iter().zip(check_truth))
        .map(|(s, t)| {
            let q = s.joints_rad();
            let p = fit
                .robot
                .point_under_load(fit.compliance.as_ref(), &q, s.load);
            (p - t.position).norm()
        })
        .sum();
    Ok(e / checks.len() as f64)
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let seeds: u64 = (args.iter().position(|a| a == "--seeds"))
        .and_then(|i| args.get(i + 1))
        .and_then(|v| v.parse().ok())
        .unwrap_or(2);
    let arms: Option<Vec<String>> = (args.iter().position(|a| a == "--arms"))
        .and_then(|i| args.get(i + 1))
        .map(|v| v.split(',').map(str::to_string).collect());
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    println!(
        "| arm | effects | criterion | seed | K | planned | random (median of 10) | change | random best / worst | predicted | measured / predicted |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|---|");
    for (name, file) in ARMS {
        if arms.as_ref().is_some_and(|a| !a.iter().any(|n| n == name)) {
            continue;
        }
        let base = TwinConfig::load(root.join(file))?;
        for (kinematic_only, physics) in [(true, false), (false, false), (false, true)] {
            let mut twin = base.clone();
            if kinematic_only {
                twin.compliance = None;
                twin.gear = None;
                twin.backlash.clear();
            }
            for (seed, criterion) in
                (0..seeds).flat_map(|s| [(s, Criterion::DOptimal), (s, Criterion::IOptimal)])
            {
                let mut settings = PlanSettings {
                    seed: 11 + seed,
                    criterion,
                    harmonics: if physics { 2 } else { 0 },
                    self_weight: physics,
                    ..PlanSettings::default()
                };
                let nominal = &twin.nominal;
                let pool =
                    candidates_from_limits(nominal, Path::new(file), &settings, 1000, 1, &Silent)?;
                let check_q =
                    candidates_from_limits(nominal, Path::new(file), &settings, 200, 2, &Silent)?;
                let checks = samples(&check_q, "k");
                let (_, check_truth) = twin.measure_samples(&checks);
                // The tracker noise the plan assumes: the twin's own, measured on the pool.
                let (noisy, exact) = twin.measure_samples(&samples(&pool, "n"));
                let d: Vec<f64> = (noisy.rows.iter().zip(&exact.rows))
                    .flat_map(|(a, b)| {
                        (a.position - b.position)
                            .iter()
                            .copied()
                            .collect::<Vec<_>>()
                    })
                    .collect();
                settings.noise_mm = (d.iter().map(|v| v * v).sum::<f64>() / d.len() as f64).sqrt();
                for count in [30, 60] {
                    let result = match plan(
                        nominal,
                        pool.clone(),
                        "pool".into(),
                        &check_q,
                        &[count],
                        &settings,
                        &Silent,
                    ) {
                        Ok(r) => r,
                        Err(e) => {
                            println!(
                                "| {name} | physics | {criterion:?} | {seed} | {count} | {e} |"
                            );
                            continue;
                        }
                    };
                    for p in &result.plans {
                        let set: Vec<Vec<f64>> =
                            p.chosen.iter().map(|&c| pool[c].clone()).collect();
                        // The planned set's error averaged over 5 noise draws (the twin's seed sets
                        // its noise), so that one lucky or unlucky draw does not decide; each
                        // random set gets a draw of its own.
                        let mut planned = 0.0;
                        for draw in 0..5 {
                            let mut noisy = twin.clone();
                            noisy.seed = twin.seed ^ (0x5eed_0000 + draw);
                            planned +=
                                held_out(&noisy, &set, &checks, &check_truth.rows, physics)? / 5.0;
                        }
                        let mut rng_sets = Vec::new();
                        let mut state = 0x9e37_79b9_7f4a_7c15u64 ^ seed;
                        for draw in 0..10u64 {
                            // A small xorshift: the random sets' draw, independent of the plan's.
                            let mut idx: Vec<usize> = (0..pool.len()).collect();
                            for i in 0..p.count {
                                state ^= state << 13;
                                state ^= state >> 7;
                                state ^= state << 17;
                                let j = i + (state % (pool.len() - i) as u64) as usize;
                                idx.swap(i, j);
                            }
                            let set: Vec<Vec<f64>> =
                                idx[..p.count].iter().map(|&c| pool[c].clone()).collect();
                            let mut noisy = twin.clone();
                            noisy.seed = twin.seed ^ (0x5eed_1000 + draw);
                            rng_sets.push(held_out(
                                &noisy,
                                &set,
                                &checks,
                                &check_truth.rows,
                                physics,
                            )?);
                        }
                        let mut sorted = rng_sets.clone();
                        sorted.sort_by(f64::total_cmp);
                        let median = 0.5 * (sorted[4] + sorted[5]);
                        println!(
                            "| {name} | {} | {criterion:?} | {seed} | {} | {planned:.4} | {median:.4} | {:+.0} % | {:.4} / {:.4} | {:.4} | {:.2} |",
                            match (kinematic_only, physics) {
                                (true, _) => "geometry + noise",
                                (false, false) => "all; geometry calibrated",
                                (false, true) =>
                                    "all; + harmonics 2 + self-weight planned and calibrated",
                            },
                            p.count,
                            100.0 * (planned / median - 1.0),
                            sorted[0],
                            sorted[9],
                            p.predicted[0],
                            planned / p.predicted[0]
                        );
                    }
                }
            }
        }
    }
    Ok(())
}
