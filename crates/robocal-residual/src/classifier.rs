//! The CA-SOMM gate: which world axis's error splits the rows into two classes, and a linfa
//! decision tree that tells the class from the inputs.

use std::collections::BTreeMap;

use linfa::prelude::*;
use linfa_trees::DecisionTree;
use ndarray::Array2;
use serde::{Deserialize, Serialize};

use crate::samples::Samples;

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
