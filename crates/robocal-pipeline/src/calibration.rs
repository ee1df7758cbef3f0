//! `robocal calibrate` as a library: the stages a stage config asks for, or — with no config —
//! the default calibration, whose stages are chosen from the data by their error on held-out
//! poses.
//!
//! The default tries, in order: kinematic identification (LM, the identifiable parameters);
//! joint compliances identified with the geometry, when the data hold two or more loads; a
//! residual model (SOMM, the paper's settings), when there are enough configurations. Each
//! stage is kept only if it lowers the mean error on the held-out poses (the `--validate` file,
//! or a seeded hold-out of whole configurations), and the report says what was kept and why.
//! When the hold-out was carved from the data, the kept stages are fitted again on every row.

use std::collections::HashSet;

use indicatif::ProgressBar;
use nalgebra::Vector3;
use rand::SeedableRng;
use rand::seq::SliceRandom;
use rand_chacha::ChaCha8Rng;
use robocal_data::{ErrorStats, Measurement, Sample};
use robocal_ident::{
    ComplianceSettings, KinematicCalibration, KinematicSettings, Observations, calibrate_kinematics,
};
use robocal_residual::{
    ResidualKind, ResidualModel, ResidualSettings, ResidualStage, Samples, SearchLog, inputs_of,
};
use robocal_robot::{Compliance, Robot};
use serde::Serialize;

use crate::error::{PipelineError, Result};
use crate::stages::Stages;

/// A model that predicts the target point: a table, joint compliances, a residual model.
#[derive(Debug, Clone)]
pub struct Predictor {
    /// Kinematic table.
    pub robot: Robot,
    /// Joint compliance under the payload.
    pub compliance: Option<Compliance>,
    /// What the rest leaves, learned.
    pub residual: Option<ResidualModel>,
}

impl Predictor {
    /// The geometric (and elastic) model of an identification, without a residual model.
    pub fn kinematic(calibration: &KinematicCalibration) -> Self {
        Self {
            robot: calibration.robot.clone(),
            compliance: calibration.compliance.clone(),
            residual: None,
        }
    }

    /// The table and compliance part of the prediction, mm, world frame.
    pub fn base_point(&self, s: &Sample) -> Vector3<f64> {
        (self.robot).point_under_load(self.compliance.as_ref(), &s.joints_rad(), s.load)
    }

    /// Predicted points for `samples`, mm, world frame (the residual model in one batch).
    pub fn predict<'a>(&self, samples: impl IntoIterator<Item = &'a Sample>) -> Vec<Vector3<f64>> {
        let samples: Vec<&Sample> = samples.into_iter().collect();
        let mut points: Vec<Vector3<f64>> = samples.iter().map(|s| self.base_point(s)).collect();
        if let Some(residual) = &self.residual {
            let inputs: Vec<Vec<f64>> = samples.iter().map(|s| inputs_of(s)).collect();
            for (p, e) in points.iter_mut().zip(residual.predict(&inputs)) {
                *p += Vector3::from(e);
            }
        }
        points
    }

    /// Error statistics on measured rows.
    pub fn stats(&self, rows: &[&Measurement]) -> ErrorStats {
        let predicted = self.predict(rows.iter().map(|m| &m.sample));
        let errors: Vec<f64> = (predicted.iter().zip(rows))
            .map(|(p, m)| (p - m.position).norm())
            .collect();
        ErrorStats::from_errors(&errors)
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
    /// `somm`, `mosm` or `ca-somm`.
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
    pub validation_before: ErrorStats,
    /// See `validation_before`.
    pub validation_after: ErrorStats,
    /// CA-SOMM: share of rows the classifier puts in their true class.
    pub classifier_accuracy_training: Option<f64>,
    /// See `classifier_accuracy_training`.
    pub classifier_accuracy_validation: Option<f64>,
    /// TPE searches that chose the settings (when the stage asked for one).
    pub search: Vec<SearchLog>,
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
    base: &Predictor,
    train: &[&Measurement],
    validation: Option<(&[&Measurement], String)>,
    bar: Option<&ProgressBar>,
) -> Result<(ResidualModel, ResidualReport)> {
    let seed = stage.settings.seed;
    let model = |s: &Sample| base.base_point(s);
    let (train, val, source) = match validation {
        Some((v, source)) => (
            Samples::from_model(model, train.iter().copied()),
            Samples::from_model(model, v.iter().copied()),
            source,
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
    let fitted = ResidualModel::fit(&stage.settings, &train, &val, bar)?;
    let left = |s: &Samples, predicted: Option<&[[f64; 3]]>| {
        ErrorStats::from_errors(&s.remaining(predicted))
    };
    let report = ResidualReport {
        model: stage.settings.kind.name(),
        seed,
        validation_source: source,
        training_rows: train.len(),
        validation_rows: val.len(),
        networks: (fitted.nets.iter())
            .map(|n| NetTraining {
                axes: n.axes_name(),
                epochs: n.report.epochs,
                best_epoch: n.report.best_epoch,
                stopped_early: n.report.stopped_early,
            })
            .collect(),
        training_before: left(&train, None),
        training_after: left(&train, Some(&fitted.predict(&train.inputs))),
        validation_before: left(&val, None),
        validation_after: left(&val, Some(&fitted.predict(&val.inputs))),
        classifier_accuracy_training: fitted.classifier.as_ref().map(|c| c.accuracy(&train)),
        classifier_accuracy_validation: fitted.classifier.as_ref().map(|c| c.accuracy(&val)),
        search: fitted.search.clone(),
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
    /// Mean error on the held-out poses of the model without the stage, mm (absent when the
    /// stage was not tried).
    pub held_out_without: Option<f64>,
    /// Mean error on the held-out poses with the stage, mm.
    pub held_out_with: Option<f64>,
    /// Why.
    pub reason: String,
}

/// How the default calibration chose its stages.
#[derive(Debug, Clone, Serialize)]
pub struct Selection {
    /// Where the held-out poses came from.
    pub held_out: String,
    /// Rows the stages were fitted on while choosing.
    pub fitted_rows: usize,
    /// Held-out rows.
    pub held_out_rows: usize,
    /// One per stage, in order.
    pub decisions: Vec<Decision>,
    /// Whether the kept stages were fitted again on every row of the data file.
    pub refitted_on_every_row: bool,
}

/// Settings of the default calibration.
#[derive(Debug, Clone, PartialEq)]
pub struct AutoSettings {
    /// Share of configurations held out when no validation file is given.
    pub holdout: f64,
    /// Seed of the hold-out (and of the residual networks).
    pub seed: u64,
    /// Fewest training configurations for which a residual model is tried.
    pub min_residual_configurations: usize,
    /// The residual stage tried.
    pub residual: ResidualStage,
}

impl Default for AutoSettings {
    fn default() -> Self {
        Self {
            holdout: 0.2,
            seed: robocal_residual::DEFAULT_SEED,
            min_residual_configurations: 40,
            residual: ResidualStage {
                settings: ResidualSettings::paper(
                    ResidualKind::Somm,
                    robocal_residual::DEFAULT_SEED,
                ),
                holdout: 0.2,
            },
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
    /// The model.
    pub fn predictor(&self) -> Predictor {
        Predictor {
            residual: self.residual.as_ref().map(|(m, _)| m.clone()),
            ..Predictor::kinematic(&self.kinematic)
        }
    }
}

/// Runs the stages of a stage config on `rows` (early stopping on `validation` when given).
pub fn configured(
    stages: &Stages,
    nominal: &Robot,
    rows: &[&Measurement],
    validation: Option<(&[&Measurement], String)>,
    bar: Option<&ProgressBar>,
) -> Result<Built> {
    let kinematic = fit_kinematic(nominal, rows, &stages.kinematic)?;
    let base = Predictor::kinematic(&kinematic);
    let residual = stages
        .residual
        .as_ref()
        .map(|stage| train_residual(stage, &base, rows, validation, bar))
        .transpose()?;
    Ok(Built {
        kinematic,
        residual,
        stages: stages.clone(),
        selection: None,
    })
}

/// The default calibration: see the module documentation. `say` hears a line per decision.
pub fn automatic(
    settings: &AutoSettings,
    nominal: &Robot,
    rows: &[&Measurement],
    validation: Option<(&[&Measurement], String)>,
    bar: Option<&ProgressBar>,
    say: &mut dyn FnMut(&str),
) -> Result<Built> {
    let (fit, held, held_out, refit) = match &validation {
        Some((v, source)) => (rows.to_vec(), v.to_vec(), source.clone(), false),
        None => match hold_out(rows, settings.holdout, settings.seed) {
            Some((fit, held, how)) if configurations(&fit).len() >= 3 => (fit, held, how, true),
            _ => {
                // Too few poses to hold any out: the kinematic stage alone, on everything.
                say("too few configurations to hold any out: kinematic identification only");
                let stages = Stages::default();
                let mut built = configured(&stages, nominal, rows, None, bar)?;
                built.selection = Some(Selection {
                    held_out: "none: fewer than 4 configurations".into(),
                    fitted_rows: rows.len(),
                    held_out_rows: 0,
                    decisions: vec![Decision {
                        stage: "kinematic",
                        kept: true,
                        held_out_without: None,
                        held_out_with: None,
                        reason: "kept untested: too few configurations to hold any out".into(),
                    }],
                    refitted_on_every_row: false,
                });
                return Ok(built);
            }
        },
    };
    let mut decisions = Vec::new();
    fn decide(
        decisions: &mut Vec<Decision>,
        stage: &'static str,
        without: f64,
        with: f64,
        what: &str,
    ) -> bool {
        let kept = with < without;
        let reason = format!(
            "{}: held-out mean {without:.4} mm without, {with:.4} mm with {what}",
            if kept { "kept" } else { "dropped" }
        );
        decisions.push(Decision {
            stage,
            kept,
            held_out_without: Some(without),
            held_out_with: Some(with),
            reason,
        });
        kept
    }

    // Kinematic identification against the nominal table with base and tool fitted.
    let rigid = KinematicSettings::default();
    let kinematic = fit_kinematic(nominal, &fit, &rigid)?;
    let aligned = Predictor {
        robot: kinematic.aligned.clone(),
        compliance: None,
        residual: None,
    };
    let identified = Predictor::kinematic(&kinematic);
    let (mut best, mut best_mean) = (aligned.clone(), aligned.stats(&held).mean);
    let mut chosen = Stages::default();
    let with = identified.stats(&held).mean;
    let mut kinematic_kept = false;
    if decide(
        &mut decisions,
        "kinematic",
        best_mean,
        with,
        "the identified table (LM, identifiable parameters)",
    ) {
        (best, best_mean, kinematic_kept) = (identified, with, true);
    }
    let mut kinematic_run = kinematic;

    // Joint compliance, when there are loads to separate it from the geometry.
    let mut loads: Vec<f64> = fit.iter().map(|r| r.sample.load).collect();
    loads.sort_by(f64::total_cmp);
    loads.dedup();
    let elastic_settings = KinematicSettings {
        compliance: Some(ComplianceSettings::default()),
        ..KinematicSettings::default()
    };
    if loads.len() < 2 {
        decisions.push(Decision {
            stage: "compliance",
            kept: false,
            held_out_without: None,
            held_out_with: None,
            reason: format!(
                "skipped: the data hold one load ({} kg); compliance needs two or more",
                loads.first().copied().unwrap_or(0.0)
            ),
        });
    } else {
        match fit_kinematic(nominal, &fit, &elastic_settings) {
            Ok(elastic) => {
                let candidate = Predictor::kinematic(&elastic);
                let with = candidate.stats(&held).mean;
                if decide(
                    &mut decisions,
                    "compliance",
                    best_mean,
                    with,
                    "joint compliances identified with the geometry on every load",
                ) {
                    (best, best_mean) = (candidate, with);
                    kinematic_run = elastic;
                    kinematic_kept = true;
                    chosen.kinematic = elastic_settings.clone();
                }
            }
            Err(e) => decisions.push(Decision {
                stage: "compliance",
                kept: false,
                held_out_without: Some(best_mean),
                held_out_with: None,
                reason: format!("skipped: {e}"),
            }),
        }
    }

    // A residual model, when there are enough configurations to learn one.
    let trained_configurations = configurations(&fit).len();
    let mut residual = None;
    if trained_configurations < settings.min_residual_configurations {
        decisions.push(Decision {
            stage: "residual",
            kept: false,
            held_out_without: Some(best_mean),
            held_out_with: None,
            reason: format!(
                "skipped: {trained_configurations} configurations to train on; a residual model needs at least {}",
                settings.min_residual_configurations
            ),
        });
    } else {
        let (model, report) = train_residual(&settings.residual, &best, &fit, None, bar)?;
        let candidate = Predictor {
            residual: Some(model.clone()),
            ..best.clone()
        };
        let with = candidate.stats(&held).mean;
        if decide(
            &mut decisions,
            "residual",
            best_mean,
            with,
            &format!(
                "a {} residual model (paper settings)",
                settings.residual.settings.kind.name()
            ),
        ) {
            residual = Some((model, report));
            chosen.residual = Some(settings.residual.clone());
        }
    }
    for d in &decisions {
        say(&format!("stage {}: {}", d.stage, d.reason));
    }
    if !kinematic_kept {
        // Neither identification beat the nominal table: keep its base and tool fit.
        kinematic_run.robot = kinematic_run.aligned.clone();
        kinematic_run.compliance = None;
    }
    let selection = Selection {
        held_out,
        fitted_rows: fit.len(),
        held_out_rows: held.len(),
        decisions,
        refitted_on_every_row: refit,
    };
    if refit {
        say("fitting the kept stages again on every row");
        let mut built = configured(&chosen, nominal, rows, None, bar)?;
        if !kinematic_kept {
            built.kinematic.robot = built.kinematic.aligned.clone();
        }
        built.selection = Some(selection);
        return Ok(built);
    }
    Ok(Built {
        kinematic: kinematic_run,
        residual,
        stages: chosen,
        selection: Some(selection),
    })
}
