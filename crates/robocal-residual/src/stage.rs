//! The residual stage of a stage config (`[residual]`), raw and validated.

use robocal_data::{Invalid, one_of};
use serde::{Deserialize, Serialize};

use crate::classifier::ClassifierSettings;
use crate::gp::GpSettings;
use crate::mlp::NetSettings;
use crate::samples::Encoding;
use crate::search::SearchSettings;
use crate::settings::{ResidualKind, ResidualSettings};

/// `[residual]` as written. Absent networks get the paper's settings (Tables 2 and 3).
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawResidualStage {
    /// `"somm"`, `"mosm"`, `"ca-somm"` or `"gp"`.
    pub model: String,
    /// How inputs are presented: `"raw"` (angles in degrees and the load, the paper's; the
    /// default for the networks) or `"periodic"` (sin and cos of every angle, and the load; the
    /// default for the GP).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub encoding: Option<Encoding>,
    /// Seed of initialisation, batch order and the validation hold-out.
    pub seed: Option<u64>,
    /// Share of the training configurations held out for early stopping when no `--validate`
    /// file is given (whole configurations, every load of each), default 0.2.
    pub holdout: Option<f64>,
    /// The X network.
    pub x: Option<NetSettings>,
    /// The Y network.
    pub y: Option<NetSettings>,
    /// The Z network.
    pub z: Option<NetSettings>,
    /// The multi-output network (MOSM).
    pub mosm: Option<NetSettings>,
    /// The CA-SOMM classifier.
    pub classifier: Option<ClassifierSettings>,
    /// A TPE search of every network's architecture and learning rate before training.
    pub search: Option<SearchSettings>,
    /// The Gaussian process (`model = "gp"`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gp: Option<GpSettings>,
}

/// A validated residual stage.
#[derive(Debug, Clone, PartialEq)]
pub struct ResidualStage {
    /// Model settings.
    pub settings: ResidualSettings,
    /// Share of configurations held out for validation when no file is given.
    pub holdout: f64,
}

/// Default seed of a residual stage.
pub const DEFAULT_SEED: u64 = 2020;

impl RawResidualStage {
    /// Validates; errors name the key (`residual.x.learning_rate`, …).
    pub fn validate(&self) -> Result<ResidualStage, Invalid> {
        let kind = ResidualKind::from_name(&self.model).ok_or_else(|| {
            Invalid::new(
                "residual.model",
                format!(
                    "`{}` is not a residual model; use {}",
                    self.model,
                    one_of(&ResidualKind::ALL.map(ResidualKind::name))
                ),
            )
        })?;
        let seed = self.seed.unwrap_or(DEFAULT_SEED);
        let mut settings = match kind {
            ResidualKind::Gp => ResidualSettings::gp(seed),
            _ => ResidualSettings::paper(kind, seed),
        };
        if let Some(e) = self.encoding {
            settings.encoding = e;
        }
        if let Some(g) = &self.gp {
            settings.gp = g.clone();
        }
        for (slot, given) in settings.axes.iter_mut().zip([&self.x, &self.y, &self.z]) {
            if let Some(s) = given {
                *slot = s.clone();
            }
        }
        if let Some(s) = &self.mosm {
            settings.mosm = s.clone();
        }
        if let Some(c) = &self.classifier {
            settings.classifier = c.clone();
        }
        settings.search = self.search.clone();
        settings.validate().map_err(|e| e.within("residual"))?;
        let holdout = self.holdout.unwrap_or(0.2);
        if !(holdout > 0.0 && holdout < 1.0) {
            return Err(Invalid::new("residual.holdout", "must lie between 0 and 1"));
        }
        Ok(ResidualStage { settings, holdout })
    }
}
