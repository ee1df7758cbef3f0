//! A Gaussian-process residual: one GP per world axis over the encoded inputs, with an ARD
//! squared-exponential kernel and Gaussian noise whose hyper-parameters maximise the marginal
//! likelihood; it gives a predictive standard deviation with every correction ([`GpResidual`],
//! the residual model; [`GpAxis`], one axis).
//!
//! For axis `a` with standardised targets `y` (mean 0, variance 1 on the training rows) and
//! standardised features `x`:
//!
//! `k(x, x') = s² exp(−½ Σ_d (x_d − x'_d)² / ℓ_d²)`, `K = k(X, X) + σ² I`,
//!
//! `−log p(y) = ½ yᵀK⁻¹y + ½ log |K| + (n/2) log 2π`, minimised over `log s², log ℓ_d, log σ²`
//! by Adam (or L-BFGS, [`GpOptimizer`]) with the analytic gradient `½ tr((K⁻¹ − ααᵀ) ∂K/∂θ)`,
//! `α = K⁻¹y`, on a seeded subset of at most `hyper_rows` rows (O(n³) per evaluation), the best
//! point seen kept. The model then conditions on at most `max_rows` rows (one Cholesky
//! factorisation, faer): the mean is `k(x*, X) α` and the latent variance `s² − k*ᵀ K⁻¹ k*`, both
//! in standardised units and scaled back to mm.
//!
//! ```
//! use robocal_residual::gp::{GpAxis, GpSettings};
//! // y = sin(3x) on 40 points of [-1, 1]: the GP interpolates between them.
//! let x: Vec<Vec<f64>> = (0..40).map(|i| vec![-1.0 + 2.0 * i as f64 / 39.0]).collect();
//! let y: Vec<f64> = x.iter().map(|r| (3.0 * r[0]).sin()).collect();
//! let gp = GpAxis::fit(&x, &y, &GpSettings::default(), 7).unwrap();
//! let (mean, std) = gp.predict_one(&x, &[0.31], None);
//! assert!((mean - (0.93f64).sin()).abs() < 1e-2, "{mean}");
//! assert!(std.is_none());
//! ```

use std::cell::{Cell, RefCell};
use std::rc::Rc;

use faer::linalg::solvers::{DenseSolveCore, Solve};
use faer::{Mat, Side};
use rand::SeedableRng;
use rand::seq::SliceRandom;
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use robocal_data::Invalid;
use serde::{Deserialize, Serialize};

use crate::error::{ResidualError, Result};
use crate::residual::Residual;
use crate::samples::{Samples, Standardizer};

/// How a Gaussian process is fitted.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GpSettings {
    /// Most rows the marginal likelihood is maximised on (a seeded subset; O(n³) per step).
    #[serde(default = "default_hyper_rows")]
    pub hyper_rows: usize,
    /// Most rows the model conditions on (a seeded subset; O(n³) once, O(n) per prediction).
    #[serde(default = "default_max_rows")]
    pub max_rows: usize,
    /// Evaluations of the marginal likelihood: Adam's steps, or the most L-BFGS may spend.
    #[serde(default = "default_iterations")]
    pub iterations: usize,
    /// Adam's step size in log units.
    #[serde(default = "default_step")]
    pub step: f64,
    /// How the marginal likelihood is maximised.
    #[serde(default)]
    pub optimizer: GpOptimizer,
}

/// The optimiser of a Gaussian process's marginal likelihood; `iterations` bounds either one's
/// likelihood evaluations.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum GpOptimizer {
    /// Adam on the log hyper-parameters, the iterates clamped to their bounds.
    #[default]
    Adam,
    /// L-BFGS (argmin, More–Thuente line search) on the log hyper-parameters mapped onto their
    /// bounds by a logistic function, restarted from the best point where it stops early.
    Lbfgs,
}

fn default_hyper_rows() -> usize {
    500
}
fn default_max_rows() -> usize {
    2500
}
fn default_iterations() -> usize {
    80
}
fn default_step() -> f64 {
    0.08
}

impl Default for GpSettings {
    fn default() -> Self {
        Self {
            hyper_rows: default_hyper_rows(),
            max_rows: default_max_rows(),
            iterations: default_iterations(),
            step: default_step(),
            optimizer: GpOptimizer::default(),
        }
    }
}

/// Most rows a GP may condition on: its kernel matrix is `n² × 8` bytes (about 200 MB here).
pub const MAX_GP_ROWS: usize = 5000;

impl GpSettings {
    /// The first bad setting as (field, message).
    pub fn check(&self) -> std::result::Result<(), Invalid> {
        if self.hyper_rows < 2 || self.hyper_rows > MAX_GP_ROWS {
            return Err(Invalid::new(
                "hyper_rows",
                format!("must lie between 2 and {MAX_GP_ROWS}"),
            ));
        }
        if self.max_rows < 2 || self.max_rows > MAX_GP_ROWS {
            return Err(Invalid::new(
                "max_rows",
                format!("must lie between 2 and {MAX_GP_ROWS}"),
            ));
        }
        if self.iterations > 10_000 {
            return Err(Invalid::new("iterations", "at most 10000"));
        }
        if !(self.step.is_finite() && self.step > 0.0 && self.step < 10.0) {
            return Err(Invalid::new("step", "must lie between 0 and 10"));
        }
        Ok(())
    }
}

/// Bounds of the log hyper-parameters (standardised units): signal variance, length-scales,
/// noise variance. They keep the kernel matrix well away from singular.
const LOG_SIGNAL: (f64, f64) = (-9.2, 4.6); // 1e-4 .. 100
const LOG_LENGTH: (f64, f64) = (-3.0, 5.0); // 0.05 .. 150
const LOG_NOISE: (f64, f64) = (-11.5, 0.7); // 1e-5 .. 2
/// Rows whose standard deviations are solved for at once: a kernel block of conditioning rows ×
/// 256 values (5 MB at the default 2500 rows, 10 MB at [`MAX_GP_ROWS`]).
const STD_CHUNK: usize = 256;

/// [`GpResidual::std_scale`] of a model fitted without folds.
fn unit_scale() -> f64 {
    1.0
}

/// Added to the kernel's diagonal for round-off, standardised units.
const JITTER: f64 = 1e-8;

/// One axis's Gaussian process, in standardised units.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GpAxis {
    /// Signal variance `s²`.
    pub signal_variance: f64,
    /// One length-scale per feature.
    pub lengthscales: Vec<f64>,
    /// Noise variance `σ²`.
    pub noise_variance: f64,
    /// Target mean and standard deviation (mm) that standardised the targets.
    pub target_mean: f64,
    /// See `target_mean`.
    pub target_std: f64,
    /// `K⁻¹ y` over the rows the model conditions on.
    pub alpha: Vec<f64>,
    /// Negative log marginal likelihood per row at the chosen hyper-parameters (on the
    /// hyper-parameter subset).
    pub nll_per_row: f64,
}

/// Squared-exponential kernel without the noise term.
fn kernel(a: &[f64], b: &[f64], inv_l2: &[f64], s2: f64) -> f64 {
    let mut d2 = 0.0;
    for ((x, y), w) in a.iter().zip(b).zip(inv_l2) {
        let d = x - y;
        d2 += d * d * w;
    }
    s2 * (-0.5 * d2).exp()
}

/// The kernel matrix of `x` with noise `noise` on the diagonal: its lower triangle, all that its
/// Cholesky factorisation (`llt(Side::Lower)`) and the gradient read; zeros above.
fn gram(x: &[Vec<f64>], inv_l2: &[f64], s2: f64, noise: f64) -> Mat<f64> {
    let n = x.len();
    let mut k = Mat::<f64>::zeros(n, n);
    for j in 0..n {
        k[(j, j)] = s2 + noise + JITTER;
        for i in j + 1..n {
            k[(i, j)] = kernel(&x[i], &x[j], inv_l2, s2);
        }
    }
    k
}

/// Negative log marginal likelihood and its gradient in `theta = [log s², log ℓ.., log σ²]`.
fn nll_and_gradient(x: &[Vec<f64>], y: &[f64], theta: &[f64]) -> Option<(f64, Vec<f64>)> {
    let n = x.len();
    let d = theta.len() - 2;
    let s2 = theta[0].exp();
    let inv_l2: Vec<f64> = theta[1..=d].iter().map(|t| (-2.0 * t).exp()).collect();
    let noise = theta[d + 1].exp();
    let k = gram(x, &inv_l2, s2, noise);
    let llt = k.llt(Side::Lower).ok()?;
    let yv = Mat::from_fn(n, 1, |i, _| y[i]);
    let alpha = llt.solve(&yv);
    let l = llt.L();
    let log_det: f64 = (0..n).map(|i| l[(i, i)].ln()).sum::<f64>() * 2.0;
    let fit: f64 = (0..n).map(|i| y[i] * alpha[(i, 0)]).sum();
    let nll = 0.5 * fit + 0.5 * log_det + 0.5 * n as f64 * (2.0 * std::f64::consts::PI).ln();
    // W = K⁻¹ − ααᵀ; dNLL/dθ = ½ Σ_ij W_ij ∂K_ij/∂θ.
    let kinv = llt.inverse();
    // W and ∂K/∂θ are symmetric: each pair i > j counted once, twice over.
    // Every sum takes its terms in the same order as one loop over the pairs would; the
    // length-scales' sums are kept apart, each row's slices cut to `d` up front, so that the
    // loop over the features runs without bounds checks, lane by lane (the same products).
    let (mut signal, mut noise_grad) = (0.0, 0.0);
    let mut lengths = vec![0.0; d];
    let inv_l2 = &inv_l2[..d];
    for i in 0..n {
        let w = kinv[(i, i)] - alpha[(i, 0)] * alpha[(i, 0)];
        signal += 0.5 * w * s2;
        noise_grad += 0.5 * w * noise;
        let xi = &x[i][..d];
        for j in 0..i {
            let wk = (kinv[(i, j)] - alpha[(i, 0)] * alpha[(j, 0)]) * k[(i, j)];
            signal += wk;
            let xj = &x[j][..d];
            for (((g, a), b), w) in lengths.iter_mut().zip(xi).zip(xj).zip(inv_l2) {
                let r = a - b;
                *g += wk * r * r * w;
            }
        }
    }
    let mut grad = Vec::with_capacity(d + 2);
    grad.push(signal);
    grad.extend(lengths);
    grad.push(noise_grad);
    Some((nll, grad))
}

/// A point of the marginal likelihood's optimisation: its negative log likelihood and `theta`.
type Optimum = Option<(f64, Vec<f64>)>;

/// A point `z` with its cost and gradient.
type Evaluation = (Vec<f64>, f64, Vec<f64>);

/// The lower and upper bounds of `theta` for `d` features.
fn bounds(d: usize) -> (Vec<f64>, Vec<f64>) {
    let mut lo = vec![LOG_SIGNAL.0];
    let mut hi = vec![LOG_SIGNAL.1];
    lo.extend(std::iter::repeat_n(LOG_LENGTH.0, d));
    hi.extend(std::iter::repeat_n(LOG_LENGTH.1, d));
    lo.push(LOG_NOISE.0);
    hi.push(LOG_NOISE.1);
    (lo, hi)
}

/// Adam from `theta` for `settings.iterations` evaluations, the iterates clamped to their
/// bounds; where the kernel matrix is not positive definite, more noise. The best point seen.
fn adam(x: &[Vec<f64>], y: &[f64], mut theta: Vec<f64>, settings: &GpSettings) -> Optimum {
    let (lo, hi) = bounds(theta.len() - 2);
    let noise = theta.len() - 1;
    let clamp = |theta: &mut [f64]| {
        for ((t, lo), hi) in theta.iter_mut().zip(&lo).zip(&hi) {
            *t = t.clamp(*lo, *hi);
        }
    };
    let (b1, b2, eps) = (0.9, 0.999, 1e-8);
    let (mut m, mut v) = (vec![0.0; theta.len()], vec![0.0; theta.len()]);
    let mut best: Optimum = None;
    let steps = settings.iterations.max(1);
    for step in 1..=steps {
        let Some((nll, grad)) = nll_and_gradient(x, y, &theta) else {
            theta[noise] += 1.0;
            clamp(&mut theta);
            continue;
        };
        if best.as_ref().is_none_or(|(b, _)| nll < *b) {
            best = Some((nll, theta.clone()));
        }
        if step == steps {
            break;
        }
        for k in 0..theta.len() {
            m[k] = b1 * m[k] + (1.0 - b1) * grad[k];
            v[k] = b2 * v[k] + (1.0 - b2) * grad[k] * grad[k];
            let mh = m[k] / (1.0 - b1.powi(step as i32));
            let vh = v[k] / (1.0 - b2.powi(step as i32));
            theta[k] -= settings.step * mh / (vh.sqrt() + eps);
        }
        clamp(&mut theta);
    }
    best
}

/// L-BFGS restarts after a run that stops early (a line search that gives up, a step too small
/// for the cost tolerance) while it still lowers the likelihood's negative.
const LBFGS_RESTARTS: usize = 3;

/// The negative log likelihood over `z`, `theta = lo + (hi − lo) σ(z)` (σ logistic), for
/// argmin; it counts its evaluations and keeps the best point seen.
struct Likelihood<'a> {
    x: &'a [Vec<f64>],
    y: &'a [f64],
    lo: &'a [f64],
    hi: &'a [f64],
    last: RefCell<Option<Evaluation>>,
    best: Rc<RefCell<Optimum>>,
    evaluations: Rc<Cell<usize>>,
    /// Most evaluations over every run; past them the cost is an error that ends the run.
    budget: usize,
}

impl Likelihood<'_> {
    fn theta(&self, z: &[f64]) -> Vec<f64> {
        z.iter()
            .zip(self.lo.iter().zip(self.hi))
            .map(|(z, (lo, hi))| lo + (hi - lo) * logistic(*z))
            .collect()
    }

    fn evaluate(&self, z: &[f64]) -> std::result::Result<(f64, Vec<f64>), argmin::core::Error> {
        if let Some((at, nll, grad)) = &*self.last.borrow()
            && at.as_slice() == z
        {
            return Ok((*nll, grad.clone()));
        }
        if self.evaluations.get() >= self.budget {
            return Err(argmin::core::Error::msg(
                "the likelihood's evaluations are spent",
            ));
        }
        self.evaluations.set(self.evaluations.get() + 1);
        let theta = self.theta(z);
        let (nll, grad) = match nll_and_gradient(self.x, self.y, &theta) {
            Some((nll, g)) => {
                let mut best = self.best.borrow_mut();
                if nll.is_finite() && best.as_ref().is_none_or(|(b, _)| nll < *b) {
                    *best = Some((nll, theta));
                }
                // dθ/dz = (hi − lo) σ(z) (1 − σ(z)).
                let gz = g
                    .iter()
                    .zip(z)
                    .zip(self.lo.iter().zip(self.hi))
                    .map(|((g, z), (lo, hi))| {
                        let s = logistic(*z);
                        g * (hi - lo) * s * (1.0 - s)
                    })
                    .collect();
                (nll, gz)
            }
            // Not positive definite: a cost the line search backs away from.
            None => (f64::INFINITY, vec![0.0; z.len()]),
        };
        *self.last.borrow_mut() = Some((z.to_vec(), nll, grad.clone()));
        Ok((nll, grad))
    }
}

fn logistic(z: f64) -> f64 {
    1.0 / (1.0 + (-z).exp())
}

impl argmin::core::CostFunction for Likelihood<'_> {
    type Param = Vec<f64>;
    type Output = f64;
    fn cost(&self, z: &Vec<f64>) -> std::result::Result<f64, argmin::core::Error> {
        Ok(self.evaluate(z)?.0)
    }
}

impl argmin::core::Gradient for Likelihood<'_> {
    type Param = Vec<f64>;
    type Gradient = Vec<f64>;
    fn gradient(&self, z: &Vec<f64>) -> std::result::Result<Vec<f64>, argmin::core::Error> {
        Ok(self.evaluate(z)?.1)
    }
}

/// L-BFGS (memory 7) from `theta0` (inside its bounds) for at most `evaluations` likelihood
/// evaluations; a run that stops before them and still lowered the best point is restarted from
/// it with a fresh memory, at most [`LBFGS_RESTARTS`] times. The best point seen.
fn lbfgs(x: &[Vec<f64>], y: &[f64], theta0: &[f64], evaluations: usize) -> Optimum {
    use argmin::core::Executor;
    use argmin::solver::linesearch::MoreThuenteLineSearch;
    use argmin::solver::quasinewton::LBFGS;
    let (lo, hi) = bounds(theta0.len() - 2);
    let to_z = |theta: &[f64]| -> Vec<f64> {
        theta
            .iter()
            .zip(lo.iter().zip(&hi))
            .map(|(t, (lo, hi))| {
                let u = ((t - lo) / (hi - lo)).clamp(1e-6, 1.0 - 1e-6);
                (u / (1.0 - u)).ln()
            })
            .collect()
    };
    let best = Rc::new(RefCell::new(None));
    let spent = Rc::new(Cell::new(0));
    let mut start = to_z(theta0);
    for _ in 0..=LBFGS_RESTARTS {
        let before = best.borrow().as_ref().map(|(b, _): &(f64, Vec<f64>)| *b);
        let problem = Likelihood {
            x,
            y,
            lo: &lo,
            hi: &hi,
            last: RefCell::new(None),
            best: Rc::clone(&best),
            evaluations: Rc::clone(&spent),
            budget: evaluations,
        };
        let Ok(solver) = LBFGS::new(MoreThuenteLineSearch::new(), 7)
            .with_tolerance_grad(1e-6)
            .and_then(|s| s.with_tolerance_cost(1e-9))
        else {
            break;
        };
        // A failed line search or the evaluations spent end a run like any other stop: the best
        // point is kept.
        let left = evaluations.saturating_sub(spent.get()) as u64;
        let _ = Executor::new(problem, solver)
            .configure(|s| s.param(start.clone()).max_iters(left))
            .run();
        let now = best.borrow().as_ref().map(|(b, _)| *b);
        let improved = match (before, now) {
            (None, Some(_)) => true,
            (Some(b), Some(n)) => n < b,
            _ => false,
        };
        if !improved || spent.get() >= evaluations {
            break;
        }
        start = to_z(&best.borrow().as_ref().expect("improved").1);
    }
    best.take()
}

/// Seeded choice of at most `max` of `n` row indices, ascending (all of them when `n ≤ max`).
pub fn subset(n: usize, max: usize, rng: &mut ChaCha8Rng) -> Vec<usize> {
    let mut idx: Vec<usize> = (0..n).collect();
    if n > max {
        idx.shuffle(rng);
        idx.truncate(max);
        idx.sort_unstable();
    }
    idx
}

impl GpAxis {
    /// Fits one axis on standardised features `x` (rows) and targets `y` (mm): the
    /// hyper-parameters on a seeded subset, then `α` on at most `settings.max_rows` rows (the
    /// same subset for every call with the same `seed` and row count, so that axes fitted with
    /// one seed share their rows).
    pub fn fit(x: &[Vec<f64>], y: &[f64], settings: &GpSettings, seed: u64) -> Result<Self> {
        let (model, _, _) = Self::fit_rows(x, y, settings, seed)?;
        Ok(model)
    }

    /// [`Self::fit`], also returning the rows (indices into `x`) the model conditions on and
    /// the Cholesky factor of its kernel matrix over them ([`Self::factor`]; for variances).
    pub fn fit_rows(
        x: &[Vec<f64>],
        y: &[f64],
        settings: &GpSettings,
        seed: u64,
    ) -> Result<(Self, Vec<usize>, faer::linalg::solvers::Llt<f64>)> {
        settings
            .check()
            .map_err(|e| ResidualError::Settings(e.within("gp")))?;
        let n = x.len();
        if n < 2 || y.len() != n {
            return Err(ResidualError::Data(format!(
                "a Gaussian process needs at least two rows with one target each ({n} rows, {} targets)",
                y.len()
            )));
        }
        let d = x[0].len();
        let target_mean = y.iter().sum::<f64>() / n as f64;
        let var = y.iter().map(|v| (v - target_mean).powi(2)).sum::<f64>() / n as f64;
        let target_std = if var > 1e-24 { var.sqrt() } else { 1.0 };
        let ys: Vec<f64> = y.iter().map(|v| (v - target_mean) / target_std).collect();

        // Hyper-parameters by Adam on a subset.
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let keep = subset(n, settings.hyper_rows, &mut rng);
        let hx: Vec<Vec<f64>> = keep.iter().map(|&i| x[i].clone()).collect();
        let hy: Vec<f64> = keep.iter().map(|&i| ys[i]).collect();
        let mut theta = vec![0.0; d + 2];
        theta[1..=d].fill((d.max(1) as f64).sqrt().ln());
        theta[d + 1] = (0.1f64).ln();
        let best = match settings.optimizer {
            GpOptimizer::Adam => adam(&hx, &hy, theta, settings),
            GpOptimizer::Lbfgs => lbfgs(&hx, &hy, &theta, settings.iterations.max(1)),
        };
        let Some((nll, theta)) = best else {
            return Err(ResidualError::Data(
                "the Gaussian process's kernel matrix is not positive definite at any tried hyper-parameters (duplicate rows with different targets?)".into(),
            ));
        };

        // Condition on (a subset of) every row.
        let rows = subset(n, settings.max_rows, &mut rng);
        let fx: Vec<Vec<f64>> = rows.iter().map(|&i| x[i].clone()).collect();
        let mut model = Self {
            signal_variance: theta[0].exp(),
            lengthscales: theta[1..=d].iter().map(|t| t.exp()).collect(),
            noise_variance: theta[d + 1].exp(),
            target_mean,
            target_std,
            alpha: Vec::new(),
            nll_per_row: nll / hx.len() as f64,
        };
        let llt = model.factor(&fx).ok_or_else(|| {
            ResidualError::Data(
                "the Gaussian process's kernel matrix is not positive definite".into(),
            )
        })?;
        let yv = Mat::from_fn(rows.len(), 1, |i, _| ys[rows[i]]);
        let alpha = llt.solve(&yv);
        model.alpha = (0..rows.len()).map(|i| alpha[(i, 0)]).collect();
        Ok((model, rows, llt))
    }

    fn inv_l2(&self) -> Vec<f64> {
        self.lengthscales.iter().map(|l| 1.0 / (l * l)).collect()
    }

    /// The Cholesky factor of the kernel matrix over the conditioning rows `x` (for variances).
    pub fn factor(&self, x: &[Vec<f64>]) -> Option<faer::linalg::solvers::Llt<f64>> {
        gram(x, &self.inv_l2(), self.signal_variance, self.noise_variance)
            .llt(Side::Lower)
            .ok()
    }

    /// Mean (mm) at the standardised feature row `row`, given the conditioning rows `x`; with
    /// the factor of [`Self::factor`], also the latent standard deviation (mm).
    pub fn predict_one(
        &self,
        x: &[Vec<f64>],
        row: &[f64],
        factor: Option<&faer::linalg::solvers::Llt<f64>>,
    ) -> (f64, Option<f64>) {
        let inv_l2 = self.inv_l2();
        let ks: Vec<f64> = x
            .iter()
            .map(|xi| kernel(xi, row, &inv_l2, self.signal_variance))
            .collect();
        let mean: f64 = ks.iter().zip(&self.alpha).map(|(k, a)| k * a).sum();
        let std = factor.map(|llt| self.stds(x, &[row.to_vec()], llt)[0]);
        (mean * self.target_std + self.target_mean, std)
    }

    /// Latent standard deviations (mm) at the standardised feature rows `rows`, given the
    /// conditioning rows `x` and the factor of [`Self::factor`]: `√(s² − |L⁻¹k*|²)` for every
    /// row at once (one triangular solve with a right-hand side per row: many rows together are
    /// several times faster than one at a time).
    pub fn stds(
        &self,
        x: &[Vec<f64>],
        rows: &[Vec<f64>],
        factor: &faer::linalg::solvers::Llt<f64>,
    ) -> Vec<f64> {
        let inv_l2 = self.inv_l2();
        let mut ks = Mat::from_fn(x.len(), rows.len(), |i, j| {
            kernel(&x[i], &rows[j], &inv_l2, self.signal_variance)
        });
        faer::linalg::triangular_solve::solve_lower_triangular_in_place(
            factor.L(),
            ks.as_mut(),
            faer::Par::Seq,
        );
        (0..rows.len())
            .map(|j| {
                let explained: f64 = ks.col(j).iter().map(|v| v * v).sum();
                (self.signal_variance - explained).max(0.0).sqrt() * self.target_std
            })
            .collect()
    }

    /// Checks a model read from a file against its feature count and row count.
    pub fn check(&self, features: usize, rows: usize) -> std::result::Result<(), String> {
        let positive = |v: f64| v.is_finite() && v > 0.0;
        if self.lengthscales.len() != features || self.alpha.len() != rows {
            return Err(format!(
                "{} length-scales and {} weights for {features} features and {rows} rows",
                self.lengthscales.len(),
                self.alpha.len()
            ));
        }
        if !positive(self.signal_variance)
            || !positive(self.noise_variance)
            || !positive(self.target_std)
            || !self.target_mean.is_finite()
            || !self.lengthscales.iter().all(|l| positive(*l))
            || !self.alpha.iter().all(|a| a.is_finite())
        {
            return Err(
                "variances, length-scales and the target scale must be positive, every value finite"
                    .into(),
            );
        }
        Ok(())
    }
}

/// The Gaussian-process residual: one [`GpAxis`] per world axis over standardised features,
/// conditioned on the same rows.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GpResidual {
    /// Feature scaling (of the encoded inputs).
    pub input_scale: Standardizer,
    /// The standardised feature rows the model conditions on.
    pub rows: Vec<Vec<f64>>,
    /// X, Y, Z.
    pub axes: Vec<GpAxis>,
    /// The factor every latent standard deviation is multiplied by: the one the default
    /// calibration's cross-validation found (the held-out errors' likelihood, see
    /// `robocal-pipeline`), 1 for a model fitted without folds (and in files that predate it).
    #[serde(default = "unit_scale")]
    pub std_scale: f64,
    /// Cholesky factors for the variances: kept from the fit (three times conditioning rows²
    /// values, 150 MB at 2500 rows), made on first use in a model read from its file.
    #[serde(skip)]
    factors: std::sync::OnceLock<Vec<Option<faer::linalg::solvers::Llt<f64>>>>,
}

impl GpResidual {
    /// Fits one GP per axis on `train_set` (encoded inputs), on one seeded subset of rows.
    pub fn fit(settings: &GpSettings, train_set: &Samples, seed: u64) -> Result<Self> {
        let input_scale = Standardizer::fit(&train_set.inputs);
        let x: Vec<Vec<f64>> = (train_set.inputs.iter())
            .map(|r| input_scale.apply(r))
            .collect();
        // The axes are independent: on every core at once. One seed for every axis: the same
        // conditioning rows.
        let fits: Vec<(GpAxis, Vec<usize>, faer::linalg::solvers::Llt<f64>)> = (0..3)
            .into_par_iter()
            .map(|a| {
                let y: Vec<f64> = train_set.errors.iter().map(|e| e[a]).collect();
                GpAxis::fit_rows(&x, &y, settings, seed)
            })
            .collect::<Result<_>>()?;
        let rows = fits.first().map(|f| f.1.clone()).unwrap_or_default();
        let (axes, factors): (Vec<GpAxis>, Vec<_>) =
            fits.into_iter().map(|f| (f.0, Some(f.2))).unzip();
        Ok(Self {
            input_scale,
            rows: rows.iter().map(|&i| x[i].clone()).collect(),
            axes,
            std_scale: 1.0,
            factors: factors.into(),
        })
    }

    /// Predicted error (mm) per encoded row, and with `std` the standard deviation of each
    /// axis's correction (mm): the latent one times [`Self::std_scale`].
    fn predict_rows(
        &self,
        encoded: &[Vec<f64>],
        std: bool,
    ) -> (Vec<[f64; 3]>, Option<Vec<[f64; 3]>>) {
        let x: Vec<Vec<f64>> = encoded.iter().map(|r| self.input_scale.apply(r)).collect();
        let mut mean = vec![[0.0; 3]; encoded.len()];
        for (i, row) in x.iter().enumerate() {
            for (a, gp) in self.axes.iter().enumerate() {
                mean[i][a] = gp.predict_one(&self.rows, row, None).0;
            }
        }
        let sd = std.then(|| {
            let factors = self
                .factors
                .get_or_init(|| self.axes.iter().map(|a| a.factor(&self.rows)).collect());
            let mut sd = vec![[f64::NAN; 3]; encoded.len()];
            for (a, gp) in self.axes.iter().enumerate() {
                let Some(f) = &factors[a] else { continue };
                // In chunks: the kernel block is conditioning rows × chunk rows.
                for (c, chunk) in x.chunks(STD_CHUNK).enumerate() {
                    for (i, s) in gp.stds(&self.rows, chunk, f).into_iter().enumerate() {
                        sd[c * STD_CHUNK + i][a] = s * self.std_scale;
                    }
                }
            }
            sd
        });
        (mean, sd)
    }

    /// Checks a model read from a file against the feature count.
    pub(crate) fn check(&self, features: usize) -> std::result::Result<(), String> {
        if !self.input_scale.fits(features) {
            return Err(format!("gp.input_scale: does not fit {features} features"));
        }
        if self.rows.len() < 2 || self.rows.len() > crate::gp::MAX_GP_ROWS {
            return Err(format!(
                "gp.rows: {} rows; a model conditions on 2 to {}",
                self.rows.len(),
                crate::gp::MAX_GP_ROWS
            ));
        }
        if (self.rows.iter()).any(|r| r.len() != features || r.iter().any(|v| !v.is_finite())) {
            return Err(format!(
                "gp.rows: every row must hold {features} finite values"
            ));
        }
        if self.axes.len() != 3 {
            return Err("gp.axes: one per world axis (3)".into());
        }
        for (a, gp) in self.axes.iter().enumerate() {
            gp.check(features, self.rows.len())
                .map_err(|m| format!("gp.axes[{a}]: {m}"))?;
        }
        if !(self.std_scale.is_finite() && self.std_scale > 0.0) {
            return Err(format!(
                "gp.std_scale: {} (must be positive and finite)",
                self.std_scale
            ));
        }
        Ok(())
    }
}

impl Residual for GpResidual {
    fn predict(
        &self,
        encoded: &[Vec<f64>],
        _raw: &Samples,
        std: bool,
    ) -> (Vec<[f64; 3]>, Option<Vec<[f64; 3]>>) {
        self.predict_rows(encoded, std)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The NLL's gradient against central differences.
    #[test]
    fn gradient_matches_central_differences() {
        let x: Vec<Vec<f64>> = (0..25)
            .map(|i| {
                let t = i as f64 * 0.37;
                vec![t.sin(), (1.3 * t).cos(), 0.1 * t]
            })
            .collect();
        let y: Vec<f64> = x.iter().map(|r| r[0] * r[1] + 0.3 * r[2]).collect();
        let theta = vec![0.2, -0.1, 0.3, 0.5, -2.0];
        let (_, g) = nll_and_gradient(&x, &y, &theta).unwrap();
        for k in 0..theta.len() {
            let h = 1e-5;
            let mut up = theta.clone();
            up[k] += h;
            let mut down = theta.clone();
            down[k] -= h;
            let fd = (nll_and_gradient(&x, &y, &up).unwrap().0
                - nll_and_gradient(&x, &y, &down).unwrap().0)
                / (2.0 * h);
            assert!(
                (fd - g[k]).abs() < 1e-5 * (1.0 + fd.abs()),
                "θ{k}: {fd} vs {}",
                g[k]
            );
        }
    }

    /// The gradient's sums, taken lane by lane over the features, and the kernel matrix's lower
    /// triangle alone give the NLL and gradient of the full symmetric matrix and one loop over
    /// the pairs, to the bit: 60 rows of 13 features (the periodic
    /// encoding's count for six joints and a load), a hyper-parameter per feature.
    #[test]
    fn the_gradient_is_the_one_loop_over_pairs_to_the_bit() {
        let (n, d) = (60, 13);
        let x: Vec<Vec<f64>> = (0..n)
            .map(|i| {
                (0..d)
                    .map(|c| (0.37 * i as f64 + 1.1 * c as f64).sin())
                    .collect()
            })
            .collect();
        let y: Vec<f64> = x.iter().map(|r| r[0] * r[3] + 0.3 * r[7] - r[12]).collect();
        let theta: Vec<f64> = (0..d + 2).map(|k| 0.1 * k as f64 - 0.6).collect();
        let (nll, grad) = nll_and_gradient(&x, &y, &theta).unwrap();

        let s2 = theta[0].exp();
        let inv_l2: Vec<f64> = theta[1..=d].iter().map(|t| (-2.0 * t).exp()).collect();
        let noise = theta[d + 1].exp();
        let mut k = Mat::<f64>::zeros(n, n);
        for i in 0..n {
            for j in 0..i {
                let v = kernel(&x[i], &x[j], &inv_l2, s2);
                k[(i, j)] = v;
                k[(j, i)] = v;
            }
            k[(i, i)] = s2 + noise + JITTER;
        }
        let llt = k.llt(Side::Lower).unwrap();
        let alpha = llt.solve(Mat::from_fn(n, 1, |i, _| y[i]));
        let l = llt.L();
        let log_det: f64 = (0..n).map(|i| l[(i, i)].ln()).sum::<f64>() * 2.0;
        let fit: f64 = (0..n).map(|i| y[i] * alpha[(i, 0)]).sum();
        let want = 0.5 * fit + 0.5 * log_det + 0.5 * n as f64 * (2.0 * std::f64::consts::PI).ln();
        let kinv = llt.inverse();
        let mut g = vec![0.0; d + 2];
        for i in 0..n {
            let w = kinv[(i, i)] - alpha[(i, 0)] * alpha[(i, 0)];
            g[0] += 0.5 * w * s2;
            g[d + 1] += 0.5 * w * noise;
            for j in 0..i {
                let wk = (kinv[(i, j)] - alpha[(i, 0)] * alpha[(j, 0)]) * k[(i, j)];
                g[0] += wk;
                for (c, gc) in g[1..=d].iter_mut().enumerate() {
                    let r = x[i][c] - x[j][c];
                    *gc += wk * r * r * inv_l2[c];
                }
            }
        }
        assert_eq!(nll.to_bits(), want.to_bits(), "{nll} {want}");
        for (a, b) in grad.iter().zip(&g) {
            assert_eq!(a.to_bits(), b.to_bits(), "{grad:?} {g:?}");
        }
    }

    /// With fixed hyper-parameters the mean and variance are the closed-form GP posterior,
    /// computed here independently for two training points.
    #[test]
    fn posterior_matches_the_two_point_closed_form() {
        let x = vec![vec![0.0], vec![1.0]];
        let (s2, l, noise) = (1.5, 0.8, 0.1);
        let model = GpAxis {
            signal_variance: s2,
            lengthscales: vec![l],
            noise_variance: noise,
            target_mean: 0.0,
            target_std: 1.0,
            alpha: Vec::new(),
            nll_per_row: 0.0,
        };
        let y = [0.7, -0.4];
        let k12 = s2 * (-0.5 / (l * l)).exp();
        let (a, b) = (s2 + noise + JITTER, k12);
        let det = a * a - b * b;
        let inv = [[a / det, -b / det], [-b / det, a / det]];
        let alpha = [
            inv[0][0] * y[0] + inv[0][1] * y[1],
            inv[1][0] * y[0] + inv[1][1] * y[1],
        ];
        let model = GpAxis {
            alpha: alpha.to_vec(),
            ..model
        };
        let star = 0.4;
        let ks = [
            s2 * (-0.5 * star * star / (l * l)).exp(),
            s2 * (-0.5 * (star - 1.0f64).powi(2) / (l * l)).exp(),
        ];
        let mean = ks[0] * alpha[0] + ks[1] * alpha[1];
        let quad = ks[0] * (inv[0][0] * ks[0] + inv[0][1] * ks[1])
            + ks[1] * (inv[1][0] * ks[0] + inv[1][1] * ks[1]);
        let llt = model.factor(&x).unwrap();
        let (m, s) = model.predict_one(&x, &[star], Some(&llt));
        assert!((m - mean).abs() < 1e-12, "{m} vs {mean}");
        assert!((s.unwrap() - (s2 - quad).sqrt()).abs() < 1e-12);
    }

    /// The deviations of many rows at once (one triangular solve, a column per row) equal those
    /// of [`GpAxis::predict_one`], row by row (the closed form above checks the formula).
    #[test]
    fn batched_deviations_match_one_row_at_a_time() {
        let x: Vec<Vec<f64>> = (0..60)
            .map(|i| {
                let t = i as f64 * 0.21;
                vec![t.sin(), (0.7 * t).cos()]
            })
            .collect();
        let y: Vec<f64> = x.iter().map(|r| r[0] - 0.5 * r[1] * r[1]).collect();
        let settings = GpSettings {
            iterations: 30,
            ..GpSettings::default()
        };
        let (gp, rows, factor) = GpAxis::fit_rows(&x, &y, &settings, 4).unwrap();
        let conditioning: Vec<Vec<f64>> = rows.iter().map(|&i| x[i].clone()).collect();
        let stars: Vec<Vec<f64>> = (0..25)
            .map(|i| vec![-1.5 + 0.12 * i as f64, 0.3 - 0.05 * i as f64])
            .collect();
        let batched = gp.stds(&conditioning, &stars, &factor);
        for (star, b) in stars.iter().zip(&batched) {
            let one = gp
                .predict_one(&conditioning, star, Some(&factor))
                .1
                .unwrap();
            assert!((one - b).abs() <= 1e-9 * (1.0 + one), "{one} vs {b}");
        }
        // Away from the data the deviation is larger than among it.
        assert!(batched[0] > 2.0 * batched[12], "{batched:?}");
    }

    /// Fitting recovers the noise level of data with known noise, and the fitted model's
    /// mean passes near the noise-free function.
    #[test]
    fn fit_finds_the_noise_level() {
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let x: Vec<Vec<f64>> = (0..150)
            .map(|i| vec![-2.0 + 4.0 * i as f64 / 149.0])
            .collect();
        let noise = 0.05;
        let y: Vec<f64> = x
            .iter()
            .map(|r| {
                let e: f64 = rand_distr::Distribution::sample(
                    &rand_distr::Normal::new(0.0, noise).unwrap(),
                    &mut rng,
                );
                r[0].sin() + e
            })
            .collect();
        for optimizer in [GpOptimizer::Adam, GpOptimizer::Lbfgs] {
            let settings = GpSettings {
                iterations: 150,
                optimizer,
                ..GpSettings::default()
            };
            let gp = GpAxis::fit(&x, &y, &settings, 1).unwrap();
            let sigma = gp.noise_variance.sqrt() * gp.target_std;
            assert!(
                (0.6 * noise..1.5 * noise).contains(&sigma),
                "{optimizer:?}: σ {sigma}"
            );
            let (m, _) = gp.predict_one(&x, &[0.5], None);
            assert!((m - 0.5f64.sin()).abs() < 0.03, "{optimizer:?}: {m}");
        }
    }

    /// Two features, the second irrelevant, 0.1 noise: standardised targets as the fit makes them.
    fn two_feature_data() -> (Vec<Vec<f64>>, Vec<f64>, Vec<f64>) {
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        let normal = rand_distr::Normal::new(0.0, 0.1).unwrap();
        let x: Vec<Vec<f64>> = (0..80)
            .map(|i| {
                let t = i as f64 * 0.61;
                vec![t.sin() * 1.7, (0.7 * t).cos()]
            })
            .collect();
        let y: Vec<f64> = x
            .iter()
            .map(|r| (1.3 * r[0]).sin() + rand_distr::Distribution::sample(&normal, &mut rng))
            .collect();
        let mean = y.iter().sum::<f64>() / y.len() as f64;
        let std = (y.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / y.len() as f64).sqrt();
        let ys = y.iter().map(|v| (v - mean) / std).collect();
        let mut theta0 = vec![0.0; 4];
        theta0[1..=2].fill(2f64.sqrt().ln());
        theta0[3] = 0.1f64.ln();
        (x, ys, theta0)
    }

    /// L-BFGS ends at a stationary point of the likelihood (its gradient, recomputed at the
    /// returned hyper-parameters, near zero in every one not held at a bound), no higher than
    /// Adam's best after the default 80 steps.
    #[test]
    fn lbfgs_ends_where_the_likelihood_is_stationary() {
        let (x, y, theta0) = two_feature_data();
        let (nll, theta) = lbfgs(&x, &y, &theta0, 200).unwrap();
        let (at, grad) = nll_and_gradient(&x, &y, &theta).unwrap();
        assert_eq!(at, nll);
        let (lo, hi) = bounds(2);
        for k in 0..4 {
            if theta[k] - lo[k] > 0.05 && hi[k] - theta[k] > 0.05 {
                assert!(grad[k].abs() < 1e-3, "θ {theta:?}: gradient {grad:?}");
            }
        }
        // The irrelevant feature's length-scale grows well past the relevant one's.
        assert!(theta[2] > theta[1] + 1.0, "{theta:?}");
        let (adam_nll, _) = adam(&x, &y, theta0, &GpSettings::default()).unwrap();
        assert!(nll <= adam_nll + 1e-9, "L-BFGS {nll}, Adam {adam_nll}");
    }

    /// L-BFGS spends no more likelihood evaluations than it is given: with one, it returns the
    /// start; with a few, a point no worse than the start; with more, a lower one still.
    #[test]
    fn lbfgs_spends_no_more_evaluations_than_it_is_given() {
        let (x, y, theta0) = two_feature_data();
        let (start, _) = nll_and_gradient(&x, &y, &theta0).unwrap();
        let (one, theta) = lbfgs(&x, &y, &theta0, 1).unwrap();
        // The start, up to the logistic map's round trip.
        assert!(
            (one - start).abs() < 1e-9 * start.abs(),
            "{one} against {start}"
        );
        for (a, b) in theta.iter().zip(&theta0) {
            assert!((a - b).abs() < 1e-9, "{theta:?} against {theta0:?}");
        }
        let (few, _) = lbfgs(&x, &y, &theta0, 4).unwrap();
        let (many, _) = lbfgs(&x, &y, &theta0, 200).unwrap();
        assert!(few < start && many < few, "{start} → {few} → {many}");
    }
}
