//! The report's text: its tables and sections as Markdown (`report.md`) and as a
//! self-contained page (`report.html`, the figures inlined).

use super::stats::DataReport;
use robocal_data::ErrorStats;
use std::fmt::Write as _;
use std::path::Path;

/// The statistics table: (row name, stats).
pub(super) fn stats_rows(r: &DataReport) -> Vec<(&'static str, &ErrorStats)> {
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
pub(super) fn stats_table(rows: Vec<(&str, &ErrorStats)>) -> Table {
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
pub(super) struct Table {
    pub(super) header: Vec<String>,
    pub(super) rows: Vec<Vec<String>>,
}

/// The report's text: (heading, paragraphs, tables), then the figures.
pub(super) fn sections(r: &DataReport) -> Vec<(String, Vec<String>, Vec<Table>)> {
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
pub(super) fn sigma_paragraphs(r: &DataReport) -> Vec<String> {
    if r.sigma.is_none() {
        return Vec::new();
    }
    vec!["The standard deviation the model gives each row (`predict --sigma`: a GP's, scaled as its folds found; a network's, the physics' with the spread its folds found beside it; a physical model's, from its parameters' covariance) against the row's error. For errors drawn as the model says, the root mean square of error/σ is 1, 61 % of the rows lie within σ and 99 % within 2σ. The errors here are from the measured points, which carry the tracker's noise and the arm's repeatability besides the model's error: a physical model's or a GP's σ leaves those out, so on rows predicted to the noise the ratio lies above 1 by them. A ratio well above 1 says the model is surer than it should be: read its σ as a floor.".into()]
}

/// The σ check's table.
pub(super) fn sigma_table(r: &DataReport) -> Vec<Table> {
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

pub(super) fn markdown(r: &DataReport) -> String {
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
pub(super) fn escape(text: &str) -> String {
    text.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
}

/// HTML of a paragraph: `code` spans as `<code>`.
pub(super) fn paragraph(text: &str) -> String {
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
pub(super) fn html(
    r: &DataReport,
    dir: &Path,
) -> std::result::Result<String, (String, std::io::Error)> {
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
