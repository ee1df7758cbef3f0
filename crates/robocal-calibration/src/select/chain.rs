//! The chain of physical candidates: each richer model taken only where it lowers the held-out
//! errors significantly.

use super::physics::{Physics, Scored, projection, score_physics};
use super::plan::FoldPlan;
use super::words::{leaving, report, the_budget};
use super::{AutoSettings, Candidate};
use crate::budget::Meter;
use crate::folds::improves;
use crate::rows::loads;
use robocal_data::{Measurement, Observer};
use robocal_robot::Robot;

/// One step of the chain: a richer physical model tried on the current one.
pub(super) struct Step {
    /// The decision it belongs to.
    pub(super) stage: &'static str,
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
    /// Why compliance was not tried, if it was not.
    pub(super) compliance_skip: Option<String>,
}

impl Chain {
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
    pub(super) fn step(&mut self, stage: &'static str, next: Scored, groups: &[usize]) {
        self.scored.push(next);
        self.take(stage, self.scored.len() - 1, groups);
    }

    /// Compares the scored candidate `next` (already in the chain) with the current model and
    /// takes it if it is significantly better.
    pub(super) fn take(&mut self, stage: &'static str, next: usize, groups: &[usize]) {
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

/// The physical models, each scored on every fold: the nominal table, the identified one, with
/// compliances (two or more loads); then, on the current identified one, transmission
/// harmonics and self-weight terms by forward stepwise selection — each kept only if it lowers
/// the held-out errors significantly.
#[allow(clippy::too_many_arguments)]
pub(super) fn physics_chain(
    settings: &AutoSettings,
    nominal: &Robot,
    rows: &[&Measurement],
    plan: &FoldPlan<'_>,
    groups: &[usize],
    candidates: &mut Vec<Candidate>,
    observer: &dyn Observer,
    meter: &Meter,
    (over_budget, left, residual_share): (
        &(dyn Fn(f64) -> bool + Sync),
        &(dyn Fn() -> f64 + Sync),
        f64,
    ),
) -> Chain {
    // A candidate scored with `reserve` seconds of the budget kept from it: the axis runouts'
    // candidate, the one with the most unknowns and the slowest (its pace known only after a
    // core's worth of folds), leaves `residual_share` of the budget to the residual models
    // ([`RESIDUAL_SHARE`]); every other (the flank search and the tilt after it too, on physics
    // that may hold the runouts) has the whole budget.
    let mut score = |physics: Physics, reserve: f64| {
        let over_budget = |spent: f64| over_budget(spent + reserve);
        let left = || left() - reserve;
        let leaving = match leaving(reserve) {
            words if words.is_empty() => words,
            words => words + ",",
        };
        // A joint-error candidate does not start when the budget would be spent before it and the
        // final fit of its physics end (`projection`).
        let (from, seconds, projected) = projection(physics, candidates);
        if physics.has_joint_errors() && over_budget(projected) {
            let c = Candidate {
                name: physics.name(),
                held_out: None,
                held_out_blocks: None,
                score: None,
                seconds: 0.0,
                cost: 0.0,
                status: format!(
                    "skipped: {}{leaving} would be spent before its folds and the final fit end (projected from {from}, {seconds:.1} s: {projected:.1} s)",
                    the_budget(settings.budget_seconds)
                ),
                budget_cut: true,
            };
            report(&c, observer);
            candidates.push(c);
            return Scored {
                physics,
                score: None,
                errors: None,
                fitted: vec![None; plan.splits.len()],
                budget_cut: true,
            };
        }
        score_physics(
            physics,
            settings,
            nominal,
            plan,
            candidates,
            observer,
            meter,
            (&over_budget, &left, reserve),
        )
    };
    let mut chain = Chain {
        scored: vec![score(Physics::ALIGNED, 0.0)],
        steps: Vec::new(),
        current: 0,
        compliance_skip: None,
    };
    chain.step("kinematic", score(Physics::RIGID, 0.0), groups);
    let loads = loads(rows);
    if loads.len() >= 2 {
        let elastic = Physics {
            compliance: true,
            ..Physics::RIGID
        };
        chain.step("compliance", score(elastic, 0.0), groups);
    } else {
        chain.compliance_skip = Some(format!(
            "skipped: the data hold one load ({} kg); compliance needs two or more",
            loads.first().copied().unwrap_or(0.0)
        ));
    }
    // The joint-error blocks by forward stepwise selection: each block alone on the identified
    // model, in the order of their held-out scores, until one is kept (significantly better);
    // then each remaining block added to the kept ones, the best of them taken if it is
    // significantly better, until none is or none remains. A flexible block cannot take the place
    // of the block whose form the effect has only because it was tried first (harmonics of the
    // joint angles absorb part of a self-weight deflection or of a backlash step, and extrapolate
    // them badly).
    let base = chain.scored[chain.identified()].physics;
    let none = Physics {
        harmonics: 0,
        self_weight: false,
        backlash: false,
        tilt: false,
        runout: 0,
        ..base
    };
    let blocks: Vec<Physics> = [
        (settings.harmonics > 0).then_some(Physics {
            harmonics: settings.harmonics,
            ..none
        }),
        settings.self_weight.then_some(Physics {
            self_weight: true,
            ..none
        }),
        settings.backlash.then_some(Physics {
            backlash: true,
            ..none
        }),
    ]
    .into_iter()
    .flatten()
    .collect();
    // Every scored candidate joins the chain in the order it was scored, so that the chain's
    // indices stay those of the candidates.
    let singles: Vec<usize> = (blocks.iter())
        .map(|&b| {
            chain.scored.push(score(base.union(b), 0.0));
            chain.scored.len() - 1
        })
        .collect();
    let by_score = |chain: &Chain, a: &usize, b: &usize| match (
        chain.scored[*a].score,
        chain.scored[*b].score,
    ) {
        (Some(x), Some(y)) => x.total_cmp(&y),
        (Some(_), None) => std::cmp::Ordering::Less,
        (None, Some(_)) => std::cmp::Ordering::Greater,
        (None, None) => std::cmp::Ordering::Equal,
    };
    let mut order: Vec<usize> = (0..blocks.len()).collect();
    order.sort_by(|a, b| by_score(&chain, &singles[*a], &singles[*b]));
    let mut remaining: Vec<usize> = Vec::new();
    let mut kept = None;
    for (k, &b) in order.iter().enumerate() {
        chain.take("joint_errors", singles[b], groups);
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
                chain.scored.push(score(current.union(blocks[b]), 0.0));
                chain.scored.len() - 1
            })
            .collect();
        let best = (0..tried.len())
            .min_by(|a, b| by_score(&chain, &tried[*a], &tried[*b]))
            .expect("a block remains");
        chain.take("joint_errors", tried[best], groups);
        kept = (chain.current == tried[best]).then(|| chain.scored[tried[best]].physics);
        remaining.remove(best);
    }
    // The axis runouts on the physics the blocks reached: one candidate more, kept only if it
    // lowers the held-out errors significantly.
    let current = chain.scored[chain.current].physics;
    if settings.runout > 0 && !current.aligned {
        let wobbling = Physics {
            runout: settings.runout,
            ..current
        };
        chain.step("runout", score(wobbling, residual_share), groups);
        // Where the budget cut the runouts' fits (skipped, or abandoned during their folds), the
        // cheaper fit that starts them from the model without them, whose first fit and flanks
        // the candidates before made (a third of the work on the paper's arm, whose twin beyond
        // the model, at 75 s, goes from 0.101 to 0.022 mm on its joint-1 extrapolation with it).
        // Other fits than the full one, so tried only where that one has no score; and only
        // where the compliances' first fit would hold the runouts (elsewhere the two are the
        // same fits).
        let cut = chain.scored.last().is_some_and(|s| s.budget_cut);
        if cut && wobbling.settings(settings).runouts_in_first_fit() {
            let cheaper = Physics {
                runout_from_without: true,
                ..wobbling
            };
            chain.step("runout", score(cheaper, residual_share), groups);
        }
    }
    // The backlash flanks searched beyond each joint's own terms, on chosen physics with
    // backlash (or, where asked, with backlash added where the block was not kept): one
    // candidate more, kept only if it lowers the held-out errors significantly.
    let current = chain.scored[chain.current].physics;
    let added = settings.flank_search && settings.backlash && !current.backlash;
    if (current.backlash || added) && !current.aligned {
        let searched = Physics {
            backlash: true,
            flank_search: true,
            ..current
        };
        chain.step("flank_search", score(searched, 0.0), groups);
    }
    // Last, the bearings' tilt on the chosen physics (with the compliances: the payload's moment
    // and, where the links' weights were kept, theirs): one candidate more, kept only if it
    // lowers the held-out errors significantly.
    let current = chain.scored[chain.current].physics;
    if settings.tilt && current.compliance && !current.aligned {
        let tilted = Physics {
            tilt: true,
            ..current
        };
        chain.step("tilt", score(tilted, 0.0), groups);
    }
    debug_assert!(
        (chain.scored.iter().zip(candidates.iter())).all(|(s, c)| s.physics.name() == c.name)
            && chain.scored.len() == candidates.len()
    );
    chain
}
