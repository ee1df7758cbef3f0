//! MOSM: one network with three outputs (the paper's "traditional" MOSM-ANN baseline).

use robocal_data::Observer;

use crate::mlp::NetSettings;
use crate::net::AxisNet;
use crate::residual::Residual;
use crate::samples::Samples;

/// One network, outputs X, Y, Z.
#[derive(Debug, Clone)]
pub struct Mosm {
    /// The network.
    pub net: AxisNet,
}

impl Mosm {
    /// Trains the network, early-stopping on `validation`.
    pub fn fit(
        settings: &NetSettings,
        train_set: &Samples,
        validation: &Samples,
        seed: u64,
        progress: &dyn Observer,
    ) -> Self {
        Self {
            net: AxisNet::fit(
                vec![0, 1, 2],
                settings,
                train_set,
                validation,
                seed,
                progress,
            ),
        }
    }
}

impl Residual for Mosm {
    fn predict(
        &self,
        encoded: &[Vec<f64>],
        _raw: &Samples,
        _std: bool,
    ) -> (Vec<[f64; 3]>, Option<Vec<[f64; 3]>>) {
        let mut out = vec![[0.0; 3]; encoded.len()];
        self.net.predict_into(encoded, &mut out);
        (out, None)
    }

    fn nets(&self) -> Vec<&AxisNet> {
        vec![&self.net]
    }
}
