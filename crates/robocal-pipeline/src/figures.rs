//! The experiments' figures beside the paper's: per-configuration errors (Figs. 11–12), error
//! against load (Fig. 13), per-axis error distributions (Figs. 14, 16, 21), the gate's classes
//! (Figs. 22–25) and the histogram comparison of every stage (Fig. 26).

use std::path::{Path, PathBuf};

use nalgebra::Vector3;
use robocal_report::plots::{Draw, Panel, Series, TWO, WIDE, figure, histograms, slug};

use crate::error::Result;
use crate::run::Outcome;

/// Draws every figure into `dir` (the report's temporary folder; `out` is where it will be, for
/// error messages). Returns (what it shows, file names).
pub fn draw_all(o: &Outcome, dir: &Path, out: &Path) -> Result<Vec<(String, Vec<String>)>> {
    let mut made = Vec::new();
    configurations_figure(o, dir, out, &mut made)?;
    load_figure(o, dir, out, &mut made)?;
    // Figs. 14–26 are drawn on the Table 6 rows.
    let t6 = o.rows("table6");
    axes_figures(o, &t6, dir, out, &mut made)?;
    class_figures(o, &t6, dir, out, &mut made)?;
    stages_figure(o, &t6, dir, out, &mut made)?;
    Ok(made)
}

/// Figs. 11–12: per configuration at the kinematic load, trained then untrained.
fn configurations_figure(
    o: &Outcome,
    dir: &Path,
    out: &Path,
    made: &mut Vec<(String, Vec<String>)>,
) -> Result<()> {
    let rows: Vec<usize> = o
        .splits
        .kinematic_rows
        .iter()
        .chain(&o.splits.kinematic_held_out_rows)
        .copied()
        .collect();
    let n_fit = o.splits.kinematic_rows.len();
    let before = vec![Series {
        name: "before (nominal, base+tool fitted)".into(),
        points: rows
            .iter()
            .enumerate()
            .map(|(k, &i)| ((k + 1) as f64, o.before[i].norm()))
            .collect(),
        draw: Draw::Line,
    }];
    let mut series = Vec::new();
    for k in &o.kinematics {
        let points = |range: std::ops::Range<usize>| -> Vec<(f64, f64)> {
            range
                .map(|k2| ((k2 + 1) as f64, k.errors[rows[k2]].norm()))
                .collect()
        };
        series.push(Series {
            name: format!("after {} (fitted)", k.label),
            points: points(0..n_fit),
            draw: Draw::Marked,
        });
        series.push(Series {
            name: format!("after {} (held out)", k.label),
            points: points(n_fit..rows.len()),
            draw: Draw::Marked,
        });
    }
    let load = o.splits.kinematic_load;
    let stem = "fig11-12-configurations";
    made.push((
        format!("Figs. 11–12: error per configuration at {load} kg, before and after kinematic calibration; configurations 1–{n_fit} fitted, the rest held out (cross-validation)"),
        figure(dir, out, stem, TWO, &[
            Panel {
                title: format!("Before calibration, at {load} kg"),
                x_label: format!("configuration (1–{n_fit} fitted, {}–{} held out)", n_fit + 1, rows.len()),
                y_label: "error (mm)".into(),
                series: before,
            },
            Panel {
                title: format!("After kinematic calibration, at {load} kg"),
                x_label: format!("configuration (1–{n_fit} fitted, {}–{} held out)", n_fit + 1, rows.len()),
                y_label: "error (mm)".into(),
                series,
            },
        ])?,
    ));
    Ok(())
}

/// Fig. 13: mean error against load, untrained configurations.
fn load_figure(
    o: &Outcome,
    dir: &Path,
    out: &Path,
    made: &mut Vec<(String, Vec<String>)>,
) -> Result<()> {
    let before = vec![Series {
        name: "before".into(),
        points: o.mean_by_load(&o.before),
        draw: Draw::Marked,
    }];
    let mut series = Vec::new();
    for m in &o.models {
        series.push(Series {
            name: m.name.clone(),
            points: o.mean_by_load(&m.errors),
            draw: Draw::Marked,
        });
    }
    made.push((
        "Fig. 13: mean error against load over the untrained configurations, before and after each model".into(),
        figure(dir, out, "fig13-load", TWO, &[
            Panel {
                title: "Before calibration (untrained configurations)".into(),
                x_label: "load (kg)".into(),
                y_label: "mean error (mm)".into(),
                series: before,
            },
            Panel {
                title: "After each model (untrained configurations)".into(),
                x_label: "load (kg)".into(),
                y_label: "mean error (mm)".into(),
                series,
            },
        ])?,
    ));
    Ok(())
}

/// Figs. 14, 16, 21: per-axis distributions on the Table 6 rows.
fn axes_figures(
    o: &Outcome,
    t6: &[usize],
    dir: &Path,
    out: &Path,
    made: &mut Vec<(String, Vec<String>)>,
) -> Result<()> {
    let axis_values =
        |e: &[Vector3<f64>], a: usize| t6.iter().map(|&i| e[i][a]).collect::<Vec<f64>>();
    for m in &o.models {
        let kin = &o.kinematics[m.kinematic];
        let (first, first_errors, second) = if m.residual.is_some() {
            (
                format!("after {}", kin.label),
                &kin.errors,
                format!("after {}", m.name),
            )
        } else {
            ("before".to_string(), &o.before, format!("after {}", m.name))
        };
        let panels: Vec<Panel> = (0..3)
            .map(|a| Panel {
                // The model is in the legend; rows and frame here.
                title: format!(
                    "{} error, {} GB10+GB30 rows, world frame",
                    ["X", "Y", "Z"][a],
                    t6.len()
                ),
                x_label: "signed error (mm)".into(),
                y_label: "share of rows (%)".into(),
                series: histograms(
                    &[
                        (first.clone(), axis_values(first_errors, a)),
                        (second.clone(), axis_values(&m.errors, a)),
                    ],
                    40,
                    false,
                ),
            })
            .collect();
        let stem = format!("axes-{}", slug(&m.name));
        made.push((
            format!("Figs. 14/16/21: X, Y, Z error distributions on the {} GB10+GB30 rows, {first} and {second}", t6.len()),
            figure(dir, out, &stem, WIDE, &panels)?,
        ));
    }
    Ok(())
}

/// Figs. 22–25: the bimodal X error of each CA-SOMM model's gate classes, before and after.
fn class_figures(
    o: &Outcome,
    t6: &[usize],
    dir: &Path,
    out: &Path,
    made: &mut Vec<(String, Vec<String>)>,
) -> Result<()> {
    for m in &o.models {
        let Some(classes) = o.gate_classes(m, t6) else {
            continue;
        };
        let kin = &o.kinematics[m.kinematic];
        let per_class = |e: &[Vector3<f64>]| -> Vec<(String, Vec<f64>)> {
            (0..2)
                .map(|k| {
                    let values: Vec<f64> = (t6.iter().zip(&classes))
                        .filter(|(_, c)| **c == k)
                        .map(|(&i, _)| e[i].x)
                        .collect();
                    (
                        format!("class {} ({} rows)", ["A", "B"][k], values.len()),
                        values,
                    )
                })
                .collect()
        };
        let panels = [
            (format!("after {}", kin.label), &kin.errors),
            (format!("after {}", m.name), &m.errors),
        ]
        .into_iter()
        .map(|(stage, errors)| Panel {
            title: format!(
                "X error {stage}, by the gate's class ({} GB10+GB30 rows)",
                t6.len()
            ),
            x_label: "signed X error, world frame (mm)".into(),
            y_label: "share of rows (%)".into(),
            series: histograms(&per_class(errors), 40, false),
        })
        .collect::<Vec<Panel>>();
        let stem = format!("classes-{}", slug(&m.name));
        made.push((
            format!(
                "Figs. 22–25: the X error of the {} GB10+GB30 rows by the class {}'s gate gives them, after {} and after {}",
                t6.len(),
                m.name,
                kin.label,
                m.name
            ),
            figure(dir, out, &stem, WIDE, &panels)?,
        ));
    }
    Ok(())
}

/// Fig. 26: every stage's error distribution on the Table 6 rows.
fn stages_figure(
    o: &Outcome,
    t6: &[usize],
    dir: &Path,
    out: &Path,
    made: &mut Vec<(String, Vec<String>)>,
) -> Result<()> {
    let norms = |e: &[Vector3<f64>], rows: &[usize]| {
        rows.iter().map(|&i| e[i].norm()).collect::<Vec<f64>>()
    };
    let before = vec![("before".to_string(), norms(&o.before, t6))];
    let mut named = Vec::new();
    for m in &o.models {
        named.push((m.name.clone(), norms(&m.errors, t6)));
    }
    made.push((
        format!(
            "Fig. 26: error distributions of every stage on the {} GB10+GB30 rows",
            t6.len()
        ),
        figure(
            dir,
            out,
            "fig26-stages",
            TWO,
            &[
                Panel {
                    title: "Before calibration (GB10 + GB30)".into(),
                    x_label: "error (mm)".into(),
                    y_label: "share of rows (%)".into(),
                    series: histograms(&before, 60, true),
                },
                Panel {
                    title: "After every model (GB10 + GB30)".into(),
                    x_label: "error (mm)".into(),
                    y_label: "share of rows (%)".into(),
                    series: histograms(&named, 60, true),
                },
            ],
        )?,
    ));
    Ok(())
}

/// The report folder of an experiment: `<output>/<name>`.
pub fn report_dir(output: &Path, name: &str) -> PathBuf {
    output.join(name)
}
