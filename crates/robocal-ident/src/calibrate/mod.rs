//! Kinematic calibration end to end: registration, best-fit alignment ("before"),
//! identifiability, the chosen solver, statistics and parameter uncertainties.

mod frames;
mod joint_errors;
mod memo;
mod priors;
mod report;
mod settings;
mod warnings;

use std::borrow::Cow;

use crate::error::{IdentError, Result};
use crate::identifiability::{Column, analyse, deviations_of};
use crate::problem::{CalibrationProblem, Observations, select};
use nalgebra::Vector3;
use robocal_data::{ErrorStats, robust_std};
use robocal_robot::{Compliance, Flank, ParamId, ParameterCovariance, Robot};

pub use frames::{align, tracker_down};
use frames::{by_reflectors, down_of_aligned};
pub use joint_errors::default_compliance_joints;
use joint_errors::{
    choose_compliance, compliance_report, joint_error_reports, joint_error_start, solve_gated,
};
pub use memo::FitMemo;
pub use priors::prior_spread;
pub use report::{
    ComplianceReport, ErrorTermReport, Fixed, FixedParameter, JointCompliance,
    KinematicCalibration, KinematicReport, OrientationReport, ParameterReport,
};
pub use settings::{
    BACKLASH_BOUND_DEG, COMPLIANCE_BOUND, ComplianceSettings, FLANK_ROUNDS, HARMONIC_BOUND_DEG,
    HUBER_K, IRLS_ROUNDS, JointErrorSettings, KinematicSettings, Loss, MOUNTING_ANGLE_DEG,
    PAYLOAD_COM_BOUND, SEARCH_FLANK_ROUNDS, SolverKind, TILT_START_SHARE, TORQUE_SHARE,
};
use warnings::fit_warnings;
pub use warnings::{
    FAR_FROM_NOMINAL, FAR_SIGMAS, ILL_CONDITIONED, POOR_FIT, far_from_nominal, poorly_determined,
};

/// Identifies the kinematic parameters of `nominal` from `obs` (and, when the settings ask for
/// it, the joint compliances with them: then the points of every load take part).
///
/// Tilting compliances multiply the links' weights and the payload's centre of mass, which may
/// take either sign: LM can end in a minimum worse than the same model without them (measured
/// on the paper's twin beyond the model family: 0.216 against 0.075 mm on the fitted rows, the
/// tilts far from the twin's and some negative). With tilts asked for, the model without them
/// is fitted too, and the one that fits the rows better (RMS) is kept.
pub fn calibrate_kinematics(
    nominal: &Robot,
    obs: &Observations,
    settings: &KinematicSettings,
) -> Result<KinematicCalibration> {
    calibrate_kinematics_with(nominal, obs, settings, &FitMemo::default())
}

/// [`calibrate_kinematics`], remembering in `memo` every alignment and identification it makes
/// and taking any `memo` already holds: callers that identify several models of the same rows
/// (the default calibration's candidates on one fold) share their common fits — the first fit
/// of a model with the links' weights is the fit of the same model without them, and every
/// model starts from the same alignment. The results are those of [`calibrate_kinematics`],
/// bit for bit (each identification is a function of its table, rows and settings).
pub fn calibrate_kinematics_with(
    nominal: &Robot,
    obs: &Observations,
    settings: &KinematicSettings,
    memo: &FitMemo,
) -> Result<KinematicCalibration> {
    let Some(je) = settings.joint_errors.as_ref().filter(|je| je.tilt) else {
        return identify(nominal, obs, settings, memo);
    };
    let mut upright = settings.clone();
    upright.joint_errors = Some(JointErrorSettings {
        tilt: false,
        ..je.clone()
    });
    if upright
        .joint_errors
        .as_ref()
        .is_some_and(|je| je.harmonics == 0 && !je.self_weight && !je.link_weights && !je.backlash)
    {
        upright.joint_errors = None;
    }
    let without = identify(nominal, obs, &upright, memo)?;
    Ok(match identify(nominal, obs, settings, memo) {
        Ok(with) if with.report.after.rms <= without.report.after.rms => with,
        _ => without,
    })
}

/// [`identify_anew`], or the identification `memo` remembers for the same table, rows and
/// settings.
fn identify(
    nominal: &Robot,
    obs: &Observations,
    settings: &KinematicSettings,
    memo: &FitMemo,
) -> Result<KinematicCalibration> {
    if let Some(fit) = memo.fit(nominal, obs, settings) {
        return Ok(fit);
    }
    let fit = identify_anew(nominal, obs, settings, memo)?;
    memo.remember(nominal, obs, settings, &fit);
    Ok(fit)
}

/// [`calibrate_kinematics`] without its comparison of the tilts: the identification itself
/// (the identifications it starts from taken from `memo` where it holds them). The settings
/// that need identifications of their own go first: the mounting (gravity's direction), a first
/// fit for the links' weights, the backlash flanks' rounds; then the fit.
fn identify_anew(
    nominal: &Robot,
    obs: &Observations,
    settings: &KinematicSettings,
    memo: &FitMemo,
) -> Result<KinematicCalibration> {
    if obs.dof != nominal.dof() {
        return Err(IdentError::JointCountMismatch {
            expected: nominal.dof(),
            found: obs.dof,
        });
    }
    let (nominal, obs) = probed(nominal, obs, settings);
    let (nominal, obs) = (nominal.as_ref(), obs.as_ref());
    if let Some(c) = &settings.compliance
        && c.detect_mounting
    {
        return identify_mounting(nominal, obs, settings, c, memo);
    }
    // The links' weights and the payload's centre of mass act through the joints' compliances:
    // a first identification without them (nor backlash, whose flanks are chosen below with the
    // whole model) gives the compliances the one with them starts from (at zero compliance they
    // move nothing, and the identifiability analysis would hold them at zero).
    let link_weights = (settings.joint_errors.as_ref()).is_some_and(|je| je.link_weights);
    if link_weights && settings.compliance.is_none() {
        return Err(IdentError::Compliance(
            "link weights act through the joint compliances: identify the compliances too".into(),
        ));
    }
    if let Some(first) = settings.first_fit() {
        let fit = identify(nominal, obs, &first, memo)?;
        let Some(values) = fit.compliance.as_ref().map(|c| c.values.clone()) else {
            return Ok(fit);
        };
        let mut next = settings.clone();
        next.compliance.as_mut().expect("compliance").start = Some(values);
        return identify(nominal, obs, &next, memo);
    }
    if let Some(je) = &settings.joint_errors
        && je.backlash
        && je.backlash_torque
        && je.flanks.is_none()
    {
        return identify_flank_rounds(nominal, obs, settings, je, memo);
    }
    fit(nominal, obs, settings, memo)
}

/// The table and rows as a fit takes them: a 6-DoF probe's rows weigh as the settings say, and
/// its tool frame is identified (from the flange's when the table declares none).
fn probed<'a>(
    nominal: &'a Robot,
    obs: &'a Observations,
    settings: &KinematicSettings,
) -> (Cow<'a, Robot>, Cow<'a, Observations>) {
    if obs.oriented().is_empty() && settings.target_weights.is_empty() {
        return (Cow::Borrowed(nominal), Cow::Borrowed(obs));
    }
    let mut weighted = obs.clone();
    weighted.weigh_targets(&settings.target_weights);
    if obs.oriented().is_empty() {
        return (Cow::Borrowed(nominal), Cow::Owned(weighted));
    }
    weighted.angle_weight = settings.angle_weight_per_rad();
    let nominal = if nominal.tool_rpy.is_some() {
        Cow::Borrowed(nominal)
    } else {
        Cow::Owned(Robot {
            tool_rpy: Some(Vector3::zeros()),
            ..nominal.clone()
        })
    };
    (nominal, Cow::Owned(weighted))
}

/// An arm hung on a wall or a ceiling: gravity is not along its base's −z. With a levelled
/// tracker it is along the tracker's; the data tell which of the two fits (`c`: the
/// compliances' settings, which ask for the choice).
fn identify_mounting(
    nominal: &Robot,
    obs: &Observations,
    settings: &KinematicSettings,
    c: &ComplianceSettings,
    memo: &FitMemo,
) -> Result<KinematicCalibration> {
    let mut given = settings.clone();
    let gc = given.compliance.as_mut().expect("compliance");
    gc.detect_mounting = false;
    // Gravity along the tracker's −z in the base frame of `robot`.
    let down_of = |robot: &Robot| {
        robot.base_rotation().transpose() * Vector3::new(0.0, 0.0, -c.gravity.norm())
    };
    // The settings with gravity `g` for the compliances and the joint errors alike.
    let with_gravity = |mut s: KinematicSettings, g: Vector3<f64>| {
        s.compliance.as_mut().expect("compliance").gravity = g;
        if let Some(je) = s.joint_errors.as_mut() {
            je.gravity = g;
        }
        s
    };
    // The alignment every identification below starts from, made once.
    let (down, angle) = down_of_aligned(&memo.align(nominal, obs)?, &c.gravity);
    if angle <= MOUNTING_ANGLE_DEG {
        return identify(nominal, obs, &given, memo);
    }
    let upright = identify(nominal, obs, &given, memo);
    // The registration's base is a first guess of the base's rotation: once more with the
    // identified one.
    let tracker =
        identify(nominal, obs, &with_gravity(given.clone(), down), memo).and_then(|fit| {
            let levelled = with_gravity(given.clone(), down_of(&fit.robot));
            identify(nominal, obs, &levelled, memo)
        });
    match (upright, tracker) {
        (Ok(u), Ok(mut t)) if t.report.after.rms < u.report.after.rms => {
            let g = t.compliance.as_ref().map_or(down, |c| c.gravity);
            let warning = format!(
                "gravity taken along the tracker's -z, [{:.3}, {:.3}, {:.3}] m/s² in the robot base frame: the registered base is {angle:.0}° from upright (an arm on a wall or a ceiling), and the fit with gravity along the base's -z was worse (RMS {:.4} against {:.4} mm); give gravity in a stage config's [compliance] if neither is right",
                g.x, g.y, g.z, u.report.after.rms, t.report.after.rms
            );
            t.report.warnings.push(warning.clone());
            t.report.mounting_warning = Some(warning);
            Ok(t)
        }
        (Ok(u), _) => Ok(u),
        (Err(_), Ok(t)) => Ok(t),
        (Err(e), Err(_)) => Err(e),
    }
}

/// Backlash that may rest on the flank its torque presses (`je`: the joint errors' settings): a
/// first identification on the flanks of the approach from home, each joint's flank chosen from
/// what it leaves, then the identification on those flanks; the choice made again from that fit
/// (a flank chosen from a fit that lacked it is blurred where the first fit absorbed the step),
/// until the rows' flanks stay as they were or FLANK_ROUNDS (SEARCH_FLANK_ROUNDS with the
/// search) choices have been made.
fn identify_flank_rounds(
    nominal: &Robot,
    obs: &Observations,
    settings: &KinematicSettings,
    je: &JointErrorSettings,
    memo: &FitMemo,
) -> Result<KinematicCalibration> {
    let mut round = settings.clone();
    let start = round.joint_errors.as_mut().expect("joint errors");
    start.backlash_torque = false;
    let home = (start.backlash_home.clone()).unwrap_or_else(|| vec![0.0; nominal.dof()]);
    // With axis runouts, the rounds start from the flanks chosen on the model without them
    // (that model's own rounds had the fit on the approach flanks competing): a runout can
    // take part of a step on a fit that lacks it, and the choice made from what that fit
    // leaves goes wrong (the paper's arm beyond the model); the rounds then choose again
    // with the runouts in the model, and the lowest sum of squares of their fits is kept.
    // No fit on the approach flanks with the runouts: it would be the dearest identification
    // of the candidate (a third to two fifths of its time on the paper's arm, hundreds of
    // iterations from zero), and its sum of squares was never the lowest on the cases
    // traced.
    let chosen_flanks = if je.runout > 0 {
        let mut plain = settings.clone();
        let je_plain = plain.joint_errors.as_mut().expect("joint errors");
        je_plain.runout = 0;
        je_plain.runout_from_without = false;
        let chosen = identify(nominal, obs, &plain, memo)?;
        chosen.compliance.as_ref().map(|errors| {
            let mut flanks: Vec<Flank> = (home.iter())
                .map(|&h| Flank::Approach { home: h })
                .collect();
            for b in &errors.backlash {
                flanks[b.joint] = b.flank.clone();
            }
            flanks
        })
    } else {
        None
    };
    if let Some(flanks) = chosen_flanks {
        round.joint_errors.as_mut().expect("joint errors").flanks = Some(flanks);
    }
    let mut fit = identify(nominal, obs, &round, memo)?;
    // Without runouts, the fit on the approach flanks competes too: flanks chosen from a fit
    // that lacked them can leave more than it did (a joint's flank chosen nearly constant,
    // its step then absorbed by its offset and bent into its harmonics).
    let mut best = fit.clone();
    // The identification on `flanks`, kept as the best when its sum of squares (the
    // identification's own objective) is the lowest yet (of equal ones, the later).
    let mut on_flanks = |flanks: Vec<Flank>, best: &mut KinematicCalibration| {
        round.joint_errors.as_mut().expect("joint errors").flanks = Some(flanks);
        let next = identify(nominal, obs, &round, memo)?;
        if next.report.after.rms <= best.report.after.rms {
            *best = next.clone();
        }
        Ok::<_, IdentError>(next)
    };
    let mut signs: Option<Vec<f64>> = None;
    let rounds = if je.flank_search {
        SEARCH_FLANK_ROUNDS
    } else {
        FLANK_ROUNDS
    };
    for _ in 0..rounds {
        let Some(errors) = fit.compliance.as_ref() else {
            break;
        };
        let flanks = crate::flank::choose_flanks(&fit.robot, errors, obs, &home, je.flank_search);
        if signs.is_none() && flanks.iter().all(|f| matches!(f, Flank::Approach { .. })) {
            break;
        }
        fit = on_flanks(flanks, &mut best)?;
        let now = (fit.compliance.as_ref()).map(|e| crate::flank::flank_signs(&fit.robot, e, obs));
        let settled = now.is_some() && now == signs;
        signs = now;
        if settled {
            break;
        }
    }
    Ok(best)
}

/// The identification of the settings' model itself, from the registration's alignment.
fn fit(
    nominal: &Robot,
    obs: &Observations,
    settings: &KinematicSettings,
    memo: &FitMemo,
) -> Result<KinematicCalibration> {
    let selected = select(nominal, settings.parameters.as_deref())?;
    if 3 * obs.len() < selected.len().min(9) || obs.len() < 3 {
        return Err(IdentError::TooFewMeasurements {
            points: obs.len(),
            equations: 3 * obs.len(),
            parameters: selected.len(),
        });
    }
    let aligned = memo.align(nominal, obs)?;
    let before = ErrorStats::from_errors(&obs.errors(&aligned));
    let choice = settings
        .compliance
        .as_ref()
        .map(|c| choose_compliance(c, &aligned, obs))
        .transpose()?;

    // Identifiability at the aligned model (the neighbourhood of the solution).
    let ids = aligned.param_ids();
    let mut problem = CalibrationProblem::new(&aligned, selected.clone(), obs);
    let mut columns: Vec<Column> = selected.iter().map(|&i| ids[i].into()).collect();
    let (start, params) = joint_error_start(settings, &aligned, choice.as_ref(), obs)?;
    if let Some(model) = &start {
        columns.extend(params.iter().map(|&p| Column::of_error(model, p)));
        problem = problem.with_joint_errors(model.clone(), params.clone());
    }
    let jac = problem.first_order_jacobian(&vec![0.0; problem.unknowns()]);
    let ident = analyse(&jac, &columns, settings.rank_tolerance);
    let identified_by_reflectors = by_reflectors(obs, &jac, &columns, &ident, settings);
    let mut problem = problem.restricted(&ident.identifiable);
    let mut kept: Vec<Column> = ident.identifiable.iter().map(|&p| columns[p]).collect();
    let mut fixed: Vec<FixedParameter> = ident
        .unidentifiable
        .iter()
        .map(|&(p, fraction)| FixedParameter {
            name: columns[p].to_string(),
            independent_fraction: fraction,
            why: Fixed::Unidentifiable,
            reason: if fraction == 0.0 {
                "no effect on the measured points with these poses".into()
            } else {
                "redundant with the identified parameters for these poses".into()
            },
        })
        .collect();

    let (u, iterations, termination) = solve_robust(&mut problem, &mut kept, &mut fixed, settings)?;
    let robot = problem.robot_at(&u);
    let compliance = problem.compliance_at(&u);
    let finite = robot.params().iter().all(|v| v.is_finite())
        && compliance
            .as_ref()
            .is_none_or(|c| c.params().iter().all(|&p| c.param(p).is_finite()));
    if !finite {
        return Err(IdentError::Solver {
            solver: settings.solver.name(),
            message: "the identification diverged to non-finite values (check the data's units and the robot table)".into(),
        });
    }
    let after = ErrorStats::from_errors(&obs.errors_with(&robot, compliance.as_ref()));
    let degrees = |errors: Vec<f64>| {
        ErrorStats::from_errors(&errors.iter().map(|e| e.to_degrees()).collect::<Vec<_>>())
    };
    let orientation = (!obs.oriented().is_empty()).then(|| OrientationReport {
        rows: obs.oriented().len(),
        angle_weight: obs.angle_weight.to_radians(),
        before: degrees(obs.orientation_errors_with(&aligned, None)),
        after: degrees(obs.orientation_errors_with(&robot, compliance.as_ref())),
    });
    let mut warnings = fit_warnings(obs, selected.len(), ident.condition_number, after.mean);
    warnings.extend(negative_tilts(compliance.as_ref()));
    // Under the harmonics' prior, the posterior's: a coefficient the poses barely determine is
    // as sure as the prior makes it, not as unsure as the data alone leave it.
    let cov_u = problem.covariance(&u);
    let std_u = cov_u.as_ref().and_then(deviations_of);
    // The same covariance in internal units, by the parameters' names: what a predicted
    // point's standard deviation is made of.
    let covariance = std_u.as_ref().and(cov_u.as_ref()).map(|c| {
        let scale = problem.scale();
        let names = kept.iter().map(Column::to_string).collect();
        let m = nalgebra::DMatrix::from_fn(c.nrows(), c.ncols(), |i, j| {
            c[(i, j)] * scale[i] * scale[j]
        });
        ParameterCovariance::new(names, &m)
    });
    // What is written must read back: a fit so ill-conditioned that round-off leaves a negative
    // variance keeps no covariance (and its points no deviation).
    let covariance = covariance.filter(|c| c.check().is_ok());
    // Standard deviation of the unknown for `column`, internal units.
    let std_of = |column: Column| {
        let p = kept.iter().position(|&k| k == column)?;
        std_u.as_ref().map(|s| (s[p] * problem.scale()[p]).abs())
    };

    let parameters = parameter_reports(&ids, nominal, &robot, &kept, &std_of);
    warnings.extend(length_warnings(&parameters, &ids));
    let compliance_report = compliance_report(
        choice.as_ref(),
        compliance.as_ref(),
        obs,
        &kept,
        &fixed,
        &std_of,
    );
    let spread = problem.prior_spread();
    let joint_errors = match &compliance {
        Some(model)
            if settings.joint_errors.is_some()
                || (settings.compliance.as_ref()).is_some_and(|c| c.identify_payload_com) =>
        {
            joint_error_reports(model, &params, &kept, &std_of)
        }
        _ => Vec::new(),
    };
    Ok(KinematicCalibration {
        robot,
        compliance,
        aligned,
        covariance,
        report: KinematicReport {
            solver: settings.solver.name(),
            cost: match settings.solver {
                SolverKind::Lm => "sum of squared errors",
                SolverKind::Bfgs => "mean Euclidean distance (paper eq. 15)",
            },
            iterations,
            termination,
            points: obs.len(),
            before,
            after,
            orientation,
            parameters,
            fixed,
            identified_by_reflectors,
            condition_number: ident.condition_number,
            observability_index: ident.observability_index,
            compliance: compliance_report,
            joint_errors,
            harmonic_prior_deg: spread.harmonics.map(f64::to_degrees),
            runout_prior_deg: spread.runouts.map(f64::to_degrees),
            warnings,
            mounting_warning: None,
        },
    })
}

/// Solves `problem` ([`solve_gated`]); under the Huber loss, again with the rows reweighted by
/// what each leaves, until the weights settle or [`IRLS_ROUNDS`] rounds have run. Returns the
/// solution, every solve's iterations and why the last stopped.
fn solve_robust(
    problem: &mut CalibrationProblem<'_>,
    kept: &mut Vec<Column>,
    fixed: &mut Vec<FixedParameter>,
    settings: &KinematicSettings,
) -> Result<(Vec<f64>, u64, String)> {
    let (mut u, mut iterations, mut termination) = solve_gated(problem, kept, fixed, settings)?;
    if settings.loss == Loss::Huber {
        let mut previous: Option<Vec<f64>> = None;
        for _ in 0..IRLS_ROUNDS {
            let errors = problem.point_errors(&u);
            let components: Vec<f64> = errors.iter().flat_map(|e| [e.x, e.y, e.z]).collect();
            let corner = HUBER_K * robust_std(&components);
            if corner <= 0.0 {
                break;
            }
            let weights: Vec<f64> = (errors.iter())
                .map(|e| (corner / e.norm()).min(1.0))
                .collect();
            if previous
                .as_ref()
                .is_some_and(|p| p.iter().zip(&weights).all(|(a, b)| (a - b).abs() < 1e-3))
            {
                break;
            }
            problem.set_point_weights(&weights);
            let solved = solve_gated(problem, kept, fixed, settings)?;
            (u, iterations, termination) = (solved.0, iterations + solved.1, solved.2);
            previous = Some(weights);
        }
    }
    Ok((u, iterations, termination))
}

/// The warning for tilting compliances below zero, if any.
fn negative_tilts(compliance: Option<&Compliance>) -> Option<String> {
    // A negative tilting compliance is no bearing's: the tilts traded with the links' weights
    // (whose sign is free) or took an effect the model lacks.
    let negative: Vec<String> = (compliance.into_iter())
        .flat_map(|c| c.tilts.iter())
        .filter(|t| t.value < 0.0)
        .map(|t| format!("j{}", t.joint + 1))
        .collect();
    (!negative.is_empty()).then(|| {
        format!(
            "tilting compliance NEGATIVE on {}: no bearing stiffens under a moment; the tilts traded with the links' weights or took an effect the model does not hold; consider leaving tilt out",
            negative.join(", ")
        )
    })
}

/// The warnings for link lengths far from the nominal table, and for those the poses barely
/// determine.
fn length_warnings(parameters: &[ParameterReport], ids: &[ParamId]) -> Vec<String> {
    let mut warnings = Vec::new();
    let far: Vec<String> = far_from_nominal(parameters, ids)
        .iter()
        .map(|p| format!("{} {:.3} → {:.3} mm", p.name, p.nominal, p.identified))
        .collect();
    if !far.is_empty() {
        warnings.push(format!(
            "identified link lengths far from the nominal table (more than {FAR_FROM_NOMINAL} mm and 10 %): {}; check the units of the data (mm) and that the robot file describes this arm",
            far.join(", ")
        ));
    }
    let poor: Vec<String> = poorly_determined(parameters, ids)
        .iter()
        .map(|p| {
            format!(
                "{} {:.1} → {:.1} ± {:.1} mm",
                p.name,
                p.nominal,
                p.identified,
                p.std.unwrap_or(f64::NAN)
            )
        })
        .collect();
    if !poor.is_empty() {
        warnings.push(format!(
            "link lengths the poses barely determine (moved far, within {FAR_SIGMAS} standard deviations): {}; measure more configurations, or plan them (`robocal plan`), before trusting the model",
            poor.join(", ")
        ));
    }
    warnings
}

/// Every parameter of the table, nominal and identified in its file unit, with its standard
/// deviation (`std_of`, internal units) where it was identified (among `kept`); `ids` the
/// table's parameters.
fn parameter_reports(
    ids: &[ParamId],
    nominal: &Robot,
    robot: &Robot,
    kept: &[Column],
    std_of: &impl Fn(Column) -> Option<f64>,
) -> Vec<ParameterReport> {
    let nominal_values = nominal.params();
    let identified_values = robot.params();
    ids.iter()
        .enumerate()
        .map(|(i, id)| {
            let flag = kept.contains(&Column::Param(*id));
            let nominal = id.to_file_units(nominal_values[i]);
            let identified = id.to_file_units(identified_values[i]);
            ParameterReport {
                name: id.to_string(),
                unit: id.file_unit_name(),
                nominal,
                identified,
                delta: identified - nominal,
                std: std_of(Column::Param(*id)).map(|s| id.to_file_units(s).abs()),
                identified_flag: flag,
            }
        })
        .collect()
}
