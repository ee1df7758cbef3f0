//! The physical candidates scored: each one's fits on every fold within its allowance of the
//! budget, or its start skipped where the budget would be spent before it ends.

use super::physics::{Effect, Physics};
use super::plan::FoldPlan;
use super::selection::Candidate;
use super::selection::report;
use super::settings::AutoSettings;
use super::status::Status;
use crate::budget::{self, Allowance, REFERENCE_CORES};
use crate::error::{CalibrationError, Result};
use crate::fit::fit_kinematic_with;
use crate::folds::Held;
use rayon::prelude::*;
use robocal_data::Observer;
use robocal_ident::{
    FLANK_ROUNDS, IdentError, KinematicCalibration, KinematicSettings, SEARCH_FLANK_ROUNDS,
};
use robocal_model::CalibratedModel;
use robocal_robot::Robot;
use std::time::{Duration, Instant};

/// A physical candidate scored on every fold.
pub(super) struct Scored {
    pub(super) physics: Physics,
    /// Selection score (none when a fold's fit failed).
    pub(super) score: Option<f64>,
    /// Every held-out error ([`Held::all`]; none when a fold's fit failed).
    pub(super) errors: Option<Vec<f64>>,
    /// The fitted model of each fold.
    pub(super) fitted: Vec<Option<CalibratedModel>>,
}

/// The share of the slowest physical candidate's seconds (every fold) set aside for the final
/// fit of the physics on every row when the residual models are given the rest of the budget.
/// The candidate's ten fits ran two at a time; the final fit, on a quarter more rows, runs its
/// rows on both cores: about 0.13 of the candidate's seconds (the paper's arm), 0.25 when it runs
/// on one core.
pub(super) const FINAL_FIT_SHARE: f64 = 0.2;

/// The seconds one fold's fit of a candidate may take when `left` seconds of the budget remain
/// for its `folds` fits, `at_once` at a time, and the final fit after them
/// ([`FINAL_FIT_SHARE`] of the folds' time): a fold past it leaves too little for the rest
/// at its pace (each round of folds takes as long as its slowest). Never negative.
pub(super) fn fold_share(left: f64, folds: usize, at_once: usize) -> f64 {
    let rounds = folds.div_ceil(at_once.max(1)).max(1);
    (left / (1.0 + FINAL_FIT_SHARE) / rounds as f64).max(0.0)
}

/// The fits of `physics` on every fold with the budget kept by counted work ([`budget`]), with
/// whether the candidate was abandoned and the reference seconds its work came to (charged to
/// `meter`). Each fold's fit may count up to its share of what the budget has left
/// ([`fold_share`] among the reference machine's [`REFERENCE_CORES`]), and stops where its count
/// passes it, at the same evaluation on every machine; the first [`REFERENCE_CORES`] folds are
/// fitted first, and the rest only if, at those folds' count, they and the final fit would end
/// within the budget — the decision a 2-core machine's clock makes after its first round, here
/// from counts. No fit runs past the budget by the clock (the guard).
pub(crate) fn counted_folds(
    physics: Physics,
    kinematic: &KinematicSettings,
    nominal: &Robot,
    plan: &FoldPlan<'_>,
    observer: &dyn Observer,
    budget: &Allowance<'_>,
) -> (Vec<Option<Result<KinematicCalibration>>>, bool, f64) {
    let splits = &plan.splits;
    let meter = budget.meter();
    let limit = physics.has_joint_errors().then(|| {
        let share = fold_share(budget.left(), splits.len(), REFERENCE_CORES);
        (share * budget::FIT_UNITS_PER_SECOND) as u64
    });
    let fit_range = |range: std::ops::Range<usize>| -> Vec<(Result<KinematicCalibration>, u64)> {
        (splits[range.clone()].par_iter())
            .zip(&plan.memos[range])
            .map(|(fold, memo)| {
                let work = robocal_ident::Work::new(limit);
                let until = KinematicSettings {
                    deadline: physics.has_joint_errors().then(|| meter.end()),
                    work: Some(work.clone()),
                    ..kinematic.clone()
                };
                let fit = fit_kinematic_with(nominal, &fold.train, &until, memo);
                observer.advance(1);
                (fit, work.count())
            })
            .collect()
    };
    let stopped = |fits: &[(Result<KinematicCalibration>, u64)]| {
        (fits.iter()).any(|(f, _)| matches!(f, Err(CalibrationError::Ident(IdentError::Deadline))))
    };
    let first = REFERENCE_CORES.min(splits.len());
    let mut fits = fit_range(0..first);
    let mut abandoned = stopped(&fits);
    if !abandoned && first < splits.len() {
        let units: u64 = fits.iter().map(|(_, u)| u).sum();
        let rest = budget::fit_seconds(units) / first as f64 * (splits.len() - first) as f64;
        if physics.has_joint_errors() && budget.over(rest * (1.0 + FINAL_FIT_SHARE)) {
            abandoned = true;
        } else {
            let more = fit_range(first..splits.len());
            abandoned = stopped(&more);
            fits.extend(more);
        }
    }
    let cost = budget::fit_seconds(fits.iter().map(|(_, u)| u).sum());
    meter.charge(cost);
    // A fold stopped at its count is one not fitted, as one never started.
    let mut fits: Vec<_> = (fits.into_iter())
        .map(|(f, _)| {
            (!matches!(f, Err(CalibrationError::Ident(IdentError::Deadline)))).then_some(f)
        })
        .collect();
    fits.resize_with(splits.len(), || None);
    (fits, abandoned, cost)
}

/// Fits `physics` on every fold and scores it on the fold's held-out rows. A joint-error
/// candidate is abandoned once its remaining folds, at the pace of those fitted, and the final
/// fit would run past its allowance (`budget`: the time budget less the seconds kept from this
/// candidate for the residual models, which its status then names), or once a fold's fit runs
/// past its share of what the allowance has left ([`fold_share`]): the folds not yet ended are
/// not fitted and the candidate has no score. Its start was projected from the candidates
/// before it ([`projection`]); one that unites more blocks than any before can take twice
/// that, and one with many more unknowns far more (the axis runouts on the paper's arm: 22–46 s
/// of folds spent before the pace says so).
pub(super) fn score_physics(
    physics: Physics,
    auto: &AutoSettings,
    nominal: &Robot,
    plan: &FoldPlan<'_>,
    observer: &dyn Observer,
    budget: &Allowance<'_>,
) -> (Candidate, Scored) {
    let splits = &plan.splits;
    let t = std::time::Instant::now();
    let kinematic = physics.settings(auto);
    let mut held = Held::default();
    let mut fitted = Vec::new();
    // Counted work's reference seconds (by the clock, the candidate's seconds below).
    let (fits, abandoned, counted) = if budget.meter().counts() {
        let (fits, abandoned, cost) =
            counted_folds(physics, &kinematic, nominal, plan, observer, budget);
        (fits, abandoned, Some(cost))
    } else {
        let (fits, abandoned) = clocked_folds(physics, &kinematic, nominal, plan, observer, budget);
        (fits, abandoned, None)
    };
    let mut status = abandoned.then(|| Status::Abandoned {
        budget: budget.budget(),
        reserve: budget.reserve(),
    });
    for (fold, fit) in splits.iter().zip(fits) {
        // A fold not fitted (the candidate abandoned).
        let Some(fit) = fit else {
            fitted.push(None);
            continue;
        };
        match fit {
            Ok(fit) => {
                let model = physics.model(&fit);
                held.add(fold, model.errors(&fold.test));
                fitted.push(Some(model));
            }
            Err(e) => {
                status = Some(Status::Failed(e.to_string()));
                fitted.push(None);
            }
        }
    }
    let seconds = t.elapsed().as_secs_f64();
    let mut c = Candidate {
        name: physics.name(),
        physics: Some(physics),
        held_out: None,
        held_out_blocks: None,
        score: None,
        seconds,
        cost: counted.unwrap_or(seconds),
        status: status.unwrap_or(Status::Evaluated),
    };
    if c.status == Status::Evaluated {
        let (random, blocked, score) = held.summary();
        (c.held_out, c.held_out_blocks, c.score) = (Some(random), blocked, Some(score));
    }
    report(&c, observer);
    let scored = Scored {
        physics,
        score: c.score,
        errors: c.score.map(|_| held.all()),
        fitted,
    };
    (c, scored)
}

/// The fits of `physics` on every fold with the budget kept by the clock, with whether the
/// candidate was abandoned. The folds' fits are independent: on every core at once, taken in
/// fold order (the same results on any number of cores), each sharing with the candidates
/// before it the fits of its rows they made. Before a fold starts, once a core's worth are
/// fitted, the rest are projected at their pace; a fold's fit stops at its share of what the
/// allowance has left ([`fold_share`]).
pub(crate) fn clocked_folds(
    physics: Physics,
    kinematic: &KinematicSettings,
    nominal: &Robot,
    plan: &FoldPlan<'_>,
    observer: &dyn Observer,
    budget: &Allowance<'_>,
) -> (Vec<Option<Result<KinematicCalibration>>>, bool) {
    use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
    let splits = &plan.splits;
    let t = std::time::Instant::now();
    let at_once = rayon::current_num_threads().max(1);
    let share = fold_share(budget.left(), splits.len(), at_once);
    let (done, abandoned) = (AtomicUsize::new(0), AtomicBool::new(false));
    let fits: Vec<_> = (splits.par_iter())
        .zip(&plan.memos)
        .map(|(fold, memo)| {
            let n = done.load(Ordering::SeqCst);
            if physics.has_joint_errors() && n >= at_once {
                let pace = t.elapsed().as_secs_f64() / n as f64;
                let left = pace * (splits.len() - n) as f64;
                if budget.over(left * (1.0 + FINAL_FIT_SHARE)) {
                    abandoned.store(true, Ordering::SeqCst);
                }
            }
            if abandoned.load(Ordering::SeqCst) {
                return None;
            }
            let until = KinematicSettings {
                deadline: (physics.has_joint_errors())
                    .then(|| Instant::now() + Duration::from_secs_f64(share)),
                ..kinematic.clone()
            };
            let fit = fit_kinematic_with(nominal, &fold.train, &until, memo);
            if matches!(fit, Err(CalibrationError::Ident(IdentError::Deadline))) {
                abandoned.store(true, Ordering::SeqCst);
                return None;
            }
            done.fetch_add(1, Ordering::SeqCst);
            observer.advance(1);
            Some(fit)
        })
        .collect();
    (fits, abandoned.load(Ordering::SeqCst))
}

/// The candidate of `physics` skipped before its folds when, with joint-error terms, its
/// projection ([`projection`] from the `candidates` before it) would run past its allowance.
pub(super) fn skipped(
    physics: Physics,
    candidates: &[Candidate],
    budget: &Allowance<'_>,
) -> Option<Candidate> {
    let (from, seconds, projected) = projection(physics, candidates);
    (physics.has_joint_errors() && budget.over(projected)).then(|| Candidate {
        name: physics.name(),
        physics: Some(physics),
        held_out: None,
        held_out_blocks: None,
        score: None,
        seconds: 0.0,
        cost: 0.0,
        status: Status::Projected {
            budget: budget.budget(),
            reserve: budget.reserve(),
            from,
            seconds,
            projected,
        },
    })
}

/// The seconds (by the budget's measure, [`Candidate::cost`]) a physical candidate's folds and
/// the final fit of its physics are projected to take from the candidates scored before it,
/// with what the projection is taken from and its seconds: the slowest candidate so far (a new
/// one holds at least as many terms), × (1 + [`FINAL_FIT_SHARE`]). The flank search fits the physics it extends, choosing the flanks up to
/// [`SEARCH_FLANK_ROUNDS`] times where that candidate chose them [`FLANK_ROUNDS`] times: projected
/// from that candidate where it was scored, × their ratio (a slower one before it — the axis
/// runouts the chain dropped — holds terms the search does not fit: on ARM7 it took 38 s against
/// 2.6 s), from the slowest elsewhere.
pub(super) fn projection(physics: Physics, candidates: &[Candidate]) -> (&'static str, f64, f64) {
    let rounds = if physics.has(Effect::FlankSearch) {
        SEARCH_FLANK_ROUNDS as f64 / FLANK_ROUNDS as f64
    } else {
        1.0
    };
    let extended = physics.has(Effect::FlankSearch).then(|| {
        let without = physics.without(Effect::FlankSearch);
        (candidates.iter().rev()).find(|c| c.physics == Some(without) && c.score.is_some())
    });
    let (from, seconds) = match extended.flatten() {
        Some(c) => ("the candidate it extends", c.cost),
        None => (
            "the slowest candidate",
            candidates.iter().map(|c| c.cost).fold(0.0, f64::max),
        ),
    };
    (from, seconds, seconds * rounds * (1.0 + FINAL_FIT_SHARE))
}
