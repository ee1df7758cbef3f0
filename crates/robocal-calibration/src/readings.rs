//! Joint readings logged to a few decimals. A controller that exports its joint positions
//! rounded to 0.01° feeds every row an error of up to 0.005° per joint, a uniform error of
//! standard deviation step/√12 — 0.05 mm per joint at a metre from its axis, more than a laser
//! tracker's noise — which no model can take out: it is in the readings the model is asked to
//! predict from. What the rounding leaves is the joint Jacobian times that error.

use robocal_data::Measurement;
use robocal_robot::Robot;

/// The steps a reading is tested against, coarsest first, deg.
const STEPS: [f64; 4] = [1.0, 0.1, 0.01, 0.001];

/// A joint needs this many distinct readings before its rounding is judged (a joint that stays
/// at one or two angles says nothing of how it was logged).
const MIN_DISTINCT: usize = 3;

/// The rounding is worth a warning from this root-mean-square position error on, mm (a laser
/// tracker's noise is about 0.015 mm).
pub const ROUNDING_WARNING_MM: f64 = 0.01;

/// Readings whose rounding would leave more than this many times the fit's own root-mean-square
/// error cannot have been rounded (the rounding error is in every row, and a fit takes out at
/// most a small part of it: the share of its parameters in the rows' coordinates): they are exact
/// values, commanded angles on a grid. Judged for each joint alone, then for the rest together.
const EXACT_RATIO: f64 = 1.25;

/// The coarsest step of `STEPS` every reading is a multiple of, deg; none for readings finer
/// than the finest, or with fewer than `MIN_DISTINCT` distinct values.
pub fn reading_step(readings: &[f64]) -> Option<f64> {
    let mut distinct: Vec<f64> = readings.to_vec();
    distinct.sort_by(f64::total_cmp);
    distinct.dedup();
    if distinct.len() < MIN_DISTINCT {
        return None;
    }
    // A reading written with d decimals parses to within a few units in the last place of a
    // multiple of 10^-d.
    STEPS.into_iter().find(|&step| {
        distinct
            .iter()
            .all(|&v| (v / step - (v / step).round()).abs() <= 1e-6)
    })
}

/// One joint's rounding.
#[derive(Debug, Clone, PartialEq)]
pub struct JointRounding {
    /// 0-based joint.
    pub joint: usize,
    /// The step its readings are multiples of, deg.
    pub step: f64,
    /// The root-mean-square position error its rounding alone leaves over the rows, mm.
    pub rms_mm: f64,
}

/// Every joint whose readings are multiples of a step of `STEPS`, with the position error a
/// uniform rounding error of that step leaves (`robot`'s joint Jacobian at each row's readings;
/// the rows' mean of `|∂p/∂q_j|² (step_j)² / 12`, as a root).
pub fn rounded_joints(robot: &Robot, rows: &[&Measurement]) -> Vec<JointRounding> {
    let dof = robot.dof();
    let steps: Vec<Option<f64>> = (0..dof)
        .map(|j| {
            let readings: Vec<f64> = rows.iter().map(|m| m.sample.joints[j]).collect();
            reading_step(&readings)
        })
        .collect();
    if rows.is_empty() || steps.iter().all(Option::is_none) {
        return Vec::new();
    }
    let mut sum = vec![0.0; dof];
    for m in rows {
        let jac = robot.joint_jacobian(&m.sample.joints_rad());
        for (j, s) in sum.iter_mut().enumerate() {
            *s += jac.column(j).norm_squared();
        }
    }
    (steps.iter().enumerate())
        .filter_map(|(joint, step)| {
            let step = (*step)?;
            let sigma = step.to_radians() / 12f64.sqrt();
            Some(JointRounding {
                joint,
                step,
                rms_mm: (sum[joint] / rows.len() as f64).sqrt() * sigma,
            })
        })
        .collect()
}

/// The warning for readings rounded coarsely enough to cost accuracy: the joints whose readings
/// are multiples of a step, those whose rounding alone would leave more than the fit does
/// (`EXACT_RATIO`) left aside as exact values, when the rest leave [`ROUNDING_WARNING_MM`] or
/// more together and no more than the fit does.
/// `fit_rms`: the root-mean-square error of the fitted physical model on its rows, mm.
pub fn rounding_warning(joints: &[JointRounding], fit_rms: f64) -> Option<String> {
    let rounded: Vec<&JointRounding> = (joints.iter())
        .filter(|j| j.rms_mm <= EXACT_RATIO * fit_rms)
        .collect();
    let total = rounded.iter().map(|j| j.rms_mm.powi(2)).sum::<f64>().sqrt();
    // None rounded: a total of 0, under the threshold.
    if total < ROUNDING_WARNING_MM || total > EXACT_RATIO * fit_rms {
        return None;
    }
    let names: Vec<String> = (rounded.iter())
        .map(|j| format!("q{} to {}°", j.joint + 1, j.step))
        .collect();
    // Ten times finer than the finest step found: a tenth of the rounding's error.
    let finer = rounded.iter().map(|j| j.step).fold(f64::INFINITY, f64::min) / 10.0;
    let finer = (finer * 1e6).round() / 1e6;
    Some(format!(
        "the joint readings are rounded ({}): the rounding alone leaves about {total:.3} mm (root mean square) at these poses, which no model can take out (the fit leaves {fit_rms:.3} mm); log the controller's readings to {finer}° or finer (if they are commanded angles the arm reached exactly, this does not apply)",
        names.join(", ")
    ))
}

#[cfg(test)]
mod tests {
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    use super::*;

    #[test]
    fn the_step_is_the_coarsest_the_readings_are_multiples_of() {
        let parse = |v: &[&str]| -> Vec<f64> { v.iter().map(|s| s.parse().unwrap()).collect() };
        assert_eq!(
            reading_step(&parse(&["12.35", "-3.1", "0.07", "100"])),
            Some(0.01)
        );
        assert_eq!(reading_step(&parse(&["10", "-20", "35"])), Some(1.0));
        assert_eq!(reading_step(&parse(&["-50.2", "52.1", "127.0"])), Some(0.1));
        assert_eq!(
            reading_step(&parse(&["-50.196", "52.091", "1.5"])),
            Some(0.001)
        );
        assert_eq!(reading_step(&parse(&["-50.1944", "52.0913", "1.5"])), None);
        // A joint that stays put, or takes two angles, says nothing.
        assert_eq!(reading_step(&parse(&["0", "0", "0", "0"])), None);
        assert_eq!(reading_step(&parse(&["0", "90", "0", "90"])), None);
    }

    /// The estimate against the rounding done: 2000 readings spread over each joint's range
    /// (seeded), rounded to 0.01° on every joint, the points moved by the rounding
    /// computed by forward kinematics; their root-mean-square distance within 5 % of the
    /// estimate's total, and each joint's share within 10 % of the same done on it alone.
    #[test]
    fn the_estimate_matches_the_points_moved_by_rounding() {
        let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
        let robot = Robot::load(root.join("configs/robots/pmc6va030.toml")).unwrap();
        let dof = robot.dof();
        let mut rng = ChaCha8Rng::seed_from_u64(12345);
        let rows: Vec<Measurement> = (0..2000)
            .map(|i| {
                let joints: Vec<f64> = (0..dof)
                    .map(|_| (rng.random_range(-100.0..100.0) * 100.0_f64).round() / 100.0)
                    .collect();
                Measurement {
                    sample: robocal_data::Sample {
                        pose: format!("p{i}"),
                        joints,
                        load: 0.0,
                        line: i as u64 + 2,
                        target: String::new(),
                        seq: None,
                        last_move: Vec::new(),
                    },
                    position: nalgebra::Vector3::zeros(),
                    orientation: None,
                }
            })
            .collect();
        // The true readings: the rounded ones plus a uniform error of ±0.005°.
        let truth: Vec<Vec<f64>> = (rows.iter())
            .map(|m| {
                m.sample
                    .joints
                    .iter()
                    .map(|q| q + rng.random_range(-0.005..0.005))
                    .collect()
            })
            .collect();
        let refs: Vec<&Measurement> = rows.iter().collect();
        let joints = rounded_joints(&robot, &refs);
        assert_eq!(joints.len(), dof);
        assert!(joints.iter().all(|j| j.step == 0.01));
        let rad = |q: &[f64]| -> Vec<f64> { q.iter().map(|v| v.to_radians()).collect() };
        let moved = |only: Option<usize>| -> f64 {
            let sum: f64 = (rows.iter().zip(&truth))
                .map(|(m, t)| {
                    let mut q = m.sample.joints.clone();
                    for (j, v) in q.iter_mut().enumerate() {
                        if only.is_some_and(|o| o != j) {
                            *v = t[j];
                        }
                    }
                    (robot.point(&rad(&q)) - robot.point(&rad(t))).norm_squared()
                })
                .sum();
            (sum / rows.len() as f64).sqrt()
        };
        let total = joints.iter().map(|j| j.rms_mm.powi(2)).sum::<f64>().sqrt();
        let done = moved(None);
        assert!((done / total - 1.0).abs() < 0.05, "{done} vs {total}");
        for j in &joints {
            let done = moved(Some(j.joint));
            if j.rms_mm > 1e-3 {
                assert!(
                    (done / j.rms_mm - 1.0).abs() < 0.10,
                    "q{}: {done} vs {}",
                    j.joint + 1,
                    j.rms_mm
                );
            }
        }
    }

    fn joint(joint: usize, step: f64, rms_mm: f64) -> JointRounding {
        JointRounding {
            joint,
            step,
            rms_mm,
        }
    }

    #[test]
    fn exact_grid_values_and_fine_readings_are_not_warned_of() {
        // Rounded to 0.01° on three joints: 0.02, 0.015, 0.01 mm → 0.027 mm together.
        let rounded = [
            joint(0, 0.01, 0.02),
            joint(1, 0.01, 0.015),
            joint(2, 0.01, 0.01),
        ];
        let w = rounding_warning(&rounded, 0.05).unwrap();
        assert!(w.contains("q1 to 0.01°, q2 to 0.01°, q3 to 0.01°"), "{w}");
        assert!(w.contains("about 0.027 mm"), "{w}");
        assert!(
            w.contains("log the controller's readings to 0.001° or finer"),
            "{w}"
        );
        // Readings to 0.001° on a long arm: the advice is a tenth of that.
        let w = rounding_warning(&[joint(0, 0.001, 0.012)], 0.05).unwrap();
        assert!(w.contains("(q1 to 0.001°)"), "{w}");
        assert!(
            w.contains("log the controller's readings to 0.0001° or finer"),
            "{w}"
        );
        // Too little to matter.
        assert_eq!(rounding_warning(&[joint(0, 0.001, 0.004)], 0.05), None);
        // Whole degrees on joint 4 would leave 3 mm where the fit leaves 0.05: exact values, left
        // out; the other joints still warned of.
        let mut mixed = rounded.to_vec();
        mixed.push(joint(3, 1.0, 3.0));
        let w = rounding_warning(&mixed, 0.05).unwrap();
        assert!(!w.contains("q4"), "{w}");
        assert!(w.contains("about 0.027 mm"), "{w}");
        assert_eq!(rounding_warning(&[joint(3, 1.0, 3.0)], 0.05), None);
        // Each joint's share below what the fit leaves, but together more than it: exact values.
        assert_eq!(rounding_warning(&rounded, 0.02), None);
    }
}
