//! The residual candidates: each residual model trained on every fold on what the chain's
//! physics leaves, within what the budget has left.

use super::chain::Chain;
use super::plan::FoldPlan;
use super::words::{abandoned_for, report, the_budget};
use super::{AutoSettings, Candidate};
use crate::budget::{self, Epochs, Meter, REFERENCE_CORES};
use crate::configured::train_residual_model;
use crate::error::Result;
use crate::folds::{Held, improves};
use crate::spread::{self, SpreadCalibration};
use rayon::prelude::*;
use robocal_data::Observer;
use robocal_model::CalibratedModel;
use robocal_residual::{Frame, ResidualStage};
use std::time::Instant;

/// The share of the time budget the axis runouts' candidate leaves to the residual models: one
/// GP's folds and final fit on the paper's arm (about 900 rows) take 16–20 s of the 120; the
/// runouts, started late, could take the rest (44 s) and leave none.
pub(super) const RESIDUAL_SHARE: f64 = 0.25;

/// The seconds of the budget the axis runouts' candidate leaves to the residual models
/// ([`RESIDUAL_SHARE`]): none where no residual model will be scored (none given, or fewer than
/// `min_residual_configurations` configurations, `fewest`, in a fold's training rows).
pub(super) fn residual_share(settings: &AutoSettings, fewest: usize) -> f64 {
    if settings.residuals.is_empty() || fewest < settings.min_residual_configurations {
        0.0
    } else {
        RESIDUAL_SHARE * settings.budget_seconds
    }
}

/// A residual candidate's result.
pub(super) struct ResidualScore {
    /// The residual model's settings.
    pub(super) stage: ResidualStage,
    /// The physical candidate it is trained on (index into [`Chain::scored`]).
    pub(super) base: usize,
    /// Its selection score (none when skipped or abandoned).
    pub(super) score: Option<f64>,
    /// Whether it lowers the chain model's held-out errors significantly.
    pub(super) significant: bool,
    /// Its standard deviations calibrated on the held-out rows (a model that gives them).
    pub(super) spread: Option<SpreadCalibration>,
    /// Its spread beside the physics' deviation, from the held-out rows (a model that gives
    /// no deviation of its own).
    pub(super) beside: Option<spread::SpreadBeside>,
}

/// Each residual model of `settings`, trained on every fold on what the identified chain model
/// leaves, scored like the physical candidates; skipped with too few configurations, and
/// abandoned when its folds would run past the time budget. Then, where the chain's physics
/// holds more than the identified table, the lowest-scoring of those significantly better than
/// it again on the identified table alone, in each frame: a large error of no physical form can
/// bend the physics' terms (a backlash step, a harmonic) into shapes a residual model must then
/// undo, where on the table alone it learns the error and the physics' effects together.
#[allow(clippy::too_many_arguments)]
pub(super) fn residual_candidates(
    settings: &AutoSettings,
    chain: &Chain,
    plan: &FoldPlan<'_>,
    groups: &[usize],
    candidates: &mut Vec<Candidate>,
    observer: &dyn Observer,
    (meter, over_budget): (&Meter, &dyn Fn(f64) -> bool),
) -> Result<Vec<ResidualScore>> {
    let base_physics = chain.identified();
    let mut pace = Pace::default();
    // With the models in both frames, each one's name says its frame.
    let frames = |f: Frame| settings.residuals.iter().any(|s| s.settings.frame == f);
    let both = frames(Frame::World) && frames(Frame::Joint1);
    // Each residual model `stage` on the physical candidate `base`, its name saying its frame
    // where `named`, in order.
    let mut score_each = |jobs: Vec<(ResidualStage, usize, bool)>| -> Result<Vec<_>> {
        (jobs.iter())
            .map(|(stage, base, named)| {
                score_residual(
                    settings,
                    chain,
                    (stage, *base, *named),
                    plan,
                    groups,
                    observer,
                    (meter, over_budget),
                    &mut pace,
                )
            })
            .collect()
    };
    let mut scored = score_each(
        (settings.residuals.iter())
            .map(|s| (s.clone(), base_physics, both))
            .collect(),
    )?;
    // Only where a residual model beat the chain's physics significantly: the data then hold
    // an error the physics misses (where none did, a model on the table alone, which must learn
    // the physics' effects too, has never won on the accuracy suite).
    let best = (scored.iter())
        .filter(|(_, s)| s.significant)
        .filter_map(|(_, s)| s.score.map(|m| (s, m)))
        .min_by(|a, b| a.1.total_cmp(&b.1))
        .map(|(s, _)| s.stage.clone());
    if let Some(best) = best.filter(|_| base_physics != KINEMATIC) {
        let table = TABLE_FRAMES.map(|frame| {
            let mut stage = best.clone();
            stage.settings.frame = frame;
            (stage, KINEMATIC, true)
        });
        scored.extend(score_each(table.into())?);
    }
    let mut scores = Vec::new();
    for (c, score) in scored {
        candidates.push(c);
        scores.push(score);
    }
    Ok(scores)
}

/// The index of the identified table among the physical candidates ([`Chain::scored`]).
pub(super) const KINEMATIC: usize = 1;

/// The frames the lowest-scoring residual model is scored in again on the identified table
/// alone, the folds choosing: the world frame (an error fixed in the tracker's frame, as the
/// probe's field is) and the frame turning with joint 1 (what the links' weights do, which the
/// physics then leaves to the residual model, turns with it).
pub(super) const TABLE_FRAMES: [Frame; 2] = [Frame::World, Frame::Joint1];

/// What the residual candidates' folds have taken, for the next one's budget: the final
/// training of the residual model that may be chosen, kept out of what the later candidates may
/// spend (about one chunk of its folds: one training per core, each on a fold's rows, against
/// one on every row with the axes on the cores); and the pace of the last candidate's chunks,
/// which a new one is expected to take for its first.
#[derive(Default)]
pub(super) struct Pace {
    pub(super) pending_final: f64,
    pub(super) last_pace: f64,
}

/// One residual model `stage` trained on every fold on what the physical candidate `base`
/// (index into [`Chain::scored`]) leaves, scored, its name saying its frame where `named` (the
/// same model is tried in the other frame too: `… (world frame)`, `… (joint-1 frame)`).
#[allow(clippy::too_many_arguments)]
pub(super) fn score_residual(
    settings: &AutoSettings,
    chain: &Chain,
    (stage, base_physics, named): (&ResidualStage, usize, bool),
    plan: &FoldPlan<'_>,
    groups: &[usize],
    observer: &dyn Observer,
    (meter, over_budget): (&Meter, &dyn Fn(f64) -> bool),
    pace: &mut Pace,
) -> Result<(Candidate, ResidualScore)> {
    let splits = &plan.splits;
    let fewest = plan.fewest_configurations();
    let Pace {
        pending_final,
        last_pace,
    } = pace;
    let mut c = Candidate {
        name: format!(
            "{} + {}{}",
            chain.scored[base_physics].physics.name(),
            stage.settings.kind.name(),
            match (named, stage.settings.frame) {
                (false, _) => "",
                (true, Frame::World) => " (world frame)",
                (true, Frame::Joint1) => " (joint-1 frame)",
            }
        ),
        held_out: None,
        held_out_blocks: None,
        score: None,
        seconds: 0.0,
        cost: 0.0,
        status: String::new(),
        budget_cut: false,
    };
    let mut significant = false;
    let mut spread_pairs: Vec<(f64, f64)> = Vec::new();
    let mut spread = None;
    let mut beside = None;
    if fewest < settings.min_residual_configurations {
        c.status = format!(
            "skipped: {fewest} configurations to train on; a residual model needs at least {}",
            settings.min_residual_configurations
        );
    } else if over_budget(*pending_final + *last_pace) {
        c.status = format!("skipped: {} is spent", the_budget(settings.budget_seconds));
        c.budget_cut = true;
    } else {
        let mut held = Held::default();
        let mut abandoned = None;
        let fitted: Option<Vec<&CalibratedModel>> = (chain.scored[base_physics].fitted)
            .iter()
            .map(Option::as_ref)
            .collect();
        let fitted = fitted.unwrap_or_else(|| {
            abandoned = Some("skipped: its physical model failed on a fold".to_string());
            Vec::new()
        });
        // The folds' trainings are independent and seeded: as many at once as there are
        // cores, taken in fold order (the same models on any number of cores); with the budget
        // counted, as many as the reference machine has, so that its decisions after each
        // chunk are the same everywhere.
        let at_once = if meter.counts() {
            REFERENCE_CORES
        } else {
            rayon::current_num_threads().max(1)
        };
        let mut done = 0;
        // This candidate's slowest chunk.
        let mut slowest: f64 = 0.0;
        while abandoned.is_none() && done < splits.len() {
            let t = Instant::now();
            let chunk = done..(done + at_once).min(splits.len());
            let trained: Vec<_> = (splits[chunk.clone()].par_iter())
                .zip(&fitted[chunk.clone()])
                .zip(chunk.clone())
                .map(|((fold, &base), k)| {
                    observer.advance(1);
                    let epochs = Epochs::default();
                    let trained = train_residual_model(stage, base, &fold.train, &epochs);
                    let joints = fold.train.first().map_or(0, |m| m.sample.joints.len());
                    let seconds =
                        budget::training_seconds(stage, fold.train.len(), joints, epochs.count());
                    trained.map(|model| {
                        let model = CalibratedModel {
                            residual: Some(model),
                            ..base.clone()
                        };
                        // A model that says how sure it is: its deviations on (some of)
                        // the held-out rows, against the errors there.
                        // A network: the physics' deviations there, beside which its
                        // own spread is estimated.
                        let seed = settings.seed + k as u64;
                        let pairs = if stage.settings.kind.gives_std() {
                            spread::held_out_pairs(&model, &fold.test, seed)
                        } else {
                            spread::held_out_pairs_beside(&model, &fold.test, seed)
                        };
                        (model.errors(&fold.test), pairs, seconds)
                    })
                })
                .collect();
            let mut counted = 0.0;
            for (fold, candidate) in splits[chunk.clone()].iter().zip(trained) {
                let (errors, pairs, seconds) = candidate?;
                held.add(fold, errors);
                spread_pairs.extend(pairs);
                counted += seconds;
            }
            let wall = t.elapsed().as_secs_f64();
            c.seconds += wall;
            // What the chunk spent by the budget's measure: the clock's seconds, or its counted
            // trainings on the reference machine's cores.
            let took = if meter.counts() {
                counted / REFERENCE_CORES as f64
            } else {
                wall
            };
            meter.charge(took);
            c.cost += took;
            done = chunk.end;
            // The remaining folds at this chunk's pace, and the final fit (one training,
            // as long as one of the chunk's).
            let left = took * ((splits.len() - done) as f64 / chunk.len() as f64 + 1.0);
            slowest = slowest.max(took);
            *last_pace = slowest;
            if done < splits.len() && over_budget(left + *pending_final) {
                abandoned = Some(abandoned_for(settings.budget_seconds, 0.0));
                c.budget_cut = true;
            }
        }
        match abandoned {
            Some(why) => c.status = why,
            None => {
                let (random, blocked, score) = held.summary();
                (c.held_out, c.held_out_blocks, c.score) = (Some(random), blocked, Some(score));
                *pending_final = pending_final.max(slowest);
                if stage.settings.kind.gives_std() {
                    spread = spread::calibrate(&spread_pairs);
                } else {
                    beside = spread::spread_beside(&spread_pairs);
                }
                significant = (chain.scored[chain.current].errors.as_ref())
                    .is_some_and(|base| improves(base, &held.all(), groups));
                c.status = if significant {
                    "evaluated".into()
                } else {
                    "evaluated: not significantly better than the physical model".into()
                };
            }
        }
    }
    report(&c, observer);
    let score = ResidualScore {
        stage: stage.clone(),
        base: base_physics,
        score: c.score,
        significant,
        spread,
        beside,
    };
    Ok((c, score))
}

/// The residual model the default keeps, with its score: of those whose held-out errors are
/// significantly lower than the physical model's (and whose score is lower), the one with the
/// lowest score: the test is asked of each, so a lowest-scoring network that fails it does not
/// keep out a GP that passed.
pub(super) fn pick_residual(
    residuals: &[ResidualScore],
    physics_mean: f64,
) -> Option<(usize, f64)> {
    (residuals.iter().enumerate())
        .filter(|(_, s)| s.significant)
        .filter_map(|(r, s)| s.score.map(|m| (r, m)))
        .filter(|&(_, m)| m < physics_mean)
        .min_by(|a, b| a.1.total_cmp(&b.1))
}
