//! SOMM: one network per world axis (the paper's SOMM-ANN).

use robocal_data::Observer;

use crate::mlp::NetSettings;
use crate::model::Residual;
use crate::net::AxisNet;
use crate::samples::Samples;

/// One network per world axis: X, Y, Z.
#[derive(Debug, Clone)]
pub struct Somm {
    /// The X, Y and Z networks.
    pub nets: [AxisNet; 3],
}

impl Somm {
    /// Trains the three networks (axis `a` seeded `seed + offset + a`), early-stopping on
    /// `validation`.
    pub fn fit(
        settings: &[NetSettings; 3],
        train_set: &Samples,
        validation: &Samples,
        seed: u64,
        offset: u64,
        progress: &dyn Observer,
    ) -> Self {
        Self {
            nets: std::array::from_fn(|a| {
                Self::fit_axis(settings, a, train_set, validation, seed, offset, progress)
            }),
        }
    }

    /// The network of axis `a` alone, seeded as in [`Self::fit`].
    pub fn fit_axis(
        settings: &[NetSettings; 3],
        a: usize,
        train_set: &Samples,
        validation: &Samples,
        seed: u64,
        offset: u64,
        progress: &dyn Observer,
    ) -> AxisNet {
        AxisNet::fit(
            vec![a],
            &settings[a],
            train_set,
            validation,
            seed.wrapping_add(offset + a as u64),
            progress,
        )
    }

    /// Writes each network's predictions into its axis of `out`.
    pub(crate) fn predict_into(&self, encoded: &[Vec<f64>], out: &mut [[f64; 3]]) {
        for net in &self.nets {
            net.predict_into(encoded, out);
        }
    }
}

impl Residual for Somm {
    fn predict(
        &self,
        encoded: &[Vec<f64>],
        _raw: &Samples,
        _std: bool,
    ) -> (Vec<[f64; 3]>, Option<Vec<[f64; 3]>>) {
        let mut out = vec![[0.0; 3]; encoded.len()];
        self.predict_into(encoded, &mut out);
        (out, None)
    }

    fn nets(&self) -> Vec<&AxisNet> {
        self.nets.iter().collect()
    }
}
