//! How sure a residual model is, checked on the folds: the Gaussian process's standard
//! deviations, calibrated on the held-out rows the default calibration has anyway.
//!
//! A GP's latent standard deviation says how well its training rows pin the residual down at a
//! pose, under its own kernel; it knows nothing of the physics' uncertainty beneath it, and a
//! kernel fitted by marginal likelihood is often too sure of itself. On the accuracy suite's
//! development twins the raw deviation was 1.8–3× smaller than the error left on the test
//! poses. The folds hold the independent check: on each
//! held-out row the error from the measured point `e = y − ŷ` is the tracker's noise plus the
//! model's own error, so with `σᵢ` the fold model's deviation there (root sum of the axes'
//! variances) and the error taken as isotropic,
//!
//! `eᵢ ~ N(0, vᵢ I₃)`, `vᵢ = (ν + c² σᵢ²) / 3`,
//!
//! whose negative log-likelihood `Σ 1.5 ln vᵢ + |eᵢ|² / (2 vᵢ)` gives the factor `c` on the
//! deviations and the noise `ν` (mm², the three axes' together) that the held-out rows support
//! best. The noise is estimated with the factor rather than taken from the GP (whose noise term
//! also takes what its kernel cannot follow). The final model's deviations are multiplied by
//! `c` (`std_scale` in `residual.json`).

use nalgebra::Vector3;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use robocal_data::{Measurement, Sample};
use robocal_model::CalibratedModel;
use robocal_residual::gp::subset;
use serde::Serialize;

/// Held-out rows per fold whose deviation is computed (a seeded choice; each costs a triangular
/// solve per axis against the fold model's conditioning rows).
pub const ROWS_PER_FOLD: usize = 150;

/// Fewest held-out rows a factor is estimated from.
pub const MIN_ROWS: usize = 30;

/// What the folds say of a residual model's standard deviations.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct SpreadCalibration {
    /// Held-out rows it was estimated on.
    pub rows: usize,
    /// The factor on the model's latent standard deviations.
    pub scale: f64,
    /// Standard deviation of what the held-out errors hold besides the model's own error (the
    /// tracker's noise and whatever no model takes), mm, root sum of the three axes' variances.
    pub noise: f64,
    /// Share of the held-out rows whose error from the measured point lies within
    /// `√(noise² + σ²)` with the model's deviations as they were (for errors drawn as the model
    /// says, 61 %).
    pub within_before: f64,
    /// The same with the deviations multiplied by `scale`.
    pub within_after: f64,
}

/// `(|y − ŷ|², σ²)` (mm²) of at most [`ROWS_PER_FOLD`] of `test`'s rows (seeded), with the
/// points and deviations `predicted` gives for them; empty when it gives none.
fn pairs_of(
    test: &[&Measurement],
    seed: u64,
    predicted: impl FnOnce(&[&Sample]) -> Option<(Vec<Vector3<f64>>, Vec<f64>)>,
) -> Vec<(f64, f64)> {
    let idx = subset(
        test.len(),
        ROWS_PER_FOLD,
        &mut ChaCha8Rng::seed_from_u64(seed),
    );
    let rows: Vec<&Sample> = idx.iter().map(|&i| &test[i].sample).collect();
    let Some((points, sigmas)) = predicted(&rows) else {
        return Vec::new();
    };
    (idx.iter().zip(points).zip(sigmas))
        .map(|((&i, p), s)| ((test[i].position - p).norm_squared(), s * s))
        .filter(|(e, s)| e.is_finite() && s.is_finite())
        .collect()
}

/// `(|y − ŷ|², σ²)` (mm²) of at most [`ROWS_PER_FOLD`] of `test`'s rows (seeded), under a fold
/// model whose residual gives standard deviations; empty when it gives none.
pub fn held_out_pairs(
    model: &CalibratedModel,
    test: &[&Measurement],
    seed: u64,
) -> Vec<(f64, f64)> {
    pairs_of(test, seed, |rows| {
        let (points, sigmas) = model.predict_with_sigma(rows.iter().copied(), true);
        sigmas.map(|s| (points, s))
    })
}

/// Negative log-likelihood (constants dropped) of the pairs at noise `nu` and squared factor `c2`.
fn nll(pairs: &[(f64, f64)], nu: f64, c2: f64) -> f64 {
    pairs
        .iter()
        .map(|&(e2, s2)| {
            let v = (nu + c2 * s2) / 3.0;
            1.5 * v.ln() + 0.5 * e2 / v
        })
        .sum()
}

/// Minimum of `f` on `[a, b]` by golden-section search (`f` unimodal there).
fn golden(f: impl Fn(f64) -> f64, mut a: f64, mut b: f64) -> f64 {
    let r = (5f64.sqrt() - 1.0) / 2.0;
    let (mut x1, mut x2) = (b - r * (b - a), a + r * (b - a));
    let (mut f1, mut f2) = (f(x1), f(x2));
    for _ in 0..60 {
        if f1 <= f2 {
            b = x2;
            (x2, f2) = (x1, f1);
            x1 = b - r * (b - a);
            f1 = f(x1);
        } else {
            a = x1;
            (x1, f1) = (x2, f2);
            x2 = a + r * (b - a);
            f2 = f(x2);
        }
    }
    0.5 * (a + b)
}

/// Bounds of the factor `c`.
const SCALE: (f64, f64) = (0.1, 100.0);

/// The factor and noise that make the held-out errors most likely (module docs); `None` with
/// fewer than [`MIN_ROWS`] pairs or deviations that are all zero.
pub fn calibrate(pairs: &[(f64, f64)]) -> Option<SpreadCalibration> {
    if pairs.len() < MIN_ROWS || pairs.iter().all(|p| p.1 <= 0.0) {
        return None;
    }
    let mean_e2 = pairs.iter().map(|p| p.0).sum::<f64>() / pairs.len() as f64;
    if !(mean_e2.is_finite() && mean_e2 > 0.0) {
        return None;
    }
    // The noise between a millionth of the mean squared error and all of it (ln units).
    let (nu_lo, nu_hi) = ((mean_e2 * 1e-6).ln(), mean_e2.ln());
    let best_nu = |ln_c2: f64| {
        let c2 = ln_c2.exp();
        golden(|ln_nu| nll(pairs, ln_nu.exp(), c2), nu_lo, nu_hi)
    };
    let profile = |ln_c2: f64| nll(pairs, best_nu(ln_c2).exp(), ln_c2.exp());
    // The factor: a grid over its range (the profile need not be unimodal over all of it),
    // then golden-section search between the best point's neighbours.
    let (lo, hi) = ((SCALE.0 * SCALE.0).ln(), (SCALE.1 * SCALE.1).ln());
    let steps = 80;
    let grid: Vec<f64> = (0..=steps)
        .map(|k| lo + (hi - lo) * k as f64 / steps as f64)
        .collect();
    let k = (0..grid.len())
        .map(|k| (k, profile(grid[k])))
        .min_by(|a, b| a.1.total_cmp(&b.1))?
        .0;
    let ln_c2 = golden(profile, grid[k.saturating_sub(1)], grid[(k + 1).min(steps)]);
    let nu = best_nu(ln_c2).exp();
    let scale = (0.5 * ln_c2).exp();
    let within = |c: f64| {
        pairs
            .iter()
            .filter(|&&(e2, s2)| e2 <= nu + c * c * s2)
            .count() as f64
            / pairs.len() as f64
    };
    Some(SpreadCalibration {
        rows: pairs.len(),
        scale,
        noise: nu.sqrt(),
        within_before: within(1.0),
        within_after: within(scale),
    })
}

/// What the folds say of a network residual's spread beside the physics' deviation.
///
/// A network gives no standard deviation; the physical model beneath it gives its parameters'
/// (`CalibratedModel::physics_sigmas`: the covariance, a flank that may turn, a harmonic held
/// beyond its reach), which grows where the poses did not reach but knows nothing of what the
/// network leaves. On the held-out rows `eᵢ ~ N(0, (ν + σᵢ²)/3 · I₃)`, `σᵢ` the fold's physical
/// deviation, and the `ν` that makes them most likely is that spread (the factor on `σ` held at
/// 1: the physics' deviation is its own, and a factor fitted beside `ν` brought it farther from
/// the truth on ten of twelve development cases). `ν` holds the tracker's noise too,
/// which the held-out rows cannot tell from the network's error: the deviation is the measured
/// point's, on the cautious side by that noise.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct SpreadBeside {
    /// Held-out rows it was estimated on.
    pub rows: usize,
    /// `√ν`, mm (root sum of the three axes' variances).
    pub spread: f64,
    /// Share of the held-out rows whose error from the measured point lies within the physical
    /// deviation alone.
    pub within_physics: f64,
    /// The same within `√(σ² + ν)` (for errors drawn as the model says, 61 %).
    pub within_after: f64,
}

/// `(|y − ŷ|², σ²)` (mm²) of at most [`ROWS_PER_FOLD`] of `test`'s rows (seeded, the rows
/// [`held_out_pairs`] takes), `ŷ` the fold model's prediction and `σ` its physical model's
/// deviation; empty when it has no covariance.
pub fn held_out_pairs_beside(
    model: &CalibratedModel,
    test: &[&Measurement],
    seed: u64,
) -> Vec<(f64, f64)> {
    pairs_of(test, seed, |rows| {
        let sigmas = model.physics_sigmas(rows)?;
        Some((model.predict(rows.iter().copied()), sigmas))
    })
}

/// The spread `ν` beside the deviations that makes the held-out errors most likely
/// ([`SpreadBeside`]); `None` with fewer than [`MIN_ROWS`] pairs or no error at all.
pub fn spread_beside(pairs: &[(f64, f64)]) -> Option<SpreadBeside> {
    if pairs.len() < MIN_ROWS {
        return None;
    }
    let mean_e2 = pairs.iter().map(|p| p.0).sum::<f64>() / pairs.len() as f64;
    if !(mean_e2.is_finite() && mean_e2 > 0.0) {
        return None;
    }
    // Between a millionth of the mean squared error and all of it (ln units); the likelihood
    // in ν with the deviations fixed has one maximum.
    let ln_nu = golden(
        |ln_nu| nll(pairs, ln_nu.exp(), 1.0),
        (mean_e2 * 1e-6).ln(),
        mean_e2.ln(),
    );
    let nu = ln_nu.exp();
    let within = |nu: f64| {
        pairs.iter().filter(|&&(e2, s2)| e2 <= nu + s2).count() as f64 / pairs.len() as f64
    };
    Some(SpreadBeside {
        rows: pairs.len(),
        spread: nu.sqrt(),
        within_physics: within(0.0),
        within_after: within(nu),
    })
}

#[cfg(test)]
mod tests {
    use rand_distr::{Distribution, Normal, Uniform};

    use super::*;

    /// Errors drawn as `N(0, (ν + c² σ²)/3 I₃)` with deviations spread over two decades: the
    /// factor and the noise put in come back.
    fn recovered(scale: f64, noise: f64, rows: usize, seed: u64) -> SpreadCalibration {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let log_sigma = Uniform::new(-4.0f64, -1.0).unwrap();
        let unit = Normal::new(0.0, 1.0).unwrap();
        let pairs: Vec<(f64, f64)> = (0..rows)
            .map(|_| {
                let s = 10f64.powf(log_sigma.sample(&mut rng) / 2.0);
                let v = (noise * noise + scale * scale * s * s) / 3.0;
                let e2: f64 = (0..3)
                    .map(|_| f64::powi(unit.sample(&mut rng), 2) * v)
                    .sum();
                (e2, s * s)
            })
            .collect();
        calibrate(&pairs).unwrap()
    }

    #[test]
    fn the_factor_and_the_noise_put_in_come_back() {
        for (scale, noise) in [(2.5, 0.03), (0.6, 0.01), (1.0, 0.05)] {
            let c = recovered(scale, noise, 3000, 11);
            assert!((c.scale / scale - 1.0).abs() < 0.08, "{scale}: {c:?}");
            assert!((c.noise / noise - 1.0).abs() < 0.15, "{noise}: {c:?}");
            // Errors drawn as the scaled deviations say: about 61 % within one spread.
            assert!((0.55..0.67).contains(&c.within_after), "{c:?}");
        }
    }

    /// Errors drawn as `N(0, (ν + σ²)/3 I₃)`: the spread put in comes back, with deviations
    /// much smaller than it, about as large, and larger.
    #[test]
    fn the_spread_beside_the_deviations_comes_back() {
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        let unit = Normal::new(0.0, 1.0).unwrap();
        for (spread, sigma) in [(0.03, 0.003), (0.02, 0.02), (0.01, 0.03)] {
            let spreads = Uniform::new(0.5 * sigma, 1.5 * sigma).unwrap();
            let pairs: Vec<(f64, f64)> = (0..3000)
                .map(|_| {
                    let s: f64 = spreads.sample(&mut rng);
                    let v = (spread * spread + s * s) / 3.0;
                    let e2: f64 = (0..3)
                        .map(|_| f64::powi(unit.sample(&mut rng), 2) * v)
                        .sum();
                    (e2, s * s)
                })
                .collect();
            let b = spread_beside(&pairs).unwrap();
            assert!(
                (b.spread / spread - 1.0).abs() < 0.1,
                "{spread}, {sigma}: {b:?}"
            );
            assert!((0.55..0.67).contains(&b.within_after), "{b:?}");
            assert!(b.within_physics < b.within_after, "{b:?}");
        }
        assert!(spread_beside(&[(0.01, 0.001); MIN_ROWS - 1]).is_none());
    }

    #[test]
    fn too_few_rows_or_no_deviations_give_none() {
        assert!(calibrate(&[(0.01, 0.001); MIN_ROWS - 1]).is_none());
        assert!(calibrate(&[(0.01, 0.0); 100]).is_none());
    }
}
