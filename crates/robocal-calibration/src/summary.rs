//! What a calibration says: the lines that describe the fit (the identified physics, its joint
//! errors, the residual model, the validation), and the summary a calibration ends with. The
//! command line prints them (`robocal: ` before each line, the summary on stdout); Python gives
//! the summary as `Model.summary`.

use std::fmt;
use std::path::{Path, PathBuf};

use robocal_ident::{ErrorTermReport, KinematicReport};
use robocal_robot::{
    DEG_PER_KNM, Flank, Harmonic, JointErrors, MomentPart, Runout, backlash_name, payload_com_name,
    tilt_name,
};

use crate::built::Built;
use crate::calibrate::{Calibration, CalibrationReport};
use crate::select::Selection;

/// The lines that describe a calibration's fit, in order: the identified physics (its errors
/// before and after, the orientations, the warnings, the compliances, the joint errors, the
/// priors, what the extra reflectors identified, what was held fixed), the residual model, the
/// validation file's errors.
pub fn fit_lines(calibration: &Calibration) -> Vec<String> {
    let Calibration { report, built, .. } = calibration;
    let mut said = physics_lines(built);
    said.extend(residual_lines(built));
    if let Some(v) = &report.validation {
        said.push(format!(
            "validation {}: mean {:.4} → {:.4} mm (kinematics alone {:.4})",
            v.file.display(),
            v.before.mean,
            v.after.mean,
            v.after_kinematic.mean
        ));
    }
    said
}

/// The lines of the identified physics.
fn physics_lines(built: &Built) -> Vec<String> {
    let mut said = Vec::new();
    let r = &built.kinematic.report;
    // What the identified physical model holds, so that its error is read as that model's.
    let mut holds = vec!["table"];
    if r.compliance.is_some() {
        holds.push("joint compliance");
    }
    if r.joint_errors.iter().any(|t| t.identified) {
        holds.push("joint errors");
    }
    said.push(format!(
        "identified physics ({}, by {}): {} points, mean error {:.4} → {:.4} mm (max {:.4} → {:.4}), {} iterations",
        holds.join(" + "),
        r.solver,
        r.points,
        r.before.mean,
        r.after.mean,
        r.before.max,
        r.after.max,
        r.iterations
    ));
    if let Some(o) = &r.orientation {
        said.push(format!(
            "orientation (a 6-DoF probe's {} rows, {:.3} mm per deg): mean angle {:.4} → {:.4} deg (max {:.4} → {:.4})",
            o.rows, o.angle_weight, o.before.mean, o.after.mean, o.before.max, o.after.max
        ));
    }
    for w in &r.warnings {
        said.push(format!("warning: {w}"));
    }
    if let Some(c) = &r.compliance {
        for j in c.joints.iter().filter(|j| j.identified) {
            said.push(format!(
                "joint {} compliance {:.4} deg/kN·m{}{}",
                j.joint,
                j.compliance,
                plus_minus(j.std, 4),
                if j.compliance < 0.0 {
                    " (warning: negative; see report.json)"
                } else {
                    ""
                }
            ));
        }
        if c.payload_com_identified > 0 {
            // Each coordinate with its σ where the report has one.
            let coordinates: Vec<String> = (0..3)
                .map(|axis| {
                    let name = payload_com_name(axis);
                    let std = term_std(&r.joint_errors, &name);
                    // The coordinate's letter, as its name in the report ends.
                    let letter = name.rsplit('.').next().unwrap_or_default();
                    format!("{letter} {:.1}{}", c.payload_com[axis], plus_minus(std, 1))
                })
                .collect();
            said.push(format!(
                "payload centre of mass {} mm (flange frame; {})",
                coordinates.join(", "),
                c.payload_com_source
            ));
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
            said.push(line);
        }
    }
    if let Some(spread) = r.harmonic_prior_deg {
        said.push(format!(
            "transmission harmonics under a prior of spread {spread:.4}° (chosen by marginal likelihood: a harmonic the poses barely determine is drawn toward it)"
        ));
    }
    if let Some(spread) = r.runout_prior_deg {
        said.push(format!(
            "axis runouts under a prior of spread {spread:.4}° (chosen by marginal likelihood, as the harmonics')"
        ));
    }
    if !r.identified_by_reflectors.is_empty() {
        said.push(format!(
            "identified thanks to the extra reflectors (the default one alone would hold them fixed): {}",
            r.identified_by_reflectors.join(", ")
        ));
    }
    if !r.fixed.is_empty() {
        let names: Vec<&str> = r.fixed.iter().map(|f| f.name.as_str()).collect();
        said.push(format!(
            "not identifiable with these poses, held fixed: {}",
            names.join(", ")
        ));
    }
    said
}

/// The lines of the residual model: its errors, its gate's decision, its spread.
fn residual_lines(built: &Built) -> Vec<String> {
    let mut said = Vec::new();
    if let Some((_, r)) = &built.residual {
        let validation = match (&r.validation_before, &r.validation_after) {
            (Some(b), Some(a)) => format!(
                ", validation ({}) {:.4} → {:.4} mm",
                r.validation_source, b.mean, a.mean
            ),
            _ => format!(" (validation: {})", r.validation_source),
        };
        said.push(format!(
            "residual ({}): training mean {:.4} → {:.4} mm{validation}{}",
            r.model,
            r.training_before.mean,
            r.training_after.mean,
            r.classifier_accuracy_validation
                .map_or(String::new(), |a| format!(
                    ", classifier accuracy {:.1} %",
                    100.0 * a
                ))
        ));
        if let Some(d) = r.gate.as_ref().and_then(|g| g.decision.as_ref()) {
            said.push(format!("CA-SOMM: {d}"));
        }
        if let Some(s) = &r.spread {
            said.push(format!(
                "residual ({}): standard deviations × {:.2}, as its folds found them on {} held-out predictions (up to 150 rows of each random fold and each block of joint 1; within one predicted spread of the measured point: {:.0} % as fitted, {:.0} % scaled, 61 % if the spread is right)",
                r.model,
                s.scale,
                s.rows,
                100.0 * s.within_before,
                100.0 * s.within_after,
            ));
        }
        if let Some(b) = &r.spread_beside {
            said.push(format!(
                "residual ({}): spread {:.4} mm beside the physics' standard deviation, as its folds found it on {} held-out predictions (within one predicted spread of the measured point: {:.0} % with the physics' alone, {:.0} % with the spread, 61 % if it is right; it holds the tracker's noise too)",
                r.model,
                b.spread,
                b.rows,
                100.0 * b.within_physics,
                100.0 * b.within_after,
            ));
        }
    }
    said
}

/// The line of what the repeated shots say of the measurement's own spread, if there are any.
pub fn repeats_line(report: &CalibrationReport) -> Option<String> {
    let mut said = Vec::new();
    if let Some(r) = &report.repeats {
        said.push(format!(
            "repeated shots: {} configurations and loads measured again ({} rows): {:.4} mm per coordinate about their means (the tracker's noise, and the arm's repeatability where it moved between shots), a floor of {:.4} mm mean error on measured points{}",
            r.groups,
            r.rows,
            r.std_mm,
            r.floor_mm,
            r.held_out_over_floor.map_or(String::new(), |f| format!(
                "; the chosen model's held-out error on random folds is {f:.2}× it"
            ))
        ));
    }
    said.pop()
}

/// Standard deviations (mm, deg) below which an identified parameter counts as determined in the
/// summary's warning, whatever its change from nominal: a tracker's own noise is hundredths of
/// a millimetre.
const LOOSE_MM: f64 = 0.1;
const LOOSE_DEG: f64 = 0.01;

/// Condition number of the identified parameters' scaled Jacobian above which the summary warns:
/// a well-spread pose set on a six-axis arm with base and tool gives about a thousand.
const CONDITION_WARNING: f64 = 1e4;

/// The summary a calibration ends with: the model chosen, its held-out error, the fit, the time,
/// where the files are, and the warnings that matter most — a high condition number,
/// parameters whose standard deviation exceeds their change from the nominal table (the data do
/// not say which way they moved), a budget that cut the search.
#[derive(Debug, Clone, PartialEq)]
pub struct Summary {
    /// The model chosen: the candidate's name, or the stage file's stages.
    pub model: String,
    /// The held-out error, in words: on the validation file, or the chosen candidate's score.
    pub held_out: Option<String>,
    /// The mean error on the training rows by the identified physics, and by the nominal table
    /// with base and tool fitted, mm.
    pub fitted: (f64, f64),
    /// Seconds the calibration took, and the default's budget.
    pub seconds: (f64, Option<f64>),
    /// Where the model was written (none: not written).
    pub files: Option<PathBuf>,
    /// The warnings.
    pub warnings: Vec<String>,
}

impl Summary {
    /// The summary of `report`, written to `out`, after `seconds`.
    pub fn new(report: &CalibrationReport, out: Option<&Path>, seconds: f64) -> Self {
        let k = &report.kinematic;
        let (model, score) = match &report.selection {
            Some(s) => match s.chosen() {
                Some(c) => (c.name.clone(), c.score.map(|v| (v, s.held_out.clone()))),
                None => ("(none chosen)".to_string(), None),
            },
            None => (format!("the stages of {}", report.stages_from), None),
        };
        let held_out = match (&report.validation, score) {
            (Some(v), _) => Some(format!(
                "{:.4} mm mean, {:.4} mm max on {}",
                v.after.mean,
                v.after.max,
                v.file.display()
            )),
            (None, Some((score, how))) => Some(format!("{score:.4} mm mean ({how})")),
            (None, None) => None,
        };
        let mut warnings = model_warnings(k);
        warnings.extend(
            report
                .selection
                .as_ref()
                .and_then(Selection::budget_warning),
        );
        Self {
            model,
            held_out,
            fitted: (k.after.mean, k.before.mean),
            seconds: (seconds, report.selection.as_ref().map(|s| s.budget_seconds)),
            files: out.map(Path::to_path_buf),
            warnings,
        }
    }
}

impl fmt::Display for Summary {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(f, "calibration summary")?;
        writeln!(f, "  model      {}", self.model)?;
        if let Some(h) = &self.held_out {
            writeln!(f, "  held out   {h}")?;
        }
        writeln!(
            f,
            "  fitted     {:.4} mm mean on the training rows by the identified physics (the nominal table, base and tool fitted: {:.4} mm)",
            self.fitted.0, self.fitted.1
        )?;
        let budget = self
            .seconds
            .1
            .map_or(String::new(), |b| format!(" (budget {b:.0} s)"));
        writeln!(f, "  time       {:.0} s{budget}", self.seconds.0)?;
        if let Some(files) = &self.files {
            writeln!(f, "  files      {}", files.display())?;
        }
        for (i, w) in self.warnings.iter().enumerate() {
            let head = if i == 0 { "  warnings" } else { "          " };
            writeln!(f, "{head}   {w}")?;
        }
        Ok(())
    }
}

/// The summary's warnings on the identified parameters: a high condition number, and
/// parameters whose standard deviation exceeds both their change from nominal and the floor.
fn model_warnings(k: &KinematicReport) -> Vec<String> {
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
    warnings
}

/// One line per link with identified shared weights: its mass (kg, at its frame's origin) and
/// first moments (kg·m), as identified (the poses may separate only some of them: the rest
/// are held at zero and named with what was not identifiable).
fn link_weight_lines(errors: &JointErrors) -> Vec<String> {
    (errors.link_weights)
        .chunk_by(|a, b| a.body == b.body)
        .filter(|parts| parts.iter().any(|w| w.value != 0.0))
        .map(|parts| {
            let values: Vec<String> = (parts.iter())
                .filter(|w| w.value != 0.0)
                .map(|w| match w.part {
                    MomentPart::Mass => {
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
fn term_std(terms: &[ErrorTermReport], name: &str) -> Option<f64> {
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
fn tilt_lines(errors: &JointErrors, terms: &[ErrorTermReport]) -> Vec<String> {
    (errors.tilts.iter())
        .filter(|t| t.value != 0.0)
        .map(|t| {
            format!(
                "joint {} tilting compliance {:.4} deg/kN·m{} (the parts beyond it turning across its axis under the gravity moment there)",
                t.joint + 1,
                t.value / DEG_PER_KNM,
                plus_minus(term_std(terms, &tilt_name(t.joint)), 4),
            )
        })
        .collect()
}

/// One line per joint with identified axis runouts: each order's largest turn across the axis
/// (the amplitude of the turn about x and about y together, deg) and how far they are continued.
fn runout_lines(errors: &JointErrors) -> Vec<String> {
    let identified: Vec<&Runout> = (errors.runouts.iter())
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
fn backlash_lines(errors: &JointErrors, terms: &[ErrorTermReport]) -> Vec<String> {
    (errors.backlash.iter())
        .filter(|b| b.value != 0.0)
        .map(|b| {
            let (value, play) = (b.value.to_degrees(), 2.0 * b.value.abs().to_degrees());
            let play = format!(
                "{play:.4}°{}",
                plus_minus(
                    term_std(terms, &backlash_name(b.joint)).map(|s| 2.0 * s),
                    4
                )
            );
            match &b.flank {
                Flank::Approach { home } => format!(
                    "joint {} backlash: {value:+.4}° at or above {:.1}° (the home it was moved out from), {:+.4}° below: a play of {play}",
                    b.joint + 1,
                    home.to_degrees(),
                    -value
                ),
                Flank::Torque { .. } => {
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
fn harmonic_lines(errors: &JointErrors) -> Vec<String> {
    // A joint's harmonics are consecutive (orders 1..H), and share its reach.
    let identified: Vec<&Harmonic> = (errors.harmonics.iter())
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
