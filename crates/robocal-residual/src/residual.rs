//! The interface every kind of residual model implements: prediction from encoded rows, and the
//! networks it saves. Its own module, so that [`crate::model`], which holds every kind, and the
//! kinds, which implement it, do not import each other.

use crate::net::AxisNet;
use crate::samples::Samples;

/// A fitted residual model of one kind.
pub trait Residual {
    /// Predicted error (mm, world X/Y/Z) for each encoded input row, and — for a model that
    /// knows how sure it is, when `std` is asked for — each axis's standard deviation (mm).
    /// `raw` holds the same rows unencoded, with their physics rows (what a gate may read).
    fn predict(
        &self,
        encoded: &[Vec<f64>],
        raw: &Samples,
        std: bool,
    ) -> (Vec<[f64; 3]>, Option<Vec<[f64; 3]>>);

    /// Its networks, in the order they are saved (none for a model without networks).
    fn nets(&self) -> Vec<&AxisNet> {
        Vec::new()
    }
}
