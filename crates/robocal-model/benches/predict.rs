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
    let samples = data
        .rows
        .iter()
        .take(1000)
        .map(|m| m.sample.clone())
        .collect();
    (model, samples)
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
