//! The report's figures, drawn with plotters as PNG and SVG: per-configuration errors (the
//! paper's Figs. 11–12), error against load (Fig. 13), per-axis error distributions (Figs. 14, 16,
//! 21) and the histogram comparison of every stage (Fig. 26).
//!
//! Text is drawn with DejaVu Sans, shipped in `assets/` (its licence beside it), so the plots do
//! not depend on the fonts of the machine.

use std::error::Error;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use nalgebra::Vector3;
use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::{FontStyle, register_font};

use crate::error::{PipelineError, Result};
use crate::run::Outcome;

const FONT: &[u8] = include_bytes!("../assets/DejaVuSans.ttf");
const SIZE: (u32, u32) = (1000, 600);
const WIDE: (u32, u32) = (1500, 500);

/// Registers the shipped font once.
fn font() -> std::result::Result<(), String> {
    static DONE: OnceLock<std::result::Result<(), String>> = OnceLock::new();
    DONE.get_or_init(|| {
        register_font("sans-serif", FontStyle::Normal, FONT)
            .map_err(|_| "the shipped font does not load".to_string())
    })
    .clone()
}

/// A colour per series, in order.
fn colour(i: usize) -> RGBColor {
    const P: [RGBColor; 8] = [
        RGBColor(0x44, 0x44, 0x44),
        RGBColor(0x1f, 0x77, 0xb4),
        RGBColor(0xd6, 0x27, 0x28),
        RGBColor(0x2c, 0xa0, 0x2c),
        RGBColor(0xff, 0x7f, 0x0e),
        RGBColor(0x94, 0x67, 0xbd),
        RGBColor(0x8c, 0x56, 0x4b),
        RGBColor(0x17, 0xbe, 0xcf),
    ];
    P[i % P.len()]
}

/// Named (x, y) points.
struct Series {
    name: String,
    points: Vec<(f64, f64)>,
    markers: bool,
}

/// One panel of lines.
struct Panel {
    title: String,
    x_label: String,
    y_label: String,
    series: Vec<Series>,
}

type Drawn = std::result::Result<(), Box<dyn Error>>;

fn range(values: impl Iterator<Item = f64>, from_zero: bool) -> (f64, f64) {
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for v in values.filter(|v| v.is_finite()) {
        lo = lo.min(v);
        hi = hi.max(v);
    }
    if !lo.is_finite() {
        return (0.0, 1.0);
    }
    if from_zero {
        lo = lo.min(0.0);
    }
    let pad = ((hi - lo) * 0.05).max(1e-9);
    (
        if from_zero && lo == 0.0 {
            0.0
        } else {
            lo - pad
        },
        hi + pad,
    )
}

fn draw_panel<DB: DrawingBackend>(area: &DrawingArea<DB, Shift>, panel: &Panel) -> Drawn
where
    DB::ErrorType: 'static,
{
    let (x0, x1) = range(
        panel
            .series
            .iter()
            .flat_map(|s| s.points.iter().map(|p| p.0)),
        false,
    );
    let (y0, y1) = range(
        panel
            .series
            .iter()
            .flat_map(|s| s.points.iter().map(|p| p.1)),
        true,
    );
    let mut chart = ChartBuilder::on(area)
        .caption(&panel.title, ("sans-serif", 20))
        .margin(12)
        .x_label_area_size(45)
        .y_label_area_size(60)
        .build_cartesian_2d(x0..x1, y0..y1)?;
    chart
        .configure_mesh()
        .x_desc(panel.x_label.as_str())
        .y_desc(panel.y_label.as_str())
        .label_style(("sans-serif", 14))
        .axis_desc_style(("sans-serif", 15))
        .draw()?;
    for (i, s) in panel.series.iter().enumerate() {
        let c = colour(i);
        chart
            .draw_series(LineSeries::new(s.points.iter().copied(), c.stroke_width(2)))?
            .label(s.name.as_str())
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], c.stroke_width(2)));
        if s.markers {
            chart.draw_series(s.points.iter().map(|&p| Circle::new(p, 3, c.filled())))?;
        }
    }
    chart
        .configure_series_labels()
        .label_font(("sans-serif", 14))
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .position(SeriesLabelPosition::UpperRight)
        .draw()?;
    Ok(())
}

fn draw_panels<DB: DrawingBackend>(root: DrawingArea<DB, Shift>, panels: &[Panel]) -> Drawn
where
    DB::ErrorType: 'static,
{
    root.fill(&WHITE)?;
    let areas = root.split_evenly((1, panels.len()));
    for (area, panel) in areas.iter().zip(panels) {
        draw_panel(area, panel)?;
    }
    root.present()?;
    Ok(())
}

/// Draws `panels` side by side into `<dir>/<stem>.png` and `.svg`; returns the file names.
fn figure(
    dir: &Path,
    out: &Path,
    stem: &str,
    size: (u32, u32),
    panels: &[Panel],
) -> Result<Vec<String>> {
    let fail = |name: &str, message: String| PipelineError::Plot {
        path: out.join(name),
        message,
    };
    font().map_err(|m| fail(stem, m))?;
    let png = format!("{stem}.png");
    let svg = format!("{stem}.svg");
    draw_panels(
        BitMapBackend::new(&dir.join(&png), size).into_drawing_area(),
        panels,
    )
    .map_err(|e| fail(&png, e.to_string()))?;
    draw_panels(
        SVGBackend::new(&dir.join(&svg), size).into_drawing_area(),
        panels,
    )
    .map_err(|e| fail(&svg, e.to_string()))?;
    Ok(vec![png, svg])
}

/// Frequency polygon of `values` over `bins` equal bins on [lo, hi]: (bin centre, share of the
/// values in the bin, %).
pub fn histogram(values: &[f64], lo: f64, hi: f64, bins: usize) -> Vec<(f64, f64)> {
    let width = (hi - lo) / bins as f64;
    let mut counts = vec![0usize; bins];
    for &v in values.iter().filter(|v| v.is_finite()) {
        let b = (((v - lo) / width).floor() as isize).clamp(0, bins as isize - 1) as usize;
        counts[b] += 1;
    }
    let n = values.len().max(1) as f64;
    counts
        .iter()
        .enumerate()
        .map(|(b, &c)| (lo + (b as f64 + 0.5) * width, 100.0 * c as f64 / n))
        .collect()
}

/// Histograms of several named value lists over one common range.
fn histograms(named: &[(String, Vec<f64>)], bins: usize, from_zero: bool) -> Vec<Series> {
    let (lo, hi) = range(named.iter().flat_map(|(_, v)| v.iter().copied()), from_zero);
    named
        .iter()
        .map(|(name, v)| Series {
            name: name.clone(),
            points: histogram(v, lo, hi, bins),
            markers: false,
        })
        .collect()
}

/// A file-name slug of a model name.
pub fn slug(name: &str) -> String {
    let mut s = String::new();
    for c in name.chars() {
        if c.is_ascii_alphanumeric() {
            s.push(c.to_ascii_lowercase());
        } else if !s.ends_with('-') {
            s.push('-');
        }
    }
    s.trim_matches('-').to_string()
}

/// Draws every figure into `dir` (the report's temporary folder; `out` is where it will be, for
/// error messages). Returns (what it shows, file names).
pub fn draw_all(o: &Outcome, dir: &Path, out: &Path) -> Result<Vec<(String, Vec<String>)>> {
    let mut made = Vec::new();
    let norms = |e: &[Vector3<f64>], rows: &[usize]| {
        rows.iter().map(|&i| e[i].norm()).collect::<Vec<f64>>()
    };

    // Figs. 11–12: per configuration at the kinematic load, trained then untrained.
    let rows: Vec<usize> = o
        .splits
        .kinematic_rows
        .iter()
        .chain(&o.splits.kinematic_held_out_rows)
        .copied()
        .collect();
    let n_fit = o.splits.kinematic_rows.len();
    let mut series = vec![Series {
        name: "before (nominal, base+tool fitted)".into(),
        points: rows
            .iter()
            .enumerate()
            .map(|(k, &i)| ((k + 1) as f64, o.before[i].norm()))
            .collect(),
        markers: false,
    }];
    for k in &o.kinematics {
        let points = |range: std::ops::Range<usize>| -> Vec<(f64, f64)> {
            range
                .map(|k2| ((k2 + 1) as f64, k.errors[rows[k2]].norm()))
                .collect()
        };
        series.push(Series {
            name: format!("after {} (fitted)", k.label),
            points: points(0..n_fit),
            markers: true,
        });
        series.push(Series {
            name: format!("after {} (held out)", k.label),
            points: points(n_fit..rows.len()),
            markers: true,
        });
    }
    let load = o.splits.kinematic_load;
    let stem = "fig11-12-configurations";
    made.push((
        format!("Figs. 11–12: error per configuration at {load} kg, before and after kinematic calibration; configurations 1–{n_fit} fitted, the rest held out (cross-validation)"),
        figure(dir, out, stem, SIZE, &[Panel {
            title: format!("Error per configuration at {load} kg"),
            x_label: format!("configuration (1–{n_fit} fitted, {}–{} held out)", n_fit + 1, rows.len()),
            y_label: "error (mm)".into(),
            series,
        }])?,
    ));

    // Fig. 13: mean error against load, untrained configurations.
    let mut series = vec![Series {
        name: "before".into(),
        points: o.mean_by_load(&o.before),
        markers: true,
    }];
    for m in &o.models {
        series.push(Series {
            name: m.name.clone(),
            points: o.mean_by_load(&m.errors),
            markers: true,
        });
    }
    made.push((
        "Fig. 13: mean error against load over the untrained configurations, before and after each model".into(),
        figure(dir, out, "fig13-load", SIZE, &[Panel {
            title: "Mean error against load (untrained configurations)".into(),
            x_label: "load (kg)".into(),
            y_label: "mean error (mm)".into(),
            series,
        }])?,
    ));

    // Figs. 14, 16, 21: per-axis distributions on the Table 6 rows.
    let t6 = o.rows("table6");
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

    // Figs. 22–25: the bimodal X error of each CA-SOMM model's gate classes, before and after.
    for m in &o.models {
        let Some(classes) = o.gate_classes(m, &t6) else {
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

    // Fig. 26: every stage's error distribution on the Table 6 rows.
    let mut named = vec![("before".to_string(), norms(&o.before, &t6))];
    for m in &o.models {
        named.push((m.name.clone(), norms(&m.errors, &t6)));
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
            SIZE,
            &[Panel {
                title: "Error distribution of every stage (GB10 + GB30)".into(),
                x_label: "error (mm)".into(),
                y_label: "share of rows (%)".into(),
                series: histograms(&named, 60, true),
            }],
        )?,
    ));
    Ok(made)
}

/// The report folder of an experiment: `<output>/<name>`.
pub fn report_dir(output: &Path, name: &str) -> PathBuf {
    output.join(name)
}
