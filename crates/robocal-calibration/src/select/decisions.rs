//! The decisions the selection reports, one per stage, and the reach of joint 1's harmonics.

use super::chain::Chain;
use super::physics::{Effect, Physics, orders_words};
use super::plan::FoldPlan;
use super::residual::ResidualScore;
use super::scoring::Scored;
use super::selection::{Candidate, Decision};
use super::settings::AutoSettings;
use super::status::Stage;
use crate::folds::improves;
use robocal_data::Measurement;
use robocal_model::Domain;

/// The share of the held predictions' error on the blocks of joint 1 that joint 1's harmonics,
/// continued periodically, must take away for the final model to continue them at every angle
/// (the default calibration's `harmonic_reach` decision). The blocks test a quarter of the
/// readings' span beyond them; the model is continued as far as it is used: a harmonic that
/// only just beats holding that near is too uncertain to carry farther (on the development
/// twins, gains of 2–15 % there came with losses of 2–9 % a quarter to two fifths of the span
/// beyond).
pub const REACH_GAIN: f64 = 0.2;

/// How far joint 1's transmission harmonics (and its runouts' waves, which are held and continued
/// alike: [`robocal_robot::JointErrors::waves_mut`]) are continued beyond its readings, decided on the
/// blocks of joint 1: each fold's model of the chosen physics predicts the rows of its block
/// that lie beyond the joint-1 readings it was fitted on, once with joint 1's harmonics held at
/// those readings' nearer end and once continued periodically. Where continued lowers held
/// significantly ([`improves`], over configurations) and by at least [`REACH_GAIN`] of it,
/// joint 1's harmonics are a gear's, well determined, not a fit of something else over a
/// narrow window, and the final model continues them at every angle; elsewhere they keep their
/// reach (a quarter of the readings' span beyond them, [`robocal_robot::HARMONIC_REACH`]).
/// `None`: no blocks, or the physics holds no joint-1 harmonic, or none of a block's rows lie
/// beyond its fold's readings.
pub(super) fn harmonic_reach(scored: &Scored, plan: &FoldPlan<'_>) -> Option<Decision> {
    let mut held = Vec::new();
    let mut continued = Vec::new();
    let mut rows: Vec<&Measurement> = Vec::new();
    for (fold, model) in plan.splits.iter().zip(&scored.fitted) {
        let Some(model) = model.as_ref().filter(|_| fold.blocked) else {
            continue;
        };
        let Some(domain) = Domain::of(fold.train.iter().map(|r| &r.sample)) else {
            continue;
        };
        let beyond: Vec<&Measurement> = (fold.test.iter())
            .filter(|r| domain.excess(&r.sample).iter().any(|e| e.joint == 0))
            .copied()
            .collect();
        let reached = |reach: Option<[f64; 2]>| {
            let mut m = model.clone();
            let errors = m.joint_errors.as_mut()?;
            let mut any = false;
            for h in errors.waves_mut().filter(|h| h.joint == 0) {
                h.reach = reach;
                any |= h.sin != 0.0 || h.cos != 0.0;
            }
            any.then_some(m)
        };
        let at_readings = domain.joints.first().map(|r| r.map(f64::to_radians));
        let (Some(at_ends), Some(periodic)) = (reached(at_readings), reached(None)) else {
            continue;
        };
        held.extend(at_ends.errors(&beyond));
        continued.extend(periodic.errors(&beyond));
        rows.extend(beyond);
    }
    if held.is_empty() {
        return None;
    }
    let (groups, _) = crate::folds::configuration_groups(&rows);
    let mean = |e: &[f64]| e.iter().sum::<f64>() / e.len() as f64;
    let (without, with) = (mean(&held), mean(&continued));
    let kept = improves(&held, &continued, &groups) && with < (1.0 - REACH_GAIN) * without;
    Some(Decision::said(
        Stage::HarmonicReach,
        kept,
        Some(without),
        Some(with),
        format!(
            "{}: {without:.4} mm held at the readings' nearer end, {with:.4} mm with joint 1's harmonics continued periodically, on the {} rows of the blocks of joint 1 beyond their folds' readings{}",
            if kept { "kept" } else { "dropped" },
            held.len(),
            if kept {
                ": continued at every angle".to_string()
            } else {
                format!(
                    " (continued must be lower by twice its standard error and by {:.0} % of held): continued a quarter of the readings' span beyond them, held farther",
                    100.0 * REACH_GAIN
                )
            }
        ),
    ))
}

impl Decision {
    /// A decision in the words `reason`, which say no verdict of their own.
    pub(super) fn said(
        stage: Stage,
        kept: bool,
        without: Option<f64>,
        with: Option<f64>,
        reason: String,
    ) -> Self {
        Self {
            stage,
            kept,
            held_out_without: without,
            held_out_with: with,
            after_verdict: reason.clone(),
            reason,
        }
    }

    /// A decision comparing the scores without and with the stage (`what` it adds), its reason
    /// `kept` or `dropped` and the two scores; without both scores, `what` alone.
    pub(super) fn compared(
        stage: Stage,
        kept: bool,
        without: Option<f64>,
        with: Option<f64>,
        what: &str,
    ) -> Self {
        let (verdict, after_verdict) = match (without, with) {
            (Some(w), Some(x)) => (
                if kept { "kept" } else { "dropped" },
                format!(
                    ": held-out score {w:.4} mm without, {x:.4} mm with {what}{}",
                    if !kept && x < w {
                        " (lower, but not by more than twice its standard error)"
                    } else if kept && x >= w {
                        " (the chosen residual model is trained on it)"
                    } else {
                        ""
                    }
                ),
            ),
            _ => ("", what.to_string()),
        };
        Self {
            stage,
            kept,
            held_out_without: without,
            held_out_with: with,
            reason: format!("{verdict}{after_verdict}"),
            after_verdict,
        }
    }

    /// The decision of a stage the chain kept, dropped from the chosen model: a residual model
    /// on the identified table alone scored lower than the physical models that hold it.
    pub(super) fn not_in_chosen(&mut self) {
        self.kept = false;
        self.reason = format!(
            "not in the chosen model: a residual model on the identified table alone scored lower than the physical models that hold it (kept by the chain of physical models{})",
            self.after_verdict
        );
    }
}

/// One decision per stage — kinematic, compliance, joint errors, runout, flank search, tilt,
/// residual — each comparing the model the stage was tried on with the model with it (`chosen`:
/// the physics of the chosen model, `residual`: the residual model chosen, or the best scored,
/// with its score).
pub(super) fn decisions(
    settings: &AutoSettings,
    chain: &Chain,
    candidates: &[Candidate],
    chosen: Physics,
    residuals: &[ResidualScore],
    residual: Option<(usize, f64)>,
    residual_wins: bool,
) -> Vec<Decision> {
    let mut out = Vec::new();
    let score = |i: usize| chain.scored[i].score;
    for step in chain.steps_of(Stage::Kinematic) {
        out.push(Decision::compared(
            Stage::Kinematic,
            !chosen.aligned,
            score(step.base),
            score(step.next),
            "the identified table (LM, identifiable parameters)",
        ));
    }
    out.push(compliance(chain, candidates, chosen));
    out.push(joint_errors(chain));
    out.extend(after_blocks(settings, chain, chosen));
    out.push(residual_decision(
        chain,
        candidates,
        residuals,
        residual,
        residual_wins,
    ));
    out
}

/// The compliances' decision: skipped with one load, else the step's comparison, else why its
/// candidate has no score.
fn compliance(chain: &Chain, candidates: &[Candidate], chosen: Physics) -> Decision {
    let score = |i: usize| chain.scored[i].score;
    let step = chain.steps_of(Stage::Compliance).into_iter().next();
    match (chain.skip_of(Stage::Compliance), step) {
        (Some(why), _) => Decision::compared(Stage::Compliance, false, None, None, why),
        (None, Some(step)) if score(step.next).is_some() => Decision::compared(
            Stage::Compliance,
            chosen.has(Effect::Compliance),
            score(step.base),
            score(step.next),
            "joint compliances identified with the geometry on every load",
        ),
        (None, step) => Decision::compared(
            Stage::Compliance,
            false,
            None,
            None,
            &step.map_or("skipped".to_string(), |s| {
                candidates[s.next].status.to_string()
            }),
        ),
    }
}

/// The joint-error blocks' decision: kept where the stage kept a block, named by the blocks of
/// the model it scored (backlash the flank search added and the tilts are their own decisions);
/// with the stage, the last step the chain kept, else the best one tried.
fn joint_errors(chain: &Chain) -> Decision {
    let score = |i: usize| chain.scored[i].score;
    let joint_errors = chain.steps_of(Stage::JointErrors);
    let with = (joint_errors.iter().rev().find(|s| s.kept))
        .or_else(|| {
            (joint_errors.iter())
                .filter(|s| score(s.next).is_some())
                .min_by(|a, b| {
                    score(a.next)
                        .unwrap_or(f64::INFINITY)
                        .total_cmp(&score(b.next).unwrap_or(f64::INFINITY))
                })
        })
        .copied();
    let has_errors = joint_errors.iter().any(|s| s.kept);
    match (joint_errors.first(), with) {
        (Some(first), Some(step)) => Decision::compared(
            Stage::JointErrors,
            has_errors,
            score(first.base),
            score(step.next),
            &chain.scored[step.next].physics.joint_error_terms(),
        ),
        _ => Decision::compared(
            Stage::JointErrors,
            false,
            None,
            None,
            "not tried (no harmonics, self-weight or backlash in the settings), or every fit failed",
        ),
    }
}

/// The decisions of the links after the blocks: the runouts (the last step: the cheaper fit's
/// where the budget cut the full one), the flank search, the tilts.
fn after_blocks(settings: &AutoSettings, chain: &Chain, chosen: Physics) -> Vec<Decision> {
    let score = |i: usize| chain.scored[i].score;
    let mut out = Vec::new();
    if let Some(step) = chain.steps_of(Stage::Runout).last() {
        out.push(Decision::compared(
            Stage::Runout,
            chosen.runout() > 0,
            score(step.base),
            score(step.next),
            &format!(
                "axis runouts identified with the geometry ({}): the parts beyond each joint turning across its axis periodically in its angle",
                orders_words(settings.runout)
            ),
        ));
    }
    if let Some(step) = chain.steps_of(Stage::FlankSearch).first() {
        out.push(Decision::compared(
            Stage::FlankSearch,
            chosen.has(Effect::FlankSearch),
            score(step.base),
            score(step.next),
            if chain.scored[step.base].physics.has(Effect::Backlash) {
                "the backlash flanks searched beyond each joint's own terms (a torque flank's preload where its step explains most)"
            } else {
                "backlash added (the block was not kept with the regression's flanks), its flanks searched beyond each joint's own terms (a torque flank's preload where its step explains most)"
            },
        ));
    }
    out.push(match chain.steps_of(Stage::Tilt).first() {
        Some(step) => Decision::compared(
            Stage::Tilt,
            chosen.has(Effect::Tilt),
            score(step.base),
            score(step.next),
            "tilting compliances identified with the geometry: the parts beyond each joint turning across its axis under the gravity moment of the payload and of the links' weights",
        ),
        None => Decision::compared(
            Stage::Tilt,
            false,
            None,
            None,
            if settings.tilt {
                "not tried: the chosen physics holds no compliances"
            } else {
                "not tried (`calibrate --tilt`, or tilt=True in Python, tries it)"
            },
        ),
    });
    out
}

/// The residual model's decision against the physics the chain ended on: the model chosen (or
/// the best scored, `residual`), or why none was scored.
fn residual_decision(
    chain: &Chain,
    candidates: &[Candidate],
    residuals: &[ResidualScore],
    residual: Option<(usize, f64)>,
    residual_wins: bool,
) -> Decision {
    let physics_mean = chain.scored[chain.current].score.unwrap_or(f64::INFINITY);
    match residual {
        Some((r, mean)) => Decision::compared(
            Stage::Residual,
            residual_wins,
            Some(physics_mean),
            Some(mean),
            &format!(
                "a {} residual model{} (of {} tried, the lowest-scoring of those significantly better than the physical model)",
                residuals[r].stage.settings.kind.name(),
                if residuals[r].base == chain.identified() {
                    String::new()
                } else {
                    format!(
                        " on the identified table alone, in the {} frame",
                        residuals[r].stage.settings.frame.name()
                    )
                },
                residuals.len()
            ),
        ),
        None => Decision::compared(
            Stage::Residual,
            false,
            Some(physics_mean),
            None,
            &candidates
                .get(chain.scored.len())
                .map_or("skipped: no residual model configured".to_string(), |c| {
                    c.status.to_string()
                }),
        ),
    }
}
