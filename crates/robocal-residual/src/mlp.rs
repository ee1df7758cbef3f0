//! One multilayer perceptron (burn, CPU `flex` backend) and its training loop: Adam on the
//! mean squared error, shuffled mini-batches, early stopping on the validation loss with the best
//! epoch's weights kept.

use burn::nn::{Linear, LinearConfig};
use burn::optim::decay::WeightDecayConfig;
use burn::optim::{AdamConfig, GradientsParams};
use burn::prelude::*;
use burn::tensor::TensorData;
use burn::tensor::activation::{relu, tanh};
use rand::SeedableRng;
use rand::seq::SliceRandom;
use rand_chacha::ChaCha8Rng;
use robocal_data::Invalid;
use robocal_data::Observer;
use serde::{Deserialize, Serialize};
use std::sync::{Mutex, PoisonError};

/// The activation between hidden layers (the output layer is linear).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Activation {
    /// Hyperbolic tangent.
    Tanh,
    /// Rectified linear unit.
    Relu,
}

fn default_batch() -> usize {
    200
}
fn default_epochs() -> usize {
    200
}
fn default_patience() -> usize {
    5
}
fn is_zero(v: &f64) -> bool {
    *v == 0.0
}

/// How the learning rate changes during training.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Schedule {
    /// The same rate throughout (the paper).
    #[default]
    Constant,
    /// Halved whenever the validation loss has not improved for a quarter of the patience (at
    /// least 3 epochs), down to 1/64 of the start: large steps first, then the fine ones a
    /// smooth residual needs.
    Plateau,
}

impl Schedule {
    /// Whether this is [`Schedule::Constant`] (the default, left out of saved files).
    pub fn is_constant(&self) -> bool {
        *self == Self::Constant
    }
}

/// Architecture and training settings of one network (paper Tables 2 and 3).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct NetSettings {
    /// Neurons of each hidden layer.
    pub hidden: Vec<usize>,
    /// Activation of the hidden layers.
    pub activation: Activation,
    /// Adam learning rate.
    pub learning_rate: f64,
    /// Samples per mini-batch.
    #[serde(default = "default_batch")]
    pub batch_size: usize,
    /// Most epochs.
    #[serde(default = "default_epochs")]
    pub max_epochs: usize,
    /// Stop when the validation loss has not improved for this many epochs.
    #[serde(default = "default_patience")]
    pub patience: usize,
    /// L2 penalty on the weights (Adam's coupled weight decay); 0: none (the paper).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub weight_decay: f64,
    /// How the learning rate changes.
    #[serde(default, skip_serializing_if = "Schedule::is_constant")]
    pub schedule: Schedule,
    /// Train for about this many mini-batch steps: the epochs are sized to the data
    /// (`steps / batches per epoch`, at most `max_epochs`); absent: `max_epochs` alone.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub steps: Option<usize>,
}

/// Most hidden layers a network may have (the paper's deepest has six).
pub const MAX_LAYERS: usize = 32;
/// Most neurons in one hidden layer: a bound that keeps a mistyped size (or a tampered model
/// file) from asking for gigabytes before anything is trained or read.
pub const MAX_WIDTH: usize = 4096;

impl NetSettings {
    /// The paper's X-axis network: 20-20-20-20-10-20 tanh, Adam 8e-4.
    pub fn paper_x() -> Self {
        Self::paper(vec![20, 20, 20, 20, 10, 20], Activation::Tanh, 8e-4)
    }
    /// The paper's Y-axis network: 100-50 ReLU, Adam 5e-4.
    pub fn paper_y() -> Self {
        Self::paper(vec![100, 50], Activation::Relu, 5e-4)
    }
    /// The paper's Z-axis network: 50-50-40-30 tanh, Adam 1e-3.
    pub fn paper_z() -> Self {
        Self::paper(vec![50, 50, 40, 30], Activation::Tanh, 1e-3)
    }

    fn paper(hidden: Vec<usize>, activation: Activation, learning_rate: f64) -> Self {
        Self {
            hidden,
            activation,
            learning_rate,
            batch_size: default_batch(),
            max_epochs: default_epochs(),
            patience: default_patience(),
            weight_decay: 0.0,
            schedule: Schedule::Constant,
            steps: None,
        }
    }

    /// robocal's network for a residual axis (not the paper's): two hidden layers of 64 tanh
    /// units on the periodic encoding, small batches, a light L2 penalty, the learning rate
    /// halved on plateaus, about 6000 steps whatever the data's size (at most 1500 epochs),
    /// patience 40.
    pub fn robocal() -> Self {
        Self {
            hidden: vec![64, 64],
            activation: Activation::Tanh,
            learning_rate: 3e-3,
            batch_size: 32,
            max_epochs: 1500,
            patience: 40,
            weight_decay: 1e-5,
            schedule: Schedule::Plateau,
            steps: Some(6000),
        }
    }

    /// Epochs for `rows` training rows: `max_epochs`, or fewer when `steps` is set.
    pub fn epochs_for(&self, rows: usize) -> usize {
        match self.steps {
            Some(steps) => {
                let batches = rows.div_ceil(self.batch_size.max(1)).max(1);
                steps.div_ceil(batches).clamp(1, self.max_epochs)
            }
            None => self.max_epochs,
        }
    }

    /// Checks the settings: the first bad one as (field, message).
    pub fn check(&self) -> Result<(), Invalid> {
        if self.hidden.contains(&0) {
            return Err(Invalid::new(
                "hidden",
                "every layer needs at least one neuron",
            ));
        }
        if self.hidden.len() > MAX_LAYERS || self.hidden.iter().any(|&n| n > MAX_WIDTH) {
            return Err(Invalid::new(
                "hidden",
                format!("at most {MAX_LAYERS} layers of at most {MAX_WIDTH} neurons"),
            ));
        }
        if !(self.learning_rate.is_finite() && self.learning_rate > 0.0) {
            return Err(Invalid::new("learning_rate", "must be a positive number"));
        }
        if self.batch_size == 0 {
            return Err(Invalid::new("batch_size", "must be at least 1"));
        }
        if self.max_epochs == 0 {
            return Err(Invalid::new("max_epochs", "must be at least 1"));
        }
        if !(self.weight_decay.is_finite() && self.weight_decay >= 0.0) {
            return Err(Invalid::new(
                "weight_decay",
                "must be 0 or a positive number",
            ));
        }
        if self.steps == Some(0) {
            return Err(Invalid::new("steps", "must be at least 1"));
        }
        Ok(())
    }
}

/// A fully connected network: linear layers with an activation between them.
#[derive(Module, Debug)]
pub struct Mlp {
    layers: Vec<Linear>,
    #[module(skip)]
    activation: Activation,
}

impl Mlp {
    /// A freshly initialised network (weights from the device's seeded generator).
    pub fn new(
        inputs: usize,
        hidden: &[usize],
        outputs: usize,
        activation: Activation,
        device: &Device,
    ) -> Self {
        let mut sizes = vec![inputs];
        sizes.extend_from_slice(hidden);
        sizes.push(outputs);
        let layers = sizes
            .windows(2)
            .map(|w| LinearConfig::new(w[0], w[1]).init(device))
            .collect();
        Self { layers, activation }
    }

    /// Draws every weight and bias now, layer by layer, weight before bias (as a first forward
    /// pass would), instead of lazily at their first use.
    fn initialise(&self) {
        for layer in &self.layers {
            let _ = layer.weight.val();
            if let Some(bias) = &layer.bias {
                let _ = bias.val();
            }
        }
    }

    /// Forward pass, `[batch, inputs] → [batch, outputs]`.
    pub fn forward(&self, x: Tensor<2>) -> Tensor<2> {
        let last = self.layers.len() - 1;
        let mut x = x;
        for (i, layer) in self.layers.iter().enumerate() {
            x = layer.forward(x);
            if i < last {
                x = match self.activation {
                    Activation::Tanh => tanh(x),
                    Activation::Relu => relu(x),
                };
            }
        }
        x
    }

    /// The weights as plain matrices, for [`Dense::forward`].
    pub fn dense(&self) -> Dense {
        let layers = self
            .layers
            .iter()
            .map(|l| {
                let w = l.weight.val();
                let [inputs, outputs] = w.dims();
                let w = w.into_data().try_to_vec::<f32>().unwrap_or_default();
                let b = l.bias.as_ref().map_or(vec![0.0; outputs], |b| {
                    b.val().into_data().try_to_vec::<f32>().unwrap_or_default()
                });
                (inputs, outputs, w, b)
            })
            .collect();
        Dense {
            layers,
            activation: self.activation,
        }
    }

    /// Predictions for `rows` inputs stored row-major in `x`, row-major `rows × outputs`.
    pub fn predict(&self, x: &[f32], inputs: usize) -> Vec<f32> {
        let rows = x.len() / inputs.max(1);
        if rows == 0 {
            return Vec::new();
        }
        let device = Device::flex();
        let t = Tensor::<2>::from_data(TensorData::new(x.to_vec(), [rows, inputs]), &device);
        self.forward(t)
            .into_data()
            .try_to_vec::<f32>()
            .unwrap_or_default()
    }
}

/// A trained network's weights as plain row-major matrices: inference without burn's per-call
/// tensor setup (one sample through three small networks in a few microseconds).
#[derive(Debug, Clone, PartialEq)]
pub struct Dense {
    /// Per layer: inputs, outputs, weights (`inputs × outputs`, row-major), biases.
    layers: Vec<(usize, usize, Vec<f32>, Vec<f32>)>,
    activation: Activation,
}

impl Dense {
    /// Forward pass of one input row; `out` receives the outputs.
    pub fn forward(&self, x: &[f32], out: &mut Vec<f32>) {
        let last = self.layers.len() - 1;
        let mut current = x.to_vec();
        for (k, (inputs, outputs, w, b)) in self.layers.iter().enumerate() {
            let mut next = b.clone();
            for (i, xi) in current.iter().enumerate().take(*inputs) {
                let row = &w[i * outputs..(i + 1) * outputs];
                for (n, wij) in next.iter_mut().zip(row) {
                    *n += xi * wij;
                }
            }
            if k < last {
                for v in &mut next {
                    *v = match self.activation {
                        Activation::Tanh => v.tanh(),
                        Activation::Relu => v.max(0.0),
                    };
                }
            }
            current = next;
        }
        out.clear();
        out.extend_from_slice(&current);
    }
}

/// What training did.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TrainReport {
    /// Epochs run.
    pub epochs: usize,
    /// The epoch (1-based) whose weights were kept: lowest validation loss.
    pub best_epoch: usize,
    /// Mean squared training loss per epoch (standardised units).
    pub train_loss: Vec<f64>,
    /// Mean squared validation loss per epoch (standardised units).
    pub validation_loss: Vec<f64>,
    /// Whether early stopping ended the run before `max_epochs`.
    pub stopped_early: bool,
}

/// Training data in standardised units, row-major.
#[derive(Debug, Clone, Copy)]
pub struct Split<'a> {
    /// Inputs, `rows × inputs`.
    pub x: &'a [f32],
    /// Targets, `rows × outputs`.
    pub y: &'a [f32],
}

/// The learning rate through training, as the schedule sets it.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Rate {
    schedule: Schedule,
    /// The rate of the next epoch.
    current: f64,
    /// The lowest rate the schedule goes to.
    floor: f64,
    /// Epochs without improvement before the rate is halved.
    wait: usize,
    /// The epoch of the last improvement or change of rate.
    last_change: usize,
}

impl Rate {
    fn new(settings: &NetSettings) -> Self {
        Self {
            schedule: settings.schedule,
            current: settings.learning_rate,
            floor: settings.learning_rate / 64.0,
            wait: (settings.patience / 4).max(3),
            last_change: 0,
        }
    }

    /// After `epoch`: halves the rate when the schedule says so.
    fn after_epoch(&mut self, epoch: usize, improved: bool) {
        if improved {
            self.last_change = epoch;
        } else if self.schedule == Schedule::Plateau
            && epoch - self.last_change >= self.wait
            && self.current / 2.0 >= self.floor
        {
            self.current /= 2.0;
            self.last_change = epoch;
        }
    }
}

fn mse(pred: &[f32], y: &[f32]) -> f64 {
    if y.is_empty() {
        return 0.0;
    }
    pred.iter()
        .zip(y)
        .map(|(p, t)| f64::from(p - t).powi(2))
        .sum::<f64>()
        / y.len() as f64
}

/// Held while burn's process-wide generator is seeded and a network's weights are drawn.
static SEEDED_DRAWS: Mutex<()> = Mutex::new(());

/// Trains a network on `train`, early-stopping on `validation`; returns the best epoch's network
/// (inference device) and the report. Deterministic for a given `seed` on the CPU backend, with
/// other trainings running at once or not.
pub fn train(
    settings: &NetSettings,
    inputs: usize,
    outputs: usize,
    train: Split<'_>,
    validation: Split<'_>,
    seed: u64,
    progress: &dyn Observer,
) -> (Mlp, TrainReport) {
    let device = Device::flex().autodiff();
    let mut model = {
        // burn's CPU backend keeps one seeded generator for the whole process and draws a
        // network's weights from it lazily, at their first use: trainings running at once (the
        // cross-validation's folds, one per core) would interleave their draws and each get
        // weights that depend on the other's timing. Seeding and every draw happen under one
        // lock, in the order a first forward pass takes them (the same weights as before).
        let _draws = SEEDED_DRAWS.lock().unwrap_or_else(PoisonError::into_inner);
        device.seed(seed);
        let model = Mlp::new(
            inputs,
            &settings.hidden,
            outputs,
            settings.activation,
            &device,
        );
        model.initialise();
        model
    };
    let mut optim = AdamConfig::new()
        .with_weight_decay(
            (settings.weight_decay > 0.0)
                .then(|| WeightDecayConfig::new(settings.weight_decay as f32)),
        )
        .init();
    let rows = train.y.len() / outputs;
    let max_epochs = settings.epochs_for(rows);
    let mut rate = Rate::new(settings);
    let mut order: Vec<usize> = (0..rows).collect();
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut best = (f64::INFINITY, 0usize, model.valid());
    let mut report = TrainReport {
        epochs: 0,
        best_epoch: 0,
        train_loss: Vec::new(),
        validation_loss: Vec::new(),
        stopped_early: false,
    };
    let (mut xb, mut yb) = (Vec::new(), Vec::new());
    for epoch in 1..=max_epochs {
        order.shuffle(&mut rng);
        let mut total = 0.0;
        for batch in order.chunks(settings.batch_size) {
            xb.clear();
            yb.clear();
            for &i in batch {
                xb.extend_from_slice(&train.x[i * inputs..(i + 1) * inputs]);
                yb.extend_from_slice(&train.y[i * outputs..(i + 1) * outputs]);
            }
            let x =
                Tensor::<2>::from_data(TensorData::new(xb.clone(), [batch.len(), inputs]), &device);
            let y = Tensor::<2>::from_data(
                TensorData::new(yb.clone(), [batch.len(), outputs]),
                &device,
            );
            let loss = (model.forward(x) - y).powi_scalar(2).mean();
            let grads = loss.backward();
            total += f64::from(loss.into_scalar::<f32>()) * batch.len() as f64;
            let grads = GradientsParams::from_grads(grads, &model);
            model = optim.step(rate.current, model, grads);
        }
        let current = model.valid();
        let train_loss = total / rows.max(1) as f64;
        // Without validation data, early stopping watches the training loss.
        let val = if validation.y.is_empty() {
            train_loss
        } else {
            mse(&current.predict(validation.x, inputs), validation.y)
        };
        report.epochs = epoch;
        report.train_loss.push(train_loss);
        report.validation_loss.push(val);
        progress.advance(1);
        let improved = val < best.0;
        if improved {
            best = (val, epoch, current);
        } else if epoch - best.1 >= settings.patience {
            report.stopped_early = epoch < max_epochs;
            break;
        }
        rate.after_epoch(epoch, improved);
    }
    report.best_epoch = best.1;
    (best.2, report)
}

#[cfg(test)]
mod tests {
    use super::{NetSettings, Rate, Schedule};

    /// The plateau schedule halves the rate after `wait` epochs without improvement (a quarter
    /// of the patience, at least 3), counts again from each change, and stops at 1/64; the
    /// constant schedule never changes it.
    #[test]
    fn the_plateau_schedule_halves_the_rate_after_a_quarter_of_the_patience() {
        let settings = NetSettings {
            patience: 20,
            learning_rate: 1.0,
            schedule: Schedule::Plateau,
            ..NetSettings::robocal()
        };
        let mut rate = Rate::new(&settings);
        let mut history = Vec::new();
        for epoch in 1..=60 {
            rate.after_epoch(epoch, epoch <= 2);
            history.push(rate.current);
        }
        // Improvements at epochs 1 and 2; halvings at 7, 12, 17, 22, 27, 32; then the floor.
        assert_eq!(history[5], 1.0);
        assert_eq!(history[6], 0.5);
        assert_eq!(history[11], 0.25);
        assert_eq!(history[31], 1.0 / 64.0);
        assert_eq!(history[59], 1.0 / 64.0);
        let mut constant = Rate::new(&NetSettings {
            schedule: Schedule::Constant,
            ..settings
        });
        for epoch in 1..=60 {
            constant.after_epoch(epoch, false);
        }
        assert_eq!(constant.current, 1.0);
    }

    /// Epochs sized to the data: 6000 steps of 32 rows are 240 epochs of 800 rows, 24 of 8000,
    /// and never more than `max_epochs`.
    #[test]
    fn steps_size_the_epochs_to_the_data() {
        let s = NetSettings::robocal();
        assert_eq!(s.epochs_for(800), 240);
        assert_eq!(s.epochs_for(8000), 24);
        assert_eq!(s.epochs_for(10), s.max_epochs);
        assert_eq!(
            NetSettings {
                steps: None,
                ..s.clone()
            }
            .epochs_for(800),
            s.max_epochs
        );
    }
}
