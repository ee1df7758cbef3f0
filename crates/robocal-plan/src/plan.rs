//! A plan: candidates, the D-optimal set for each asked count, and what it buys.

use std::path::Path;

use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use robocal_data::Observer;
use robocal_robot::Robot;
use serde::Serialize;

use crate::design::{Indices, Pool};
use crate::error::{PlanError, Result};
use crate::settings::PlanSettings;

/// Random sets drawn to compare a plan with.
pub const RANDOM_SETS: usize = 10;

/// One parameter's predicted standard deviation.
#[derive(Debug, Clone, Serialize)]
pub struct ParameterSigma {
    /// Name (`j2.a`).
    pub name: String,
    /// File unit.
    pub unit: &'static str,
    /// Standard deviation with the planned set.
    pub planned: f64,
    /// The median over the random sets.
    pub random: f64,
}

/// The plan for one count.
#[derive(Debug, Clone, Serialize)]
pub struct PlanReport {
    /// Configurations chosen.
    pub count: usize,
    /// Their indices among the candidates, in the order chosen.
    pub chosen: Vec<usize>,
    /// `log det` of the scaled information: greedy, after exchanges, and the random sets'
    /// median.
    pub log_det: [f64; 3],
    /// Exchanges that raised it.
    pub exchanges: usize,
    /// Indices of the planned set.
    pub planned: Indices,
    /// The median of each index over the random sets of the same size.
    pub random: Indices,
    /// Predicted position error at the check poses with the planned set: mean and max, mm.
    pub predicted: [f64; 2],
    /// The same for the random sets (medians of their means and maxima), mm.
    pub predicted_random: [f64; 2],
    /// Every parameter's predicted standard deviation.
    pub parameters: Vec<ParameterSigma>,
}

/// A whole plan.
#[derive(Debug, Clone, Serialize)]
pub struct PlanResult {
    /// Candidates (joint angles, deg).
    #[serde(skip)]
    pub candidates: Vec<Vec<f64>>,
    /// Where they came from.
    pub candidate_source: String,
    /// Candidates offered.
    pub candidate_count: usize,
    /// Check poses.
    pub check_count: usize,
    /// Loads, kg.
    pub loads: Vec<f64>,
    /// Tracker noise, mm.
    pub noise_mm: f64,
    /// Parameters identified.
    pub parameters: Vec<String>,
    /// Parameters the candidates cannot identify (held fixed).
    pub fixed: Vec<String>,
    /// One per asked count, ascending.
    pub plans: Vec<PlanReport>,
}

/// Random configurations within `robot`'s joint limits whose measured point lies in the
/// workspace box and whose point Jacobian is conditioned at least as `settings` ask: `count` of
/// them (rad), drawn from stream `stream` of the seed. Joints without limits are an error
/// naming `robot_file`.
pub fn candidates_from_limits(
    robot: &Robot,
    robot_file: &Path,
    settings: &PlanSettings,
    count: usize,
    stream: u64,
    observer: &dyn Observer,
) -> Result<Vec<Vec<f64>>> {
    let mut limits = Vec::new();
    for (i, j) in robot.joints.iter().enumerate() {
        match j.limits {
            Some(l) => limits.push(l),
            None => {
                return Err(PlanError::invalid(
                    robot_file,
                    &format!("joint[{i}].limits"),
                    format!(
                        "joint {} has no limits: a plan draws candidates within them (or give --candidates)",
                        i + 1
                    ),
                ));
            }
        }
    }
    let mut rng = ChaCha8Rng::seed_from_u64(settings.seed ^ stream);
    let base_r = robot.base_rotation();
    let mut out = Vec::with_capacity(count);
    let tries = 200 * count.max(1);
    observer.start("candidates", count as u64);
    for _ in 0..tries {
        if out.len() == count {
            break;
        }
        let q: Vec<f64> = limits
            .iter()
            .map(|&(lo, hi)| rng.random_range(lo..=hi))
            .collect();
        if let Some((lo, hi)) = settings.workspace {
            let p = base_r.transpose() * (robot.point(&q) - robot.base.xyz);
            if (0..3).any(|a| p[a] < lo[a] || p[a] > hi[a]) {
                continue;
            }
        }
        let sv = robot.joint_jacobian(&q).svd(false, false).singular_values;
        let (max, min) = sv
            .iter()
            .fold((0.0f64, f64::INFINITY), |(a, b), &s| (a.max(s), b.min(s)));
        if max <= 0.0 || min / max < settings.min_conditioning {
            continue;
        }
        out.push(q);
        observer.advance(1);
    }
    observer.finish();
    if out.len() < count {
        let key = if settings.workspace.is_some() {
            "workspace.min"
        } else {
            "min_conditioning"
        };
        return Err(PlanError::invalid(
            &settings.source,
            key,
            format!(
                "only {} of {count} candidates found in {tries} draws within the joint limits: the workspace box (or the conditioning bound) leaves too little of the robot's reach",
                out.len()
            ),
        ));
    }
    Ok(out)
}

/// Plans `counts` configurations each (ascending) from `candidates` (rad), reporting on
/// `checks` (rad).
pub fn plan(
    robot: &Robot,
    candidates: Vec<Vec<f64>>,
    candidate_source: String,
    checks: &[Vec<f64>],
    counts: &[usize],
    settings: &PlanSettings,
    observer: &dyn Observer,
) -> Result<PlanResult> {
    let pool = Pool::new(robot, &candidates, checks, settings)?;
    let k = pool.parameters();
    let mut counts = counts.to_vec();
    counts.sort_unstable();
    counts.dedup();
    for &c in &counts {
        if 3 * c * settings.loads.len() < k || 3 * c < k {
            return Err(PlanError::invalid(
                "--count",
                "--count",
                format!(
                    "{c} configurations cannot identify the {k} parameters (at least {} needed: three coordinates each)",
                    k.div_ceil(3)
                ),
            ));
        }
        if c > candidates.len() {
            return Err(PlanError::invalid(
                "--count",
                "--count",
                format!(
                    "{c} configurations asked, only {} candidates",
                    candidates.len()
                ),
            ));
        }
    }
    let mut rng = ChaCha8Rng::seed_from_u64(settings.seed ^ 0x7261_6e64);
    let mut plans = Vec::new();
    observer.start("plans", counts.len() as u64);
    for &count in &counts {
        let design = pool.select(count, settings.criterion);
        let random: Vec<Vec<usize>> = (0..RANDOM_SETS)
            .map(|_| sample(&mut rng, candidates.len(), count))
            .collect();
        let planned_sigmas = pool.parameter_sigmas(&design.chosen, settings.noise_mm);
        let random_sigmas: Vec<Vec<f64>> = random
            .iter()
            .map(|s| pool.parameter_sigmas(s, settings.noise_mm))
            .collect();
        let mean_max = |v: Vec<f64>| {
            let mean = v.iter().sum::<f64>() / v.len().max(1) as f64;
            [mean, v.iter().copied().fold(0.0, f64::max)]
        };
        let random_errors: Vec<[f64; 2]> = random
            .iter()
            .map(|s| mean_max(pool.predicted_errors(s, settings.noise_mm)))
            .collect();
        let random_indices: Vec<Indices> = random.iter().map(|s| pool.indices(s)).collect();
        plans.push(PlanReport {
            count,
            log_det: [
                design.greedy_log_det,
                design.log_det,
                median(
                    random
                        .iter()
                        .map(|s| crate::log_det(&pool.information(s)))
                        .collect(),
                ),
            ],
            exchanges: design.exchanges.len(),
            planned: pool.indices(&design.chosen),
            random: Indices {
                o1: median(random_indices.iter().map(|i| i.o1).collect()),
                o3: median(random_indices.iter().map(|i| i.o3).collect()),
                o4: median(random_indices.iter().map(|i| i.o4).collect()),
                condition_number: median(
                    random_indices.iter().map(|i| i.condition_number).collect(),
                ),
            },
            predicted: mean_max(pool.predicted_errors(&design.chosen, settings.noise_mm)),
            predicted_random: [
                median(random_errors.iter().map(|e| e[0]).collect()),
                median(random_errors.iter().map(|e| e[1]).collect()),
            ],
            parameters: (0..k)
                .map(|j| ParameterSigma {
                    name: pool.names[j].clone(),
                    unit: pool.units[j].0,
                    planned: planned_sigmas[j],
                    random: median(random_sigmas.iter().map(|s| s[j]).collect()),
                })
                .collect(),
            chosen: design.chosen,
        });
        observer.advance(1);
    }
    observer.finish();
    Ok(PlanResult {
        candidates: candidates
            .iter()
            .map(|q| q.iter().map(|v| v.to_degrees()).collect())
            .collect(),
        candidate_source,
        candidate_count: candidates.len(),
        check_count: checks.len(),
        loads: settings.loads.clone(),
        noise_mm: settings.noise_mm,
        parameters: pool.names.clone(),
        fixed: pool.fixed.clone(),
        plans,
    })
}

/// `count` distinct indices below `n`, drawn by `rng`.
fn sample(rng: &mut ChaCha8Rng, n: usize, count: usize) -> Vec<usize> {
    let mut all: Vec<usize> = (0..n).collect();
    for i in 0..count.min(n) {
        let j = rng.random_range(i..n);
        all.swap(i, j);
    }
    all.truncate(count.min(n));
    all
}

/// The median (the mean of the middle two for an even count); NaN for none.
fn median(mut v: Vec<f64>) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}
