//! A report's statistics: the errors before and after, by axis, load, target and row, and how
//! well a model's predicted spread matches its errors.

use std::path::PathBuf;

use nalgebra::Vector3;
use robocal_data::{ErrorStats, Measurement};
use robocal_model::CalibratedModel;
use serde::Serialize;

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
    pub(crate) fn describe(self) -> &'static str {
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
pub(crate) fn parts(model: &CalibratedModel) -> Vec<String> {
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
pub(crate) fn mean(values: &[f64]) -> f64 {
    if values.is_empty() {
        0.0
    } else {
        values.iter().sum::<f64>() / values.len() as f64
    }
}

/// Distinct loads of `rows`, ascending.
pub(crate) fn loads(rows: &[&Measurement]) -> Vec<f64> {
    let mut loads: Vec<f64> = rows.iter().map(|m| m.sample.load).collect();
    loads.sort_by(f64::total_cmp);
    loads.dedup();
    loads
}

/// Mean errors per target, in order of first appearance (none when no row names a target).
pub(crate) fn by_target(
    rows: &[&Measurement],
    before: Option<&[f64]>,
    after: &[f64],
) -> Vec<TargetStats> {
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
pub(crate) fn ranks(v: &[f64]) -> Vec<f64> {
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
pub(crate) fn rank_correlation(a: &[f64], b: &[f64]) -> f64 {
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
pub(crate) fn sigma_check(after: &[f64], sigmas: &[f64]) -> Option<SigmaCheck> {
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
pub(crate) fn axis_stats(signed: &[Vector3<f64>]) -> Vec<AxisStats> {
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
