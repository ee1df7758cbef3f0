//! What a residual model's training reports: its networks, its gate, its GP.

use crate::spread;
use robocal_data::ErrorStats;
use robocal_model::{CalibratedModel, resolve_gate_physics};
use robocal_residual::{
    GateInputs, ResidualKind, ResidualModel, ResidualSettings, Samples, SearchLog,
    gate_feature_names,
};
use serde::Serialize;

/// One network's training, in the report.
#[derive(Debug, Clone, Serialize)]
pub struct NetTraining {
    /// Axes it predicts (`x`, `xyz`, …).
    pub axes: String,
    /// Epochs run.
    pub epochs: usize,
    /// Epoch whose weights were kept.
    pub best_epoch: usize,
    /// Whether early stopping ended it.
    pub stopped_early: bool,
}

/// The residual stage in `report.json`.
#[derive(Debug, Clone, Serialize)]
pub struct ResidualReport {
    /// `somm`, `mosm`, `ca-somm` or `gp`.
    pub model: &'static str,
    /// Seed of the networks and of the hold-out.
    pub seed: u64,
    /// Sets of networks averaged (a SOMM of several members; 1 otherwise).
    pub members: usize,
    /// The frame its errors are in, `world` or `joint1` (turning with joint 1): the GP's and
    /// the networks' axes are that frame's.
    pub frame: &'static str,
    /// Where the early-stopping data came from.
    pub validation_source: String,
    /// Rows trained on.
    pub training_rows: usize,
    /// Rows of the early-stopping set.
    pub validation_rows: usize,
    /// Every network.
    pub networks: Vec<NetTraining>,
    /// Training rows: error after the stages before, and after the residual too.
    pub training_before: ErrorStats,
    /// See `training_before`.
    pub training_after: ErrorStats,
    /// Early-stopping rows, before and after.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub validation_before: Option<ErrorStats>,
    /// See `validation_before`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub validation_after: Option<ErrorStats>,
    /// CA-SOMM: share of rows the classifier puts in their true class.
    pub classifier_accuracy_training: Option<f64>,
    /// See `classifier_accuracy_training`.
    pub classifier_accuracy_validation: Option<f64>,
    /// CA-SOMM: its classes, what the tree reads and splits on, and whether two classes paid.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub gate: Option<GateSummary>,
    /// TPE searches that chose the settings (when the stage asked for one).
    pub search: Vec<SearchLog>,
    /// The Gaussian process of each axis (a GP residual).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub gp: Vec<GpSummary>,
    /// The default calibration's check of the model's standard deviations on its folds' held-out
    /// rows, and the factor it put on them (a GP chosen by cross-validation).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub spread: Option<spread::SpreadCalibration>,
    /// The default calibration's estimate, on its folds' held-out rows, of a network's spread
    /// beside the physics' deviation (`spread_mm` in `residual.json`; a network chosen by
    /// cross-validation).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub spread_beside: Option<spread::SpreadBeside>,
}

/// The CA-SOMM gate, in the report.
#[derive(Debug, Clone, Default, Serialize)]
pub struct GateSummary {
    /// The world axis whose error splits the classes.
    pub axis: &'static str,
    /// Training errors on that axis at or above this (mm) are class B.
    pub threshold: f64,
    /// What the tree reads: `model`, `periodic` or `physics`.
    pub inputs: &'static str,
    /// Which rows each class's networks trained on: `threshold` or `routed`.
    pub classes: &'static str,
    /// Training rows in class A and class B.
    pub class_rows: [usize; 2],
    /// The tree's depth limit and fewest rows per leaf.
    pub tree: [usize; 2],
    /// Whether the tree's size was chosen on the validation rows (from how many grid points).
    pub tree_searched: usize,
    /// Mean X, Y, Z error of each class's training rows, mm.
    pub class_mean_error: [[f64; 3]; 2],
    /// The tree's splits, root first: the feature and the value below which a row goes left.
    pub splits: Vec<GateSplit>,
    /// With a fallback: whether two classes or one were kept, and why.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub decision: Option<String>,
}

/// One split of the CA-SOMM tree.
#[derive(Debug, Clone, Serialize)]
pub struct GateSplit {
    /// 0 at the root.
    pub depth: usize,
    /// The feature it reads (`payload torque j4`, `sin q1`, `load`, …).
    pub feature: String,
    /// Rows below this value go left.
    pub below: f64,
}

/// One axis's Gaussian process, in the report.
#[derive(Debug, Clone, Serialize)]
pub struct GpSummary {
    /// `x`, `y` or `z`.
    pub axis: &'static str,
    /// Rows it conditions on.
    pub rows: usize,
    /// Standard deviation of the learned error, mm (the kernel's signal).
    pub signal_std: f64,
    /// Standard deviation of what it takes as noise, mm.
    pub noise_std: f64,
    /// Length-scale of each standardised feature (sin q1, cos q1, …, load): short means the
    /// error changes fast with it, long that it hardly depends on it.
    pub lengthscales: Vec<f64>,
    /// Negative log marginal likelihood per row on the hyper-parameter subset.
    pub nll_per_row: f64,
}

/// `settings` with a CA-SOMM gate's physics resolved against `base` (its table and joint
/// errors: [`resolve_gate_physics`]); unchanged for any other model or gate.
pub fn gate_ready(settings: &ResidualSettings, base: &CalibratedModel) -> ResidualSettings {
    let mut settings = settings.clone();
    if settings.kind == ResidualKind::CaSomm
        && settings.classifier.gate_inputs() == GateInputs::Physics
    {
        let p = resolve_gate_physics(
            &settings.classifier,
            &base.robot,
            base.joint_errors.as_ref(),
        );
        settings.classifier.gravity = Some(p.gravity);
        settings.classifier.payload_com = Some(p.payload_com);
    }
    settings
}

/// The CA-SOMM gate in the report: its classes, what it reads and splits on, and whether two
/// classes paid (`None` for any other model).
pub fn gate_summary(model: &ResidualModel, joints: usize, train: &Samples) -> Option<GateSummary> {
    let decision = model.fallback_decision();
    let Some(c) = model.classifier() else {
        return decision.map(|d| GateSummary {
            decision: Some(d),
            ..GateSummary::default()
        });
    };
    let names = gate_feature_names(c.inputs, model.encoding, joints);
    let splits = c
        .splits()
        .into_iter()
        .map(|(f, value, depth)| GateSplit {
            depth,
            feature: names
                .get(f)
                .cloned()
                .unwrap_or_else(|| format!("input {f}")),
            below: value,
        })
        .collect();
    let mut class_means = [[0.0; 3]; 2];
    let truth = c.training_classes(&model.encoding.encode_all(&train.inputs), train);
    for (class, means) in class_means.iter_mut().enumerate() {
        let rows: Vec<&[f64; 3]> = (train.errors.iter().zip(&truth))
            .filter(|(_, t)| **t == class)
            .map(|(e, _)| e)
            .collect();
        for (a, m) in means.iter_mut().enumerate() {
            *m = rows.iter().map(|e| e[a]).sum::<f64>() / rows.len().max(1) as f64;
        }
    }
    Some(GateSummary {
        axis: ["x", "y", "z"][c.axis.min(2)],
        threshold: c.threshold,
        inputs: c.inputs.name(),
        classes: c.classes.name(),
        class_rows: c.class_rows,
        tree: [c.max_depth, c.min_samples_leaf],
        tree_searched: c.tree_search.len(),
        class_mean_error: class_means,
        splits,
        decision,
    })
}

/// The report of a trained residual model: its training rows `train` and early-stopping rows
/// `val` (none: no validation figures) before and after it.
pub(super) fn residual_report(
    fitted: &ResidualModel,
    seed: u64,
    source: String,
    train: &Samples,
    val: &Samples,
    joints: usize,
) -> ResidualReport {
    let left = |s: &Samples, predicted: Option<&[[f64; 3]]>| {
        ErrorStats::from_errors(&s.remaining(predicted))
    };
    ResidualReport {
        model: fitted.kind().name(),
        seed,
        members: fitted.members(),
        frame: fitted.frame.name(),
        validation_source: source,
        training_rows: train.len(),
        validation_rows: val.len(),
        networks: (fitted.nets().into_iter())
            .map(|n| NetTraining {
                axes: n.axes_name(),
                epochs: n.report.epochs,
                best_epoch: n.report.best_epoch,
                stopped_early: n.report.stopped_early,
            })
            .collect(),
        training_before: left(train, None),
        training_after: left(train, Some(&fitted.predict(train))),
        validation_before: (!val.is_empty()).then(|| left(val, None)),
        validation_after: (!val.is_empty()).then(|| left(val, Some(&fitted.predict(val)))),
        classifier_accuracy_training: fitted.classifier_accuracy(train),
        classifier_accuracy_validation: fitted.classifier_accuracy(val),
        gate: gate_summary(fitted, joints, train),
        search: fitted.search.clone(),
        gp: fitted.gp().map_or_else(Vec::new, |g| {
            (g.axes.iter().zip(["x", "y", "z"]))
                .map(|(a, axis)| GpSummary {
                    axis,
                    rows: g.rows.len(),
                    signal_std: a.signal_variance.sqrt() * a.target_std,
                    noise_std: a.noise_variance.sqrt() * a.target_std,
                    lengthscales: a.lengthscales.clone(),
                    nll_per_row: a.nll_per_row,
                })
                .collect()
        }),
        spread: None,
        spread_beside: None,
    }
}
