//! Predicting a file of poses with a physical model of the paper's arm (compliance and two
//! transmission harmonics per joint identified on its twin's 168 configurations at every
//! load): the points alone, and the points with their standard deviations from the identified
//! parameters' covariance (a central difference per direction of the covariance, two
//! predictions each).

use divan::{Bencher, black_box};
use robocal_data::Sample;
use robocal_ident::{
    ComplianceSettings, JointErrorSettings, KinematicSettings, Observations, calibrate_kinematics,
};
use robocal_model::CalibratedModel;
use robocal_twin::TwinConfig;

fn main() {
    divan::main();
}

/// The identified model and 1000 of the twin's rows to predict.
fn setup() -> (CalibratedModel, Vec<Sample>) {
    let (model, rows) = fitted();
    (model, rows.into_iter().map(|m| m.sample).collect())
}

/// The identified model and 1000 of the twin's measurements.
fn fitted() -> (CalibratedModel, Vec<robocal_data::Measurement>) {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    let twin = TwinConfig::load(root.join("configs/twin/pmc6va030.toml")).expect("twin");
    let data = twin.generate().expect("data").measurements;
    let settings = KinematicSettings {
        compliance: Some(ComplianceSettings {
            gravity: twin.gravity,
            ..ComplianceSettings::default()
        }),
        joint_errors: Some(JointErrorSettings {
            harmonics: 2,
            gravity: twin.gravity,
            ..JointErrorSettings::default()
        }),
        ..KinematicSettings::default()
    };
    let obs = Observations::from_set(&data);
    let fit = calibrate_kinematics(&twin.nominal, &obs, &settings).expect("fit");
    let model = CalibratedModel {
        covariance: fit.covariance,
        ..CalibratedModel::new(fit.robot, fit.compliance, None)
    };
    (model, data.rows.into_iter().take(1000).collect())
}

#[divan::bench(sample_count = 10)]
fn predict_1000_samples(b: Bencher) {
    let (model, samples) = setup();
    b.bench(|| black_box(model.predict_with_sigma(&samples, false)));
}

#[divan::bench(sample_count = 10)]
fn predict_1000_samples_with_sigma(b: Bencher) {
    let (model, samples) = setup();
    println!(
        "{} parameters in the covariance",
        model.covariance.as_ref().map_or(0, |c| c.parameters.len())
    );
    b.bench(|| black_box(model.predict_with_sigma(&samples, true)));
}

/// The same model with a GP residual (on what the physics leaves on 1000 rows), its domain the
/// rows with joint 1 below its median: the standard deviations of 1000 rows, about half of
/// them outside the domain, where the physics' growth is computed (two more physical
/// deviations per such row), against the same rows with the domain taken as all of them.
fn with_gp() -> (CalibratedModel, Vec<Sample>, robocal_model::Domain) {
    use robocal_residual::{ResidualModel, ResidualSettings, Samples};
    let (physical, measured) = fitted();
    let samples: Vec<Sample> = measured.iter().map(|m| m.sample.clone()).collect();
    let set = Samples {
        inputs: samples.iter().map(robocal_residual::inputs_of).collect(),
        errors: physical
            .residuals(&measured)
            .into_iter()
            .map(Into::into)
            .collect(),
        physics: Vec::new(),
    };
    let mut settings = ResidualSettings::gp(7);
    settings.gp.iterations = 20;
    let residual = ResidualModel::fit(&settings, &set, &Samples::default(), &robocal_data::Silent)
        .expect("GP");
    let mut q1: Vec<f64> = samples.iter().map(|s| s.joints[0]).collect();
    q1.sort_by(f64::total_cmp);
    let median = q1[q1.len() / 2];
    let narrow =
        robocal_model::Domain::of(samples.iter().filter(|s| s.joints[0] <= median)).expect("rows");
    let model = CalibratedModel {
        residual: Some(residual),
        domain: Some(narrow),
        ..physical
    };
    let all = robocal_model::Domain::of(&samples).expect("rows");
    (model, samples, all)
}

#[divan::bench(sample_count = 10)]
fn gp_sigma_1000_samples_half_outside_the_domain(b: Bencher) {
    let (model, samples, _) = with_gp();
    b.bench(|| black_box(model.predict_with_sigma(&samples, true)));
}

#[divan::bench(sample_count = 10)]
fn gp_sigma_1000_samples_inside_the_domain(b: Bencher) {
    let (mut model, samples, all) = with_gp();
    model.domain = Some(all);
    b.bench(|| black_box(model.predict_with_sigma(&samples, true)));
}

/// The same GP read in the frame turning with joint 1 (its predictions turned by joint 1's
/// reading, one turn per row) against the world frame: what the turn costs on 1000 rows.
#[divan::bench(args = ["world", "joint1"], sample_count = 10)]
fn gp_1000_samples_by_frame(b: Bencher, frame: &str) {
    let (mut model, samples, all) = with_gp();
    model.domain = Some(all);
    if let Some(r) = model.residual.as_mut() {
        r.frame = robocal_residual::Frame::parse(frame).expect("frame");
    }
    b.bench(|| black_box(model.predict_with_sigma(&samples, false)));
}
