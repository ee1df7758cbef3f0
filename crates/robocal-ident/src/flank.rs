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
//! worth `|y_i|`. The torque flank is the sign of a linear function of the joint's
//! gravity-torque features ([`JointErrors::torque_features`]): the torque of the links, the
//! payload and a preload, the form a torque-pressed flank has. Its weights are those of a
//! logistic regression of the rows' wanted flanks on the features, each row weighted by `|y_i|`
//! (Newton's method with a small ridge on standardized features). The joint takes the torque
//! flank when it lowers the error more than the approach flank does — judged on flanks
//! cross-fitted over two halves of the configurations (each half's flanks from a regression on
//! the other half), so that a regression with two dozen weights does not win by fitting the
//! noise.
//!
//! The compliance given back is linear in the same torque, so where the joint is compliant the
//! regression's boundary lies where that line crosses the step, near the rows' middle torque,
//! not at the arm's preload. With the search (`JointErrorSettings::flank_search`) a flank is
//! scored by what its step gains **beyond the joint's own terms** (offset, compliance times its
//! torque, harmonics, self-weight; [`StepGain`]: the step projected off them), the preload is
//! the split of the rows' torques that scores most, the direction is fitted again on the wanted
//! flanks with those terms fitted beside the step and taken out, and the preload again, until
//! the flanks settle ([`torque_weights`]); the torque flank is then taken where its
//! cross-fitted flanks score more than the approach flank's.

use nalgebra::{DMatrix, DVector, Matrix3xX, Vector3};
use robocal_robot::{
    Flank, JointErrors, MomentPart, Robot, TORQUE_FEATURES_PER_LINK, payload_mass_feature,
    torque_side, turned,
};

use crate::problem::Observations;

/// Ridge on the standardized logistic weights: keeps them finite when the flanks are
/// separable (they are, for a torque-pressed flank without noise).
const RIDGE: f64 = 1e-3;

/// A joint's gravity-torque features (RMS over the rows and the links' features) below this
/// share of the largest joint's: no flank its torque presses is tried.
const TORQUE_SHARE: f64 = 0.05;

/// Rounds of a torque flank's direction (the logistic regression) and preload (the search),
/// at most.
const DIRECTION_ROUNDS: usize = 4;

/// Newton steps of the logistic regression, at most.
const NEWTON_STEPS: usize = 50;

/// For every joint, the flank its backlash should be identified on — of its approach from
/// `home[j]` (rad), or the one its torque presses — from the fit `robot` + `errors` and the
/// observations it was fitted on; with `search`, each torque flank's preload searched and its
/// direction fitted again beyond the joint's own terms ([`torque_weights`]), else the
/// regression's alone.
pub(crate) fn choose_flanks(
    robot: &Robot,
    errors: &JointErrors,
    obs: &Observations,
    home: &[f64],
    search: bool,
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
        let (d, e, jac) = row_left(robot, errors, obs, i);
        deflection.push(d);
        residual.push(e);
        columns.push(jac);
    }
    // The torque each joint's compliance meets, per row (the search's terms; every joint's at
    // once).
    let load_torques: Vec<Vec<f64>> = if search {
        (0..n)
            .map(|i| errors.load_torques(robot, obs.joints(i), obs.loads[i]))
            .collect()
    } else {
        Vec::new()
    };
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
            if !search {
                let regression = |rows: &[usize]| {
                    logistic(
                        &rows
                            .iter()
                            .map(|&i| features[i].clone())
                            .collect::<Vec<_>>(),
                        &rows.iter().map(|&i| y[i]).collect::<Vec<_>>(),
                    )
                };
                let gain = |s: &[f64]| {
                    let dot: f64 = s.iter().zip(&y).map(|(s, y)| s * y).sum();
                    dot * dot / norm2
                };
                return cross_fitted(features, &half, &approach_flank, regression, gain)
                    .unwrap_or(approach);
            }
            // Every row's terms of the joint that a step is judged beyond, as the fit has them:
            // its offset, its compliance (times the payload's and the links' torque), its
            // harmonics' sines and cosines and its self-weight terms (each a torque feature).
            let orders: Vec<u32> = (errors.harmonics.iter())
                .filter(|h| h.joint == j)
                .map(|h| h.order)
                .collect();
            let own: Vec<usize> = (errors.self_weight.iter())
                .filter(|w| w.joint == j)
                .filter_map(|w| {
                    let part = MomentPart::ALL.iter().position(|p| *p == w.part)?;
                    Some((w.body - j) * TORQUE_FEATURES_PER_LINK + part)
                })
                .collect();
            let basis: Vec<Vec<f64>> = (0..n)
                .map(|i| {
                    let q = obs.joints(i);
                    let mut b = vec![1.0, load_torques[i][j]];
                    for &k in &orders {
                        let (s, c) = (f64::from(k) * q[j]).sin_cos();
                        b.extend([s, c]);
                    }
                    b.extend(own.iter().map(|&f| features[i][f]));
                    b
                })
                .collect();
            let weight: Vec<f64> = (0..n)
                .map(|i| columns[i].column(j).norm_squared())
                .collect();
            let all: Vec<usize> = (0..n).collect();
            let Some(whole) = StepGain::new(&all, &basis, &y, &weight) else {
                return approach;
            };
            let search = |rows: &[usize]| torque_weights(rows, features, &basis, &y, &weight);
            cross_fitted(features, &half, &approach_flank, search, |s| whole.gain(s))
                .unwrap_or(approach)
        })
        .collect()
}

/// Row `i`'s joint deflections (rad), what the fit `robot` + `errors` leaves there (measured −
/// the whole model's point, mm: the point at the deflected angles, turned by the bearings'
/// tilts and the axis runouts where the fit has them) and the joint Jacobian at the deflected
/// angles. The turns are in it: without them a runout's own displacement would be read as part
/// of a step to explain.
fn row_left(
    robot: &Robot,
    errors: &JointErrors,
    obs: &Observations,
    i: usize,
) -> (Vec<f64>, Vector3<f64>, Matrix3xX<f64>) {
    let (q, load) = (obs.joints(i), obs.loads[i]);
    let target = robot.for_target(obs.target(robot, i));
    let d = errors.deflection(robot, q, load);
    let deflected: Vec<f64> = q.iter().zip(&d).map(|(q, d)| q + d).collect();
    // No turns (neither tilts nor runouts): `turns` is empty, found without the arm's frames.
    let p = turned(&errors.turns(robot, q, load), target.point(&deflected));
    (d, obs.points[i] - p, target.joint_jacobian(&deflected))
}

/// The torque flank whose weights `fit` finds on the given rows, where its flanks, cross-fitted
/// over the two `half`s of the configurations (each half's from `fit` on the other half), have a
/// larger `gain` than the approach flanks do; `None` where they do not or `fit` finds none.
fn cross_fitted(
    features: &[Vec<f64>],
    half: &[usize],
    approach_flank: &[f64],
    fit: impl Fn(&[usize]) -> Option<Vec<f64>>,
    gain: impl Fn(&[f64]) -> f64,
) -> Option<Flank> {
    let n = features.len();
    let mut crossed = vec![0.0; n];
    for h in 0..2 {
        let train: Vec<usize> = (0..n).filter(|&i| half[i] != h).collect();
        let w = fit(&train)?;
        for i in (0..n).filter(|&i| half[i] == h) {
            crossed[i] = torque_side(&w, &features[i]);
        }
    }
    // The approach flank has no weights fitted: its gain is honest as it is.
    if gain(&crossed) <= gain(approach_flank) {
        return None;
    }
    fit(&(0..n).collect::<Vec<_>>()).map(|weights| Flank::Torque { weights })
}

/// The pseudo-inverse of a symmetric positive semi-definite matrix, directions below 1e-10 of
/// its largest eigenvalue left out.
fn pseudo_inverse(gram: DMatrix<f64>) -> DMatrix<f64> {
    let eigen = gram.symmetric_eigen();
    let largest = eigen.eigenvalues.iter().copied().fold(0.0, f64::max);
    let inverse_values =
        (eigen.eigenvalues).map(|v| if v > 1e-10 * largest { 1.0 / v } else { 0.0 });
    &eigen.eigenvectors * DMatrix::from_diagonal(&inverse_values) * eigen.eigenvectors.transpose()
}

/// A torque flank's weights from the rows `rows`: the direction of the torque from a logistic
/// regression of the rows' wanted flanks on the features ([`logistic`]), the preload (the
/// constant, last weight) where the step explains most beyond the joint's own terms (offset,
/// compliance × torque, harmonics, self-weight: [`StepGain`]); then the direction again from
/// the wanted flanks of the step alone (those terms fitted beside it and taken out) and the
/// preload again, until the flanks settle or [`DIRECTION_ROUNDS`] preloads have been searched.
/// The first wanted flanks come from what the fit leaves with the joint's own terms given back,
/// its compliance among them: that term is linear in the torque and shifts the regression's
/// boundary towards the rows' middle torque (tens of N·m off where the joint is compliant),
/// which the search takes out.
fn torque_weights(
    rows: &[usize],
    features: &[Vec<f64>],
    basis: &[Vec<f64>],
    y: &[f64],
    weight: &[f64],
) -> Option<Vec<f64>> {
    let rows_features: Vec<Vec<f64>> = rows.iter().map(|&i| features[i].clone()).collect();
    let mut w = logistic(
        &rows_features,
        &rows.iter().map(|&i| y[i]).collect::<Vec<_>>(),
    )?;
    let Some(gain) = StepGain::new(rows, basis, y, weight) else {
        return Some(w);
    };
    let last = w.len() - 1;
    let mut flanks: Option<Vec<f64>> = None;
    for round in 0..DIRECTION_ROUNDS {
        let torque: Vec<f64> = (rows_features.iter())
            .map(|f| w[..last].iter().zip(f).map(|(w, f)| w * f).sum())
            .collect();
        let Some(preload) = gain.best_preload(&torque) else {
            break;
        };
        w[last] = preload;
        let now: Vec<f64> = (rows_features.iter()).map(|f| torque_side(&w, f)).collect();
        if flanks.as_ref() == Some(&now) || round + 1 == DIRECTION_ROUNDS {
            break;
        }
        // The direction again, from what the fit leaves with the step but without the joint's
        // other terms: the wanted flanks of the step alone.
        let Some(next) = logistic(&rows_features, &gain.step_and_rest(&now)) else {
            break;
        };
        w = next;
        flanks = Some(now);
    }
    Some(w)
}

/// The gain of a backlash step beyond a set of terms the joint already has: for rows `i` with
/// the joint's column `J_i`, the wanted-flank projection `y_i = J_i · e_i` and the basis values
/// `φ(i)` (each term moves the point by `J_i φ_k(i)` times its coefficient), the step `s_i J_i`
/// lowers the squared error, beyond what the terms can take, by
/// `(Σ s_i a_i)² / (Σ w_i − Bᵀ G⁺ B)`: `w_i = |J_i|²`, `G = Σ w_i φ(i) φ(i)ᵀ`,
/// `a_i = y_i − w_i φ(i) · G⁺ Σ φ y` (what the terms leave), `B = Σ s_i w_i φ(i)`.
struct StepGain {
    /// Per row (in the order given): what the terms leave along the joint's column.
    a: Vec<f64>,
    /// Per row: `w_i φ(i)`.
    b: Vec<DVector<f64>>,
    /// `Σ w_i`.
    total: f64,
    /// `G⁺`.
    inverse: DMatrix<f64>,
    /// Per row: the scaled basis values `φ(i)`, `y_i` and `w_i`.
    phi: Vec<DVector<f64>>,
    y: Vec<f64>,
    w: Vec<f64>,
}

impl StepGain {
    fn new(rows: &[usize], basis: &[Vec<f64>], y: &[f64], weight: &[f64]) -> Option<Self> {
        let p = basis.first()?.len();
        let total: f64 = rows.iter().map(|&i| weight[i]).sum();
        if rows.is_empty() || total <= 0.0 {
            return None;
        }
        // Each basis function scaled to a unit root mean square over the rows (the features
        // come in N·m per kg, N·m per kg·m, and times the load): the pseudo-inverse's cut-off
        // then judges directions, not units.
        let mut scale = vec![0.0; p];
        for &i in rows {
            for (s, v) in scale.iter_mut().zip(&basis[i]) {
                *s += v * v;
            }
        }
        let scale: Vec<f64> = (scale.iter())
            .map(|s| (s / rows.len() as f64).sqrt())
            .map(|s| if s > 0.0 { 1.0 / s } else { 0.0 })
            .collect();
        let phi =
            |i: usize| DVector::from_iterator(p, basis[i].iter().zip(&scale).map(|(v, s)| v * s));
        let mut gram = DMatrix::zeros(p, p);
        let mut moment = DVector::zeros(p);
        for &i in rows {
            let phi = phi(i);
            gram.ger(weight[i], &phi, &phi, 1.0);
            moment.axpy(y[i], &phi, 1.0);
        }
        let inverse = pseudo_inverse(gram);
        let coefficients = &inverse * moment;
        let phi: Vec<DVector<f64>> = rows.iter().map(|&i| phi(i)).collect();
        let y: Vec<f64> = rows.iter().map(|&i| y[i]).collect();
        let w: Vec<f64> = rows.iter().map(|&i| weight[i]).collect();
        let a = (phi.iter().zip(&y).zip(&w))
            .map(|((phi, y), w)| y - w * phi.dot(&coefficients))
            .collect();
        let b = phi.iter().zip(&w).map(|(phi, w)| phi * *w).collect();
        Some(Self {
            a,
            b,
            total,
            inverse,
            phi,
            y,
            w,
        })
    }

    /// `y_i` less the joint's terms as a fit of them together with the step `s` finds them:
    /// the step and what neither explains.
    fn step_and_rest(&self, s: &[f64]) -> Vec<f64> {
        let p = self.inverse.nrows();
        let mut gram = DMatrix::zeros(p + 1, p + 1);
        let mut moment = DVector::zeros(p + 1);
        for ((phi, s), (y, w)) in (self.phi.iter().zip(s)).zip(self.y.iter().zip(&self.w)) {
            let x = DVector::from_iterator(p + 1, phi.iter().copied().chain([*s]));
            gram.ger(*w, &x, &x, 1.0);
            moment.axpy(*y, &x, 1.0);
        }
        let coefficients = pseudo_inverse(gram) * moment;
        let terms = coefficients.rows(0, p);
        (self.phi.iter().zip(self.y.iter().zip(&self.w)))
            .map(|(phi, (y, w))| y - w * phi.dot(&terms))
            .collect()
    }

    /// The gain of the step with flanks `s` (one per row, in the order given).
    fn gain(&self, s: &[f64]) -> f64 {
        let dot: f64 = s.iter().zip(&self.a).map(|(s, a)| s * a).sum();
        let mut sum = DVector::zeros(self.inverse.nrows());
        for (s, b) in s.iter().zip(&self.b) {
            sum.axpy(*s, b, 1.0);
        }
        self.ratio(dot, &sum)
    }

    /// `dot² / (Σ w_i − Bᵀ G⁺ B)` for `B` = `sum`, zero where the step is (nearly) one of the
    /// terms.
    fn ratio(&self, dot: f64, sum: &DVector<f64>) -> f64 {
        let rest = self.total - sum.dot(&(&self.inverse * sum));
        if rest > 1e-9 * self.total {
            dot * dot / rest
        } else {
            0.0
        }
    }

    /// The constant `c` whose flanks `+1` where `torque_i + c ≥ 0` (`torque` one per row, in
    /// the order given) gain the most; `None` where no split of the rows gains anything.
    fn best_preload(&self, torque: &[f64]) -> Option<f64> {
        let mut order: Vec<usize> = (0..torque.len()).collect();
        order.sort_by(|&a, &b| torque[b].total_cmp(&torque[a]));
        // Every row on the negative flank, then the largest torques turned one by one.
        let mut dot: f64 = -self.a.iter().sum::<f64>();
        let mut sum = DVector::zeros(self.inverse.nrows());
        for b in &self.b {
            sum -= b;
        }
        let mut best: Option<(f64, f64)> = None;
        for (k, &i) in order.iter().enumerate() {
            dot += 2.0 * self.a[i];
            sum.axpy(2.0, &self.b[i], 1.0);
            let Some(&next) = order.get(k + 1) else {
                break;
            };
            if torque[next] == torque[i] {
                continue;
            }
            let gain = self.ratio(dot, &sum);
            if best.is_none_or(|(g, _)| gain > g) {
                best = Some((gain, -(torque[i] + torque[next]) / 2.0));
            }
        }
        best.filter(|(g, _)| *g > 0.0).map(|(_, c)| c)
    }
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
    let mut roots = vec![0.0; n];
    let mut scaled = x.clone();
    for _ in 0..NEWTON_STEPS {
        let eta = &x * &beta;
        let mut residual = DVector::zeros(n);
        for i in 0..n {
            let mu = 1.0 / (1.0 + (-eta[i]).exp());
            residual[i] = weight[i] * (label[i] - mu);
            roots[i] = (weight[i] * mu * (1.0 - mu)).max(1e-12).sqrt();
        }
        // Each row times its root, a column at a time (the columns are whole in memory).
        for (out, column) in
            (scaled.as_mut_slice().chunks_exact_mut(n)).zip(x.as_slice().chunks_exact(n))
        {
            for ((o, v), root) in out.iter_mut().zip(column).zip(&roots) {
                *o = v * root;
            }
        }
        // `scaledᵀ scaled`, one triangle: each entry the dot product of two columns, as
        // `tr_mul` computes it, whose products commute (the same sum either way round).
        let mut gram = DMatrix::zeros(m, m);
        for i in 0..m {
            for j in i..m {
                let v = scaled.column(i).dot(&scaled.column(j));
                gram[(i, j)] = v;
                gram[(j, i)] = v;
            }
        }
        let grad = x.tr_mul(&residual) - &beta * RIDGE;
        let hess = gram + DMatrix::identity(m, m) * RIDGE;
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

    /// What a fit leaves on a row, against the whole model's point computed independently
    /// (`JointErrors::point`): on noise-free rows of a model with axis runouts (orders 1–2 on
    /// every joint, 0.01–0.04°), compliances and backlash, nothing at that model — the runouts
    /// are not read as something a flank should explain — though they move the points by
    /// tenths of a millimetre.
    #[test]
    fn what_a_fit_with_runouts_leaves_is_the_measured_less_the_whole_model() {
        use robocal_robot::DEG_PER_KNM;
        let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
        let robot = Robot::load(root.join("configs/robots/pmc6va030.toml")).unwrap();
        let mut errors = JointErrors::new(
            [0.0, 0.08, 0.14, 0.38, 0.48, 0.57]
                .iter()
                .map(|c| c * DEG_PER_KNM)
                .collect(),
            Vector3::new(0.0, 0.0, -9.80665),
            Vector3::new(100.0, 0.0, 60.0),
        )
        .with_backlash(&[1, 3])
        .with_runouts(&[0, 1, 2, 3, 4, 5], 2);
        for b in &mut errors.backlash {
            b.value = 0.02f64.to_radians();
        }
        for (k, r) in errors.runouts.iter_mut().enumerate() {
            r.wave.sin = (0.01 + 0.01 * (k % 4) as f64).to_radians();
            r.wave.cos = -(0.02 + 0.005 * (k % 3) as f64).to_radians();
        }
        let mut without = errors.clone();
        without.runouts.clear();
        let mut obs = Observations::new(6);
        let mut moved = 0.0f64;
        for k in 0..40 {
            let t = k as f64;
            let q: Vec<f64> = [0.7, -0.4, 0.9, 1.3, -0.6, 1.1]
                .iter()
                .enumerate()
                .map(|(j, a)| a * (0.37 * t + j as f64).sin())
                .collect();
            let load = [0.0, 8.0, 20.0][k % 3];
            let p = errors.point(&robot, &q, load);
            moved = moved.max((p - without.point(&robot, &q, load)).norm());
            obs.q.extend_from_slice(&q);
            obs.loads.push(load);
            obs.points.push(p);
        }
        assert!(moved > 0.1, "{moved} mm");
        for i in 0..obs.len() {
            let (_, left, _) = row_left(&robot, &errors, &obs, i);
            assert!(left.norm() < 1e-9, "row {i}: {left}");
        }
    }

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
