//! Identification benchmarks on the twin's 168 unloaded poses, all 34 parameters of the
//! PMC6VA030 table: the LM solve (target < 5 ms), the paper's BFGS (target < 50 ms), and the
//! whole kinematic calibration (registration, alignment, identifiability, solve, covariance);
//! and the default's fullest physical candidate on all 3528 rows of the bundled twin (every
//! load): compliances, harmonics to order 2, the links' weights and the payload's centre of
//! mass, backlash with its flank rounds (target: a fold's share of the 120 s budget), and its
//! flank search alone and after the fit without it (what the two share); and one
//! Jacobian of those rows with compliances, harmonics, the links' weights and axis runouts, the
//! solvers' first-order columns against the exact ones the covariance takes; and, on one core,
//! what a residual evaluation and a Jacobian compute per row of those rows with the fullest
//! candidate as fitted (its torque flanks, its links' weights, most held at zero), and with
//! the candidate with the self-weight terms (most of them held at zero too).

use divan::{Bencher, black_box};
use robocal_data::MeasurementSet;
use robocal_ident::{
    CalibrationProblem, ComplianceSettings, FitMemo, JointErrorSettings, KinematicSettings,
    LeastSquares, Observations, SolverKind, align, analyse, calibrate_kinematics,
    calibrate_kinematics_with, run_lm,
};
use robocal_robot::{DEG_PER_KNM, JointErrors, Robot, RowTerms};

fn main() {
    divan::main();
}

fn setup() -> (Robot, Observations) {
    let (robot, set) = bundled();
    let obs = Observations::from_rows(6, set.rows.iter().filter(|r| r.sample.load == 0.0));
    (robot, obs)
}

/// The nominal table and the bundled twin's measurements.
fn bundled() -> (Robot, MeasurementSet) {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    let robot = Robot::load(root.join("configs/robots/pmc6va030.toml")).expect("robot");
    let set =
        MeasurementSet::read(root.join("datasets/pmc6va030/measurements.csv"), 6).expect("data");
    (robot, set)
}

/// The identifiable subset at the aligned model: what the solvers run on.
fn prepared(robot: &Robot, obs: &Observations) -> (Robot, Vec<usize>) {
    let aligned = align(robot, obs).expect("align");
    let all: Vec<usize> = (0..aligned.param_count()).collect();
    let problem = CalibrationProblem::new(&aligned, all.clone(), obs);
    let (_, jac) = problem.residuals_and_jacobian(&vec![0.0; all.len()]);
    let ident = analyse(&jac, &aligned.param_ids(), 1e-6);
    (aligned, ident.identifiable)
}

#[divan::bench]
fn lm_solve_168_poses(b: Bencher) {
    let (robot, obs) = setup();
    let (aligned, kept) = prepared(&robot, &obs);
    b.bench_local(|| {
        let problem = CalibrationProblem::new(&aligned, kept.clone(), &obs);
        run_lm(LeastSquares(&problem), vec![0.0; kept.len()], 200).expect("lm")
    });
}

#[divan::bench]
fn bfgs_solve_168_poses(b: Bencher) {
    let (robot, obs) = setup();
    let (aligned, kept) = prepared(&robot, &obs);
    b.bench_local(|| {
        let problem = CalibrationProblem::new(&aligned, kept.clone(), &obs);
        robocal_ident::bfgs::run_bfgs(&problem, vec![0.0; kept.len()], 500).expect("bfgs")
    });
}

#[divan::bench(args = [SolverKind::Lm, SolverKind::Bfgs])]
fn whole_kinematic_calibration(b: Bencher, solver: SolverKind) {
    let (robot, obs) = setup();
    let settings = KinematicSettings {
        solver,
        max_iterations: 500,
        ..Default::default()
    };
    b.bench_local(|| {
        calibrate_kinematics(black_box(&robot), &obs, &settings).expect("calibration")
    });
}

#[divan::bench(sample_count = 3)]
fn full_physics_3528_rows(b: Bencher) {
    let (robot, set) = bundled();
    let obs = Observations::from_rows(6, set.rows.iter());
    let settings = full_physics_settings();
    b.bench_local(|| {
        calibrate_kinematics(black_box(&robot), &obs, &settings).expect("calibration")
    });
}

/// Compliances, harmonics to order 2, the links' weights and the payload's centre of mass,
/// backlash with its flank rounds: the default's fullest physical candidate.
fn full_physics_settings() -> KinematicSettings {
    KinematicSettings {
        compliance: Some(ComplianceSettings {
            plausible_only: true,
            identify_payload_com: true,
            ..ComplianceSettings::default()
        }),
        joint_errors: Some(JointErrorSettings {
            harmonics: 2,
            link_weights: true,
            backlash: true,
            ..JointErrorSettings::default()
        }),
        ..KinematicSettings::default()
    }
}

/// What the flank search's memo holds before it starts ([`flank_search_3528_rows`]).
#[derive(Debug, Clone, Copy)]
enum Memo {
    /// Nothing: the search alone.
    Empty,
    /// The fit without the search on the same rows, as the default calibration's folds hold it
    /// when the search candidate starts: the search takes its first fits from it.
    AfterRegression,
}

/// The flank search on the fullest physical candidate of [`full_physics_3528_rows`], with an
/// empty memo and after the fit without the search (the search's time in the default
/// calibration, where the first fit and the fit on the approach flanks are shared).
#[divan::bench(args = [Memo::Empty, Memo::AfterRegression], sample_count = 3)]
fn flank_search_3528_rows(b: Bencher, memo: Memo) {
    let (robot, set) = bundled();
    let obs = Observations::from_rows(6, set.rows.iter());
    let regression = full_physics_settings();
    let mut search = regression.clone();
    search
        .joint_errors
        .as_mut()
        .expect("joint errors")
        .flank_search = true;
    b.with_inputs(|| {
        let held = FitMemo::default();
        if let Memo::AfterRegression = memo {
            calibrate_kinematics_with(&robot, &obs, &regression, &held).expect("calibration");
        }
        held
    })
    .bench_local_values(|held| {
        calibrate_kinematics_with(black_box(&robot), &obs, &search, &held).expect("calibration")
    });
}

/// Which Jacobian [`jacobian_3528_rows`] evaluates.
#[derive(Debug, Clone, Copy)]
enum Columns {
    /// The solvers' (`residuals_and_jacobian`).
    FirstOrder,
    /// The covariance's (`exact_jacobian`).
    Exact,
}

#[divan::bench(args = [Columns::FirstOrder, Columns::Exact], sample_count = 10)]
fn jacobian_3528_rows(b: Bencher, columns: Columns) {
    let (robot, set) = bundled();
    let obs = Observations::from_rows(6, set.rows.iter());
    let aligned = align(&robot, &obs).expect("align");
    let values = [0.0, 0.076, 0.136, 0.38, 0.48, 0.57];
    let mut errors = JointErrors::new(
        values.iter().map(|c| c * DEG_PER_KNM).collect(),
        nalgebra::Vector3::new(0.0, 0.0, -9.80665),
        nalgebra::Vector3::new(100.0, 0.0, 60.0),
    )
    .with_harmonics(&[0, 1, 2, 3, 4, 5], 2)
    .with_link_weights(&[1, 2, 3, 4, 5])
    .with_runouts(&[0, 1, 2, 3, 4, 5], 2);
    for w in &mut errors.link_weights {
        w.value = 1.0;
    }
    for r in &mut errors.runouts {
        r.wave.sin = 1e-4;
    }
    let all: Vec<usize> = (0..aligned.param_count()).collect();
    let problem = CalibrationProblem::new(&aligned, all, &obs)
        .with_joint_errors(errors.clone(), errors.params());
    let u = vec![0.0; problem.unknowns()];
    b.bench_local(|| match columns {
        Columns::FirstOrder => problem.residuals_and_jacobian(black_box(&u)),
        Columns::Exact => problem.exact_jacobian(black_box(&u)),
    });
}

/// The fullest physical candidate fitted on every row of the bundled twin, once for the
/// per-row benches: its table, its joint errors (torque flanks, the links' weights, most of them
/// held at zero, harmonics) and the rows.
fn fitted() -> &'static (Robot, JointErrors, Observations) {
    static FITTED: std::sync::OnceLock<(Robot, JointErrors, Observations)> =
        std::sync::OnceLock::new();
    FITTED.get_or_init(|| fitted_on_every_row(&full_physics_settings()))
}

/// The fit with `settings` on every row of the bundled twin: its table, its joint errors and
/// the rows.
fn fitted_on_every_row(settings: &KinematicSettings) -> (Robot, JointErrors, Observations) {
    let (robot, set) = bundled();
    let obs = Observations::from_rows(6, set.rows.iter());
    let fit = calibrate_kinematics(&robot, &obs, settings).expect("fit");
    let errors = fit.compliance.expect("joint errors");
    (fit.robot, errors, obs)
}

/// Where a per-row bench's wave bases (the harmonics' sines and cosines) come from.
#[derive(Debug, Clone, Copy)]
enum Waves {
    /// Computed by the model at every row (`point`, `row_terms`).
    Computed,
    /// Computed once before, as a fit's problem does (`point_on_waves`; `write_row_terms` with
    /// them, the rows' terms in one buffer in turn, as a fit's Jacobian writes them).
    Given,
}

/// Every row's wave bases for the fitted model.
fn wave_bases() -> &'static Vec<Vec<(f64, f64)>> {
    static BASES: std::sync::OnceLock<Vec<Vec<(f64, f64)>>> = std::sync::OnceLock::new();
    BASES.get_or_init(|| {
        let (_, errors, obs) = fitted();
        (0..obs.len())
            .map(|i| errors.wave_bases(obs.joints(i)))
            .collect()
    })
}

/// What one residual evaluation computes per row, on one core: the fitted model's point for
/// every row of the bundled twin (its torques, flanks and deflection, then the chain).
#[divan::bench(args = [Waves::Computed, Waves::Given], sample_count = 30)]
fn point_3528_rows(b: Bencher, waves: Waves) {
    let (robot, errors, obs) = fitted();
    let bases = wave_bases();
    b.bench_local(|| {
        (0..obs.len())
            .map(|i| {
                let (q, load) = (obs.joints(i), obs.loads[i]);
                match waves {
                    Waves::Computed => errors.point(robot, q, load),
                    Waves::Given => errors.point_on_waves(robot, q, load, &bases[i]),
                }
            })
            .fold(nalgebra::Vector3::zeros(), |sum, p| sum + p)
    });
}

/// What one Jacobian computes per row before the chain's columns, on one core: the fitted
/// model's deflection, and the basis and turns of the coefficients it identified (those not
/// held at zero), for every row.
#[divan::bench(args = [Waves::Computed, Waves::Given], sample_count = 30)]
fn row_terms_3528_rows(b: Bencher, waves: Waves) {
    let (robot, errors, obs) = fitted();
    let bases = wave_bases();
    let params: Vec<_> = (errors.params().into_iter())
        .filter(|p| errors.param(*p) != 0.0)
        .collect();
    b.bench_local(|| {
        let mut row = RowTerms::default();
        (0..obs.len())
            .map(|i| {
                let (q, load) = (obs.joints(i), obs.loads[i]);
                match waves {
                    Waves::Computed => errors.row_terms(robot, q, load, &params).basis.len(),
                    Waves::Given => {
                        let waves = Some(bases[i].as_slice());
                        errors.write_row_terms(robot, q, load, &params, waves, &mut row);
                        row.basis.len()
                    }
                }
            })
            .sum::<usize>()
    });
}

/// Compliances, harmonics to order 2 and the self-weight terms fitted on every row of the
/// bundled twin, once for [`self_weight_rows_3528`]: the default's candidate with the
/// self-weight, whose fit holds most of its 84 terms at zero (the poses tell few of the links'
/// masses and moments from the geometry).
fn fitted_self_weight() -> &'static (Robot, JointErrors, Observations) {
    static FITTED: std::sync::OnceLock<(Robot, JointErrors, Observations)> =
        std::sync::OnceLock::new();
    FITTED.get_or_init(|| {
        fitted_on_every_row(&KinematicSettings {
            compliance: Some(ComplianceSettings::default()),
            joint_errors: Some(JointErrorSettings {
                harmonics: 2,
                self_weight: true,
                ..JointErrorSettings::default()
            }),
            ..KinematicSettings::default()
        })
    })
}

/// What a row computes per evaluation, on one core.
#[derive(Debug, Clone, Copy)]
enum PerRow {
    /// A residual evaluation's: the point (torques, deflection, chain).
    Point,
    /// A Jacobian's before the chain's columns: the deflection and the basis of the
    /// coefficients the fit identified (those not held at zero).
    Terms,
}

/// [`point_3528_rows`] and [`row_terms_3528_rows`] (waves computed) with the self-weight model
/// of [`fitted_self_weight`]: a term held at zero should cost nothing.
#[divan::bench(args = [PerRow::Point, PerRow::Terms], sample_count = 30)]
fn self_weight_rows_3528(b: Bencher, per_row: PerRow) {
    let (robot, errors, obs) = fitted_self_weight();
    let params: Vec<_> = (errors.params().into_iter())
        .filter(|p| errors.param(*p) != 0.0)
        .collect();
    let zero = (errors.self_weight.iter())
        .filter(|t| t.value == 0.0)
        .count();
    assert!(
        2 * zero > errors.self_weight.len(),
        "most terms held at zero"
    );
    b.bench_local(|| {
        (0..obs.len())
            .map(|i| {
                let (q, load) = (obs.joints(i), obs.loads[i]);
                match per_row {
                    PerRow::Point => errors.point(robot, q, load).x,
                    PerRow::Terms => {
                        let row = errors.row_terms(robot, q, load, &params);
                        row.deflected[0] + row.basis.len() as f64
                    }
                }
            })
            .sum::<f64>()
    });
}
