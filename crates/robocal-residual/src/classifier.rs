//! The CA-SOMM gate: which world axis's error splits the rows into two classes, and a linfa
//! decision tree that tells the class from the inputs.

use std::collections::BTreeMap;

use linfa::prelude::*;
use linfa_trees::DecisionTree;
use ndarray::Array2;
use serde::{Deserialize, Serialize};

use crate::samples::{Encoding, Samples};

/// A world axis.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Axis {
    /// X.
    #[default]
    X,
    /// Y.
    Y,
    /// Z.
    Z,
}

impl Axis {
    /// Every axis, in order.
    pub const ALL: [Self; 3] = [Self::X, Self::Y, Self::Z];

    /// 0, 1, 2 for X, Y, Z: the column of an error triple.
    pub fn index(self) -> usize {
        self as usize
    }

    /// `x`, `y` or `z`.
    pub fn name(self) -> &'static str {
        ["x", "y", "z"][self.index()]
    }
}

impl std::fmt::Display for Axis {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

fn default_depth() -> usize {
    3
}
fn default_leaf() -> usize {
    66
}
fn default_axis() -> Axis {
    Axis::X
}

/// The CA-SOMM classifier's settings (paper section V-B3).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ClassifierSettings {
    /// The bimodal axis whose error splits the training set: `x`, `y` or `z`.
    #[serde(default = "default_axis")]
    pub axis: Axis,
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
    /// What the tree reads: `model` (the residual model's own inputs: the paper's raw angles
    /// and load under the paper's defaults), `periodic` (sin and cos of every angle, and the
    /// load) or `physics` (periodic, plus per joint the payload's gravity torque per kg and
    /// under the load, and the measured point's motion per degree, from the identified table:
    /// [`GateInputs::Physics`]). Absent: `model` under the paper's defaults, `physics` under
    /// robocal's.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub inputs: Option<GateInputs>,
    /// The payload's centre of mass in the flange frame (mm) for the `physics` inputs; absent:
    /// the joint-error model's, else the measured point.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub payload_com: Option<[f64; 3]>,
    /// Gravity in the robot base frame (m/s²) for the `physics` inputs; absent: the
    /// joint-error model's, else `[0, 0, -9.80665]`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gravity: Option<[f64; 3]>,
    /// Whether to keep one class when two do not pay: a SOMM is trained on every row beside
    /// the two sets, and the two sets are kept only when they beat it on the validation rows
    /// significantly ([`GateDecision`](crate::GateDecision)). Absent: no under the paper's
    /// defaults (its CA-SOMM as printed), yes under robocal's.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fallback: Option<bool>,
    /// Which rows each class's networks train on: `threshold` (the paper: the rows on each side
    /// of the two-means threshold of the axis's error) or `routed` (the threshold's classes
    /// teach the tree; each set then trains on the rows the tree sends it). Absent: `threshold`
    /// under the paper's defaults, `routed` under robocal's.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub classes: Option<ClassRule>,
    /// Whether to choose the tree's depth and fewest rows per leaf from a grid
    /// ([`TREE_DEPTHS`](crate::casomm::TREE_DEPTHS) × [`TREE_LEAVES`](crate::casomm::TREE_LEAVES))
    /// by its accuracy on the validation rows, instead of `max_depth` and `min_samples_leaf`.
    /// Absent: no under the paper's defaults, yes under robocal's.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tree_search: Option<bool>,
}

/// How CA-SOMM's two classes are made.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ClassRule {
    /// The two-means threshold of the axis's error (the paper's).
    #[default]
    Threshold,
    /// The threshold's classes teach the tree; each set then trains on the rows the tree sends
    /// it, as it will see them when predicting (a row whose error crosses the threshold for a
    /// reason the inputs cannot tell is left where the tree puts it).
    Routed,
}

impl ClassRule {
    /// Name in files.
    pub fn name(self) -> &'static str {
        match self {
            Self::Threshold => "threshold",
            Self::Routed => "routed",
        }
    }
}

/// Physics features per joint that a gate reading physics gets (computed by the model that
/// knows the robot): the payload's lever (N·m/kg), its torque (N·m), and the measured point's
/// world X, Y, Z motion per degree of the joint (mm/deg), in that order, each block over every
/// joint.
pub const PHYSICS_PER_JOINT: usize = 5;

/// What the CA-SOMM tree reads.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum GateInputs {
    /// The residual model's encoded inputs (the paper's: raw angles and the load).
    #[default]
    Model,
    /// `sin q, cos q` of every angle, then the load.
    Periodic,
    /// [`GateInputs::Periodic`], then the [`PHYSICS_PER_JOINT`] blocks over every joint: the
    /// payload's gravity lever (N·m per kg), its torque under the row's load (N·m), and the
    /// measured point's world X, Y, Z motion per degree (mm/deg). The flank a joint with play
    /// rests on is set by the sign of such a torque, and the point jumps along the joint's
    /// motion.
    Physics,
}

impl GateInputs {
    /// Every kind, in order.
    pub const ALL: [Self; 3] = [Self::Model, Self::Periodic, Self::Physics];

    /// Features the tree reads for a residual model of `inputs` raw inputs (the joints, then
    /// the load) that encodes them with `encoding`.
    pub fn features(self, encoding: Encoding, inputs: usize) -> usize {
        match self {
            Self::Model => encoding.features(inputs),
            Self::Periodic => Encoding::Periodic.features(inputs),
            Self::Physics => {
                Encoding::Periodic.features(inputs) + PHYSICS_PER_JOINT * inputs.saturating_sub(1)
            }
        }
    }

    /// Name in files.
    pub fn name(self) -> &'static str {
        match self {
            Self::Model => "model",
            Self::Periodic => "periodic",
            Self::Physics => "physics",
        }
    }
}

/// Where the `physics` gate's gravity torques come from, as resolved when the model was trained
/// and saved with it (prediction computes the same features).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GatePhysics {
    /// Gravity in the robot base frame {0}, m/s².
    pub gravity: [f64; 3],
    /// The payload's centre of mass in the flange frame, mm.
    pub payload_com: [f64; 3],
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
            inputs: None,
            payload_com: None,
            gravity: None,
            fallback: None,
            classes: None,
            tree_search: None,
        }
    }
}

impl ClassifierSettings {
    /// What the tree reads (`model` when not resolved).
    pub fn gate_inputs(&self) -> GateInputs {
        self.inputs.unwrap_or_default()
    }

    /// The physics the tree reads, when it reads physics and both quantities are resolved.
    pub fn physics(&self) -> Option<GatePhysics> {
        match (self.gate_inputs(), self.gravity, self.payload_com) {
            (GateInputs::Physics, Some(gravity), Some(payload_com)) => Some(GatePhysics {
                gravity,
                payload_com,
            }),
            _ => None,
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
    /// What the tree reads.
    #[serde(default)]
    pub inputs: GateInputs,
    /// The gravity and payload the `physics` inputs were computed with.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub physics: Option<GatePhysics>,
    /// Training rows in class A and in class B.
    #[serde(default)]
    pub class_rows: [usize; 2],
    /// Which rows each class's networks trained on.
    #[serde(default)]
    pub classes: ClassRule,
    /// The tree's depth limit.
    #[serde(default)]
    pub max_depth: usize,
    /// The tree's fewest training rows per leaf.
    #[serde(default)]
    pub min_samples_leaf: usize,
    /// The tree search: (depth, fewest rows per leaf, validation accuracy) of every grid point
    /// tried (empty without a search).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub tree_search: Vec<(usize, usize, f64)>,
}

impl Classifier {
    /// Class of each input row (0 = A, 1 = B).
    ///
    /// A leaf whose share of class B among the training rows is recorded gives class B when
    /// that share is above one half, class A otherwise (linfa breaks a tie by hash order, which
    /// differs between runs); a leaf without one gives the tree's class.
    pub fn classify(&self, inputs: &[Vec<f64>]) -> Vec<usize> {
        (self.shares(inputs).into_iter())
            .map(|(share, tree)| share.map_or(tree, |p| usize::from(p > 0.5)))
            .collect()
    }

    /// Per row, its leaf's recorded share of class B (one walk down the tree), and the tree's
    /// own class where no share is recorded (linfa's prediction, for those rows only; 0
    /// where a share is).
    fn shares(&self, inputs: &[Vec<f64>]) -> Vec<(Option<f64>, usize)> {
        let mut out: Vec<(Option<f64>, usize)> = (inputs.iter())
            .map(|row| (self.leaf_share_b.get(&self.leaf_path(row)).copied(), 0))
            .collect();
        let missing: Vec<usize> = (0..inputs.len()).filter(|&i| out[i].0.is_none()).collect();
        if let Some(&first) = missing.first() {
            let cols = inputs[first].len();
            let x = Array2::from_shape_fn((missing.len(), cols), |(i, j)| inputs[missing[i]][j]);
            for (&i, class) in missing.iter().zip(self.tree.predict(&x)) {
                out[i].1 = class;
            }
        }
        out
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
        let physics_ok = match (self.inputs, &self.physics) {
            (GateInputs::Physics, Some(p)) => p
                .gravity
                .iter()
                .chain(&p.payload_com)
                .all(|v| v.is_finite()),
            (GateInputs::Physics, None) => false,
            (_, p) => p.is_none(),
        };
        if !physics_ok {
            return Err(
                "classifier: `physics` (finite gravity and payload_com) goes with inputs = \"physics\" and only with it".into(),
            );
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
        (self.shares(inputs).into_iter())
            .map(|(share, tree)| match (self.gate, share) {
                (Gate::Soft, Some(p)) => p,
                (Gate::Hard, Some(p)) => f64::from(u8::from(p > 0.5)),
                (_, None) => tree as f64,
            })
            .collect()
    }

    /// The class each sample's networks trained on: the tree's class (routed) or the side of
    /// the threshold. `encoded`: the samples' inputs as the model encodes them.
    pub fn training_classes(&self, encoded: &[Vec<f64>], samples: &Samples) -> Vec<usize> {
        match self.classes {
            ClassRule::Routed => self.classify(&self.rows(encoded, samples)),
            ClassRule::Threshold => self.truth(samples),
        }
    }

    /// The true class of each sample, from its error: the side of the threshold.
    pub fn truth(&self, samples: &Samples) -> Vec<usize> {
        samples
            .errors
            .iter()
            .map(|e| usize::from(e[self.axis] >= self.threshold))
            .collect()
    }

    /// The rows the tree reads, from the model's `encoded` rows and the `raw` samples (their
    /// input rows and, for the `physics` inputs, their physics rows).
    pub fn rows(&self, encoded: &[Vec<f64>], raw: &Samples) -> Vec<Vec<f64>> {
        gate_rows(self.inputs, encoded, raw)
    }

    /// Fraction of samples whose predicted class is the true one; `rows` are the tree's rows
    /// of the samples ([`Self::rows`]).
    pub fn accuracy(&self, rows: &[Vec<f64>], samples: &Samples) -> f64 {
        if samples.is_empty() {
            return f64::NAN;
        }
        let hit = self
            .classify(rows)
            .iter()
            .zip(self.truth(samples))
            .filter(|(p, t)| **p == *t)
            .count();
        hit as f64 / samples.len() as f64
    }
}

/// The rows a tree reading `inputs` sees, from the model's `encoded` rows and the `raw`
/// samples. `physics` rows must be present for [`GateInputs::Physics`] (the caller's contract:
/// the calibrated model and the pipeline compute them).
pub fn gate_rows(inputs: GateInputs, encoded: &[Vec<f64>], raw: &Samples) -> Vec<Vec<f64>> {
    match inputs {
        GateInputs::Model => encoded.to_vec(),
        GateInputs::Periodic => Encoding::Periodic.encode_all(&raw.inputs),
        GateInputs::Physics => {
            assert_eq!(
                raw.physics.len(),
                raw.inputs.len(),
                "a gate reading physics needs one physics row per input row"
            );
            (raw.inputs.iter().zip(&raw.physics))
                .map(|(row, physics)| {
                    let mut out = Encoding::Periodic.encode(row);
                    out.extend_from_slice(physics);
                    out
                })
                .collect()
        }
    }
}

/// The names of the features a tree reading `inputs` sees, for a robot of `joints` joints
/// whose residual model encodes its inputs with `encoding`.
pub fn gate_feature_names(inputs: GateInputs, encoding: Encoding, joints: usize) -> Vec<String> {
    let periodic = || -> Vec<String> {
        let mut v: Vec<String> = (1..=joints)
            .flat_map(|j| [format!("sin q{j}"), format!("cos q{j}")])
            .collect();
        v.push("load".into());
        v
    };
    match (inputs, encoding) {
        (GateInputs::Model, Encoding::Raw) => {
            let mut v: Vec<String> = (1..=joints).map(|j| format!("q{j}")).collect();
            v.push("load".into());
            v
        }
        (GateInputs::Model | GateInputs::Periodic, _) => periodic(),
        (GateInputs::Physics, _) => {
            let mut v = periodic();
            v.extend((1..=joints).map(|j| format!("payload lever j{j}")));
            v.extend((1..=joints).map(|j| format!("payload torque j{j}")));
            for axis in ["X", "Y", "Z"] {
                v.extend((1..=joints).map(|j| format!("{axis} motion per degree of j{j}")));
            }
            v
        }
    }
}

impl Classifier {
    /// The tree's splits from the root, breadth first: (feature index, threshold, depth).
    pub fn splits(&self) -> Vec<(usize, f64, usize)> {
        let mut out = Vec::new();
        let mut level = vec![self.tree.root_node()];
        let mut depth = 0;
        while !level.is_empty() {
            let mut next = Vec::new();
            for node in level {
                if node.is_leaf() {
                    continue;
                }
                let (feature, value, _) = node.split();
                out.push((feature, value, depth));
                next.extend(node.children().into_iter().filter_map(|c| c.as_deref()));
            }
            level = next;
            depth += 1;
        }
        out
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
