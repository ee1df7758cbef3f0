//! Experiment files (`robocal run EXPERIMENT.toml`): parsed raw (unknown keys refused) and
//! validated once into an [`Experiment`], errors naming the key.
//!
//! Paths inside the file are relative to the file's folder; the output folder is relative to the
//! working directory (default `reports`, the report going to `<output>/<name>/`).

use std::path::{Path, PathBuf};

use robocal_ident::SolverKind;
use robocal_residual::{Gate, PerClass, ResidualKind};
use serde::{Deserialize, Serialize};

use crate::error::{Result, invalid, key};
use robocal_calibration::error::read_text;
use robocal_calibration::{CalibrationError, RawStages, Stages};

/// An experiment file as written.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawExperiment {
    /// Name of the experiment and of its report folder (letters, digits, `-`, `_`, `.`).
    pub name: String,
    /// One line on what it shows, printed at the top of the report.
    pub description: Option<String>,
    /// Seed of the split and, unless a stage gives its own, of the residual models (default 2020).
    pub seed: Option<u64>,
    /// Folder the report folder goes into (default `reports`, relative to the working directory).
    pub output: Option<PathBuf>,
    /// Where the measurements come from.
    pub data: RawData,
    /// The split design (section IV-E of the paper).
    pub split: Option<RawSplit>,
    /// The models to build and compare, each a kinematic stage and an optional residual stage.
    #[serde(default, rename = "model")]
    pub models: Vec<RawModel>,
    /// Which model fills which paper table.
    pub tables: Option<RawTables>,
}

/// `[data]` as written.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawData {
    /// A twin description: measurements are generated from it in memory (unless `measurements`
    /// is given), and its truth fills Table 4.
    pub twin: Option<PathBuf>,
    /// The nominal robot table (default: the twin's).
    pub robot: Option<PathBuf>,
    /// A measurement CSV (default: generated from the twin).
    pub measurements: Option<PathBuf>,
}

/// `[split]` as written.
#[derive(Debug, Clone, Serialize, Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub struct RawSplit {
    /// Configurations drawn (by the seed) for training; the rest are untrained (paper: 112).
    pub trained_configurations: Option<usize>,
    /// Loads never trained on (default: the twin's `[loads] untrained`; required without a twin).
    pub untrained_loads: Option<Vec<f64>>,
    /// Trained loads (drawn by the seed) whose untrained-configuration rows validate: GB20
    /// (paper: 6).
    pub validation_loads: Option<usize>,
    /// Load of the rows the kinematic stage fits (default: the lightest trained load).
    pub kinematic_load: Option<f64>,
}

/// `[[model]]` as written.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawModel {
    /// Name in tables and plots, unique in the experiment.
    pub name: String,
    /// `[model.kinematic]`, as in a stage config (absent: LM, every parameter).
    pub kinematic: Option<robocal_ident::RawKinematicStage>,
    /// `[model.compliance]`, as in a stage config (absent: a rigid arm).
    pub compliance: Option<robocal_ident::RawComplianceStage>,
    /// `[model.joint_errors]`, as in a stage config (absent: none).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub joint_errors: Option<robocal_ident::RawJointErrorStage>,
    /// `[model.residual]`, as in a stage config (absent: none).
    pub residual: Option<robocal_residual::RawResidualStage>,
}

/// `[tables]` as written.
#[derive(Debug, Clone, Serialize, Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub struct RawTables {
    /// The model whose train/validation/test errors fill Table 5 (default: the first SOMM model
    /// on a BFGS kinematic stage, else the first SOMM model).
    pub table5: Option<String>,
}

/// Where the data come from, paths resolved.
#[derive(Debug, Clone, PartialEq)]
pub enum DataSource {
    /// A twin: its nominal table unless `robot` is given, measurements generated from it in
    /// memory unless `measurements` is given; its truth fills Table 4.
    Twin {
        /// Twin description.
        twin: PathBuf,
        /// Nominal robot table, instead of the twin's.
        robot: Option<PathBuf>,
        /// Measurement CSV, instead of generated ones.
        measurements: Option<PathBuf>,
    },
    /// A robot table and its measurements.
    Files {
        /// Nominal robot table.
        robot: PathBuf,
        /// Measurement CSV.
        measurements: PathBuf,
    },
}

impl DataSource {
    /// The twin description, if the data come from one.
    pub fn twin(&self) -> Option<&Path> {
        match self {
            Self::Twin { twin, .. } => Some(twin),
            Self::Files { .. } => None,
        }
    }

    /// The nominal robot table, if a file gives it.
    pub fn robot(&self) -> Option<&Path> {
        match self {
            Self::Twin { robot, .. } => robot.as_deref(),
            Self::Files { robot, .. } => Some(robot),
        }
    }

    /// The measurement CSV, if a file gives them.
    pub fn measurements(&self) -> Option<&Path> {
        match self {
            Self::Twin { measurements, .. } => measurements.as_deref(),
            Self::Files { measurements, .. } => Some(measurements),
        }
    }
}

/// The split design; sizes are checked against the data when it runs.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SplitDesign {
    /// Trained configurations.
    pub trained_configurations: usize,
    /// Untrained loads (`None`: the twin's).
    pub untrained_loads: Option<Vec<f64>>,
    /// Validation loads drawn from the trained ones.
    pub validation_loads: usize,
    /// Load of the kinematic rows (`None`: the lightest trained load).
    pub kinematic_load: Option<f64>,
}

/// One model to build: its stages.
#[derive(Debug, Clone, PartialEq)]
pub struct ModelPlan {
    /// Name in tables and plots.
    pub name: String,
    /// Kinematic, then residual.
    pub stages: Stages,
}

impl ModelPlan {
    /// The paper's Table 6 row this model corresponds to, if any (mean, std, max in mm).
    /// Only a model with the paper's CA-SOMM gate (hard, every axis per class) gets its row.
    pub fn paper_row(&self) -> Option<(&'static str, [f64; 3])> {
        let residual = self.stages.residual.as_ref().map(|r| &r.settings);
        if let Some(s) = residual
            && s.kind == ResidualKind::CaSomm
            && (s.classifier.gate != Gate::Hard || s.classifier.per_class != PerClass::All)
        {
            return None;
        }
        crate::paper::table6_row(self.stages.kinematic.solver, residual.map(|s| s.kind))
    }
}

/// A validated experiment.
#[derive(Debug, Clone, PartialEq)]
pub struct Experiment {
    /// The file it came from.
    pub source: PathBuf,
    /// Name (and report folder).
    pub name: String,
    /// What it shows.
    pub description: Option<String>,
    /// Seed of the split (and of residual models without their own).
    pub seed: u64,
    /// Folder the report folder goes into.
    pub output: PathBuf,
    /// Where the data come from.
    pub data: DataSource,
    /// The split design.
    pub split: SplitDesign,
    /// Models in the order they are built and shown.
    pub models: Vec<ModelPlan>,
    /// Index into `models` of the Table 5 model.
    pub table5: Option<usize>,
}

/// Default seed of an experiment: the one seed robocal uses wherever none is given.
pub use robocal_residual::DEFAULT_SEED;

/// `a/b/../c` → `a/c`, lexically (no file system access); leading `..` are kept.
fn tidy(path: &Path) -> PathBuf {
    use std::path::Component;
    let mut out: Vec<Component<'_>> = Vec::new();
    for c in path.components() {
        match c {
            Component::CurDir => {}
            Component::ParentDir if matches!(out.last(), Some(Component::Normal(_))) => {
                out.pop();
            }
            other => out.push(other),
        }
    }
    if out.is_empty() {
        PathBuf::from(".")
    } else {
        out.iter().collect()
    }
}

impl Experiment {
    /// Reads and validates an experiment file.
    pub fn load(path: &Path) -> Result<Self> {
        let text = read_text(path)?;
        let raw: RawExperiment =
            toml::from_str(&text).map_err(|e| CalibrationError::toml(path, &text, &e))?;
        raw.validate(path)
    }
}

impl RawExperiment {
    /// Validates into an experiment; `path` is the file (relative paths resolve against its
    /// folder, errors name it).
    pub fn validate(&self, path: &Path) -> Result<Experiment> {
        let folder = path.parent().unwrap_or(Path::new(""));
        let resolve = |p: &Option<PathBuf>| p.as_ref().map(|p| tidy(&folder.join(p)));
        let name_ok = !self.name.is_empty()
            && !self.name.starts_with('.')
            && self
                .name
                .chars()
                .all(|c| c.is_ascii_alphanumeric() || matches!(c, '-' | '_' | '.'));
        if !name_ok {
            return Err(key(
                path,
                "name",
                format!(
                    "`{}` cannot name a report folder; use letters, digits, `-`, `_` and `.`",
                    self.name
                ),
            ));
        }
        let seed = self.seed.unwrap_or(DEFAULT_SEED);
        let data = match (
            resolve(&self.data.twin),
            resolve(&self.data.robot),
            resolve(&self.data.measurements),
        ) {
            (Some(twin), robot, measurements) => DataSource::Twin {
                twin,
                robot,
                measurements,
            },
            (None, Some(robot), Some(measurements)) => DataSource::Files {
                robot,
                measurements,
            },
            _ => {
                return Err(key(
                    path,
                    "data",
                    "give a `twin`, or a `robot` and its `measurements`",
                ));
            }
        };
        let design = self.split_design(path, &data)?;
        if self.models.is_empty() {
            return Err(key(
                path,
                "model",
                "lists no model; add at least one [[model]] with a name",
            ));
        }
        let models = self.model_plans(path, seed)?;
        let is_somm = |m: &ModelPlan| {
            m.stages.residual.as_ref().map(|r| r.settings.kind) == Some(ResidualKind::Somm)
        };
        let table5 = match self.tables.as_ref().and_then(|t| t.table5.as_ref()) {
            Some(name) => Some(models.iter().position(|m| &m.name == name).ok_or_else(|| {
                key(
                    path,
                    "tables.table5",
                    format!("no [[model]] is named `{name}`"),
                )
            })?),
            None => models
                .iter()
                .position(|m| is_somm(m) && m.stages.kinematic.solver == SolverKind::Bfgs)
                .or_else(|| models.iter().position(is_somm)),
        };
        Ok(Experiment {
            source: path.to_path_buf(),
            name: self.name.clone(),
            description: self.description.clone(),
            seed,
            output: self
                .output
                .clone()
                .unwrap_or_else(|| PathBuf::from("reports")),
            data,
            split: design,
            models,
            table5,
        })
    }

    /// The split's design, checked (`data`: where the rows come from; without a twin the
    /// untrained loads must be listed).
    fn split_design(&self, path: &Path, data: &DataSource) -> Result<SplitDesign> {
        let split = self.split.clone().unwrap_or_default();
        if data.twin().is_none() && split.untrained_loads.is_none() {
            return Err(key(
                path,
                "split.untrained_loads",
                "required when the data do not come from a twin (list them, or `[]` for none)",
            ));
        }
        let design = SplitDesign {
            trained_configurations: split.trained_configurations.unwrap_or(112),
            untrained_loads: split.untrained_loads.clone(),
            validation_loads: split.validation_loads.unwrap_or(6),
            kinematic_load: split.kinematic_load,
        };
        if design.trained_configurations == 0 {
            return Err(key(
                path,
                "split.trained_configurations",
                "must be at least 1",
            ));
        }
        if design.validation_loads == 0 {
            return Err(key(path, "split.validation_loads", "must be at least 1"));
        }
        if let Some(loads) = &design.untrained_loads
            && let Some(l) = loads.iter().find(|l| !(l.is_finite() && **l >= 0.0))
        {
            return Err(key(
                path,
                "split.untrained_loads",
                format!("{l} is not a load (kg, finite, not negative)"),
            ));
        }
        if let Some(l) = design.kinematic_load
            && !(l.is_finite() && l >= 0.0)
        {
            return Err(key(
                path,
                "split.kinematic_load",
                "must be a finite load, not negative (kg)",
            ));
        }
        Ok(design)
    }

    /// Each `[[model]]`'s stages, validated (named once each, residuals in the world frame).
    fn model_plans(&self, path: &Path, seed: u64) -> Result<Vec<ModelPlan>> {
        let mut models: Vec<ModelPlan> = Vec::new();
        for (i, m) in self.models.iter().enumerate() {
            let at = format!("model[{}]", i + 1);
            if m.name.trim().is_empty() {
                return Err(key(path, format!("{at}.name"), "is empty"));
            }
            if models.iter().any(|o| o.name == m.name) {
                return Err(key(
                    path,
                    format!("{at}.name"),
                    format!("`{}` names two models", m.name),
                ));
            }
            let stages = RawStages {
                kinematic: m.kinematic.clone(),
                compliance: m.compliance.clone(),
                joint_errors: m.joint_errors.clone(),
                residual: m.residual.clone(),
                default: None,
            }
            .validate(Some(seed), robocal_residual::Defaults::Paper)
            .map_err(|e| invalid(path, e.within(&at)))?;
            // An experiment scores its residual models on the world frame's errors, as the
            // paper's tables do; a frame turning with joint 1 is `calibrate`'s.
            if let Some(r) = stages.residual.as_ref()
                && !r.settings.frame.is_world()
            {
                return Err(key(
                    path,
                    format!("{at}.residual.frame"),
                    format!(
                        "`{}`: an experiment learns residuals in the world frame (the paper's); a frame turning with joint 1 is for `calibrate --config`",
                        r.settings.frame.name()
                    ),
                ));
            }
            models.push(ModelPlan {
                name: m.name.clone(),
                stages,
            });
        }
        Ok(models)
    }
}

impl Experiment {
    /// The experiment as it ran, every default filled in and paths made absolute, given the
    /// untrained and kinematic loads the split settled on: an experiment file (written beside
    /// the report as `experiment.toml`) that runs the same experiment from anywhere.
    pub fn resolved(&self, untrained_loads: Vec<f64>, kinematic_load: f64) -> RawExperiment {
        let absolute = |p: &Option<PathBuf>| {
            p.as_ref()
                .map(|p| std::path::absolute(p).unwrap_or_else(|_| p.clone()))
        };
        RawExperiment {
            name: self.name.clone(),
            description: self.description.clone(),
            seed: Some(self.seed),
            // The report is where it is; a rerun chooses its own place.
            output: None,
            data: RawData {
                twin: absolute(&self.data.twin().map(Path::to_path_buf)),
                robot: absolute(&self.data.robot().map(Path::to_path_buf)),
                measurements: absolute(&self.data.measurements().map(Path::to_path_buf)),
            },
            split: Some(RawSplit {
                trained_configurations: Some(self.split.trained_configurations),
                untrained_loads: Some(untrained_loads),
                validation_loads: Some(self.split.validation_loads),
                kinematic_load: Some(kinematic_load),
            }),
            models: self
                .models
                .iter()
                .map(|m| {
                    let k = &m.stages.kinematic;
                    RawModel {
                        name: m.name.clone(),
                        kinematic: Some(robocal_ident::RawKinematicStage {
                            solver: Some(k.solver.name().to_string()),
                            parameters: k.parameters.clone(),
                            max_iterations: Some(k.max_iterations),
                            rank_tolerance: Some(k.rank_tolerance),
                            loss: (k.loss == robocal_ident::Loss::Huber).then(|| "huber".into()),
                            angle_weight: k.angle_weight,
                            // Stated only when not the defaults (resolved files stay as they were).
                            noise_mm: (k.noise_mm != robocal_ident::DEFAULT_NOISE_MM)
                                .then_some(k.noise_mm),
                            noise_deg: (k.noise_deg != robocal_ident::DEFAULT_NOISE_DEG)
                                .then_some(k.noise_deg),
                        }),
                        compliance: k
                            .compliance
                            .as_ref()
                            .map(robocal_ident::RawComplianceStage::from_settings),
                        joint_errors: k
                            .joint_errors
                            .as_ref()
                            .map(robocal_ident::RawJointErrorStage::from_settings),
                        residual: m.stages.residual.as_ref().map(|r| {
                            let s = &r.settings;
                            robocal_residual::RawResidualStage {
                                model: s.kind.name().to_string(),
                                defaults: None,
                                seed: Some(s.seed),
                                members: (s.members > 1).then_some(s.members),
                                holdout: Some(r.holdout),
                                x: Some(s.axes[0].clone()),
                                y: Some(s.axes[1].clone()),
                                z: Some(s.axes[2].clone()),
                                mosm: Some(s.mosm.clone()),
                                classifier: Some(s.classifier.clone()),
                                search: s.search.clone(),
                                encoding: (s.kind == ResidualKind::Gp || !s.encoding.is_raw())
                                    .then_some(s.encoding),
                                frame: (!s.frame.is_world()).then_some(s.frame),
                                gp: (s.kind == ResidualKind::Gp).then(|| s.gp.clone()),
                            }
                        }),
                    }
                })
                .collect(),
            tables: Some(RawTables {
                table5: self.table5.map(|i| self.models[i].name.clone()),
            }),
        }
    }
}
