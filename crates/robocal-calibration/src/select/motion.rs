//! Play that follows the order of motion: where the rows carry the order they were measured in
//! (`seq`), each joint's play in the direction of its last move is identified with the
//! geometry, and kept where the folds say it pays.

use nalgebra::{DMatrix, DVector};
use robocal_data::{Measurement, Observer};
use robocal_ident::KinematicSettings;
use robocal_model::{CalibratedModel, MotionPlay};
use robocal_robot::Robot;

use super::plan::FoldPlan;
use super::selection::Decision;
use super::settings::AutoSettings;
use super::status::Stage;
use crate::error::Result;
use crate::fit::{fit_kinematic, physical_model};
use crate::folds::{Held, improves};

/// Steps of the play at most (each after a fit of the table).
const ROUNDS: usize = 6;

/// A step that moves no play by more than this (deg) ends the identification.
const SETTLED_DEG: f64 = 1e-4;

/// A joint whose last move took each direction on fewer than this share of the rows has no play
/// of its own in the data (on one flank throughout, its play is a constant offset, which the
/// table's zero takes).
const FEWEST_EACH_WAY: f64 = 0.05;

/// A joint whose column is smaller than this share of the largest moves the point by too
/// little for its play to be told from the noise (a last axis through, or within a hair of,
/// the measured point): its play is held at 0.
const NO_LEVER: f64 = 1e-3;

/// Directions of the columns smaller than this share of the largest are left out of the
/// least squares.
const SINGULAR: f64 = 1e-9;

/// The least share of the table's held-out score the play must take off to be kept, beyond
/// the paired test: a play of a few thousandths of a degree that the table's folds find also
/// fits what the joint-error terms of the chain model in its place.
const MIN_GAIN: f64 = 0.05;

/// The most rows the decision is made on: beyond, every k-th row of the file (each keeps the
/// last move its place in the whole order gave it).
const DECIDE_ROWS: usize = 2000;

/// Step of the central differences of the point in a joint, deg.
const STEP_DEG: f64 = 1e-3;

/// Whether the rows carry an order of measurement.
pub(crate) fn ordered(rows: &[&Measurement]) -> bool {
    rows.iter().any(|r| !r.sample.last_move.is_empty())
}

/// The joints whose last move took both directions on enough of the rows.
fn moving_joints(rows: &[&Measurement]) -> Vec<usize> {
    let n = rows.first().map_or(0, |r| r.sample.joints.len());
    let count = rows.len().max(1) as f64;
    (0..n)
        .filter(|&j| {
            let side = |s: f64| {
                (rows.iter())
                    .filter(|r| r.sample.last_move.get(j) == Some(&s))
                    .count() as f64
                    / count
            };
            side(1.0) >= FEWEST_EACH_WAY && side(-1.0) >= FEWEST_EACH_WAY
        })
        .collect()
}

/// The rows read with `play`: each row's joints less the play in the direction of its last move
/// ([`MotionPlay::read`]).
pub(crate) fn read_rows(play: &MotionPlay, rows: &[&Measurement]) -> Vec<Measurement> {
    (rows.iter())
        .map(|r| Measurement {
            sample: play.read(&r.sample).into_owned(),
            ..(*r).clone()
        })
        .collect()
}

/// The play identified with the table, and the tables fitted on the way.
pub(crate) struct Identified {
    /// The play, deg per joint.
    pub(crate) play: MotionPlay,
    /// The table fitted on the rows as read (no play).
    pub(crate) first: CalibratedModel,
    /// The table fitted on the rows read with the play found, with the play.
    pub(crate) last: CalibratedModel,
}

/// The play of `joints` identified with the table from `rows`: the table fitted on the rows
/// read with the play so far, then the play's step by linear least squares on the positions
/// it leaves (each joint's column the point's derivative in the joint times the direction of
/// its last move), until no step moves the play by more than [`SETTLED_DEG`] (at most
/// [`ROUNDS`] steps), and the table fitted once more on the rows read with it. A play that
/// comes out negative (a joint ahead of its reading) is held at 0.
pub(crate) fn identify_play(
    nominal: &Robot,
    rows: &[&Measurement],
    joints: &[usize],
    settings: &KinematicSettings,
) -> Result<Identified> {
    let n = nominal.dof();
    let mut play = MotionPlay { play: vec![0.0; n] };
    // A joint stands behind its reading, never ahead: one whose play comes out negative is
    // held at 0 and the rest found again.
    let mut held = vec![false; joints.len()];
    let mut first: Option<CalibratedModel> = None;
    let mut settled = joints.is_empty();
    for round in 0..=ROUNDS {
        let read = read_rows(&play, rows);
        let read: Vec<&Measurement> = read.iter().collect();
        let model = physical_model(&fit_kinematic(nominal, &read, settings)?);
        if first.is_none() {
            first = Some(model.clone());
        }
        if settled || round == ROUNDS {
            let last = CalibratedModel {
                motion: Some(play.clone()),
                ..model
            };
            let first = first.expect("set in the first round");
            return Ok(Identified { play, first, last });
        }
        let step = play_step(&model, &read, rows, joints, &held)?;
        let mut turned = false;
        for (k, &j) in joints.iter().enumerate() {
            play.play[j] += step[k];
            if play.play[j] < 0.0 {
                play.play[j] = 0.0;
                held[k] = true;
                turned = true;
            }
        }
        settled = step.amax() <= SETTLED_DEG && !turned;
    }
    unreachable!("the last round returns")
}

/// The linear least-squares step of the play of `joints` (not `held`) on what `model` leaves
/// of the rows as read (`read`, with the last moves of `rows`): each joint's column the point's
/// derivative in the joint times the direction of its last move.
fn play_step(
    model: &CalibratedModel,
    read: &[&Measurement],
    rows: &[&Measurement],
    joints: &[usize],
    held: &[bool],
) -> Result<DVector<f64>> {
    let mut a = DMatrix::zeros(3 * read.len(), joints.len());
    let mut b = DVector::zeros(3 * read.len());
    for (i, (r, raw)) in read.iter().zip(rows).enumerate() {
        let e = r.position - model.base_point(&r.sample);
        for (k, &j) in joints.iter().enumerate() {
            let side = raw.sample.last_move.get(j).copied().unwrap_or(0.0);
            if side == 0.0 {
                continue;
            }
            let moved = |d: f64| {
                let mut s = r.sample.clone();
                s.joints[j] += d;
                model.base_point(&s)
            };
            let slope = (moved(STEP_DEG) - moved(-STEP_DEG)) / (2.0 * STEP_DEG);
            for c in 0..3 {
                // The point moves by −slope × side per degree of play.
                a[(3 * i + c, k)] = -slope[c] * side;
            }
        }
        for c in 0..3 {
            b[3 * i + c] = e[c];
        }
    }
    // A joint that moves the point by next to nothing has no play to find: its column is
    // left out.
    let norms: Vec<f64> = (0..joints.len()).map(|k| a.column(k).norm()).collect();
    let largest = norms.iter().copied().fold(0.0, f64::max);
    for (k, norm) in norms.iter().enumerate() {
        if *norm <= NO_LEVER * largest || held[k] {
            a.column_mut(k).fill(0.0);
        }
    }
    let svd = a.svd(true, true);
    let floor = SINGULAR * svd.singular_values.max();
    let step = svd.solve(&b, floor).map_err(|why| {
        crate::error::CalibrationError::Stage(format!(
            "the play that follows the order of motion: {why}"
        ))
    })?;
    Ok(step)
}

/// What the folds say of the play: the table alone against the table with the play, each
/// fitted on every fold's training rows and scored on its held-out rows (read with the fold's
/// play), and the play of every row when it pays significantly. `None` without an order, or
/// with no joint that moved both ways.
pub(crate) fn decide(
    settings: &AutoSettings,
    nominal: &Robot,
    rows: &[&Measurement],
    validation: Option<&(&[&Measurement], String)>,
    observer: &dyn Observer,
) -> Result<Option<(Decision, Option<MotionPlay>)>> {
    if !ordered(rows) {
        return Ok(None);
    }
    let every = rows.len().div_ceil(DECIDE_ROWS).max(1);
    let subset: Vec<&Measurement> = rows.iter().copied().step_by(every).collect();
    let rows = subset.as_slice();
    let joints = moving_joints(rows);
    let names: Vec<String> = joints.iter().map(|j| format!("j{}", j + 1)).collect();
    let what = format!(
        "play in the direction of each joint's last move ({}) identified with the table",
        names.join(", ")
    );
    if joints.is_empty() {
        let d = Decision::said(
            Stage::Motion,
            false,
            None,
            None,
            "not tried: no joint moved both ways between the rows in their order (`seq`)".into(),
        );
        observer.message(&format!("stage {}: {}", d.stage, d.reason));
        return Ok(Some((d, None)));
    }
    let Some(plan) = FoldPlan::new(settings, rows, validation) else {
        return Ok(None);
    };
    let kinematic = KinematicSettings {
        angle_weight: settings.angle_weight,
        target_weights: settings.target_weights.clone(),
        ..KinematicSettings::default()
    };
    // On every row first: a play whose first step takes less than the share the folds ask of
    // it off the table's own training error is not scored on them.
    let table = physical_model(&fit_kinematic(nominal, rows, &kinematic)?);
    let step = play_step(&table, rows, rows, &joints, &vec![false; joints.len()])?;
    let mut first = MotionPlay {
        play: vec![0.0; nominal.dof()],
    };
    for (k, &j) in joints.iter().enumerate() {
        first.play[j] = step[k].max(0.0);
    }
    let mean = |m: &CalibratedModel| {
        let e = m.errors(rows);
        e.iter().sum::<f64>() / e.len().max(1) as f64
    };
    let stepped = CalibratedModel {
        motion: Some(first),
        ..table.clone()
    };
    let (fitted, with_play) = (mean(&table), mean(&stepped));
    if fitted - with_play < MIN_GAIN * fitted {
        let d = Decision::said(
            Stage::Motion,
            false,
            None,
            None,
            format!(
                "dropped: {what}: its first step takes {:.1} % off the table's mean error on the training rows ({fitted:.4} → {with_play:.4} mm), under the {:.0} % it must take off the held-out score: not scored on the folds",
                100.0 * (fitted - with_play) / fitted.max(f64::MIN_POSITIVE),
                MIN_GAIN * 100.0
            ),
        );
        observer.message(&format!("stage {}: {}", d.stage, d.reason));
        return Ok(Some((d, None)));
    }
    let (mut without, mut with) = (Held::default(), Held::default());
    for fold in &plan.splits {
        let found = identify_play(nominal, &fold.train, &joints, &kinematic)?;
        without.add(fold, found.first.errors(&fold.test));
        with.add(fold, found.last.errors(&fold.test));
    }
    let (base, new) = (without.all(), with.all());
    let (w, x) = (without.summary().2, with.summary().2);
    let significant = improves(&base, &new, &plan.groups());
    let kept = significant && w - x >= MIN_GAIN * w;
    let play = if kept {
        Some(identify_play(nominal, rows, &joints, &kinematic)?.play)
    } else {
        None
    };
    let why = match (kept, significant) {
        (true, _) => String::new(),
        (false, true) => format!(
            " (lower by less than {:.0} % of the score without)",
            MIN_GAIN * 100.0
        ),
        (false, false) if x < w => " (lower, but not by more than twice its standard error)".into(),
        (false, false) => String::new(),
    };
    let mut d = Decision::said(
        Stage::Motion,
        kept,
        Some(w),
        Some(x),
        format!(
            "{}: held-out score {w:.4} mm without, {x:.4} mm with {what}{why}",
            if kept { "kept" } else { "dropped" }
        ),
    );
    if let Some(p) = &play {
        let values: Vec<String> = (joints.iter())
            .map(|&j| format!("j{} {:.4}°", j + 1, p.play[j]))
            .collect();
        d.reason += &format!("; play {}", values.join(", "));
    }
    observer.message(&format!("stage {}: {}", d.stage, d.reason));
    Ok(Some((d, play)))
}

#[cfg(test)]
mod tests {
    use std::path::Path;

    use nalgebra::Vector3;
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;
    use robocal_data::{Sample, Silent, set_last_moves};
    use robocal_model::CalibratedModel;

    use super::*;

    /// ARM5's nominal table, and a true arm whose table differs from it (lengths by a few
    /// millimetres, zeros by a few hundredths of a degree) and whose joints stand `play` behind
    /// their readings in the direction of their last move: `count` poses measured in a random
    /// order (their `seq`), each point with 0.01 mm of noise.
    fn measured(play: &[f64], count: usize) -> (Robot, Vec<Measurement>) {
        let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
        let nominal = Robot::load(root.join("configs/robots/arm5.toml")).unwrap();
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        let mut truth = nominal.clone();
        for j in &mut truth.joints {
            j.a += rng.random_range(-2.0..2.0);
            j.d += rng.random_range(-2.0..2.0);
            j.theta += rng.random_range(-0.05f64..0.05).to_radians();
        }
        let mut samples: Vec<Sample> = (0..count)
            .map(|i| Sample {
                pose: format!("p{i:03}"),
                joints: (0..5).map(|_| rng.random_range(-90.0..90.0)).collect(),
                load: 0.0,
                line: i as u64 + 2,
                target: String::new(),
                seq: Some(i as i64),
                last_move: Vec::new(),
            })
            .collect();
        set_last_moves(&mut samples);
        let truth = CalibratedModel {
            motion: Some(MotionPlay {
                play: play.to_vec(),
            }),
            ..CalibratedModel::kinematic(truth)
        };
        let rows = (truth.predict(&samples).into_iter().zip(samples))
            .map(|(p, sample)| Measurement {
                position: p + Vector3::from_fn(|_, _| rng.random_range(-0.01..0.01)),
                sample,
                orientation: None,
            })
            .collect();
        (nominal, rows)
    }

    /// The play identified with the table from rows measured in order comes back as the true
    /// arm's, to the noise; every joint moved both ways, so every joint's play is sought.
    #[test]
    fn the_play_that_follows_the_order_of_motion_is_identified_against_truth() {
        // ARM5's last axis runs through its measured point: its play moves next to nothing
        // (the identified tool a hair off the axis), and stays 0.
        let play = [0.05, 0.02, 0.08, 0.01, 0.03];
        let (nominal, rows) = measured(&play, 150);
        let rows: Vec<&Measurement> = rows.iter().collect();
        assert_eq!(moving_joints(&rows), vec![0, 1, 2, 3, 4]);
        let found = identify_play(&nominal, &rows, &[0, 1, 2, 3, 4], &Default::default())
            .unwrap()
            .play;
        let expected = [0.05, 0.02, 0.08, 0.01, 0.0];
        for (f, t) in found.play.iter().zip(expected) {
            assert!(
                (f - t).abs() < 2e-3,
                "{:?} against {expected:?}",
                found.play
            );
        }
    }

    /// A twin whose joints stand behind their readings in the direction of their last move
    /// (`[motion] play`), with its compliances, gear errors, backlash and noise: its rows carry
    /// their order, and the default finds the play it was given, to what identifying it with
    /// the table alone leaves of the other effects (0.012° on joint 4).
    #[test]
    fn the_default_finds_the_play_of_a_twin() {
        let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
        let mut twin = robocal_twin::TwinConfig::load(root.join("configs/twin/arm5.toml")).unwrap();
        twin.poses.count = 60;
        let play = [0.06, 0.03, 0.08, 0.04, 0.0];
        twin.motion = Some(play.to_vec());
        let owned = twin.generate().unwrap().measurements.rows;
        assert!(owned.iter().all(|r| r.sample.seq.is_some()));
        let rows: Vec<&Measurement> = owned.iter().collect();
        let settings = AutoSettings {
            residuals: Vec::new(),
            runout: 0,
            ..AutoSettings::default()
        };
        let built =
            super::super::automatic(&settings, &twin.nominal, &rows, None, &Silent).unwrap();
        let found = built.motion.expect("the play kept");
        for (f, t) in found.play.iter().zip(play).take(4) {
            assert!((f - t).abs() < 0.015, "{:?} against {play:?}", found.play);
        }
    }

    /// A joint that runs ahead of its reading (a negative play) is held at 0: a joint with play
    /// stands behind the direction it moved in.
    #[test]
    fn a_play_never_comes_out_negative() {
        let (nominal, rows) = measured(&[0.05, -0.03, 0.08, 0.01, 0.0], 150);
        let rows: Vec<&Measurement> = rows.iter().collect();
        let found = identify_play(&nominal, &rows, &[0, 1, 2, 3, 4], &Default::default())
            .unwrap()
            .play;
        assert_eq!(found.play[1], 0.0, "{:?}", found.play);
        assert!(found.play.iter().all(|p| *p >= 0.0), "{:?}", found.play);
        assert!((found.play[2] - 0.08).abs() < 0.01, "{:?}", found.play);
    }

    /// The default keeps the play where the arm has it, and the model it writes carries it;
    /// where the arm has none, the folds drop it.
    #[test]
    fn the_default_keeps_the_play_only_where_the_folds_say_it_pays() {
        let settings = AutoSettings::table_only();
        for (play, kept) in [([0.05, 0.02, 0.08, 0.0, 0.03], true), ([0.0; 5], false)] {
            let (nominal, rows) = measured(&play, 120);
            let rows: Vec<&Measurement> = rows.iter().collect();
            let built = super::super::automatic(&settings, &nominal, &rows, None, &Silent).unwrap();
            let decision = &built.selection.as_ref().unwrap().decisions[0];
            assert_eq!(decision.stage, Stage::Motion);
            assert_eq!(decision.kept, kept, "{}", decision.reason);
            assert_eq!(built.model().motion.is_some(), kept);
        }
    }
}
