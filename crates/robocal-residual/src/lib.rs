//! Residual learning (paper section III-B, V-B): what kinematic calibration leaves, learned as a
//! function of the joint angles and the load.
//!
//! - [`mlp`]: one burn MLP on the CPU `flex` backend, Adam, mini-batches, early stopping.
//! - [`model`]: SOMM (one network per world axis), MOSM (one three-output network) and CA-SOMM
//!   (a linfa decision tree picks one of two SOMM sets), standardised inputs and outputs, and the
//!   saved form (`residual.json` + one burn record per network).
//! - [`gp`]: a Gaussian process per axis (ARD squared-exponential kernel, marginal likelihood),
//!   with a predictive standard deviation.
//! - [`search`](mod@search): TPE hyper-parameter search (layers, neurons, activation, learning rate).

pub mod error;
pub mod gp;
pub mod mlp;
pub mod model;
pub mod search;
pub mod stage;

pub use error::{ResidualError, Result};
pub use gp::{GpAxis, GpSettings};
pub use mlp::{Activation, Dense, Mlp, NetSettings, Split, TrainReport, train};
pub use model::{
    AxisNet, Classifier, ClassifierSettings, Encoding, Gate, GpResidual, MANIFEST, PerClass,
    RESIDUAL_FORMAT, ResidualKind, ResidualModel, ResidualSettings, Samples, Standardizer,
    inputs_of, two_means_threshold,
};
pub use search::{SearchLog, SearchSettings, Trial, search};
pub use stage::{DEFAULT_SEED, RawResidualStage, ResidualStage};
