//! `plan.toml`: what a plan draws from and what the calibration will identify.

use std::path::{Path, PathBuf};

use nalgebra::Vector3;
use robocal_robot::TomlFault;
use serde::{Deserialize, Serialize};

use crate::error::{PlanError, Result};

/// `plan.toml` as written. Every key is optional.
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawPlan {
    /// Seed of the candidates, the check poses and the random comparison sets (default 7).
    pub seed: Option<u64>,
    /// Loads, kg: each chosen configuration is to be measured at every one (default `[0.0]`).
    pub loads: Option<Vec<f64>>,
    /// Tracker noise, mm, 1σ per coordinate (default 0.02).
    pub noise_mm: Option<f64>,
    /// Random candidate configurations drawn within the joint limits (default 2000).
    pub pool: Option<usize>,
    /// Check poses over which the predicted position error is reported (default 200).
    pub check: Option<usize>,
    /// Smallest ratio of the smallest to the largest singular value of the point's Jacobian
    /// for a candidate (default 0.05): poses nearer a singularity are left out.
    pub min_conditioning: Option<f64>,
    /// What the selection optimises: `"i-optimal"` (default: the mean predicted position
    /// variance over the check poses) or `"d-optimal"` (the information's `log det`).
    pub criterion: Option<Criterion>,
    /// The box the measured point must lie in, robot base frame {0}, mm.
    pub workspace: Option<RawWorkspace>,
    /// What the calibration will identify besides the geometry.
    pub model: Option<RawModel>,
}

/// `[workspace]`.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawWorkspace {
    /// Lower corner, mm.
    pub min: [f64; 3],
    /// Upper corner, mm.
    pub max: [f64; 3],
}

/// `[model]`.
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawModel {
    /// Joint compliances under the payload (needs two or more loads).
    #[serde(default)]
    pub compliance: bool,
    /// Transmission harmonics of every joint, orders 1..H (0: none).
    #[serde(default)]
    pub harmonics: u32,
    /// Self-weight terms.
    #[serde(default)]
    pub self_weight: bool,
    /// The payload's centre of mass in the flange frame, mm (default: the measured point).
    pub payload_com: Option<[f64; 3]>,
    /// Gravity in the robot base frame, m/s² (default `[0, 0, -9.80665]`).
    pub gravity: Option<[f64; 3]>,
}

/// Validated plan settings.
#[derive(Debug, Clone, PartialEq)]
pub struct PlanSettings {
    /// Where they came from (for messages).
    pub source: PathBuf,
    /// Seed.
    pub seed: u64,
    /// Loads, kg, ascending.
    pub loads: Vec<f64>,
    /// Tracker noise, mm per coordinate.
    pub noise_mm: f64,
    /// Candidate configurations drawn.
    pub pool: usize,
    /// Check poses.
    pub check: usize,
    /// Smallest conditioning of a candidate's point Jacobian.
    pub min_conditioning: f64,
    /// What the selection optimises.
    pub criterion: Criterion,
    /// The workspace box, base frame, mm (`None`: anywhere).
    pub workspace: Option<(Vector3<f64>, Vector3<f64>)>,
    /// Compliances identified.
    pub compliance: bool,
    /// Harmonic orders identified per joint.
    pub harmonics: u32,
    /// Self-weight terms identified.
    pub self_weight: bool,
    /// The payload's centre of mass, flange frame, mm (`None`: the measured point).
    pub payload_com: Option<Vector3<f64>>,
    /// Gravity, base frame, m/s².
    pub gravity: Vector3<f64>,
}

impl Default for PlanSettings {
    fn default() -> Self {
        RawPlan::default()
            .validate(Path::new("(defaults)"))
            .unwrap_or_else(|_| unreachable!("the defaults are valid"))
    }
}

impl PlanSettings {
    /// Reads and validates `plan.toml`.
    pub fn load(path: &Path) -> Result<Self> {
        let text = std::fs::read_to_string(path).map_err(|source| PlanError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        Self::from_toml_str(&text, path)
    }

    /// Parses and validates the text of `path`.
    pub fn from_toml_str(text: &str, path: &Path) -> Result<Self> {
        let raw: RawPlan =
            toml::from_str(text).map_err(|e| PlanError::Toml(TomlFault::of(path, text, &e)))?;
        raw.validate(path)
    }
}

impl RawPlan {
    /// Validates; errors name `path` and the key.
    pub fn validate(&self, path: &Path) -> Result<PlanSettings> {
        let bad = |key: &str, message: &str| PlanError::invalid(path, key, message);
        let loads = self.loads.clone().unwrap_or_else(|| vec![0.0]);
        if loads.is_empty() || loads.iter().any(|l| !l.is_finite() || *l < 0.0) {
            return Err(bad("loads", "must list one or more loads, each ≥ 0 kg"));
        }
        let mut loads = loads;
        loads.sort_by(f64::total_cmp);
        loads.dedup();
        let noise_mm = self.noise_mm.unwrap_or(0.02);
        if !(noise_mm.is_finite() && noise_mm > 0.0) {
            return Err(bad("noise_mm", "must be a positive number of mm"));
        }
        let pool = self.pool.unwrap_or(2000);
        if !(10..=1_000_000).contains(&pool) {
            return Err(bad("pool", "must lie between 10 and 1000000 candidates"));
        }
        let check = self.check.unwrap_or(200);
        if !(1..=100_000).contains(&check) {
            return Err(bad("check", "must lie between 1 and 100000 poses"));
        }
        let min_conditioning = self.min_conditioning.unwrap_or(0.05);
        if !(0.0..1.0).contains(&min_conditioning) {
            return Err(bad("min_conditioning", "must lie in [0, 1)"));
        }
        let workspace = match &self.workspace {
            None => None,
            Some(w) => {
                if w.min.iter().chain(&w.max).any(|v| !v.is_finite()) {
                    return Err(bad("workspace.min", "corners must be finite (mm)"));
                }
                if (0..3).any(|a| w.min[a] >= w.max[a]) {
                    return Err(bad(
                        "workspace.min",
                        "every coordinate must lie below workspace.max's: the box is empty",
                    ));
                }
                Some((Vector3::from(w.min), Vector3::from(w.max)))
            }
        };
        let model = self.model.clone().unwrap_or_default();
        if model.compliance && loads.len() < 2 {
            return Err(bad(
                "model.compliance",
                "joint compliances need two or more loads in `loads`",
            ));
        }
        if model.harmonics > 8 {
            return Err(bad("model.harmonics", "must lie between 0 and 8"));
        }
        if let Some(c) = model.payload_com
            && c.iter().any(|v| !v.is_finite())
        {
            return Err(bad(
                "model.payload_com",
                "must be finite (mm, flange frame)",
            ));
        }
        let gravity = model.gravity.unwrap_or([0.0, 0.0, -9.80665]);
        if gravity.iter().any(|v| !v.is_finite()) || gravity.iter().all(|v| *v == 0.0) {
            return Err(bad(
                "model.gravity",
                "must be a finite, non-zero vector (m/s², robot base frame)",
            ));
        }
        Ok(PlanSettings {
            source: path.to_path_buf(),
            seed: self.seed.unwrap_or(7),
            loads,
            noise_mm,
            pool,
            check,
            min_conditioning,
            criterion: self.criterion.unwrap_or_default(),
            workspace,
            compliance: model.compliance,
            harmonics: model.harmonics,
            self_weight: model.self_weight,
            payload_com: model.payload_com.map(Vector3::from),
            gravity: Vector3::from(gravity),
        })
    }
}

/// What a plan optimises.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Criterion {
    /// D-optimal: the largest `log det` of the information (the parameters' joint confidence
    /// region smallest).
    DOptimal,
    /// I-optimal (the default): the smallest mean predicted variance of the position over the
    /// check poses, the error the plan predicts and the one users judge a calibration by. On
    /// robocal's twins it left less error on unmeasured poses than D-optimal plans more often
    /// (`docs/accuracy.md`, "Planned poses").
    #[default]
    IOptimal,
}
