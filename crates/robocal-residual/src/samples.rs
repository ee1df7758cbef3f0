//! What every residual model learns from and how it sees it: samples (an input row and the
//! error to learn), the input encoding, and per-column standardisation.

use nalgebra::Vector3;
use robocal_data::{Measurement, Sample};
use serde::{Deserialize, Serialize};

/// Residual samples: one input row (joint angles in degrees, then the load in kg) and the
/// position error (measured − kinematic prediction, mm, world X/Y/Z) per sample.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Samples {
    /// Input rows, all of one length.
    pub inputs: Vec<Vec<f64>>,
    /// Errors, mm (empty for rows to predict).
    pub errors: Vec<[f64; 3]>,
    /// What the identified model knows about each row that a gate reading physics needs
    /// ([`GateInputs::Physics`](crate::GateInputs)): empty, or one row per input row.
    pub physics: Vec<Vec<f64>>,
}

/// The residual model's input row for a sample: joint angles (deg), then the load (kg).
pub fn inputs_of(sample: &Sample) -> Vec<f64> {
    let mut row = sample.joints.clone();
    row.push(sample.load);
    row
}

/// How an input row (joint angles in degrees, then the load) is presented to a model.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Encoding {
    /// As read: angles in degrees, then the load (the paper's inputs, eq. (24)).
    #[default]
    Raw,
    /// `sin q, cos q` of every joint angle, then the load: an error that is periodic in the
    /// angles is a smooth function of these, and ±180° are one angle.
    Periodic,
}

/// The frame a residual model's errors are learned and predicted in.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Frame {
    /// The world (tracker) frame's X, Y, Z.
    #[default]
    World,
    /// A frame turning with joint 1: the world frame turned about joint 1's axis by its reading.
    /// What the parts beyond joint 1 do under their own weight and the payload's (a joint-1 axis
    /// along gravity) turns with them and is the same function of the other joints at every
    /// joint-1 angle, so a model that learned it on part of joint 1's range carries it to the
    /// rest; in the world frame the same error turns with joint 1 and a model must learn every
    /// angle of it.
    Joint1,
}

impl Frame {
    /// Whether this is [`Frame::World`] (the default, left out of saved files).
    pub fn is_world(&self) -> bool {
        *self == Self::World
    }

    /// Every frame, in the order they are listed.
    pub const ALL: [Self; 2] = [Self::World, Self::Joint1];

    /// Its name in files: `world` or `joint1`.
    pub fn name(self) -> &'static str {
        match self {
            Self::World => "world",
            Self::Joint1 => "joint1",
        }
    }

    /// The frame a name in files names, if any.
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|f| f.name() == name)
    }

    /// The frame `name` names, or what to say about a name that names none (every frame's
    /// name listed), for the command line and Python to prefix with their option's name.
    pub fn parse(name: &str) -> Result<Self, String> {
        Self::from_name(name).ok_or_else(|| {
            let names: Vec<String> = Self::ALL
                .iter()
                .map(|f| format!("`{}`", f.name()))
                .collect();
            format!("`{name}` is not a frame; use {}", names.join(" or "))
        })
    }
}

impl Encoding {
    /// Whether this is [`Encoding::Raw`] (the default, left out of saved files).
    pub fn is_raw(&self) -> bool {
        *self == Self::Raw
    }

    /// Features of an encoded row of `inputs` raw inputs (the last one the load).
    pub fn features(self, inputs: usize) -> usize {
        match self {
            Self::Raw => inputs,
            Self::Periodic => 2 * inputs.saturating_sub(1) + usize::from(inputs > 0),
        }
    }

    /// The encoded row.
    pub fn encode(self, row: &[f64]) -> Vec<f64> {
        match self {
            Self::Raw => row.to_vec(),
            Self::Periodic => {
                let Some((load, joints)) = row.split_last() else {
                    return Vec::new();
                };
                let mut out = Vec::with_capacity(2 * joints.len() + 1);
                for q in joints {
                    let (s, c) = q.to_radians().sin_cos();
                    out.push(s);
                    out.push(c);
                }
                out.push(*load);
                out
            }
        }
    }

    /// Every row encoded.
    pub fn encode_all(self, rows: &[Vec<f64>]) -> Vec<Vec<f64>> {
        rows.iter().map(|r| self.encode(r)).collect()
    }
}

impl Samples {
    /// Residual samples of measured rows: inputs, and measured − `model`'s predicted point
    /// (e.g. an elasto-geometric model's, which depends on the load).
    pub fn from_model<'a>(
        model: impl Fn(&Sample) -> Vector3<f64>,
        rows: impl IntoIterator<Item = &'a Measurement>,
    ) -> Self {
        let mut samples = Self::default();
        for m in rows {
            samples.inputs.push(inputs_of(&m.sample));
            let e = m.position - model(&m.sample);
            samples.errors.push([e.x, e.y, e.z]);
        }
        samples
    }

    /// Length of each sample's error left after subtracting `predicted` (`None`: the error
    /// itself), mm.
    pub fn remaining(&self, predicted: Option<&[[f64; 3]]>) -> Vec<f64> {
        self.errors
            .iter()
            .enumerate()
            .map(|(i, e)| {
                let p = predicted.map_or([0.0; 3], |p| p[i]);
                ((e[0] - p[0]).powi(2) + (e[1] - p[1]).powi(2) + (e[2] - p[2]).powi(2)).sqrt()
            })
            .collect()
    }

    /// Samples of known errors, no physics rows.
    pub fn new(inputs: Vec<Vec<f64>>, errors: Vec<[f64; 3]>) -> Self {
        Self {
            inputs,
            errors,
            physics: Vec::new(),
        }
    }

    /// Rows to predict: inputs, no errors.
    pub fn rows(inputs: Vec<Vec<f64>>) -> Self {
        Self::new(inputs, Vec::new())
    }

    /// The same samples with each row's physics features.
    pub fn with_physics(mut self, physics: Vec<Vec<f64>>) -> Self {
        self.physics = physics;
        self
    }

    /// The same samples with their inputs as `encoding` presents them.
    pub fn encoded(&self, encoding: Encoding) -> Self {
        Self {
            inputs: encoding.encode_all(&self.inputs),
            ..self.clone()
        }
    }

    /// The configuration of each sample, numbered from 0 in order of first appearance: samples
    /// whose joint angles (every input but the last, the load) are equal share one.
    pub fn configurations(&self) -> Vec<usize> {
        let mut seen: std::collections::HashMap<Vec<u64>, usize> = std::collections::HashMap::new();
        self.inputs
            .iter()
            .map(|row| {
                let key: Vec<u64> = row[..row.len().saturating_sub(1)]
                    .iter()
                    .map(|v| v.to_bits())
                    .collect();
                let next = seen.len();
                *seen.entry(key).or_insert(next)
            })
            .collect()
    }

    /// Number of samples (input rows).
    pub fn len(&self) -> usize {
        self.inputs.len()
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.inputs.is_empty()
    }

    pub(crate) fn subset(&self, keep: &[bool]) -> Self {
        let pick = |i: &usize| keep[*i];
        let idx: Vec<usize> = (0..self.len()).filter(pick).collect();
        let rows = |v: &[Vec<f64>]| -> Vec<Vec<f64>> {
            if v.is_empty() {
                Vec::new()
            } else {
                idx.iter().map(|&i| v[i].clone()).collect()
            }
        };
        Self {
            inputs: rows(&self.inputs),
            errors: idx
                .iter()
                .filter_map(|&i| self.errors.get(i).copied())
                .collect(),
            physics: rows(&self.physics),
        }
    }
}

/// Per-column mean and standard deviation from training data.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Standardizer {
    /// Column means.
    pub mean: Vec<f64>,
    /// Column standard deviations (1 where a column is constant).
    pub std: Vec<f64>,
}

impl Standardizer {
    /// Fits the columns of `rows`.
    pub fn fit(rows: &[Vec<f64>]) -> Self {
        let cols = rows.first().map_or(0, Vec::len);
        let n = rows.len().max(1) as f64;
        let mean: Vec<f64> = (0..cols)
            .map(|c| rows.iter().map(|r| r[c]).sum::<f64>() / n)
            .collect();
        let std = (0..cols)
            .map(|c| {
                let v = rows.iter().map(|r| (r[c] - mean[c]).powi(2)).sum::<f64>() / n;
                if v > 1e-24 { v.sqrt() } else { 1.0 }
            })
            .collect();
        Self { mean, std }
    }

    /// Whether this scaling fits `n` columns: that many finite means and positive finite
    /// standard deviations (what a file read back must hold).
    pub fn fits(&self, n: usize) -> bool {
        self.mean.len() == n
            && self.std.len() == n
            && self.mean.iter().chain(&self.std).all(|v| v.is_finite())
            && self.std.iter().all(|v| *v > 0.0)
    }

    /// The standardised row.
    pub fn apply(&self, row: &[f64]) -> Vec<f64> {
        (row.iter().zip(&self.mean).zip(&self.std))
            .map(|((v, m), s)| (v - m) / s)
            .collect()
    }

    pub(crate) fn forward(&self, row: &[f64], out: &mut Vec<f32>) {
        for ((v, m), s) in row.iter().zip(&self.mean).zip(&self.std) {
            out.push(((v - m) / s) as f32);
        }
    }

    pub(crate) fn back(&self, col: usize, v: f32) -> f64 {
        f64::from(v) * self.std[col] + self.mean[col]
    }
}
