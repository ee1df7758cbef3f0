//! A physical model's standard deviations (the identified parameters' covariance carried to the
//! predicted points): against the spread of the points over repeated identifications from
//! fresh noise, and against the covariance carried through the identification's own analytic
//! Jacobian.

use std::path::Path;

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use robocal_calibration::fit_kinematic;
use robocal_calibration::physical_model;
use robocal_data::{Measurement, Sample};
use robocal_ident::{
    CalibrationProblem, ComplianceSettings, JointErrorSettings, KinematicSettings, Observations,
};
use robocal_robot::Parameter;
use robocal_twin::TwinConfig;

/// ARM5's twin, `count` configurations, noise-free rows; geometry alone unless `errors`.
fn twin_rows(count: usize, errors: bool) -> (TwinConfig, Vec<Measurement>) {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    let mut twin = TwinConfig::load(root.join("configs/twin/arm5.toml")).unwrap();
    twin.poses.count = count;
    if !errors {
        (twin.compliance, twin.gear, twin.beyond) = (None, None, None);
        twin.backlash.clear();
    }
    let rows = twin.generate().unwrap().truth.rows;
    (twin, rows)
}

/// Every fifth configuration held out (all its loads).
fn split(rows: &[Measurement]) -> (Vec<&Measurement>, Vec<&Measurement>) {
    let mut poses: Vec<&str> = rows.iter().map(|m| m.sample.pose.as_str()).collect();
    poses.dedup();
    rows.iter().partition(|m| {
        let k = poses.iter().position(|p| *p == m.sample.pose).unwrap();
        k % 5 != 4
    })
}

/// Repeated identifications of the same configurations from fresh tracker noise: the spread of
/// the held-out points they predict is what the covariance says (the mean over the points of
/// each point's variance, the three axes together, within what 60 draws can tell: a relative
/// spread of about 18 %).
#[test]
fn deviations_match_the_spread_of_repeated_identifications() {
    let (twin, rows) = twin_rows(40, false);
    let (train, test) = split(&rows);
    let test: Vec<&Sample> = test.iter().map(|m| &m.sample).collect();
    let noise = Normal::new(0.0, 0.05).unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    let draws = 60;
    let mut points: Vec<Vec<nalgebra::Vector3<f64>>> = Vec::new();
    let mut predicted = vec![0.0; test.len()];
    for _ in 0..draws {
        let noisy: Vec<Measurement> = (train.iter())
            .map(|m| {
                let mut m = (*m).clone();
                m.position += nalgebra::Vector3::from_fn(|_, _| noise.sample(&mut rng));
                m
            })
            .collect();
        let noisy: Vec<&Measurement> = noisy.iter().collect();
        let fit = fit_kinematic(&twin.nominal, &noisy, &KinematicSettings::default()).unwrap();
        let model = physical_model(&fit);
        let (p, s) = model.predict_with_sigma(test.iter().copied(), true);
        for (v, s) in predicted.iter_mut().zip(s.expect("a covariance")) {
            *v += s * s / draws as f64;
        }
        points.push(p);
    }
    let empirical: Vec<f64> = (0..test.len())
        .map(|i| {
            let mean = points.iter().map(|p| p[i]).sum::<nalgebra::Vector3<f64>>() / draws as f64;
            (points.iter())
                .map(|p| (p[i] - mean).norm_squared())
                .sum::<f64>()
                / (draws - 1) as f64
        })
        .collect();
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
    let ratio = mean(&empirical) / mean(&predicted);
    assert!(
        (0.6..1.6).contains(&ratio),
        "spread of the points over the draws / the covariance's: {ratio} (empirical {}, predicted {} mm²)",
        mean(&empirical),
        mean(&predicted)
    );
}

/// With compliance and gear harmonics identified, the deviations the model computes by central
/// differences along the covariance's factors equal `√tr(J C Jᵀ)` with `J` the identification
/// problem's analytic Jacobian on the same poses (whose geometric columns leave out the torques'
/// second-order dependence on the geometry: equal to a part in a thousand), with what holding a
/// harmonic may miss added on the poses beyond its reach.
#[test]
fn deviations_are_the_covariance_through_the_analytic_jacobian() {
    let (twin, rows) = twin_rows(30, true);
    let (train, test) = split(&rows);
    let settings = KinematicSettings {
        compliance: Some(ComplianceSettings {
            gravity: twin.gravity,
            ..ComplianceSettings::default()
        }),
        joint_errors: Some(JointErrorSettings {
            harmonics: 1,
            gravity: twin.gravity,
            ..JointErrorSettings::default()
        }),
        ..KinematicSettings::default()
    };
    let fit = fit_kinematic(&twin.nominal, &train, &settings).unwrap();
    let model = physical_model(&fit);
    let cov = model.covariance.as_ref().expect("a covariance");
    let samples: Vec<&Sample> = test.iter().map(|m| &m.sample).collect();
    let sigmas = model.physics_sigmas(&samples).unwrap();

    // The problem on the held-out poses, its unknowns the covariance's parameters.
    let errors = model.joint_errors.clone().unwrap();
    let parameters = cov.resolve(&model.robot, Some(&errors)).unwrap();
    let ids = model.robot.param_ids();
    let (mut selected, mut params, mut order) = (Vec::new(), Vec::new(), Vec::new());
    for (i, p) in parameters.iter().enumerate() {
        if let Parameter::Table(id) = p {
            selected.push(ids.iter().position(|x| x == id).unwrap());
            order.push(i);
        }
    }
    for (i, p) in parameters.iter().enumerate() {
        if let Parameter::Error(e) = p {
            params.push(*e);
            order.push(i);
        }
    }
    assert!(!params.is_empty() && !selected.is_empty());
    let obs = Observations::from_rows(model.dof(), test.iter().copied());
    let problem =
        CalibrationProblem::new(&model.robot, selected, &obs).with_joint_errors(errors, params);
    let (_, jac) = problem.residuals_and_jacobian(&vec![0.0; problem.unknowns()]);
    let k = order.len();
    let c = nalgebra::DMatrix::from_fn(k, k, |a, b| cov.matrix[order[a]][order[b]]);
    // The Jacobian's columns are the scaled unknowns': back to internal units.
    let j = nalgebra::DMatrix::from_fn(jac.nrows(), k, |r, a| jac[(r, a)] / problem.scale()[a]);
    let jc = &j * &c;
    for (i, s) in sigmas.iter().enumerate() {
        let variance: f64 = (0..3)
            .map(|a| {
                (0..k)
                    .map(|b| jc[(3 * i + a, b)] * j[(3 * i + a, b)])
                    .sum::<f64>()
            })
            .sum();
        // Beyond a harmonic's reach, what holding it may miss on top (tested on its own in
        // robocal-model).
        let want = (variance + model.held_variance(samples[i])).sqrt();
        assert!(
            (s - want).abs() < 1e-3 * want,
            "pose {}: {s} mm by differences, {want} mm analytic",
            samples[i].pose
        );
    }
}
