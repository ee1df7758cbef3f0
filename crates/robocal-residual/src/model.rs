//! Residual models over (joint angles, load) → position error per world axis: SOMM (one network
//! per axis), MOSM (one network, three outputs) and CA-SOMM (a decision tree picks one of two
//! per-axis model sets), with standardisation, training, and the saved form.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use burn::module::Module;
use burn::prelude::Device;
use linfa::prelude::*;
use linfa_trees::DecisionTree;
use nalgebra::Vector3;
use ndarray::{Array1, Array2};
use robocal_data::{Measurement, Sample};
use robocal_data::{Observer, Silent};
use robocal_robot::Robot;
use serde::{Deserialize, Serialize};

use crate::error::{ResidualError, Result};
use crate::gp::{GpAxis, GpSettings};
use crate::mlp::{Dense, Mlp, NetSettings, Split, TrainReport, train};
use crate::search::{SearchLog, SearchSettings, search};

/// Renumbers a module's parameters 0, 1, 2, … in visiting order.
struct SequentialIds(u64);

impl burn::module::ModuleMapper for SequentialIds {
    fn map_float<const D: usize>(
        &mut self,
        mut param: burn::module::Param<burn::tensor::Tensor<D>>,
    ) -> burn::module::Param<burn::tensor::Tensor<D>> {
        param.id = burn::module::ParamId::from(self.0);
        self.0 += 1;
        param
    }
}

/// Version of the saved residual model (`residual.json`).
pub const RESIDUAL_FORMAT: u32 = 1;

/// Residual samples: one input row (joint angles in degrees, then the load in kg) and the
/// position error (measured − kinematic prediction, mm, world X/Y/Z) per sample.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Samples {
    /// Input rows, all of one length.
    pub inputs: Vec<Vec<f64>>,
    /// Errors, mm.
    pub errors: Vec<[f64; 3]>,
}

/// The residual model's input row for a sample: joint angles (deg), then the load (kg).
pub fn inputs_of(sample: &Sample) -> Vec<f64> {
    let mut row = sample.joints.clone();
    row.push(sample.load);
    row
}

/// How an input row (joint angles in degrees, then the load) is presented to a model.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Encoding {
    /// As read: angles in degrees, then the load (the paper's inputs, eq. (24)).
    #[default]
    Raw,
    /// `sin q, cos q` of every joint angle, then the load: an error that is periodic in the
    /// angles is a smooth function of these, and ±180° are one angle.
    Periodic,
}

impl Encoding {
    /// Whether this is [`Encoding::Raw`] (the default, left out of saved files).
    pub fn is_raw(&self) -> bool {
        *self == Self::Raw
    }

    /// Features of an encoded row of `inputs` raw inputs (the last one the load).
    pub fn features(self, inputs: usize) -> usize {
        match self {
            Self::Raw => inputs,
            Self::Periodic => 2 * inputs.saturating_sub(1) + usize::from(inputs > 0),
        }
    }

    /// The encoded row.
    pub fn encode(self, row: &[f64]) -> Vec<f64> {
        match self {
            Self::Raw => row.to_vec(),
            Self::Periodic => {
                let Some((load, joints)) = row.split_last() else {
                    return Vec::new();
                };
                let mut out = Vec::with_capacity(2 * joints.len() + 1);
                for q in joints {
                    let (s, c) = q.to_radians().sin_cos();
                    out.push(s);
                    out.push(c);
                }
                out.push(*load);
                out
            }
        }
    }

    /// Every row encoded.
    pub fn encode_all(self, rows: &[Vec<f64>]) -> Vec<Vec<f64>> {
        rows.iter().map(|r| self.encode(r)).collect()
    }
}

/// The Gaussian-process residual: one [`GpAxis`] per world axis over standardised features,
/// conditioned on the same rows.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GpResidual {
    /// Feature scaling (of the encoded inputs).
    pub input_scale: Standardizer,
    /// The standardised feature rows the model conditions on.
    pub rows: Vec<Vec<f64>>,
    /// X, Y, Z.
    pub axes: Vec<GpAxis>,
    /// Cholesky factors for the variances, made on first use.
    #[serde(skip)]
    factors: std::sync::OnceLock<Vec<Option<faer::linalg::solvers::Llt<f64>>>>,
}

impl GpResidual {
    fn fit(settings: &GpSettings, train_set: &Samples, seed: u64) -> Result<Self> {
        let input_scale = Standardizer::fit(&train_set.inputs);
        let x: Vec<Vec<f64>> = (train_set.inputs.iter())
            .map(|r| input_scale.apply(r))
            .collect();
        let mut axes = Vec::with_capacity(3);
        let mut rows = Vec::new();
        for a in 0..3 {
            let y: Vec<f64> = train_set.errors.iter().map(|e| e[a]).collect();
            // One seed for every axis: the same conditioning rows.
            let (gp, kept) = GpAxis::fit_rows(&x, &y, settings, seed)?;
            axes.push(gp);
            rows = kept;
        }
        Ok(Self {
            input_scale,
            rows: rows.iter().map(|&i| x[i].clone()).collect(),
            axes,
            factors: std::sync::OnceLock::new(),
        })
    }

    /// Predicted error (mm) per encoded row, and with `std` the latent standard deviation of
    /// each axis's correction (mm).
    fn predict(&self, encoded: &[Vec<f64>], std: bool) -> (Vec<[f64; 3]>, Option<Vec<[f64; 3]>>) {
        let factors = std.then(|| {
            self.factors
                .get_or_init(|| self.axes.iter().map(|a| a.factor(&self.rows)).collect())
        });
        let mut mean = vec![[0.0; 3]; encoded.len()];
        let mut sd = std.then(|| vec![[f64::NAN; 3]; encoded.len()]);
        for (i, row) in encoded.iter().enumerate() {
            let x = self.input_scale.apply(row);
            for (a, gp) in self.axes.iter().enumerate() {
                let f = factors.and_then(|f| f[a].as_ref());
                let (m, s) = gp.predict_one(&self.rows, &x, f);
                mean[i][a] = m;
                if let (Some(sd), Some(s)) = (sd.as_mut(), s) {
                    sd[i][a] = s;
                }
            }
        }
        (mean, sd)
    }

    fn check(&self, features: usize) -> std::result::Result<(), String> {
        if !self.input_scale.fits(features) {
            return Err(format!("gp.input_scale: does not fit {features} features"));
        }
        if self.rows.len() < 2 || self.rows.len() > crate::gp::MAX_GP_ROWS {
            return Err(format!(
                "gp.rows: {} rows; a model conditions on 2 to {}",
                self.rows.len(),
                crate::gp::MAX_GP_ROWS
            ));
        }
        if (self.rows.iter()).any(|r| r.len() != features || r.iter().any(|v| !v.is_finite())) {
            return Err(format!(
                "gp.rows: every row must hold {features} finite values"
            ));
        }
        if self.axes.len() != 3 {
            return Err("gp.axes: one per world axis (3)".into());
        }
        for (a, gp) in self.axes.iter().enumerate() {
            gp.check(features, self.rows.len())
                .map_err(|m| format!("gp.axes[{a}]: {m}"))?;
        }
        Ok(())
    }
}

impl Samples {
    /// Residual samples of measured rows: inputs, and measured − `robot`'s predicted point.
    pub fn from_measurements<'a>(
        robot: &Robot,
        rows: impl IntoIterator<Item = &'a Measurement>,
    ) -> Self {
        Self::from_model(|s| robot.point(&s.joints_rad()), rows)
    }

    /// Residual samples of measured rows: inputs, and measured − `model`'s predicted point
    /// (e.g. an elasto-geometric model's, which depends on the load).
    pub fn from_model<'a>(
        model: impl Fn(&Sample) -> Vector3<f64>,
        rows: impl IntoIterator<Item = &'a Measurement>,
    ) -> Self {
        let mut samples = Self::default();
        for m in rows {
            samples.inputs.push(inputs_of(&m.sample));
            let e = m.position - model(&m.sample);
            samples.errors.push([e.x, e.y, e.z]);
        }
        samples
    }

    /// Length of each sample's error left after subtracting `predicted` (`None`: the error
    /// itself), mm.
    pub fn remaining(&self, predicted: Option<&[[f64; 3]]>) -> Vec<f64> {
        self.errors
            .iter()
            .enumerate()
            .map(|(i, e)| {
                let p = predicted.map_or([0.0; 3], |p| p[i]);
                ((e[0] - p[0]).powi(2) + (e[1] - p[1]).powi(2) + (e[2] - p[2]).powi(2)).sqrt()
            })
            .collect()
    }

    /// Number of samples.
    pub fn len(&self) -> usize {
        self.errors.len()
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.errors.is_empty()
    }

    fn subset(&self, keep: &[bool]) -> Self {
        let pick = |i: &usize| keep[*i];
        let idx: Vec<usize> = (0..self.len()).filter(pick).collect();
        Self {
            inputs: idx.iter().map(|&i| self.inputs[i].clone()).collect(),
            errors: idx.iter().map(|&i| self.errors[i]).collect(),
        }
    }
}

/// Per-column mean and standard deviation from training data.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Standardizer {
    /// Column means.
    pub mean: Vec<f64>,
    /// Column standard deviations (1 where a column is constant).
    pub std: Vec<f64>,
}

impl Standardizer {
    /// Fits the columns of `rows`.
    pub fn fit(rows: &[Vec<f64>]) -> Self {
        let cols = rows.first().map_or(0, Vec::len);
        let n = rows.len().max(1) as f64;
        let mean: Vec<f64> = (0..cols)
            .map(|c| rows.iter().map(|r| r[c]).sum::<f64>() / n)
            .collect();
        let std = (0..cols)
            .map(|c| {
                let v = rows.iter().map(|r| (r[c] - mean[c]).powi(2)).sum::<f64>() / n;
                if v > 1e-24 { v.sqrt() } else { 1.0 }
            })
            .collect();
        Self { mean, std }
    }

    /// Whether this scaling fits `n` columns: that many finite means and positive finite
    /// standard deviations (what a file read back must hold).
    pub fn fits(&self, n: usize) -> bool {
        self.mean.len() == n
            && self.std.len() == n
            && self.mean.iter().chain(&self.std).all(|v| v.is_finite())
            && self.std.iter().all(|v| *v > 0.0)
    }

    /// The standardised row.
    pub fn apply(&self, row: &[f64]) -> Vec<f64> {
        (row.iter().zip(&self.mean).zip(&self.std))
            .map(|((v, m), s)| (v - m) / s)
            .collect()
    }

    fn forward(&self, row: &[f64], out: &mut Vec<f32>) {
        for ((v, m), s) in row.iter().zip(&self.mean).zip(&self.std) {
            out.push(((v - m) / s) as f32);
        }
    }

    fn back(&self, col: usize, v: f32) -> f64 {
        f64::from(v) * self.std[col] + self.mean[col]
    }
}

/// One trained network with its scaling: inputs → the error on `axes`.
#[derive(Debug, Clone)]
pub struct AxisNet {
    /// Which world axes (0 = X, 1 = Y, 2 = Z) the outputs are.
    pub axes: Vec<usize>,
    /// Its settings.
    pub settings: NetSettings,
    /// Input scaling.
    pub input_scale: Standardizer,
    /// Output scaling.
    pub output_scale: Standardizer,
    /// What training did.
    pub report: TrainReport,
    net: Mlp,
    dense: Dense,
}

impl AxisNet {
    /// The axes it predicts as letters: `x`, `xyz`, …
    pub fn axes_name(&self) -> String {
        self.axes.iter().map(|&a| ["x", "y", "z"][a]).collect()
    }

    fn inputs(&self) -> usize {
        self.input_scale.mean.len()
    }

    fn fit(
        axes: Vec<usize>,
        settings: &NetSettings,
        train_set: &Samples,
        validation: &Samples,
        seed: u64,
        progress: &dyn Observer,
    ) -> Self {
        let input_scale = Standardizer::fit(&train_set.inputs);
        let targets = |s: &Samples| -> Vec<Vec<f64>> {
            s.errors
                .iter()
                .map(|e| axes.iter().map(|&a| e[a]).collect())
                .collect()
        };
        let train_y = targets(train_set);
        let output_scale = Standardizer::fit(&train_y);
        let flat = |s: &Samples, y: &[Vec<f64>]| {
            let (mut x, mut t) = (Vec::new(), Vec::new());
            for row in &s.inputs {
                input_scale.forward(row, &mut x);
            }
            for row in y {
                output_scale.forward(row, &mut t);
            }
            (x, t)
        };
        let (tx, ty) = flat(train_set, &train_y);
        let (vx, vy) = flat(validation, &targets(validation));
        let (net, report) = train(
            settings,
            input_scale.mean.len(),
            axes.len(),
            Split { x: &tx, y: &ty },
            Split { x: &vx, y: &vy },
            seed,
            progress,
        );
        Self {
            axes,
            settings: settings.clone(),
            input_scale,
            output_scale,
            report,
            dense: net.dense(),
            net,
        }
    }

    /// Writes this network's predictions (mm) for `inputs` into its axes of `out`.
    fn predict_into(&self, inputs: &[Vec<f64>], out: &mut [[f64; 3]]) {
        let (mut x, mut y) = (Vec::with_capacity(self.inputs()), Vec::new());
        for (row, o) in inputs.iter().zip(out.iter_mut()) {
            x.clear();
            self.input_scale.forward(row, &mut x);
            self.dense.forward(&x, &mut y);
            for (c, &axis) in self.axes.iter().enumerate() {
                o[axis] = self.output_scale.back(c, y[c]);
            }
        }
    }

    /// The burn network's own predictions in standardised units, row-major (what
    /// [`Self::predict_standardised`] must agree with).
    pub fn burn_forward(&self, x: &[f32]) -> Vec<f32> {
        self.net.predict(x, self.inputs())
    }

    /// The plain-matrix forward pass in standardised units, row-major.
    pub fn predict_standardised(&self, x: &[f32]) -> Vec<f32> {
        let mut out = Vec::new();
        let mut y = Vec::new();
        for row in x.chunks_exact(self.inputs()) {
            self.dense.forward(row, &mut y);
            out.extend_from_slice(&y);
        }
        out
    }
}

/// Which residual model.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum ResidualKind {
    /// One network per axis (the paper's SOMM-ANN).
    Somm,
    /// One network with three outputs (the paper's "traditional" MOSM-ANN baseline).
    Mosm,
    /// A classifier picks one of two SOMM sets (the paper's CA-SOMM-ANN).
    CaSomm,
    /// A Gaussian process per axis (ARD squared-exponential kernel), with predictive
    /// standard deviations.
    Gp,
}

impl ResidualKind {
    /// The name used in files.
    pub fn name(self) -> &'static str {
        match self {
            Self::Somm => "somm",
            Self::Mosm => "mosm",
            Self::CaSomm => "ca-somm",
            Self::Gp => "gp",
        }
    }

    /// Whether training early-stops on a validation set (the networks; the GP does not).
    pub fn early_stops(self) -> bool {
        self != Self::Gp
    }
}

fn default_depth() -> usize {
    3
}
fn default_leaf() -> usize {
    66
}
fn default_axis() -> char {
    'x'
}

/// The CA-SOMM classifier's settings (paper section V-B3).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ClassifierSettings {
    /// The bimodal axis whose error splits the training set: `x`, `y` or `z`.
    #[serde(default = "default_axis")]
    pub axis: char,
    /// Deepest tree.
    #[serde(default = "default_depth")]
    pub max_depth: usize,
    /// Fewest training samples in a leaf.
    #[serde(default = "default_leaf")]
    pub min_samples_leaf: usize,
    /// How a prediction uses the class: `hard` (the paper: the set the tree picks) or `soft`
    /// (both sets, weighted by the share of each class among the training rows in the row's
    /// leaf, which costs less when the tree is unsure).
    #[serde(default)]
    pub gate: Gate,
    /// Which axes get a network per class: `all` (the paper: two full SOMM sets) or `axis`
    /// (only the classifier's axis; the other axes get one network trained on every row, which
    /// both sets share).
    #[serde(default)]
    pub per_class: PerClass,
}

/// Which axes CA-SOMM models per class.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum PerClass {
    /// Every axis (the paper's CA-SOMM).
    #[default]
    All,
    /// Only the classifier's axis.
    Axis,
}

/// How CA-SOMM combines its two model sets.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Gate {
    /// The set of the class the tree picks (the paper's CA-SOMM).
    #[default]
    Hard,
    /// `(1 − p) A + p B`, `p` the share of class B among the training rows in the leaf.
    Soft,
}

impl Default for ClassifierSettings {
    fn default() -> Self {
        Self {
            axis: default_axis(),
            max_depth: default_depth(),
            min_samples_leaf: default_leaf(),
            gate: Gate::Hard,
            per_class: PerClass::All,
        }
    }
}

/// Everything that defines how a residual model is trained.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ResidualSettings {
    /// Which model.
    pub kind: ResidualKind,
    /// Per-axis networks (SOMM, and each CA-SOMM set).
    pub axes: [NetSettings; 3],
    /// The multi-output network (MOSM).
    pub mosm: NetSettings,
    /// The CA-SOMM classifier.
    pub classifier: ClassifierSettings,
    /// A TPE search of each network's architecture and learning rate before training, if asked.
    pub search: Option<SearchSettings>,
    /// The Gaussian process (GP).
    pub gp: GpSettings,
    /// How input rows are presented to the networks, the classifier and the GP.
    pub encoding: Encoding,
    /// Seed of weight initialisation and batch order.
    pub seed: u64,
}

impl ResidualSettings {
    /// The paper's settings (Tables 2 and 3) for `kind`. The MOSM network has no published
    /// architecture; it gets the Z network's (the largest tanh one) with three outputs.
    pub fn paper(kind: ResidualKind, seed: u64) -> Self {
        Self {
            kind,
            axes: [
                NetSettings::paper_x(),
                NetSettings::paper_y(),
                NetSettings::paper_z(),
            ],
            mosm: NetSettings::paper_z(),
            classifier: ClassifierSettings::default(),
            search: None,
            gp: GpSettings::default(),
            encoding: Encoding::Raw,
            seed,
        }
    }

    /// A Gaussian process per axis on the periodic encoding (robocal's default residual).
    pub fn gp(seed: u64) -> Self {
        Self {
            encoding: Encoding::Periodic,
            ..Self::paper(ResidualKind::Gp, seed)
        }
    }

    /// The first invalid setting as (key relative to `[residual]`, message), e.g.
    /// (`x.learning_rate`, …); every network is checked, used by this kind or not.
    pub fn invalid(&self) -> Option<(String, String)> {
        let [x, y, z] = &self.axes;
        for (name, s) in [("x", x), ("y", y), ("z", z), ("mosm", &self.mosm)] {
            if let Err((field, m)) = s.check() {
                return Some((format!("{name}.{field}"), m));
            }
        }
        if let Some(search) = &self.search
            && let Err((field, m)) = search.check()
        {
            return Some((format!("search.{field}"), m));
        }
        if let Err((field, m)) = self.gp.check() {
            return Some((format!("gp.{field}"), m));
        }
        if !matches!(self.classifier.axis, 'x' | 'y' | 'z') {
            return Some((
                "classifier.axis".into(),
                "must be \"x\", \"y\" or \"z\"".into(),
            ));
        }
        if self.classifier.max_depth == 0 {
            return Some(("classifier.max_depth".into(), "must be at least 1".into()));
        }
        None
    }

    /// Checks every setting; the error names the key.
    pub fn check(&self) -> Result<()> {
        match self.invalid() {
            Some((key, m)) => Err(ResidualError::Settings(format!("{key}: {m}"))),
            None => Ok(()),
        }
    }
}

/// The CA-SOMM gate: a decision tree on the inputs, and how its classes were made.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Classifier {
    /// The split axis (0 = X).
    pub axis: usize,
    /// Training errors on that axis at or above this (mm) are class B, below class A.
    pub threshold: f64,
    /// The tree: inputs → 0 (A) or 1 (B).
    pub tree: DecisionTree<f64, usize>,
    /// How predictions use the class.
    #[serde(default)]
    pub gate: Gate,
    /// Share of class B among the training rows in each leaf, keyed by the leaf's path from
    /// the root (`l`/`r` per split; the root alone is `""`).
    #[serde(default)]
    pub leaf_share_b: BTreeMap<String, f64>,
}

impl Classifier {
    /// Class of each input row (0 = A, 1 = B).
    pub fn classify(&self, inputs: &[Vec<f64>]) -> Vec<usize> {
        if inputs.is_empty() {
            return Vec::new();
        }
        let cols = inputs[0].len();
        let x = Array2::from_shape_fn((inputs.len(), cols), |(i, j)| inputs[i][j]);
        self.tree.predict(&x).to_vec()
    }

    /// Checks a classifier read from a file against the model's input count: every split on
    /// an existing input with both branches present, every leaf a class (0 or 1), the axis and
    /// threshold valid. linfa would panic on a tree that breaks these.
    pub fn check(&self, inputs: usize) -> std::result::Result<(), String> {
        if self.axis > 2 || !self.threshold.is_finite() {
            return Err("classifier: axis must be 0..2 and threshold a finite number".into());
        }
        for node in self.tree.iter_nodes() {
            if node.is_leaf() {
                if !matches!(node.prediction(), Some(0 | 1)) {
                    return Err("classifier: a leaf's class is not 0 or 1".into());
                }
            } else if node.split().0 >= inputs || node.children().iter().any(|c| c.is_none()) {
                return Err(format!(
                    "classifier: a split on input {} of {inputs}, or a missing branch",
                    node.split().0
                ));
            }
        }
        if self.leaf_share_b.values().any(|v| !(0.0..=1.0).contains(v)) {
            return Err("classifier: leaf_share_b values must lie in 0..1".into());
        }
        Ok(())
    }

    /// The path from the root to the leaf `row` falls in: `l` or `r` per split (linfa's rule:
    /// left when the feature is below the split value).
    pub fn leaf_path(&self, row: &[f64]) -> String {
        let mut path = String::new();
        let mut node = self.tree.root_node();
        while !node.is_leaf() {
            let (feature, value, _) = node.split();
            let children = node.children();
            let (next, step) = if row[feature] < value {
                (children[0], 'l')
            } else {
                (children[1], 'r')
            };
            match next {
                Some(child) => {
                    node = child;
                    path.push(step);
                }
                None => break,
            }
        }
        path
    }

    /// Probability of class B for each input row: the training share of its leaf (soft gate),
    /// or 0/1 from the tree's class (hard gate, or a leaf without a recorded share).
    pub fn share_b(&self, inputs: &[Vec<f64>]) -> Vec<f64> {
        let classes = self.classify(inputs);
        inputs
            .iter()
            .zip(classes)
            .map(|(row, class)| match self.gate {
                Gate::Soft => self
                    .leaf_share_b
                    .get(&self.leaf_path(row))
                    .copied()
                    .unwrap_or(class as f64),
                Gate::Hard => class as f64,
            })
            .collect()
    }

    /// The true class of each sample, from its error.
    pub fn truth(&self, samples: &Samples) -> Vec<usize> {
        samples
            .errors
            .iter()
            .map(|e| usize::from(e[self.axis] >= self.threshold))
            .collect()
    }

    /// Fraction of samples whose predicted class is the true one.
    pub fn accuracy(&self, samples: &Samples) -> f64 {
        if samples.is_empty() {
            return f64::NAN;
        }
        let hit = self
            .classify(&samples.inputs)
            .iter()
            .zip(self.truth(samples))
            .filter(|(p, t)| **p == *t)
            .count();
        hit as f64 / samples.len() as f64
    }
}

/// Two-means in one dimension: the threshold between two groups that minimises the within-group
/// sum of squares (every split of the sorted values is tried).
pub fn two_means_threshold(values: &[f64]) -> Option<f64> {
    let mut v: Vec<f64> = values.iter().copied().filter(|x| x.is_finite()).collect();
    if v.len() < 2 {
        return None;
    }
    v.sort_by(f64::total_cmp);
    let n = v.len();
    let total: f64 = v.iter().sum();
    let total_sq: f64 = v.iter().map(|x| x * x).sum();
    let (mut best, mut threshold) = (f64::INFINITY, None);
    let (mut s, mut s2) = (0.0, 0.0);
    for k in 1..n {
        s += v[k - 1];
        s2 += v[k - 1] * v[k - 1];
        if v[k] == v[k - 1] {
            continue;
        }
        let (m1, m2) = (k as f64, (n - k) as f64);
        let sse = (s2 - s * s / m1) + ((total_sq - s2) - (total - s).powi(2) / m2);
        if sse < best {
            best = sse;
            threshold = Some(0.5 * (v[k - 1] + v[k]));
        }
    }
    threshold
}

/// A trained residual model.
#[derive(Debug, Clone)]
pub struct ResidualModel {
    /// Which model.
    pub kind: ResidualKind,
    /// Length of an input row.
    pub inputs: usize,
    /// The networks: SOMM X, Y, Z; MOSM one; CA-SOMM A's X, Y, Z then B's.
    pub nets: Vec<AxisNet>,
    /// The CA-SOMM gate.
    pub classifier: Option<Classifier>,
    /// The hyper-parameter searches that chose the networks' settings (empty without search).
    pub search: Vec<SearchLog>,
    /// How input rows are encoded before anything sees them.
    pub encoding: Encoding,
    /// The Gaussian process (GP).
    pub gp: Option<GpResidual>,
}

/// A model file's manifest entry for one network.
#[derive(Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct NetEntry {
    file: String,
    axes: Vec<usize>,
    settings: NetSettings,
    input_scale: Standardizer,
    output_scale: Standardizer,
    report: TrainReport,
}

#[derive(Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct Manifest {
    residual_format: u32,
    kind: ResidualKind,
    inputs: usize,
    nets: Vec<NetEntry>,
    classifier: Option<Classifier>,
    #[serde(default)]
    search: Vec<SearchLog>,
    #[serde(default, skip_serializing_if = "Encoding::is_raw")]
    encoding: Encoding,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    gp: Option<GpResidual>,
}

/// Most inputs a residual model may take (joint angles and the load: 1 to 63 joints).
pub const MAX_INPUTS: usize = 64;

/// Manifest file name inside a model directory.
pub const MANIFEST: &str = "residual.json";

impl ResidualModel {
    /// Trains the model `settings` describe on `train_set`, early-stopping on `validation`.
    /// `progress` advances by one per epoch of every network.
    pub fn fit(
        settings: &ResidualSettings,
        train_set: &Samples,
        validation: &Samples,
        progress: &dyn Observer,
    ) -> Result<Self> {
        settings.check()?;
        let inputs = match train_set.inputs.first() {
            Some(r) => r.len(),
            None => return Err(ResidualError::Data("no training samples".into())),
        };
        if train_set
            .inputs
            .iter()
            .chain(&validation.inputs)
            .any(|r| r.len() != inputs)
        {
            return Err(ResidualError::Data(
                "input rows of different lengths".into(),
            ));
        }
        let seed = settings.seed;
        let encoding = settings.encoding;
        let encoded = |s: &Samples| Samples {
            inputs: encoding.encode_all(&s.inputs),
            errors: s.errors.clone(),
        };
        let (train_set, validation) = (&encoded(train_set), &encoded(validation));
        if settings.kind == ResidualKind::Gp {
            return Ok(Self {
                kind: settings.kind,
                inputs,
                nets: Vec::new(),
                classifier: None,
                search: Vec::new(),
                encoding,
                gp: Some(GpResidual::fit(&settings.gp, train_set, seed)?),
            });
        }
        let (settings, search_logs) = Self::searched(settings, train_set, validation);
        let settings = &settings;
        // One axis's network; a SOMM set is the three of them.
        let fit = |a: usize, set: &Samples, val: &Samples, offset: u64| {
            AxisNet::fit(
                vec![a],
                &settings.axes[a],
                set,
                val,
                seed.wrapping_add(offset + a as u64),
                progress,
            )
        };
        let somm = |set: &Samples, val: &Samples, offset: u64| -> Vec<AxisNet> {
            (0..3).map(|a| fit(a, set, val, offset)).collect()
        };
        let (nets, classifier) = match settings.kind {
            ResidualKind::Somm | ResidualKind::Gp => (somm(train_set, validation, 0), None),
            ResidualKind::Mosm => (
                vec![AxisNet::fit(
                    vec![0, 1, 2],
                    &settings.mosm,
                    train_set,
                    validation,
                    seed,
                    progress,
                )],
                None,
            ),
            ResidualKind::CaSomm => {
                let c = &settings.classifier;
                let axis = match c.axis {
                    'y' => 1,
                    'z' => 2,
                    _ => 0,
                };
                let values: Vec<f64> = train_set.errors.iter().map(|e| e[axis]).collect();
                let threshold = two_means_threshold(&values).ok_or_else(|| {
                    ResidualError::Data(format!(
                        "the {} error has fewer than two distinct values: nothing to classify",
                        c.axis
                    ))
                })?;
                let labels: Vec<usize> = values
                    .iter()
                    .map(|v| usize::from(*v >= threshold))
                    .collect();
                let features = encoding.features(inputs);
                let x = Array2::from_shape_fn((train_set.len(), features), |(i, j)| {
                    train_set.inputs[i][j]
                });
                let data = Dataset::new(x, Array1::from_vec(labels.clone()));
                let tree = DecisionTree::params()
                    .max_depth(Some(c.max_depth))
                    .min_weight_leaf(c.min_samples_leaf as f32)
                    .fit(&data)
                    .map_err(|e| ResidualError::Data(format!("classifier: {e}")))?;
                let mut classifier = Classifier {
                    axis,
                    threshold,
                    tree,
                    gate: c.gate,
                    leaf_share_b: BTreeMap::new(),
                };
                let mut counts: BTreeMap<String, (usize, usize)> = BTreeMap::new();
                for (row, label) in train_set.inputs.iter().zip(&labels) {
                    let n = counts.entry(classifier.leaf_path(row)).or_default();
                    n.0 += 1;
                    n.1 += label;
                }
                classifier.leaf_share_b = counts
                    .into_iter()
                    .map(|(leaf, (n, b))| (leaf, b as f64 / n as f64))
                    .collect();
                let in_b: Vec<bool> = labels.iter().map(|l| *l == 1).collect();
                let in_a: Vec<bool> = in_b.iter().map(|b| !b).collect();
                let val_b: Vec<bool> = classifier
                    .truth(validation)
                    .iter()
                    .map(|l| *l == 1)
                    .collect();
                let val_a: Vec<bool> = val_b.iter().map(|b| !b).collect();
                for (name, keep) in [("A", &in_a), ("B", &in_b)] {
                    if keep.iter().filter(|k| **k).count() < 2 {
                        return Err(ResidualError::Data(format!(
                            "class {name} has fewer than two training samples"
                        )));
                    }
                }
                let (train_a, val_a) = (train_set.subset(&in_a), validation.subset(&val_a));
                let (train_b, val_b) = (train_set.subset(&in_b), validation.subset(&val_b));
                let nets = match c.per_class {
                    PerClass::All => {
                        let mut nets = somm(&train_a, &val_a, 0);
                        nets.extend(somm(&train_b, &val_b, 10));
                        nets
                    }
                    PerClass::Axis => {
                        let shared: Vec<Option<AxisNet>> = (0..3)
                            .map(|a| (a != axis).then(|| fit(a, train_set, validation, 0)))
                            .collect();
                        let mut nets = Vec::with_capacity(6);
                        for (set, val, offset) in [(&train_a, &val_a, 0), (&train_b, &val_b, 10)] {
                            for (a, net) in shared.iter().enumerate() {
                                nets.push(match net {
                                    Some(n) => n.clone(),
                                    None => fit(a, set, val, offset),
                                });
                            }
                        }
                        nets
                    }
                };
                (nets, Some(classifier))
            }
        };
        Ok(Self {
            kind: settings.kind,
            inputs,
            nets,
            classifier,
            search: search_logs,
            encoding,
            gp: None,
        })
    }

    /// The settings after the TPE search `settings.search` asks for (each network searched on
    /// the whole training set; CA-SOMM's two sets share the result), and the search logs.
    fn searched(
        settings: &ResidualSettings,
        train_set: &Samples,
        validation: &Samples,
    ) -> (ResidualSettings, Vec<SearchLog>) {
        let mut tuned = settings.clone();
        let Some(s) = &settings.search else {
            return (tuned, Vec::new());
        };
        let seed = settings.seed;
        let score = |axes: Vec<usize>, offset: u64| {
            move |ns: &NetSettings| {
                let net = AxisNet::fit(
                    axes.clone(),
                    ns,
                    train_set,
                    validation,
                    seed + offset,
                    &Silent,
                );
                net.report
                    .validation_loss
                    .iter()
                    .copied()
                    .fold(f64::INFINITY, f64::min)
            }
        };
        let mut logs = Vec::new();
        if settings.kind == ResidualKind::Mosm {
            let (best, log) = search(
                &settings.mosm,
                s,
                vec![0, 1, 2],
                seed + 100,
                score(vec![0, 1, 2], 0),
            );
            tuned.mosm = best;
            logs.push(log);
        } else {
            for a in 0..3 {
                let (best, log) = search(
                    &settings.axes[a],
                    s,
                    vec![a],
                    seed + 100 + a as u64,
                    score(vec![a], a as u64),
                );
                tuned.axes[a] = best;
                logs.push(log);
            }
        }
        (tuned, logs)
    }

    /// Epochs the training of `settings` can take at most: the length of a progress bar.
    pub fn max_epochs(settings: &ResidualSettings) -> u64 {
        let axes: usize = settings.axes.iter().map(|s| s.max_epochs).sum();
        (match settings.kind {
            ResidualKind::Somm => axes,
            ResidualKind::Mosm => settings.mosm.max_epochs,
            ResidualKind::CaSomm => 2 * axes,
            ResidualKind::Gp => 0,
        }) as u64
    }

    /// Predicted error (mm, world X/Y/Z) for each input row.
    pub fn predict(&self, inputs: &[Vec<f64>]) -> Vec<[f64; 3]> {
        self.predict_with_std(inputs, false).0
    }

    /// Predicted error (mm, world X/Y/Z) for each input row, and — for a model that knows how
    /// sure it is (the GP) and when `std` is asked for — the standard deviation of each axis's
    /// correction (mm).
    pub fn predict_with_std(
        &self,
        inputs: &[Vec<f64>],
        std: bool,
    ) -> (Vec<[f64; 3]>, Option<Vec<[f64; 3]>>) {
        let encoded = self.encoding.encode_all(inputs);
        if let Some(gp) = &self.gp {
            return gp.predict(&encoded, std);
        }
        (self.predict_encoded(&encoded), None)
    }

    fn predict_encoded(&self, inputs: &[Vec<f64>]) -> Vec<[f64; 3]> {
        let mut out = vec![[0.0; 3]; inputs.len()];
        match &self.classifier {
            None => {
                for net in &self.nets {
                    net.predict_into(inputs, &mut out);
                }
            }
            Some(c) => {
                let share = c.share_b(inputs);
                for (class, nets) in self.nets.chunks(3).enumerate() {
                    let weight = |i: usize| if class == 1 { share[i] } else { 1.0 - share[i] };
                    let keep: Vec<usize> = (0..inputs.len()).filter(|&i| weight(i) > 0.0).collect();
                    if keep.is_empty() {
                        continue;
                    }
                    let rows: Vec<Vec<f64>> = keep.iter().map(|&i| inputs[i].clone()).collect();
                    let mut part = vec![[0.0; 3]; rows.len()];
                    for net in nets {
                        net.predict_into(&rows, &mut part);
                    }
                    for (&i, p) in keep.iter().zip(part) {
                        let w = weight(i);
                        for a in 0..3 {
                            out[i][a] += w * p[a];
                        }
                    }
                }
            }
        }
        out
    }

    fn net_file(&self, i: usize) -> String {
        let axis = ["x", "y", "z"];
        match self.kind {
            ResidualKind::Somm | ResidualKind::Gp => format!("residual-{}.bpk", axis[i]),
            ResidualKind::Mosm => "residual-xyz.bpk".into(),
            ResidualKind::CaSomm => {
                format!("residual-{}-{}.bpk", ["a", "b"][i / 3], axis[i % 3])
            }
        }
    }

    /// Writes `residual.json` and one burn record per network into `dir` (an existing
    /// directory; the caller makes the whole directory atomic).
    pub fn save(&self, dir: &Path) -> Result<()> {
        let io = |path: PathBuf| move |source| ResidualError::Io { path, source };
        let mut entries = Vec::new();
        for (i, net) in self.nets.iter().enumerate() {
            let file = self.net_file(i);
            let path = dir.join(&file);
            // Burn draws parameter ids at random; numbered in order, the same network is the
            // same file.
            net.net
                .clone()
                .map(&mut SequentialIds(0))
                .save_file(&path)
                .map_err(|e| ResidualError::Format {
                    path: path.clone(),
                    message: format!("cannot write the network: {e}"),
                })?;
            entries.push(NetEntry {
                file,
                axes: net.axes.clone(),
                settings: net.settings.clone(),
                input_scale: net.input_scale.clone(),
                output_scale: net.output_scale.clone(),
                report: net.report.clone(),
            });
        }
        let manifest = Manifest {
            residual_format: RESIDUAL_FORMAT,
            kind: self.kind,
            inputs: self.inputs,
            nets: entries,
            classifier: self.classifier.clone(),
            search: self.search.clone(),
            encoding: self.encoding,
            gp: self.gp.clone(),
        };
        let path = dir.join(MANIFEST);
        let text = serde_json::to_string_pretty(&manifest).map_err(|e| ResidualError::Format {
            path: path.clone(),
            message: e.to_string(),
        })?;
        std::fs::write(&path, text + "\n").map_err(io(path))
    }

    /// Reads a model written by [`Self::save`] from `dir`.
    pub fn load(dir: &Path) -> Result<Self> {
        let path = dir.join(MANIFEST);
        let text = std::fs::read_to_string(&path).map_err(|source| ResidualError::Io {
            path: path.clone(),
            source,
        })?;
        let format = |message: String| ResidualError::Format {
            path: path.clone(),
            message,
        };
        let version: serde_json::Value =
            serde_json::from_str(&text).map_err(|e| format(e.to_string()))?;
        match version
            .get("residual_format")
            .and_then(serde_json::Value::as_u64)
        {
            Some(v) if v == u64::from(RESIDUAL_FORMAT) => {}
            Some(v) => {
                return Err(format(format!(
                    "residual_format {v}: this robocal reads format {RESIDUAL_FORMAT}"
                )));
            }
            None => return Err(format("no residual_format field".into())),
        }
        let m: Manifest = serde_json::from_value(version).map_err(|e| format(e.to_string()))?;
        let expected = match m.kind {
            ResidualKind::Somm => 3,
            ResidualKind::Mosm => 1,
            ResidualKind::CaSomm => 6,
            ResidualKind::Gp => 0,
        };
        if (m.kind == ResidualKind::Gp) != m.gp.is_some() {
            return Err(format(format!(
                "a {} model {} a `gp` section",
                m.kind.name(),
                if m.kind == ResidualKind::Gp {
                    "needs"
                } else {
                    "has no"
                }
            )));
        }
        if m.nets.len() != expected || (m.kind == ResidualKind::CaSomm) != m.classifier.is_some() {
            return Err(format(format!(
                "a {} model has {expected} networks{}",
                m.kind.name(),
                if m.kind == ResidualKind::CaSomm {
                    " and a classifier"
                } else {
                    ""
                }
            )));
        }
        let features = m.encoding.features(m.inputs);
        if let Some(c) = &m.classifier {
            c.check(features).map_err(format)?;
        }
        if let Some(gp) = &m.gp {
            gp.check(features).map_err(format)?;
        }
        let device = Device::flex();
        let mut nets = Vec::new();
        if m.inputs == 0 || m.inputs > MAX_INPUTS {
            return Err(format(format!(
                "inputs {}: a residual model takes 1 to {MAX_INPUTS} inputs",
                m.inputs
            )));
        }
        for (i, e) in m.nets.into_iter().enumerate() {
            if let Err((field, message)) = e.settings.check() {
                return Err(format(format!("nets[{i}].settings.{field}: {message}")));
            }
            // The network file sits beside the manifest: a bare file name, nothing else.
            if std::path::Path::new(&e.file).file_name() != Some(std::ffi::OsStr::new(&e.file)) {
                return Err(format(format!(
                    "nets[{i}].file {:?}: must be a file name in the model directory",
                    e.file
                )));
            }
            if !e.input_scale.fits(features)
                || !e.output_scale.fits(e.axes.len())
                || e.axes.is_empty()
                || e.axes.iter().any(|a| *a > 2)
            {
                return Err(format(format!(
                    "{}: scaling does not fit the network",
                    e.file
                )));
            }
            let file = dir.join(&e.file);
            let net = Mlp::new(
                features,
                &e.settings.hidden,
                e.axes.len(),
                e.settings.activation,
                &device,
            )
            .try_load_file(&file)
            .map_err(|err| ResidualError::Format {
                path: file.clone(),
                message: format!("cannot read the network: {err}"),
            })?;
            nets.push(AxisNet {
                axes: e.axes,
                settings: e.settings,
                input_scale: e.input_scale,
                output_scale: e.output_scale,
                report: e.report,
                dense: net.dense(),
                net,
            });
        }
        Ok(Self {
            kind: m.kind,
            inputs: m.inputs,
            nets,
            classifier: m.classifier,
            search: m.search,
            encoding: m.encoding,
            gp: m.gp,
        })
    }
}
