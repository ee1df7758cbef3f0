//! The rows of points beyond the main one (other reflectors on the flange), each point's weighed
//! by its own residual spread, and used only where folds scored on the main point's held-out
//! positions do not say they harm it.

use std::collections::{BTreeMap, HashMap};

use robocal_data::{Measurement, Observer};
use robocal_ident::KinematicSettings;
use robocal_robot::Robot;

use super::plan::FoldPlan;
use super::selection::Decision;
use super::settings::AutoSettings;
use super::status::Stage;
use crate::error::Result;
use crate::fit::{fit_kinematic, physical_model};
use crate::folds::{configuration_of, improves};

/// How the calibration uses the rows of the points beyond the main one.
#[derive(Debug, Clone, PartialEq)]
pub(crate) enum Extra {
    /// Every row, each point's weighed by its spread.
    Weighed {
        /// Weight of each point's rows on their squared errors (the main point's 1).
        targets: Vec<(String, f64)>,
    },
    /// The main point's rows alone.
    MainOnly,
}

/// The point the calibration serves: the default point where any row measures it, else the
/// point most rows measure (the first name of those alike).
pub(crate) fn main_target(rows: &[&Measurement]) -> String {
    let mut count: BTreeMap<&str, usize> = BTreeMap::new();
    for r in rows {
        *count.entry(r.sample.target.as_str()).or_default() += 1;
    }
    if count.contains_key("") {
        return String::new();
    }
    let most = count.values().copied().max().unwrap_or(0);
    (count.into_iter())
        .find(|(_, c)| *c == most)
        .map_or(String::new(), |(t, _)| t.to_string())
}

/// Whether the rows measure points beyond the main one.
fn has_extra(rows: &[&Measurement], main: &str) -> bool {
    rows.iter().any(|r| r.sample.target != main)
}

/// The main point's rows.
pub(crate) fn main_rows<'a>(rows: &[&'a Measurement], main: &str) -> Vec<&'a Measurement> {
    (rows.iter().copied())
        .filter(|r| r.sample.target == main)
        .collect()
}

/// Rounds of the weights' search at most.
const WEIGHT_ROUNDS: usize = 6;

/// The weights of [`Extra::Weighed`]: each point's rows weigh `(s₀ / sₜ)²`, `sₜ` the root mean
/// square of a coordinate of the point's position errors and `s₀` the main point's, as the
/// table fitted with those weights leaves them (from every row weighing 1, refitted until no
/// weight changes by more than 5 %).
fn spread_weights(
    nominal: &Robot,
    rows: &[&Measurement],
    main: &str,
    settings: &KinematicSettings,
) -> Result<Extra> {
    let mut targets: Vec<(String, f64)> = Vec::new();
    for _ in 0..WEIGHT_ROUNDS {
        let weighed = KinematicSettings {
            target_weights: targets.clone(),
            ..settings.clone()
        };
        let model = physical_model(&fit_kinematic(nominal, rows, &weighed)?);
        let mut squares: BTreeMap<&str, (f64, usize)> = BTreeMap::new();
        for (r, e) in rows.iter().zip(model.residuals(rows.iter().copied())) {
            let s = squares.entry(r.sample.target.as_str()).or_default();
            s.0 += e.norm_squared() / 3.0;
            s.1 += 1;
        }
        let rms = |(sum, n): (f64, usize)| (sum / n.max(1) as f64).sqrt();
        let s0 = squares.get(main).map_or(0.0, |s| rms(*s));
        let next: Vec<(String, f64)> = (squares.iter())
            .filter(|(t, _)| **t != main)
            .map(|(t, s)| {
                let st = rms(*s);
                let w = if st > 0.0 { (s0 / st).powi(2) } else { 1.0 };
                (t.to_string(), w)
            })
            .collect();
        let settled = next.len() == targets.len()
            && (next.iter().zip(&targets)).all(|((_, a), (_, b))| (a / b - 1.0).abs() < 0.05);
        targets = next;
        if settled {
            break;
        }
    }
    Ok(Extra::Weighed { targets })
}

/// The kinematic settings of `extra` over `base`.
fn settings_of(extra: &Extra, base: &KinematicSettings) -> KinematicSettings {
    match extra {
        Extra::Weighed { targets } => KinematicSettings {
            target_weights: targets.clone(),
            ..base.clone()
        },
        Extra::MainOnly => base.clone(),
    }
}

/// What the folds say of the other points' rows: on every fold, the table fitted on the main
/// point's rows alone against the table fitted on every row with the weights of their spreads
/// (found on the fold's training rows), both scored on the fold's held-out rows of the main
/// point; the extra rows are left out where the main point's positions alone lower those
/// errors significantly, and used otherwise. `None` where
/// the rows measure no point beyond the main one.
pub(crate) fn decide(
    settings: &AutoSettings,
    nominal: &Robot,
    rows: &[&Measurement],
    validation: Option<&(&[&Measurement], String)>,
    observer: &dyn Observer,
) -> Result<Option<(Decision, Extra)>> {
    let main = main_target(rows);
    if !has_extra(rows, &main) {
        return Ok(None);
    }
    let Some(plan) = FoldPlan::new(settings, rows, validation) else {
        return Ok(None);
    };
    let base = KinematicSettings {
        angle_weight: settings.angle_weight,
        ..KinematicSettings::default()
    };
    let (mut alone, mut with, mut tested) = (Vec::new(), Vec::new(), Vec::new());
    for fold in &plan.splits {
        let test: Vec<&Measurement> = (fold.test.iter().copied())
            .filter(|r| r.sample.target == main)
            .collect();
        if test.is_empty() {
            continue;
        }
        let own = main_rows(&fold.train, &main);
        let table = physical_model(&fit_kinematic(nominal, &own, &base)?);
        alone.extend(table.errors(&test));
        let extra = spread_weights(nominal, &fold.train, &main, &base)?;
        let fit = fit_kinematic(nominal, &fold.train, &settings_of(&extra, &base))?;
        with.extend(physical_model(&fit).errors(&test));
        tested.extend(test.iter().map(|r| (*r, fold.blocked)));
    }
    // One group per configuration and kind of fold, as the chain's paired test.
    let rows_tested: Vec<&Measurement> = tested.iter().map(|(r, _)| *r).collect();
    let of = configuration_of(&rows_tested);
    let mut ids: HashMap<(&str, bool), usize> = HashMap::new();
    let groups: Vec<usize> = (tested.iter())
        .map(|(r, blocked)| {
            let id = of.get(r.sample.pose.as_str()).copied().unwrap_or("");
            let next = ids.len();
            *ids.entry((id, *blocked)).or_insert(next)
        })
        .collect();
    // The other points' rows carry what the main point's lack: they are left out only where
    // the main point's rows alone do significantly better.
    let kept = !improves(&with, &alone, &groups);
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len().max(1) as f64;
    let choice = if kept {
        spread_weights(nominal, rows, &main, &base)?
    } else {
        Extra::MainOnly
    };
    let (w, x) = (mean(&alone), mean(&with));
    let mut d = Decision::said(
        Stage::ExtraPoints,
        kept,
        Some(w),
        Some(x),
        format!(
            "{}: held-out error of the main point {w:.4} mm from its rows alone, {x:.4} mm with every point's, each point's weighed by its own spread{}",
            if kept { "kept" } else { "dropped" },
            if kept {
                " (alone not lower by twice its standard error)"
            } else {
                " (alone lower by more than twice its standard error)"
            }
        ),
    );
    match &choice {
        Extra::Weighed { targets } => {
            let parts: Vec<String> = (targets.iter())
                .map(|(t, w)| format!("`{t}` × {w:.3}"))
                .collect();
            d.reason += &format!("; weights {}", parts.join(", "));
        }
        Extra::MainOnly => d.reason += "; the main point's rows alone are used",
    }
    observer.message(&format!("stage {}: {}", d.stage, d.reason));
    Ok(Some((d, choice)))
}

/// `settings` with `extra`'s weights for every fit of the chain.
pub(crate) fn weighed(settings: &AutoSettings, extra: &Extra) -> AutoSettings {
    match extra {
        Extra::Weighed { targets } => AutoSettings {
            target_weights: targets.clone(),
            ..settings.clone()
        },
        Extra::MainOnly => settings.clone(),
    }
}

#[cfg(test)]
mod tests {
    use std::path::Path;

    use nalgebra::Vector3;
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;
    use robocal_data::{Sample, Silent};
    use robocal_model::CalibratedModel;

    use super::*;

    /// ARM5 with a second reflector `smr2` on its flange, measured at `count` poses: the main
    /// point with ±0.01 mm of uniform noise, `smr2` with ±`noise` mm, and `smr2`'s rows from
    /// an arm whose joint-2 zero is `skew` degrees off the main point's (a reflector the table
    /// cannot serve together with the main one).
    fn two_points(noise: f64, skew: f64, count: usize) -> (Robot, Vec<Measurement>) {
        let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
        let mut nominal = Robot::load(root.join("configs/robots/arm5.toml")).unwrap();
        nominal.points = vec![("smr2".into(), Vector3::new(60.0, 0.0, 40.0))];
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        let mut truth = nominal.clone();
        for j in &mut truth.joints {
            j.a += rng.random_range(-1.0..1.0);
            j.theta += rng.random_range(-0.03f64..0.03).to_radians();
        }
        let mut skewed = truth.clone();
        skewed.joints[1].theta += skew.to_radians();
        let mut rows = Vec::new();
        for i in 0..count {
            let joints: Vec<f64> = (0..5).map(|_| rng.random_range(-90.0..90.0)).collect();
            for (target, arm, spread) in [("", &truth, 0.01), ("smr2", &skewed, noise)] {
                let sample = Sample {
                    pose: format!("p{i:03}"),
                    joints: joints.clone(),
                    load: 0.0,
                    line: 0,
                    target: target.into(),
                    seq: None,
                    last_move: Vec::new(),
                };
                let p = CalibratedModel::kinematic(arm.clone()).predict([&sample])[0];
                rows.push(Measurement {
                    position: p + Vector3::from_fn(|_, _| rng.random_range(-spread..spread)),
                    sample,
                    orientation: None,
                });
            }
        }
        (nominal, rows)
    }

    /// A reflector measured 30 times noisier than the main point weighs by the ratio of the
    /// two noises' variances (uniform ±0.01 and ±0.3 mm: 1/900), to the spread of the noise
    /// drawn.
    #[test]
    fn each_point_weighs_by_its_own_spread() {
        let (nominal, rows) = two_points(0.3, 0.0, 80);
        let rows: Vec<&Measurement> = rows.iter().collect();
        assert_eq!(main_target(&rows), "");
        let Extra::Weighed { targets } =
            spread_weights(&nominal, &rows, "", &KinematicSettings::default()).unwrap()
        else {
            panic!("weights");
        };
        assert_eq!(targets.len(), 1);
        let (name, w) = &targets[0];
        assert_eq!(name, "smr2");
        assert!((w * 900.0 - 1.0).abs() < 0.3, "{w}");
    }

    /// The folds keep a noisy reflector's rows, weighed down, and leave out those of a reflector
    /// the table cannot serve with the main point; the main point's rows alone are then what
    /// every candidate is fitted on.
    #[test]
    fn another_point_is_left_out_only_where_it_harms_the_main_one() {
        let settings = AutoSettings::table_only();
        for (skew, kept) in [(0.0, true), (0.05, false)] {
            let (nominal, rows) = two_points(0.05, skew, 60);
            let rows: Vec<&Measurement> = rows.iter().collect();
            let (d, extra) = decide(&settings, &nominal, &rows, None, &Silent)
                .unwrap()
                .unwrap();
            assert_eq!(d.kept, kept, "{}", d.reason);
            assert_eq!(matches!(extra, Extra::MainOnly), !kept);
            let built = super::super::automatic(&settings, &nominal, &rows, None, &Silent).unwrap();
            let decisions = &built.selection.as_ref().unwrap().decisions;
            assert_eq!(decisions[0].stage, Stage::ExtraPoints);
            assert_eq!(decisions[0].kept, kept);
        }
    }
}
