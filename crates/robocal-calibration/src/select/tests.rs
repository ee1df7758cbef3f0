use std::path::Path;

use robocal_twin::TwinConfig;

use robocal_ident::{FLANK_ROUNDS, SEARCH_FLANK_ROUNDS};
use robocal_model::CalibratedModel;

use super::physics::{Effect, Physics};
use super::residual::{KINEMATIC, ResidualScore};
use super::scoring::{fold_share, projection};
use nalgebra::Vector3;
use robocal_data::{Measurement, Silent};
use robocal_residual::{Frame, ResidualKind, ResidualSettings, ResidualStage};
use robocal_robot::Robot;

use super::gravity::mounting;
use super::plan::FoldPlan;
use super::residual::{pick_residual, residual_share};
use super::run::automatic_metered;
use super::scoring::FINAL_FIT_SHARE;
use super::selection::budget_warning;
use super::*;
use crate::budget::Meter;
use crate::built::Built;
use crate::spread;

/// Joint 1's angle to gravity, against a hand count on ARM5 (joint 1 along its base's z):
/// 0° for gravity down or up, 90° across, 45° inclined, whatever the base's pose in the
/// tracker frame; the residual models in both frames only where it exceeds the bound, and
/// not when the user named the frame (every stage in one frame, or the switch off).
#[test]
fn residual_models_are_tried_in_both_frames_only_off_gravity() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    let mut arm5 = Robot::load(root.join("configs/robots/arm5.toml")).unwrap();
    let g = 9.80665;
    for rpy in [[0.0, 0.0, 0.0], [0.4, 1.2, -2.4]] {
        arm5.base.rpy = Vector3::from(rpy);
        for (gravity, expected) in [
            (Vector3::new(0.0, 0.0, -g), 0.0),
            (Vector3::new(0.0, 0.0, g), 0.0),
            (Vector3::new(g, 0.0, 0.0), 90.0),
            (Vector3::new(0.0, -g, 0.0), 90.0),
            (Vector3::new(g, 0.0, -g), 45.0),
        ] {
            let angle = joint1_gravity_angle(&arm5, &gravity).unwrap();
            assert!(
                (angle - expected).abs() < 1e-6,
                "{rpy:?} {gravity}: {angle}"
            );
        }
    }
    let d = AutoSettings::default();
    let down = Vector3::new(0.0, 0.0, -g);
    let tilted = |deg: f64| {
        let r = deg.to_radians();
        Vector3::new(g * r.sin(), 0.0, -g * r.cos())
    };
    assert_eq!(residual_stages(&d, &arm5, &down), d.residuals);
    assert_eq!(residual_stages(&d, &arm5, &tilted(9.9)), d.residuals);
    let both = residual_stages(&d, &arm5, &tilted(10.1));
    assert_eq!(both.len(), 2 * d.residuals.len());
    for (turned, world) in both.iter().zip(&both[d.residuals.len()..]) {
        assert_eq!(turned.settings.frame, Frame::Joint1);
        assert_eq!(world.settings.frame, Frame::World);
        let mut same = world.clone();
        same.settings.frame = Frame::Joint1;
        assert_eq!(&same, turned);
    }
    let off = AutoSettings {
        both_frames_off_gravity: false,
        ..d.clone()
    };
    assert_eq!(residual_stages(&off, &arm5, &tilted(45.0)), d.residuals);
    let mut world = d.clone();
    for s in &mut world.residuals {
        s.settings.frame = Frame::World;
    }
    assert_eq!(
        residual_stages(&world, &arm5, &tilted(45.0)),
        world.residuals
    );
}

/// The budget's warning names every candidate the budget cut (skipped before its folds or
/// abandoned during them) and no other (one skipped for another reason, one scored); none
/// cut, no warning.
#[test]
fn the_budget_warning_names_the_candidates_it_cut() {
    let candidate = |name: &str, score: Option<f64>, status: Status| Candidate {
        name: name.into(),
        physics: None,
        held_out: None,
        held_out_blocks: None,
        score,
        seconds: 0.0,
        cost: 0.0,
        status,
    };
    let mut candidates = vec![
        candidate("kinematic", Some(0.1), Status::Evaluated),
        candidate("kinematic + compliance", Some(0.05), Status::Chosen),
        candidate(
            "kinematic + gp",
            None,
            Status::TooFewConfigurations {
                fewest: 20,
                needed: 30,
            },
        ),
    ];
    assert_eq!(budget_warning(&candidates, 120.0), None);
    candidates.push(candidate(
        "kinematic + compliance + runout 2",
        None,
        Status::Abandoned {
            budget: 120.0,
            reserve: 0.0,
        },
    ));
    let one = budget_warning(&candidates, 120.0).unwrap();
    assert!(
        one.contains("before 1 candidate was scored (kinematic + compliance + runout 2)"),
        "{one}"
    );
    candidates.push(candidate(
        "kinematic + compliance + somm",
        None,
        Status::Spent { budget: 120.0 },
    ));
    let two = budget_warning(&candidates, 120.0).unwrap();
    assert!(
        two.starts_with("the time budget (120 s) ended the search before 2 candidates were scored (kinematic + compliance + runout 2; kinematic + compliance + somm)"),
        "{two}"
    );
    assert!(two.contains("`--budget`") && !two.contains("gp"), "{two}");
}

/// A candidate is projected from the slowest before it; the flank search from the candidate
/// it extends where that was scored, however slow a candidate between them (the runouts
/// the chain dropped), × the flank rounds' ratio; from the slowest where it was not.
#[test]
fn the_flank_search_is_projected_from_the_candidate_it_extends() {
    let scored = |physics: Physics, seconds: f64| Candidate {
        name: physics.name(),
        physics: Some(physics),
        held_out: None,
        held_out_blocks: None,
        score: Some(0.03),
        seconds,
        cost: seconds,
        status: Status::Evaluated,
    };
    let base = (Physics::RIGID)
        .with(Effect::Compliance)
        .with(Effect::Harmonics(2))
        .with(Effect::Backlash);
    let runout = base.with(Effect::Runout(2));
    let search = base.with(Effect::FlankSearch);
    let ratio = SEARCH_FLANK_ROUNDS as f64 / FLANK_ROUNDS as f64 * (1.0 + FINAL_FIT_SHARE);
    let mut candidates = vec![scored(base, 2.6), scored(runout, 38.2)];
    let (from, seconds, projected) = projection(search, &candidates);
    assert_eq!((from, seconds), ("the candidate it extends", 2.6));
    assert!((projected - 2.6 * ratio).abs() < 1e-12);
    // Any other candidate from the slowest.
    let tilt = base.with(Effect::Tilt);
    let (from, seconds, projected) = projection(tilt, &candidates);
    assert_eq!((from, seconds), ("the slowest candidate", 38.2));
    assert!((projected - 38.2 * (1.0 + FINAL_FIT_SHARE)).abs() < 1e-12);
    // The search on the runouts' physics extends the runouts' candidate.
    let (_, seconds, _) = projection(search.with(Effect::Runout(2)), &candidates);
    assert_eq!(seconds, 38.2);
    // An extended candidate without a score (abandoned) projects nothing.
    candidates[0].score = None;
    let (from, seconds, projected) = projection(search, &candidates);
    assert_eq!((from, seconds), ("the slowest candidate", 38.2));
    assert!((projected - 38.2 * ratio).abs() < 1e-12);
}

/// A fold's share of the budget left: the folds' rounds (`at_once` at a time) and the final
/// fit's share after them take it all; nothing left gives nothing.
#[test]
fn a_fold_gets_its_rounds_share_of_the_budget_left() {
    // Ten folds two at a time: five rounds, and the final fit's 0.2 of them.
    let share = fold_share(60.0, 10, 2);
    assert!((share * 5.0 * (1.0 + FINAL_FIT_SHARE) - 60.0).abs() < 1e-12);
    // An odd fold is a round of its own; one core runs every fold in turn.
    assert_eq!(fold_share(60.0, 9, 2), fold_share(60.0, 10, 2));
    assert_eq!(fold_share(60.0, 5, 1), fold_share(60.0, 10, 2));
    assert_eq!(fold_share(60.0, 5, 0), fold_share(60.0, 5, 1));
    assert_eq!(fold_share(-3.0, 10, 2), 0.0);
}

/// The runouts leave a quarter of the budget to the residual models where any will be
/// scored: 30 s of the default 120, 15 of 60; none without residual models or with fewer
/// configurations to train them on than they need; the status of runouts abandoned for the
/// share names it.
#[test]
fn the_runouts_leave_a_share_of_the_budget_to_the_residual_models() {
    let settings = AutoSettings::default();
    assert!(!settings.residuals.is_empty());
    let needed = settings.min_residual_configurations;
    assert_eq!(residual_share(&settings, needed), 30.0);
    let halved = AutoSettings {
        budget_seconds: 60.0,
        ..settings.clone()
    };
    assert_eq!(residual_share(&halved, needed + 5), 15.0);
    assert_eq!(residual_share(&settings, needed - 1), 0.0);
    let none = AutoSettings {
        residuals: Vec::new(),
        ..settings
    };
    assert_eq!(residual_share(&none, needed), 0.0);
    // A candidate cut for the share says so; one cut for the whole budget names none.
    assert_eq!(
        Status::Abandoned {
            budget: 120.0,
            reserve: 30.0
        }
        .to_string(),
        "abandoned: its folds would run past the time budget (120 s), less the 30 s left to the residual models"
    );
    assert_eq!(
        Status::Abandoned {
            budget: 120.0,
            reserve: 0.0
        }
        .to_string(),
        "abandoned: its folds would run past the time budget (120 s)"
    );
}

/// The residual pick: the lowest score among the models that pass the paired test against
/// the physics (1.0); a lower-scoring model that fails it does not hide one that passes, and
/// one that passes but scores above the physics is not taken.
#[test]
fn the_residual_pick_is_the_lowest_score_among_the_significant() {
    let stage = ResidualStage {
        settings: ResidualSettings::gp(1),
        holdout: 0.2,
    };
    let model = |score: f64, significant: bool| ResidualScore {
        stage: stage.clone(),
        base: KINEMATIC,
        score: Some(score),
        significant,
        spread: None,
        beside: None,
    };
    let skipped = ResidualScore {
        stage: stage.clone(),
        base: KINEMATIC,
        score: None,
        significant: false,
        spread: None,
        beside: None,
    };
    assert_eq!(
        pick_residual(&[model(0.8, true), model(0.75, true)], 1.0),
        Some((1, 0.75))
    );
    assert_eq!(
        pick_residual(&[model(0.8, true), model(0.75, false)], 1.0),
        Some((0, 0.8))
    );
    assert_eq!(
        pick_residual(&[skipped, model(0.9, true)], 1.0),
        Some((1, 0.9))
    );
    assert_eq!(
        pick_residual(&[model(0.8, false), model(0.75, false)], 1.0),
        None
    );
    assert_eq!(pick_residual(&[model(0.8, true)], 0.7), None);
}

/// A twin's rows, `count` configurations at its trained loads.
fn twin_rows(file: &str, count: usize) -> (TwinConfig, Vec<Measurement>) {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    let mut twin = TwinConfig::load(root.join(file)).unwrap();
    twin.poses.count = count;
    let rows = twin.generate().unwrap().measurements.rows;
    (twin, rows)
}

/// With the budget kept by counted work (`reproducible`), where it cuts the search the same
/// candidates are scored, skipped and abandoned, with the same held-out numbers to the bit,
/// on one core as on two or three: the counts decide, not the clock (its guard set far off,
/// so that a slow test machine cannot decide either). Budgets of a fifth to three fifths of
/// what the unbounded search counted cut candidates it scored.
#[test]
fn a_counted_budget_cuts_the_search_alike_on_any_number_of_cores() {
    let (twin, owned) = twin_rows("configs/twin/arm5.toml", 30);
    let rows: Vec<&Measurement> = owned.iter().collect();
    let mut gp = ResidualSettings::gp(3);
    gp.gp.iterations = 10;
    gp.gp.hyper_rows = 100;
    let settings = AutoSettings {
        self_weight: false,
        runout: 0,
        outliers: None,
        residuals: vec![ResidualStage {
            settings: gp,
            holdout: 0.2,
        }],
        reproducible: true,
        ..AutoSettings::default()
    };
    let run = |threads: usize, budget: f64| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| {
            let meter = Meter::guarded(budget, 1e6);
            automatic_metered(&settings, &twin.nominal, &rows, None, &Silent, &meter).unwrap()
        })
    };
    let summary = |built: &Built| {
        let selection = built.selection.as_ref().unwrap();
        let candidates: Vec<_> = (selection.candidates.iter())
            .map(|c| (c.name.clone(), c.status.clone(), c.score.map(f64::to_bits)))
            .collect();
        (candidates, selection.counted_seconds.map(f64::to_bits))
    };
    let unbounded = run(2, 1e6);
    let (all, counted) = summary(&unbounded);
    let counted = f64::from_bits(counted.unwrap());
    assert!(counted > 0.0);
    assert!(all.iter().all(|(_, _, score)| score.is_some()), "{all:?}");
    // A fifth of it abandons candidates during their folds (physical and residual), two
    // and three fifths skip one before its folds or abandon another.
    for share in [0.2, 0.4, 0.6] {
        let cut = summary(&run(2, counted * share));
        assert_eq!(summary(&run(1, counted * share)), cut, "at {share}");
        assert_eq!(summary(&run(3, counted * share)), cut, "at {share}");
        let scored = cut.0.iter().filter(|(_, _, score)| score.is_some()).count();
        assert!(scored < all.len(), "nothing cut at {share}: {:?}", cut.0);
        assert!(
            (cut.0.iter()).any(|(_, status, _)| status.budget_cut()),
            "{:?}",
            cut.0
        );
    }
    let abandoned = summary(&run(1, counted * 0.2)).0;
    assert!(
        (abandoned.iter())
            .any(|(name, status, _)| name.contains("+ gp")
                && matches!(status, Status::Abandoned { .. })),
        "{abandoned:?}"
    );
}

/// The ceiling-mounted ARM6K (gravity along +z of its base frame): the default decides once
/// that gravity lies along the tracker's −z — within a degree of the twin's — and keeps the
/// warning for the report; the upright ARM5's is left to each fit, and so is any arm's with
/// one load (no compliance to tell).
#[test]
fn the_mounting_is_decided_once_from_the_data() {
    let (twin, rows) = twin_rows("configs/twin/arm6k.toml", 30);
    let rows: Vec<&Measurement> = rows.iter().collect();
    let work = robocal_ident::Work::new(None);
    let (gravity, warning) =
        mounting(&AutoSettings::default(), &twin.nominal, &rows, &work).unwrap();
    assert!(work.count() > 0, "the mounting's fit is counted");
    assert!(
        gravity.angle(&twin.gravity).to_degrees() < 1.0,
        "{gravity} vs {}",
        twin.gravity
    );
    assert!(
        warning.is_some_and(|w| w.starts_with("gravity taken along the tracker's -z")),
        "no warning"
    );
    let one_load: Vec<&Measurement> = (rows.iter().copied())
        .filter(|r| r.sample.load == 0.0)
        .collect();
    assert!(mounting(&AutoSettings::default(), &twin.nominal, &one_load, &work).is_none());
    let (upright, rows) = twin_rows("configs/twin/arm5.toml", 30);
    let rows: Vec<&Measurement> = rows.iter().collect();
    assert!(mounting(&AutoSettings::default(), &upright.nominal, &rows, &work).is_none());
}

/// ARM5's twin (40 configurations) calibrated by default with its gear harmonics left out
/// of the physics and `residual` the only residual model: the settings, the rows, the
/// result, and how many held-out rows the folds' deviations are computed on (every one of
/// the five random folds and five blocks, at most 150 a fold).
fn arm5_with_only(residual: ResidualSettings) -> (AutoSettings, Vec<Measurement>, Built, usize) {
    let (twin, owned) = twin_rows("configs/twin/arm5.toml", 40);
    let rows: Vec<&Measurement> = owned.iter().collect();
    let settings = AutoSettings {
        harmonics: 0,
        self_weight: false,
        backlash: false,
        outliers: None,
        residuals: vec![ResidualStage {
            settings: residual,
            holdout: 0.2,
        }],
        ..AutoSettings::default()
    };
    let built = automatic(&settings, &twin.nominal, &rows, None, &Silent).unwrap();
    let held: usize = (FoldPlan::new(&settings, &rows, None).unwrap().splits.iter())
        .map(|f| f.test.len().min(spread::ROWS_PER_FOLD))
        .sum();
    (settings, owned, built, held)
}

/// ARM5 with an error of no physical form added to every point (0.3 mm, smooth in the
/// joints, one axis's growing with the load): the chain keeps the compliances, the GP on
/// them beats them significantly, and it is scored again on the identified table alone, in
/// each frame. The winner is the lowest score among the residual candidates significantly
/// better than the physics, recomputed here from the candidates' table; the model fitted
/// again is that candidate's — on the table alone no compliances — and the decisions say
/// which physics the chain kept and the model left out.
#[test]
fn a_residual_model_is_scored_on_the_identified_table_alone_too() {
    let (twin, mut owned) = twin_rows("configs/twin/arm5.toml", 40);
    for m in &mut owned {
        let q: Vec<f64> = m.sample.joints.iter().map(|d| d.to_radians()).collect();
        m.position += 0.3
            * Vector3::new(
                (q[0] + 2.0 * q[1] + 0.3).sin(),
                (q[1] - q[2] + 1.0).cos(),
                (2.0 * q[2] + q[3]).sin() * (1.0 + m.sample.load),
            );
    }
    let rows: Vec<&Measurement> = owned.iter().collect();
    let mut gp = ResidualSettings::gp(3);
    gp.gp.iterations = 20;
    gp.gp.hyper_rows = 150;
    let settings = AutoSettings {
        harmonics: 0,
        self_weight: false,
        backlash: false,
        runout: 0,
        outliers: None,
        residuals: vec![ResidualStage {
            settings: gp,
            holdout: 0.2,
        }],
        ..AutoSettings::default()
    };
    let built = automatic(&settings, &twin.nominal, &rows, None, &Silent).unwrap();
    let selection = built.selection.as_ref().unwrap();
    let named = |name: &str| {
        (selection.candidates.iter())
            .find(|c| c.name == name)
            .unwrap_or_else(|| panic!("no candidate {name}: {:?}", selection.candidates))
    };
    let physics = named("kinematic + compliance");
    let on_chain = named("kinematic + compliance + gp");
    let world = named("kinematic + gp (world frame)");
    let joint1 = named("kinematic + gp (joint-1 frame)");
    let compliance = (selection.decisions.iter())
        .find(|d| d.stage == Stage::Compliance)
        .unwrap();
    assert!(physics.score.is_some() && world.score.is_some() && joint1.score.is_some());
    assert_eq!(on_chain.status, Status::Evaluated, "{on_chain:?}");
    // The lowest-scoring residual candidate (each one here lowers the physics' held-out
    // errors by far more than their spread).
    let lowest = [on_chain, world, joint1]
        .into_iter()
        .min_by(|a, b| a.score.unwrap().total_cmp(&b.score.unwrap()))
        .unwrap();
    assert!(lowest.score.unwrap() < 0.8 * physics.score.unwrap());
    assert_eq!(lowest.status, Status::Chosen);
    assert!(
        !std::ptr::eq(lowest, on_chain),
        "the GP on the compliances chosen: {:?}",
        selection.candidates
    );
    assert!(built.kinematic.compliance.is_none());
    assert!(built.residual.is_some());
    assert!(!compliance.kept, "{compliance:?}");
    assert!(
        compliance.reason.contains("kept by the chain"),
        "{compliance:?}"
    );
}

/// ARM5's gear harmonics left out of the physics: the GP takes them, and the chosen GP's
/// standard deviations carry the factor its folds found — in the report, in the model, and
/// in what it predicts (the same model at factor 1 gives deviations smaller by exactly it).
#[test]
fn the_chosen_gp_carries_the_factor_its_folds_found() {
    let mut gp = ResidualSettings::gp(3);
    gp.gp.iterations = 20;
    gp.gp.hyper_rows = 150;
    let (_, rows, built, held) = arm5_with_only(gp);
    let (model, report) = built.residual.as_ref().expect("the GP chosen");
    let spread = report.spread.expect("its deviations calibrated");
    assert_eq!(spread.rows, held);
    assert!((0.1..=100.0).contains(&spread.scale), "{spread:?}");
    assert_eq!(model.gp().unwrap().std_scale, spread.scale);
    let samples = robocal_residual::Samples::rows(
        (rows.iter().take(20))
            .map(|m| robocal_residual::inputs_of(&m.sample))
            .collect(),
    );
    let mut unscaled = model.clone();
    unscaled.set_std_scale(1.0);
    let (a, sa) = model.predict_with_std(&samples, true);
    let (b, sb) = unscaled.predict_with_std(&samples, true);
    assert_eq!(a, b);
    for (x, y) in sa.unwrap().iter().zip(sb.unwrap()) {
        for k in 0..3 {
            assert!((x[k] - spread.scale * y[k]).abs() <= 1e-12 * x[k].abs().max(1e-9));
        }
    }
}

/// ARM5's gear harmonics left out of the physics and a network as the only residual model:
/// the chosen network carries the spread its folds found beside the physics' deviation — in
/// the report, in the model, and in what it predicts (the physical model's own deviation
/// and that spread in quadrature, the points as the network's).
#[test]
fn the_chosen_network_carries_the_spread_its_folds_found() {
    let mut somm = ResidualSettings::robocal(ResidualKind::Somm, 3);
    for net in &mut somm.axes {
        net.max_epochs = 60;
    }
    let (_, rows, built, held) = arm5_with_only(somm);
    let (network, report) = built.residual.as_ref().expect("the network chosen");
    assert!(report.spread.is_none());
    let beside = report.spread_beside.expect("its spread estimated");
    assert_eq!(beside.rows, held);
    assert_eq!(network.spread_mm, Some(beside.spread));
    assert!(beside.spread > 0.0, "{beside:?}");
    assert!(
        beside.within_physics < beside.within_after && beside.within_after > 0.3,
        "{beside:?}"
    );
    let model = built.model();
    let physical = CalibratedModel {
        residual: None,
        ..model.clone()
    };
    let samples: Vec<&robocal_data::Sample> = rows.iter().take(20).map(|m| &m.sample).collect();
    let (points, sigmas) = model.predict_with_sigma(samples.iter().copied(), true);
    assert_eq!(points, model.predict(samples.iter().copied()));
    let own = physical.physics_sigmas(&samples).expect("a covariance");
    for (s, p) in sigmas.expect("a deviation").iter().zip(own) {
        assert!(
            (s * s - p * p - beside.spread * beside.spread).abs() < 1e-12,
            "{s} {p}"
        );
    }
}

/// A candidate's physics is a set of effects, each kind once: named in one order whatever the
/// order they were added in; united block by block at the higher order, the compliances the
/// first one's; without its joint-error terms, the table and its compliances.
#[test]
fn a_physics_is_a_set_of_effects_named_in_one_order() {
    let mixed = (Physics::RIGID)
        .with(Effect::Tilt)
        .with(Effect::FlankSearch)
        .with(Effect::Compliance)
        .with(Effect::Backlash)
        .with(Effect::Harmonics(2));
    assert_eq!(
        mixed.name(),
        "kinematic + compliance + harmonics 2 + backlash (flank search) + tilt"
    );
    assert_eq!(Physics::ALIGNED.name(), "nominal (base and tool fitted)");
    let elastic = Physics::RIGID.with(Effect::Compliance);
    let one = elastic.with(Effect::Harmonics(1)).with(Effect::Runout(2));
    let two = elastic.with(Effect::Harmonics(2)).with(Effect::SelfWeight);
    assert_eq!(
        one.union(two),
        (elastic)
            .with(Effect::Harmonics(2))
            .with(Effect::SelfWeight)
            .with(Effect::Runout(2))
    );
    assert_eq!(Physics::RIGID.union(two), two.without(Effect::Compliance));
    assert_eq!(
        mixed.without_joint_errors().name(),
        "kinematic + compliance"
    );
    assert!(!elastic.has_joint_errors() && one.has_joint_errors());
    assert_eq!((one.harmonics(), one.runout(), elastic.runout()), (1, 2, 0));
}
