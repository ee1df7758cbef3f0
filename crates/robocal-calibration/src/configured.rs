//! The stages a stage config asks for, fitted in order: the identification, then a residual
//! model on what it leaves.

use crate::built::Built;
use crate::error::Result;
use crate::fit::{fit_kinematic_with, physical_model};
use crate::residual_report::{ResidualReport, gate_ready, residual_report};
use crate::rows::{configurations, early_stopping_hold_out};
use crate::stages::Stages;
use nalgebra::Vector3;
use rayon::prelude::*;
use robocal_data::{Measurement, Observer, Sample, Silent};
use robocal_ident::FitMemo;
use robocal_model::{CalibratedModel, with_gate_physics};
use robocal_residual::{ResidualModel, ResidualSettings, ResidualStage, Samples};
use robocal_robot::Robot;

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
        motion: None,
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

pub(super) fn train_residual_reported(
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
pub(super) fn train_members<'a>(
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
