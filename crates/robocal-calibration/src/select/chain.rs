//! The chain of physical candidates: each richer model taken only where it lowers the held-out
//! errors significantly.

use super::physics::{Effect, Physics};
use super::plan::FoldPlan;
use super::scoring::{Scored, score_physics, skipped};
use super::selection::Candidate;
use super::selection::report;
use super::settings::AutoSettings;
use super::status::Stage;
use crate::budget::Allowance;
use crate::folds::improves;
use crate::rows::loads;
use robocal_data::{Measurement, Observer};
use robocal_robot::Robot;

/// One step of the chain: a richer physical model tried on the current one.
pub(super) struct Step {
    /// The decision it belongs to.
    pub(super) stage: Stage,
    /// The model it was compared with (index into [`Chain::scored`]).
    pub(super) base: usize,
    /// The richer model.
    pub(super) next: usize,
    /// Whether it lowered the held-out errors significantly and became the current model.
    pub(super) kept: bool,
}

/// The physical candidates, scored, and the chain through them.
pub(super) struct Chain {
    pub(super) scored: Vec<Scored>,
    pub(super) steps: Vec<Step>,
    /// The model the chain ended on.
    pub(super) current: usize,
    /// The links not tried, and why, where the chain says so.
    pub(super) skipped: Vec<(Stage, String)>,
}

impl Chain {
    /// Why `stage` was not tried, where the chain says so.
    pub(super) fn skip_of(&self, stage: Stage) -> Option<&str> {
        (self.skipped.iter())
            .find(|(s, _)| *s == stage)
            .map(|(_, why)| why.as_str())
    }

    /// The steps of `stage`, in order.
    pub(super) fn steps_of(&self, stage: Stage) -> Vec<&Step> {
        self.steps.iter().filter(|s| s.stage == stage).collect()
    }

    /// The physics of the model the chain is on.
    fn physics(&self) -> Physics {
        self.scored[self.current].physics
    }

    /// The order of two scored candidates (indices into `scored`) by their score: the lower
    /// first, unscored last.
    fn by_score(&self, a: usize, b: usize) -> std::cmp::Ordering {
        match (self.scored[a].score, self.scored[b].score) {
            (Some(x), Some(y)) => x.total_cmp(&y),
            (Some(_), None) => std::cmp::Ordering::Less,
            (None, Some(_)) => std::cmp::Ordering::Greater,
            (None, None) => std::cmp::Ordering::Equal,
        }
    }

    /// The model residual models are trained on: the chain's, or the identified table when the
    /// chain ended on the nominal one (a residual model learns what an identified model
    /// leaves).
    pub(super) fn identified(&self) -> usize {
        if self.scored[self.current].physics.aligned {
            1
        } else {
            self.current
        }
    }

    /// Scores `next`, compares it with the current model and takes it if it is significantly
    /// better.
    pub(super) fn step(&mut self, stage: Stage, next: Scored, groups: &[usize]) {
        self.scored.push(next);
        self.take(stage, self.scored.len() - 1, groups);
    }

    /// Compares the scored candidate `next` (already in the chain) with the current model and
    /// takes it if it is significantly better.
    pub(super) fn take(&mut self, stage: Stage, next: usize, groups: &[usize]) {
        let better = match (&self.scored[self.current].errors, &self.scored[next].errors) {
            (Some(c), Some(n)) => improves(c, n, groups),
            (None, Some(_)) => true,
            _ => false,
        };
        self.steps.push(Step {
            stage,
            base: self.current,
            next,
            kept: better,
        });
        if better {
            self.current = next;
        }
    }
}

/// What a link of the chain tries on the physics the chain is on.
enum Try {
    /// One candidate.
    One(Physics),
    /// Nothing: the settings or the physics leave it out.
    Not,
    /// Nothing, and the decision says why.
    Skipped(String),
}

/// One link of the chain: the stage it decides and what it tries, in the chain's order. The
/// joint-error blocks are not a link: they are chosen by forward stepwise selection
/// ([`stepwise`]) between the compliances and the runouts.
struct Link {
    stage: Stage,
    /// The candidate it tries on the current physics under the settings, given the data's
    /// loads.
    tries: fn(&AutoSettings, Physics, &[f64]) -> Try,
    /// Whether its candidate leaves the residual models their share of the budget
    /// ([`super::residual::RESIDUAL_SHARE`]).
    keeps_residual_share: bool,
    /// Where the budget cut its candidate, a cheaper one of the same stage tried instead.
    cheaper: Option<fn(&AutoSettings, Physics) -> Option<Physics>>,
}

/// The links before the joint-error blocks: the identified table, then its compliances (two or
/// more loads).
const BEFORE_BLOCKS: [Link; 2] = [
    Link {
        stage: Stage::Kinematic,
        tries: |_, _, _| Try::One(Physics::RIGID),
        keeps_residual_share: false,
        cheaper: None,
    },
    Link {
        stage: Stage::Compliance,
        tries: |_, _, loads| {
            if loads.len() >= 2 {
                Try::One(Physics::RIGID.with(Effect::Compliance))
            } else {
                Try::Skipped(format!(
                    "skipped: the data hold one load ({} kg); compliance needs two or more",
                    loads.first().copied().unwrap_or(0.0)
                ))
            }
        },
        keeps_residual_share: false,
        cheaper: None,
    },
];

/// The links after the joint-error blocks, each one candidate more on the physics the chain is
/// on, kept only if it lowers the held-out errors significantly: the axis runouts; the backlash
/// flanks searched beyond each joint's own terms; last, the bearings' tilt.
const AFTER_BLOCKS: [Link; 3] = [
    // The axis runouts on the physics the blocks reached. Where the budget cut their fits
    // (skipped, or abandoned during their folds), the cheaper fit that starts them from the
    // model without them, whose first fit and flanks the candidates before made (a third of the
    // work on the paper's arm, whose twin beyond the model, at 75 s, goes from 0.101 to
    // 0.022 mm on its joint-1 extrapolation with it). Other fits than the full one, so tried
    // only where that one has no score; and only where the compliances' first fit would hold
    // the runouts (elsewhere the two are the same fits).
    Link {
        stage: Stage::Runout,
        tries: |settings, current, _| {
            if settings.runout > 0 && !current.aligned {
                Try::One(current.with(Effect::Runout(settings.runout)))
            } else {
                Try::Not
            }
        },
        keeps_residual_share: true,
        cheaper: Some(|settings, wobbling| {
            (wobbling.settings(settings).runouts_in_first_fit())
                .then_some(wobbling.with(Effect::RunoutFromWithout))
        }),
    },
    // On chosen physics with backlash, or, where asked, with backlash added where the block was
    // not kept.
    Link {
        stage: Stage::FlankSearch,
        tries: |settings, current, _| {
            let backlash = current.has(Effect::Backlash);
            let added = settings.flank_search && settings.backlash && !backlash;
            if (backlash || added) && !current.aligned {
                Try::One(current.with(Effect::Backlash).with(Effect::FlankSearch))
            } else {
                Try::Not
            }
        },
        keeps_residual_share: false,
        cheaper: None,
    },
    // With the compliances: the payload's moment and, where the links' weights were kept,
    // theirs.
    Link {
        stage: Stage::Tilt,
        tries: |settings, current, _| {
            if settings.tilt && current.has(Effect::Compliance) && !current.aligned {
                Try::One(current.with(Effect::Tilt))
            } else {
                Try::Not
            }
        },
        keeps_residual_share: false,
        cheaper: None,
    },
];

/// What scores the physical candidates: the settings, the table, the folds, the budget; and
/// the candidates scored so far, in order (the chain's indices are theirs).
pub(super) struct Scorer<'s, 'p> {
    pub(super) settings: &'s AutoSettings,
    pub(super) nominal: &'s Robot,
    pub(super) plan: &'s FoldPlan<'p>,
    pub(super) observer: &'s dyn Observer,
    pub(super) budget: Allowance<'s>,
    /// The seconds of the budget the candidates that keep it leave to the residual models.
    pub(super) residual_share: f64,
    pub(super) candidates: Vec<Candidate>,
}

impl Scorer<'_, '_> {
    /// Scores `physics` on every fold, with the residual models' share of the budget kept from
    /// it where `keep`; a joint-error candidate does not start when the budget would be spent
    /// before it and the final fit of its physics end ([`skipped`]).
    fn score(&mut self, physics: Physics, keep: bool) -> Scored {
        let budget = if keep {
            self.budget.keeping(self.residual_share)
        } else {
            self.budget
        };
        let (c, scored) = match skipped(physics, &self.candidates, &budget) {
            Some(c) => {
                report(&c, self.observer);
                let scored = Scored {
                    physics,
                    score: None,
                    errors: None,
                    fitted: vec![None; self.plan.splits.len()],
                };
                (c, scored)
            }
            None => score_physics(
                physics,
                self.settings,
                self.nominal,
                self.plan,
                self.observer,
                &budget,
            ),
        };
        self.candidates.push(c);
        scored
    }
}

/// The physical models, each scored on every fold: the nominal table, then the links of the
/// chain in order ([`BEFORE_BLOCKS`], the joint-error blocks by [`stepwise`] selection,
/// [`AFTER_BLOCKS`]), each kept only if it lowers the held-out errors significantly.
pub(super) fn physics_chain(
    scorer: &mut Scorer<'_, '_>,
    rows: &[&Measurement],
    groups: &[usize],
) -> Chain {
    let loads = loads(rows);
    let mut chain = Chain {
        scored: vec![scorer.score(Physics::ALIGNED, false)],
        steps: Vec::new(),
        current: 0,
        skipped: Vec::new(),
    };
    let follow = |chain: &mut Chain, scorer: &mut Scorer<'_, '_>, link: &Link| match (link.tries)(
        scorer.settings,
        chain.physics(),
        &loads,
    ) {
        Try::One(physics) => {
            chain.step(
                link.stage,
                scorer.score(physics, link.keeps_residual_share),
                groups,
            );
            // The candidate just scored, cut (skipped, or abandoned during its folds) or not.
            let cut = (scorer.candidates.last()).is_some_and(|c| c.status.budget_cut());
            if let Some(cheaper) = link.cheaper.filter(|_| cut)
                && let Some(physics) = cheaper(scorer.settings, physics)
            {
                let scored = scorer.score(physics, link.keeps_residual_share);
                chain.step(link.stage, scored, groups);
            }
        }
        Try::Skipped(why) => chain.skipped.push((link.stage, why)),
        Try::Not => {}
    };
    for link in &BEFORE_BLOCKS {
        follow(&mut chain, scorer, link);
    }
    stepwise(&mut chain, scorer, groups);
    for link in &AFTER_BLOCKS {
        follow(&mut chain, scorer, link);
    }
    debug_assert!(
        (chain.scored.iter().zip(&scorer.candidates)).all(|(s, c)| c.physics == Some(s.physics))
            && chain.scored.len() == scorer.candidates.len()
    );
    chain
}

/// The joint-error blocks the settings ask for (harmonics, self-weight, backlash), each alone
/// on `base` without any block.
fn blocks(settings: &AutoSettings, base: Physics) -> Vec<Physics> {
    let none = base.without_joint_errors();
    [
        (settings.harmonics > 0).then_some(none.with(Effect::Harmonics(settings.harmonics))),
        settings
            .self_weight
            .then_some(none.with(Effect::SelfWeight)),
        settings.backlash.then_some(none.with(Effect::Backlash)),
    ]
    .into_iter()
    .flatten()
    .collect()
}

/// The joint-error blocks by forward stepwise selection: each block alone on the identified
/// model, in the order of their held-out scores, until one is kept (significantly better);
/// then each remaining block added to the kept ones, the best of them taken if it is
/// significantly better, until none is or none remains. A flexible block cannot take the place
/// of the block whose form the effect has only because it was tried first (harmonics of the
/// joint angles absorb part of a self-weight deflection or of a backlash step, and extrapolate
/// them badly).
fn stepwise(chain: &mut Chain, scorer: &mut Scorer<'_, '_>, groups: &[usize]) {
    let base = chain.scored[chain.identified()].physics;
    let blocks = blocks(scorer.settings, base);
    // Every scored candidate joins the chain in the order it was scored, so that the chain's
    // indices stay those of the candidates.
    let singles: Vec<usize> = (blocks.iter())
        .map(|&b| {
            chain.scored.push(scorer.score(base.union(b), false));
            chain.scored.len() - 1
        })
        .collect();
    let mut order: Vec<usize> = (0..blocks.len()).collect();
    order.sort_by(|a, b| chain.by_score(singles[*a], singles[*b]));
    let mut remaining: Vec<usize> = Vec::new();
    let mut kept = None;
    for (k, &b) in order.iter().enumerate() {
        chain.take(Stage::JointErrors, singles[b], groups);
        if chain.current == singles[b] {
            kept = Some(chain.scored[singles[b]].physics);
            remaining = order[k + 1..].to_vec();
            break;
        }
    }
    while let Some(current) = kept
        && !remaining.is_empty()
    {
        let tried: Vec<usize> = (remaining.iter())
            .map(|&b| {
                chain
                    .scored
                    .push(scorer.score(current.union(blocks[b]), false));
                chain.scored.len() - 1
            })
            .collect();
        let best = (0..tried.len())
            .min_by(|a, b| chain.by_score(tried[*a], tried[*b]))
            .expect("a block remains");
        chain.take(Stage::JointErrors, tried[best], groups);
        kept = (chain.current == tried[best]).then(|| chain.scored[tried[best]].physics);
        remaining.remove(best);
    }
}
