//! The pictures of a calibration on the user's own measurements (`robocal report`,
//! `calibrate --report`): the error before and after as cumulative distributions, per pose, per
//! axis against every joint angle, against the load (two or more loads) and over the
//! workspace; PNG and SVG, `report.md`, one self-contained `report.html` (the SVGs inline) and
//! `statistics.json`.
//!
//! "Before" is the nominal table with its base and tool registered in the tracker frame (the
//! model directory's `nominal.toml`, written by `calibrate`); a model without it is shown after
//! calibration only.

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use nalgebra::Vector3;
use robocal_data::{ErrorStats, Measurement, write_dir_atomically, write_text_in};
use robocal_model::CalibratedModel;
use serde::Serialize;

use crate::error::{ReportError, Result};
use crate::plots::{
    ColourPanel, Draw, Panel, Series, colour_figure, cumulative_curves, figure_grid,
};

/// What the rows are to the model.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum DataRole {
    /// Rows the model never saw.
    HeldOut,
    /// The rows the model was calibrated on: its fit, not its accuracy.
    Training,
}

impl DataRole {
    fn describe(self) -> &'static str {
        match self {
            Self::HeldOut => {
                "rows given to `robocal report`: the model's accuracy if it never saw them"
            }
            Self::Training => {
                "the training rows: how well the model fits them, not its accuracy on new poses"
            }
        }
    }
}

/// Signed error along one world axis, after calibration.
#[derive(Debug, Clone, Serialize)]
pub struct AxisStats {
    /// `x`, `y` or `z`.
    pub axis: &'static str,
    /// Mean signed error (measured − predicted), mm: a bias the model leaves.
    pub mean: f64,
    /// Standard deviation, mm.
    pub std: f64,
    /// Largest absolute error, mm.
    pub max_abs: f64,
}

/// The error at one load.
#[derive(Debug, Clone, Serialize)]
pub struct LoadStats {
    /// Load, kg.
    pub load: f64,
    /// Rows at this load.
    pub rows: usize,
    /// Mean error before calibration, mm (when the model carries its nominal table).
    pub before: Option<f64>,
    /// Mean error after, mm.
    pub after: f64,
}

/// The error at one reflector (rows naming targets).
#[derive(Debug, Clone, Serialize)]
pub struct TargetStats {
    /// The point (`target`; empty: the default point).
    pub target: String,
    /// Rows measuring it.
    pub rows: usize,
    /// Mean error before calibration, mm (when the model carries its nominal table).
    pub before: Option<f64>,
    /// Mean error after, mm.
    pub after: f64,
}

/// One of the worst rows.
#[derive(Debug, Clone, Serialize)]
pub struct WorstRow {
    /// Line in the data file.
    pub line: u64,
    /// Pose id.
    pub pose: String,
    /// Load, kg.
    pub load: f64,
    /// Error after calibration, mm.
    pub error: f64,
}

/// A figure of the report.
#[derive(Debug, Clone, Serialize)]
pub struct Figure {
    /// File name without extension (`.png` and `.svg` beside each other).
    pub stem: String,
    /// What it shows.
    pub caption: String,
}

/// The orientation statistics of a 6-DoF probe's rows, deg.
#[derive(Debug, Clone, Serialize)]
pub struct OrientationStats {
    /// The registered nominal table.
    pub before: Option<ErrorStats>,
    /// The model (its table and joint errors: the residual model corrects positions only).
    pub after: ErrorStats,
}

/// The model's standard deviations checked against the errors on the rows (a model that gives
/// them: `predict --sigma`'s).
#[derive(Debug, Clone, Serialize)]
pub struct SigmaCheck {
    /// Mean standard deviation the model gives, mm (root sum of the axes' variances).
    pub mean_sigma: f64,
    /// Root mean square of error / σ over the rows (1 for errors drawn as the model says).
    pub ratio_rms: f64,
    /// Share of the rows whose error lies within σ (61 % for errors drawn as the model says:
    /// an isotropic Gaussian's `P(χ²₃ ≤ 3)`).
    pub within_one: f64,
    /// Share within 2σ (99 %: `P(χ²₃ ≤ 12)`).
    pub within_two: f64,
    /// Spearman rank correlation of σ and the error: whether the poses it is least sure of
    /// are those it misses most.
    pub rank_correlation: f64,
}

/// `statistics.json`: what `report.md` states.
#[derive(Debug, Clone, Serialize)]
pub struct DataReport {
    /// The measurement file.
    pub data: PathBuf,
    /// Held-out or training rows.
    pub role: DataRole,
    /// The model (its directory, or what made it).
    pub model: String,
    /// The model's parts.
    pub parts: Vec<String>,
    /// Rows of the file.
    pub rows: usize,
    /// Distinct pose ids.
    pub configurations: usize,
    /// Distinct loads, kg.
    pub loads: Vec<f64>,
    /// The nominal table, base and tool registered (absent when the model does not carry it).
    pub before: Option<ErrorStats>,
    /// The table and joint errors without the residual model (only when there is one).
    pub kinematic: Option<ErrorStats>,
    /// The whole model.
    pub after: ErrorStats,
    /// Signed error per world axis after calibration.
    pub axes: Vec<AxisStats>,
    /// Mean error per load.
    pub by_load: Vec<LoadStats>,
    /// Mean error per reflector (empty unless rows name targets).
    pub by_target: Vec<TargetStats>,
    /// With a 6-DoF probe's rows: the angle between measured and predicted tool frames, deg,
    /// of the registered nominal table (when the model carries it) and of the model.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub orientation: Option<OrientationStats>,
    /// The model's standard deviations against the errors (a model that gives them).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub sigma: Option<SigmaCheck>,
    /// The five worst rows after calibration.
    pub worst: Vec<WorstRow>,
    /// The figures.
    pub figures: Vec<Figure>,
}

/// The parts of a model, in words.
fn parts(model: &CalibratedModel) -> Vec<String> {
    let mut parts = vec![format!(
        "kinematic table: {} joints (MDH, β on parallel joints, base, tool)",
        model.dof()
    )];
    if let Some(e) = &model.joint_errors {
        let mut blocks = Vec::new();
        if e.values.iter().any(|c| *c != 0.0) {
            blocks.push("payload compliance");
        }
        if !e.harmonics.is_empty() {
            blocks.push("transmission harmonics");
        }
        if !e.self_weight.is_empty() || !e.link_weights.is_empty() {
            blocks.push("self-weight compliance");
        }
        if !e.backlash.is_empty() {
            blocks.push("backlash");
        }
        if !e.tilts.is_empty() {
            blocks.push("tilting compliance");
        }
        if !e.runouts.is_empty() {
            blocks.push("axis runout");
        }
        if !blocks.is_empty() {
            parts.push(format!("joint errors: {}", blocks.join(", ")));
        }
    }
    if let Some(r) = &model.residual {
        parts.push(format!("residual model: {}", r.kind().name()));
    }
    parts
}

/// Mean of `values` (0 for none).
fn mean(values: &[f64]) -> f64 {
    if values.is_empty() {
        0.0
    } else {
        values.iter().sum::<f64>() / values.len() as f64
    }
}

/// Distinct loads of `rows`, ascending.
fn loads(rows: &[&Measurement]) -> Vec<f64> {
    let mut loads: Vec<f64> = rows.iter().map(|m| m.sample.load).collect();
    loads.sort_by(f64::total_cmp);
    loads.dedup();
    loads
}

/// Each row's configuration number, 1-based, in order of the pose id's first appearance.
fn configuration_numbers(rows: &[&Measurement]) -> (Vec<usize>, usize) {
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
fn mean_by_load(rows: &[&Measurement], errors: &[f64]) -> Vec<(f64, f64)> {
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

const AXES: [&str; 3] = ["X", "Y", "Z"];

/// Draws the figures into `dir`; returns them in report order.
fn draw(
    dir: &Path,
    out: &Path,
    rows: &[&Measurement],
    before: Option<&[f64]>,
    kinematic: Option<&[f64]>,
    after: &[f64],
    signed: &[Vector3<f64>],
) -> Result<Vec<Figure>> {
    let mut figures = Vec::new();
    let n = rows.len();
    let before_title = "Before calibration (nominal table, base and tool registered)";

    // Cumulative distributions: before on its own panel, its errors being many times the
    // calibrated ones. A staircase reads the same at 20 rows as at 2000, where a histogram's
    // bins are mostly empty or one row each.
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
            title: format!("{before_title}, {n} rows"),
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
    figures.push(Figure {
        stem: "histogram".into(),
        caption: "Cumulative distribution of the position error (distance between measured and predicted point), before and after calibration: the share of rows at or below each error".into(),
    });

    // Error per pose.
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
            title: before_title.into(),
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
    figures.push(Figure {
        stem: "per-pose".into(),
        caption: "Error of every row against its configuration (every load of a configuration at its number)".into(),
    });

    // Signed error per axis against every joint angle.
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
    figures.push(Figure {
        stem: "axes-joints".into(),
        caption: "Signed error along each world axis after calibration against each joint angle: a trend or a wave here is an effect the model does not hold".into(),
    });

    // Error against load, where the rows hold two or more: one load would draw one stripe on an
    // axis around it.
    if loads(rows).len() >= 2 {
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
                title: before_title.into(),
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
        figures.push(Figure {
            stem: "load".into(),
            caption: "Error against the payload: every row and the mean per load".into(),
        });
    }

    // Error over the workspace.
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
    figures.push(Figure {
        stem: "workspace".into(),
        caption: "Where in the workspace the error after calibration is: every measured point coloured by its error".into(),
    });

    Ok(figures)
}

/// The figure of each row's error against the standard deviation the model gives it.
fn draw_sigma(dir: &Path, out: &Path, after: &[f64], sigmas: &[f64]) -> Result<Figure> {
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

/// Mean errors per target, in order of first appearance (none when no row names a target).
fn by_target(rows: &[&Measurement], before: Option<&[f64]>, after: &[f64]) -> Vec<TargetStats> {
    if rows.iter().all(|m| m.sample.target.is_empty()) {
        return Vec::new();
    }
    let mut names: Vec<&str> = Vec::new();
    for m in rows {
        if !names.contains(&m.sample.target.as_str()) {
            names.push(&m.sample.target);
        }
    }
    names
        .into_iter()
        .map(|name| {
            let at: Vec<usize> = (0..rows.len())
                .filter(|&i| rows[i].sample.target == name)
                .collect();
            let mean_of = |e: &[f64]| mean(&at.iter().map(|&i| e[i]).collect::<Vec<_>>());
            TargetStats {
                target: name.to_string(),
                rows: at.len(),
                before: before.map(mean_of),
                after: mean_of(after),
            }
        })
        .collect()
}

/// Ranks of `v` (0-based; ties share their mean rank).
fn ranks(v: &[f64]) -> Vec<f64> {
    let mut order: Vec<usize> = (0..v.len()).collect();
    order.sort_by(|&a, &b| v[a].total_cmp(&v[b]));
    let mut r = vec![0.0; v.len()];
    let mut i = 0;
    while i < order.len() {
        let mut j = i;
        while j + 1 < order.len() && v[order[j + 1]] == v[order[i]] {
            j += 1;
        }
        for &k in &order[i..=j] {
            r[k] = (i + j) as f64 / 2.0;
        }
        i = j + 1;
    }
    r
}

/// Pearson correlation of the ranks of `a` and `b` (0 where either does not vary).
fn rank_correlation(a: &[f64], b: &[f64]) -> f64 {
    let (ra, rb) = (ranks(a), ranks(b));
    let (ma, mb) = (mean(&ra), mean(&rb));
    let cov: f64 = ra.iter().zip(&rb).map(|(x, y)| (x - ma) * (y - mb)).sum();
    let va: f64 = ra.iter().map(|x| (x - ma).powi(2)).sum();
    let vb: f64 = rb.iter().map(|y| (y - mb).powi(2)).sum();
    if va > 0.0 && vb > 0.0 {
        cov / (va * vb).sqrt()
    } else {
        0.0
    }
}

/// The standard deviations `sigmas` against the errors `after` (rows with a positive σ).
fn sigma_check(after: &[f64], sigmas: &[f64]) -> Option<SigmaCheck> {
    let pairs: Vec<(f64, f64)> = (after.iter().zip(sigmas))
        .filter(|(e, s)| e.is_finite() && s.is_finite() && **s > 0.0)
        .map(|(e, s)| (*e, *s))
        .collect();
    if pairs.is_empty() {
        return None;
    }
    let n = pairs.len() as f64;
    let share = |k: f64| pairs.iter().filter(|(e, s)| *e <= k * s).count() as f64 / n;
    let (errors, sigmas): (Vec<f64>, Vec<f64>) = pairs.iter().copied().unzip();
    Some(SigmaCheck {
        mean_sigma: mean(&sigmas),
        ratio_rms: (pairs.iter().map(|(e, s)| (e / s).powi(2)).sum::<f64>() / n).sqrt(),
        within_one: share(1.0),
        within_two: share(2.0),
        rank_correlation: rank_correlation(&sigmas, &errors),
    })
}

/// Statistics of the signed errors along each axis.
fn axis_stats(signed: &[Vector3<f64>]) -> Vec<AxisStats> {
    (0..3)
        .map(|a| {
            let v: Vec<f64> = signed.iter().map(|e| e[a]).collect();
            let m = mean(&v);
            let var = if v.len() > 1 {
                v.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (v.len() - 1) as f64
            } else {
                0.0
            };
            AxisStats {
                axis: ["x", "y", "z"][a],
                mean: m,
                std: var.sqrt(),
                max_abs: v.iter().fold(0.0, |acc: f64, x| acc.max(x.abs())),
            }
        })
        .collect()
}

/// Writes the report of `model` (called `model_name` in the texts) on `rows` of `data` into the
/// folder `out`, atomically (a complete new folder, or nothing).
pub fn write_data_report(
    model: &CalibratedModel,
    model_name: &str,
    data: &Path,
    rows: &[&Measurement],
    role: DataRole,
    out: &Path,
) -> Result<DataReport> {
    if rows.is_empty() {
        return Err(ReportError::Data(format!(
            "{}: no rows to report on",
            data.display()
        )));
    }
    let signed = model.residuals(rows.iter().copied());
    let after: Vec<f64> = signed.iter().map(|r| r.norm()).collect();
    let before: Option<Vec<f64>> = model
        .nominal
        .as_ref()
        .map(|n| CalibratedModel::kinematic(n.clone()).errors(rows));
    let kinematic: Option<Vec<f64>> = model.residual.is_some().then(|| {
        CalibratedModel {
            residual: None,
            ..model.clone()
        }
        .errors(rows)
    });
    let sigmas = model
        .predict_with_sigma(rows.iter().map(|m| &m.sample), true)
        .1;
    let before_by_load = before.as_ref().map(|b| mean_by_load(rows, b));
    let mut order: Vec<usize> = (0..rows.len()).collect();
    order.sort_by(|&a, &b| after[b].total_cmp(&after[a]));
    let mut report = DataReport {
        data: data.to_path_buf(),
        role,
        model: model_name.to_string(),
        parts: parts(model),
        rows: rows.len(),
        configurations: configuration_numbers(rows).1,
        loads: loads(rows),
        before: before.as_deref().map(ErrorStats::from_errors),
        kinematic: kinematic.as_deref().map(ErrorStats::from_errors),
        after: ErrorStats::from_errors(&after),
        axes: axis_stats(&signed),
        by_load: mean_by_load(rows, &after)
            .into_iter()
            .enumerate()
            .map(|(i, (load, after_mean))| LoadStats {
                load,
                rows: rows.iter().filter(|m| m.sample.load == load).count(),
                before: before_by_load.as_ref().map(|b| b[i].1),
                after: after_mean,
            })
            .collect(),
        by_target: by_target(rows, before.as_deref(), &after),
        orientation: rows
            .iter()
            .any(|m| m.orientation.is_some())
            .then(|| OrientationStats {
                before: (model.nominal.as_ref()).map(|n| {
                    ErrorStats::from_errors(
                        &CalibratedModel::kinematic(n.clone()).orientation_errors(rows),
                    )
                }),
                after: ErrorStats::from_errors(&model.orientation_errors(rows)),
            }),
        sigma: sigmas.as_deref().and_then(|s| sigma_check(&after, s)),
        worst: order
            .iter()
            .take(5)
            .map(|&i| WorstRow {
                line: rows[i].sample.line,
                pose: rows[i].sample.pose.clone(),
                load: rows[i].sample.load,
                error: after[i],
            })
            .collect(),
        figures: Vec::new(),
    };
    write_dir_atomically(out, |dir| -> Result<()> {
        report.figures = draw(
            dir,
            out,
            rows,
            before.as_deref(),
            kinematic.as_deref(),
            &after,
            &signed,
        )?;
        if let Some(sigmas) = sigmas.as_deref() {
            report.figures.push(draw_sigma(dir, out, &after, sigmas)?);
        }
        let json = serde_json::to_string_pretty(&report)
            .map_err(|e| ReportError::Data(format!("statistics.json: {e}")))?;
        write_text_in(dir, out, "statistics.json", &(json + "\n"))?;
        write_text_in(dir, out, "report.md", &markdown(&report))?;
        let html = html(&report, dir).map_err(|(file, e)| ReportError::Read {
            path: out.join(file),
            source: e,
        })?;
        write_text_in(dir, out, "report.html", &html)?;
        Ok(())
    })?;
    Ok(report)
}

/// The statistics table: (row name, stats).
fn stats_rows(r: &DataReport) -> Vec<(&'static str, &ErrorStats)> {
    let mut rows = Vec::new();
    if let Some(b) = &r.before {
        rows.push(("before (nominal, base and tool registered)", b));
    }
    if let Some(k) = &r.kinematic {
        rows.push(("after: table + joint errors (no residual)", k));
    }
    rows.push(("after: the whole model", &r.after));
    rows
}

/// A statistics table: per named row count, mean, std, RMS and max (4 decimals).
fn stats_table(rows: Vec<(&str, &ErrorStats)>) -> Table {
    let f = |v: f64| format!("{v:.4}");
    Table {
        header: ["", "count", "mean", "std", "RMS", "max"]
            .map(String::from)
            .to_vec(),
        rows: rows
            .into_iter()
            .map(|(name, s)| {
                vec![
                    name.to_string(),
                    s.count.to_string(),
                    f(s.mean),
                    f(s.std),
                    f(s.rms),
                    f(s.max),
                ]
            })
            .collect(),
    }
}

/// A plain table: header and rows of cells.
struct Table {
    header: Vec<String>,
    rows: Vec<Vec<String>>,
}

/// The report's text: (heading, paragraphs, tables), then the figures.
fn sections(r: &DataReport) -> Vec<(String, Vec<String>, Vec<Table>)> {
    let loads: Vec<String> = r.loads.iter().map(|l| format!("{l}")).collect();
    let mut about = vec![
        format!(
            "Data: `{}`, {} rows, {} configurations, loads {} kg; {}.",
            r.data.display(),
            r.rows,
            r.configurations,
            loads.join(", "),
            r.role.describe()
        ),
        format!("Model: `{}`: {}.", r.model, r.parts.join("; ")),
    ];
    if r.before.is_none() {
        about.push("The model carries no registered nominal table (`nominal.toml`, written by `calibrate` since robocal 0.1): shown after calibration only.".into());
    }
    let f = |v: f64| format!("{v:.4}");
    let stats = stats_table(stats_rows(r));
    let axes = Table {
        header: ["axis", "mean signed", "std", "max |error|"]
            .map(String::from)
            .to_vec(),
        rows: r
            .axes
            .iter()
            .map(|a| vec![a.axis.to_string(), f(a.mean), f(a.std), f(a.max_abs)])
            .collect(),
    };
    let by_load = Table {
        header: ["load (kg)", "rows", "mean before", "mean after"]
            .map(String::from)
            .to_vec(),
        rows: r
            .by_load
            .iter()
            .map(|l| {
                vec![
                    format!("{}", l.load),
                    l.rows.to_string(),
                    l.before.map_or("–".into(), f),
                    f(l.after),
                ]
            })
            .collect(),
    };
    let worst = Table {
        header: ["line", "pose", "load (kg)", "error after"]
            .map(String::from)
            .to_vec(),
        rows: r
            .worst
            .iter()
            .map(|w| {
                vec![
                    w.line.to_string(),
                    w.pose.clone(),
                    format!("{}", w.load),
                    f(w.error),
                ]
            })
            .collect(),
    };
    let mut by_reflector = Vec::new();
    if !r.by_target.is_empty() {
        by_reflector.push(Table {
            header: ["target", "rows", "mean before", "mean after"]
                .map(String::from)
                .to_vec(),
            rows: (r.by_target.iter())
                .map(|t| {
                    vec![
                        if t.target.is_empty() {
                            "(default point)".into()
                        } else {
                            t.target.clone()
                        },
                        t.rows.to_string(),
                        t.before.map_or("–".into(), f),
                        f(t.after),
                    ]
                })
                .collect(),
        });
    }
    let mut orientation = Vec::new();
    if let Some(o) = &r.orientation {
        let mut rows = Vec::new();
        if let Some(b) = &o.before {
            rows.push(("before (nominal, base and tool registered)", b));
        }
        rows.push(("after: table + joint errors", &o.after));
        orientation.push(stats_table(rows));
    }
    vec![
        ("What was measured".into(), about, Vec::new()),
        (
            "Position error (mm)".into(),
            vec!["Distance between the measured and the predicted point, world (tracker) frame.".into()],
            vec![stats],
        ),
        (
            "Per axis after calibration (mm, measured − predicted)".into(),
            vec!["A mean far from zero is a bias the model leaves (a frame or unit problem, or a missing effect).".into()],
            vec![axes],
        ),
        (
            "Orientation error (deg)".into(),
            if orientation.is_empty() {
                Vec::new()
            } else {
                vec!["Angle between the 6-DoF probe's measured tool frame and the predicted one.".into()]
            },
            orientation,
        ),
        (
            "How sure the model is".into(),
            sigma_paragraphs(r),
            sigma_table(r),
        ),
        ("Per load (mm)".into(), Vec::new(), vec![by_load]),
        ("Per reflector (mm)".into(), Vec::new(), by_reflector),
        ("The worst rows after calibration (mm)".into(), Vec::new(), vec![worst]),
    ]
}

/// The σ check's text (none for a model that gives no standard deviation).
fn sigma_paragraphs(r: &DataReport) -> Vec<String> {
    if r.sigma.is_none() {
        return Vec::new();
    }
    vec!["The standard deviation the model gives each row (`predict --sigma`: a GP's, scaled as its folds found; a network's, the physics' with the spread its folds found beside it; a physical model's, from its parameters' covariance) against the row's error. For errors drawn as the model says, the root mean square of error/σ is 1, 61 % of the rows lie within σ and 99 % within 2σ. The errors here are from the measured points, which carry the tracker's noise and the arm's repeatability besides the model's error: a physical model's or a GP's σ leaves those out, so on rows predicted to the noise the ratio lies above 1 by them. A ratio well above 1 says the model is surer than it should be: read its σ as a floor.".into()]
}

/// The σ check's table.
fn sigma_table(r: &DataReport) -> Vec<Table> {
    let Some(c) = &r.sigma else {
        return Vec::new();
    };
    vec![Table {
        header: [
            "mean σ (mm)",
            "RMS of error/σ",
            "within σ",
            "within 2σ",
            "rank correlation of σ and error",
        ]
        .map(String::from)
        .to_vec(),
        rows: vec![vec![
            format!("{:.4}", c.mean_sigma),
            format!("{:.2}", c.ratio_rms),
            format!("{:.0} %", 100.0 * c.within_one),
            format!("{:.0} %", 100.0 * c.within_two),
            format!("{:.2}", c.rank_correlation),
        ]],
    }]
}

fn markdown(r: &DataReport) -> String {
    let mut s = format!(
        "# Calibration report: {}\n\nWritten by robocal {}. Lengths mm, angles deg, loads kg.\n",
        r.data.display(),
        env!("CARGO_PKG_VERSION")
    );
    for (heading, paragraphs, tables) in sections(r) {
        if paragraphs.is_empty() && tables.is_empty() {
            continue;
        }
        let _ = write!(s, "\n## {heading}\n\n");
        for p in paragraphs {
            let _ = write!(s, "{p}\n\n");
        }
        for t in tables {
            let _ = writeln!(s, "| {} |", t.header.join(" | "));
            let _ = writeln!(s, "|{}", "---|".repeat(t.header.len()));
            for row in t.rows {
                let _ = writeln!(s, "| {} |", row.join(" | "));
            }
            s.push('\n');
        }
    }
    s.push_str("## Figures\n\nEach as PNG and SVG beside this file.\n\n");
    for fig in &r.figures {
        let _ = write!(
            s,
            "### {}\n\n![{}]({}.png)\n\n",
            fig.caption, fig.caption, fig.stem
        );
    }
    s
}

/// Text for HTML.
fn escape(text: &str) -> String {
    text.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
}

/// HTML of a paragraph: `code` spans as `<code>`.
fn paragraph(text: &str) -> String {
    let mut out = String::new();
    for (i, part) in escape(text).split('`').enumerate() {
        if i % 2 == 1 {
            let _ = write!(out, "<code>{part}</code>");
        } else {
            out.push_str(part);
        }
    }
    out
}

/// One self-contained page: the text, the tables and every SVG inline (read from `dir`).
fn html(r: &DataReport, dir: &Path) -> std::result::Result<String, (String, std::io::Error)> {
    let title = format!("Calibration report: {}", r.data.display());
    let mut s = format!(
        "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n<title>{}</title>\n<style>\nbody {{ font-family: sans-serif; max-width: 1900px; margin: 2em auto; padding: 0 1em; }}\ntable {{ border-collapse: collapse; margin: 0.5em 0 1.5em; }}\nth, td {{ border: 1px solid #bbb; padding: 0.25em 0.7em; text-align: right; }}\nth:first-child, td:first-child {{ text-align: left; }}\nfigure {{ margin: 1em 0 2.5em; }}\nfigure svg {{ max-width: 100%; height: auto; }}\n</style>\n</head>\n<body>\n<h1>{}</h1>\n<p>Written by robocal {}. Lengths mm, angles deg, loads kg.</p>\n",
        escape(&title),
        escape(&title),
        env!("CARGO_PKG_VERSION")
    );
    for (heading, paragraphs, tables) in sections(r) {
        if paragraphs.is_empty() && tables.is_empty() {
            continue;
        }
        let _ = writeln!(s, "<h2>{}</h2>", escape(&heading));
        for p in paragraphs {
            let _ = writeln!(s, "<p>{}</p>", paragraph(&p));
        }
        for t in tables {
            s.push_str("<table>\n<tr>");
            for h in &t.header {
                let _ = write!(s, "<th>{}</th>", escape(h));
            }
            s.push_str("</tr>\n");
            for row in &t.rows {
                s.push_str("<tr>");
                for c in row {
                    let _ = write!(s, "<td>{}</td>", escape(c));
                }
                s.push_str("</tr>\n");
            }
            s.push_str("</table>\n");
        }
    }
    s.push_str("<h2>Figures</h2>\n");
    for fig in &r.figures {
        let file = format!("{}.svg", fig.stem);
        let svg = std::fs::read_to_string(dir.join(&file)).map_err(|e| (file, e))?;
        // The SVG's own XML declaration does not belong inside HTML.
        let svg = match svg.find("<svg") {
            Some(at) => &svg[at..],
            None => svg.as_str(),
        };
        let _ = write!(
            s,
            "<figure>\n<figcaption><h3>{}</h3></figcaption>\n{}\n</figure>\n",
            escape(&fig.caption),
            svg.trim_end()
        );
    }
    s.push_str("</body>\n</html>\n");
    Ok(s)
}

#[cfg(test)]
mod tests {
    use super::*;
    use robocal_data::Sample;
    use robocal_robot::Robot;

    /// Errors drawn as the deviations say (isotropic, three axes): the check's shares near the
    /// χ²₃ values it states; a ranking by hand; σ of none is no check.
    #[test]
    fn the_sigma_check_states_what_errors_drawn_as_sigma_says_give() {
        use rand::SeedableRng;
        use rand_distr::{Distribution, Normal};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let unit = Normal::new(0.0, 1.0).unwrap();
        let sigmas: Vec<f64> = (0..20000)
            .map(|i| 0.01 + 0.0001 * (i % 100) as f64)
            .collect();
        let errors: Vec<f64> = (sigmas.iter())
            .map(|s| {
                let v: f64 = (0..3).map(|_| f64::powi(unit.sample(&mut rng), 2)).sum();
                s * (v / 3.0).sqrt()
            })
            .collect();
        let c = sigma_check(&errors, &sigmas).unwrap();
        assert!((c.ratio_rms - 1.0).abs() < 0.02, "{c:?}");
        assert!((c.within_one - 0.608).abs() < 0.01, "{c:?}");
        assert!((c.within_two - 0.9926).abs() < 0.003, "{c:?}");
        assert!(
            c.rank_correlation > 0.1 && c.rank_correlation < 0.6,
            "{c:?}"
        );
        // Ranks with a tie, and correlations of ±1.
        assert_eq!(ranks(&[3.0, 1.0, 3.0, 2.0]), vec![2.5, 0.0, 2.5, 1.0]);
        let up = [0.1, 0.2, 0.5, 0.9];
        assert!((rank_correlation(&up, &[1.0, 2.0, 3.0, 40.0]) - 1.0).abs() < 1e-12);
        assert!((rank_correlation(&up, &[4.0, 3.0, 2.0, 1.0]) + 1.0).abs() < 1e-12);
        let c = sigma_check(&[0.1, 0.3], &[0.2, 0.1]).unwrap();
        assert_eq!((c.within_one, c.within_two), (0.5, 0.5));
        assert!((c.ratio_rms - ((0.25f64 + 9.0) / 2.0).sqrt()).abs() < 1e-12);
        assert!(sigma_check(&[0.1], &[0.0]).is_none());
    }

    fn rows(robot: &Robot) -> Vec<Measurement> {
        (0..12)
            .flat_map(|i| {
                let joints: Vec<f64> = (0..robot.dof())
                    .map(|j| 10.0 * ((i * 7 + j * 3) % 9) as f64 - 40.0)
                    .collect();
                [0.0, 5.0].map(|load| {
                    let q: Vec<f64> = joints.iter().map(|d| d.to_radians()).collect();
                    Measurement {
                        position: robot.point(&q) + Vector3::new(0.1 * i as f64, 0.0, 0.02),
                        orientation: None,
                        sample: Sample {
                            pose: format!("p{i}"),
                            joints: joints.clone(),
                            load,
                            line: 2 + i as u64,
                            target: String::new(),
                        },
                    }
                })
            })
            .collect()
    }

    /// The model's parts name the payload compliance only where a joint has one: a model whose
    /// compliance stage was skipped (one load) holds joint errors without it.
    #[test]
    fn the_parts_name_the_payload_compliance_only_where_a_joint_has_one() {
        let robot = Robot::load(
            Path::new(env!("CARGO_MANIFEST_DIR")).join("../../configs/robots/pmc6va030.toml"),
        )
        .unwrap();
        let mut model = CalibratedModel::kinematic(robot);
        let mut errors = robocal_robot::JointErrors::new(
            vec![0.0; 6],
            Vector3::new(0.0, 0.0, -9.80665),
            Vector3::zeros(),
        );
        errors.harmonics.push(robocal_robot::Harmonic::zero(0, 1));
        model.joint_errors = Some(errors.clone());
        assert_eq!(parts(&model)[1], "joint errors: transmission harmonics");
        errors.values[1] = 1e-6;
        model.joint_errors = Some(errors);
        assert_eq!(
            parts(&model)[1],
            "joint errors: payload compliance, transmission harmonics"
        );
    }

    #[test]
    fn a_model_without_its_nominal_table_is_reported_after_calibration_only() {
        let robot = Robot::load(
            Path::new(env!("CARGO_MANIFEST_DIR")).join("../../configs/robots/pmc6va030.toml"),
        )
        .unwrap();
        let rows = rows(&robot);
        let refs: Vec<&Measurement> = rows.iter().collect();
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("r");
        let model = CalibratedModel::kinematic(robot);
        let r = write_data_report(
            &model,
            "m",
            Path::new("d.csv"),
            &refs,
            DataRole::HeldOut,
            &out,
        )
        .unwrap();
        assert!(r.before.is_none() && r.kinematic.is_none());
        assert_eq!(
            (r.rows, r.configurations, r.loads.clone()),
            (24, 12, vec![0.0, 5.0])
        );
        // The offsets put in: x grows with the pose, z is a constant bias of 0.02.
        assert!((r.axes[2].mean - 0.02).abs() < 1e-9 && r.axes[2].std < 1e-9);
        assert!((r.worst[0].error - (1.1f64.powi(2) + 0.02f64.powi(2)).sqrt()).abs() < 1e-9);
        assert_eq!(r.figures.len(), 5);
        assert!(r.figures.iter().any(|f| f.stem == "load"));
        // The same rows at one load: no figure against the load (one stripe on an axis around it).
        let light: Vec<&Measurement> = rows.iter().filter(|m| m.sample.load == 0.0).collect();
        let one = dir.path().join("one");
        let r1 = write_data_report(
            &model,
            "m",
            Path::new("d.csv"),
            &light,
            DataRole::HeldOut,
            &one,
        )
        .unwrap();
        let stems: Vec<&str> = r1.figures.iter().map(|f| f.stem.as_str()).collect();
        assert_eq!(stems, ["histogram", "per-pose", "axes-joints", "workspace"]);
        assert!(!one.join("load.png").exists());
        let md = std::fs::read_to_string(out.join("report.md")).unwrap();
        assert!(md.contains("shown after calibration only"), "{md}");
        assert!(
            r.by_target.is_empty() && !md.contains("Per reflector"),
            "{md}"
        );
        // Nothing is written for no rows.
        let empty = dir.path().join("e");
        assert!(
            write_data_report(
                &model,
                "m",
                Path::new("d.csv"),
                &[],
                DataRole::HeldOut,
                &empty
            )
            .is_err()
        );
        assert!(!empty.exists());
    }
}
