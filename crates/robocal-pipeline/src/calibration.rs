//! `robocal calibrate` as a library: the stages a stage config asks for, or — with no config —
//! the default calibration, whose stages are chosen from the data by their error on held-out
//! poses.
//!
//! The default ([`automatic`]) scores candidate models — the nominal table with base and tool
//! fitted; kinematic identification; with joint compliances (two or more loads); with
//! transmission harmonics; with self-weight terms; residual models (GP, SOMM) on the best
//! identified one — on random folds of configurations and on blocks of joint 1's range (or the
//! `--validate` file), takes each richer one only if it lowers the held-out errors
//! significantly, fits the chosen one again on every row, and reports every candidate and
//! decision.

use std::collections::HashSet;

use rand::SeedableRng;
use rand::seq::SliceRandom;
use rand_chacha::ChaCha8Rng;
use robocal_data::{ErrorStats, Measurement, Observer, Sample, Silent};
use robocal_ident::{
    ComplianceSettings, JointErrorSettings, KinematicCalibration, KinematicSettings, Observations,
    calibrate_kinematics,
};
use robocal_model::CalibratedModel;
use robocal_residual::{
    ResidualKind, ResidualModel, ResidualSettings, ResidualStage, Samples, SearchLog,
};
use robocal_robot::Robot;
use serde::Serialize;

use crate::error::{PipelineError, Result};
use crate::stages::Stages;

/// The geometric (and elastic) model of an identification, without a residual model.
pub fn physical_model(calibration: &KinematicCalibration) -> CalibratedModel {
    CalibratedModel::new(
        calibration.robot.clone(),
        calibration.compliance.clone(),
        None,
    )
}

/// One network's training, in the report.
#[derive(Debug, Clone, Serialize)]
pub struct NetTraining {
    /// Axes it predicts (`x`, `xyz`, …).
    pub axes: String,
    /// Epochs run.
    pub epochs: usize,
    /// Epoch whose weights were kept.
    pub best_epoch: usize,
    /// Whether early stopping ended it.
    pub stopped_early: bool,
}

/// The residual stage in `report.json`.
#[derive(Debug, Clone, Serialize)]
pub struct ResidualReport {
    /// `somm`, `mosm`, `ca-somm` or `gp`.
    pub model: &'static str,
    /// Seed of the networks and of the hold-out.
    pub seed: u64,
    /// Where the early-stopping data came from.
    pub validation_source: String,
    /// Rows trained on.
    pub training_rows: usize,
    /// Rows of the early-stopping set.
    pub validation_rows: usize,
    /// Every network.
    pub networks: Vec<NetTraining>,
    /// Training rows: error after the stages before, and after the residual too.
    pub training_before: ErrorStats,
    /// See `training_before`.
    pub training_after: ErrorStats,
    /// Early-stopping rows, before and after.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub validation_before: Option<ErrorStats>,
    /// See `validation_before`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub validation_after: Option<ErrorStats>,
    /// CA-SOMM: share of rows the classifier puts in their true class.
    pub classifier_accuracy_training: Option<f64>,
    /// See `classifier_accuracy_training`.
    pub classifier_accuracy_validation: Option<f64>,
    /// TPE searches that chose the settings (when the stage asked for one).
    pub search: Vec<SearchLog>,
    /// The Gaussian process of each axis (a GP residual).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub gp: Vec<GpSummary>,
}

/// One axis's Gaussian process, in the report.
#[derive(Debug, Clone, Serialize)]
pub struct GpSummary {
    /// `x`, `y` or `z`.
    pub axis: &'static str,
    /// Rows it conditions on.
    pub rows: usize,
    /// Standard deviation of the learned error, mm (the kernel's signal).
    pub signal_std: f64,
    /// Standard deviation of what it takes as noise, mm.
    pub noise_std: f64,
    /// Length-scale of each standardised feature (sin q1, cos q1, …, load): short means the
    /// error changes fast with it, long that it hardly depends on it.
    pub lengthscales: Vec<f64>,
    /// Negative log marginal likelihood per row on the hyper-parameter subset.
    pub nll_per_row: f64,
}

/// The configurations (pose ids) of `rows`, sorted, each once.
fn configurations<'a>(rows: &[&'a Measurement]) -> Vec<&'a str> {
    let mut poses: Vec<&str> = rows.iter().map(|r| r.sample.pose.as_str()).collect();
    poses.sort_unstable();
    poses.dedup();
    poses
}

/// Splits `rows` into (kept, held out) by whole configurations: `share` of them (at least one,
/// never all), drawn by `seed`. `None` when there are fewer than two configurations.
pub fn hold_out<'a>(
    rows: &[&'a Measurement],
    share: f64,
    seed: u64,
) -> Option<(Vec<&'a Measurement>, Vec<&'a Measurement>, String)> {
    let mut poses = configurations(rows);
    if poses.len() < 2 {
        return None;
    }
    poses.shuffle(&mut ChaCha8Rng::seed_from_u64(seed));
    let n = ((poses.len() as f64 * share).round() as usize).clamp(1, poses.len() - 1);
    let held: HashSet<&str> = poses[..n].iter().copied().collect();
    let (out, kept): (Vec<&Measurement>, Vec<&Measurement>) = rows
        .iter()
        .partition(|r| held.contains(r.sample.pose.as_str()));
    let how = format!(
        "{n} of {} configurations held out (seed {seed})",
        poses.len()
    );
    Some((kept, out, how))
}

/// Identifies the kinematic stage from `rows`: a rigid stage from the rows at the lightest load
/// (geometry alone, as in the paper), an elasto-geometric one from every row.
pub fn fit_kinematic(
    nominal: &Robot,
    rows: &[&Measurement],
    settings: &KinematicSettings,
) -> Result<KinematicCalibration> {
    let obs = if settings.compliance.is_some() {
        Observations::from_rows(nominal.dof(), rows.iter().copied())
    } else {
        let lightest = rows
            .iter()
            .map(|r| r.sample.load)
            .fold(f64::INFINITY, f64::min);
        Observations::from_rows(
            nominal.dof(),
            rows.iter().copied().filter(|r| r.sample.load == lightest),
        )
    };
    Ok(calibrate_kinematics(nominal, &obs, settings)?)
}

/// Trains a residual stage on what `base` leaves of `train`; early stopping on `validation`
/// (rows and where they came from), or on a hold-out of whole configurations of `train`.
pub fn train_residual(
    stage: &ResidualStage,
    base: &CalibratedModel,
    train: &[&Measurement],
    validation: Option<(&[&Measurement], String)>,
    observer: &dyn Observer,
) -> Result<(ResidualModel, ResidualReport)> {
    let seed = stage.settings.seed;
    let model = |s: &Sample| base.base_point(s);
    let (train, val, source) = match validation {
        Some((v, source)) => (
            Samples::from_model(model, train.iter().copied()),
            Samples::from_model(model, v.iter().copied()),
            source,
        ),
        None if !stage.settings.kind.early_stops() => (
            Samples::from_model(model, train.iter().copied()),
            Samples::default(),
            format!(
                "none: a {} needs no early stopping and trains on every row",
                stage.settings.kind.name()
            ),
        ),
        None => {
            let Some((t, v, how)) = hold_out(train, stage.holdout, seed) else {
                return Err(PipelineError::Stage(
                    "the residual stage needs a --validate file or at least two configurations to hold one out".into(),
                ));
            };
            (
                Samples::from_model(model, t),
                Samples::from_model(model, v),
                how,
            )
        }
    };
    observer.start(
        "residual, epochs (at most)",
        ResidualModel::max_epochs(&stage.settings),
    );
    let fitted = ResidualModel::fit(&stage.settings, &train, &val, observer);
    observer.finish();
    let fitted = fitted?;
    let left = |s: &Samples, predicted: Option<&[[f64; 3]]>| {
        ErrorStats::from_errors(&s.remaining(predicted))
    };
    let report = ResidualReport {
        model: stage.settings.kind.name(),
        seed,
        validation_source: source,
        training_rows: train.len(),
        validation_rows: val.len(),
        networks: (fitted.nets().into_iter())
            .map(|n| NetTraining {
                axes: n.axes_name(),
                epochs: n.report.epochs,
                best_epoch: n.report.best_epoch,
                stopped_early: n.report.stopped_early,
            })
            .collect(),
        training_before: left(&train, None),
        training_after: left(&train, Some(&fitted.predict(&train.inputs))),
        validation_before: (!val.is_empty()).then(|| left(&val, None)),
        validation_after: (!val.is_empty()).then(|| left(&val, Some(&fitted.predict(&val.inputs)))),
        classifier_accuracy_training: fitted.classifier().map(|c| c.accuracy(&train)),
        classifier_accuracy_validation: fitted.classifier().map(|c| c.accuracy(&val)),
        search: fitted.search.clone(),
        gp: fitted.gp().map_or_else(Vec::new, |g| {
            (g.axes.iter().zip(["x", "y", "z"]))
                .map(|(a, axis)| GpSummary {
                    axis,
                    rows: g.rows.len(),
                    signal_std: a.signal_variance.sqrt() * a.target_std,
                    noise_std: a.noise_variance.sqrt() * a.target_std,
                    lengthscales: a.lengthscales.clone(),
                    nll_per_row: a.nll_per_row,
                })
                .collect()
        }),
    };
    Ok((fitted, report))
}

/// What the default calibration decided about one stage.
#[derive(Debug, Clone, Serialize)]
pub struct Decision {
    /// `kinematic`, `compliance` or `residual`.
    pub stage: &'static str,
    /// Whether the stage is in the model.
    pub kept: bool,
    /// Held-out score (see [`Candidate::score`]) of the best candidate without the stage, mm
    /// (absent when the stage was not tried).
    pub held_out_without: Option<f64>,
    /// Held-out score of the best candidate with the stage, mm.
    pub held_out_with: Option<f64>,
    /// Why.
    pub reason: String,
}

/// One candidate model of the default calibration and its held-out error.
#[derive(Debug, Clone, Serialize)]
pub struct Candidate {
    /// What it stacks, e.g. `kinematic + compliance + gp`.
    pub name: String,
    /// Statistics of every held-out row's error over the random folds (each row held out
    /// once), or on the validation file, mm; absent when the candidate was skipped.
    pub held_out: Option<ErrorStats>,
    /// The same over the blocks of joint 1's range (each row held out once), mm.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub held_out_blocks: Option<ErrorStats>,
    /// What the choice compares, mm: the mean of the two means (the random folds' mean alone
    /// with a validation file).
    pub score: Option<f64>,
    /// Seconds its folds took.
    pub seconds: f64,
    /// `chosen`, `evaluated`, or why it was skipped.
    pub status: String,
}

/// How the default calibration chose its stages.
#[derive(Debug, Clone, Serialize)]
pub struct Selection {
    /// Where the held-out poses came from.
    pub held_out: String,
    /// Folds: the random ones and the blocks of joint 1 (1 with a validation file).
    pub folds: usize,
    /// Rows the candidates were fitted on, summed over the folds.
    pub fitted_rows: usize,
    /// Rows held out, summed over the folds (every row twice in cross-validation: once in a
    /// random fold, once in a block).
    pub held_out_rows: usize,
    /// Every candidate, in the order tried.
    pub candidates: Vec<Candidate>,
    /// One per stage, in order.
    pub decisions: Vec<Decision>,
    /// Whether the chosen candidate was fitted again on every row of the data file (always,
    /// unless a validation file was given or there were too few configurations to hold any
    /// out).
    pub refitted_on_every_row: bool,
    /// The time budget, s, and what the selection took.
    pub budget_seconds: f64,
    /// See `budget_seconds`.
    pub seconds: f64,
}

/// Settings of the default calibration.
#[derive(Debug, Clone, PartialEq)]
pub struct AutoSettings {
    /// Folds of the cross-validation over configurations (when no validation file is given).
    pub folds: usize,
    /// Seed of the folds (and of the residual models).
    pub seed: u64,
    /// Fewest configurations (in the data, or in each fold's training part) for which a
    /// residual model is tried.
    pub min_residual_configurations: usize,
    /// Transmission harmonics up to this order tried with the geometry (0: not tried).
    pub harmonics: u32,
    /// Self-weight terms tried with the geometry.
    pub self_weight: bool,
    /// The residual models tried, each on top of the best physical model.
    pub residuals: Vec<ResidualStage>,
    /// Seconds the selection may take: a candidate whose folds would run past it (projected
    /// from its first fold) is abandoned, and none starts after it. The only setting that
    /// depends on the clock: far under budget, a seed gives the same model.
    pub budget_seconds: f64,
}

/// Folds of the default cross-validation.
pub const DEFAULT_FOLDS: usize = 5;

/// The default selection's time budget, s.
pub const DEFAULT_BUDGET_SECONDS: f64 = 120.0;

impl Default for AutoSettings {
    fn default() -> Self {
        let seed = robocal_residual::DEFAULT_SEED;
        Self {
            folds: DEFAULT_FOLDS,
            seed,
            min_residual_configurations: 40,
            harmonics: 2,
            self_weight: true,
            residuals: vec![
                ResidualStage {
                    settings: ResidualSettings::gp(seed),
                    holdout: 0.2,
                },
                ResidualStage {
                    settings: ResidualSettings::paper(ResidualKind::Somm, seed),
                    holdout: 0.2,
                },
            ],
            budget_seconds: DEFAULT_BUDGET_SECONDS,
        }
    }
}

/// A calibrated model and what made it.
#[derive(Debug)]
pub struct Built {
    /// The kinematic (or elasto-geometric) identification in the model.
    pub kinematic: KinematicCalibration,
    /// The residual stage, if one is in the model.
    pub residual: Option<(ResidualModel, ResidualReport)>,
    /// The stages, as a stage config would give them.
    pub stages: Stages,
    /// How the default calibration chose the stages (absent with a stage config).
    pub selection: Option<Selection>,
}

impl Built {
    /// The calibrated model.
    pub fn model(&self) -> CalibratedModel {
        CalibratedModel {
            residual: self.residual.as_ref().map(|(m, _)| m.clone()),
            ..physical_model(&self.kinematic)
        }
    }
}

/// Runs the stages of a stage config on `rows` (early stopping on `validation` when given).
pub fn configured(
    stages: &Stages,
    nominal: &Robot,
    rows: &[&Measurement],
    validation: Option<(&[&Measurement], String)>,
    observer: &dyn Observer,
) -> Result<Built> {
    let kinematic = fit_kinematic(nominal, rows, &stages.kinematic)?;
    let base = physical_model(&kinematic);
    let residual = stages
        .residual
        .as_ref()
        .map(|stage| train_residual(stage, &base, rows, validation, observer))
        .transpose()?;
    Ok(Built {
        kinematic,
        residual,
        stages: stages.clone(),
        selection: None,
    })
}

/// The fold (0..k) of every row: configurations shuffled with `seed` and dealt round-robin, so
/// that every load of a configuration falls in one fold. `k` is capped at the number of
/// configurations.
pub fn folds(rows: &[&Measurement], k: usize, seed: u64) -> (Vec<usize>, usize) {
    let mut poses = configurations(rows);
    poses.shuffle(&mut ChaCha8Rng::seed_from_u64(seed));
    let k = k.clamp(1, poses.len().max(1));
    let fold: std::collections::HashMap<&str, usize> =
        poses.iter().enumerate().map(|(i, p)| (*p, i % k)).collect();
    (
        rows.iter()
            .map(|r| fold.get(r.sample.pose.as_str()).copied().unwrap_or(0))
            .collect(),
        k,
    )
}

/// The physical part of a candidate.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct Physics {
    /// Only base and tool fitted to the nominal table.
    aligned: bool,
    /// Joint compliances under the payload.
    compliance: bool,
    /// Transmission harmonics up to this order.
    harmonics: u32,
    /// Self-weight terms.
    self_weight: bool,
}

impl Physics {
    const ALIGNED: Self = Self {
        aligned: true,
        compliance: false,
        harmonics: 0,
        self_weight: false,
    };
    const RIGID: Self = Self {
        aligned: false,
        ..Self::ALIGNED
    };

    fn name(self) -> String {
        if self.aligned {
            return "nominal (base and tool fitted)".into();
        }
        let mut name = String::from("kinematic");
        if self.compliance {
            name += " + compliance";
        }
        if self.harmonics > 0 {
            name += &format!(" + harmonics {}", self.harmonics);
        }
        if self.self_weight {
            name += " + self-weight";
        }
        name
    }

    fn settings(self) -> KinematicSettings {
        KinematicSettings {
            compliance: self.compliance.then(ComplianceSettings::default),
            joint_errors: (self.harmonics > 0 || self.self_weight).then(|| JointErrorSettings {
                harmonics: self.harmonics,
                self_weight: self.self_weight,
                ..JointErrorSettings::default()
            }),
            ..KinematicSettings::default()
        }
    }

    /// The model of this physics from the identification that made it.
    fn model(self, fit: &KinematicCalibration) -> CalibratedModel {
        if self.aligned {
            CalibratedModel::kinematic(fit.aligned.clone())
        } else {
            physical_model(fit)
        }
    }
}

/// A physical candidate scored on every fold.
struct Scored {
    physics: Physics,
    /// Selection score (none when a fold's fit failed).
    score: Option<f64>,
    /// Every held-out error ([`Held::all`]; none when a fold's fit failed).
    errors: Option<Vec<f64>>,
    /// The fitted model of each fold.
    fitted: Vec<Option<CalibratedModel>>,
}

/// Whether `new` (held-out errors) lowers `base`'s significantly: the mean over groups (a
/// configuration in one kind of fold: its rows share one pose; `groups` numbers them from 0)
/// of base − new is positive and more than [`SIGNIFICANCE`] times its standard error. A stage
/// that helps by less than the spread of the difference is not worth its parameters: on poses
/// beyond those measured it can do harm.
pub fn improves(base: &[f64], new: &[f64], groups: &[usize]) -> bool {
    let n_groups = groups.iter().copied().max().map_or(0, |g| g + 1);
    let mut sums = vec![0.0; n_groups];
    let mut counts = vec![0usize; n_groups];
    for ((b, n), &g) in base.iter().zip(new).zip(groups) {
        sums[g] += b - n;
        counts[g] += 1;
    }
    let d: Vec<f64> = (sums.iter().zip(&counts))
        .filter(|(_, c)| **c > 0)
        .map(|(s, c)| s / *c as f64)
        .collect();
    let n = d.len() as f64;
    let mean = d.iter().sum::<f64>() / n.max(1.0);
    if d.len() < 2 {
        return mean > 0.0;
    }
    let var = d.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1.0);
    mean > 0.0 && mean > SIGNIFICANCE * (var / n).sqrt()
}

/// How many standard errors a stage's held-out improvement must exceed to be kept.
pub const SIGNIFICANCE: f64 = 2.0;

/// Fits `physics` on every fold and scores it on the fold's held-out rows.
fn score_physics(
    physics: Physics,
    nominal: &Robot,
    splits: &[Fold<'_>],
    candidates: &mut Vec<Candidate>,
    observer: &dyn Observer,
) -> Scored {
    let t = std::time::Instant::now();
    let kinematic = physics.settings();
    let mut held = Held::default();
    let mut fitted = Vec::new();
    let mut failure = None;
    for fold in splits {
        observer.advance(1);
        match fit_kinematic(nominal, &fold.train, &kinematic) {
            Ok(fit) => {
                let model = physics.model(&fit);
                held.add(fold, model.errors(&fold.test));
                fitted.push(Some(model));
            }
            Err(e) => {
                failure = Some(format!("skipped: {e}"));
                fitted.push(None);
            }
        }
    }
    let mut c = Candidate {
        name: physics.name(),
        held_out: None,
        held_out_blocks: None,
        score: None,
        seconds: t.elapsed().as_secs_f64(),
        status: failure.clone().unwrap_or_else(|| "evaluated".into()),
    };
    if failure.is_none() {
        let (random, blocked, score) = held.summary();
        (c.held_out, c.held_out_blocks, c.score) = (Some(random), blocked, Some(score));
    }
    report(&c, observer);
    let score = c.score;
    candidates.push(c);
    Scored {
        physics,
        score,
        errors: score.map(|_| held.all()),
        fitted,
    }
}

/// Says a candidate's held-out numbers, or why it was skipped.
fn report(c: &Candidate, observer: &dyn Observer) {
    observer.message(&match (&c.held_out, &c.held_out_blocks) {
        (Some(h), Some(b)) => format!(
            "candidate {}: held-out mean {:.4} mm (max {:.4}) on random folds, {:.4} mm (max {:.4}) on blocks of joint 1 ({:.1} s)",
            c.name, h.mean, h.max, b.mean, b.max, c.seconds
        ),
        (Some(h), None) => format!(
            "candidate {}: held-out mean {:.4} mm, max {:.4} mm ({:.1} s)",
            c.name, h.mean, h.max, c.seconds
        ),
        _ => format!("candidate {}: {}", c.name, c.status),
    });
}

/// One split of the rows: fitted on `train`, scored on `test`.
struct Fold<'a> {
    train: Vec<&'a Measurement>,
    test: Vec<&'a Measurement>,
    /// A block of joint 1's range (extrapolation), not a random fold.
    blocked: bool,
}

/// The rows of every fold of `fold_of` (`k` folds) as train/test splits.
fn splits_of<'a>(
    rows: &[&'a Measurement],
    fold_of: &[usize],
    k: usize,
    blocked: bool,
) -> Vec<Fold<'a>> {
    (0..k)
        .map(|f| {
            let (test, train) =
                (rows.iter().zip(fold_of)).partition::<Vec<_>, _>(|(_, g)| **g == f);
            Fold {
                train: train.into_iter().map(|(r, _)| *r).collect(),
                test: test.into_iter().map(|(r, _)| *r).collect(),
                blocked,
            }
        })
        .collect()
}

/// The block (0..k) of every row: configurations sorted by their joint-1 reading and cut into
/// `k` contiguous blocks of (nearly) equal count, so that each block's poses lie outside the
/// joint-1 range of the rest — how a cell's working area grows. `k` is capped at the number
/// of configurations.
pub fn blocks(rows: &[&Measurement], k: usize) -> (Vec<usize>, usize) {
    let mut poses: Vec<(&str, f64)> = rows
        .iter()
        .map(|r| {
            (
                r.sample.pose.as_str(),
                r.sample.joints.first().copied().unwrap_or(0.0),
            )
        })
        .collect();
    poses.sort_by(|a, b| a.0.cmp(b.0));
    poses.dedup_by(|a, b| a.0 == b.0);
    poses.sort_by(|a, b| a.1.total_cmp(&b.1).then(a.0.cmp(b.0)));
    let n = poses.len();
    let k = k.clamp(1, n.max(1));
    let block: std::collections::HashMap<&str, usize> = (poses.iter().enumerate())
        .map(|(i, p)| (p.0, i * k / n.max(1)))
        .collect();
    (
        rows.iter()
            .map(|r| block.get(r.sample.pose.as_str()).copied().unwrap_or(0))
            .collect(),
        k,
    )
}

/// Held-out errors of one candidate, split by the kind of fold.
#[derive(Default)]
struct Held {
    random: Vec<f64>,
    blocked: Vec<f64>,
}

impl Held {
    fn add(&mut self, fold: &Fold<'_>, errors: Vec<f64>) {
        if fold.blocked {
            self.blocked.extend(errors);
        } else {
            self.random.extend(errors);
        }
    }

    /// Every held-out error: the random folds', then the blocks'.
    fn all(&self) -> Vec<f64> {
        let mut all = self.random.clone();
        all.extend(&self.blocked);
        all
    }

    /// The candidate's statistics: random folds, blocks, and the selection score (the mean of
    /// the two means; the random folds' mean alone without blocks).
    fn summary(&self) -> (ErrorStats, Option<ErrorStats>, f64) {
        let random = ErrorStats::from_errors(&self.random);
        if self.blocked.is_empty() {
            return (random, None, random.mean);
        }
        let blocked = ErrorStats::from_errors(&self.blocked);
        (random, Some(blocked), 0.5 * (random.mean + blocked.mean))
    }
}

/// The default calibration: every candidate model — the nominal table with base and tool
/// fitted; kinematic identification; with joint compliances (two or more loads); with
/// transmission harmonics, with self-weight terms; each residual model of `settings` on top of
/// the best identified one — is scored by its error on held-out poses: the mean of its mean
/// over k random folds of configurations (interpolation) and over k contiguous blocks of joint
/// 1's range (extrapolation to a new working area), or its mean on the `validation` rows.
/// The choice is a chain — identified table, compliance, harmonics, self-weight, the best
/// residual model — each step taken only if it lowers the held-out errors significantly
/// ([`improves`]); the model it ends on is fitted again on every row. `say` hears a line per
/// candidate and per decision.
pub fn automatic(
    settings: &AutoSettings,
    nominal: &Robot,
    rows: &[&Measurement],
    validation: Option<(&[&Measurement], String)>,
    observer: &dyn Observer,
) -> Result<Built> {
    let start = std::time::Instant::now();
    let n_configurations = configurations(rows).len();
    let (splits, held_out, refit) = match &validation {
        Some((v, source)) => (
            vec![Fold {
                train: rows.to_vec(),
                test: v.to_vec(),
                blocked: false,
            }],
            source.clone(),
            false,
        ),
        None if n_configurations >= 4 => {
            let (fold_of, k) = folds(rows, settings.folds, settings.seed);
            let mut splits = splits_of(rows, &fold_of, k, false);
            let (block_of, kb) = blocks(rows, settings.folds);
            splits.extend(splits_of(rows, &block_of, kb, true));
            (
                splits,
                format!(
                    "{k}-fold cross-validation over {n_configurations} configurations (seed {}), and {kb} blocks of joint 1's range",
                    settings.seed
                ),
                true,
            )
        }
        None => {
            // Too few poses to hold any out: the kinematic stage alone, on everything.
            observer
                .message("too few configurations to hold any out: kinematic identification only");
            let stages = Stages::default();
            let mut built = configured(&stages, nominal, rows, None, observer)?;
            built.selection = Some(Selection {
                held_out: "none: fewer than 4 configurations".into(),
                folds: 0,
                fitted_rows: rows.len(),
                held_out_rows: 0,
                candidates: Vec::new(),
                decisions: vec![Decision {
                    stage: "kinematic",
                    kept: true,
                    held_out_without: None,
                    held_out_with: None,
                    reason: "kept untested: too few configurations to hold any out".into(),
                }],
                refitted_on_every_row: false,
                budget_seconds: settings.budget_seconds,
                seconds: start.elapsed().as_secs_f64(),
            });
            return Ok(built);
        }
    };
    let over_budget = |spent: f64| start.elapsed().as_secs_f64() + spent > settings.budget_seconds;
    let mut candidates: Vec<Candidate> = Vec::new();
    // The progress bar counts fits: every candidate on every fold, and the final one.
    observer.start(
        "candidates × folds fitted",
        (splits.len() * (5 + settings.residuals.len()) + 1) as u64,
    );

    // The physical models, each scored on every fold: the nominal table, the identified one,
    // with compliances (two or more loads); then, on the better identified one, transmission
    // harmonics, then self-weight terms, each kept for the next step only if it lowers the
    // held-out error.
    let mut loads: Vec<f64> = rows.iter().map(|r| r.sample.load).collect();
    loads.sort_by(f64::total_cmp);
    loads.dedup();
    let mut scored = vec![
        score_physics(
            Physics::ALIGNED,
            nominal,
            &splits,
            &mut candidates,
            observer,
        ),
        score_physics(Physics::RIGID, nominal, &splits, &mut candidates, observer),
    ];
    let mut compliance_skip = None;
    if loads.len() >= 2 {
        let elastic = Physics {
            compliance: true,
            ..Physics::RIGID
        };
        scored.push(score_physics(
            elastic,
            nominal,
            &splits,
            &mut candidates,
            observer,
        ));
    } else {
        compliance_skip = Some(format!(
            "skipped: the data hold one load ({} kg); compliance needs two or more",
            loads.first().copied().unwrap_or(0.0)
        ));
    }
    // One group per configuration and kind of fold, in the order the errors are kept.
    let groups: Vec<usize> = {
        let mut ids: std::collections::HashMap<(&str, bool), usize> = Default::default();
        let mut out = Vec::new();
        for blocked in [false, true] {
            for fold in splits.iter().filter(|f| f.blocked == blocked) {
                for r in &fold.test {
                    let next = ids.len();
                    out.push(*ids.entry((r.sample.pose.as_str(), blocked)).or_insert(next));
                }
            }
        }
        out
    };
    // The chain: each richer model replaces the current one only if it lowers the held-out
    // errors significantly.
    let better = |current: &Scored, next: &Scored| match (&current.errors, &next.errors) {
        (Some(c), Some(n)) => improves(c, n, &groups),
        (None, Some(_)) => true,
        _ => false,
    };
    let mut current = usize::from(better(&scored[0], &scored[1]));
    if scored.len() > 2 && better(&scored[current], &scored[2]) {
        current = 2;
    }
    let identified = |current: usize, scored: &[Scored]| {
        if scored[current].physics.aligned {
            1
        } else {
            current
        }
    };
    for step in [
        Physics {
            harmonics: settings.harmonics,
            ..Physics::RIGID
        },
        Physics {
            self_weight: settings.self_weight,
            ..Physics::RIGID
        },
    ] {
        if step.harmonics == 0 && !step.self_weight {
            continue;
        }
        let base = scored[identified(current, &scored)].physics;
        let next = Physics {
            harmonics: base.harmonics.max(step.harmonics),
            self_weight: base.self_weight || step.self_weight,
            ..base
        };
        scored.push(score_physics(
            next,
            nominal,
            &splits,
            &mut candidates,
            observer,
        ));
        if better(&scored[current], &scored[scored.len() - 1]) {
            current = scored.len() - 1;
        }
    }
    let physics: Vec<Physics> = scored.iter().map(|s| s.physics).collect();
    let physics_scores: Vec<Option<f64>> = scored.iter().map(|s| s.score).collect();
    let best_physics = current;
    // Residual models learn what an identified model leaves.
    let base_physics = identified(current, &scored);

    // Residual models on top of the best physics.
    let fewest = splits
        .iter()
        .map(|f| configurations(&f.train).len())
        .min()
        .unwrap_or(0);
    let mut residual_scores: Vec<(usize, Option<f64>, bool)> = Vec::new();
    for (r, stage) in settings.residuals.iter().enumerate() {
        let name = format!(
            "{} + {}",
            physics[base_physics].name(),
            stage.settings.kind.name()
        );
        let mut c = Candidate {
            name,
            held_out: None,
            held_out_blocks: None,
            score: None,
            seconds: 0.0,
            status: String::new(),
        };
        if fewest < settings.min_residual_configurations {
            c.status = format!(
                "skipped: {fewest} configurations to train on; a residual model needs at least {}",
                settings.min_residual_configurations
            );
        } else if over_budget(0.0) {
            c.status = format!(
                "skipped: the time budget ({} s) is spent",
                settings.budget_seconds
            );
        } else {
            let mut held = Held::default();
            let mut abandoned = None;
            for (f, fold) in splits.iter().enumerate() {
                let t = std::time::Instant::now();
                let Some(base) = &scored[base_physics].fitted[f] else {
                    abandoned = Some("skipped: its physical model failed on a fold".to_string());
                    break;
                };
                observer.advance(1);
                let (model, _) = train_residual(stage, base, &fold.train, None, &Silent)?;
                let candidate = CalibratedModel {
                    residual: Some(model),
                    ..base.clone()
                };
                held.add(fold, candidate.errors(&fold.test));
                let took = t.elapsed().as_secs_f64();
                c.seconds += took;
                // The remaining folds and the final fit, at this fold's pace.
                let left = (splits.len() - f) as f64 * took;
                if f + 1 < splits.len() && over_budget(left) {
                    abandoned = Some(format!(
                        "abandoned: its folds would run past the time budget ({} s)",
                        settings.budget_seconds
                    ));
                    break;
                }
            }
            let mut significant = false;
            match abandoned {
                Some(why) => c.status = why,
                None => {
                    let (random, blocked, score) = held.summary();
                    (c.held_out, c.held_out_blocks, c.score) = (Some(random), blocked, Some(score));
                    significant = scored[best_physics]
                        .errors
                        .as_ref()
                        .is_some_and(|base| improves(base, &held.all(), &groups));
                    c.status = if significant {
                        "evaluated".into()
                    } else {
                        "evaluated: not significantly better than the physical model".into()
                    };
                }
            }
            report(&c, observer);
            residual_scores.push((r, c.score, significant));
            candidates.push(c);
            continue;
        }
        report(&c, observer);
        residual_scores.push((r, c.score, false));
        candidates.push(c);
    }
    let best_residual = residual_scores
        .iter()
        .filter_map(|(r, s, _)| s.map(|s| (*r, s)))
        .min_by(|a, b| a.1.total_cmp(&b.1));

    // The winner: the best residual model if it is significantly better than the physical
    // model, else the physical model the chain ended on.
    let physics_mean = physics_scores[best_physics].unwrap_or(f64::INFINITY);
    let residual_wins = best_residual.filter(|(r, m)| {
        *m < physics_mean && residual_scores.iter().any(|(q, _, sig)| q == r && *sig)
    });
    let (winner, chosen_physics) = match residual_wins {
        Some((r, _)) => (physics.len() + r, physics[base_physics]),
        None => (best_physics, physics[best_physics]),
    };
    candidates[winner].status = "chosen".into();
    // The lowest score among the physical candidates `which` accepts.
    let best_where = |which: &dyn Fn(&Physics) -> bool| {
        (0..physics.len())
            .filter(|&i| which(&physics[i]))
            .filter_map(|i| physics_scores[i])
            .min_by(f64::total_cmp)
    };
    let mut decisions = Vec::new();
    let decision =
        |stage: &'static str, kept: bool, without: Option<f64>, with: Option<f64>, what: &str| {
            let reason = match (without, with) {
                (Some(w), Some(x)) => format!(
                    "{}: held-out score {w:.4} mm without, {x:.4} mm with {what}{}",
                    if kept { "kept" } else { "dropped" },
                    if !kept && x < w {
                        " (lower, but not by more than twice its standard error)"
                    } else {
                        ""
                    }
                ),
                _ => what.to_string(),
            };
            Decision {
                stage,
                kept,
                held_out_without: without,
                held_out_with: with,
                reason,
            }
        };
    let kept_kinematic = !chosen_physics.aligned;
    decisions.push(decision(
        "kinematic",
        kept_kinematic,
        best_where(&|p| p.aligned),
        best_where(&|p| !p.aligned),
        "the identified table (LM, identifiable parameters)",
    ));
    let has_errors = |p: &Physics| p.harmonics > 0 || p.self_weight;
    decisions.push(match (&compliance_skip, best_where(&|p| p.compliance)) {
        (Some(why), _) => decision("compliance", false, None, None, why),
        (None, None) => decision(
            "compliance",
            false,
            None,
            None,
            &(candidates.iter())
                .find(|c| c.name == "kinematic + compliance")
                .map_or("skipped".to_string(), |c| c.status.clone()),
        ),
        (None, Some(with)) => decision(
            "compliance",
            chosen_physics.compliance,
            best_where(&|p| !p.aligned && !p.compliance),
            Some(with),
            "joint compliances identified with the geometry on every load",
        ),
    });
    decisions.push(match best_where(&has_errors) {
        None => decision(
            "joint_errors",
            false,
            None,
            None,
            "not tried (no harmonics or self-weight in the settings), or every fit failed",
        ),
        Some(with) => decision(
            "joint_errors",
            has_errors(&chosen_physics),
            best_where(&|p| !p.aligned && !has_errors(p)),
            Some(with),
            &format!(
                "transmission harmonics{} identified with the geometry",
                if settings.self_weight {
                    " and self-weight terms"
                } else {
                    ""
                }
            ),
        ),
    });
    decisions.push(match best_residual {
        Some((r, mean)) => decision(
            "residual",
            residual_wins.is_some(),
            Some(physics_mean),
            Some(mean),
            &format!(
                "a {} residual model (the best of {} tried)",
                settings.residuals[r].settings.kind.name(),
                settings.residuals.len()
            ),
        ),
        None => decision(
            "residual",
            false,
            Some(physics_mean),
            None,
            &candidates
                .get(physics.len())
                .map_or("skipped: no residual model configured".to_string(), |c| {
                    c.status.clone()
                }),
        ),
    });
    for d in &decisions {
        observer.message(&format!("stage {}: {}", d.stage, d.reason));
    }
    observer.message(&format!(
        "chosen: {} (held-out score {:.4} mm)",
        candidates[winner].name,
        candidates[winner].score.unwrap_or(f64::NAN)
    ));

    // Fit the winner on every row (with a validation file: on the data file's rows, the
    // validation file early-stopping the networks as it always has).
    let stages = Stages {
        kinematic: chosen_physics.settings(),
        residual: residual_wins.map(|(r, _)| settings.residuals[r].clone()),
    };
    if refit {
        observer.message("fitting the chosen model again on every row");
    }
    let mut built = configured(&stages, nominal, rows, validation.clone(), &Silent)?;
    observer.advance(1);
    observer.finish();
    if chosen_physics.aligned {
        built.kinematic.robot = built.kinematic.aligned.clone();
        built.kinematic.compliance = None;
    }
    built.selection = Some(Selection {
        held_out,
        folds: splits.len(),
        fitted_rows: splits.iter().map(|f| f.train.len()).sum(),
        held_out_rows: splits.iter().map(|f| f.test.len()).sum(),
        candidates,
        decisions,
        refitted_on_every_row: refit,
        budget_seconds: settings.budget_seconds,
        seconds: start.elapsed().as_secs_f64(),
    });
    Ok(built)
}

#[cfg(test)]
mod tests {
    use super::improves;

    /// The paired test by group, computed by hand: differences per group 0.2, 0.1, 0.3 (mean
    /// 0.2, standard error 0.0577) pass; with a group that got worse, 0.2, 0.1, −0.4 (mean
    /// −0.033) fail; a small, consistent gain passes and an inconsistent one does not.
    #[test]
    fn improvement_must_exceed_twice_its_standard_error() {
        let groups = [0, 0, 1, 2, 2];
        let base = [1.0, 1.0, 1.0, 1.0, 1.0];
        assert!(improves(&base, &[0.8, 0.8, 0.9, 0.7, 0.7], &groups));
        assert!(!improves(&base, &[0.8, 0.8, 0.9, 1.4, 1.4], &groups));
        // Mean 0.01, standard error 0.0029: 3.5 standard errors.
        assert!(improves(
            &[1.0, 1.0, 1.0],
            &[0.99, 0.995, 0.985],
            &[0, 1, 2]
        ));
        // Mean 0.01, standard error 0.0173: 0.6 standard errors.
        assert!(!improves(&[1.0, 1.0, 1.0], &[0.96, 1.02, 0.99], &[0, 1, 2]));
    }
}
