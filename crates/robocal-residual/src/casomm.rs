//! CA-SOMM: a classifier picks one of two SOMM sets (the paper's CA-SOMM-ANN, section V-B3).
//!
//! The training rows are split in two classes at the two-means threshold of one axis's error;
//! a decision tree learns the class from the inputs; each class gets its own per-axis networks
//! (or, with `per_class = "axis"`, only the classifier's axis does).

use std::collections::BTreeMap;

use linfa::prelude::*;
use linfa_trees::DecisionTree;
use ndarray::{Array1, Array2};
use robocal_data::Observer;

use crate::classifier::{
    ClassRule, Classifier, ClassifierSettings, GateInputs, PerClass, gate_rows, two_means_threshold,
};
use crate::error::{ResidualError, Result};
use crate::mlp::NetSettings;
use crate::net::AxisNet;
use crate::residual::Residual;
use crate::samples::Samples;
use crate::somm::Somm;

/// The weight of a class-A row in the gate's tree (class B's weigh 1): it breaks a tie between
/// the classes' weights at a node toward A (`n_A (1 + 2⁻¹⁶) = n_B` needs 2¹⁶ rows of A). Exact
/// in `f32`.
pub const TIE_WEIGHT: f32 = 1.0 + 1.0 / 65536.0;

/// Depths a tree search tries ([`ClassifierSettings::tree_search`]).
pub const TREE_DEPTHS: [usize; 7] = [2, 3, 4, 6, 8, 10, 12];
/// Fewest rows per leaf a tree search tries, largest first (simpler trees first among equals).
pub const TREE_LEAVES: [usize; 5] = [66, 40, 20, 10, 5];

/// Rows in class A (label 0) and class B (label 1).
fn class_rows(labels: &[usize]) -> [usize; 2] {
    let b = labels.iter().filter(|l| **l == 1).count();
    [labels.len() - b, b]
}

/// The gate and the two model sets.
#[derive(Debug, Clone)]
pub struct CaSomm {
    /// The gate.
    pub classifier: Classifier,
    /// The networks of class A (X, Y, Z) and of class B.
    pub sets: [Somm; 2],
}

impl CaSomm {
    /// Splits the training rows into classes, fits the tree on the rows it reads (from the
    /// encoded `train_set` and the `raw` training samples: see [`gate_rows`]) and trains each
    /// class's networks (class A seeded like a SOMM, class B with offset 10).
    #[expect(
        clippy::too_many_arguments,
        reason = "the training data in its two forms"
    )]
    pub fn fit(
        c: &ClassifierSettings,
        axes: &[NetSettings; 3],
        train_set: &Samples,
        validation: &Samples,
        raw: &Samples,
        raw_validation: &Samples,
        seed: u64,
        progress: &dyn Observer,
    ) -> Result<Self> {
        let inputs = c.gate_inputs();
        let physics = c.physics();
        if inputs == GateInputs::Physics
            && (physics.is_none() || raw.physics.len() != raw.inputs.len())
        {
            return Err(ResidualError::Data(
                "a classifier reading physics needs the payload's centre of mass, gravity and one physics row per sample".into(),
            ));
        }
        let axis = c.axis.index();
        let values: Vec<f64> = train_set.errors.iter().map(|e| e[axis]).collect();
        let threshold = two_means_threshold(&values).ok_or_else(|| {
            ResidualError::Data(format!(
                "the {} error has fewer than two distinct values: nothing to classify",
                c.axis
            ))
        })?;
        let mut labels: Vec<usize> = values
            .iter()
            .map(|v| usize::from(*v >= threshold))
            .collect();
        let rows = gate_rows(inputs, &train_set.inputs, raw);
        let features = rows.first().map_or(0, Vec::len);
        let x = Array2::from_shape_fn((rows.len(), features), |(i, j)| rows[i][j]);
        // Class A's rows weigh a little more than B's (`TIE_WEIGHT`): linfa settles a node whose
        // classes weigh the same by its hash maps' order, which differs from one map to the next,
        // and prunes the siblings it then predicts alike, so an exact tie at a leaf made the
        // tree's shape, and the gate, differ between runs. Weighted, a tie goes to class A (as
        // the leaves' shares settle it below); elsewhere the split scores move by about the
        // weight's excess, far less than any two distinct splits' of a few hundred rows differ.
        let weights = labels
            .iter()
            .map(|&l| if l == 0 { TIE_WEIGHT } else { 1.0 });
        let data = Dataset::new(x, Array1::from_vec(labels.clone()))
            .with_weights(Array1::from_iter(weights));
        // A gate of a given size: the tree, and each leaf's share of class B among the
        // training rows (which also settles a leaf's class where linfa's tie would not).
        let gate = |depth: usize, leaf: usize| -> Result<Classifier> {
            let tree = DecisionTree::params()
                .max_depth(Some(depth))
                .min_weight_leaf(leaf as f32)
                .fit(&data)
                .map_err(|e| ResidualError::Data(format!("classifier: {e}")))?;
            let mut classifier = Classifier {
                axis,
                threshold,
                tree,
                gate: c.gate,
                leaf_share_b: BTreeMap::new(),
                inputs,
                physics,
                class_rows: class_rows(&labels),
                classes: c.classes.unwrap_or_default(),
                max_depth: depth,
                min_samples_leaf: leaf,
                tree_search: Vec::new(),
            };
            let mut counts: BTreeMap<String, (usize, usize)> = BTreeMap::new();
            for (row, label) in rows.iter().zip(&labels) {
                let n = counts.entry(classifier.leaf_path(row)).or_default();
                n.0 += 1;
                n.1 += label;
            }
            classifier.leaf_share_b = counts
                .into_iter()
                .map(|(leaf, (n, b))| (leaf, b as f64 / n as f64))
                .collect();
            Ok(classifier)
        };
        // The tree's size: as given, or the grid point whose tree classifies the validation
        // rows best (the smallest tree among equals).
        let mut size = (c.max_depth, c.min_samples_leaf);
        let mut search = Vec::new();
        if c.tree_search == Some(true) && !raw_validation.is_empty() {
            let val_rows = gate_rows(inputs, &validation.inputs, raw_validation);
            let mut best = f64::NEG_INFINITY;
            for &depth in &TREE_DEPTHS {
                for &leaf in &TREE_LEAVES {
                    let accuracy = gate(depth, leaf)?.accuracy(&val_rows, raw_validation);
                    search.push((depth, leaf, accuracy));
                    if accuracy > best {
                        best = accuracy;
                        size = (depth, leaf);
                    }
                }
            }
        }
        let mut classifier = gate(size.0, size.1)?;
        classifier.tree_search = search;
        let routed = c.classes == Some(ClassRule::Routed);
        if routed {
            labels = classifier.classify(&rows);
            classifier.class_rows = class_rows(&labels);
        }
        let in_b: Vec<bool> = labels.iter().map(|l| *l == 1).collect();
        let in_a: Vec<bool> = in_b.iter().map(|b| !b).collect();
        let val_labels = if routed {
            classifier.classify(&gate_rows(inputs, &validation.inputs, raw_validation))
        } else {
            classifier.truth(raw_validation)
        };
        let val_b: Vec<bool> = val_labels.iter().map(|l| *l == 1).collect();
        let val_a: Vec<bool> = val_b.iter().map(|b| !b).collect();
        for (name, keep) in [("A", &in_a), ("B", &in_b)] {
            if keep.iter().filter(|k| **k).count() < 2 {
                return Err(ResidualError::EmptyClass { class: name });
            }
        }
        let (train_a, val_a) = (train_set.subset(&in_a), validation.subset(&val_a));
        let (train_b, val_b) = (train_set.subset(&in_b), validation.subset(&val_b));
        let sets = match c.per_class {
            PerClass::All => [
                Somm::fit(axes, &train_a, &val_a, seed, 0, progress),
                Somm::fit(axes, &train_b, &val_b, seed, 10, progress),
            ],
            PerClass::Axis => {
                // The other axes: one network on every row, which both sets share.
                let shared: Vec<Option<AxisNet>> = (0..3)
                    .map(|a| {
                        (a != axis).then(|| {
                            Somm::fit_axis(axes, a, train_set, validation, seed, 0, progress)
                        })
                    })
                    .collect();
                let set = |set: &Samples, val: &Samples, offset: u64| {
                    Somm::single(std::array::from_fn(|a| match &shared[a] {
                        Some(n) => n.clone(),
                        None => Somm::fit_axis(axes, a, set, val, seed, offset, progress),
                    }))
                };
                [set(&train_a, &val_a, 0), set(&train_b, &val_b, 10)]
            }
        };
        Ok(Self { classifier, sets })
    }
}

impl Residual for CaSomm {
    fn predict(
        &self,
        inputs: &[Vec<f64>],
        raw: &Samples,
        _std: bool,
    ) -> (Vec<[f64; 3]>, Option<Vec<[f64; 3]>>) {
        let mut out = vec![[0.0; 3]; inputs.len()];
        let share = self.classifier.share_b(&self.classifier.rows(inputs, raw));
        for (class, set) in self.sets.iter().enumerate() {
            let weight = |i: usize| if class == 1 { share[i] } else { 1.0 - share[i] };
            let keep: Vec<usize> = (0..inputs.len()).filter(|&i| weight(i) > 0.0).collect();
            if keep.is_empty() {
                continue;
            }
            let rows: Vec<Vec<f64>> = keep.iter().map(|&i| inputs[i].clone()).collect();
            let mut part = vec![[0.0; 3]; rows.len()];
            set.predict_into(&rows, &mut part);
            for (&i, p) in keep.iter().zip(part) {
                let w = weight(i);
                for a in 0..3 {
                    out[i][a] += w * p[a];
                }
            }
        }
        (out, None)
    }

    fn nets(&self) -> Vec<&AxisNet> {
        self.sets.iter().flat_map(Somm::all_nets).collect()
    }
}
