//! The priors on the harmonics and runouts: how large a coefficient the poses cannot tell
//! from zero is taken to be.

use crate::problem::{CalibrationProblem, PriorSpreads};
use robocal_robot::{Compliance, ErrorParam};

/// Zero-mean Gaussian priors on the transmission harmonics' coefficients (empirical Bayes), their
/// variance `τ²` by marginal likelihood over the coefficients of the fit without them at `u`
/// (each estimate `â ~ N(0, τ² + s²)`, `s` its standard error; [`prior_spread`]): a coefficient
/// the poses determine well keeps its value, one they barely determine (a harmonic of a joint
/// seen over a narrow window, trading with the geometry) is drawn toward the spread of the rest
/// instead of growing to whatever fits. Each prior's row weight is the fit's residual σ over
/// `τ`. The axis runouts' coefficients, waves of the joint angles too, get a prior of their own
/// the same way (their own `τ`: a turn across an axis is not a gear's error). `model`, `r` and
/// `std` are the fit's joint errors, residuals and unknowns' standard deviations. Returns the
/// priors and each group's `τ` (rad; none for a group without two coefficients); none where
/// neither group has two.
pub(super) fn harmonic_prior(
    problem: &CalibrationProblem<'_>,
    model: &Compliance,
    r: &[f64],
    std: &[f64],
) -> Option<(Priors, PriorSpreads)> {
    let ng = problem.selected().len();
    let params = problem.error_params().to_vec();
    let dof = (r.len().checked_sub(problem.unknowns())).filter(|&d| d > 0)?;
    let sigma = (r.iter().map(|v| v * v).sum::<f64>() / dof as f64).sqrt();
    // One group's priors and spread, `None` with fewer than two coefficients.
    let group = |member: fn(&ErrorParam) -> bool| {
        let members: Vec<usize> = (0..params.len()).filter(|&k| member(&params[k])).collect();
        if members.len() < 2 {
            return None;
        }
        let est: Vec<(f64, f64)> = (members.iter())
            .map(|&k| {
                let s = std[ng + k] * problem.scale()[ng + k];
                (model.param(params[k]), s * s)
            })
            .collect();
        let tau = prior_spread(&est).max(HARMONIC_PRIOR_FLOOR);
        let prior: Priors = members.iter().map(|&k| (params[k], sigma / tau)).collect();
        Some((prior, tau))
    };
    let harmonics = group(|p| matches!(p, ErrorParam::HarmonicSin(_) | ErrorParam::HarmonicCos(_)));
    let runouts = group(|p| matches!(p, ErrorParam::RunoutSin(_) | ErrorParam::RunoutCos(_)));
    if harmonics.is_none() && runouts.is_none() {
        return None;
    }
    let spread = PriorSpreads {
        harmonics: harmonics.as_ref().map(|(_, tau)| *tau),
        runouts: runouts.as_ref().map(|(_, tau)| *tau),
    };
    let prior = (harmonics.into_iter().chain(runouts))
        .flat_map(|(p, _)| p)
        .collect();
    Some((prior, spread))
}

/// Priors on joint-error coefficients: each with its row weight.
pub(super) type Priors = Vec<(ErrorParam, f64)>;

/// The spread `τ` that maximises the marginal likelihood of estimates `â_j ~ N(0, τ² + s_j²)`,
/// given as `(â_j, s_j²)`: `L(τ) = −½ Σ ln(τ² + s_j²) + â_j² / (τ² + s_j²)`, searched over
/// `τ = 0` and a logarithmic grid up to twice the largest `|â_j|` (8 points per factor of two,
/// down to 10⁻⁹ of it), the best point's bracket refined by bisection on the sign of `dL/dτ`.
/// `L` can have a maximum at zero and one inside, or rise, fall and rise again where a few
/// estimates are far less certain than the rest; the fixed-point iteration of `Σ w_j² (â_j² − s_j² − τ²) = 0`
/// (`w_j = 1/(τ² + s_j²)`) started from the estimates' mean square, where the uncertain ones make
/// the right side negative, jumps to zero and stops there (ARM5's joint-1 extrapolation split:
/// five of its first ten fits held at the floor, 0.001°, where the maximum lies near 0.005°).
pub fn prior_spread(estimates: &[(f64, f64)]) -> f64 {
    let log_likelihood = |tau: f64| -> f64 {
        let t2 = tau * tau;
        -0.5 * (estimates.iter())
            .map(|(a, s2)| {
                let v = t2 + s2;
                if v > 0.0 {
                    v.ln() + a * a / v
                } else if *a == 0.0 {
                    f64::NEG_INFINITY
                } else {
                    f64::INFINITY
                }
            })
            .sum::<f64>()
    };
    let top = 2.0 * estimates.iter().fold(0.0f64, |m, (a, _)| m.max(a.abs()));
    if !(top.is_finite() && top > 0.0) {
        return 0.0;
    }
    // τ = 0, then the grid from 10⁻⁹ of the top upward; a tie keeps the smaller spread.
    const PER_OCTAVE: usize = 8;
    const OCTAVES: usize = 30;
    let grid: Vec<f64> = std::iter::once(0.0)
        .chain(
            (0..=PER_OCTAVE * OCTAVES)
                .map(|i| top * (2f64).powf(i as f64 / PER_OCTAVE as f64 - OCTAVES as f64)),
        )
        .collect();
    let values: Vec<f64> = grid.iter().map(|&t| log_likelihood(t)).collect();
    let best = (0..grid.len()).fold(0, |b, i| if values[i] > values[b] { i } else { b });
    if best == 0 {
        return 0.0;
    }
    // Between the best point's neighbours, the root of `dL/dτ = τ h(τ)`,
    // `h(τ) = Σ (â_j² − s_j² − τ²) / (τ² + s_j²)²`, by bisection (its sign is exact where `L`'s
    // differences are round-off).
    let h = |tau: f64| -> f64 {
        let t2 = tau * tau;
        (estimates.iter())
            .map(|(a, s2)| (a * a - s2 - t2) / ((t2 + s2) * (t2 + s2)))
            .sum::<f64>()
    };
    let (mut lo, mut hi) = (
        grid[best.saturating_sub(1)],
        grid[(best + 1).min(grid.len() - 1)],
    );
    if !(h(lo) > 0.0 && h(hi) < 0.0) {
        return grid[best];
    }
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if mid <= lo || mid >= hi {
            break;
        }
        if h(mid) > 0.0 {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    let tau = 0.5 * (lo + hi);
    if log_likelihood(tau) >= values[best] {
        tau
    } else {
        grid[best]
    }
}

/// The smallest spread of the harmonics' prior, rad (a thousandth of a degree, 17 µm a metre
/// out): where the harmonics spread no more than their own errors the prior holds them near
/// zero, not at it.
pub(super) const HARMONIC_PRIOR_FLOOR: f64 = 1e-3 * std::f64::consts::PI / 180.0;
