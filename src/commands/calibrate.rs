//! `robocal calibrate`: identify a model from measurements and write the model directory.
//!
//! With `--config`, the stages the file asks for; without, the default calibration, which
//! chooses its stages from the data by their error on held-out poses (see
//! `robocal_calibration`).

use std::path::Path;

use anyhow::Result;
use robocal_calibration::Stages;
use robocal_calibration::{
    Calibration, CalibrationInput, CalibrationReport, Checks, Selection, calibrate,
};
use robocal_data::{Measurement, MeasurementSet};
use robocal_report::{DataRole, write_data_report};
use robocal_robot::Robot;

use super::terminal::Terminal;

/// Runs the calibration and writes `out` atomically (and the pictures of the fit into
/// `pictures` when given); `angle_weight` (mm per deg) weighs a 6-DoF probe's orientations;
/// `budget` (s) bounds the default calibration's time (by counted work where `reproducible`);
/// `tilt` has it try the bearings' tilt,
/// `flank_search` backlash with its flanks searched where the physics it chose holds none;
/// `runout` the highest order of the axis runouts it tries (0: none; `None`: its default);
/// `residual_frame` (`world` or `joint1`) is the frame its residual models learn in.
#[allow(clippy::too_many_arguments)]
pub fn run(
    robot: &Path,
    data: &Path,
    validate: Option<&Path>,
    out: &Path,
    config: Option<&Path>,
    checks: Checks,
    pictures: Option<&Path>,
    angle_weight: Option<f64>,
    budget: Option<f64>,
    reproducible: bool,
    tilt: bool,
    flank_search: bool,
    runout: Option<u32>,
    residual_frame: Option<&str>,
) -> Result<()> {
    let started = std::time::Instant::now();
    let residual_frame = residual_frame
        .map(|f| {
            robocal_residual::Frame::parse(f).map_err(|e| anyhow::anyhow!("--residual-frame: {e}"))
        })
        .transpose()?;
    if let Some(w) = angle_weight
        && !(w.is_finite() && w > 0.0)
    {
        anyhow::bail!("--angle-weight: {w} is not a positive number of mm per degree");
    }
    let stages = config.map(Stages::load).transpose()?;
    let nominal = Robot::load(robot)?;
    let set = MeasurementSet::read(data, nominal.dof())?;
    let validation = validate
        .map(|v| MeasurementSet::read(v, nominal.dof()))
        .transpose()?;
    let input = CalibrationInput {
        nominal: &nominal,
        robot_file: robot,
        data: &set,
        validation: validation.as_ref(),
        stages: stages.as_ref().zip(config),
        checks,
        angle_weight,
        budget_seconds: budget,
        reproducible,
        tilt,
        flank_search,
        runout,
        residual_frame,
    };
    let Calibration {
        model,
        report,
        built,
        implausible,
    } = calibrate(&input, &Terminal::default())?;
    if let Some(why) = implausible {
        eprintln!("robocal: warning: {why} (written anyway: --force)");
    }
    if let Some(o) = &built.outliers {
        for row in &o.rows {
            eprintln!(
                "robocal: bad shot: {} line {} (pose {}, load {} kg): {:.3} mm from the model, {:.0} robust standard deviations ({:.4} mm){}; {}",
                data.display(),
                row.line,
                row.pose,
                row.load,
                row.error,
                row.sigmas,
                o.robust_std,
                (row.refined_sigmas.zip(o.refined_std))
                    .map(|(n, std)| format!(
                        ", {n:.0} ({std:.4} mm) under the physics with the transmission harmonics"
                    ))
                    .unwrap_or_default(),
                if o.left_out {
                    "left out of the fit (--keep-outliers keeps it)"
                } else {
                    "kept in the fit (--keep-outliers)"
                }
            );
        }
        if let (Some(held), false) = (o.held_out_std, o.suspects.is_empty()) {
            let named: Vec<String> = (o.suspects.iter().take(10))
                .map(|r| {
                    format!(
                        "line {} (pose {}, load {} kg) {:.3} mm",
                        r.line, r.pose, r.load, r.error
                    )
                })
                .collect();
            eprintln!(
                "robocal: warning: {}: too few configurations for the parameters to tell a bad shot from the model's own error (a fit without a configuration misses its rows by {:.3} mm, robust standard deviation): {} row(s) the fit of every row leaves beyond {:.0} robust standard deviations ({:.4} mm) were kept; check them: {}{}",
                data.display(),
                held,
                o.suspects.len(),
                o.threshold,
                o.robust_std,
                named.join(", "),
                if o.suspects.len() > named.len() {
                    ", …"
                } else {
                    ""
                }
            );
        }
    }
    let r = &built.kinematic.report;
    // What the identified physical model holds, so that its error is read as that model's.
    let mut holds = vec!["table"];
    if r.compliance.is_some() {
        holds.push("joint compliance");
    }
    if r.joint_errors.iter().any(|t| t.identified) {
        holds.push("joint errors");
    }
    eprintln!(
        "robocal: identified physics ({}, by {}): {} points, mean error {:.4} → {:.4} mm (max {:.4} → {:.4}), {} iterations",
        holds.join(" + "),
        r.solver,
        r.points,
        r.before.mean,
        r.after.mean,
        r.before.max,
        r.after.max,
        r.iterations
    );
    if let Some(o) = &r.orientation {
        eprintln!(
            "robocal: orientation (a 6-DoF probe's {} rows, {:.3} mm per deg): mean angle {:.4} → {:.4} deg (max {:.4} → {:.4})",
            o.rows, o.angle_weight, o.before.mean, o.after.mean, o.before.max, o.after.max
        );
    }
    for w in &r.warnings {
        eprintln!("robocal: warning: {w}");
    }
    if let Some(c) = &r.compliance {
        for j in c.joints.iter().filter(|j| j.identified) {
            eprintln!(
                "robocal: joint {} compliance {:.4} deg/kN·m{}{}",
                j.joint,
                j.compliance,
                plus_minus(j.std, 4),
                if j.compliance < 0.0 {
                    " (warning: negative; see report.json)"
                } else {
                    ""
                }
            );
        }
        if c.payload_com_source.starts_with("identified") {
            // Each coordinate with its σ where the report has one.
            let coordinates: Vec<String> = (0..3)
                .map(|axis| {
                    let name = robocal_robot::payload_com_name(axis);
                    let std = term_std(&r.joint_errors, &name);
                    // The coordinate's letter, as its name in the report ends.
                    let letter = name.rsplit('.').next().unwrap_or_default();
                    format!("{letter} {:.1}{}", c.payload_com[axis], plus_minus(std, 1))
                })
                .collect();
            eprintln!(
                "robocal: payload centre of mass {} mm (flange frame; {})",
                coordinates.join(", "),
                c.payload_com_source
            );
        }
    }
    if let Some(errors) = &built.kinematic.compliance {
        for line in harmonic_lines(errors)
            .into_iter()
            .chain(backlash_lines(errors, &r.joint_errors))
            .chain(link_weight_lines(errors))
            .chain(tilt_lines(errors, &r.joint_errors))
            .chain(runout_lines(errors))
        {
            eprintln!("robocal: {line}");
        }
    }
    if let Some(spread) = r.harmonic_prior_deg {
        eprintln!(
            "robocal: transmission harmonics under a prior of spread {spread:.4}° (chosen by marginal likelihood: a harmonic the poses barely determine is drawn toward it)"
        );
    }
    if let Some(spread) = r.runout_prior_deg {
        eprintln!(
            "robocal: axis runouts under a prior of spread {spread:.4}° (chosen by marginal likelihood, as the harmonics')"
        );
    }
    if !r.identified_by_reflectors.is_empty() {
        eprintln!(
            "robocal: identified thanks to the extra reflectors (the default one alone would hold them fixed): {}",
            r.identified_by_reflectors.join(", ")
        );
    }
    if !r.fixed.is_empty() {
        let names: Vec<&str> = r.fixed.iter().map(|f| f.name.as_str()).collect();
        eprintln!(
            "robocal: not identifiable with these poses, held fixed: {}",
            names.join(", ")
        );
    }
    if let Some((_, r)) = &built.residual {
        let validation = match (&r.validation_before, &r.validation_after) {
            (Some(b), Some(a)) => format!(
                ", validation ({}) {:.4} → {:.4} mm",
                r.validation_source, b.mean, a.mean
            ),
            _ => format!(" (validation: {})", r.validation_source),
        };
        eprintln!(
            "robocal: residual ({}): training mean {:.4} → {:.4} mm{validation}{}",
            r.model,
            r.training_before.mean,
            r.training_after.mean,
            r.classifier_accuracy_validation
                .map_or(String::new(), |a| format!(
                    ", classifier accuracy {:.1} %",
                    100.0 * a
                ))
        );
        if let Some(d) = r.gate.as_ref().and_then(|g| g.decision.as_ref()) {
            eprintln!("robocal: CA-SOMM: {d}");
        }
        if let Some(s) = &r.spread {
            eprintln!(
                "robocal: residual ({}): standard deviations × {:.2}, as its folds found them on {} held-out predictions (up to 150 rows of each random fold and each block of joint 1; within one predicted spread of the measured point: {:.0} % as fitted, {:.0} % scaled, 61 % if the spread is right)",
                r.model,
                s.scale,
                s.rows,
                100.0 * s.within_before,
                100.0 * s.within_after,
            );
        }
        if let Some(b) = &r.spread_beside {
            eprintln!(
                "robocal: residual ({}): spread {:.4} mm beside the physics' standard deviation, as its folds found it on {} held-out predictions (within one predicted spread of the measured point: {:.0} % with the physics' alone, {:.0} % with the spread, 61 % if it is right; it holds the tracker's noise too)",
                r.model,
                b.spread,
                b.rows,
                100.0 * b.within_physics,
                100.0 * b.within_after,
            );
        }
    }
    if let Some(v) = &report.validation {
        eprintln!(
            "robocal: validation {}: mean {:.4} → {:.4} mm (kinematics alone {:.4})",
            v.file.display(),
            v.before.mean,
            v.after.mean,
            v.after_kinematic.mean
        );
    }
    let rows: Vec<&Measurement> = set.rows.iter().collect();
    // The pictures first: a report that cannot be drawn leaves no model either.
    if let Some(dir) = pictures {
        let said = super::replacing(dir);
        let written = write_data_report(
            &model,
            &out.display().to_string(),
            data,
            &rows,
            DataRole::Training,
            dir,
        )?;
        said();
        eprintln!(
            "robocal: report on the training rows written to {} ({} figures, report.html)",
            dir.display(),
            written.figures.len()
        );
    }
    if let Some(r) = &report.repeats {
        eprintln!(
            "robocal: repeated shots: {} configurations and loads measured again ({} rows): {:.4} mm per coordinate about their means (the tracker's noise, and the arm's repeatability where it moved between shots), a floor of {:.4} mm mean error on measured points{}",
            r.groups,
            r.rows,
            r.std_mm,
            r.floor_mm,
            r.held_out_over_floor.map_or(String::new(), |f| format!(
                "; the chosen model's held-out error on random folds is {f:.2}× it"
            ))
        );
    }
    let said = super::replacing(out);
    model.save(out, &report)?;
    said();
    let held_out = match (&report.validation, &report.selection) {
        (Some(v), _) => format!(
            "error on the validation file {}: mean {:.4} mm, max {:.4} mm",
            v.file.display(),
            v.after.mean,
            v.after.max
        ),
        (None, Some(s)) => match s.chosen() {
            Some(c) => format!(
                "held-out error (score of the chosen candidate, {}): {:.4} mm",
                s.held_out,
                c.score.unwrap_or(f64::NAN)
            ),
            None => format!("no held-out error ({})", s.held_out),
        },
        (None, None) => format!(
            "no held-out error (pass --validate FILE); training error {:.4} mm",
            model.stats(&rows).mean
        ),
    };
    eprintln!("robocal: model written to {}; {held_out}", out.display());
    print!("{}", summary(out, &report, started.elapsed().as_secs_f64()));
    Ok(())
}

/// Standard deviations (mm, deg) below which an identified parameter counts as determined in the
/// summary's warning, whatever its change from nominal: a tracker's own noise is hundredths of
/// a millimetre.
const LOOSE_MM: f64 = 0.1;
const LOOSE_DEG: f64 = 0.01;

/// Condition number of the identified parameters' scaled Jacobian above which the summary warns:
/// a well-spread pose set on a six-axis arm with base and tool gives about a thousand.
const CONDITION_WARNING: f64 = 1e4;

/// The summary `calibrate` ends with on stdout: the model chosen, its held-out error, the time,
/// where the files are, and the warnings that matter most — a high condition number, and
/// parameters whose standard deviation exceeds their change from the nominal table (the data do
/// not say which way they moved).
fn summary(out: &Path, report: &CalibrationReport, seconds: f64) -> String {
    let k = &report.kinematic;
    let mut lines = vec!["calibration summary".to_string()];
    let (model, score) = match &report.selection {
        Some(s) => match s.chosen() {
            Some(c) => (c.name.clone(), c.score.map(|v| (v, s.held_out.clone()))),
            None => ("(none chosen)".to_string(), None),
        },
        None => (format!("the stages of {}", report.stages_from), None),
    };
    lines.push(format!("  model      {model}"));
    if let Some(v) = &report.validation {
        lines.push(format!(
            "  held out   {:.4} mm mean, {:.4} mm max on {}",
            v.after.mean,
            v.after.max,
            v.file.display()
        ));
    } else if let Some((score, how)) = score {
        lines.push(format!("  held out   {score:.4} mm mean ({how})"));
    }
    lines.push(format!(
        "  fitted     {:.4} mm mean on the training rows by the identified physics (the nominal table, base and tool fitted: {:.4} mm)",
        k.after.mean, k.before.mean
    ));
    let budget = (report.selection.as_ref()).map_or(String::new(), |s| {
        format!(" (budget {:.0} s)", s.budget_seconds)
    });
    lines.push(format!("  time       {seconds:.0} s{budget}"));
    lines.push(format!("  files      {}", out.display()));
    let mut warnings = Vec::new();
    if k.condition_number > CONDITION_WARNING {
        warnings.push(format!(
            "condition number {:.0}: the poses barely separate some parameters; spread them wider (robocal plan)",
            k.condition_number
        ));
    }
    let loose: Vec<String> = (k.parameters.iter())
        .filter(|p| p.identified_flag)
        .filter_map(|p| {
            let std = p.std?;
            // A deviation under the floor is a parameter the data pin down, moved or not.
            let floor = if p.unit == "mm" { LOOSE_MM } else { LOOSE_DEG };
            (std > p.delta.abs() && std > floor)
                .then(|| format!("{} ±{:.3} {}", p.name, std, p.unit))
        })
        .collect();
    if !loose.is_empty() {
        warnings.push(format!(
            "standard deviation above the change from nominal (the data do not tell which way these moved): {}",
            loose.join(", ")
        ));
    }
    if let Some(w) = report
        .selection
        .as_ref()
        .and_then(Selection::budget_warning)
    {
        warnings.push(w);
    }
    for (i, w) in warnings.iter().enumerate() {
        let head = if i == 0 { "  warnings" } else { "          " };
        lines.push(format!("{head}   {w}"));
    }
    lines.join("\n") + "\n"
}

/// One line per link with identified shared weights: its mass (kg, at its frame's origin) and
/// first moments (kg·m), as identified (the poses may separate only some of them: the rest
/// are held at zero and named with what was not identifiable).
fn link_weight_lines(errors: &robocal_robot::JointErrors) -> Vec<String> {
    (errors.link_weights)
        .chunk_by(|a, b| a.body == b.body)
        .filter(|parts| parts.iter().any(|w| w.value != 0.0))
        .map(|parts| {
            let values: Vec<String> = (parts.iter())
                .filter(|w| w.value != 0.0)
                .map(|w| match w.part {
                    robocal_robot::MomentPart::Mass => {
                        format!("mass {:.3} {}", w.value, w.part.weight_unit())
                    }
                    p => format!("moment {} {:.4} {}", p.name(), w.value, p.weight_unit()),
                })
                .collect();
            format!(
                "link {} weight (through the joints' compliances): {}",
                parts[0].body + 1,
                values.join(", ")
            )
        })
        .collect()
}

/// The standard deviation the report gives the identified term `name` (in its unit), if any.
fn term_std(terms: &[robocal_ident::ErrorTermReport], name: &str) -> Option<f64> {
    (terms.iter())
        .find(|t| t.name == name && t.identified)
        .and_then(|t| t.std)
}

/// ` ± σ` with `decimals` decimals, or nothing without a σ.
fn plus_minus(std: Option<f64>, decimals: usize) -> String {
    std.map_or_else(String::new, |s| format!(" ± {s:.decimals$}"))
}

/// One line per joint with an identified tilting compliance, with its σ from `terms` (the
/// report's joint-error terms).
fn tilt_lines(
    errors: &robocal_robot::JointErrors,
    terms: &[robocal_ident::ErrorTermReport],
) -> Vec<String> {
    (errors.tilts.iter())
        .filter(|t| t.value != 0.0)
        .map(|t| {
            format!(
                "joint {} tilting compliance {:.4} deg/kN·m{} (the parts beyond it turning across its axis under the gravity moment there)",
                t.joint + 1,
                t.value / robocal_robot::DEG_PER_KNM,
                plus_minus(term_std(terms, &robocal_robot::tilt_name(t.joint)), 4),
            )
        })
        .collect()
}

/// One line per joint with identified axis runouts: each order's largest turn across the axis
/// (the amplitude of the turn about x and about y together, deg) and how far they are continued.
fn runout_lines(errors: &robocal_robot::JointErrors) -> Vec<String> {
    let identified: Vec<&robocal_robot::Runout> = (errors.runouts.iter())
        .filter(|r| r.wave.sin != 0.0 || r.wave.cos != 0.0)
        .collect();
    identified
        .chunk_by(|a, b| a.wave.joint == b.wave.joint)
        .map(|terms| {
            let mut orders: Vec<u32> = terms.iter().map(|r| r.wave.order).collect();
            orders.dedup();
            let amplitudes: Vec<String> = (orders.iter())
                .map(|&k| {
                    let squares: f64 = (terms.iter())
                        .filter(|r| r.wave.order == k)
                        .map(|r| r.wave.sin.powi(2) + r.wave.cos.powi(2))
                        .sum();
                    format!("order {k} {:.4}°", squares.sqrt().to_degrees())
                })
                .collect();
            let reach = reach_words(terms[0].wave.reach);
            format!(
                "joint {} axis runout: {}; {reach} (the parts beyond it turning across its axis)",
                terms[0].wave.joint + 1,
                amplitudes.join(", ")
            )
        })
        .collect()
}

/// One line per joint with identified backlash: half its play, and the flank it rests on; the
/// play with its σ (twice the half-play's, from `terms`, the report's joint-error terms), so a
/// play the poses barely see (a wrist joint whose turn hardly moves the reflector) reads as
/// what it is.
fn backlash_lines(
    errors: &robocal_robot::JointErrors,
    terms: &[robocal_ident::ErrorTermReport],
) -> Vec<String> {
    (errors.backlash.iter())
        .filter(|b| b.value != 0.0)
        .map(|b| {
            let (value, play) = (b.value.to_degrees(), 2.0 * b.value.abs().to_degrees());
            let play = format!(
                "{play:.4}°{}",
                plus_minus(
                    term_std(terms, &robocal_robot::backlash_name(b.joint)).map(|s| 2.0 * s),
                    4
                )
            );
            match &b.flank {
                robocal_robot::Flank::Approach { home } => format!(
                    "joint {} backlash: {value:+.4}° at or above {:.1}° (the home it was moved out from), {:+.4}° below: a play of {play}",
                    b.joint + 1,
                    home.to_degrees(),
                    -value
                ),
                robocal_robot::Flank::Torque { .. } => {
                    let preload = (b.flank.preload())
                        .map_or_else(String::new, |p| format!(", preload {p:.2} N·m"));
                    format!(
                        "joint {} backlash: {value:+.4}° where its torque is positive, {:+.4}° where negative (the flank its torque presses{preload}): a play of {play}",
                        b.joint + 1,
                        -value,
                    )
                }
            }
        })
        .collect()
}

/// How far a wave (a harmonic's, a runout's) is continued before it is held, in words.
fn reach_words(reach: Option<[f64; 2]>) -> String {
    reach.map_or_else(
        || "continued periodically at every angle".to_string(),
        |[lo, hi]| {
            format!(
                "continued over {:.1}..{:.1}° (the readings widened by a quarter of their span), held beyond",
                lo.to_degrees(),
                hi.to_degrees()
            )
        },
    )
}

/// One line per joint with identified transmission harmonics: each order's amplitude and how far
/// the harmonics are continued (their reach) before they are held.
fn harmonic_lines(errors: &robocal_robot::JointErrors) -> Vec<String> {
    // A joint's harmonics are consecutive (orders 1..H), and share its reach.
    let identified: Vec<&robocal_robot::Harmonic> = (errors.harmonics.iter())
        .filter(|h| h.sin != 0.0 || h.cos != 0.0)
        .collect();
    identified
        .chunk_by(|a, b| a.joint == b.joint)
        .map(|terms| {
            let orders: Vec<String> = (terms.iter())
                .map(|h| format!("order {} {:.4}°", h.order, h.sin.hypot(h.cos).to_degrees()))
                .collect();
            let reach = reach_words(terms[0].reach);
            format!(
                "joint {} transmission harmonics: {}; {reach}",
                terms[0].joint + 1,
                orders.join(", ")
            )
        })
        .collect()
}
