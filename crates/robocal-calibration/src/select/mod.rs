//! The default calibration: candidates scored on held-out poses, a chain of decisions, the
//! chosen model fitted again on every row.

mod chain;
mod decisions;
mod gravity;
mod physics;
mod plan;
mod residual;
mod status;

use crate::budget::{self, Allowance, Meter};
use crate::configured::{Built, configured};
use crate::error::Result;
use crate::outliers::{OutlierReport, OutlierSettings, find_outliers};
use crate::rows::configurations;
use crate::stages::Stages;
use nalgebra::Vector3;
use robocal_data::{ErrorStats, Measurement, Observer, Silent};
use robocal_ident::{ComplianceSettings, Fixed, KinematicSettings};
use robocal_residual::{Frame, ResidualKind, ResidualSettings, ResidualStage};
use robocal_robot::Robot;
use serde::Serialize;
use std::time::Instant;

use chain::{Chain, Scorer, physics_chain};
pub use decisions::REACH_GAIN;
use decisions::{decisions, harmonic_reach};
use gravity::mounting;
pub use gravity::{JOINT1_GRAVITY_ANGLE_DEG, joint1_gravity_angle, residual_stages};
use physics::{FINAL_FIT_SHARE, Physics};
use plan::FoldPlan;
use residual::{
    ResidualScore, TABLE_FRAMES, Trainer, pick_residual, residual_candidates, residual_share,
};
use status::budget_warning;
pub use status::{Stage, Status};

/// What the default calibration decided about one stage.
#[derive(Debug, Clone, Serialize)]
pub struct Decision {
    /// The stage: `kinematic`, `compliance`, `joint_errors`, `flank_search`, `runout`, `tilt`,
    /// `residual` or `harmonic_reach` in the report.
    pub stage: Stage,
    /// Whether the stage is in the model.
    pub kept: bool,
    /// Held-out score (see [`Candidate::score`]) of the model the stage was added to, mm
    /// (absent when the stage was not tried).
    pub held_out_without: Option<f64>,
    /// Held-out score of that model with the stage, mm.
    pub held_out_with: Option<f64>,
    /// Why.
    pub reason: String,
    /// The reason's words after its verdict (`kept`, `dropped`): what the decision says again
    /// when the verdict changes.
    #[serde(skip)]
    after_verdict: String,
}

/// One candidate model of the default calibration and its held-out error.
#[derive(Debug, Clone, Serialize)]
pub struct Candidate {
    /// What it stacks, e.g. `kinematic + compliance + gp`.
    pub name: String,
    /// Statistics of every held-out row's error over the random folds (each row held out
    /// once), or on the validation file, mm; absent when the candidate was skipped.
    pub held_out: Option<ErrorStats>,
    /// The same over the blocks of joint 1's range (each row held out once), mm.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub held_out_blocks: Option<ErrorStats>,
    /// What the choice compares, mm: the mean of the two means (the random folds' mean alone
    /// with a validation file).
    pub score: Option<f64>,
    /// Seconds its folds took.
    pub seconds: f64,
    /// What its folds spent of the budget, by the budget's measure: `seconds` by the clock, the
    /// reference machine's seconds for its counted work with `reproducible` ([`budget`]).
    #[serde(skip)]
    pub(crate) cost: f64,
    /// Chosen, evaluated, or why it was skipped (in the report: `chosen`, `evaluated`, or the
    /// reason in words).
    pub status: Status,
    /// The physics of a physical candidate (none for a residual model).
    #[serde(skip)]
    pub(crate) physics: Option<Physics>,
}

/// How the default calibration chose its stages.
#[derive(Debug, Clone, Serialize)]
pub struct Selection {
    /// Where the held-out poses came from.
    pub held_out: String,
    /// Folds: the random ones and the blocks of joint 1 (1 with a validation file).
    pub folds: usize,
    /// Rows the candidates were fitted on, summed over the folds.
    pub fitted_rows: usize,
    /// Rows held out, summed over the folds (every row twice in cross-validation: once in a
    /// random fold, once in a block).
    pub held_out_rows: usize,
    /// Every candidate, in the order tried.
    pub candidates: Vec<Candidate>,
    /// One per stage, in order.
    pub decisions: Vec<Decision>,
    /// Whether the chosen candidate was fitted again on every row of the data file (always,
    /// unless a validation file was given or there were too few configurations to hold any
    /// out).
    pub refitted_on_every_row: bool,
    /// The time budget, s, and what the selection took.
    pub budget_seconds: f64,
    /// See `budget_seconds`.
    pub seconds: f64,
    /// Whether the budget was kept by counted work ([`AutoSettings::reproducible`]).
    pub reproducible: bool,
    /// With `reproducible`, the reference machine's seconds the selection's counted work came to
    /// (what the budget was kept by).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub counted_seconds: Option<f64>,
}

impl Selection {
    /// The candidate the selection chose, if it chose one.
    pub fn chosen(&self) -> Option<&Candidate> {
        self.candidates.iter().find(|c| c.status == Status::Chosen)
    }

    /// The warning that the time budget ended the search before some candidates were scored
    /// (the one the report's warnings hold), if it did.
    pub fn budget_warning(&self) -> Option<String> {
        budget_warning(&self.candidates, self.budget_seconds)
    }
}

/// Settings of the default calibration.
#[derive(Debug, Clone, PartialEq)]
pub struct AutoSettings {
    /// Folds of the cross-validation over configurations (when no validation file is given).
    pub folds: usize,
    /// Seed of the folds (and of the residual models).
    pub seed: u64,
    /// Fewest configurations (in the data, or in each fold's training part) for which a
    /// residual model is tried (default 10: above it the paired test decides).
    pub min_residual_configurations: usize,
    /// Transmission harmonics up to this order tried with the geometry (0: not tried).
    pub harmonics: u32,
    /// Self-weight terms tried with the geometry.
    pub self_weight: bool,
    /// Backlash tried with the geometry (each joint on the flank of its approach from home or on
    /// the one its torque presses).
    pub backlash: bool,
    /// Tilting compliances tried last, on the chosen physics when it holds the compliances: the
    /// parts beyond each joint turning across its axis under the gravity moment of the payload
    /// and of the links' weights (when identified). Off by default: on the development twins
    /// the candidate was never kept, and on the paper's arm its folds took the time the GP
    /// needed; and one case beyond the model came out 12 % higher (ARM6H, joint-1
    /// extrapolation).
    pub tilt: bool,
    /// Axis runouts of orders 1 up to this one (every joint, about both axes across it; 0: not
    /// tried), tried on the physics the joint-error blocks reached, before the flank search and
    /// the tilts: the parts beyond each joint turning across its axis periodically in its angle.
    /// Default 2: orders 1 and 2, under the prior of their own spread, on
    /// the 72 development cases lowered the 18 the folds kept them on by 2–69 % (the rest
    /// identical); with the effects beyond the model four times as large, 15 of 16 lower by
    /// 13–58 %, one higher: ARM5W seed 0's joint-1 extrapolation, +9 %, where the harmonic
    /// reach then continued joint 1's harmonics. Order 1 alone: that case +32 %. 0 switches
    /// them off.
    pub runout: u32,
    /// Backlash with its flanks searched also tried where the physics the chain chose holds no
    /// backlash (the block with the regression's flanks was not kept): for a joint whose play
    /// rests on the flank its torque presses and turns far from the rows' middle torque (at a
    /// configuration's lightest or heaviest loads only), where the regression's flanks miss and
    /// the block gains nothing. Off by default: on the development twins it lowered ARM6H's
    /// error with every effect by 16–68 % and raised one case beyond the model by 7 %
    /// (`just accuracy`). With backlash chosen the search is tried either way.
    pub flank_search: bool,
    /// The residual models tried, each on top of the best physical model. By default a GP and
    /// robocal's networks, both in the frame turning with joint 1 (`Frame::Joint1`: against the
    /// world frame, on the 48 development cases 15 lower, by up to 21 %, one higher by 4 %, the
    /// rest identical).
    pub residuals: Vec<ResidualStage>,
    /// Where joint 1's axis lies more than [`JOINT1_GRAVITY_ANGLE_DEG`] from the line of gravity
    /// (an arm on a wall or an inclined pedestal), each residual model of `residuals` in the
    /// frame turning with joint 1 is also tried in the world frame, and the folds choose: the
    /// turned frame's gain rests on joint 1 standing along gravity (on by default; off when the
    /// user names the frame).
    pub both_frames_off_gravity: bool,
    /// Seconds the selection may take: a candidate whose folds would run past it (projected
    /// from its first fold) is abandoned, and none starts after it. The only setting that
    /// depends on the clock: far under budget, a seed gives the same model.
    pub budget_seconds: f64,
    /// The budget kept by counted work instead of the clock ([`budget`]): every decision of the
    /// budget reads what the fits and trainings counted, in the seconds a reference machine of
    /// [`REFERENCE_CORES`] cores takes for it, so a seed gives the same model on every machine
    /// as fast as the reference or faster (the clock stays a guard: never past the budget).
    /// Off by default.
    ///
    /// [`REFERENCE_CORES`]: crate::budget::REFERENCE_CORES
    pub reproducible: bool,
    /// The search for bad shots before everything else (none: every row is used).
    pub outliers: Option<OutlierSettings>,
    /// Weight of a 6-DoF probe's orientation residuals, mm per deg (`None`: the kinematic
    /// settings' default, `noise_mm / noise_deg`).
    pub angle_weight: Option<f64>,
    /// Gravity in the robot base frame {0}, m/s², for every candidate (`None`: decided once
    /// from the data before the candidates — the base's −z, or for an arm on a wall or a
    /// ceiling a levelled tracker's −z where a fit with the compliances says it fits better).
    pub gravity: Option<Vector3<f64>>,
}

/// Folds of the default cross-validation.
pub const DEFAULT_FOLDS: usize = 5;

/// The default selection's time budget, s.
pub const DEFAULT_BUDGET_SECONDS: f64 = 120.0;

impl Default for AutoSettings {
    fn default() -> Self {
        let seed = robocal_residual::DEFAULT_SEED;
        Self {
            folds: DEFAULT_FOLDS,
            seed,
            min_residual_configurations: 10,
            harmonics: 2,
            self_weight: true,
            backlash: true,
            tilt: false,
            runout: 2,
            flank_search: false,
            residuals: vec![
                ResidualStage {
                    settings: ResidualSettings {
                        frame: Frame::Joint1,
                        ..ResidualSettings::gp(seed)
                    },
                    holdout: 0.2,
                },
                ResidualStage {
                    settings: ResidualSettings {
                        frame: Frame::Joint1,
                        ..ResidualSettings::robocal(ResidualKind::Somm, seed)
                    },
                    holdout: 0.2,
                },
            ],
            both_frames_off_gravity: true,
            budget_seconds: DEFAULT_BUDGET_SECONDS,
            reproducible: false,
            outliers: Some(OutlierSettings::default()),
            angle_weight: None,
            gravity: None,
        }
    }
}

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
    let meter = Meter::new(settings.budget_seconds, settings.reproducible);
    automatic_metered(settings, nominal, rows, validation, observer, &meter)
}

/// [`automatic`] with its budget kept by `meter`.
fn automatic_metered(
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
struct Prepared<'a> {
    outliers: Option<OutlierReport>,
    rows: Vec<&'a Measurement>,
    settings: AutoSettings,
    mounting_warning: Option<String>,
    work: robocal_ident::Work,
}

/// The bad shots' search, then gravity decided once for an arm on a wall or a ceiling (for
/// every candidate and fold: each fit deciding it again would identify every candidate three
/// times), and the residual models in both frames where joint 1 lies off gravity.
fn prepare<'a>(
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
struct Choice {
    residual_wins: Option<(usize, f64)>,
    chosen_physics: Physics,
    decisions: Vec<Decision>,
    reach: Option<Decision>,
}

/// The winner: a residual model significantly better than the physical model, else the
/// physical model the chain ended on; marked chosen among `candidates`, with the decisions
/// (said to `observer`).
fn choose(
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
fn final_fit(
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
fn note_implausible(decisions: &mut [Decision], built: &Built, observer: &dyn Observer) {
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
fn kinematic_only(
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

#[cfg(test)]
mod tests;
