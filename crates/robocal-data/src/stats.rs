//! Summary statistics of Euclidean position errors, as `evaluate` and the reports print them.

use serde::Serialize;

/// Count, mean, standard deviation, RMS and maximum of a set of errors (mm).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct ErrorStats {
    /// Number of errors.
    pub count: usize,
    /// Mean, mm.
    pub mean: f64,
    /// Sample standard deviation (n − 1 denominator; 0 for a single error), mm.
    pub std: f64,
    /// Root mean square, mm.
    pub rms: f64,
    /// Maximum, mm.
    pub max: f64,
}

impl ErrorStats {
    /// Statistics of `errors` (mm). An empty slice gives all zeros.
    pub fn from_errors(errors: &[f64]) -> Self {
        let count = errors.len();
        if count == 0 {
            return Self {
                count,
                mean: 0.0,
                std: 0.0,
                rms: 0.0,
                max: 0.0,
            };
        }
        let n = count as f64;
        let mean = errors.iter().sum::<f64>() / n;
        let var = if count > 1 {
            errors.iter().map(|e| (e - mean).powi(2)).sum::<f64>() / (n - 1.0)
        } else {
            0.0
        };
        Self {
            count,
            mean,
            std: var.sqrt(),
            rms: (errors.iter().map(|e| e * e).sum::<f64>() / n).sqrt(),
            max: errors.iter().copied().fold(0.0, f64::max),
        }
    }
}

/// 1.4826 × the median absolute deviation of `values`: the standard deviation of a normal
/// sample, robust to a few wild values (0 for an empty slice).
pub fn robust_std(values: &[f64]) -> f64 {
    let median = |v: &mut Vec<f64>| {
        v.sort_by(f64::total_cmp);
        let n = v.len();
        if n == 0 {
            0.0
        } else if n % 2 == 1 {
            v[n / 2]
        } else {
            0.5 * (v[n / 2 - 1] + v[n / 2])
        }
    };
    let mut v = values.to_vec();
    let m = median(&mut v);
    let mut dev: Vec<f64> = values.iter().map(|x| (x - m).abs()).collect();
    1.4826 * median(&mut dev)
}

/// Whether `new` (held-out errors) lowers `base`'s significantly: the mean over groups (a
/// configuration in one kind of fold: its rows share one pose; `groups` numbers them from 0)
/// of base − new is positive and more than [`SIGNIFICANCE`] times its standard error. A stage
/// that helps by less than the spread of the difference is not worth its parameters: on poses
/// beyond those measured it can do harm.
pub fn improves(base: &[f64], new: &[f64], groups: &[usize]) -> bool {
    let n_groups = groups.iter().copied().max().map_or(0, |g| g + 1);
    let mut sums = vec![0.0; n_groups];
    let mut counts = vec![0usize; n_groups];
    for ((b, n), &g) in base.iter().zip(new).zip(groups) {
        sums[g] += b - n;
        counts[g] += 1;
    }
    let d: Vec<f64> = (sums.iter().zip(&counts))
        .filter(|(_, c)| **c > 0)
        .map(|(s, c)| s / *c as f64)
        .collect();
    let n = d.len() as f64;
    let mean = d.iter().sum::<f64>() / n.max(1.0);
    if d.len() < 2 {
        return mean > 0.0;
    }
    let var = d.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1.0);
    mean > 0.0 && mean > SIGNIFICANCE * (var / n).sqrt()
}

/// How many standard errors a stage's held-out improvement must exceed to be kept.
pub const SIGNIFICANCE: f64 = 2.0;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hand_worked_statistics() {
        let s = ErrorStats::from_errors(&[1.0, 2.0, 3.0, 4.0]);
        assert_eq!(s.count, 4);
        assert!((s.mean - 2.5).abs() < 1e-15);
        // sample variance of 1..4 is 5/3
        assert!((s.std - (5.0f64 / 3.0).sqrt()).abs() < 1e-15);
        assert!((s.rms - 7.5f64.sqrt()).abs() < 1e-15);
        assert_eq!(s.max, 4.0);
        let one = ErrorStats::from_errors(&[0.5]);
        assert_eq!((one.std, one.max), (0.0, 0.5));
    }

    /// 1.4826 × MAD by hand: values 1..9 have median 5 and absolute deviations 0,1,1,2,2,3,3,4,4
    /// (median 2); one wild value moves neither.
    #[test]
    fn the_robust_spread_ignores_a_wild_value() {
        let v: Vec<f64> = (1..=9).map(f64::from).collect();
        assert!((robust_std(&v) - 2.0 * 1.4826).abs() < 1e-12);
        let mut w = v.clone();
        w[8] = 1e6;
        assert!((robust_std(&w) - 2.0 * 1.4826).abs() < 1e-12);
        assert_eq!(robust_std(&[]), 0.0);
    }
}
