//! How the default calibration holds poses out: random folds of configurations
//! (interpolation), contiguous blocks of joint 1's range (extrapolation to a new working area),
//! and the paired test a richer model must pass to be kept.

use rand::SeedableRng;
use rand::seq::SliceRandom;
use rand_chacha::ChaCha8Rng;
use robocal_data::{ErrorStats, Measurement};
pub use robocal_data::{SIGNIFICANCE, improves};

use super::configurations;

/// The fold (0..k) of every row: configurations shuffled with `seed` and dealt round-robin, so
/// that every load of a configuration falls in one fold. `k` is capped at the number of
/// configurations.
pub fn folds(rows: &[&Measurement], k: usize, seed: u64) -> (Vec<usize>, usize) {
    let mut poses = configurations(rows);
    poses.shuffle(&mut ChaCha8Rng::seed_from_u64(seed));
    let k = k.clamp(1, poses.len().max(1));
    let fold: std::collections::HashMap<&str, usize> =
        poses.iter().enumerate().map(|(i, p)| (*p, i % k)).collect();
    (
        rows.iter()
            .map(|r| fold.get(r.sample.pose.as_str()).copied().unwrap_or(0))
            .collect(),
        k,
    )
}

/// One split of the rows: fitted on `train`, scored on `test`.
pub(crate) struct Fold<'a> {
    pub(crate) train: Vec<&'a Measurement>,
    pub(crate) test: Vec<&'a Measurement>,
    /// A block of joint 1's range (extrapolation), not a random fold.
    pub(crate) blocked: bool,
}

/// The rows of every fold of `fold_of` (`k` folds) as train/test splits.
pub(crate) fn splits_of<'a>(
    rows: &[&'a Measurement],
    fold_of: &[usize],
    k: usize,
    blocked: bool,
) -> Vec<Fold<'a>> {
    (0..k)
        .map(|f| {
            let (test, train) =
                (rows.iter().zip(fold_of)).partition::<Vec<_>, _>(|(_, g)| **g == f);
            Fold {
                train: train.into_iter().map(|(r, _)| *r).collect(),
                test: test.into_iter().map(|(r, _)| *r).collect(),
                blocked,
            }
        })
        .collect()
}

/// The block (0..k) of every row: configurations sorted by their joint-1 reading and cut into
/// `k` contiguous blocks of (nearly) equal count, so that each block's poses lie outside the
/// joint-1 range of the rest — how a cell's working area grows. `k` is capped at the number
/// of configurations.
pub fn blocks(rows: &[&Measurement], k: usize) -> (Vec<usize>, usize) {
    let mut poses: Vec<(&str, f64)> = rows
        .iter()
        .map(|r| {
            (
                r.sample.pose.as_str(),
                r.sample.joints.first().copied().unwrap_or(0.0),
            )
        })
        .collect();
    poses.sort_by(|a, b| a.0.cmp(b.0));
    poses.dedup_by(|a, b| a.0 == b.0);
    poses.sort_by(|a, b| a.1.total_cmp(&b.1).then(a.0.cmp(b.0)));
    let n = poses.len();
    let k = k.clamp(1, n.max(1));
    let block: std::collections::HashMap<&str, usize> = (poses.iter().enumerate())
        .map(|(i, p)| (p.0, i * k / n.max(1)))
        .collect();
    (
        rows.iter()
            .map(|r| block.get(r.sample.pose.as_str()).copied().unwrap_or(0))
            .collect(),
        k,
    )
}

/// Held-out errors of one candidate, split by the kind of fold.
#[derive(Default)]
pub(crate) struct Held {
    random: Vec<f64>,
    blocked: Vec<f64>,
}

impl Held {
    pub(crate) fn add(&mut self, fold: &Fold<'_>, errors: Vec<f64>) {
        if fold.blocked {
            self.blocked.extend(errors);
        } else {
            self.random.extend(errors);
        }
    }

    /// Every held-out error: the random folds', then the blocks'.
    pub(crate) fn all(&self) -> Vec<f64> {
        let mut all = self.random.clone();
        all.extend(&self.blocked);
        all
    }

    /// The candidate's statistics: random folds, blocks, and the selection score (the mean of
    /// the two means; the random folds' mean alone without blocks).
    pub(crate) fn summary(&self) -> (ErrorStats, Option<ErrorStats>, f64) {
        let random = ErrorStats::from_errors(&self.random);
        if self.blocked.is_empty() {
            return (random, None, random.mean);
        }
        let blocked = ErrorStats::from_errors(&self.blocked);
        (random, Some(blocked), 0.5 * (random.mean + blocked.mean))
    }
}

#[cfg(test)]
mod tests {
    use super::improves;

    /// The paired test by group, computed by hand: differences per group 0.2, 0.1, 0.3 (mean
    /// 0.2, standard error 0.0577) pass; with a group that got worse, 0.2, 0.1, −0.4 (mean
    /// −0.033) fail; a small, consistent gain passes and an inconsistent one does not.
    #[test]
    fn improvement_must_exceed_twice_its_standard_error() {
        let groups = [0, 0, 1, 2, 2];
        let base = [1.0, 1.0, 1.0, 1.0, 1.0];
        assert!(improves(&base, &[0.8, 0.8, 0.9, 0.7, 0.7], &groups));
        assert!(!improves(&base, &[0.8, 0.8, 0.9, 1.4, 1.4], &groups));
        // Mean 0.01, standard error 0.0029: 3.5 standard errors.
        assert!(improves(
            &[1.0, 1.0, 1.0],
            &[0.99, 0.995, 0.985],
            &[0, 1, 2]
        ));
        // Mean 0.01, standard error 0.0173: 0.6 standard errors.
        assert!(!improves(&[1.0, 1.0, 1.0], &[0.96, 1.02, 0.99], &[0, 1, 2]));
    }
}
