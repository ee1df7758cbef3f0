//! Hyper-parameter search with the Tree-structured Parzen Estimator (the paper used Hyperopt's
//! TPE, section V-B): layer count, neurons per layer, activation and learning rate of a network,
//! scored by its best validation loss. Seeded, bounded in trials, run only when a stage config
//! asks for it.

use robocal_data::Invalid;
use serde::{Deserialize, Serialize};
use tpe::{TpeOptimizer, categorical_range, histogram_estimator, parzen_estimator, range};

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

use crate::mlp::{Activation, NetSettings};

fn default_layers() -> [usize; 2] {
    [1, 6]
}
fn default_neurons() -> [usize; 2] {
    [5, 100]
}
fn default_rate() -> [f64; 2] {
    [1e-4, 1e-2]
}

/// What a search may try (`[residual.search]`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SearchSettings {
    /// Networks trained per searched network.
    pub trials: usize,
    /// Hidden layers, inclusive range.
    #[serde(default = "default_layers")]
    pub layers: [usize; 2],
    /// Neurons per hidden layer (every layer the same), inclusive range.
    #[serde(default = "default_neurons")]
    pub neurons: [usize; 2],
    /// Adam learning rate range, searched on a log scale.
    #[serde(default = "default_rate")]
    pub learning_rate: [f64; 2],
}

impl SearchSettings {
    /// Checks the ranges: the first bad one as (field, message).
    pub fn check(&self) -> Result<(), Invalid> {
        if self.trials == 0 {
            return Err(Invalid::new("trials", "must be at least 1"));
        }
        if self.layers[0] == 0 || self.layers[0] > self.layers[1] {
            return Err(Invalid::new("layers", "needs 1 <= low <= high"));
        }
        if self.neurons[0] == 0 || self.neurons[0] > self.neurons[1] {
            return Err(Invalid::new("neurons", "needs 1 <= low <= high"));
        }
        let [lo, hi] = self.learning_rate;
        if !(lo.is_finite() && hi.is_finite() && lo > 0.0 && lo < hi) {
            return Err(Invalid::new("learning_rate", "needs 0 < low < high"));
        }
        Ok(())
    }
}

/// One trial: the settings tried and the best validation loss they reached.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Trial {
    /// Hidden layer sizes.
    pub hidden: Vec<usize>,
    /// Activation.
    pub activation: Activation,
    /// Learning rate.
    pub learning_rate: f64,
    /// Lowest validation loss over the epochs (standardised MSE).
    pub validation_loss: f64,
}

/// The search of one network: every trial, and the index of the best.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SearchLog {
    /// Which world axes the network predicts (0 = X).
    pub axes: Vec<usize>,
    /// Trials in order.
    pub trials: Vec<Trial>,
    /// Index of the best trial.
    pub best: usize,
}

/// Runs a TPE search around `base` (batch size, epochs and patience are kept); `score` trains a
/// network with the given settings and returns its best validation loss. Returns the best
/// settings and the log.
pub fn search(
    base: &NetSettings,
    s: &SearchSettings,
    axes: Vec<usize>,
    seed: u64,
    mut score: impl FnMut(&NetSettings) -> f64,
) -> (NetSettings, SearchLog) {
    let span = |lo: f64, hi: f64| range(lo, hi).expect("checked range");
    let mut layers = TpeOptimizer::new(
        parzen_estimator(),
        span(s.layers[0] as f64, s.layers[1] as f64 + 1.0),
    );
    let mut neurons = TpeOptimizer::new(
        parzen_estimator(),
        span(s.neurons[0] as f64, s.neurons[1] as f64 + 1.0),
    );
    let mut activation = TpeOptimizer::new(
        histogram_estimator(),
        categorical_range(2).expect("two choices"),
    );
    let mut rate = TpeOptimizer::new(
        parzen_estimator(),
        span(s.learning_rate[0].ln(), s.learning_rate[1].ln()),
    );
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut log = SearchLog {
        axes,
        trials: Vec::new(),
        best: 0,
    };
    let mut best = base.clone();
    for _ in 0..s.trials {
        let (l, n, a, r) = (
            layers.ask(&mut rng).unwrap_or(s.layers[0] as f64),
            neurons.ask(&mut rng).unwrap_or(s.neurons[0] as f64),
            activation.ask(&mut rng).unwrap_or(0.0),
            rate.ask(&mut rng).unwrap_or(s.learning_rate[0].ln()),
        );
        let count = (l.floor() as usize).clamp(s.layers[0], s.layers[1]);
        let width = (n.floor() as usize).clamp(s.neurons[0], s.neurons[1]);
        let settings = NetSettings {
            hidden: vec![width; count],
            activation: if a < 1.0 {
                Activation::Tanh
            } else {
                Activation::Relu
            },
            learning_rate: r.exp(),
            ..base.clone()
        };
        let loss = score(&settings);
        // A diverged trial scores as very bad rather than poisoning the estimators with NaN.
        let told = if loss.is_finite() { loss } else { f64::MAX };
        let _ = layers.tell(l, told);
        let _ = neurons.tell(n, told);
        let _ = activation.tell(a, told);
        let _ = rate.tell(r, told);
        if log.trials.is_empty() || told < log.trials[log.best].validation_loss {
            log.best = log.trials.len();
            best = settings.clone();
        }
        log.trials.push(Trial {
            hidden: settings.hidden,
            activation: settings.activation,
            learning_rate: settings.learning_rate,
            validation_loss: told,
        });
    }
    (best, log)
}
