//! Levenberg–Marquardt as an argmin [`Solver`]: damped Gauss–Newton steps on the normal
//! equations `(JᵀJ + λ diag(JᵀJ)) δ = −Jᵀr`, solved by Cholesky (faer).

use argmin::core::{
    Error, IterState, Jacobian, KV, Operator, Problem, Solver, State, TerminationReason,
    TerminationStatus,
};
use faer::linalg::matmul::triangular::{self, BlockStructure};
use faer::linalg::solvers::Solve;
use faer::{Accum, Mat, Par, Side};
use std::time::Instant;

/// The relative decrease of the cost below which [`STALLED_STEPS`] accepted steps in a row end
/// the solve. With `N` residuals of a fit that leaves noise, the cost sits `δ² / N` of itself
/// above its minimum when the parameters lie `δ` standard deviations from it: a step that gains
/// 1e-6 of the cost moves them by a few hundredths to a tenth of a standard deviation (`N` from
/// hundreds to ten thousand), and the points by far less than the tracker's noise. Tighter buys
/// nothing but iterations: where the model is not smooth — a backlash flank that flips with the
/// parameters, compliances whose torques the Jacobian takes at the current geometry — LM crawls
/// on with its damping growing, two thirds of a full physical model's iterations on the paper's
/// arm (2646 rows) gaining 1e-4 of the cost together. A noise-free fit is not stopped by it: its
/// cost keeps falling by large fractions down to round-off.
pub const COST_TOLERANCE: f64 = 1e-6;

/// Accepted steps in a row, each gaining less than [`COST_TOLERANCE`], that end the solve: one
/// alone can be a slow step in a narrow valley that the next one leaves. (A third, one iteration
/// of every solve, 6 % of a default calibration's on ARM7, gains under 1e-9 of the cost on two
/// thirds of the solves traced there.)
pub const STALLED_STEPS: usize = 2;

/// The damping's divisor after an accepted step (Marquardt's own 10; it is multiplied by 4
/// after a rejected one). The identifications here are nearly linear least squares started
/// at zero: with 3 the first steps come out damped long after the model has proven linear (a fit
/// of the full physical model takes 12–14 iterations, 8 of them climbing down from 1e-3 to 1e-7);
/// with 10 it gets there in 4.
pub const LAMBDA_DOWN: f64 = 10.0;

/// Settings and running state of the solver.
#[derive(Debug, Clone)]
pub struct LevenbergMarquardt {
    /// Current damping.
    lambda: f64,
    /// Stop when [`STALLED_STEPS`] steps in a row lower the cost by less than this fraction
    /// each ([`COST_TOLERANCE`]).
    cost_tolerance: f64,
    /// Accepted steps in a row that lowered the cost by less than `cost_tolerance`.
    stalled: usize,
    /// Stop when the step is shorter than this (scaled units).
    step_tolerance: f64,
    /// Stop when the largest gradient entry is below this.
    gradient_tolerance: f64,
    /// Damping increases tried within one iteration before giving up.
    max_rejections: usize,
    converged: Option<&'static str>,
}

impl Default for LevenbergMarquardt {
    fn default() -> Self {
        Self {
            lambda: 1e-3,
            cost_tolerance: COST_TOLERANCE,
            stalled: 0,
            step_tolerance: 1e-12,
            gradient_tolerance: 1e-14,
            max_rejections: 30,
            converged: None,
        }
    }
}

impl LevenbergMarquardt {
    /// Why the solver stopped, when it converged.
    pub fn converged(&self) -> Option<&'static str> {
        self.converged
    }
}

/// `JᵀJ`'s lower triangle (the upper one zero): all the Cholesky factorisation of the damped
/// normal equations reads ([`Side::Lower`]), at half the full product's cost. Each entry is the
/// full product's to the bit: faer hands both to the same kernels (the same blocks of the
/// depth, the same sums), the triangular one storing only the entries on or below the diagonal
/// (tested) — except where the full product takes kernels of its own, for one column or a
/// product of at most [`SMALL_PRODUCT`] multiplications (faer's dot products and small
/// kernels, whose sums come out otherwise): there it is the full product's lower triangle.
fn gram_lower(jac: &Mat<f64>) -> Mat<f64> {
    let (rows, k) = jac.shape();
    if k < 2 || k * k * rows <= SMALL_PRODUCT {
        let mut a: Mat<f64> = jac.transpose() * jac;
        for j in 1..k {
            for i in 0..j {
                a[(i, j)] = 0.0;
            }
        }
        return a;
    }
    let mut a = Mat::zeros(k, k);
    triangular::matmul(
        &mut a,
        BlockStructure::TriangularLower,
        Accum::Replace,
        jac.transpose(),
        BlockStructure::Rectangular,
        jac,
        BlockStructure::Rectangular,
        1.0,
        Par::Seq,
    );
    a
}

/// The largest product (rows times columns times depth) faer multiplies with its small kernels
/// rather than its general one (its `NANO_GEMM_THRESHOLD`, 16³).
const SMALL_PRODUCT: usize = 16 * 16 * 16;

type LmState = IterState<Vec<f64>, (), Mat<f64>, (), Vec<f64>, f64>;

fn half_squared(r: &[f64]) -> f64 {
    0.5 * r.iter().map(|v| v * v).sum::<f64>()
}

impl<O> Solver<O, LmState> for LevenbergMarquardt
where
    O: Operator<Param = Vec<f64>, Output = Vec<f64>>
        + Jacobian<Param = Vec<f64>, Jacobian = Mat<f64>>,
{
    fn name(&self) -> &str {
        "Levenberg-Marquardt"
    }

    fn init(
        &mut self,
        problem: &mut Problem<O>,
        mut state: LmState,
    ) -> Result<(LmState, Option<KV>), Error> {
        let u = state
            .take_param()
            .ok_or_else(|| argmin::core::ArgminError::NotInitialized {
                text: "Levenberg-Marquardt needs a starting point".into(),
            })?;
        let r = problem.apply(&u)?;
        let cost = half_squared(&r);
        Ok((state.param(u).residuals(r).cost(cost), None))
    }

    fn next_iter(
        &mut self,
        problem: &mut Problem<O>,
        mut state: LmState,
    ) -> Result<(LmState, Option<KV>), Error> {
        let u = state.take_param().unwrap_or_default();
        let r = match state.take_residuals() {
            Some(r) => r,
            None => problem.apply(&u)?,
        };
        let cost = half_squared(&r);
        let jac = problem.jacobian(&u)?;
        let k = u.len();
        let jt = jac.transpose();
        let a = gram_lower(&jac);
        let rv = Mat::from_fn(r.len(), 1, |i, _| r[i]);
        let g: Mat<f64> = jt * &rv;
        let gmax = (0..k).map(|i| g[(i, 0)].abs()).fold(0.0, f64::max);
        if gmax <= self.gradient_tolerance {
            self.converged = Some("gradient below tolerance");
            return Ok((state.param(u).residuals(r).cost(cost), None));
        }
        for _ in 0..self.max_rejections {
            let mut damped = a.clone();
            for i in 0..k {
                damped[(i, i)] += self.lambda * a[(i, i)].max(1e-12);
            }
            let Ok(llt) = damped.llt(Side::Lower) else {
                self.lambda *= 10.0;
                continue;
            };
            let delta = llt.solve(&g);
            let trial: Vec<f64> = (0..k).map(|i| u[i] - delta[(i, 0)]).collect();
            let r_trial = problem.apply(&trial)?;
            let c_trial = half_squared(&r_trial);
            if c_trial.is_finite() && c_trial < cost {
                let step = (0..k).map(|i| delta[(i, 0)].powi(2)).sum::<f64>().sqrt();
                let unorm = trial.iter().map(|v| v * v).sum::<f64>().sqrt();
                if (cost - c_trial) <= self.cost_tolerance * cost {
                    self.stalled += 1;
                } else {
                    self.stalled = 0;
                }
                if self.stalled >= STALLED_STEPS {
                    self.converged = Some("relative cost decrease below tolerance");
                } else if step <= self.step_tolerance * (1.0 + unorm) {
                    self.converged = Some("step below tolerance");
                }
                self.lambda = (self.lambda / LAMBDA_DOWN).max(1e-15);
                let kv = argmin::kv!("lambda" => self.lambda; "step" => step;);
                return Ok((
                    state.param(trial).residuals(r_trial).cost(c_trial),
                    Some(kv),
                ));
            }
            self.lambda *= 4.0;
        }
        self.converged = Some("no further decrease possible");
        Ok((state.param(u).residuals(r).cost(cost), None))
    }

    fn terminate(&mut self, _state: &LmState) -> TerminationStatus {
        match self.converged {
            Some(_) => TerminationStatus::Terminated(TerminationReason::SolverConverged),
            None => TerminationStatus::NotTerminated,
        }
    }
}

/// Runs LM from `u0` and returns (solution, iterations, termination text).
pub fn run_lm<O>(op: O, u0: Vec<f64>, max_iters: u64) -> crate::Result<(Vec<f64>, u64, String)>
where
    O: Operator<Param = Vec<f64>, Output = Vec<f64>>
        + Jacobian<Param = Vec<f64>, Jacobian = Mat<f64>>,
{
    run_lm_until(op, u0, max_iters, None, None)
}

/// [`run_lm`] that stops with [`crate::IdentError::Deadline`] once `deadline` has passed (checked
/// at every evaluation of the residuals), or once `work` has counted past its limit (counted at
/// every evaluation: [`Work`]).
pub fn run_lm_until<O>(
    op: O,
    u0: Vec<f64>,
    max_iters: u64,
    deadline: Option<Instant>,
    work: Option<&Work>,
) -> crate::Result<(Vec<f64>, u64, String)>
where
    O: Operator<Param = Vec<f64>, Output = Vec<f64>>
        + Jacobian<Param = Vec<f64>, Jacobian = Mat<f64>>,
{
    let solver = LevenbergMarquardt::default();
    let op = UntilDeadline { op, deadline, work };
    let result = argmin::core::Executor::new(op, solver)
        .configure(|s| s.param(u0).max_iters(max_iters))
        .run()
        .map_err(|e| match e.downcast::<crate::IdentError>() {
            Ok(deadline) => deadline,
            Err(e) => crate::IdentError::Solver {
                solver: "lm",
                message: e.to_string(),
            },
        })?;
    let reason = match result.solver.converged() {
        Some(why) => format!("converged: {why}"),
        None => result
            .state
            .get_termination_reason()
            .map_or("stopped".to_string(), |r| r.text().to_string()),
    };
    let iters = result.state.get_iter();
    let u = result.state.get_best_param().cloned().unwrap_or_default();
    Ok((u, iters, reason))
}

/// The work of identifications, counted so that it is the same on every machine and any number
/// of cores: each evaluation of the residuals adds their count, each evaluation of the Jacobian
/// their count times (the unknowns + 1) — the entries it computes, what an evaluation's time
/// grows with. Shared by its clones (one count for every solve of a fit); with a limit, a solve
/// whose evaluation takes the count past it stops with [`crate::IdentError::Deadline`], at the
/// same evaluation wherever it runs.
#[derive(Debug, Clone, Default)]
pub struct Work {
    count: std::sync::Arc<std::sync::atomic::AtomicU64>,
    limit: Option<u64>,
}

impl Work {
    /// A count from zero that stops a solve past `limit` (`None`: never).
    pub fn new(limit: Option<u64>) -> Self {
        Self {
            count: Default::default(),
            limit,
        }
    }

    /// What has been counted.
    pub fn count(&self) -> u64 {
        self.count.load(std::sync::atomic::Ordering::SeqCst)
    }

    /// Counts `units`; an error once the count is past the limit.
    fn add(&self, units: usize) -> Result<(), Error> {
        let units = units as u64;
        let total = (self.count).fetch_add(units, std::sync::atomic::Ordering::SeqCst) + units;
        match self.limit {
            Some(limit) if total > limit => Err(crate::IdentError::Deadline.into()),
            _ => Ok(()),
        }
    }
}

/// Counts alike are the same work: settings holding two counts with the same limit and count
/// compare equal (a count is not a setting of the fit).
impl PartialEq for Work {
    fn eq(&self, other: &Self) -> bool {
        self.limit == other.limit && self.count() == other.count()
    }
}

/// An operator whose residuals fail with [`crate::IdentError::Deadline`] once `deadline` has
/// passed or `work` has counted past its limit.
struct UntilDeadline<'a, O> {
    op: O,
    deadline: Option<Instant>,
    work: Option<&'a Work>,
}

impl<O: Operator<Param = Vec<f64>, Output = Vec<f64>>> Operator for UntilDeadline<'_, O> {
    type Param = Vec<f64>;
    type Output = Vec<f64>;
    fn apply(&self, u: &Vec<f64>) -> Result<Vec<f64>, Error> {
        if self.deadline.is_some_and(|d| Instant::now() >= d) {
            return Err(crate::IdentError::Deadline.into());
        }
        let r = self.op.apply(u)?;
        if let Some(work) = self.work {
            work.add(r.len())?;
        }
        Ok(r)
    }
}

impl<O: Jacobian<Param = Vec<f64>, Jacobian = Mat<f64>>> Jacobian for UntilDeadline<'_, O> {
    type Param = Vec<f64>;
    type Jacobian = Mat<f64>;
    fn jacobian(&self, u: &Vec<f64>) -> Result<Mat<f64>, Error> {
        let j = self.op.jacobian(u)?;
        if let Some(work) = self.work {
            work.add(j.nrows() * (j.ncols() + 1))?;
        }
        Ok(j)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{DMatrix, DVector};
    use rand::SeedableRng;
    use rand_distr::{Distribution, Normal};

    /// `y = a exp(−b x) + c exp(−d x)` at fixed abscissae: residuals `model − y`. Two decays
    /// are a classic ill-conditioned fit: a narrow curved valley in which LM's steps shrink.
    struct Curve {
        x: Vec<f64>,
        y: Vec<f64>,
    }

    /// The model's value at `x` and its derivatives by `a, b, c, d`.
    fn model(u: &[f64], x: f64) -> (f64, [f64; 4]) {
        let (a, b, c, d) = (u[0], u[1], u[2], u[3]);
        let (e, f) = ((-b * x).exp(), (-d * x).exp());
        (a * e + c * f, [e, -a * x * e, f, -c * x * f])
    }

    impl Operator for Curve {
        type Param = Vec<f64>;
        type Output = Vec<f64>;
        fn apply(&self, u: &Vec<f64>) -> Result<Vec<f64>, Error> {
            Ok((self.x.iter().zip(&self.y))
                .map(|(&x, &y)| model(u, x).0 - y)
                .collect())
        }
    }

    impl Jacobian for Curve {
        type Param = Vec<f64>;
        type Jacobian = Mat<f64>;
        fn jacobian(&self, u: &Vec<f64>) -> Result<Mat<f64>, Error> {
            Ok(Mat::from_fn(self.x.len(), 4, |i, j| {
                model(u, self.x[i]).1[j]
            }))
        }
    }

    /// The Gram matrix's lower triangle is the full product's to the bit (the normal equations
    /// LM solved before it are the ones it solves), its upper triangle zero: on tall matrices
    /// of normal entries the shapes of fits (thousands of rows, tens to over a hundred
    /// columns: the depth in several of the kernels' blocks, columns that split their tiles
    /// unevenly), and on every shape of up to 12 columns around the full product's switches of
    /// kernel (one column; 16³ multiplications), where the triangular product alone differed
    /// in the last bits (on a rigid fit's small solves: the five-axis twin's default
    /// calibration, before the switch).
    #[test]
    fn the_gram_triangle_is_the_full_products_to_the_bit() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let normal = Normal::new(0.0, 1.0).unwrap();
        let fits = [(7932, 115), (2614, 37), (1500, 61), (40, 13)];
        let small = [1, 5, 30, 200, 511, 512, 513, 1000, 2000, 4096, 4097]
            .into_iter()
            .flat_map(|rows| (1..=12).map(move |cols| (rows, cols)));
        for (rows, cols) in fits.into_iter().chain(small) {
            let jac = Mat::from_fn(rows, cols, |_, _| normal.sample(&mut rng));
            let full: Mat<f64> = jac.transpose() * &jac;
            let lower = gram_lower(&jac);
            for j in 0..cols {
                for i in 0..cols {
                    let want = if i >= j { full[(i, j)] } else { 0.0 };
                    assert_eq!(
                        lower[(i, j)].to_bits(),
                        want.to_bits(),
                        "{rows} x {cols}: entry ({i}, {j})"
                    );
                }
            }
        }
    }

    const TRUTH: [f64; 4] = [1.0, 0.5, 1.0, 2.0];
    const START: [f64; 4] = [1.5, 0.2, 0.5, 3.0];

    /// 200 points on `[0, 5]`, seeded normal noise of standard deviation `noise`.
    fn curve(noise: f64) -> Curve {
        let x: Vec<f64> = (0..200).map(|i| 4.0 * i as f64 / 199.0).collect();
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        let normal = Normal::new(0.0, 1.0).unwrap();
        let y = (x.iter())
            .map(|&x| model(&TRUTH, x).0 + noise * normal.sample(&mut rng))
            .collect();
        Curve { x, y }
    }

    /// The least-squares minimum by plain Gauss–Newton from the truth (nalgebra's normal
    /// equations, independent of the solver), and each parameter's standard deviation there.
    fn gauss_newton(c: &Curve) -> (Vec<f64>, Vec<f64>) {
        let mut u = TRUTH.to_vec();
        let (n, k) = (c.x.len(), 4);
        let mut jtj = DMatrix::zeros(k, k);
        let mut rss = 0.0;
        for _ in 0..100 {
            let r = DVector::from_vec(c.apply(&u).unwrap());
            let j = DMatrix::from_fn(n, k, |i, p| model(&u, c.x[i]).1[p]);
            jtj = j.transpose() * &j;
            let step = jtj.clone().cholesky().unwrap().solve(&(j.transpose() * &r));
            u = (0..k).map(|p| u[p] - step[p]).collect();
            rss = r.norm_squared();
        }
        let cov = jtj.try_inverse().unwrap() * (rss / (n - k) as f64);
        (u, (0..k).map(|p| cov[(p, p)].sqrt()).collect())
    }

    /// The stopping rule ([`COST_TOLERANCE`] over [`STALLED_STEPS`] steps) ends a noisy fit at
    /// the least-squares minimum (within 0.05 σ of it), from a start far from it. On a smooth
    /// problem like this LM gains large fractions of the cost until it is there, so the rule's
    /// threshold is not what this pins (the fit is the same with 0.5); a rule that ends the solve
    /// at the first accepted step fails it (38 σ away).
    #[test]
    fn lm_stops_within_a_fraction_of_a_standard_deviation_of_the_minimum() {
        let c = curve(0.001);
        let (reference, sigma) = gauss_newton(&c);
        let (u, iterations, why) = run_lm(c, START.to_vec(), 500).unwrap();
        assert!(why.contains("converged"), "{why} after {iterations}");
        for p in 0..4 {
            let off = (u[p] - reference[p]).abs() / sigma[p];
            assert!(
                off < 0.05,
                "parameter {p}: {off} σ from the minimum ({why})"
            );
        }
    }

    /// A deadline already passed stops the solve at its first evaluation, with the deadline's
    /// own error (the default calibration abandons the candidate on it); one far ahead changes
    /// nothing, to the bit.
    #[test]
    fn a_solve_past_its_deadline_stops_with_the_deadline_error() {
        let past = Instant::now();
        let stopped = run_lm_until(curve(0.001), START.to_vec(), 500, Some(past), None);
        assert!(
            matches!(stopped, Err(crate::IdentError::Deadline)),
            "{stopped:?}"
        );
        let ahead = Instant::now() + std::time::Duration::from_secs(3600);
        let (u, iterations, _) =
            run_lm_until(curve(0.001), START.to_vec(), 500, Some(ahead), None).unwrap();
        let (free, free_iterations, _) = run_lm(curve(0.001), START.to_vec(), 500).unwrap();
        assert_eq!((u, iterations), (free, free_iterations));
    }

    /// A noise-free fit is not stopped by the rule: its cost falls by large fractions down to
    /// round-off, and the parameters come out exact.
    #[test]
    fn lm_runs_a_noise_free_fit_down_to_round_off() {
        let (u, _, why) = run_lm(curve(0.0), START.to_vec(), 500).unwrap();
        for p in 0..4 {
            assert!(
                (u[p] - TRUTH[p]).abs() < 1e-9,
                "parameter {p}: {} ({why})",
                u[p]
            );
        }
    }
}
