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
//!
//! Modules: [`select`] (the default: candidates, the chain of decisions, the final fit),
//! [`folds`](mod@folds) (random folds, blocks of joint 1, the paired significance test); this
//! module fits the stages themselves.

pub mod budget;
pub mod calibrate;
pub mod folds;
pub mod outliers;
pub mod plausibility;
pub mod readings;
pub mod repeats;
pub mod select;
pub mod spread;

use std::collections::HashSet;

use nalgebra::Vector3;
use rand::SeedableRng;
use rand::seq::SliceRandom;
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use robocal_data::{ErrorStats, Measurement, Observer, Sample, Silent};
use robocal_ident::{
    FitMemo, KinematicCalibration, KinematicSettings, Observations, calibrate_kinematics_with,
};
use robocal_model::{CalibratedModel, resolve_gate_physics, with_gate_physics};
use robocal_residual::{
    GateInputs, ResidualKind, ResidualModel, ResidualSettings, ResidualStage, Samples, SearchLog,
    gate_feature_names,
};
use robocal_robot::Robot;
use serde::Serialize;

use crate::error::{PipelineError, Result};
use crate::stages::Stages;

pub use calibrate::{
    Calibration, CalibrationInput, CalibrationReport, Checks, Validation, calibrate,
};
pub use folds::{SIGNIFICANCE, blocks, folds, improves};
pub use outliers::{Outlier, OutlierReport, OutlierSettings, find_outliers, find_outliers_with};
pub use plausibility::{Implausible, check_plausible};
pub use repeats::{Repeats, repeats};
pub use select::{
    AutoSettings, Candidate, DEFAULT_BUDGET_SECONDS, DEFAULT_FOLDS, Decision,
    JOINT1_GRAVITY_ANGLE_DEG, REACH_GAIN, Selection, automatic, joint1_gravity_angle,
    residual_stages,
};

/// The geometric (and elastic) model of an identification, without a residual model, with its
/// parameters' covariance.
pub fn physical_model(calibration: &KinematicCalibration) -> CalibratedModel {
    CalibratedModel {
        covariance: calibration.covariance.clone(),
        ..CalibratedModel::new(
            calibration.robot.clone(),
            calibration.compliance.clone(),
            None,
        )
    }
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
    /// Sets of networks averaged (a SOMM of several members; 1 otherwise).
    pub members: usize,
    /// The frame its errors are in, `world` or `joint1` (turning with joint 1): the GP's and
    /// the networks' axes are that frame's.
    pub frame: &'static str,
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
    /// CA-SOMM: its classes, what the tree reads and splits on, and whether two classes paid.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub gate: Option<GateSummary>,
    /// TPE searches that chose the settings (when the stage asked for one).
    pub search: Vec<SearchLog>,
    /// The Gaussian process of each axis (a GP residual).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub gp: Vec<GpSummary>,
    /// The default calibration's check of the model's standard deviations on its folds' held-out
    /// rows, and the factor it put on them (a GP chosen by cross-validation).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub spread: Option<spread::SpreadCalibration>,
    /// The default calibration's estimate, on its folds' held-out rows, of a network's spread
    /// beside the physics' deviation (`spread_mm` in `residual.json`; a network chosen by
    /// cross-validation).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub spread_beside: Option<spread::SpreadBeside>,
}

/// The CA-SOMM gate, in the report.
#[derive(Debug, Clone, Default, Serialize)]
pub struct GateSummary {
    /// The world axis whose error splits the classes.
    pub axis: &'static str,
    /// Training errors on that axis at or above this (mm) are class B.
    pub threshold: f64,
    /// What the tree reads: `model`, `periodic` or `physics`.
    pub inputs: &'static str,
    /// Which rows each class's networks trained on: `threshold` or `routed`.
    pub classes: &'static str,
    /// Training rows in class A and class B.
    pub class_rows: [usize; 2],
    /// The tree's depth limit and fewest rows per leaf.
    pub tree: [usize; 2],
    /// Whether the tree's size was chosen on the validation rows (from how many grid points).
    pub tree_searched: usize,
    /// Mean X, Y, Z error of each class's training rows, mm.
    pub class_mean_error: [[f64; 3]; 2],
    /// The tree's splits, root first: the feature and the value below which a row goes left.
    pub splits: Vec<GateSplit>,
    /// With a fallback: whether two classes or one were kept, and why.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub decision: Option<String>,
}

/// One split of the CA-SOMM tree.
#[derive(Debug, Clone, Serialize)]
pub struct GateSplit {
    /// 0 at the root.
    pub depth: usize,
    /// The feature it reads (`payload torque j4`, `sin q1`, `load`, …).
    pub feature: String,
    /// Rows below this value go left.
    pub below: f64,
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
pub(crate) fn configurations<'a>(rows: &[&'a Measurement]) -> Vec<&'a str> {
    let mut poses: Vec<&str> = rows.iter().map(|r| r.sample.pose.as_str()).collect();
    poses.sort_unstable();
    poses.dedup();
    poses
}

/// The rows of `rows` at its lightest load: what a rigid kinematic stage is fitted on.
pub(crate) fn lightest_load_rows<'a>(rows: &[&'a Measurement]) -> Vec<&'a Measurement> {
    let lightest = (rows.iter())
        .map(|r| r.sample.load)
        .fold(f64::INFINITY, f64::min);
    (rows.iter().copied())
        .filter(|r| r.sample.load == lightest)
        .collect()
}

/// A row's joint readings, bit for bit: rows with the same key are the same configuration
/// whatever their pose ids.
pub(crate) fn readings_key(r: &Measurement) -> Vec<u64> {
    r.sample.joints.iter().map(|q| q.to_bits()).collect()
}

/// Three coordinates per configuration and reflector of `rows` (the loads add nothing to the
/// geometry), and the parameters `fit` identified (its covariance's, or the table's identified
/// entries where it kept none).
pub(crate) fn coordinates_and_parameters(
    fit: &KinematicCalibration,
    rows: &[&Measurement],
) -> (usize, usize) {
    let mut points: Vec<(&str, &str)> = (rows.iter())
        .map(|r| (r.sample.pose.as_str(), r.sample.target.as_str()))
        .collect();
    points.sort_unstable();
    points.dedup();
    let parameters = fit.covariance.as_ref().map_or_else(
        || {
            (fit.report.parameters.iter())
                .filter(|p| p.identified_flag)
                .count()
        },
        |c| c.parameters.len(),
    );
    (3 * points.len(), parameters)
}

/// The loads (kg) of `rows`, ascending, each once.
pub(crate) fn loads(rows: &[&Measurement]) -> Vec<f64> {
    let mut loads: Vec<f64> = rows.iter().map(|r| r.sample.load).collect();
    loads.sort_by(f64::total_cmp);
    loads.dedup();
    loads
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

/// [`hold_out`] for a residual stage's early stopping, or the error that the stage needs a
/// validation file.
fn early_stopping_hold_out<'a>(
    rows: &[&'a Measurement],
    share: f64,
    seed: u64,
) -> Result<(Vec<&'a Measurement>, Vec<&'a Measurement>, String)> {
    hold_out(rows, share, seed).ok_or_else(|| {
        PipelineError::Stage(
            "the residual stage needs a --validate file or at least two configurations to hold one out".into(),
        )
    })
}

/// Identifies the kinematic stage from `rows`: a rigid stage from the rows at the lightest load
/// (geometry alone, as in the paper), an elasto-geometric one from every row.
pub fn fit_kinematic(
    nominal: &Robot,
    rows: &[&Measurement],
    settings: &KinematicSettings,
) -> Result<KinematicCalibration> {
    fit_kinematic_with(nominal, rows, settings, &FitMemo::default())
}

/// [`fit_kinematic`], sharing with the other fits of the same rows the alignments and
/// identifications `memo` remembers ([`robocal_ident::calibrate_kinematics_with`]: the same
/// results, bit for bit).
pub fn fit_kinematic_with(
    nominal: &Robot,
    rows: &[&Measurement],
    settings: &KinematicSettings,
    memo: &FitMemo,
) -> Result<KinematicCalibration> {
    let obs = if settings.compliance.is_some() {
        Observations::from_rows(nominal.dof(), rows.iter().copied())
    } else {
        Observations::from_rows(nominal.dof(), lightest_load_rows(rows).into_iter())
    };
    Ok(calibrate_kinematics_with(nominal, &obs, settings, memo)?)
}

/// `settings` with a CA-SOMM gate's physics resolved against `base` (its table and joint
/// errors: [`resolve_gate_physics`]); unchanged for any other model or gate.
pub fn gate_ready(settings: &ResidualSettings, base: &CalibratedModel) -> ResidualSettings {
    let mut settings = settings.clone();
    if settings.kind == ResidualKind::CaSomm
        && settings.classifier.gate_inputs() == GateInputs::Physics
    {
        let p = resolve_gate_physics(
            &settings.classifier,
            &base.robot,
            base.joint_errors.as_ref(),
        );
        settings.classifier.gravity = Some(p.gravity);
        settings.classifier.payload_com = Some(p.payload_com);
    }
    settings
}

/// The CA-SOMM gate in the report: its classes, what it reads and splits on, and whether two
/// classes paid (`None` for any other model).
pub fn gate_summary(model: &ResidualModel, joints: usize, train: &Samples) -> Option<GateSummary> {
    let decision = model.fallback_decision();
    let Some(c) = model.classifier() else {
        return decision.map(|d| GateSummary {
            decision: Some(d),
            ..GateSummary::default()
        });
    };
    let names = gate_feature_names(c.inputs, model.encoding, joints);
    let splits = c
        .splits()
        .into_iter()
        .map(|(f, value, depth)| GateSplit {
            depth,
            feature: names
                .get(f)
                .cloned()
                .unwrap_or_else(|| format!("input {f}")),
            below: value,
        })
        .collect();
    let mut class_means = [[0.0; 3]; 2];
    let truth = c.training_classes(&model.encoding.encode_all(&train.inputs), train);
    for (class, means) in class_means.iter_mut().enumerate() {
        let rows: Vec<&[f64; 3]> = (train.errors.iter().zip(&truth))
            .filter(|(_, t)| **t == class)
            .map(|(e, _)| e)
            .collect();
        for (a, m) in means.iter_mut().enumerate() {
            *m = rows.iter().map(|e| e[a]).sum::<f64>() / rows.len().max(1) as f64;
        }
    }
    Some(GateSummary {
        axis: ["x", "y", "z"][c.axis.min(2)],
        threshold: c.threshold,
        inputs: c.inputs.name(),
        classes: c.classes.name(),
        class_rows: c.class_rows,
        tree: [c.max_depth, c.min_samples_leaf],
        tree_searched: c.tree_search.len(),
        class_mean_error: class_means,
        splits,
        decision,
    })
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
    let (fitted, report) = train_residual_reported(stage, base, train, validation, observer, true)?;
    Ok((fitted, report.expect("asked for")))
}

/// [`train_residual`] without the report: the same model, without predicting every training
/// row for the report's figures (a Gaussian process conditioned on `n` rows predicts them in
/// `n²` kernel evaluations per axis — on the paper's arm's folds, 2100 rows, a tenth of a
/// fold's training). For the default calibration's folds, which keep the model alone.
pub fn train_residual_model(
    stage: &ResidualStage,
    base: &CalibratedModel,
    train: &[&Measurement],
    observer: &dyn Observer,
) -> Result<ResidualModel> {
    train_residual_reported(stage, base, train, None, observer, false).map(|(fitted, _)| fitted)
}

fn train_residual_reported(
    stage: &ResidualStage,
    base: &CalibratedModel,
    train: &[&Measurement],
    validation: Option<(&[&Measurement], String)>,
    observer: &dyn Observer,
    reported: bool,
) -> Result<(ResidualModel, Option<ResidualReport>)> {
    let seed = stage.settings.seed;
    let settings = gate_ready(&stage.settings, base);
    let physics = settings.classifier.physics();
    let model = |s: &Sample| base.base_point(s);
    let make = |rows: &[&Measurement]| {
        let mut samples = Samples::from_model(model, rows.iter().copied());
        // In the frame the model learns in (the world's, or one turning with joint 1).
        for (e, m) in samples.errors.iter_mut().zip(rows) {
            let q = m.sample.joints_rad();
            *e = base
                .from_world(settings.frame, &q, Vector3::from(*e))
                .into();
        }
        let s: Vec<&Sample> = rows.iter().map(|m| &m.sample).collect();
        with_gate_physics(samples, &base.robot, physics.as_ref(), &s)
    };
    if settings.members > 1 && validation.is_none() {
        return train_members(stage, &settings, base, train, make, observer, reported);
    }
    let (train, val, source) = match validation {
        Some((v, source)) => (make(train), make(v), source),
        None if !settings.kind.early_stops() => (
            make(train),
            Samples::default(),
            format!(
                "none: a {} needs no early stopping and trains on every row",
                settings.kind.name()
            ),
        ),
        None => {
            let (t, v, how) = early_stopping_hold_out(train, stage.holdout, seed)?;
            (make(&t), make(&v), how)
        }
    };
    observer.start(
        "residual, epochs (at most)",
        ResidualModel::max_epochs(&stage.settings),
    );
    let fitted = ResidualModel::fit(&settings, &train, &val, observer);
    observer.finish();
    let fitted = fitted?;
    let report = reported.then(|| residual_report(&fitted, seed, source, &train, &val, base.dof()));
    Ok((fitted, report))
}

/// A SOMM of several members, member `m` trained on its own hold-out of whole configurations
/// (seeded as its networks are: [`ResidualSettings::member`]) and early-stopping on it, the
/// members as many at once as there are cores (each seeded: the same model on any number);
/// then averaged. Every row is in some member's training. The report's rows are every row
/// (the members' hold-outs differ, so none is a validation set of the average).
fn train_members<'a>(
    stage: &ResidualStage,
    settings: &ResidualSettings,
    base: &CalibratedModel,
    train: &[&'a Measurement],
    make: impl Fn(&[&'a Measurement]) -> Samples + Sync,
    observer: &dyn Observer,
    reported: bool,
) -> Result<(ResidualModel, Option<ResidualReport>)> {
    observer.message(&format!(
        "residual: {} sets of networks, each on its own hold-out",
        settings.members
    ));
    let (models, held): (Vec<ResidualModel>, Vec<usize>) = (0..settings.members)
        .into_par_iter()
        .map(|m| {
            let member = settings.member(m);
            let (t, v, _) = early_stopping_hold_out(train, stage.holdout, member.seed)?;
            let fitted = ResidualModel::fit(&member, &make(&t), &make(&v), &Silent)?;
            Ok((fitted, configurations(&v).len()))
        })
        .collect::<Result<Vec<_>>>()?
        .into_iter()
        .unzip();
    // Every member holds out the same share of the same configurations.
    let held = held[0];
    let fitted = ResidualModel::average(models)?;
    let seeds: Vec<String> = (0..settings.members)
        .map(|m| settings.member(m).seed.to_string())
        .collect();
    let source = format!(
        "{} members averaged, each early-stopping on its own {held} of {} configurations held out (seeds {})",
        settings.members,
        configurations(train).len(),
        seeds.join(", ")
    );
    let report = reported.then(|| {
        residual_report(
            &fitted,
            settings.seed,
            source,
            &make(train),
            &Samples::default(),
            base.dof(),
        )
    });
    Ok((fitted, report))
}

/// The report of a trained residual model: its training rows `train` and early-stopping rows
/// `val` (none: no validation figures) before and after it.
fn residual_report(
    fitted: &ResidualModel,
    seed: u64,
    source: String,
    train: &Samples,
    val: &Samples,
    joints: usize,
) -> ResidualReport {
    let left = |s: &Samples, predicted: Option<&[[f64; 3]]>| {
        ErrorStats::from_errors(&s.remaining(predicted))
    };
    ResidualReport {
        model: fitted.kind().name(),
        seed,
        members: fitted.members(),
        frame: fitted.frame.name(),
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
        training_before: left(train, None),
        training_after: left(train, Some(&fitted.predict(train))),
        validation_before: (!val.is_empty()).then(|| left(val, None)),
        validation_after: (!val.is_empty()).then(|| left(val, Some(&fitted.predict(val)))),
        classifier_accuracy_training: fitted.classifier_accuracy(train),
        classifier_accuracy_validation: fitted.classifier_accuracy(val),
        gate: gate_summary(fitted, joints, train),
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
        spread: None,
        spread_beside: None,
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
    /// The bad shots found before the calibration (absent when not searched).
    pub outliers: Option<OutlierReport>,
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
    configured_with(
        stages,
        nominal,
        rows,
        validation,
        observer,
        &FitMemo::default(),
    )
}

/// [`configured`], its kinematic stage sharing with the fits `memo` remembers
/// ([`fit_kinematic_with`]): the search for bad shots fits the same physics on the same rows in
/// its last round, and the calibration after it takes that fit (the same results, bit for bit).
pub fn configured_with(
    stages: &Stages,
    nominal: &Robot,
    rows: &[&Measurement],
    validation: Option<(&[&Measurement], String)>,
    observer: &dyn Observer,
    memo: &FitMemo,
) -> Result<Built> {
    let kinematic = fit_kinematic_with(nominal, rows, &stages.kinematic, memo)?;
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
        outliers: None,
    })
}
