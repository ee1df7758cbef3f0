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
}
