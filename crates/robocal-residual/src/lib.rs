//! Residual learning (paper section III-B, V-B): what kinematic calibration leaves, learned as a
//! function of the joint angles and the load.
//!
//! - [`model`]: [`ResidualModel`], training and prediction on raw input rows; [`residual`]:
//!   the [`Residual`] trait every kind implements; [`persist`]: its saved form
//!   (`residual.json` and one burn record per network).
//! - The kinds, one module each: [`somm`] (one network per world axis), [`mosm`] (one
//!   three-output network), [`casomm`] (a linfa decision tree, [`classifier`], picks one of two
//!   SOMM sets), [`gp`] (a Gaussian process per axis, ARD squared-exponential kernel, marginal
//!   likelihood, with a predictive standard deviation).
//! - [`settings`]: which kind and its settings; [`stage`]: the `[residual]` table of a stage
//!   file.
//! - [`samples`]: samples, input encoding, standardisation; [`net`]: one network with its
//!   scaling; [`mlp`]: one burn MLP on the CPU `flex` backend, Adam, mini-batches, early
//!   stopping; [`search`](mod@search): TPE hyper-parameter search.
//!
//! A Gaussian process learns what a kinematic model left (mm, world X, Y, Z) as a function of
//! the joint readings (deg) and the load (kg), and predicts it between the readings it saw:
//!
//! ```
//! use robocal_data::Silent;
//! use robocal_residual::{ResidualModel, ResidualSettings, Samples};
//!
//! // 60 readings of a two-joint arm at no load; the error left: a wave of joint 1 along X.
//! let row = |i: usize| vec![-90.0 + 3.0 * i as f64, 20.0 + (i % 7) as f64, 0.0];
//! let error = |r: &[f64]| [0.05 * r[0].to_radians().sin(), 0.0, 0.0];
//! let inputs: Vec<Vec<f64>> = (0..60).map(row).collect();
//! let errors = inputs.iter().map(|r| error(r)).collect();
//! let train = Samples::new(inputs, errors);
//! let model = ResidualModel::fit(&ResidualSettings::gp(7), &train, &Samples::rows(vec![]), &Silent)?;
//! let between = vec![-1.5, 23.0, 0.0];
//! let predicted = model.predict(&Samples::rows(vec![between.clone()]))[0];
//! assert!((predicted[0] - error(&between)[0]).abs() < 0.005, "{predicted:?}");
//! # Ok::<(), robocal_residual::ResidualError>(())
//! ```

pub mod casomm;
pub mod classifier;
pub mod error;
pub mod gp;
pub mod mlp;
pub mod model;
pub mod mosm;
pub mod net;
pub mod persist;
pub mod residual;
pub mod samples;
pub mod search;
pub mod settings;
pub mod somm;
pub mod stage;

pub use casomm::CaSomm;
pub use classifier::{
    Axis, ClassRule, Classifier, ClassifierSettings, Gate, GateInputs, GatePhysics,
    PHYSICS_PER_JOINT, PerClass, gate_feature_names, gate_rows, two_means_threshold,
};
pub use error::{ResidualError, Result};
pub use gp::{GpAxis, GpOptimizer, GpResidual, GpSettings};
pub use mlp::{Activation, Dense, Mlp, NetSettings, Schedule, Split, TrainReport, train};
pub use model::{Fitted, GateDecision, ResidualModel};
pub use mosm::Mosm;
pub use net::AxisNet;
pub use persist::{MANIFEST, MAX_INPUTS, RESIDUAL_FORMAT};
pub use residual::Residual;
pub use samples::{Encoding, Frame, Samples, Standardizer, inputs_of};
pub use search::{SearchLog, SearchSettings, Trial, search};
pub use settings::{ResidualKind, ResidualSettings};
pub use somm::Somm;
pub use stage::{DEFAULT_SEED, Defaults, RawResidualStage, ResidualStage};
