//! Repeated shots: rows of the same configuration (the same joint readings), load and reflector
//! measured more than once. Their spread about their own mean is the measurement's — the
//! tracker's noise, and the arm's repeatability where it moved away and back between shots —,
//! with no model in it: the floor no calibration goes below on measured points.

use std::collections::HashMap;

use nalgebra::Vector3;
use robocal_data::Measurement;
use serde::Serialize;

use crate::rows::readings_key;

/// `E|e|` for `e ~ N(0, I₃)`: `2 √(2/π)`, the mean length of a three-axis Gaussian error of unit
/// standard deviation per axis.
pub const MEAN_NORM_3D: f64 = 1.595_769_121_605_730_7;

/// What the repeated shots say about the measurement.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Repeats {
    /// Groups of two or more rows with the same joint readings, load and reflector.
    pub groups: usize,
    /// Rows in them.
    pub rows: usize,
    /// Pooled standard deviation of a coordinate about its group's mean, mm (`Σ |x − x̄|²` over
    /// `3 (rows − groups)` degrees of freedom).
    pub std_mm: f64,
    /// The mean distance a model that knew each pose exactly would leave from the measured
    /// points, mm: `std_mm × 2√(2/π)`.
    pub floor_mm: f64,
    /// The chosen model's held-out mean error (random folds of configurations) over that floor,
    /// when the default calibration measured one.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub held_out_over_floor: Option<f64>,
}

/// What makes two rows shots of the same point: the joint readings (bits), the load (bits) and
/// the reflector.
type ShotKey<'a> = (Vec<u64>, u64, &'a str);

/// The repeated shots of `rows`; `None` when no configuration, load and reflector was measured
/// twice.
pub fn repeats(rows: &[&Measurement]) -> Option<Repeats> {
    let mut groups: HashMap<ShotKey<'_>, Vec<Vector3<f64>>> = HashMap::new();
    for r in rows {
        let key = (
            readings_key(r),
            r.sample.load.to_bits(),
            r.sample.target.as_str(),
        );
        groups.entry(key).or_default().push(r.position);
    }
    let (mut sum, mut dof, mut count, mut members) = (0.0, 0usize, 0usize, 0usize);
    for points in groups.values().filter(|p| p.len() >= 2) {
        let mean = points.iter().sum::<Vector3<f64>>() / points.len() as f64;
        sum += points
            .iter()
            .map(|p| (p - mean).norm_squared())
            .sum::<f64>();
        dof += 3 * (points.len() - 1);
        count += 1;
        members += points.len();
    }
    (count > 0).then(|| {
        let std_mm = (sum / dof as f64).sqrt();
        Repeats {
            groups: count,
            rows: members,
            std_mm,
            floor_mm: std_mm * MEAN_NORM_3D,
            held_out_over_floor: None,
        }
    })
}

#[cfg(test)]
mod tests {
    use robocal_data::Sample;

    use super::*;

    fn row(pose: &str, q: f64, load: f64, x: f64) -> Measurement {
        Measurement {
            sample: Sample {
                pose: pose.into(),
                joints: vec![q, 10.0],
                load,
                line: 0,
                target: String::new(),
                seq: None,
                last_move: Vec::new(),
            },
            position: Vector3::new(x, 100.0, 200.0),
            orientation: None,
        }
    }

    /// By hand: a pose shot three times at load 0 (x 1, 2, 3: squares 1 + 0 + 1 about 2) and
    /// again under another id (the same readings), a second pose twice at load 5 (x 10, 14:
    /// 4 + 4); everything else shot once. Σ 10 over 3 × ((4 − 1) + (2 − 1)) = 12 degrees of
    /// freedom: σ² = 10/12.
    #[test]
    fn pooled_spread_of_the_groups_by_hand() {
        let data = [
            row("a", 1.0, 0.0, 1.0),
            row("a", 1.0, 0.0, 2.0),
            row("a", 1.0, 0.0, 3.0),
            row("ref", 1.0, 0.0, 2.0),
            row("a", 1.0, 5.0, 7.0),
            row("b", 2.0, 5.0, 10.0),
            row("b", 2.0, 5.0, 14.0),
            row("c", 3.0, 0.0, 50.0),
        ];
        let rows: Vec<&Measurement> = data.iter().collect();
        let r = repeats(&rows).unwrap();
        assert_eq!((r.groups, r.rows), (2, 6));
        assert!((r.std_mm - (10.0f64 / 12.0).sqrt()).abs() < 1e-12, "{r:?}");
        assert!((r.floor_mm - r.std_mm * 2.0 * (2.0 / std::f64::consts::PI).sqrt()).abs() < 1e-12);
        assert_eq!(repeats(&rows[4..]).map(|r| r.groups), Some(1));
        assert_eq!(repeats(&rows[7..]), None);
    }
}
