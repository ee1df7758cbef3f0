//! The residual candidates: each residual model trained on every fold on what the chain's
//! physics leaves, within what the budget has left.

use super::chain::Chain;
use super::plan::FoldPlan;
use super::selection::Candidate;
use super::selection::report;
use super::settings::AutoSettings;
use super::status::Status;
use crate::budget::{self, Allowance, Epochs, REFERENCE_CORES};
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
pub(super) fn residual_candidates(
    trainer: &mut Trainer<'_, '_>,
    candidates: &mut Vec<Candidate>,
) -> Result<Vec<ResidualScore>> {
    let settings = trainer.settings;
    let base_physics = trainer.chain.identified();
    // With the models in both frames, each one's name says its frame.
    let frames = |f: Frame| settings.residuals.iter().any(|s| s.settings.frame == f);
    let both = frames(Frame::World) && frames(Frame::Joint1);
    let mut scored = (settings.residuals.iter())
        .map(|s| trainer.score(s, base_physics, both))
        .collect::<Result<Vec<_>>>()?;
    // Only where a residual model beat the chain's physics significantly: the data then hold
    // an error the physics misses (where none did, a model on the table alone, which must learn
    // the physics' effects too, has never won on the accuracy suite).
    let best = (scored.iter())
        .filter(|(_, s)| s.significant)
        .filter_map(|(_, s)| s.score.map(|m| (s, m)))
        .min_by(|a, b| a.1.total_cmp(&b.1))
        .map(|(s, _)| s.stage.clone());
    if let Some(best) = best.filter(|_| base_physics != KINEMATIC) {
        for frame in TABLE_FRAMES {
            let mut stage = best.clone();
            stage.settings.frame = frame;
            scored.push(trainer.score(&stage, KINEMATIC, true)?);
        }
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
struct Pace {
    pending_final: f64,
    last_pace: f64,
}

/// What trains and scores the residual candidates: the settings, the chain of physical
/// candidates they are trained on, the folds and the paired test's groups, the budget (less the
/// final fit of the physics), and the pace of those trained so far.
pub(super) struct Trainer<'s, 'p> {
    pub(super) settings: &'s AutoSettings,
    pub(super) chain: &'s Chain,
    pub(super) plan: &'s FoldPlan<'p>,
    pub(super) groups: &'s [usize],
    pub(super) observer: &'s dyn Observer,
    pub(super) budget: Allowance<'s>,
    pace: Pace,
}

/// One residual model's folds, trained: their held-out errors, the pairs its spread is
/// calibrated on, and the seconds they took on the clock and by the budget's measure; or the
/// status of the candidate abandoned for the budget.
struct Trained {
    held: Held,
    pairs: Vec<(f64, f64)>,
    slowest: f64,
    abandoned: Option<Status>,
}

impl<'s, 'p> Trainer<'s, 'p> {
    /// A trainer on `chain`'s candidates, within `budget`.
    pub(super) fn new(
        settings: &'s AutoSettings,
        chain: &'s Chain,
        plan: &'s FoldPlan<'p>,
        groups: &'s [usize],
        observer: &'s dyn Observer,
        budget: Allowance<'s>,
    ) -> Self {
        Self {
            settings,
            chain,
            plan,
            groups,
            observer,
            budget,
            pace: Pace::default(),
        }
    }

    /// One residual model `stage` trained on every fold on what the physical candidate `base`
    /// (index into [`Chain::scored`]) leaves, scored, its name saying its frame where `named`
    /// (the same model is tried in the other frame too: `… (world frame)`, `… (joint-1 frame)`).
    fn score(
        &mut self,
        stage: &ResidualStage,
        base: usize,
        named: bool,
    ) -> Result<(Candidate, ResidualScore)> {
        let settings = self.settings;
        let fewest = self.plan.fewest_configurations();
        let mut c = Candidate {
            name: format!(
                "{} + {}{}",
                self.chain.scored[base].physics.name(),
                stage.settings.kind.name(),
                match (named, stage.settings.frame) {
                    (false, _) => "",
                    (true, Frame::World) => " (world frame)",
                    (true, Frame::Joint1) => " (joint-1 frame)",
                }
            ),
            physics: None,
            held_out: None,
            held_out_blocks: None,
            score: None,
            seconds: 0.0,
            cost: 0.0,
            status: Status::Evaluated,
        };
        let mut score = ResidualScore {
            stage: stage.clone(),
            base,
            score: None,
            significant: false,
            spread: None,
            beside: None,
        };
        if fewest < settings.min_residual_configurations {
            c.status = Status::TooFewConfigurations {
                fewest,
                needed: settings.min_residual_configurations,
            };
        } else if (self.budget).over(self.pace.pending_final + self.pace.last_pace) {
            c.status = Status::Spent {
                budget: self.budget.budget(),
            };
        } else {
            let trained = self.train(stage, base, &mut c)?;
            match trained.abandoned {
                Some(why) => c.status = why,
                None => {
                    let (random, blocked, mean) = trained.held.summary();
                    (c.held_out, c.held_out_blocks, c.score) = (Some(random), blocked, Some(mean));
                    self.pace.pending_final = self.pace.pending_final.max(trained.slowest);
                    if stage.settings.kind.gives_std() {
                        score.spread = spread::calibrate(&trained.pairs);
                    } else {
                        score.beside = spread::spread_beside(&trained.pairs);
                    }
                    score.significant = (self.chain.scored[self.chain.current].errors.as_ref())
                        .is_some_and(|physics| improves(physics, &trained.held.all(), self.groups));
                    c.status = if score.significant {
                        Status::Evaluated
                    } else {
                        Status::NotSignificant
                    };
                }
            }
        }
        report(&c, self.observer);
        score.score = c.score;
        Ok((c, score))
    }

    /// Trains `stage` on every fold on what the physical candidate `base` left there, a chunk of
    /// folds at a time, adding to `c`'s seconds and cost; abandoned once the remaining folds at
    /// the pace of the chunks before, and the final training, would run past the budget.
    fn train(&mut self, stage: &ResidualStage, base: usize, c: &mut Candidate) -> Result<Trained> {
        let splits = &self.plan.splits;
        let meter = self.budget.meter();
        let mut trained = Trained {
            held: Held::default(),
            pairs: Vec::new(),
            slowest: 0.0,
            abandoned: None,
        };
        let fitted: Option<Vec<&CalibratedModel>> = (self.chain.scored[base].fitted)
            .iter()
            .map(Option::as_ref)
            .collect();
        let Some(fitted) = fitted else {
            trained.abandoned = Some(Status::PhysicsFailed);
            return Ok(trained);
        };
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
        while trained.abandoned.is_none() && done < splits.len() {
            let t = Instant::now();
            let chunk = done..(done + at_once).min(splits.len());
            let counted = self.train_chunk(stage, &fitted, chunk.clone(), &mut trained)?;
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
            trained.slowest = trained.slowest.max(took);
            self.pace.last_pace = trained.slowest;
            if done < splits.len() && self.budget.over(left + self.pace.pending_final) {
                trained.abandoned = Some(Status::Abandoned {
                    budget: self.budget.budget(),
                    reserve: 0.0,
                });
            }
        }
        Ok(trained)
    }

    /// Trains `stage` on the folds of `chunk` at once, each on what its physical model
    /// (`fitted`) leaves, adding their held-out errors and spread pairs to `trained`; returns the
    /// reference seconds their counted trainings came to.
    fn train_chunk(
        &self,
        stage: &ResidualStage,
        fitted: &[&CalibratedModel],
        chunk: std::ops::Range<usize>,
        trained: &mut Trained,
    ) -> Result<f64> {
        let splits = &self.plan.splits;
        let seed = self.settings.seed;
        let observer = self.observer;
        let results: Vec<_> = (splits[chunk.clone()].par_iter())
            .zip(&fitted[chunk.clone()])
            .zip(chunk.clone())
            .map(|((fold, &base), k)| {
                observer.advance(1);
                let epochs = Epochs::default();
                let model = train_residual_model(stage, base, &fold.train, &epochs);
                let joints = fold.train.first().map_or(0, |m| m.sample.joints.len());
                let seconds =
                    budget::training_seconds(stage, fold.train.len(), joints, epochs.count());
                model.map(|model| {
                    let model = CalibratedModel {
                        residual: Some(model),
                        ..base.clone()
                    };
                    // A model that says how sure it is: its deviations on (some of) the
                    // held-out rows, against the errors there. A network: the physics'
                    // deviations there, beside which its own spread is estimated.
                    let seed = seed + k as u64;
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
        for (fold, result) in splits[chunk].iter().zip(results) {
            let (errors, pairs, seconds) = result?;
            trained.held.add(fold, errors);
            trained.pairs.extend(pairs);
            counted += seconds;
        }
        Ok(counted)
    }
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
