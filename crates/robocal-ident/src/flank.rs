//! Which flank of its play each joint's backlash rests on: the flank of its approach from home,
//! or the flank its gravity torque presses, whichever explains more of what a fit with the
//! approach flanks left.
//!
//! For joint `j` and row `i`, a backlash term moves the point by `b · s_i · J_i` (`J_i` the
//! joint's column of the point Jacobian at the deflected angles, `s_i = ±1` the flank). Added
//! to a fit that leaves `e_i` (measured − predicted) with every joint-error term of the joint
//! given back — its compliance and self-weight terms are linear in the same torques and absorb
//! the part of a torque-pressed step that is linear in them, which would turn the sign of what
//! is left —, the best `b` lowers the squared error by `(Σ s_i y_i)² / Σ |J_i|²`,
//! `y_i = J_i · e_i`: the flank each row wants is the sign of `y_i`, and getting it right is
//! worth `|y_i|`. The torque
//! flank is the sign of a linear function of the joint's gravity-torque features
//! ([`JointErrors::torque_features`]): the torque of the links, the payload and a preload, the
//! form a torque-pressed flank has. Its weights are those of a logistic regression of the rows'
//! wanted flanks on the features, each row weighted by `|y_i|` (Newton's method with a small
//! ridge on standardized features). The joint takes the torque flank when it lowers the error
//! more than the approach flank does — judged on flanks cross-fitted over two halves of the
//! configurations (each half's flanks from a regression on the other half), so that a
//! regression with two dozen weights does not win by fitting the noise.

use nalgebra::{DMatrix, DVector, Vector3};
use robocal_robot::{
    Flank, JointErrors, Robot, TORQUE_FEATURES_PER_LINK, payload_mass_feature, torque_side,
};

use crate::problem::Observations;

/// Ridge on the standardized logistic weights: keeps them finite when the flanks are
/// separable (they are, for a torque-pressed flank without noise).
const RIDGE: f64 = 1e-3;

/// A joint's gravity-torque features (RMS over the rows and the links' features) below this
/// share of the largest joint's: no flank its torque presses is tried.
const TORQUE_SHARE: f64 = 0.05;

/// Newton steps of the logistic regression, at most.
const NEWTON_STEPS: usize = 50;

/// For every joint, the flank its backlash should be identified on — of its approach from
/// `home[j]` (rad), or the one its torque presses — from the fit `robot` + `errors` and the
/// observations it was fitted on.
pub(crate) fn choose_flanks(
    robot: &Robot,
    errors: &JointErrors,
    obs: &Observations,
    home: &[f64],
) -> Vec<Flank> {
    let dof = robot.dof();
    let n = obs.len();
    // Two halves of the configurations (every load of a configuration in the same half).
    let mut seen: Vec<&[f64]> = Vec::new();
    let half: Vec<usize> = (0..n)
        .map(|i| {
            let q = obs.joints(i);
            let k = seen.iter().position(|s| *s == q).unwrap_or_else(|| {
                seen.push(q);
                seen.len() - 1
            });
            k % 2
        })
        .collect();
    // Each row's joint errors, its error and its joint Jacobian columns at the deflected angles.
    let mut deflection = Vec::with_capacity(n);
    let mut residual = Vec::with_capacity(n);
    let mut columns = Vec::with_capacity(n);
    for i in 0..n {
        let q = obs.joints(i);
        let target = robot.for_target(obs.target(robot, i));
        let d = errors.deflection(robot, q, obs.loads[i]);
        let deflected: Vec<f64> = q.iter().zip(&d).map(|(q, d)| q + d).collect();
        residual.push(obs.points[i] - target.point(&deflected));
        columns.push(target.joint_jacobian(&deflected));
        deflection.push(d);
    }
    let features: Vec<Vec<Vec<f64>>> = (0..dof)
        .map(|j| {
            (0..n)
                .map(|i| errors.torque_features(robot, obs.joints(i), obs.loads[i], j))
                .collect()
        })
        .collect();
    // The RMS of the links' torque features (a unit mass at each frame's origin, N·m per kg, a
    // unit first moment along each axis, N·m per kg·m), per joint: a joint whose axis is
    // (nearly) vertical carries no gravity torque, and no flank its torque presses.
    let rms_torque: Vec<f64> = (features.iter())
        .map(|rows| {
            let link_features = rows[0].len() - 1 - TORQUE_FEATURES_PER_LINK;
            let sum: f64 = (rows.iter())
                .map(|f| f[..link_features].iter().map(|v| v * v).sum::<f64>())
                .sum();
            (sum / (n * link_features).max(1) as f64).sqrt()
        })
        .collect();
    let largest = rms_torque.iter().copied().fold(0.0, f64::max);
    (0..dof)
        .map(|j| {
            let approach = Flank::Approach { home: home[j] };
            if rms_torque[j] < TORQUE_SHARE * largest {
                return approach;
            }
            let features = &features[j];
            // What the fit leaves with every joint-error term of the joint given back, along
            // its column; and the rows' approach flanks.
            let mut y = Vec::with_capacity(n);
            let mut norm2 = 0.0;
            let mut approach_flank = Vec::with_capacity(n);
            for i in 0..n {
                let col: Vector3<f64> = columns[i].column(j).into_owned();
                let e = residual[i] + col * deflection[i][j];
                y.push(col.dot(&e));
                norm2 += col.norm_squared();
                approach_flank.push(if obs.joints(i)[j] >= home[j] {
                    1.0
                } else {
                    -1.0
                });
            }
            if norm2 <= 0.0 {
                return approach;
            }
            let gain = |s: &[f64]| {
                let dot: f64 = s.iter().zip(&y).map(|(s, y)| s * y).sum();
                dot * dot / norm2
            };
            // Cross-fitted flanks: each half's from the regression on the other half.
            let mut crossed = vec![0.0; n];
            for h in 0..2 {
                let train: Vec<usize> = (0..n).filter(|&i| half[i] != h).collect();
                let Some(w) = logistic(
                    &train
                        .iter()
                        .map(|&i| features[i].clone())
                        .collect::<Vec<_>>(),
                    &train.iter().map(|&i| y[i]).collect::<Vec<_>>(),
                ) else {
                    return approach;
                };
                for i in (0..n).filter(|&i| half[i] == h) {
                    crossed[i] = torque_side(&w, &features[i]);
                }
            }
            // The approach flank has no weights fitted: its gain is honest as it is.
            if gain(&crossed) <= gain(&approach_flank) {
                return approach;
            }
            logistic(features, &y).map_or(approach, |weights| Flank::Torque { weights })
        })
        .collect()
}

/// Weights `w` (one per feature, in the features' own units) of a logistic regression of the
/// sign of `y` on `features`, each row weighted by `|y|`; scaled so that the weight of the
/// payload's unit mass (the fifth feature from the end) is 1 when it is positive, else to unit
/// length with that weight not negative. `None` when no row has a weight or no feature varies.
fn logistic(features: &[Vec<f64>], y: &[f64]) -> Option<Vec<f64>> {
    let n = features.len();
    let p = features.first()?.len();
    let total: f64 = y.iter().map(|v| v.abs()).sum();
    if total <= 0.0 {
        return None;
    }
    let weight: Vec<f64> = y.iter().map(|v| v.abs() / total * n as f64).collect();
    // Standardize every feature that varies (the last one is the constant); drop the others.
    let mut mean = vec![0.0; p];
    let mut sd = vec![0.0; p];
    for k in 0..p - 1 {
        let m = features.iter().map(|f| f[k]).sum::<f64>() / n as f64;
        let v = features.iter().map(|f| (f[k] - m).powi(2)).sum::<f64>() / n as f64;
        (mean[k], sd[k]) = (m, v.sqrt());
    }
    let scale = sd.iter().copied().fold(0.0, f64::max);
    let used: Vec<usize> = (0..p - 1).filter(|&k| sd[k] > 1e-9 * scale).collect();
    if used.is_empty() {
        return None;
    }
    let m = used.len() + 1;
    let x = DMatrix::from_fn(n, m, |i, c| match used.get(c) {
        Some(&k) => (features[i][k] - mean[k]) / sd[k],
        None => 1.0,
    });
    let label: Vec<f64> = y.iter().map(|v| f64::from(u8::from(*v >= 0.0))).collect();
    let mut beta = DVector::zeros(m);
    for _ in 0..NEWTON_STEPS {
        let eta = &x * &beta;
        let mut residual = DVector::zeros(n);
        let mut scaled = x.clone();
        for i in 0..n {
            let mu = 1.0 / (1.0 + (-eta[i]).exp());
            residual[i] = weight[i] * (label[i] - mu);
            let root = (weight[i] * mu * (1.0 - mu)).max(1e-12).sqrt();
            scaled.row_mut(i).scale_mut(root);
        }
        let grad = x.tr_mul(&residual) - &beta * RIDGE;
        let hess = scaled.tr_mul(&scaled) + DMatrix::identity(m, m) * RIDGE;
        let step = hess.cholesky()?.solve(&grad);
        beta += &step;
        if step.norm() < 1e-8 * (1.0 + beta.norm()) {
            break;
        }
    }
    // Back to the features' own units.
    let mut w = vec![0.0; p];
    let mut constant = beta[m - 1];
    for (c, &k) in used.iter().enumerate() {
        w[k] = beta[c] / sd[k];
        constant -= w[k] * mean[k];
    }
    w[p - 1] = constant;
    let payload = w[payload_mass_feature(p)];
    let norm = if payload > 1e-12 * w.iter().map(|v| v.abs()).fold(0.0, f64::max) {
        payload
    } else {
        let length = w.iter().map(|v| v * v).sum::<f64>().sqrt();
        if payload < 0.0 { -length } else { length }
    };
    if !(norm.is_finite() && norm != 0.0) {
        return None;
    }
    Some(w.iter().map(|v| v / norm).collect())
}

/// Every row's flank (`±1`) of every backlash term of `errors`: what a round of flank choices
/// changed.
pub(crate) fn flank_signs(robot: &Robot, errors: &JointErrors, obs: &Observations) -> Vec<f64> {
    (errors.backlash.iter())
        .flat_map(|b| (0..obs.len()).map(move |i| (b, i)))
        .map(|(b, i)| errors.flank(b, robot, obs.joints(i), obs.loads[i]))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Rows whose wanted flank is the sign of `2 a − b + 0.5` are told apart by the regression:
    /// its weights give every row's flank, whatever the rows' weights.
    #[test]
    fn logistic_weights_separate_a_linear_flank() {
        let mut features = Vec::new();
        let mut y = Vec::new();
        for i in 0..200 {
            let a = ((i * 37) % 101) as f64 / 50.0 - 1.0;
            let b = ((i * 53) % 97) as f64 / 48.0 - 1.0;
            let payload = ((i * 11) % 7) as f64;
            let t = 2.0 * a - b + 0.3 * payload + 0.5;
            features.push(vec![a, b, payload, 0.0, 0.0, 0.0, 1.0]);
            y.push(t.signum() * (0.1 + (i % 5) as f64));
        }
        let w = logistic(&features, &y).unwrap();
        let wrong = (features.iter().zip(&y))
            .filter(|(f, y)| {
                let t: f64 = w.iter().zip(f.iter()).map(|(w, f)| w * f).sum();
                (t >= 0.0) != (**y >= 0.0)
            })
            .count();
        assert_eq!(wrong, 0, "{w:?}");
        // Scaled so that the payload's weight is 1: the others are the torque's own.
        assert!((w[2] - 1.0).abs() < 1e-12, "{w:?}");
        assert!((w[0] / w[2] - 2.0 / 0.3).abs() < 0.25 * 2.0 / 0.3, "{w:?}");
    }
}
