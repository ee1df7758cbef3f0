//! Bad shots: rows whose error under the identified model is far beyond the data's own spread
//! (a reflector mis-seated, the beam broken, a row typed wrong). They are found after a fit, the
//! model is fitted again without them until the set no longer changes, and the calibration
//! leaves them out (or keeps them, named, when asked).

use std::collections::BTreeSet;

use nalgebra::Vector3;
use robocal_data::{Measurement, robust_std};
use robocal_ident::{
    ComplianceSettings, FitMemo, JointErrorSettings, KinematicCalibration, KinematicSettings, Loss,
    SolverKind,
};
use robocal_robot::Robot;
use serde::Serialize;

use crate::error::Result;
use crate::fit::{fit_kinematic, fit_kinematic_with, physical_model};
use crate::folds::configuration_groups;
use crate::rows::{coordinates_and_parameters, loads, readings_key};

/// How bad shots are found.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OutlierSettings {
    /// A row is an outlier when its error exceeds this many robust standard deviations of the
    /// error components (1.4826 × their median absolute deviation).
    pub threshold: f64,
    /// Most fits (each without the rows the one before flagged).
    pub rounds: usize,
    /// Keep the flagged rows in the fit (they are still named).
    pub keep: bool,
}

/// The default threshold, in robust standard deviations: no clean row of robocal's twins came
/// near it (their largest about 7 of them: 7.1 under `accuracy --outliers`, 7.0 on the
/// development families' 36 cases), while a 2 mm bad shot on a 0.1 mm calibration
/// is 20 of them and more (not on the paper's arm, whose compliance fit leaves 0.16–0.24 mm:
/// there the refined search, [`REFINED_SHARE`]).
pub const OUTLIER_THRESHOLD: f64 = 12.0;

/// Share of the threshold beyond which the search's physics must leave a row for the refined
/// search to flag it ([`find_outliers`]). Where the search's physics leaves a large robust
/// spread of its own (the paper's arm: gear errors and a backlash that flips with the payload,
/// 0.16–0.24 mm), a 2 mm shot lies 7–12 of it out and the threshold misses most; under the
/// physics with the transmission harmonics the same shots lie 13–21 robust standard deviations
/// out, and no clean row of the development families beyond 10.8 — but a richer physics has
/// failures of its own that leave a clean row far out (a backlash flank taken wrongly, or one
/// it does not hold: [`SINGLE_JOINT_SHARE`]), so a row must be far out under both. Measured:
/// no clean row of the 144 cases of the accuracy suite (every family, seeds 0 and 1, all three
/// effect sets, both splits) flagged; of shots of 2 mm in random directions on the paper's arm
/// (four cases, 48 shots) 43 found, 9 by the threshold alone; of 1.5 mm, 22, none by the
/// threshold alone (`accuracy --outliers`).
pub const REFINED_SHARE: f64 = 0.5;

/// Share of a row's error under the refined physics (its square) that one joint's motion may
/// explain before the refined search no longer flags it where it may lie past a flank's flip
/// (`past_a_flip`): an error along a single joint's motion at a configuration's lightest or
/// heaviest loads may be that joint's play, on the flank its torque presses, which the refined
/// physics does not hold (ARM6H: 14 clean rows of 12 cases at the lightest loads, 0.96–1.00 of
/// their errors along joint 2's motion); a reflector mis-seated moves the point in
/// any direction, at any load.
pub const SINGLE_JOINT_SHARE: f64 = 0.95;

impl Default for OutlierSettings {
    fn default() -> Self {
        Self {
            threshold: OUTLIER_THRESHOLD,
            rounds: 4,
            keep: false,
        }
    }
}

/// Fewer coordinates than this many times the identified parameters (three per configuration
/// and reflector: the loads add nothing to the geometry) and a fit of every row bends to each
/// of them, so that its errors are no measure of the model's: with 8 configurations of the
/// paper's arm at six loads the clean rows of four lay 37–55 robust standard deviations out
/// (the joint-4 backlash that flips with the payload, which such a fit absorbs elsewhere),
/// while a fit without a configuration may miss it by tens of millimetres, so that neither
/// alone tells a bad shot. Below it a row is a bad shot only when both leave it beyond the
/// threshold: the fit of every row, and the fit without its configuration.
pub const HELD_OUT_REDUNDANCY: f64 = 2.0;

/// A row found to be a bad shot.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Outlier {
    /// Configuration id.
    pub pose: String,
    /// Load, kg.
    pub load: f64,
    /// Line in its file (1-based; 0 when made in memory).
    pub line: u64,
    /// Its error under the model fitted without the outliers, mm.
    pub error: f64,
    /// That error in robust standard deviations.
    pub sigmas: f64,
    /// With the refined search ([`OutlierReport::refined_std`]): its error under the refined
    /// physics fitted without the outliers, in that fit's robust standard deviations.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub refined_sigmas: Option<f64>,
}

/// What the search found.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct OutlierReport {
    /// Robust standard deviation of the error components of the inliers, mm.
    pub robust_std: f64,
    /// The threshold, in robust standard deviations.
    pub threshold: f64,
    /// Whether the outliers were left out of the fit.
    pub left_out: bool,
    /// With too few configurations for the parameters ([`HELD_OUT_REDUNDANCY`]): the robust
    /// standard deviation of the rows' errors under fits without their configurations, mm; a
    /// row flagged was beyond the threshold in both.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub held_out_std: Option<f64>,
    /// When some row lay beyond [`REFINED_SHARE`] of the threshold under the search's physics
    /// (and the data hold enough configurations): the robust standard deviation, mm, of the
    /// error components under the refined physics (the search's with the transmission
    /// harmonics), fitted without the outliers; a row beyond the threshold of it and that share
    /// of the search's threshold is flagged too (unless its error lies along one joint's motion
    /// where that joint's flank may have flipped: [`SINGLE_JOINT_SHARE`]).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub refined_std: Option<f64>,
    /// The rows flagged, in file order.
    pub rows: Vec<Outlier>,
    /// With too few configurations: the rows the fit of every row leaves beyond the threshold
    /// but a fit without their configuration does not (kept, and named for checking), in file
    /// order.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub suspects: Vec<Outlier>,
}

/// The physics the search fits: `settings`, with joint compliances when the data hold two or
/// more loads and `settings` have none (a rigid table cannot tell a heavy load's deflection
/// from a bad shot). Least squares by Levenberg–Marquardt, on purpose, whatever loss and solver
/// `settings` ask for: the threshold is in robust standard deviations of a least-squares fit's
/// errors (a Huber fit, or BFGS on the mean distance, hugs the bulk closer, and the same rows
/// then sit further out: the error components' robust spread 2–12 % smaller under the BFGS stage
/// on eight development cases); the refits without the flagged rows keep the shots from pulling
/// it.
fn search_physics(settings: &KinematicSettings, rows: &[&Measurement]) -> KinematicSettings {
    let mut s = KinematicSettings {
        solver: SolverKind::Lm,
        loss: Loss::Squared,
        ..settings.clone()
    };
    if loads(rows).len() >= 2 && s.compliance.is_none() {
        s.compliance = Some(ComplianceSettings::default());
    }
    s
}

/// The physics of the refined search: the search's with the transmission harmonics (order 2,
/// under their prior), where it has compliances and no joint errors yet (else none: a stage
/// config's joint errors are searched under already, and without loads there is no compliance
/// to tell a shot from).
fn refined_physics(physics: &KinematicSettings) -> Option<KinematicSettings> {
    (physics.compliance.is_some() && physics.joint_errors.is_none()).then(|| KinematicSettings {
        joint_errors: Some(JointErrorSettings {
            harmonics: 2,
            ..JointErrorSettings::default()
        }),
        ..physics.clone()
    })
}

/// The bad shots of `rows` under the physics of `settings`: fit, flag the rows beyond the
/// threshold, fit again without them, until the flagged set repeats (at most `rounds` fits).
/// With too few configurations for the parameters ([`HELD_OUT_REDUNDANCY`]) a row is flagged
/// only when the fit without its configuration (each left out in turn) also leaves it beyond
/// the threshold of that fit's own spread. With enough, the rows that fit leaves beyond
/// [`REFINED_SHARE`] of the threshold are searched again under the refined physics (with the
/// transmission harmonics: `refined_physics`), fitted without the flagged rows in the same
/// rounds, and a row beyond its threshold is flagged too, unless its error there lies along one
/// joint's motion at loads where that joint's flank may have flipped ([`SINGLE_JOINT_SHARE`]).
/// Returns the report and the rows to calibrate on (all of them with `keep`).
pub fn find_outliers<'a>(
    nominal: &Robot,
    rows: &[&'a Measurement],
    settings: &KinematicSettings,
    outliers: &OutlierSettings,
) -> Result<(OutlierReport, Vec<&'a Measurement>)> {
    find_outliers_with(nominal, rows, settings, outliers, &FitMemo::default())
}

/// [`find_outliers`], remembering its fits of every row not flagged in `memo`
/// ([`fit_kinematic_with`]): the last round fits the search's physics on the rows it returns
/// (the flagged set repeated), and a calibration of that physics on them after it, given the
/// same `memo`, takes that fit instead of making it again (a stage config whose physics the
/// search fits: one identification of its fullest model in four on the paper's arm). The fits
/// without a configuration and the refined search's, which no stage repeats, are not kept. The
/// same results, bit for bit.
pub fn find_outliers_with<'a>(
    nominal: &Robot,
    rows: &[&'a Measurement],
    settings: &KinematicSettings,
    outliers: &OutlierSettings,
    memo: &FitMemo,
) -> Result<(OutlierReport, Vec<&'a Measurement>)> {
    let physics = search_physics(settings, rows);
    let mut flagged: BTreeSet<usize> = BTreeSet::new();
    let mut errors = Vec::new();
    let mut sigma = 0.0;
    let mut folds: Option<(Vec<usize>, usize)> = None;
    let mut held_sigma = None;
    for round in 0..outliers.rounds.max(1) {
        let inliers = |keep: &dyn Fn(usize) -> bool| -> Vec<&Measurement> {
            (rows.iter().enumerate())
                .filter(|&(i, _)| !flagged.contains(&i) && keep(i))
                .map(|(_, r)| *r)
                .collect()
        };
        let fit = fit_kinematic_with(nominal, &inliers(&|_| true), &physics, memo)?;
        if round == 0 && too_few_configurations(&fit, rows) {
            folds = Some(configuration_groups(rows));
        }
        let residuals = physical_model(&fit).residuals(rows.iter().copied());
        let spread =
            |residuals: &[Vector3<f64>]| robust_spread(residuals, &|i| flagged.contains(&i));
        sigma = spread(&residuals);
        errors = residuals.iter().map(|r| r.norm()).collect::<Vec<f64>>();
        let beyond = |errors: &[f64], sigma: f64| -> BTreeSet<usize> {
            (errors.iter().enumerate())
                .filter(|(_, e)| sigma > 0.0 && **e > outliers.threshold * sigma)
                .map(|(i, _)| i)
                .collect()
        };
        let mut next = beyond(&errors, sigma);
        if let Some((fold, n)) = &folds {
            let mut held = vec![Vector3::zeros(); rows.len()];
            for k in 0..*n {
                let test: Vec<usize> = (0..rows.len()).filter(|&i| fold[i] == k).collect();
                if test.is_empty() {
                    continue;
                }
                // A fold whose others cannot be fitted leaves nothing to tell a bad shot by.
                let Ok(without) = fit_kinematic(nominal, &inliers(&|i| fold[i] != k), &physics)
                else {
                    return Ok(none_found(rows, outliers, sigma));
                };
                let model = physical_model(&without);
                for (&i, r) in test
                    .iter()
                    .zip(model.residuals(test.iter().map(|&i| rows[i])))
                {
                    held[i] = r;
                }
            }
            let held_std = spread(&held);
            let held_errors: Vec<f64> = held.iter().map(|r| r.norm()).collect();
            next = &next & &beyond(&held_errors, held_std);
            held_sigma = Some(held_std);
        }
        if next == flagged {
            break;
        }
        flagged = next;
    }
    let refined = match (&folds, refined_physics(&physics)) {
        (None, Some(rich)) => refine(nominal, rows, &rich, outliers, &errors, sigma, &flagged),
        _ => None,
    };
    if let Some(r) = &refined {
        flagged.extend(&r.flagged);
    }
    let outlier = |i: usize| Outlier {
        pose: rows[i].sample.pose.clone(),
        load: rows[i].sample.load,
        line: rows[i].sample.line,
        error: errors[i],
        sigmas: errors[i] / sigma,
        refined_sigmas: (refined.as_ref()).map(|r| r.errors[i] / r.std),
    };
    let report = OutlierReport {
        robust_std: sigma,
        threshold: outliers.threshold,
        left_out: !outliers.keep,
        held_out_std: held_sigma,
        refined_std: refined.as_ref().map(|r| r.std),
        rows: flagged.iter().map(|&i| outlier(i)).collect(),
        suspects: (0..rows.len())
            .filter(|i| held_sigma.is_some() && !flagged.contains(i))
            .filter(|&i| sigma > 0.0 && errors[i] > outliers.threshold * sigma)
            .map(outlier)
            .collect(),
    };
    let kept = if outliers.keep {
        rows.to_vec()
    } else {
        (rows.iter().enumerate())
            .filter(|(i, _)| !flagged.contains(i))
            .map(|(_, r)| *r)
            .collect()
    };
    Ok((report, kept))
}

/// What the refined search found.
struct Refined {
    /// The refined fit's robust standard deviation of the error components, mm.
    std: f64,
    /// Every row's error under it, mm.
    errors: Vec<f64>,
    /// The rows it flagged.
    flagged: BTreeSet<usize>,
}

/// The refined search ([`find_outliers`]): the rows not `flagged` whose `errors` under the
/// search's physics lie beyond [`REFINED_SHARE`] of the threshold of `sigma`, flagged where the
/// refined physics `rich`, fitted without the flagged rows, leaves them beyond the threshold of
/// its own robust standard deviation, unless its error there lies along one joint's motion
/// ([`SINGLE_JOINT_SHARE`]) where a flank's flip may have put it (`past_a_flip`); fitted
/// again without those until the set repeats (at most `rounds` fits). None where no row lies
/// that far out (nothing to fit for), or where a refined fit fails (the first search's finding
/// stands).
fn refine(
    nominal: &Robot,
    rows: &[&Measurement],
    rich: &KinematicSettings,
    outliers: &OutlierSettings,
    errors: &[f64],
    sigma: f64,
    flagged: &BTreeSet<usize>,
) -> Option<Refined> {
    let candidates: BTreeSet<usize> = (0..rows.len())
        .filter(|i| !flagged.contains(i))
        .filter(|&i| sigma > 0.0 && errors[i] > REFINED_SHARE * outliers.threshold * sigma)
        .collect();
    if candidates.is_empty() {
        return None;
    }
    let mut found = Refined {
        std: 0.0,
        errors: Vec::new(),
        flagged: BTreeSet::new(),
    };
    for _ in 0..outliers.rounds.max(1) {
        let out = |i: &usize| flagged.contains(i) || found.flagged.contains(i);
        let inliers: Vec<&Measurement> = (rows.iter().enumerate())
            .filter(|(i, _)| !out(i))
            .map(|(_, r)| *r)
            .collect();
        // A refined fit that fails leaves the first search's finding as it was.
        let Ok(fit) = fit_kinematic(nominal, &inliers, rich) else {
            return None;
        };
        let residuals = physical_model(&fit).residuals(rows.iter().copied());
        let std = robust_spread(&residuals, &|i| out(&i));
        let rich_errors: Vec<f64> = residuals.iter().map(|r| r.norm()).collect();
        let far = |i: usize| rich_errors[i] > REFINED_SHARE * outliers.threshold * std;
        let next: BTreeSet<usize> = (candidates.iter().copied())
            .filter(|&i| std > 0.0 && rich_errors[i] > outliers.threshold * std)
            .filter(|&i| {
                single_joint_share(&fit.robot, rows[i], &residuals[i]) < SINGLE_JOINT_SHARE
                    || !past_a_flip(rows, i, &far)
            })
            .collect();
        found.std = std;
        found.errors = rich_errors;
        if next == found.flagged {
            break;
        }
        found.flagged = next;
    }
    Some(found)
}

/// The robust standard deviation ([`robust_std`]) of the error components of `residuals`, the
/// rows `out` left aside: the spread both searches measure their thresholds in.
fn robust_spread(residuals: &[Vector3<f64>], out: &dyn Fn(usize) -> bool) -> f64 {
    let components: Vec<f64> = (residuals.iter().enumerate())
        .filter(|&(i, _)| !out(i))
        .flat_map(|(_, r)| [r.x, r.y, r.z])
        .collect();
    robust_std(&components)
}

/// Whether row `i` could lie past the one flip of a flank its torque presses in its
/// configuration (the same joint readings, [`readings_key`], and reflector: a pose shot again
/// under another id is the same configuration): a joint's gravity torque is affine in the load,
/// so that as the load grows its flank flips once at most, and the rows on the other flank are
/// the lightest loads or the heaviest. True where every row of the configuration lighter than
/// `i`, or every one heavier, is `far` too (at the lightest or heaviest load: always).
fn past_a_flip(rows: &[&Measurement], i: usize, far: &dyn Fn(usize) -> bool) -> bool {
    let readings = readings_key(rows[i]);
    let same = |k: usize| {
        k != i
            && rows[k].sample.target == rows[i].sample.target
            && readings_key(rows[k]) == readings
    };
    let load = rows[i].sample.load;
    let all_far = |side: &dyn Fn(f64) -> bool| {
        (0..rows.len())
            .filter(|&k| same(k) && side(rows[k].sample.load))
            .all(far)
    };
    all_far(&|l| l < load) || all_far(&|l| l > load)
}

/// The largest share of the error `r` of `row` (its square) that one joint's motion explains:
/// `cos²` of the angle between `r` and the point's velocity under each joint of `robot` at the
/// row's readings (the axis crossed with the lever to the measured point).
fn single_joint_share(robot: &Robot, row: &Measurement, r: &Vector3<f64>) -> f64 {
    let (axes, _) = robot.axes_and_frames(&row.sample.joints_rad());
    (axes.iter())
        .map(|(axis, on)| {
            let motion = axis.cross(&(row.position - on));
            let norms = motion.norm() * r.norm();
            if norms > 0.0 {
                (motion.dot(r) / norms).powi(2)
            } else {
                0.0
            }
        })
        .fold(0.0, f64::max)
}

/// Whether `rows` hold fewer coordinates than [`HELD_OUT_REDUNDANCY`] times the parameters
/// `fit` identified (three per configuration and reflector).
fn too_few_configurations(fit: &KinematicCalibration, rows: &[&Measurement]) -> bool {
    let (coordinates, parameters) = coordinates_and_parameters(fit, rows);
    (coordinates as f64) < HELD_OUT_REDUNDANCY * parameters as f64
}

/// No bad shot found (a fold could not be fitted without its configurations: nothing could
/// be told), every row kept; `sigma` the fit of every row's robust standard deviation.
fn none_found<'a>(
    rows: &[&'a Measurement],
    outliers: &OutlierSettings,
    sigma: f64,
) -> (OutlierReport, Vec<&'a Measurement>) {
    let report = OutlierReport {
        robust_std: sigma,
        threshold: outliers.threshold,
        left_out: !outliers.keep,
        held_out_std: None,
        refined_std: None,
        rows: Vec::new(),
        suspects: Vec::new(),
    };
    (report, rows.to_vec())
}

#[cfg(test)]
mod tests {
    use robocal_data::Sample;

    use super::*;

    /// Against finite differences of the point: an error along one joint's motion (the point's
    /// change as that joint turns) is explained whole, one across every joint's motion is not;
    /// with the measured point where the model puts it.
    #[test]
    fn single_joint_share_against_finite_differences() {
        let path = concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../configs/robots/pmc6va030.toml"
        );
        let robot = Robot::load(path).unwrap();
        let joints = vec![20.0, -35.0, 15.0, 40.0, -60.0, 25.0];
        let row = Measurement {
            position: robot.point(
                &joints
                    .iter()
                    .map(|d: &f64| d.to_radians())
                    .collect::<Vec<_>>(),
            ),
            sample: Sample {
                pose: "p".into(),
                joints: joints.clone(),
                load: 0.0,
                line: 0,
                target: String::new(),
                seq: None,
                last_move: Vec::new(),
            },
            orientation: None,
        };
        let motion = |j: usize| {
            let h = 1e-6;
            let at = |d: f64| {
                let mut q: Vec<f64> = joints.iter().map(|d| d.to_radians()).collect();
                q[j] += d;
                robot.point(&q)
            };
            (at(h) - at(-h)) / (2.0 * h)
        };
        // (Joint 6 does not move a point on its axis: nothing to explain there.)
        for j in (0..6).filter(|&j| motion(j).norm() > 1e-3) {
            let along = motion(j) * 0.01;
            let share = single_joint_share(&robot, &row, &along);
            assert!((share - 1.0).abs() < 1e-9, "joint {j}: {share}");
        }
        // Across joints 1 and 2's motions: explained by neither whole; the share is the
        // largest cos² over the six joints, computed here from the differences.
        let across = motion(0).cross(&motion(1));
        let by_hand = (0..6)
            .map(|j| {
                let m = motion(j);
                (m.dot(&across) / (m.norm() * across.norm())).powi(2)
            })
            .fold(0.0, f64::max);
        let share = single_joint_share(&robot, &row, &across);
        assert!((share - by_hand).abs() < 1e-9, "{share} vs {by_hand}");
        assert!(share < SINGLE_JOINT_SHARE, "{share}");
    }

    fn row(pose: &str, target: &str, load: f64) -> Measurement {
        Measurement {
            position: Vector3::zeros(),
            sample: Sample {
                pose: pose.into(),
                joints: vec![if pose == "b" { 10.0 } else { 0.0 }; 6],
                load,
                line: 0,
                target: target.into(),
                seq: None,
                last_move: Vec::new(),
            },
            orientation: None,
        }
    }

    /// By hand, on one configuration at loads 0, 5, 10, 15, 20 (rows 0–4) beside another
    /// configuration and another reflector of the same pose (rows 5–7, never far, and not to be
    /// counted): the lightest and heaviest loads may always lie past a flip; a middle load only
    /// where every lighter or every heavier row of its own configuration is far too.
    #[test]
    fn past_a_flip_by_hand() {
        let data = [
            row("a", "", 0.0),
            row("a", "", 5.0),
            row("a", "", 10.0),
            row("a", "", 15.0),
            row("a", "", 20.0),
            row("b", "", 0.0),
            row("a", "t2", 0.0),
            row("a", "t2", 20.0),
        ];
        let rows: Vec<&Measurement> = data.iter().collect();
        let with = |far_rows: &[usize], i: usize| past_a_flip(&rows, i, &|k| far_rows.contains(&k));
        assert!(with(&[], 0) && with(&[], 4), "the ends");
        assert!(!with(&[], 2) && !with(&[2], 2), "a middle load alone");
        assert!(with(&[0, 1], 2), "the lighter loads off too");
        assert!(with(&[3, 4], 2), "the heavier loads off too");
        assert!(!with(&[1], 2) && !with(&[0, 4], 2), "a gap on either side");
        assert!(
            !with(&[5, 6, 7], 1),
            "other configurations and reflectors do not count"
        );
        // A pose shot again under another id (the same readings) is the same configuration:
        // its heavier load puts the middle row between two loads.
        let again = [
            row("a", "", 0.0),
            row("a", "", 10.0),
            row("a-again", "", 20.0),
        ];
        let rows: Vec<&Measurement> = again.iter().collect();
        assert!(!past_a_flip(&rows, 1, &|_| false));
        assert!(past_a_flip(&rows, 1, &|k| k == 2));
    }
}
