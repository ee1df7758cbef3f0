//! Figures drawn with plotters as PNG and SVG: panels of lines, markers and histograms side by
//! side or in a grid, and panels of points coloured by a value, each series in a style of its own
//! with a legend.
//!
//! Text is drawn with DejaVu Sans, shipped in `assets/` (its licence beside it), so the plots do
//! not depend on the fonts of the machine.

use std::error::Error;
use std::path::Path;
use std::sync::OnceLock;

use plotters::coord::Shift;
use plotters::coord::types::RangedCoordf64;
use plotters::prelude::*;
use plotters::style::colors::colormaps::{ColorMap, ViridisRGB};
use plotters::style::{FontStyle, register_font};

use crate::error::{ReportError, Result};

const FONT: &[u8] = include_bytes!("../assets/DejaVuSans.ttf");
/// The size (pixels) of a figure of two panels side by side.
pub const TWO: (u32, u32) = (1700, 600);
/// The size (pixels) of a figure of three panels side by side.
pub const WIDE: (u32, u32) = (1840, 500);

/// Registers the shipped font once.
fn font() -> std::result::Result<(), String> {
    static DONE: OnceLock<std::result::Result<(), String>> = OnceLock::new();
    DONE.get_or_init(|| {
        register_font("sans-serif", FontStyle::Normal, FONT)
            .map_err(|_| "the shipped font does not load".to_string())
    })
    .clone()
}

/// The Okabe–Ito palette: eight colours told apart with every common colour-vision deficiency.
const PALETTE: [RGBColor; 8] = [
    RGBColor(0x00, 0x00, 0x00),
    RGBColor(0xe6, 0x9f, 0x00),
    RGBColor(0x56, 0xb4, 0xe9),
    RGBColor(0x00, 0x9e, 0x73),
    RGBColor(0xd5, 0x5e, 0x00),
    RGBColor(0x00, 0x72, 0xb2),
    RGBColor(0xcc, 0x79, 0xa7),
    RGBColor(0x99, 0x99, 0x99),
];

/// A marker shape.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Marker {
    Circle,
    Triangle,
    Cross,
    Square,
}

/// How a series is drawn: colour, line (solid or dashed) and marker. [`style`] gives every
/// series of a figure its own.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Style {
    colour: RGBColor,
    dashed: bool,
    marker: Marker,
}

/// Series a figure may hold, each with a style of its own.
const MAX_SERIES: usize = PALETTE.len() * 4;

/// The style of the `i`-th series of a figure: the palette's colours in order, solid lines
/// with circles, then dashed with triangles, solid with crosses, dashed with squares; no two
/// of the first [`MAX_SERIES`] alike.
fn style(i: usize) -> Style {
    let round = (i / PALETTE.len()) % 4;
    Style {
        colour: PALETTE[i % PALETTE.len()],
        dashed: round % 2 == 1,
        marker: [
            Marker::Circle,
            Marker::Triangle,
            Marker::Cross,
            Marker::Square,
        ][round],
    }
}

/// How a series' points are drawn.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Draw {
    /// A line, with a marker every few points (a histogram).
    Line,
    /// A line with a marker on every point.
    Marked,
    /// Markers alone (a scatter).
    Points,
    /// A line alone, no markers (a cumulative distribution, a reference line): nothing on it
    /// that could be read as a data point.
    Curve,
}

/// Named (x, y) points.
pub struct Series {
    /// Its name in the legend.
    pub name: String,
    /// Its points.
    pub points: Vec<(f64, f64)>,
    /// How they are drawn.
    pub draw: Draw,
}

/// One panel of lines.
pub struct Panel {
    /// Its title.
    pub title: String,
    /// The x axis' label.
    pub x_label: String,
    /// The y axis' label.
    pub y_label: String,
    /// Its series.
    pub series: Vec<Series>,
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
    // A single value (one load) gets a range around it rather than a zero-width axis.
    let pad = if hi - lo > 1e-12 {
        (hi - lo) * 0.05
    } else {
        (hi.abs() * 0.05).max(1.0)
    };
    (
        if from_zero && lo == 0.0 {
            0.0
        } else {
            lo - pad
        },
        hi + pad,
    )
}

/// Tick labels on an axis `width` pixels long: about one per 80 pixels, 3 to 10.
fn ticks(width: u32) -> usize {
    (width as usize / 80).clamp(3, 10)
}

/// A tick label: the value with at most four decimals, trailing zeros dropped (`2`, `0.25`).
fn tick(v: &f64) -> String {
    let s = format!("{v:.4}");
    let s = s.trim_end_matches('0').trim_end_matches('.');
    if s == "-0" { "0".into() } else { s.into() }
}

/// Width of the legend column at the right of a figure, pixels.
const LEGEND_W: u32 = 340;

/// A panel's axes: its title, labelled axes over `ranges` (tick labels sized to the panel,
/// trailing zeros dropped), `label_width` pixels for the y labels.
fn axes<'a, DB: DrawingBackend>(
    area: &'a DrawingArea<DB, Shift>,
    title: &str,
    (x_label, y_label): (&str, &str),
    (x, y): (std::ops::Range<f64>, std::ops::Range<f64>),
    label_width: u32,
) -> std::result::Result<
    ChartContext<'a, DB, Cartesian2d<RangedCoordf64, RangedCoordf64>>,
    Box<dyn Error>,
>
where
    DB::ErrorType: 'static,
{
    let mut chart = ChartBuilder::on(area)
        .caption(title, ("sans-serif", 18))
        .margin(12)
        .x_label_area_size(45)
        .y_label_area_size(label_width)
        .build_cartesian_2d(x, y)?;
    chart
        .configure_mesh()
        .x_labels(ticks(area.dim_in_pixel().0))
        .x_label_formatter(&tick)
        .y_label_formatter(&tick)
        .x_desc(x_label)
        .y_desc(y_label)
        .label_style(("sans-serif", 14))
        .axis_desc_style(("sans-serif", 15))
        .draw()?;
    Ok(chart)
}

fn draw_panel<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    panel: &Panel,
    style_of: &dyn Fn(&str) -> Style,
) -> Drawn
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
    let mut chart = axes(
        area,
        &panel.title,
        (&panel.x_label, &panel.y_label),
        (x0..x1, y0..y1),
        60,
    )?;
    for s in &panel.series {
        let st = style_of(&s.name);
        let c = st.colour;
        let points = s.points.iter().copied();
        if s.draw != Draw::Points {
            if st.dashed {
                chart.draw_series(DashedLineSeries::new(points, 8, 5, c.stroke_width(2)))?;
            } else {
                chart.draw_series(LineSeries::new(points, c.stroke_width(2)))?;
            }
        }
        if s.draw == Draw::Curve {
            continue;
        }
        // Markers on every point of a short series, on every few of a long one (a histogram):
        // the shape tells series apart where colours alone would not.
        let every = if s.draw == Draw::Line {
            (s.points.len() / 12).max(1)
        } else {
            1
        };
        let at = s.points.iter().copied().step_by(every);
        // A scatter's markers are small: many points, and the shape still reads.
        let r = if s.draw == Draw::Points { 3 } else { 4 };
        match st.marker {
            Marker::Circle => chart.draw_series(at.map(|p| Circle::new(p, r, c.filled())))?,
            Marker::Triangle => {
                chart.draw_series(at.map(|p| TriangleMarker::new(p, r + 1, c.filled())))?
            }
            Marker::Cross => chart.draw_series(at.map(|p| Cross::new(p, r, c.stroke_width(2))))?,
            Marker::Square => {
                chart.draw_series(at.map(|p| {
                    EmptyElement::at(p) + Rectangle::new([(-3, -3), (3, 3)], c.filled())
                }))?
            }
        };
    }
    Ok(())
}

/// The legend column: one line per series name, drawn as its series is (a line for a line, a
/// marker for markers, both for a marked line), beside the panels so that it never covers data.
fn draw_legend<DB: DrawingBackend>(area: &DrawingArea<DB, Shift>, names: &[(String, Draw)]) -> Drawn
where
    DB::ErrorType: 'static,
{
    let font = ("sans-serif", 13).into_font();
    for (i, (name, draw)) in names.iter().enumerate() {
        let st = style(i);
        let c = st.colour;
        let y = 40 + 22 * i as i32;
        if *draw != Draw::Points {
            if st.dashed {
                area.draw(&PathElement::new(vec![(8, y), (17, y)], c.stroke_width(2)))?;
                area.draw(&PathElement::new(vec![(25, y), (34, y)], c.stroke_width(2)))?;
            } else {
                area.draw(&PathElement::new(vec![(8, y), (34, y)], c.stroke_width(2)))?;
            }
        }
        if *draw != Draw::Curve {
            match st.marker {
                Marker::Circle => area.draw(&Circle::new((21, y), 4, c.filled()))?,
                Marker::Triangle => area.draw(&TriangleMarker::new((21, y), 5, c.filled()))?,
                Marker::Cross => area.draw(&Cross::new((21, y), 4, c.stroke_width(2)))?,
                Marker::Square => {
                    area.draw(&Rectangle::new([(18, y - 3), (24, y + 3)], c.filled()))?
                }
            }
        }
        area.draw(&Text::new(name.clone(), (42, y - 7), font.clone()))?;
    }
    Ok(())
}

/// Every series name of `panels` with how its first series is drawn, in order of first
/// appearance: a name's place is its style.
fn series_names(panels: &[Panel]) -> Vec<(String, Draw)> {
    let mut names: Vec<(String, Draw)> = Vec::new();
    for s in panels.iter().flat_map(|p| &p.series) {
        if !names.iter().any(|(n, _)| *n == s.name) {
            names.push((s.name.clone(), s.draw));
        }
    }
    names
}

fn draw_panels<DB: DrawingBackend>(
    root: DrawingArea<DB, Shift>,
    panels: &[Panel],
    columns: usize,
) -> Drawn
where
    DB::ErrorType: 'static,
{
    root.fill(&WHITE)?;
    let names = series_names(panels);
    let width = root.dim_in_pixel().0;
    let (plots, legend) = root.split_horizontally(width.saturating_sub(LEGEND_W));
    let style_of = |name: &str| style(names.iter().position(|(n, _)| n == name).unwrap_or(0));
    let columns = columns.clamp(1, panels.len().max(1));
    let areas = plots.split_evenly((panels.len().div_ceil(columns), columns));
    for (area, panel) in areas.iter().zip(panels) {
        draw_panel(area, panel, &style_of)?;
    }
    draw_legend(&legend, &names)?;
    root.present()?;
    Ok(())
}

/// Draws `panels` side by side into `<dir>/<stem>.png` and `.svg`; returns the file names.
pub fn figure(
    dir: &Path,
    out: &Path,
    stem: &str,
    size: (u32, u32),
    panels: &[Panel],
) -> Result<Vec<String>> {
    figure_grid(dir, out, stem, size, panels, panels.len())
}

/// Draws `panels` row by row, `columns` to a row, into `<dir>/<stem>.png` and `.svg` (`out` is
/// where `dir` will be, for error messages); returns the file names.
pub fn figure_grid(
    dir: &Path,
    out: &Path,
    stem: &str,
    size: (u32, u32),
    panels: &[Panel],
    columns: usize,
) -> Result<Vec<String>> {
    let fail = |name: &str, message: String| ReportError::Plot {
        path: out.join(name),
        message,
    };
    font().map_err(|m| fail(stem, m))?;
    let names = series_names(panels);
    if names.len() > MAX_SERIES {
        return Err(fail(
            stem,
            format!(
                "{} series: a figure holds at most {MAX_SERIES}, each in a style of its own",
                names.len()
            ),
        ));
    }
    let png = format!("{stem}.png");
    let svg = format!("{stem}.svg");
    draw_panels(
        BitMapBackend::new(&dir.join(&png), size).into_drawing_area(),
        panels,
        columns,
    )
    .map_err(|e| fail(&png, e.to_string()))?;
    draw_panels(
        SVGBackend::new(&dir.join(&svg), size).into_drawing_area(),
        panels,
        columns,
    )
    .map_err(|e| fail(&svg, e.to_string()))?;
    Ok(vec![png, svg])
}

/// One panel of points coloured by a value.
pub struct ColourPanel {
    /// Its title.
    pub title: String,
    /// The x axis' label.
    pub x_label: String,
    /// The y axis' label.
    pub y_label: String,
    /// (x, y, value).
    pub points: Vec<(f64, f64, f64)>,
}

/// The colour scale of a [`colour_figure`]: from 0 to the 99th percentile of the values (a few
/// wild points do not wash out the rest; those above are drawn in the top colour).
fn colour_scale(panels: &[ColourPanel]) -> f64 {
    let mut values: Vec<f64> = panels
        .iter()
        .flat_map(|p| p.points.iter().map(|q| q.2))
        .filter(|v| v.is_finite())
        .collect();
    values.sort_by(f64::total_cmp);
    match values.len() {
        0 => 1.0,
        n => values[((n - 1) as f64 * 0.99).round() as usize].max(1e-9),
    }
}

fn draw_colour_panels<DB: DrawingBackend>(
    root: DrawingArea<DB, Shift>,
    panels: &[ColourPanel],
    value_label: &str,
) -> Drawn
where
    DB::ErrorType: 'static,
{
    root.fill(&WHITE)?;
    let (width, height) = root.dim_in_pixel();
    let (plots, legend) = root.split_horizontally(width.saturating_sub(LEGEND_W));
    let top = colour_scale(panels);
    let colour = |v: f64| ViridisRGB.get_color_normalized(v.clamp(0.0, top), 0.0, top);
    for (area, panel) in plots.split_evenly((1, panels.len())).iter().zip(panels) {
        let (x0, x1) = range(panel.points.iter().map(|p| p.0), false);
        let (y0, y1) = range(panel.points.iter().map(|p| p.1), false);
        let mut chart = axes(
            area,
            &panel.title,
            (&panel.x_label, &panel.y_label),
            (x0..x1, y0..y1),
            70,
        )?;
        // Largest values last, on top.
        let mut points = panel.points.clone();
        points.sort_by(|a, b| a.2.total_cmp(&b.2));
        chart.draw_series(
            points
                .iter()
                .map(|&(x, y, v)| Circle::new((x, y), 3, colour(v).filled())),
        )?;
    }
    // The scale: a vertical bar with five labelled ticks.
    let font = ("sans-serif", 13).into_font();
    legend.draw(&Text::new(value_label.to_string(), (8, 22), font.clone()))?;
    let (y_top, y_bottom) = (50, height as i32 - 70);
    let steps = 200;
    for k in 0..steps {
        let v = top * (1.0 - k as f64 / steps as f64);
        let y = y_top + (y_bottom - y_top) * k / steps;
        let y_next = y_top + (y_bottom - y_top) * (k + 1) / steps;
        legend.draw(&Rectangle::new(
            [(12, y), (40, y_next + 1)],
            colour(v).filled(),
        ))?;
    }
    for t in 0..=4 {
        let v = top * (1.0 - t as f64 / 4.0);
        let y = y_top + (y_bottom - y_top) * t / 4;
        legend.draw(&PathElement::new(
            vec![(40, y), (46, y)],
            BLACK.stroke_width(1),
        ))?;
        let text = if t == 0 {
            format!("≥ {v:.3}")
        } else {
            format!("{v:.3}")
        };
        legend.draw(&Text::new(text, (50, y - 7), font.clone()))?;
    }
    root.present()?;
    Ok(())
}

/// Draws `panels` side by side, every point coloured by its value on one colour-blind-safe
/// (viridis) scale shown in the column at the right, into `<dir>/<stem>.png` and `.svg`;
/// returns the file names.
pub fn colour_figure(
    dir: &Path,
    out: &Path,
    stem: &str,
    size: (u32, u32),
    panels: &[ColourPanel],
    value_label: &str,
) -> Result<Vec<String>> {
    let fail = |name: &str, message: String| ReportError::Plot {
        path: out.join(name),
        message,
    };
    font().map_err(|m| fail(stem, m))?;
    let png = format!("{stem}.png");
    let svg = format!("{stem}.svg");
    draw_colour_panels(
        BitMapBackend::new(&dir.join(&png), size).into_drawing_area(),
        panels,
        value_label,
    )
    .map_err(|e| fail(&png, e.to_string()))?;
    draw_colour_panels(
        SVGBackend::new(&dir.join(&svg), size).into_drawing_area(),
        panels,
        value_label,
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

/// The share of `values` (%) at or below each error: the empirical cumulative distribution as
/// a staircase from `(0, 0)`, rising by `100 / n` at each sorted value, flat to `top` after the
/// largest. Non-finite values count in `n` but never rise.
pub fn cumulative(values: &[f64], top: f64) -> Vec<(f64, f64)> {
    let mut sorted: Vec<f64> = values.iter().copied().filter(|v| v.is_finite()).collect();
    sorted.sort_by(f64::total_cmp);
    let n = values.len().max(1) as f64;
    let mut points = vec![(0f64.min(sorted.first().copied().unwrap_or(0.0)), 0.0)];
    for (i, &v) in sorted.iter().enumerate() {
        points.push((v, 100.0 * i as f64 / n));
        points.push((v, 100.0 * (i + 1) as f64 / n));
    }
    let last = points.last().map_or(0.0, |p| p.1);
    points.push((top.max(sorted.last().copied().unwrap_or(0.0)), last));
    points
}

/// Cumulative distributions ([`cumulative`]) of several named value lists, each flat to the
/// largest value of them all, drawn as lines without markers.
pub fn cumulative_curves(named: &[(String, Vec<f64>)]) -> Vec<Series> {
    let top = (named.iter())
        .flat_map(|(_, v)| v.iter().copied())
        .filter(|v| v.is_finite())
        .fold(0.0, f64::max);
    (named.iter())
        .map(|(name, v)| Series {
            name: name.clone(),
            points: cumulative(v, top),
            draw: Draw::Curve,
        })
        .collect()
}

/// Histograms of several named value lists over one common range.
pub fn histograms(named: &[(String, Vec<f64>)], bins: usize, from_zero: bool) -> Vec<Series> {
    let (lo, hi) = range(named.iter().flat_map(|(_, v)| v.iter().copied()), from_zero);
    named
        .iter()
        .map(|(name, v)| Series {
            name: name.clone(),
            points: histogram(v, lo, hi, bins),
            draw: Draw::Line,
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tick_labels_drop_trailing_zeros() {
        let labels: Vec<String> = [2.0, 0.25, -50.0, 0.30000000000000004, -0.00001, 1234.5678]
            .iter()
            .map(tick)
            .collect();
        assert_eq!(labels, ["2", "0.25", "-50", "0.3", "0", "1234.5678"]);
    }

    /// No two series of a figure share a style: colour, line and marker.
    #[test]
    fn every_series_of_a_figure_has_a_style_of_its_own() {
        for i in 0..MAX_SERIES {
            for j in 0..i {
                assert_ne!(style(i), style(j), "series {j} and {i}");
            }
        }
        let panel = |names: &[&str]| Panel {
            title: String::new(),
            x_label: String::new(),
            y_label: String::new(),
            series: names
                .iter()
                .map(|n| Series {
                    name: n.to_string(),
                    points: vec![(0.0, 1.0)],
                    draw: Draw::Marked,
                })
                .collect(),
        };
        // A name in two panels keeps its style; names are styled in order of appearance.
        let names = series_names(&[panel(&["before"]), panel(&["a", "b"]), panel(&["a", "c"])]);
        let names: Vec<&str> = names.iter().map(|(n, _)| n.as_str()).collect();
        assert_eq!(names, ["before", "a", "b", "c"]);
        // More series than styles is refused.
        let many: Vec<String> = (0..=MAX_SERIES).map(|i| format!("s{i}")).collect();
        let refs: Vec<&str> = many.iter().map(String::as_str).collect();
        let dir = tempfile::tempdir().unwrap();
        let err = figure(dir.path(), dir.path(), "many", TWO, &[panel(&refs)]).unwrap_err();
        assert!(err.to_string().contains("at most"), "{err}");
    }

    /// The cumulative staircase against a count made point by point: at every error `x` it
    /// reaches, the share of values at or below `x` is its height at the end of the riser there.
    #[test]
    fn the_cumulative_curve_is_the_share_of_values_at_or_below_each_error() {
        let values = [0.3, 0.1, 0.2, 0.2, f64::NAN];
        let curve = cumulative(&values, 0.5);
        assert_eq!(curve.first(), Some(&(0.0, 0.0)));
        assert_eq!(curve.last(), Some(&(0.5, 80.0)));
        for &x in &[0.1, 0.2, 0.3] {
            let share = 100.0 * values.iter().filter(|v| **v <= x).count() as f64 / 5.0;
            let top = (curve.iter())
                .filter(|p| p.0 == x)
                .map(|p| p.1)
                .fold(f64::MIN, f64::max);
            assert!((top - share).abs() < 1e-12, "at {x}: {top} against {share}");
        }
        // A staircase: x never decreases, and each step rises by one value's share.
        for w in curve.windows(2) {
            assert!(w[1].0 >= w[0].0 && w[1].1 >= w[0].1);
            assert!(w[1].1 - w[0].1 <= 20.0 + 1e-12);
        }
    }
}
