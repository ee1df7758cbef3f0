//! Where the candidates are scored: the folds, the blocks of joint 1 or the validation file.

use super::settings::AutoSettings;
use crate::folds::{Fold, blocks, folds, splits_of};
use crate::rows::configurations;
use robocal_data::Measurement;
use robocal_ident::FitMemo;

/// Where the candidates are scored: the folds, how they were made, and whether the winner is
/// fitted again on every row.
pub(super) struct FoldPlan<'a> {
    pub(super) splits: Vec<Fold<'a>>,
    /// One per split: the alignments and identifications of its training rows, which the
    /// physical candidates share (the first fit of one is often another's whole fit).
    pub(super) memos: Vec<FitMemo>,
    pub(super) held_out: String,
    pub(super) refit: bool,
}

impl<'a> FoldPlan<'a> {
    /// The validation file as the one fold, or random folds and blocks of joint 1; `None` with
    /// fewer than 4 configurations and no validation file.
    pub(super) fn new(
        settings: &AutoSettings,
        rows: &[&'a Measurement],
        validation: Option<&(&[&'a Measurement], String)>,
    ) -> Option<Self> {
        let n_configurations = configurations(rows).len();
        match validation {
            Some((v, source)) => Some(Self {
                splits: vec![Fold {
                    train: rows.to_vec(),
                    test: v.to_vec(),
                    blocked: false,
                }],
                memos: vec![FitMemo::default()],
                held_out: source.clone(),
                refit: false,
            }),
            None if n_configurations >= 4 => {
                let (fold_of, k) = folds(rows, settings.folds, settings.seed);
                let mut splits = splits_of(rows, &fold_of, k, false);
                let (block_of, kb) = blocks(rows, settings.folds);
                splits.extend(splits_of(rows, &block_of, kb, true));
                Some(Self {
                    memos: splits.iter().map(|_| FitMemo::default()).collect(),
                    splits,
                    held_out: format!(
                        "{k}-fold cross-validation over {n_configurations} configurations (seed {}), and {kb} blocks of joint 1's range",
                        settings.seed
                    ),
                    refit: true,
                })
            }
            None => None,
        }
    }

    /// The fewest configurations any fold trains on (what a residual model needs enough of).
    pub(super) fn fewest_configurations(&self) -> usize {
        (self.splits.iter())
            .map(|f| configurations(&f.train).len())
            .min()
            .unwrap_or(0)
    }

    /// One group per configuration and kind of fold, in the order [`Held::all`] keeps the
    /// errors: the units of the paired test (a configuration: a pose id and every id with the
    /// same joint readings, as the folds deal them).
    pub(super) fn groups(&self) -> Vec<usize> {
        let tested: Vec<&Measurement> = (self.splits.iter())
            .flat_map(|f| f.test.iter().copied())
            .collect();
        let of = crate::folds::configuration_of(&tested);
        let mut ids: std::collections::HashMap<(&str, bool), usize> = Default::default();
        let mut out = Vec::new();
        for blocked in [false, true] {
            for fold in self.splits.iter().filter(|f| f.blocked == blocked) {
                for r in &fold.test {
                    let pose = r.sample.pose.as_str();
                    let configuration = of.get(pose).copied().unwrap_or(pose);
                    let next = ids.len();
                    out.push(*ids.entry((configuration, blocked)).or_insert(next));
                }
            }
        }
        out
    }
}
