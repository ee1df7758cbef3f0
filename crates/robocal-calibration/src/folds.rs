//! How the default calibration holds poses out: random folds of configurations
//! (interpolation), contiguous blocks of joint 1's range (extrapolation to a new working area),
//! and the paired test a richer model must pass to be kept.

use std::collections::HashMap;

use rand::SeedableRng;
use rand::seq::SliceRandom;
use rand_chacha::ChaCha8Rng;
use robocal_data::{ErrorStats, Measurement};
pub use robocal_data::{SIGNIFICANCE, improves};

use crate::rows::{configurations, readings_key};

/// Every pose id's configuration: the smallest pose id whose rows have the same joint readings
/// (a reference pose measured again under a new id, as a drift check is, is one configuration:
/// held out with its first measurement, never predicted from it). Ids whose readings no other id
/// shares are their own.
pub(crate) fn configuration_of<'a>(rows: &[&'a Measurement]) -> HashMap<&'a str, &'a str> {
    let mut first: HashMap<Vec<u64>, &str> = HashMap::new();
    for r in rows {
        let pose = r.sample.pose.as_str();
        let id = first.entry(readings_key(r)).or_insert(pose);
        *id = (*id).min(pose);
    }
    (rows.iter())
        .map(|r| (r.sample.pose.as_str(), first[&readings_key(r)]))
        .collect()
}

/// Every row's configuration numbered from 0 (in the order of the configurations' first ids), and
/// how many there are: the units of a paired test and of holding one configuration out, a pose id
/// and every id with the same joint readings ([`configuration_of`]) being one.
pub(crate) fn configuration_groups(rows: &[&Measurement]) -> (Vec<usize>, usize) {
    let of = configuration_of(rows);
    let mut ids: Vec<&str> = of.values().copied().collect();
    ids.sort_unstable();
    ids.dedup();
    let groups = (rows.iter())
        .map(|r| {
            let id = of.get(r.sample.pose.as_str()).copied().unwrap_or("");
            ids.binary_search(&id).unwrap_or(0)
        })
        .collect();
    (groups, ids.len())
}

/// The fold (0..k) of every row: configurations shuffled with `seed` and dealt round-robin, so
/// that every load of a configuration falls in one fold (a configuration: the rows of one pose
/// id, and of every id with the same joint readings). `k` is capped at the number of
/// configurations.
pub fn folds(rows: &[&Measurement], k: usize, seed: u64) -> (Vec<usize>, usize) {
    let of = configuration_of(rows);
    let mut poses: Vec<&str> = (configurations(rows).into_iter())
        .filter(|p| of.get(p) == Some(p))
        .collect();
    poses.shuffle(&mut ChaCha8Rng::seed_from_u64(seed));
    let k = k.clamp(1, poses.len().max(1));
    let fold: HashMap<&str, usize> = poses.iter().enumerate().map(|(i, p)| (*p, i % k)).collect();
    (
        rows.iter()
            .map(|r| {
                (of.get(r.sample.pose.as_str()))
                    .and_then(|p| fold.get(p))
                    .copied()
                    .unwrap_or(0)
            })
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
/// joint-1 range of the rest — how a cell's working area grows (every id with the same joint
/// readings in one block). `k` is capped at the number of configurations.
pub fn blocks(rows: &[&Measurement], k: usize) -> (Vec<usize>, usize) {
    let of = configuration_of(rows);
    let mut poses: Vec<(&str, f64)> = rows
        .iter()
        .map(|r| {
            (
                of.get(r.sample.pose.as_str()).copied().unwrap_or(""),
                r.sample.joints.first().copied().unwrap_or(0.0),
            )
        })
        .collect();
    poses.sort_by(|a, b| a.0.cmp(b.0));
    poses.dedup_by(|a, b| a.0 == b.0);
    poses.sort_by(|a, b| a.1.total_cmp(&b.1).then(a.0.cmp(b.0)));
    let n = poses.len();
    let k = k.clamp(1, n.max(1));
    let block: HashMap<&str, usize> = (poses.iter().enumerate())
        .map(|(i, p)| (p.0, i * k / n.max(1)))
        .collect();
    (
        rows.iter()
            .map(|r| {
                (of.get(r.sample.pose.as_str()))
                    .and_then(|p| block.get(p))
                    .copied()
                    .unwrap_or(0)
            })
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
    use nalgebra::Vector3;
    use robocal_data::{Measurement, Sample};

    use super::{blocks, configuration_groups, folds, improves};

    fn row(pose: &str, joints: [f64; 2], load: f64) -> Measurement {
        Measurement {
            sample: Sample {
                pose: pose.into(),
                joints: joints.to_vec(),
                load,
                line: 0,
                target: String::new(),
                seq: None,
                last_move: Vec::new(),
            },
            position: Vector3::zeros(),
            orientation: None,
        }
    }

    /// A configuration measured again under a new id (a drift check's reference pose) falls in
    /// the fold and block of its first id at every load; rows whose readings no other id shares
    /// are dealt as by their ids alone (the same folds as before the rule, by construction:
    /// checked against the pose ids shuffled the same way).
    #[test]
    fn ids_with_the_same_readings_share_a_fold_and_a_block() {
        let mut data: Vec<Measurement> = (0..40)
            .flat_map(|i| {
                let q = [i as f64 * 7.3 - 140.0, (i * 13 % 40) as f64];
                [
                    row(&format!("p{i:02}"), q, 0.0),
                    row(&format!("p{i:02}"), q, 5.0),
                ]
            })
            .collect();
        let unique: Vec<&Measurement> = data.iter().collect();
        let (fold, k) = folds(&unique, 5, 2020);
        // By the ids alone, as the rule was.
        let mut ids: Vec<&str> = unique.iter().map(|r| r.sample.pose.as_str()).collect();
        ids.sort_unstable();
        ids.dedup();
        {
            use rand::SeedableRng;
            use rand::seq::SliceRandom;
            ids.shuffle(&mut rand_chacha::ChaCha8Rng::seed_from_u64(2020));
        }
        let by_id: Vec<usize> = (unique.iter())
            .map(|r| ids.iter().position(|p| *p == r.sample.pose).unwrap() % k)
            .collect();
        assert_eq!(fold, by_id);
        // p07 measured again as ref1 and ref2, at both loads.
        let q = data[14].sample.joints.clone();
        for id in ["ref1", "ref2"] {
            for load in [0.0, 5.0] {
                data.push(row(id, [q[0], q[1]], load));
            }
        }
        let rows: Vec<&Measurement> = data.iter().collect();
        for (of, _) in [folds(&rows, 5, 2020), blocks(&rows, 5)] {
            let p07 = of[14];
            assert!((80..84).all(|i| of[i] == p07), "{of:?}");
        }
    }

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

    /// A configuration measured again under a new id is one unit (one group) with its first id,
    /// at every load; the rest are one group per id, numbered in the order of the ids.
    #[test]
    fn ids_with_the_same_readings_are_one_group() {
        let data = [
            row("b", [10.0, 20.0], 0.0),
            row("a", [1.0, 2.0], 0.0),
            row("c", [1.0, 2.0], 5.0),
            row("a", [1.0, 2.0], 5.0),
            row("d", [3.0, 4.0], 0.0),
            row("c", [1.0, 2.0], 0.0),
        ];
        let rows: Vec<&Measurement> = data.iter().collect();
        let (groups, n) = configuration_groups(&rows);
        assert_eq!(n, 3);
        assert_eq!(groups, vec![1, 0, 0, 0, 2, 0]);
        // By the ids alone there would be four units: `c`, measured again at `a`'s readings,
        // would count as a configuration of its own in a paired test.
        let (_, k) = folds(&rows, 10, 1);
        assert_eq!(k, 3);
    }
}
