//! The residual stage of a stage config (`[residual]`), raw and validated.

use robocal_data::{Invalid, one_of};
use serde::{Deserialize, Serialize};

use crate::classifier::ClassifierSettings;
use crate::gp::GpSettings;
use crate::mlp::NetSettings;
use crate::samples::{Encoding, Frame};
use crate::search::SearchSettings;
use crate::settings::{ResidualKind, ResidualSettings};

/// Which defaults fill what a `[residual]` table leaves out.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Defaults {
    /// The paper's: raw inputs (angles in degrees, the load) and the networks of its Tables 2
    /// and 3 (200 epochs, patience 5). The default in experiment files, which reproduce it.
    Paper,
    /// robocal's: periodic inputs and [`NetSettings::robocal`] networks (trained to
    /// convergence: epochs sized to the data, L2 penalty, learning rate halved on plateaus).
    /// The default in stage files (`calibrate --config`).
    Robocal,
}

/// `[residual]` as written. Absent settings come from `defaults`.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawResidualStage {
    /// `"somm"`, `"mosm"`, `"ca-somm"` or `"gp"`.
    pub model: String,
    /// `"paper"` or `"robocal"`: what fills the settings not given (default: `"robocal"` in a
    /// stage file, `"paper"` in an experiment).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub defaults: Option<Defaults>,
    /// How inputs are presented: `"raw"` (angles in degrees and the load, the paper's) or
    /// `"periodic"` (sin and cos of every angle, and the load; robocal's default, and the GP's
    /// whatever the defaults).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub encoding: Option<Encoding>,
    /// The frame the errors are learned in: `"world"` (the tracker's X, Y, Z; the default) or
    /// `"joint1"` (turning with joint 1's reading about its axis).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub frame: Option<Frame>,
    /// Seed of initialisation, batch order and the validation hold-out.
    pub seed: Option<u64>,
    /// Share of the training configurations held out for early stopping when no `--validate`
    /// file is given (whole configurations, every load of each), default 0.2.
    pub holdout: Option<f64>,
    /// `model = "somm"`: sets of networks trained from different seeds (each on its own
    /// hold-out) and averaged; default 1.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub members: Option<usize>,
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
    /// Validates, filling what is not given from `self.defaults`, else `context`'s; errors
    /// name the key (`residual.x.learning_rate`, …).
    pub fn validate(&self, context: Defaults) -> Result<ResidualStage, Invalid> {
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
        let mut settings = match (kind, self.defaults.unwrap_or(context)) {
            (ResidualKind::Gp, _) => ResidualSettings::gp(seed),
            (_, Defaults::Paper) => ResidualSettings::paper(kind, seed),
            (_, Defaults::Robocal) => ResidualSettings::robocal(kind, seed),
        };
        if let Some(e) = self.encoding {
            settings.encoding = e;
        }
        if let Some(f) = self.frame {
            settings.frame = f;
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
            // What the table leaves out of the gate comes from the defaults too.
            let defaults = &settings.classifier;
            settings.classifier = ClassifierSettings {
                inputs: c.inputs.or(defaults.inputs),
                fallback: c.fallback.or(defaults.fallback),
                classes: c.classes.or(defaults.classes),
                tree_search: c.tree_search.or(defaults.tree_search),
                ..c.clone()
            };
        }
        settings.search = self.search.clone();
        if let Some(m) = self.members {
            settings.members = m;
        }
        settings.validate().map_err(|e| e.within("residual"))?;
        let holdout = self.holdout.unwrap_or(0.2);
        if !(holdout > 0.0 && holdout < 1.0) {
            return Err(Invalid::new("residual.holdout", "must lie between 0 and 1"));
        }
        Ok(ResidualStage { settings, holdout })
    }
}
