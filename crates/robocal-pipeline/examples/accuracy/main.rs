//! robocal's accuracy suite (`just accuracy`): the default calibration, and each stage alone, on
//! twins of several arms (by default the development families: the paper's arm, ARM7, ARM5,
//! ARM5W, ARM5 on a wall, and ARM5T, ARM5 on a pedestal inclined 45°), several seeds, with the twins' effects all on or only those the physical model
//! family holds, on a split of configurations and on an extrapolation split. Errors are measured
//! against the twins' noise-free points on poses never trained on; the noise floor is the
//! measured points' own distance from those.
//!
//! ```sh
//! cargo run --release -p robocal-pipeline --example accuracy -- [--seeds N] [--arms a,b] [--aside]
//!     [--write FILE [--section NAME]]
//!     [--effects all,modelled,beyond] [--budget S] [--no-compensation] [--verbose] [--networks]
//!     [--physics full] [--export DIR] [--poses N] [--splits configurations,q1,window]
//!     [--beyond-scale K]
//! ```
//!
//! The effect sets: *all* (what the twin file holds: every effect robocal's physics models),
//! *modelled only* (geometry, compliance, noise) and *beyond the model* (all, and effects a
//! real arm holds that robocal's physics does not: bearing tilt under the gravity moment, axis
//! runout, a third gear harmonic, a coupled wrist; [`beyond`]), where only a learned residual
//! model can take what the physics leaves.
//!
//! Every twin is a twin's; none of these numbers is a real robot's. The families of [`ASIDE`]
//! are kept aside: they run only with `--aside` (or `--arms`), never while tuning.
//! `--networks` prints the residual models side by side on the identified physics instead
//! (SOMM with the paper's and robocal's settings, robocal's CA-SOMM, the GP); with
//! `--physics full`, on the default's fullest physical candidate (backlash and the links'
//! weights too).
//! `--export DIR` writes every case's files instead (`DIR/ARM-sSEED-EFFECTS-SPLIT/`: the nominal
//! `robot.toml`, `train.csv`, `test.csv`, and `truth.csv` with the test rows' noise-free points),
//! for the outside pipeline of `scripts/peer/lm_mlp.py`.

mod cases;

use nalgebra::Vector3;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use robocal_calibration::DEFAULT_BUDGET_SECONDS;
use robocal_calibration::{AutoSettings, Stages, automatic};
use robocal_calibration::{
    configured, fit_kinematic, hold_out, physical_model, train_residual_model,
};
use robocal_data::{ErrorStats, Measurement, MeasurementSet, Observer, Silent};
use robocal_ident::{ComplianceSettings, JointErrorSettings, KinematicSettings};
use robocal_pipeline::CalibratedModel;
use robocal_residual::{ResidualKind, ResidualSettings, ResidualStage};
use robocal_twin::TwinConfig;
use std::path::{Path, PathBuf};
use std::time::Instant;

use cases::{ARMS, ASIDE, Effects, Split, case_twin, member, ring, root, split, truth_of};

/// Mean error of `model` against the noise-free points of `test` (`truth`: pose/load → point).
fn versus_truth(
    model: &CalibratedModel,
    test: &[&Measurement],
    truth: &std::collections::HashMap<(String, u64), Vector3<f64>>,
) -> ErrorStats {
    let predicted = model.predict(test.iter().map(|m| &m.sample));
    let errors: Vec<f64> = (predicted.iter().zip(test))
        .map(|(p, m)| (p - truth[&(m.sample.pose.clone(), m.sample.load.to_bits())]).norm())
        .collect();
    ErrorStats::from_errors(&errors)
}

/// robocal 0.1's default calibration, the baseline of the suite's "robocal 0.1" column:
/// stages tried in order — kinematic, compliance (two or more loads), SOMM with the paper's
/// settings (40 or more configurations) — on one seeded 20 % hold-out of configurations, each
/// kept if it lowers the held-out mean, the kept ones fitted again on every row.
fn previous_default(
    nominal: &robocal_robot::Robot,
    rows: &[&Measurement],
) -> Result<CalibratedModel, Box<dyn std::error::Error>> {
    let rigid = KinematicSettings::default();
    let Some((fit, held, _)) = hold_out(rows, 0.2, 2020) else {
        return Ok(configured(&Stages::default(), nominal, rows, None, &Silent)?.model());
    };
    let mean = |m: &CalibratedModel| m.stats(&held).mean;
    let kin = fit_kinematic(nominal, &fit, &rigid)?;
    let aligned = CalibratedModel::kinematic(kin.aligned.clone());
    let mut best = aligned.clone();
    let mut chosen = Stages::default();
    let mut identified = false;
    let k = physical_model(&kin);
    if mean(&k) < mean(&best) {
        best = k;
        identified = true;
    }
    let elastic = KinematicSettings {
        compliance: Some(ComplianceSettings::default()),
        ..rigid.clone()
    };
    let mut loads: Vec<f64> = fit.iter().map(|r| r.sample.load).collect();
    loads.sort_by(f64::total_cmp);
    loads.dedup();
    if loads.len() >= 2
        && let Ok(e) = fit_kinematic(nominal, &fit, &elastic)
    {
        let e = physical_model(&e);
        if mean(&e) < mean(&best) {
            best = e;
            identified = true;
            chosen.kinematic = elastic;
        }
    }
    let mut poses: Vec<&str> = fit.iter().map(|r| r.sample.pose.as_str()).collect();
    poses.sort_unstable();
    poses.dedup();
    if poses.len() >= 40 {
        let stage = ResidualStage {
            settings: ResidualSettings::paper(ResidualKind::Somm, 2020),
            holdout: 0.2,
        };
        let model = train_residual_model(&stage, &best, &fit, &Silent)?;
        let with = CalibratedModel {
            residual: Some(model),
            ..best.clone()
        };
        if mean(&with) < mean(&best) {
            chosen.residual = Some(stage);
        }
    }
    let mut built = configured(&chosen, nominal, rows, None, &Silent)?;
    if !identified {
        built.kinematic.robot = built.kinematic.aligned.clone();
        built.kinematic.compliance = None;
    }
    Ok(built.model())
}

/// Writes one case for an outside pipeline: `robot.toml` (the nominal table), `train.csv`,
/// `test.csv` (measured) and `truth.csv` (the test rows' noise-free points) in `dir/case`.
fn export_case(
    dir: &Path,
    case: &str,
    nominal: &robocal_robot::Robot,
    train: &[&Measurement],
    test: &[&Measurement],
    truth: &std::collections::HashMap<(String, u64), Vector3<f64>>,
) -> Result<(), Box<dyn std::error::Error>> {
    let out = dir.join(case);
    std::fs::create_dir_all(&out)?;
    std::fs::write(out.join("robot.toml"), nominal.to_toml_string())?;
    let set = |rows: Vec<Measurement>| MeasurementSet {
        source: PathBuf::new(),
        joint_count: nominal.joints.len(),
        rows,
    };
    set(train.iter().map(|m| (*m).clone()).collect()).write(out.join("train.csv"))?;
    set(test.iter().map(|m| (*m).clone()).collect()).write(out.join("test.csv"))?;
    set(test
        .iter()
        .map(|m| Measurement {
            position: truth[&(m.sample.pose.clone(), m.sample.load.to_bits())],
            ..(*m).clone()
        })
        .collect())
    .write(out.join("truth.csv"))?;
    Ok(())
}

/// The number after `flag` in `args` (none without the flag), or an error naming the flag and
/// what it was given.
fn number<T: std::str::FromStr>(args: &[String], flag: &str) -> Result<Option<T>, String>
where
    T::Err: std::fmt::Display,
{
    let text = (args.iter().position(|a| a == flag)).and_then(|i| args.get(i + 1));
    (text.map(|s| s.parse().map_err(|e| format!("{flag}: `{s}`: {e}")))).transpose()
}

/// What the suite printed on stdout, for `--write`.
static PRINTED: std::sync::Mutex<String> = std::sync::Mutex::new(String::new());

/// `println!`, and the line kept for `--write`.
macro_rules! out {
    () => {
        out!("")
    };
    ($($arg:tt)*) => {{
        let line = format!($($arg)*);
        println!("{line}");
        let mut printed = PRINTED.lock().unwrap_or_else(|e| e.into_inner());
        printed.push_str(&line);
        printed.push('\n');
    }};
}

/// Runs the suite; with `--write FILE` its tables replace the section of FILE between
/// `<!-- SECTION:begin -->` and `<!-- SECTION:end -->` (`--section SECTION`, default
/// `twins-suite`), so that the page holds what this code measured.
fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let value = |flag: &str| {
        args.iter()
            .position(|a| a == flag)
            .and_then(|i| args.get(i + 1).cloned())
    };
    let write = value("--write").map(PathBuf::from);
    let section = value("--section").unwrap_or_else(|| "twins-suite".into());
    if let Some(path) = &write {
        // Checked before hours of calibrations, not after.
        marked_section(&std::fs::read_to_string(path)?, &section, "").ok_or_else(|| {
            format!(
                "{}: no `<!-- {section}:begin -->` … `<!-- {section}:end -->` section",
                path.display()
            )
        })?;
    }
    suite()?;
    if let Some(path) = write {
        let page = std::fs::read_to_string(&path)?;
        let printed = PRINTED.lock().unwrap_or_else(|e| e.into_inner()).clone();
        let command = format!(
            "Written by `cargo run --release -p robocal-pipeline --example accuracy -- {}`.\n\n",
            args.join(" ")
        );
        let page = marked_section(&page, &section, &(command + printed.trim_end()))
            .expect("checked before the suite ran");
        std::fs::write(&path, page)?;
    }
    Ok(())
}

/// `page` with the text between `<!-- SECTION:begin -->` and `<!-- SECTION:end -->` replaced by
/// `text`; `None` where the page has no such section.
fn marked_section(page: &str, section: &str, text: &str) -> Option<String> {
    let (begin, end) = (
        format!("<!-- {section}:begin -->"),
        format!("<!-- {section}:end -->"),
    );
    let (head, rest) = page.split_once(&begin)?;
    let (_, tail) = rest.split_once(&end)?;
    Some(format!("{head}{begin}\n{text}\n{end}{tail}"))
}

fn suite() -> Result<(), Box<dyn std::error::Error>> {
    let SuiteArgs {
        seeds,
        compensation,
        verbose,
        networks,
        full_physics,
        budget_seconds,
        export,
        poses,
        beyond_scale,
        effect_sets,
        splits,
        arms,
        outliers,
    } = suite_args()?;
    let mut landings: Vec<(String, u64, Effects, Landing)> = Vec::new();
    if outliers {
        return bad_shots(&arms, seeds);
    }
    if networks {
        out!(
            "| arm | seed | effects | split | test rows | noise floor | physics | + SOMM (paper) | s | + SOMM (robocal) | s | + CA-SOMM (robocal) | s | + GP | s |"
        );
        out!("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|");
    } else {
        out!(
            "| arm | seed | effects | split | test rows | noise floor | robocal 0.1 default | kinematic | + compliance | + compliance + harmonics + self-weight | that + GP | default | against robocal 0.1 | default's choice | default s |"
        );
        out!("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|");
    }
    for (name, file) in ARMS.iter().filter(|a| arms.iter().any(|n| n == a.0)) {
        let base = TwinConfig::load(root().join(file))?;
        for seed in 0..seeds {
            for &effects in &effect_sets {
                let twin = case_twin(&base, seed, effects, poses, beyond_scale);
                let boxed = twin.generate()?;
                let ringed = (splits.contains(&Split::Window))
                    .then(|| ring(&twin).generate())
                    .transpose()?;
                for &how in &splits {
                    let data = match (&ringed, how) {
                        (Some(ringed), Split::Window) => ringed,
                        _ => &boxed,
                    };
                    let truth = truth_of(data);
                    let rows: Vec<&Measurement> = data.measurements.rows.iter().collect();
                    let (train, test) = split(&rows, how, seed);
                    if let Some(dir) = &export {
                        export_case(
                            dir,
                            &format!(
                                "{name}-s{seed}-{}-{}",
                                effects.key(),
                                match how {
                                    Split::Configurations => "configurations",
                                    Split::Extrapolation => "q1",
                                    Split::Window => "window",
                                }
                            ),
                            &twin.nominal,
                            &train,
                            &test,
                            &truth,
                        )?;
                        continue;
                    }
                    let floor = {
                        let e: Vec<f64> = test
                            .iter()
                            .map(|m| {
                                (m.position
                                    - truth[&(m.sample.pose.clone(), m.sample.load.to_bits())])
                                    .norm()
                            })
                            .collect();
                        ErrorStats::from_errors(&e).mean
                    };
                    let score = |stages: &Stages| -> String {
                        match configured(stages, &twin.nominal, &train, None, &Silent) {
                            Ok(b) => {
                                format!("{:.4}", versus_truth(&b.model(), &test, &truth).mean)
                            }
                            Err(e) => format!("failed ({e})"),
                        }
                    };
                    if networks {
                        let (e, h) = (effects.label(), split_label(how));
                        let row = networks_row(&score, full_physics);
                        out!(
                            "| {name} | {seed} | {e} | {h} | {} | {floor:.4} | {row}",
                            test.len()
                        );
                        continue;
                    }
                    let kin = score(&stage(0, None));
                    let comp = score(&stage(1, None));
                    let physics = score(&stage(2, None));
                    let gp = score(&stage(2, Some(ResidualSettings::gp(2020))));
                    let previous =
                        versus_truth(&previous_default(&twin.nominal, &train)?, &test, &truth).mean;
                    let prefix = format!("{name} {seed}");
                    let (model, choice, secs) =
                        run_default(&twin, &train, budget_seconds, &prefix, verbose)?;
                    let default = versus_truth(&model, &test, &truth).mean;
                    if compensation && effects != Effects::Modelled && how == Split::Configurations
                    {
                        landings.push((
                            name.to_string(),
                            seed,
                            effects,
                            land(&twin, &model, &test),
                        ));
                    }
                    let (e, h) = (effects.label(), split_label(how));
                    out!(
                        "| {name} | {seed} | {e} | {h} | {} | {floor:.4} | {previous:.4} | {kin} | {comp} | {physics} | {gp} | **{default:.4}** | {:+.0} % | {choice} | {secs:.1} |",
                        test.len(),
                        100.0 * (default / previous - 1.0),
                    );
                }
            }
        }
    }
    if !landings.is_empty() {
        out!();
        out!(
            "Compensation (every effect, and beyond the model; configuration split): each test row's noise-free point, moved by (1.2, -1.0, 1.2) mm, is a target; the default model's commands from the row's reading as seed, executed by the twin without noise."
        );
        out!();
        out!("| arm | seed | effects | targets | mean before | mean after | max after |");
        out!("|---|---|---|---|---|---|---|");
        for (name, seed, effects, (n, before, after, max)) in landings {
            out!(
                "| {name} | {seed} | {} | {n} | {before:.4} | {after:.4} | {max:.4} |",
                effects.label()
            );
        }
    }
    Ok(())
}

/// The default calibration's lines on stderr, prefixed with the twin and seed (`--verbose`).
struct Prefixed {
    prefix: String,
    verbose: bool,
}

impl Observer for Prefixed {
    fn message(&self, line: &str) {
        if self.verbose {
            eprintln!("{}: {line}", self.prefix);
        }
    }
}

/// Targets reached, mean distance at the seed, mean and max after compensation, mm.
type Landing = (usize, f64, f64, f64);

/// Compensation through `model`: every test row's true point is a target, the row's reading the
/// seed; where the twin really puts the point at the command, against the target. Returns
/// (targets reached, mean distance at the seed, mean after, max after), mm.
fn land(twin: &TwinConfig, model: &CalibratedModel, test: &[&Measurement]) -> Landing {
    use robocal_compensate::{CompensationOptions, compensate};
    let options = CompensationOptions::default();
    let (mut before, mut after) = (Vec::new(), Vec::new());
    for m in test {
        let q = m.sample.joints_rad();
        let target = twin.true_point(&q, m.sample.load);
        // Aim at a point 2 mm off the one the reading reaches, so that the command must move.
        let target = target + Vector3::new(1.2, -1.0, 1.2);
        if let Ok(c) = compensate(model, &target, m.sample.load, &m.sample.joints, &options) {
            let q: Vec<f64> = c.joints_deg.iter().map(|d| d.to_radians()).collect();
            before.push((twin.true_point(&m.sample.joints_rad(), m.sample.load) - target).norm());
            after.push((twin.true_point(&q, m.sample.load) - target).norm());
        }
    }
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len().max(1) as f64;
    let max = after.iter().copied().fold(0.0, f64::max);
    (after.len(), mean(&before), mean(&after), max)
}

/// `--outliers`: on each twin (all effects, the configuration split's training rows, at most
/// 500), the largest clean row's error in robust standard deviations and the rows the default
/// search flags (none should be); then 1 to 3 bad shots of 20–50 mm added to random rows:
/// which the search names, and the default calibration's error on the test rows (against the
/// truth) with them against without.
fn bad_shots(arms: &[String], seeds: u64) -> Result<(), Box<dyn std::error::Error>> {
    use robocal_calibration::{OutlierSettings, find_outliers};
    out!(
        "| arm | seed | rows | largest clean row (robust σ) | clean rows flagged | bad shots | named | missed | clean flagged with them | test mean clean | with bad shots | change |"
    );
    out!("|---|---|---|---|---|---|---|---|---|---|---|---|");
    for (name, file) in ARMS.iter().filter(|a| arms.iter().any(|n| n == a.0)) {
        let base = TwinConfig::load(root().join(file))?;
        for seed in 0..seeds {
            let twin = member(&base, seed);
            let data = twin.generate()?;
            let truth = truth_of(&data);
            let rows: Vec<&Measurement> = data.measurements.rows.iter().collect();
            let (train, test) = split(&rows, Split::Configurations, seed);
            let train: Vec<Measurement> = train.into_iter().take(500).cloned().collect();
            let clean: Vec<&Measurement> = train.iter().collect();
            let all = OutlierSettings {
                threshold: 0.0,
                rounds: 1,
                keep: true,
            };
            let kinematic = KinematicSettings::default();
            let (ratios, _) = find_outliers(&twin.nominal, &clean, &kinematic, &all)?;
            let largest = ratios.rows.iter().map(|o| o.sigmas).fold(0.0, f64::max);
            let (found, _) = find_outliers(
                &twin.nominal,
                &clean,
                &kinematic,
                &OutlierSettings::default(),
            )?;
            let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0xBAD);
            let k = 1 + (seed as usize % 3);
            let mut dirty = train.clone();
            let mut shot = Vec::new();
            while shot.len() < k {
                let i = rng.random_range(0..dirty.len());
                if shot.contains(&i) {
                    continue;
                }
                let d = Vector3::new(
                    rng.random_range(-1.0..1.0),
                    rng.random_range(-1.0..1.0),
                    rng.random_range(-1.0..1.0),
                )
                .normalize();
                dirty[i].position += d * rng.random_range(20.0..50.0);
                shot.push(i);
            }
            let dirty_rows: Vec<&Measurement> = dirty.iter().collect();
            let (named, _) = find_outliers(
                &twin.nominal,
                &dirty_rows,
                &kinematic,
                &OutlierSettings::default(),
            )?;
            let is_shot = |o: &robocal_calibration::Outlier| {
                shot.iter()
                    .any(|&i| dirty[i].sample.pose == o.pose && dirty[i].sample.load == o.load)
            };
            let hit = named.rows.iter().filter(|o| is_shot(o)).count();
            let wrong = named.rows.len() - hit;
            let mean = |rows: &[&Measurement]| -> Result<f64, Box<dyn std::error::Error>> {
                let built =
                    automatic(&AutoSettings::default(), &twin.nominal, rows, None, &Silent)?;
                Ok(versus_truth(&built.model(), &test, &truth).mean)
            };
            let (a, b) = (mean(&clean)?, mean(&dirty_rows)?);
            out!(
                "| {name} | {seed} | {} | {largest:.1} | {} | {k} | {hit} | {} | {wrong} | {a:.4} | {b:.4} | {:+.1} % |",
                clean.len(),
                found.rows.len(),
                k - hit,
                100.0 * (b / a - 1.0)
            );
        }
    }
    Ok(())
}

/// Physics 0: kinematic; 1: + compliance; 2: + harmonics 2 and per-joint
/// self-weight; 3: the default's fullest candidate (compliance held
/// plausible, harmonics 2, the links' weights and the payload's centre of
/// mass, backlash on either flank). Every one with the compliances finds an
/// arm on a wall or a ceiling as the default does.
fn stage(physics: u8, residual: Option<ResidualSettings>) -> Stages {
    Stages {
        kinematic: KinematicSettings {
            compliance: match physics {
                0 => None,
                1 | 2 => Some(ComplianceSettings {
                    detect_mounting: true,
                    ..ComplianceSettings::default()
                }),
                _ => Some(ComplianceSettings {
                    plausible_only: true,
                    detect_mounting: true,
                    identify_payload_com: true,
                    ..ComplianceSettings::default()
                }),
            },
            joint_errors: (physics >= 2).then(|| JointErrorSettings {
                harmonics: 2,
                self_weight: physics == 2,
                link_weights: physics >= 3,
                backlash: physics >= 3,
                ..JointErrorSettings::default()
            }),
            ..KinematicSettings::default()
        },
        residual: residual.map(|settings| ResidualStage {
            settings,
            holdout: 0.2,
        }),
        default: None,
    }
}

/// The columns of a `--networks` row after the noise floor: the physics alone, then each
/// residual model with its seconds, `score` scoring a stage config on the case.
fn networks_row(score: &dyn Fn(&Stages) -> String, full_physics: bool) -> String {
    let timed = |stages: &Stages| {
        let t = Instant::now();
        let e = score(stages);
        (e, t.elapsed().as_secs_f64())
    };
    let level = if full_physics { 3 } else { 2 };
    let (physics, _) = timed(&stage(level, None));
    let (paper, paper_s) = timed(&stage(
        level,
        Some(ResidualSettings::paper(ResidualKind::Somm, 2020)),
    ));
    let (ours, ours_s) = timed(&stage(
        level,
        Some(ResidualSettings::robocal(ResidualKind::Somm, 2020)),
    ));
    let (gated, gated_s) = timed(&stage(
        level,
        Some(ResidualSettings::robocal(ResidualKind::CaSomm, 2020)),
    ));
    let (gp, gp_s) = timed(&stage(level, Some(ResidualSettings::gp(2020))));
    format!(
        "{physics} | {paper} | {paper_s:.1} | {ours} | {ours_s:.1} | {gated} | {gated_s:.1} | {gp} | {gp_s:.1} |"
    )
}

/// The suite's command-line arguments (see the module's documentation).
struct SuiteArgs {
    seeds: u64,
    compensation: bool,
    verbose: bool,
    /// Residual models side by side on the identified physics, instead of the default.
    networks: bool,
    /// With `networks`: on the default's fullest physical candidate (backlash, the links'
    /// weights) instead of compliance + harmonics + per-joint self-weight.
    full_physics: bool,
    /// The default's time budget, s.
    budget_seconds: f64,
    /// Every case's files for an outside pipeline (scripts/peer), instead of the table.
    export: Option<PathBuf>,
    /// More configurations than the twin file's: a larger member of each family.
    poses: Option<usize>,
    /// The effects beyond the model made this many times as large.
    beyond_scale: f64,
    effect_sets: Vec<Effects>,
    splits: Vec<Split>,
    arms: Vec<String>,
    /// The bad shots' table instead.
    outliers: bool,
}

/// Reads the suite's arguments.
fn suite_args() -> Result<SuiteArgs, Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let value = |flag: &str| {
        args.iter()
            .position(|a| a == flag)
            .and_then(|i| args.get(i + 1).cloned())
    };
    let seeds: u64 = number(&args, "--seeds")?.unwrap_or(2);
    let aside = args.iter().any(|a| a == "--aside");
    let compensation = !args.iter().any(|a| a == "--no-compensation");
    let verbose = args.iter().any(|a| a == "--verbose");
    // Residual models side by side on the identified physics, instead of the default.
    let networks = args.iter().any(|a| a == "--networks");
    // With `--networks`: on the default's fullest physical candidate (backlash, the links'
    // weights) instead of compliance + harmonics + per-joint self-weight.
    let full_physics = value("--physics").is_some_and(|p| p == "full");
    // The default's time budget, s (`--budget`; robocal's default otherwise).
    let budget_seconds: f64 = number(&args, "--budget")?.unwrap_or(DEFAULT_BUDGET_SECONDS);
    // Every case's files for an outside pipeline (scripts/peer), instead of the table.
    let export = value("--export").map(PathBuf::from);
    // More configurations than the twin file's (`--poses N`): a larger member of each family,
    // its grid made finer by the cube root of the ratio so that enough points are measurable.
    let poses: Option<usize> = number(&args, "--poses")?;
    // The effects beyond the model made K times as large (`--beyond-scale K`; 1 otherwise).
    let beyond_scale: f64 = number(&args, "--beyond-scale")?.unwrap_or(1.0);
    if !(beyond_scale > 0.0 && beyond_scale.is_finite()) {
        return Err(format!("--beyond-scale: {beyond_scale} is not a positive number").into());
    }
    // Which effect sets (`--effects all,modelled,beyond`; default every one).
    let effect_sets: Vec<Effects> = match value("--effects") {
        Some(list) => list
            .split(',')
            .map(|k| {
                (Effects::EVERY.into_iter().find(|e| e.key() == k))
                    .ok_or_else(|| format!("--effects: unknown effect set `{k}`"))
            })
            .collect::<Result<_, _>>()?,
        None => Effects::EVERY.to_vec(),
    };
    // Which splits (`--splits configurations,q1,window`; default the first two).
    let splits: Vec<Split> = match value("--splits") {
        Some(list) => list
            .split(',')
            .map(|k| match k {
                "configurations" => Ok(Split::Configurations),
                "q1" => Ok(Split::Extrapolation),
                "window" => Ok(Split::Window),
                _ => Err(format!(
                    "--splits: unknown split `{k}` (configurations, q1, window)"
                )),
            })
            .collect::<Result<_, _>>()?,
        None => vec![Split::Configurations, Split::Extrapolation],
    };
    let arms: Vec<String> = match value("--arms") {
        Some(list) => list.split(',').map(str::to_string).collect(),
        None => ARMS
            .iter()
            .map(|a| a.0.to_string())
            .filter(|a| aside || !ASIDE.contains(&a.as_str()))
            .collect(),
    };
    Ok(SuiteArgs {
        seeds,
        compensation,
        verbose,
        networks,
        full_physics,
        budget_seconds,
        export,
        poses,
        beyond_scale,
        effect_sets,
        splits,
        arms,
        outliers: args.iter().any(|a| a == "--outliers"),
    })
}

/// The default calibration on `train` within `budget_seconds`, its lines prefixed with `prefix`
/// where `verbose`: the model, the name of its choice (checked against what the model holds),
/// and its seconds.
fn run_default(
    twin: &TwinConfig,
    train: &[&Measurement],
    budget_seconds: f64,
    prefix: &str,
    verbose: bool,
) -> Result<(CalibratedModel, String, f64), Box<dyn std::error::Error>> {
    let t = Instant::now();
    let built = automatic(
        &AutoSettings {
            budget_seconds,
            ..AutoSettings::default()
        },
        &twin.nominal,
        train,
        None,
        &Prefixed {
            prefix: prefix.to_string(),
            verbose,
        },
    )?;
    let secs = t.elapsed().as_secs_f64();
    let choice = built
        .selection
        .as_ref()
        .and_then(|s| s.chosen())
        .map_or("?".to_string(), |c| c.name.clone());
    // The choice's name is what the model holds.
    let terms =
        |kind: &str| (built.kinematic.report.joint_errors.iter()).any(|t| t.name.contains(kind));
    assert_eq!(terms(".h"), choice.contains("harmonics"), "{choice}");
    // Self-weight: per-joint terms (`j2.sw3.x`) or the links' weights (`link3.x`).
    assert_eq!(
        terms(".sw") || terms("link"),
        choice.contains("self-weight"),
        "{choice}"
    );
    // A residual model, in either frame (`… + gp (world frame)`).
    assert_eq!(
        built.residual.is_some(),
        choice.contains(" + gp") || choice.contains(" + somm"),
        "{choice}"
    );
    Ok((built.model(), choice, secs))
}

/// A split's name in the table.
fn split_label(how: Split) -> &'static str {
    match how {
        Split::Configurations => "configurations",
        Split::Extrapolation => "extrapolation (q1)",
        Split::Window => "window (joint 1 −60…30°)",
    }
}
