//! Which residual model, and every setting its training takes.

use robocal_data::Invalid;
use serde::{Deserialize, Serialize};

use crate::classifier::{ClassRule, ClassifierSettings, GateInputs};
use crate::error::{ResidualError, Result};
use crate::gp::GpSettings;
use crate::mlp::NetSettings;
use crate::samples::{Encoding, Frame};
use crate::search::SearchSettings;

/// Which residual model.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum ResidualKind {
    /// One network per axis (the paper's SOMM-ANN).
    Somm,
    /// One network with three outputs (the paper's "traditional" MOSM-ANN baseline).
    Mosm,
    /// A classifier picks one of two SOMM sets (the paper's CA-SOMM-ANN).
    CaSomm,
    /// A Gaussian process per axis (ARD squared-exponential kernel), with predictive
    /// standard deviations.
    Gp,
}

impl ResidualKind {
    /// Every residual model.
    pub const ALL: [Self; 4] = [Self::Somm, Self::Mosm, Self::CaSomm, Self::Gp];

    /// The model a stage file names.
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|k| k.name() == name)
    }

    /// The name used in files.
    pub fn name(self) -> &'static str {
        match self {
            Self::Somm => "somm",
            Self::Mosm => "mosm",
            Self::CaSomm => "ca-somm",
            Self::Gp => "gp",
        }
    }

    /// Whether training early-stops on a validation set (the networks; the GP does not).
    pub fn early_stops(self) -> bool {
        self != Self::Gp
    }

    /// Whether the model gives a standard deviation with each correction (the GP).
    pub fn gives_std(self) -> bool {
        self == Self::Gp
    }
}

/// Most members a SOMM may average.
pub const MAX_MEMBERS: usize = 16;

/// Member `m` of a SOMM is seeded `seed + MEMBER_SEED_STRIDE × m` (its axes `+ 0, 1, 2` after
/// that, as a single SOMM's are): apart from every other member's.
pub const MEMBER_SEED_STRIDE: u64 = 1000;

/// Everything that defines how a residual model is trained.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ResidualSettings {
    /// Which model.
    pub kind: ResidualKind,
    /// Per-axis networks (SOMM, and each CA-SOMM set).
    pub axes: [NetSettings; 3],
    /// The multi-output network (MOSM).
    pub mosm: NetSettings,
    /// The CA-SOMM classifier.
    pub classifier: ClassifierSettings,
    /// A TPE search of each network's architecture and learning rate before training, if asked.
    pub search: Option<SearchSettings>,
    /// The Gaussian process (GP).
    pub gp: GpSettings,
    /// How input rows are presented to the networks, the classifier and the GP.
    pub encoding: Encoding,
    /// The frame the errors are learned in ([`Frame`]; the world's unless asked).
    #[serde(skip_serializing_if = "Frame::is_world")]
    pub frame: Frame,
    /// Seed of weight initialisation and batch order.
    pub seed: u64,
    /// SOMM: how many sets of networks are trained (member `m` seeded `seed + 1000 m`, on its
    /// own hold-out in the calibration pipeline) and averaged. 1 for every other model.
    pub members: usize,
}

impl ResidualSettings {
    /// The paper's settings (Tables 2 and 3) for `kind`. The MOSM network has no published
    /// architecture; it gets the Z network's (the largest tanh one) with three outputs.
    pub fn paper(kind: ResidualKind, seed: u64) -> Self {
        Self {
            kind,
            axes: [
                NetSettings::paper_x(),
                NetSettings::paper_y(),
                NetSettings::paper_z(),
            ],
            mosm: NetSettings::paper_z(),
            classifier: ClassifierSettings {
                inputs: Some(GateInputs::Model),
                fallback: Some(false),
                classes: Some(ClassRule::Threshold),
                tree_search: Some(false),
                ..ClassifierSettings::default()
            },
            search: None,
            gp: GpSettings::default(),
            encoding: Encoding::Raw,
            frame: Frame::World,
            seed,
            members: 1,
        }
    }

    /// robocal's settings for `kind`: periodic inputs and [`NetSettings::robocal`] networks
    /// (every axis, each CA-SOMM set, the MOSM network); the paper's tree reading physics
    /// ([`GateInputs::Physics`]), with a fallback to one class when two do not pay.
    pub fn robocal(kind: ResidualKind, seed: u64) -> Self {
        Self {
            axes: [
                NetSettings::robocal(),
                NetSettings::robocal(),
                NetSettings::robocal(),
            ],
            mosm: NetSettings::robocal(),
            encoding: Encoding::Periodic,
            classifier: ClassifierSettings {
                inputs: Some(GateInputs::Physics),
                fallback: Some(true),
                classes: Some(ClassRule::Routed),
                tree_search: Some(true),
                ..ClassifierSettings::default()
            },
            ..Self::paper(kind, seed)
        }
    }

    /// A Gaussian process per axis on the periodic encoding (robocal's default residual).
    pub fn gp(seed: u64) -> Self {
        Self {
            encoding: Encoding::Periodic,
            ..Self::paper(ResidualKind::Gp, seed)
        }
    }

    /// Member `m`'s settings: seeded `seed + 1000 m`, one member.
    pub fn member(&self, m: usize) -> Self {
        Self {
            seed: self.seed.wrapping_add(MEMBER_SEED_STRIDE * m as u64),
            members: 1,
            ..self.clone()
        }
    }

    /// Every setting checked, used by this kind or not; the error's key is relative to
    /// `[residual]` (`x.learning_rate`, `gp.step`).
    pub fn validate(&self) -> std::result::Result<(), Invalid> {
        if !(1..=MAX_MEMBERS).contains(&self.members) {
            return Err(Invalid::new(
                "members",
                format!("{}: must be 1 to {MAX_MEMBERS}", self.members),
            ));
        }
        if self.members > 1 && self.kind != ResidualKind::Somm {
            return Err(Invalid::new(
                "members",
                format!(
                    "{}: only a somm averages several sets of networks (a {} model has one)",
                    self.members,
                    self.kind.name()
                ),
            ));
        }
        let [x, y, z] = &self.axes;
        for (name, s) in [("x", x), ("y", y), ("z", z), ("mosm", &self.mosm)] {
            s.check().map_err(|e| e.within(name))?;
        }
        if let Some(search) = &self.search {
            search.check().map_err(|e| e.within("search"))?;
        }
        self.gp.check().map_err(|e| e.within("gp"))?;
        if self.classifier.max_depth == 0 {
            return Err(Invalid::new("classifier.max_depth", "must be at least 1"));
        }
        if let Some(c) = self.classifier.payload_com
            && c.iter().any(|v| !v.is_finite())
        {
            return Err(Invalid::new(
                "classifier.payload_com",
                "must be finite (mm, flange frame)",
            ));
        }
        if let Some(g) = self.classifier.gravity
            && (g.iter().any(|v| !v.is_finite()) || g.iter().all(|v| *v == 0.0))
        {
            return Err(Invalid::new(
                "classifier.gravity",
                "must be a finite, non-zero vector (m/s², robot base frame)",
            ));
        }
        Ok(())
    }

    /// Checks every setting; the error names the key.
    pub fn check(&self) -> Result<()> {
        self.validate().map_err(ResidualError::Settings)
    }
}
