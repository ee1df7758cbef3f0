//! The default calibration from end to end: bad shots and gravity, the chain of physical
//! candidates, the residual candidates, the choice, the final fit.

use super::chain::{Chain, Scorer, physics_chain};
use super::decisions::{decisions, harmonic_reach};
use super::gravity::{mounting, residual_stages};
use super::physics::Physics;
use super::plan::FoldPlan;
use super::residual::{
    ResidualScore, TABLE_FRAMES, Trainer, pick_residual, residual_candidates, residual_share,
};
use super::scoring::FINAL_FIT_SHARE;
use super::selection::{Candidate, Decision, Selection, budget_warning};
use super::settings::AutoSettings;
use super::status::{Stage, Status};
use crate::budget::{self, Allowance, Meter};
use crate::built::Built;
use crate::configured::configured;
use crate::error::Result;
use crate::outliers::{OutlierReport, find_outliers};
use crate::rows::configurations;
use crate::stages::Stages;
use robocal_data::{Measurement, Observer, Silent};
use robocal_ident::{ComplianceSettings, Fixed, KinematicSettings};
use robocal_robot::Robot;
use std::time::Instant;

/// The default calibration: every candidate model — the nominal table with base and tool
/// fitted; kinematic identification; with joint compliances (two or more loads); with
/// transmission harmonics, with self-weight terms; each residual model of `settings` on top of
/// the best identified one (in both frames where joint 1 lies off gravity: [`residual_stages`])
/// — is scored by its error on held-out poses: the mean of its mean
/// over k random folds of configurations (interpolation) and over k contiguous blocks of joint
/// 1's range (extrapolation to a new working area), or its mean on the `validation` rows.
///
/// The choice is a chain — identified table, compliance, the joint-error blocks by forward
/// stepwise selection (harmonics and self-weight each alone, the better first, then the other),
/// the best residual model — each step taken only if it lowers the held-out errors significantly
/// ([`improves`]); the model it ends on is fitted again on every row. `observer` hears a line
/// per candidate and per decision, and counts the fits.
///
/// [`improves`]: crate::folds::improves
pub fn automatic(
    settings: &AutoSettings,
    nominal: &Robot,
    rows: &[&Measurement],
    validation: Option<(&[&Measurement], String)>,
    observer: &dyn Observer,
) -> Result<Built> {
    let mut decisions = Vec::new();
    // The rows of points beyond the main one: weighed by their spread, or left out.
    let extra = super::targets::decide(settings, nominal, rows, validation.as_ref(), observer)?;
    let settings = match &extra {
        Some((_, extra)) => super::targets::weighed(settings, extra),
        None => settings.clone(),
    };
    let rows: Vec<&Measurement> = match &extra {
        Some((_, super::targets::Extra::MainOnly)) => {
            super::targets::main_rows(rows, &super::targets::main_target(rows))
        }
        _ => rows.to_vec(),
    };
    decisions.extend(extra.map(|(d, _)| d));
    // The play that follows the order of motion: with it kept, every candidate sees the rows
    // at the joint angles it puts them at.
    let motion = super::motion::decide(&settings, nominal, &rows, validation.as_ref(), observer)?;
    let play = motion.as_ref().and_then(|(_, p)| p.clone());
    decisions.extend(motion.map(|(d, _)| d));
    let (read, read_validation) = match &play {
        Some(p) => (
            super::motion::read_rows(p, &rows),
            validation
                .as_ref()
                .map(|(v, _)| super::motion::read_rows(p, v)),
        ),
        None => (Vec::new(), None),
    };
    let read_rows: Vec<&Measurement> = read.iter().collect();
    let read_v: Option<Vec<&Measurement>> = read_validation.as_ref().map(|v| v.iter().collect());
    let (rows, validation) = match &play {
        Some(_) => (read_rows, read_v.as_deref().zip(validation.map(|(_, s)| s))),
        None => (rows, validation),
    };
    // The budget is the chain's and the residual models': the stages before them are not
    // charged to it.
    let meter = Meter::new(settings.budget_seconds, settings.reproducible);
    let mut built = automatic_metered(&settings, nominal, &rows, validation, observer, &meter)?;
    built.motion = play;
    if let Some(selection) = &mut built.selection {
        selection.decisions.splice(0..0, decisions);
    }
    Ok(built)
}

/// [`automatic`] with its budget kept by `meter`.
pub(crate) fn automatic_metered(
    settings: &AutoSettings,
    nominal: &Robot,
    rows: &[&Measurement],
    validation: Option<(&[&Measurement], String)>,
    observer: &dyn Observer,
    meter: &Meter,
) -> Result<Built> {
    let start = Instant::now();
    let prepared = prepare(settings, nominal, rows)?;
    let (settings, rows) = (&prepared.settings, prepared.rows.as_slice());
    let Some(plan) = FoldPlan::new(settings, rows, validation.as_ref()) else {
        let mut built = kinematic_only(settings, nominal, rows, observer, start)?;
        built.outliers = prepared.outliers;
        return Ok(built);
    };
    meter.charge(budget::fit_seconds(prepared.work.count()));
    // The progress bar counts fits: every candidate on every fold, and the final one. Physical
    // candidates: nominal, identified, compliance, and at most n + (n − 1) + … + 1 of the n
    // joint-error blocks' stepwise selection.
    let blocks = usize::from(settings.harmonics > 0)
        + usize::from(settings.self_weight)
        + usize::from(settings.backlash);
    let physical = 3 + blocks * (blocks + 1) / 2 + usize::from(settings.runout > 0);
    observer.start(
        "candidates × folds fitted",
        (plan.splits.len() * (physical + settings.residuals.len() + TABLE_FRAMES.len()) + 1) as u64,
    );
    let groups = plan.groups();
    let mut scorer = Scorer {
        settings,
        nominal,
        plan: &plan,
        observer,
        budget: Allowance::new(meter),
        residual_share: residual_share(settings, plan.fewest_configurations()),
        candidates: Vec::new(),
    };
    let chain = physics_chain(&mut scorer, rows, &groups);
    let mut candidates = scorer.candidates;
    // The final fit of the chosen physics on every row, kept out of the residual models'
    // budget: about a fold's fit of the slowest physical candidate (its folds ran two at a time)
    // on a quarter more rows and both cores, with room to spare.
    let reserve = FINAL_FIT_SHARE * (candidates.iter()).map(|c| c.cost).fold(0.0, f64::max);
    let budget = Allowance::new(meter).keeping(reserve);
    let mut trainer = Trainer::new(settings, &chain, &plan, &groups, observer, budget);
    let residuals = residual_candidates(&mut trainer, &mut candidates)?;
    let choice = choose(
        settings,
        &chain,
        &plan,
        &mut candidates,
        &residuals,
        observer,
    );
    let mut built = final_fit(
        settings,
        nominal,
        rows,
        validation,
        &plan,
        (&choice, &residuals),
        observer,
    )?;
    observer.finish();
    let mut decisions = choice.decisions;
    note_implausible(&mut decisions, &built, observer);
    if let Some(w) = prepared.mounting_warning {
        built.kinematic.report.warnings.push(w);
    }
    if let Some(w) = budget_warning(&candidates, settings.budget_seconds) {
        built.kinematic.report.warnings.push(w);
    }
    built.outliers = prepared.outliers;
    built.selection = Some(Selection {
        held_out: plan.held_out.clone(),
        folds: plan.splits.len(),
        fitted_rows: plan.splits.iter().map(|f| f.train.len()).sum(),
        held_out_rows: plan.splits.iter().map(|f| f.test.len()).sum(),
        candidates,
        decisions,
        refitted_on_every_row: plan.refit,
        budget_seconds: settings.budget_seconds,
        seconds: start.elapsed().as_secs_f64(),
        reproducible: settings.reproducible,
        counted_seconds: meter.counts().then(|| meter.spent()),
    });
    Ok(built)
}

/// What the selection works on once the data are looked at: the bad shots found and the rows
/// kept, the settings with gravity decided (and the warning of a mounting decided from the
/// data) and every residual model to try, and the work those fits counted.
pub(crate) struct Prepared<'a> {
    outliers: Option<OutlierReport>,
    rows: Vec<&'a Measurement>,
    settings: AutoSettings,
    mounting_warning: Option<String>,
    work: robocal_ident::Work,
}

/// The bad shots' search, then gravity decided once for an arm on a wall or a ceiling (for
/// every candidate and fold: each fit deciding it again would identify every candidate three
/// times), and the residual models in both frames where joint 1 lies off gravity.
pub(crate) fn prepare<'a>(
    settings: &AutoSettings,
    nominal: &Robot,
    rows: &[&'a Measurement],
) -> Result<Prepared<'a>> {
    // What the fits before the candidates count (the bad shots' search, the mounting), charged
    // to a counted budget.
    let work = robocal_ident::Work::new(None);
    let (outliers, kept) = match &settings.outliers {
        Some(o) if configurations(rows).len() >= 4 => {
            let search = KinematicSettings {
                work: Some(work.clone()),
                ..KinematicSettings::default()
            };
            let (report, kept) = find_outliers(nominal, rows, &search, o)?;
            (Some(report), kept)
        }
        _ => (None, rows.to_vec()),
    };
    let mut settings = settings.clone();
    let mut mounting_warning = None;
    if settings.gravity.is_none()
        && let Some((gravity, warning)) = mounting(&settings, nominal, &kept, &work)
    {
        settings.gravity = Some(gravity);
        mounting_warning = warning;
    }
    let gravity = (settings.gravity).unwrap_or(ComplianceSettings::default().gravity);
    settings.residuals = residual_stages(&settings, nominal, &gravity);
    Ok(Prepared {
        outliers,
        rows: kept,
        settings,
        mounting_warning,
        work,
    })
}

/// What the selection chose: the residual model that won (index into the residual candidates,
/// with its score), the physics the chosen model holds, the decisions, and the reach of joint
/// 1's harmonics.
pub(crate) struct Choice {
    residual_wins: Option<(usize, f64)>,
    chosen_physics: Physics,
    decisions: Vec<Decision>,
    reach: Option<Decision>,
}

/// The winner: a residual model significantly better than the physical model, else the
/// physical model the chain ended on; marked chosen among `candidates`, with the decisions
/// (said to `observer`).
pub(crate) fn choose(
    settings: &AutoSettings,
    chain: &Chain,
    plan: &FoldPlan<'_>,
    candidates: &mut [Candidate],
    residuals: &[ResidualScore],
    observer: &dyn Observer,
) -> Choice {
    let best_residual = (residuals.iter().enumerate())
        .filter_map(|(r, s)| s.score.map(|m| (r, m)))
        .min_by(|a, b| a.1.total_cmp(&b.1));
    let physics_mean = chain.scored[chain.current].score.unwrap_or(f64::INFINITY);
    let residual_wins = pick_residual(residuals, physics_mean);
    // The winner, and the physical candidate it holds (a residual model's is the one it was
    // trained on).
    let (winner, chosen_scored) = match residual_wins {
        Some((r, _)) => (chain.scored.len() + r, residuals[r].base),
        None => (chain.current, chain.current),
    };
    let chosen_physics = chain.scored[chosen_scored].physics;
    candidates[winner].status = Status::Chosen;
    // The decisions are the chain's; a residual model chosen on the identified table alone
    // drops what the chain kept, and says so.
    let on_table = residual_wins.is_some_and(|(r, _)| residuals[r].base != chain.identified());
    let chain_physics = if on_table {
        chain.scored[chain.identified()].physics
    } else {
        chosen_physics
    };
    let mut decisions = decisions(
        settings,
        chain,
        candidates,
        chain_physics,
        residuals,
        residual_wins.or(best_residual),
        residual_wins.is_some(),
    );
    if on_table {
        for d in (decisions.iter_mut())
            .filter(|d| d.kept && ![Stage::Kinematic, Stage::Residual].contains(&d.stage))
        {
            d.not_in_chosen();
        }
    }
    let reach = harmonic_reach(&chain.scored[chosen_scored], plan);
    decisions.extend(reach.clone());
    for d in &decisions {
        observer.message(&format!("stage {}: {}", d.stage, d.reason));
    }
    observer.message(&format!(
        "chosen: {} (held-out score {:.4} mm)",
        candidates[winner].name,
        candidates[winner].score.unwrap_or(f64::NAN)
    ));
    Choice {
        residual_wins,
        chosen_physics,
        decisions,
        reach,
    }
}

/// The chosen model fitted on every row (with a validation file: on the data file's rows, the
/// validation file early-stopping the networks as it always has): the chosen residual model's
/// deviations scaled as its folds found, the nominal table where the chain chose it, and joint
/// 1's harmonics continued where the reach decision says so.
pub(crate) fn final_fit(
    settings: &AutoSettings,
    nominal: &Robot,
    rows: &[&Measurement],
    validation: Option<(&[&Measurement], String)>,
    plan: &FoldPlan<'_>,
    (choice, residuals): (&Choice, &[ResidualScore]),
    observer: &dyn Observer,
) -> Result<Built> {
    let stages = Stages {
        kinematic: choice.chosen_physics.settings(settings),
        residual: (choice.residual_wins).map(|(r, _)| residuals[r].stage.clone()),
        default: None,
    };
    if plan.refit {
        observer.message("fitting the chosen model again on every row");
    }
    let mut built = configured(&stages, nominal, rows, validation, &Silent)?;
    observer.advance(1);
    if let (Some((r, _)), Some((model, report))) = (choice.residual_wins, built.residual.as_mut()) {
        if let Some(s) = residuals[r].spread {
            model.set_std_scale(s.scale);
            report.spread = Some(s);
        }
        // A network's spread beside the physics' deviation.
        if let Some(b) = residuals[r].beside {
            model.spread_mm = Some(b.spread);
            report.spread_beside = Some(b);
        }
    }
    if choice.chosen_physics.aligned {
        built.kinematic.robot = built.kinematic.aligned.clone();
        built.kinematic.compliance = None;
        built.kinematic.covariance = None;
    }
    if (choice.reach.as_ref()).is_some_and(|d| d.kept)
        && let Some(errors) = built.kinematic.compliance.as_mut()
    {
        for h in errors.waves_mut().filter(|h| h.joint == 0) {
            h.reach = None;
        }
    }
    Ok(built)
}

/// Compliances the final fit found impossible and held (rigid, or at the value of its first
/// fit without the links' weights and backlash), in the compliances' decision.
pub(crate) fn note_implausible(decisions: &mut [Decision], built: &Built, observer: &dyn Observer) {
    let implausible: Vec<&str> = (built.kinematic.report.fixed.iter())
        .filter(|f| f.why == Fixed::Implausible)
        .map(|f| f.name.as_str())
        .collect();
    if let Some(d) = decisions.iter_mut().find(|d| d.stage == Stage::Compliance)
        && !implausible.is_empty()
    {
        let note = format!(
            "; held (rigid, or at the first fit's value) as implausible in the final fit (negative, beyond {} deg/kN·m, or within their own uncertainty): {}",
            robocal_ident::COMPLIANCE_BOUND,
            implausible.join(", ")
        );
        d.reason.push_str(&note);
        observer.message(&format!("stage compliance: {}", d.reason));
    }
}

/// Too few poses to hold any out: the kinematic stage alone, on everything.
pub(crate) fn kinematic_only(
    settings: &AutoSettings,
    nominal: &Robot,
    rows: &[&Measurement],
    observer: &dyn Observer,
    start: Instant,
) -> Result<Built> {
    observer.message("too few configurations to hold any out: kinematic identification only");
    let mut built = configured(&Stages::default(), nominal, rows, None, observer)?;
    built.selection = Some(Selection {
        held_out: "none: fewer than 4 configurations".into(),
        folds: 0,
        fitted_rows: rows.len(),
        held_out_rows: 0,
        candidates: Vec::new(),
        decisions: vec![Decision::said(
            Stage::Kinematic,
            true,
            None,
            None,
            "kept untested: too few configurations to hold any out".into(),
        )],
        refitted_on_every_row: false,
        budget_seconds: settings.budget_seconds,
        seconds: start.elapsed().as_secs_f64(),
        reproducible: settings.reproducible,
        counted_seconds: None,
    });
    Ok(built)
}
