//! One trained network with its input and output scaling: the building block of SOMM, MOSM and
//! CA-SOMM.

use robocal_data::Observer;

use crate::mlp::{Dense, Mlp, NetSettings, Split, TrainReport, train};
use crate::samples::{Samples, Standardizer};

/// Renumbers a module's parameters 0, 1, 2, … in visiting order.
pub(crate) struct SequentialIds(pub(crate) u64);

impl burn::module::ModuleMapper for SequentialIds {
    fn map_float<const D: usize>(
        &mut self,
        mut param: burn::module::Param<burn::tensor::Tensor<D>>,
    ) -> burn::module::Param<burn::tensor::Tensor<D>> {
        param.id = burn::module::ParamId::from(self.0);
        self.0 += 1;
        param
    }
}

/// One trained network with its scaling: inputs → the error on `axes`.
#[derive(Debug, Clone)]
pub struct AxisNet {
    /// Which world axes (0 = X, 1 = Y, 2 = Z) the outputs are.
    pub axes: Vec<usize>,
    /// Its settings.
    pub settings: NetSettings,
    /// Input scaling.
    pub input_scale: Standardizer,
    /// Output scaling.
    pub output_scale: Standardizer,
    /// What training did.
    pub report: TrainReport,
    pub(crate) net: Mlp,
    pub(crate) dense: Dense,
}

impl AxisNet {
    /// The axes it predicts as letters: `x`, `xyz`, …
    pub fn axes_name(&self) -> String {
        self.axes.iter().map(|&a| ["x", "y", "z"][a]).collect()
    }

    pub(crate) fn inputs(&self) -> usize {
        self.input_scale.mean.len()
    }

    pub(crate) fn fit(
        axes: Vec<usize>,
        settings: &NetSettings,
        train_set: &Samples,
        validation: &Samples,
        seed: u64,
        progress: &dyn Observer,
    ) -> Self {
        let input_scale = Standardizer::fit(&train_set.inputs);
        let targets = |s: &Samples| -> Vec<Vec<f64>> {
            s.errors
                .iter()
                .map(|e| axes.iter().map(|&a| e[a]).collect())
                .collect()
        };
        let train_y = targets(train_set);
        let output_scale = Standardizer::fit(&train_y);
        let flat = |s: &Samples, y: &[Vec<f64>]| {
            let (mut x, mut t) = (Vec::new(), Vec::new());
            for row in &s.inputs {
                input_scale.forward(row, &mut x);
            }
            for row in y {
                output_scale.forward(row, &mut t);
            }
            (x, t)
        };
        let (tx, ty) = flat(train_set, &train_y);
        let (vx, vy) = flat(validation, &targets(validation));
        let (net, report) = train(
            settings,
            input_scale.mean.len(),
            axes.len(),
            Split { x: &tx, y: &ty },
            Split { x: &vx, y: &vy },
            seed,
            progress,
        );
        Self {
            axes,
            settings: settings.clone(),
            input_scale,
            output_scale,
            report,
            dense: net.dense(),
            net,
        }
    }

    /// Writes this network's predictions (mm) for `inputs` into its axes of `out`.
    pub(crate) fn predict_into(&self, inputs: &[Vec<f64>], out: &mut [[f64; 3]]) {
        let (mut x, mut y) = (Vec::with_capacity(self.inputs()), Vec::new());
        for (row, o) in inputs.iter().zip(out.iter_mut()) {
            x.clear();
            self.input_scale.forward(row, &mut x);
            self.dense.forward(&x, &mut y);
            for (c, &axis) in self.axes.iter().enumerate() {
                o[axis] = self.output_scale.back(c, y[c]);
            }
        }
    }

    /// The burn network's own predictions in standardised units, row-major (what
    /// [`Self::predict_standardised`] must agree with).
    pub fn burn_forward(&self, x: &[f32]) -> Vec<f32> {
        self.net.predict(x, self.inputs())
    }

    /// The plain-matrix forward pass in standardised units, row-major.
    pub fn predict_standardised(&self, x: &[f32]) -> Vec<f32> {
        let mut out = Vec::new();
        let mut y = Vec::new();
        for row in x.chunks_exact(self.inputs()) {
            self.dense.forward(row, &mut y);
            out.extend_from_slice(&y);
        }
        out
    }
}
