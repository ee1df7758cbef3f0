//! The report: tables beside the paper's (printed and in `report.md`), `results.json`, the
//! resolved experiment and the figures, written into `<output>/<name>/` atomically.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

use robocal_data::{ErrorStats, write_dir_atomically, write_text_in};
use robocal_twin::{BacklashSide, TwinConfig};

use crate::error::Result;
use crate::figures::{draw_all, report_dir};
use crate::paper;
use crate::run::{Outcome, Summary, stats};
use crate::split::Set;
use robocal_calibration::GateSummary;
use robocal_report::ReportError;

fn ours(s: &ErrorStats) -> String {
    format!("{:.3} | {:.3} | {:.3}", s.mean, s.std, s.max)
}

/// A table's paper cell, `" value |"`, or nothing when the experiment is not the paper's (its
/// numbers would sit beside another robot's).
fn paper_cell(o: &Outcome, value: &str) -> String {
    if o.is_papers() {
        format!(" {value} |")
    } else {
        String::new()
    }
}

/// The paper column's separator cell, or nothing (see [`paper_cell`]).
fn paper_rule(o: &Outcome) -> &'static str {
    if o.is_papers() { "---|" } else { "" }
}

fn theirs(p: [f64; 3]) -> String {
    format!("{:.3} / {:.3} / {:.3}", p[0], p[1], p[2])
}

/// What the twin contains, in words.
fn twin_contents(t: &TwinConfig) -> String {
    let mut parts = vec![
        "true geometry from its own table (for the bundled twin: the paper's identified Table 4)"
            .to_string(),
    ];
    if t.compliance.is_some() {
        parts
            .push("joint compliance under the gravity torques of the links and the payload".into());
    }
    if t.gear.is_some() {
        parts.push("gear transmission errors (two harmonics per joint)".into());
    }
    for b in &t.backlash {
        let side = match b.side {
            BacklashSide::Approach { .. } => "flank set by the approach direction",
            BacklashSide::Torque { .. } => {
                "flank set by the torque on the joint, which a payload can flip"
            }
        };
        parts.push(format!(
            "backlash of joint {} ({:.3}°, {side})",
            b.joint + 1,
            b.width.to_degrees()
        ));
    }
    if let Some(n) = &t.noise {
        parts.push(format!(
            "tracker noise ({:.3} mm + {:.3} mm/m, 1σ per coordinate) and repeatability ({:.3} mm)",
            n.tracker_base, n.tracker_per_metre, n.repeatability
        ));
    }
    parts.join("; ")
}

/// The tables (printed on the terminal and in the report), some read from `summary`.
fn tables(o: &Outcome, summary: &Summary<'_>) -> String {
    let mut t = String::new();
    let w = &mut t;
    split_table(w, o);
    kinematic_table(w, o);
    table4(w, o);
    compliance_table(w, o);
    groups_table(w, o);
    table5(w, o);
    table6(w, o);
    residual_training(w, o, summary);
    by_load_table(w, o);
    t
}

/// The split: which configurations and loads each group holds.
fn split_table(w: &mut String, o: &Outcome) {
    let e = &o.experiment;
    let s = &o.splits;
    let _ = writeln!(w, "## Split (seed {})\n", e.seed);
    let _ = writeln!(w, "| set | configurations | loads | rows | role |");
    let _ = writeln!(w, "|---|---|---|---|---|");
    let role = ["training", "test", "validation", "test", "test"];
    let loads = |l: &[f64]| {
        format!(
            "{} ({})",
            l.len(),
            l.iter()
                .map(|v| format!("{v}"))
                .collect::<Vec<_>>()
                .join(", ")
        )
    };
    let gb10: Vec<f64> = s
        .trained_loads
        .iter()
        .copied()
        .filter(|l| !s.validation_loads.contains(l))
        .collect();
    let cfg = [
        s.trained_configurations.len(),
        s.trained_configurations.len(),
        s.untrained_configurations.len(),
        s.untrained_configurations.len(),
        s.untrained_configurations.len(),
    ];
    let set_loads = [
        loads(&s.trained_loads),
        loads(&s.untrained_loads),
        loads(&s.validation_loads),
        loads(&gb10),
        loads(&s.untrained_loads),
    ];
    for (i, (set, n)) in s.sizes().iter().enumerate() {
        let _ = writeln!(
            w,
            "| {} | {} {} | {} | {n} | {} |",
            set.name(),
            cfg[i],
            if set.trained_configurations() {
                "trained"
            } else {
                "untrained"
            },
            set_loads[i],
            role[i]
        );
    }
    let _ = writeln!(
        w,
        "\nKinematic identification: the {} trained configurations at {} kg; cross-validation on the {} untrained ones at that load.\n",
        s.kinematic_rows.len(),
        s.kinematic_load,
        s.kinematic_held_out_rows.len()
    );
}

/// Kinematic calibration: every solver on the fitted and the held-out rows.
fn kinematic_table(w: &mut String, o: &Outcome) {
    let s = &o.splits;
    if o.is_papers() {
        let _ = writeln!(w, "## Kinematic calibration (paper section V-A)\n");
        let _ = writeln!(
            w,
            "Mean | std | max of the Euclidean error, mm. The paper's column is its real robot: 168 unloaded configurations (before/after) and 56 held out.\n"
        );
    } else {
        let _ = writeln!(w, "## Kinematic calibration\n");
        let _ = writeln!(w, "Mean | std | max of the Euclidean error, mm.\n");
    }
    let _ = writeln!(
        w,
        "| rows | model | mean | std | max |{}",
        paper_cell(o, "paper")
    );
    let _ = writeln!(w, "|---|---|---|---|---|{}", paper_rule(o));
    // Fitted rows, then held-out rows: "before", then each solver; the paper's figure beside
    // BFGS (its solver).
    let sets = [
        (
            "fitted",
            "before (nominal, base+tool fitted)",
            &s.kinematic_rows,
            theirs(paper::V_A_BEFORE),
            theirs(paper::V_A_AFTER),
        ),
        (
            "held out",
            "before",
            &s.kinematic_held_out_rows,
            "-".to_string(),
            format!("{:.3} mean", paper::V_A_HELD_OUT_MEAN),
        ),
    ];
    for (label, before, rows, paper_before, paper_bfgs) in sets {
        let n = rows.len();
        let _ = writeln!(
            w,
            "| {label} ({n}) | {before} | {} |{}",
            ours(&stats(&o.before, rows)),
            paper_cell(o, &paper_before)
        );
        for k in &o.kinematics {
            let p = if k.settings.solver == robocal_ident::SolverKind::Bfgs {
                paper_bfgs.as_str()
            } else {
                "-"
            };
            let _ = writeln!(
                w,
                "| {label} ({n}) | {} | {} |{}",
                k.label,
                ours(&stats(&k.errors, rows)),
                paper_cell(o, p)
            );
        }
    }
    let _ = writeln!(w);
    for k in &o.kinematics {
        let r = &k.calibration.report;
        let fixed: Vec<&str> = r.fixed.iter().map(|f| f.name.as_str()).collect();
        let _ = writeln!(
            w,
            "- {}: {} iterations ({}), condition number {:.0}, {:.3} s{}",
            k.label,
            r.iterations,
            r.termination,
            r.condition_number,
            k.seconds,
            if fixed.is_empty() {
                String::new()
            } else {
                format!("; held fixed as not identifiable: {}", fixed.join(", "))
            }
        );
    }
}

/// Table 4: the identified parameters beside the nominal table and the twin's truth.
fn table4(w: &mut String, o: &Outcome) {
    let _ = writeln!(w, "\n## Table 4: identified parameters\n");
    let truth_col = o.twin.is_some();
    let _ = write!(
        w,
        "| parameter | unit | nominal |{}",
        if truth_col { " twin truth |" } else { "" }
    );
    for k in &o.kinematics {
        let _ = write!(w, " {} |", k.label);
    }
    let _ = writeln!(
        w,
        " σ ({}) |",
        o.kinematics.first().map_or("-", |k| k.label.as_str())
    );
    let _ = writeln!(
        w,
        "|---|---|---|{}{}---|",
        if truth_col { "---|" } else { "" },
        "---|".repeat(o.kinematics.len())
    );
    for r in o.table4() {
        let _ = write!(w, "| {} | {} | {:.4} |", r.name, r.unit, r.nominal);
        if truth_col {
            let _ = write!(
                w,
                " {} |",
                r.truth.map_or("-".into(), |v| format!("{v:.4}"))
            );
        }
        for (_, v) in &r.identified {
            let _ = write!(w, " {} |", v.map_or("fixed".into(), |v| format!("{v:.4}")));
        }
        let _ = writeln!(w, " {} |", r.std.map_or("-".into(), |v| format!("{v:.4}")));
    }
    let _ = writeln!(
        w,
        "\n(Base and tool frames are in `results.json`. \"fixed\": not identifiable with these poses, held at nominal; the base/tool carry its effect.)\n"
    );
}

/// Joint compliance of the elasto-geometric stages, beside the twin's truth.
fn compliance_table(w: &mut String, o: &Outcome) {
    let elastic: Vec<&crate::run::KinematicRun> = (o.kinematics.iter())
        .filter(|k| k.calibration.report.compliance.is_some())
        .collect();
    if !elastic.is_empty() {
        let _ = writeln!(
            w,
            "## Joint compliance (elasto-geometric stages), deg per kN·m\n"
        );
        let truth = o.twin.as_ref().and_then(|t| t.compliance.as_ref());
        let _ = write!(w, "| joint | payload torque (N·m/kg, RMS) |");
        if truth.is_some() {
            let _ = write!(w, " twin truth |");
        }
        for k in &elastic {
            let _ = write!(w, " {} (± σ) |", k.label);
        }
        let _ = writeln!(
            w,
            "\n|---|---|{}{}",
            if truth.is_some() { "---|" } else { "" },
            "---|".repeat(elastic.len())
        );
        for j in 0..o.nominal.dof() {
            let first = elastic[0].calibration.report.compliance.as_ref();
            let torque = first.map_or(0.0, |c| c.joints[j].torque_per_kg);
            let _ = write!(w, "| {} | {torque:.3} |", j + 1);
            if let Some(t) = truth {
                let _ = write!(
                    w,
                    " {:.4} |",
                    1.0 / t.stiffness[j] / robocal_robot::DEG_PER_KNM
                );
            }
            for k in &elastic {
                let c = k
                    .calibration
                    .report
                    .compliance
                    .as_ref()
                    .map(|c| &c.joints[j]);
                let cell = match c {
                    Some(c) if c.identified => format!(
                        "{:.4}{}",
                        c.compliance,
                        c.std.map_or(String::new(), |s| format!(" ± {s:.4}"))
                    ),
                    _ => "rigid".into(),
                };
                let _ = write!(w, " {cell} |");
            }
            let _ = writeln!(w);
        }
        for k in &elastic {
            if let Some(c) = &k.calibration.report.compliance {
                let _ = writeln!(
                    w,
                    "\n- {}: {} points at loads {:?} kg; joints: {}; payload centre of mass {:?} mm (flange frame) from {}.",
                    k.label,
                    k.calibration.report.points,
                    c.loads,
                    c.joints_source,
                    c.payload_com,
                    c.payload_com_source
                );
            }
        }
        let _ = writeln!(
            w,
            "\nThe twin's links also deflect under their own weight; that part does not change with the load and the geometry absorbs it, so the twin truth is the comparison for the load-dependent part only.\n"
        );
    }
}

/// The groups of "Every model on every group", in column order.
const GROUPS: [Set; 5] = [Set::Ga10, Set::Gb20, Set::Ga20, Set::Gb10, Set::Gb30];

/// Every model on every group of the split.
fn groups_table(w: &mut String, o: &Outcome) {
    let _ = writeln!(
        w,
        "## Every model on every group: mean / max (mm)\n\n{}.\n",
        GROUPS
            .iter()
            .map(|s| format!("{} {}", s.name(), s.description()))
            .collect::<Vec<_>>()
            .join(", ")
    );
    let groups = GROUPS.map(Set::name);
    let _ = writeln!(w, "| model | {} |", groups.join(" | "));
    let _ = writeln!(w, "|---|{}", "---|".repeat(groups.len()));
    let mut line = |name: &str, errors: &[nalgebra::Vector3<f64>]| {
        let cells: Vec<String> = groups
            .iter()
            .map(|g| {
                let s = stats(errors, &o.rows(g));
                format!("{:.3} / {:.3}", s.mean, s.max)
            })
            .collect();
        let _ = writeln!(w, "| {name} | {} |", cells.join(" | "));
    };
    line("before calibration", &o.before);
    for m in &o.models {
        line(&m.name, &m.errors);
    }
    let _ = writeln!(w);
}

/// Table 5: one model on training, validation and test.
fn table5(w: &mut String, o: &Outcome) {
    let e = &o.experiment;
    if let Some(i) = e.table5 {
        let m = &o.models[i];
        let _ = writeln!(
            w,
            "## Table 5: {} on training, validation and test\n",
            m.name
        );
        let _ = writeln!(
            w,
            "| status | rows | mean | std | max |{}",
            paper_cell(o, "paper (BFGS + SOMM-ANN)")
        );
        let _ = writeln!(w, "|---|---|---|---|---|{}", paper_rule(o));
        for (label, group, p) in [
            ("training (GA10)", "GA10", paper::TABLE5_TRAINING),
            ("validation (GB20)", "GB20", paper::TABLE5_VALIDATION),
            ("test (GA20+GB10+GB30)", "test", paper::TABLE5_TEST),
        ] {
            let rows = o.rows(group);
            let _ = writeln!(
                w,
                "| {label} | {} | {} |{}",
                rows.len(),
                ours(&stats(&m.errors, &rows)),
                paper_cell(o, &theirs(p))
            );
        }
        let _ = writeln!(w);
    }
}

/// One line on a CA-SOMM gate: its classes, what the tree reads, its first splits.
pub fn gate_line(g: &GateSummary) -> String {
    let splits: Vec<String> = (g.splits.iter().take(3))
        .map(|s| format!("{} < {:.3}", s.feature, s.below))
        .collect();
    let mut line = format!(
        "{} classes A {} rows (mean {} error {:+.3} mm), B {} rows ({:+.3} mm); the tree (depth ≤ {}, ≥ {} rows a leaf{}) reads {} inputs and splits first on {}",
        g.classes,
        g.class_rows[0],
        g.axis.to_uppercase(),
        g.class_mean_error[0][axis_index(g.axis)],
        g.class_rows[1],
        g.class_mean_error[1][axis_index(g.axis)],
        g.tree[0],
        g.tree[1],
        if g.tree_searched > 0 {
            format!(", the best of {} on the validation rows", g.tree_searched)
        } else {
            String::new()
        },
        g.inputs,
        if splits.is_empty() {
            "nothing (one leaf)".to_string()
        } else {
            splits.join(", then ")
        }
    );
    if let Some(d) = &g.decision {
        let _ = write!(line, "; {d}");
    }
    line
}

fn axis_index(axis: &str) -> usize {
    match axis {
        "y" => 1,
        "z" => 2,
        _ => 0,
    }
}

/// Table 6: every model on the untrained configurations, and per axis.
fn table6(w: &mut String, o: &Outcome) {
    let e = &o.experiment;
    let t6 = o.rows("table6");
    let _ = writeln!(
        w,
        "## Table 6: the {} GB10 + GB30 rows (untrained configurations)\n",
        t6.len()
    );
    let _ = writeln!(
        w,
        "| before/after calibration | mean | std | max |{}",
        paper_cell(o, "paper")
    );
    let _ = writeln!(w, "|---|---|---|---|{}", paper_rule(o));
    let _ = writeln!(
        w,
        "| before calibration | {} |{}",
        ours(&stats(&o.before, &t6)),
        paper_cell(o, &theirs(paper::TABLE6_BEFORE))
    );
    for (m, plan) in o.models.iter().zip(&e.models) {
        let p = plan.paper_row().map_or("-".into(), |(_, p)| theirs(p));
        let _ = writeln!(
            w,
            "| after {} | {} |{}",
            m.name,
            ours(&stats(&m.errors, &t6)),
            paper_cell(o, &p)
        );
    }
    if o.is_papers() {
        let _ = writeln!(
            w,
            "\nThe paper prints 0.991 as both the standard deviation and the maximum of its BFGS + SOMM row; kept as printed.\n"
        );
    } else {
        let _ = writeln!(w);
    }

    let _ = writeln!(
        w,
        "### Per axis on the Table 6 rows: RMS of the signed error, kinematics alone → whole model (mm)\n"
    );
    let _ = writeln!(w, "| model | X | Y | Z |");
    let _ = writeln!(w, "|---|---|---|---|");
    for m in &o.models {
        let kin = &o.kinematics[m.kinematic];
        let a = crate::run::axis_rms(&kin.errors, &t6);
        let b = crate::run::axis_rms(&m.errors, &t6);
        let _ = writeln!(
            w,
            "| {} | {:.3} → {:.3} | {:.3} → {:.3} | {:.3} → {:.3} |",
            m.name, a[0], b[0], a[1], b[1], a[2], b[2]
        );
    }
    let _ = writeln!(w);
}

/// How each residual model trained.
fn residual_training(w: &mut String, o: &Outcome, summary: &Summary<'_>) {
    let mut residual_lines = Vec::new();
    for m in &summary.models {
        if m.networks.is_empty() {
            continue;
        }
        let nets: Vec<String> = m
            .networks
            .iter()
            .map(|n| format!("{} {}/{}", n.axes, n.best_epoch, n.epochs))
            .collect();
        let mut line = format!(
            "- {}: trained in {:.1} s; best/last epoch per network: {}",
            m.name,
            m.residual_seconds,
            nets.join(", ")
        );
        if let Some(c) = &m.classifier {
            let acc: Vec<String> = c
                .accuracy
                .iter()
                .map(|(g, a)| format!("{g} {:.1} %", 100.0 * a))
                .collect();
            let _ = write!(
                line,
                "; classifier (X error split at {:.3} mm) accuracy {}{}",
                c.threshold,
                acc.join(", "),
                if o.is_papers() {
                    format!(" (paper: {:.0} %)", 100.0 * paper::CLASSIFIER_ACCURACY)
                } else {
                    String::new()
                }
            );
            if let Some(g) = &c.gate {
                let _ = write!(line, "; {}", gate_line(g));
            }
        }
        residual_lines.push(line);
    }
    if !residual_lines.is_empty() {
        let _ = writeln!(w, "## Residual models\n\n{}\n", residual_lines.join("\n"));
    }
}

/// Mean error against load on the untrained configurations (Fig. 13).
fn by_load_table(w: &mut String, o: &Outcome) {
    if o.is_papers() {
        let _ = writeln!(
            w,
            "## Mean error against load, untrained configurations (Fig. 13; paper: rising to {:.2} mm at 20 kg after BFGS)\n",
            paper::FIG13_HEAVIEST_MEAN
        );
    } else {
        let _ = writeln!(w, "## Mean error against load, untrained configurations\n");
    }
    let _ = write!(w, "| load (kg) | before |");
    for m in &o.models {
        let _ = write!(w, " {} |", m.name);
    }
    let _ = writeln!(w, "\n|---|---|{}", "---|".repeat(o.models.len()));
    let before = o.mean_by_load(&o.before);
    let per: Vec<Vec<(f64, f64)>> = o.models.iter().map(|m| o.mean_by_load(&m.errors)).collect();
    for (k, (load, b)) in before.iter().enumerate() {
        let _ = write!(w, "| {load} | {b:.3} |");
        for p in &per {
            let _ = write!(w, " {:.3} |", p[k].1);
        }
        let _ = writeln!(w);
    }
}

/// The whole `report.md`.
fn markdown(o: &Outcome, tables: &str, figures: &[(String, Vec<String>)]) -> String {
    let e = &o.experiment;
    let mut w = String::new();
    let _ = writeln!(w, "# Experiment `{}`\n", e.name);
    if let Some(d) = &e.description {
        let _ = writeln!(w, "{d}\n");
    }
    match &o.twin {
        Some(t) => {
            let how = if o.generated {
                "generated in memory from it".to_string()
            } else {
                format!(
                    "read from `{}`",
                    e.data
                        .measurements()
                        .map_or(String::new(), |p| p.display().to_string())
                )
            };
            let _ = writeln!(
                w,
                "**The data come from robocal's digital twin, not from a real robot.** Twin `{}` (`{}`, seed {}), {how}: {} rows, {} configurations × {} loads. It contains {}.\n{}",
                t.name,
                e.data
                    .twin()
                    .map_or(String::new(), |p| p.display().to_string()),
                t.seed,
                o.data.len(),
                o.splits.trained_configurations.len() + o.splits.untrained_configurations.len(),
                o.data.loads().len(),
                twin_contents(t),
                if o.is_papers() {
                    "\nThe paper's numbers, printed beside ours, were measured on its real PMC6VA030 robot with a laser tracker; they are a reference for scale, not results of this run.\n"
                } else {
                    ""
                }
            );
        }
        None => {
            let _ = writeln!(
                w,
                "Data: `{}` ({} rows), robot table `{}`.{}\n",
                e.data
                    .measurements()
                    .map_or(String::new(), |p| p.display().to_string()),
                o.data.len(),
                e.data
                    .robot()
                    .map_or(String::new(), |p| p.display().to_string()),
                if o.is_papers() {
                    " The paper's numbers beside ours are from its own robot, for scale only."
                } else {
                    ""
                }
            );
        }
    }
    let _ = writeln!(
        w,
        "robocal {}; experiment file `{}`; seed {}. Resolved settings: `experiment.toml`; every figure: `results.json`.\n",
        env!("CARGO_PKG_VERSION"),
        e.source.display(),
        e.seed
    );
    w.push_str(tables);
    let _ = writeln!(w, "\n## Figures\n");
    for (what, files) in figures {
        let png = files
            .iter()
            .find(|f| f.ends_with(".png"))
            .cloned()
            .unwrap_or_default();
        let svg = files
            .iter()
            .find(|f| f.ends_with(".svg"))
            .cloned()
            .unwrap_or_default();
        let _ = writeln!(w, "{what} ([SVG]({svg}))\n\n![{what}]({png})\n");
    }
    let t = &o.timings;
    let _ = writeln!(
        w,
        "## Timings\n\nData {:.1} s, kinematic identification {:.1} s, residual training {:.1} s, everything before the report {:.1} s (wall clock, this run's machine).",
        t.data_s, t.kinematic_s, t.residual_s, t.total_s
    );
    w
}

/// What [`write_report`] wrote.
#[derive(Debug, Clone)]
pub struct Written {
    /// The report folder, `<output>/<name>`.
    pub dir: PathBuf,
    /// The tables of `report.md`, for the terminal.
    pub tables: String,
}

/// Writes the report folder `<output>/<name>/` atomically. `out` replaces the experiment's
/// output folder when given.
pub fn write_report(o: &mut Outcome, out: Option<&Path>) -> Result<Written> {
    let start = Instant::now();
    let output = out.map_or_else(|| o.experiment.output.clone(), Path::to_path_buf);
    let dir = report_dir(&output, &o.experiment.name);
    let resolved = o
        .experiment
        .resolved(o.splits.untrained_loads.clone(), o.splits.kinematic_load);
    let resolved = toml::to_string(&resolved).map_err(|e| ReportError::Plot {
        path: dir.join("experiment.toml"),
        message: e.to_string(),
    })?;
    let mut tables_text = String::new();
    write_dir_atomically(&dir, |tmp| -> Result<()> {
        let figures = draw_all(o, tmp, &dir)?;
        o.timings.report_s = start.elapsed().as_secs_f64();
        let summary = o.summary();
        tables_text = tables(o, &summary);
        let json = serde_json::to_string_pretty(&summary).expect("plain data serialises") + "\n";
        write_text_in(tmp, &dir, "results.json", &json)?;
        write_text_in(
            tmp,
            &dir,
            "experiment.toml",
            &format!(
                "# {} as it ran, every default filled in (robocal {})\n{resolved}",
                o.experiment.source.display(),
                env!("CARGO_PKG_VERSION")
            ),
        )?;
        write_text_in(tmp, &dir, "report.md", &markdown(o, &tables_text, &figures))?;
        Ok(())
    })?;
    Ok(Written {
        dir,
        tables: tables_text,
    })
}
