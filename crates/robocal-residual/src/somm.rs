//! SOMM: one network per world axis (the paper's SOMM-ANN), or the average of several such
//! sets trained from different seeds (and, in the calibration pipeline, on different hold-outs).

use robocal_data::Observer;

use crate::mlp::NetSettings;
use crate::net::AxisNet;
use crate::residual::Residual;
use crate::samples::Samples;

/// One network per world axis: X, Y, Z; with several members, the members' average.
///
/// Networks trained from different seeds err differently where the data leave them free: on
/// the development twins five members erred less than one network of five seeds, on average,
/// on 22 of 24 cases (`just network-seeds`).
#[derive(Debug, Clone)]
pub struct Somm {
    /// Each member's X, Y and Z networks (at least one).
    pub members: Vec<[AxisNet; 3]>,
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
        Self::single(std::array::from_fn(|a| {
            Self::fit_axis(settings, a, train_set, validation, seed, offset, progress)
        }))
    }

    /// One set of networks.
    pub fn single(nets: [AxisNet; 3]) -> Self {
        Self {
            members: vec![nets],
        }
    }

    /// Every member's networks, member by member (X, Y, Z each).
    pub fn all_nets(&self) -> impl Iterator<Item = &AxisNet> {
        self.members.iter().flatten()
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

    /// Writes the members' average prediction into `out` (one member: its prediction, to the
    /// bit).
    pub(crate) fn predict_into(&self, encoded: &[Vec<f64>], out: &mut [[f64; 3]]) {
        let [first, rest @ ..] = self.members.as_slice() else {
            return;
        };
        for net in first {
            net.predict_into(encoded, out);
        }
        if rest.is_empty() {
            return;
        }
        let mut each = vec![[0.0; 3]; encoded.len()];
        for nets in rest {
            for net in nets {
                net.predict_into(encoded, &mut each);
            }
            for (o, e) in out.iter_mut().zip(&each) {
                for a in 0..3 {
                    o[a] += e[a];
                }
            }
        }
        let n = self.members.len() as f64;
        for o in out.iter_mut() {
            for v in o.iter_mut() {
                *v /= n;
            }
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
        self.all_nets().collect()
    }
}
