//! The report's figures: the errors' cumulative distributions, per configuration, per axis
//! against every joint, against the load, over the workspace, and against the predicted spread.

use super::stats::{Figure, loads, mean};
use crate::error::Result;
use crate::plots::{
    ColourPanel, Draw, Panel, Series, colour_figure, cumulative_curves, figure_grid,
};
use nalgebra::Vector3;
use robocal_data::Measurement;
use std::collections::BTreeMap;
use std::path::Path;

/// Each row's configuration number, 1-based, in order of the pose id's first appearance.
pub(super) fn configuration_numbers(rows: &[&Measurement]) -> (Vec<usize>, usize) {
    let mut seen: BTreeMap<&str, usize> = BTreeMap::new();
    let numbers = rows
        .iter()
        .map(|m| {
            let next = seen.len() + 1;
            *seen.entry(m.sample.pose.as_str()).or_insert(next)
        })
        .collect();
    (numbers, seen.len())
}

/// Mean of `errors` at each load: (load, mean).
pub(super) fn mean_by_load(rows: &[&Measurement], errors: &[f64]) -> Vec<(f64, f64)> {
    loads(rows)
        .into_iter()
        .map(|l| {
            let at: Vec<f64> = (rows.iter().zip(errors))
                .filter(|(m, _)| m.sample.load == l)
                .map(|(_, e)| *e)
                .collect();
            (l, mean(&at))
        })
        .collect()
}

pub(super) const AXES: [&str; 3] = ["X", "Y", "Z"];

/// The errors a report draws: of each row, before (the nominal table, base and tool
/// registered), by the physics alone where there is a residual model, after; and each row's
/// signed error after.
#[derive(Clone, Copy)]
pub(super) struct Errors<'a> {
    pub(super) rows: &'a [&'a Measurement],
    pub(super) before: Option<&'a [f64]>,
    pub(super) kinematic: Option<&'a [f64]>,
    pub(super) after: &'a [f64],
    pub(super) signed: &'a [Vector3<f64>],
}

/// The title of a panel of the errors before calibration.
pub(super) const BEFORE_TITLE: &str =
    "Before calibration (nominal table, base and tool registered)";

/// Draws the figures into `dir`; returns them in report order.
pub(super) fn draw(dir: &Path, out: &Path, e: &Errors<'_>) -> Result<Vec<Figure>> {
    let mut figures = vec![
        cumulative_figure(dir, out, e)?,
        per_pose_figure(dir, out, e)?,
        axes_joints_figure(dir, out, e)?,
    ];
    // One load would draw one stripe on an axis around it.
    if loads(e.rows).len() >= 2 {
        figures.push(load_figure(dir, out, e)?);
    }
    figures.push(workspace_figure(dir, out, e)?);
    Ok(figures)
}

/// Cumulative distributions: before on its own panel, its errors being many times the
/// calibrated ones. A staircase reads the same at 20 rows as at 2000, where a histogram's
/// bins are mostly empty or one row each.
pub(super) fn cumulative_figure(dir: &Path, out: &Path, e: &Errors<'_>) -> Result<Figure> {
    let Errors {
        rows,
        before,
        kinematic,
        after,
        ..
    } = *e;
    let n = rows.len();
    let mut after_named = Vec::new();
    if let Some(k) = kinematic {
        after_named.push((
            "after: table + joint errors (no residual)".to_string(),
            k.to_vec(),
        ));
    }
    after_named.push(("after: the whole model".to_string(), after.to_vec()));
    let mut panels = Vec::new();
    if let Some(b) = before {
        panels.push(Panel {
            title: format!("{BEFORE_TITLE}, {n} rows"),
            x_label: "error (mm)".into(),
            y_label: "rows with this error or less (%)".into(),
            series: cumulative_curves(&[("before".to_string(), b.to_vec())]),
        });
    }
    panels.push(Panel {
        title: format!("After calibration, {n} rows"),
        x_label: "error (mm)".into(),
        y_label: "rows with this error or less (%)".into(),
        series: cumulative_curves(&after_named),
    });
    figure_grid(dir, out, "histogram", (1700, 600), &panels, 2)?;
    Ok(Figure {
        stem: "histogram".into(),
        caption: "Cumulative distribution of the position error (distance between measured and predicted point), before and after calibration: the share of rows at or below each error".into(),
    })
}

/// Error per pose.
pub(super) fn per_pose_figure(dir: &Path, out: &Path, e: &Errors<'_>) -> Result<Figure> {
    let Errors {
        rows,
        before,
        after,
        ..
    } = *e;
    let (numbers, configurations) = configuration_numbers(rows);
    let per_pose = |errors: &[f64]| -> Vec<(f64, f64)> {
        numbers
            .iter()
            .zip(errors)
            .map(|(&k, &e)| (k as f64, e))
            .collect()
    };
    let mut panels = Vec::new();
    if let Some(b) = before {
        panels.push(Panel {
            title: BEFORE_TITLE.into(),
            x_label: format!("configuration (1–{configurations}, order of the file)"),
            y_label: "error (mm)".into(),
            series: vec![Series {
                name: "before".into(),
                points: per_pose(b),
                draw: Draw::Points,
            }],
        });
    }
    panels.push(Panel {
        title: "After calibration (the whole model)".into(),
        x_label: format!("configuration (1–{configurations}, order of the file)"),
        y_label: "error (mm)".into(),
        series: vec![Series {
            name: "after: the whole model".into(),
            points: per_pose(after),
            draw: Draw::Points,
        }],
    });
    figure_grid(dir, out, "per-pose", (1700, 600), &panels, 2)?;
    Ok(Figure {
        stem: "per-pose".into(),
        caption: "Error of every row against its configuration (every load of a configuration at its number)".into(),
    })
}

/// Signed error per axis against every joint angle.
pub(super) fn axes_joints_figure(dir: &Path, out: &Path, e: &Errors<'_>) -> Result<Figure> {
    let Errors { rows, signed, .. } = *e;
    let dof = rows.first().map_or(0, |m| m.sample.joints.len());
    let mut panels = Vec::new();
    for (a, axis) in AXES.iter().enumerate() {
        for j in 0..dof {
            panels.push(Panel {
                title: format!("{axis} error against q{}", j + 1),
                x_label: format!("q{} (deg)", j + 1),
                y_label: format!("signed {axis} error (mm)"),
                series: vec![Series {
                    name: "after: measured − predicted".into(),
                    points: rows
                        .iter()
                        .zip(signed)
                        .map(|(m, e)| (m.sample.joints[j], e[a]))
                        .collect(),
                    draw: Draw::Points,
                }],
            });
        }
    }
    let width = 340 + 330 * dof.max(1) as u32;
    figure_grid(dir, out, "axes-joints", (width, 900), &panels, dof.max(1))?;
    Ok(Figure {
        stem: "axes-joints".into(),
        caption: "Signed error along each world axis after calibration against each joint angle: a trend or a wave here is an effect the model does not hold".into(),
    })
}

/// Error against load, where the rows hold two or more: one load would draw one stripe on an
/// axis around it.
pub(super) fn load_figure(dir: &Path, out: &Path, e: &Errors<'_>) -> Result<Figure> {
    let Errors {
        rows,
        before,
        after,
        ..
    } = *e;
    let at_load = |errors: &[f64]| -> Vec<Series> {
        vec![
            Series {
                name: "rows".into(),
                points: rows
                    .iter()
                    .zip(errors)
                    .map(|(m, &e)| (m.sample.load, e))
                    .collect(),
                draw: Draw::Points,
            },
            Series {
                name: "mean per load".into(),
                points: mean_by_load(rows, errors),
                draw: Draw::Marked,
            },
        ]
    };
    let mut panels = Vec::new();
    if let Some(b) = before {
        panels.push(Panel {
            title: BEFORE_TITLE.into(),
            x_label: "load (kg)".into(),
            y_label: "error (mm)".into(),
            series: at_load(b),
        });
    }
    panels.push(Panel {
        title: "After calibration (the whole model)".into(),
        x_label: "load (kg)".into(),
        y_label: "error (mm)".into(),
        series: at_load(after),
    });
    figure_grid(dir, out, "load", (1700, 600), &panels, 2)?;
    Ok(Figure {
        stem: "load".into(),
        caption: "Error against the payload: every row and the mean per load".into(),
    })
}

/// Error over the workspace.
pub(super) fn workspace_figure(dir: &Path, out: &Path, e: &Errors<'_>) -> Result<Figure> {
    let Errors { rows, after, .. } = *e;
    let panel = |title: &str, y: usize, y_name: &str| ColourPanel {
        title: title.into(),
        x_label: "x, world frame (mm)".into(),
        y_label: format!("{y_name}, world frame (mm)"),
        points: rows
            .iter()
            .zip(after)
            .map(|(m, &e)| (m.position.x, m.position[y], e))
            .collect(),
    };
    colour_figure(
        dir,
        out,
        "workspace",
        (1700, 700),
        &[
            panel("Measured points from above (x–y)", 1, "y"),
            panel("Measured points from the side (x–z)", 2, "z"),
        ],
        "error after (mm)",
    )?;
    Ok(Figure {
        stem: "workspace".into(),
        caption: "Where in the workspace the error after calibration is: every measured point coloured by its error".into(),
    })
}

/// The figure of each row's error against the standard deviation the model gives it.
pub(super) fn draw_sigma(dir: &Path, out: &Path, after: &[f64], sigmas: &[f64]) -> Result<Figure> {
    let top = sigmas
        .iter()
        .copied()
        .filter(|s| s.is_finite())
        .fold(0.0, f64::max);
    let line = |k: f64| vec![(0.0, 0.0), (top, k * top)];
    figure_grid(
        dir,
        out,
        "sigma",
        (1200, 700),
        &[Panel {
            title: "Error against the model's standard deviation".into(),
            x_label: "σ the model gives (mm)".into(),
            y_label: "error after (mm)".into(),
            series: vec![
                Series {
                    name: "rows".into(),
                    points: sigmas.iter().copied().zip(after.iter().copied()).collect(),
                    draw: Draw::Points,
                },
                Series {
                    name: "error = σ (61 % below, if σ is right)".into(),
                    points: line(1.0),
                    draw: Draw::Curve,
                },
                Series {
                    name: "error = 2σ (99 % below)".into(),
                    points: line(2.0),
                    draw: Draw::Curve,
                },
            ],
        }],
        1,
    )?;
    Ok(Figure {
        stem: "sigma".into(),
        caption: "Each row's error after calibration against the standard deviation the model gives it (`predict --sigma`): rows far above the 2σ line are poses the model is surer of than it should be".into(),
    })
}
