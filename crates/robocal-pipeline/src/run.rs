//! Running an experiment: data, split, every model's stages, and every statistic the report and
//! the plots need.

use std::collections::BTreeMap;
use std::path::Path;
use std::time::Instant;

use nalgebra::Vector3;
use robocal_data::{ErrorStats, Invalid, Measurement, MeasurementSet, Observer, Sample};
use robocal_ident::{
    KinematicCalibration, KinematicReport, KinematicSettings, Observations, align,
    calibrate_kinematics,
};
use robocal_model::{CalibratedModel, with_gate_physics};
use robocal_residual::{GatePhysics, ResidualModel, Samples, inputs_of};
use robocal_robot::{ParamId, Robot};
use robocal_twin::TwinConfig;
use serde::Serialize;

use crate::error::{PipelineError, Result};
use crate::experiment::{DataSource, Experiment};
use crate::split::{Set, Splits};
use robocal_calibration::{GateSummary, gate_ready, gate_summary, physical_model};

/// Named groups of rows that the statistics are given for.
pub const GROUPS: [&str; 10] = [
    "GA10",
    "GA20",
    "GB20",
    "GB10",
    "GB30",
    "test",
    "table6",
    "kinematic_fit",
    "kinematic_held_out",
    "all",
];

/// The rows of a named group.
pub fn group_rows(splits: &Splits, group: &str) -> Vec<usize> {
    match group {
        "GA10" => splits.rows(&[Set::Ga10]),
        "GA20" => splits.rows(&[Set::Ga20]),
        "GB20" => splits.rows(&[Set::Gb20]),
        "GB10" => splits.rows(&[Set::Gb10]),
        "GB30" => splits.rows(&[Set::Gb30]),
        "test" => splits.rows(&[Set::Ga20, Set::Gb10, Set::Gb30]),
        "table6" => splits.rows(&[Set::Gb10, Set::Gb30]),
        "kinematic_fit" => splits.kinematic_rows.clone(),
        "kinematic_held_out" => splits.kinematic_held_out_rows.clone(),
        _ => (0..splits.set_of_row.len()).collect(),
    }
}

/// Error statistics (of the Euclidean norm) of `rows` of `errors`.
pub fn stats(errors: &[Vector3<f64>], rows: &[usize]) -> ErrorStats {
    let norms: Vec<f64> = rows.iter().map(|&i| errors[i].norm()).collect();
    ErrorStats::from_errors(&norms)
}

/// Root mean square of each axis's signed error over `rows`, mm.
pub fn axis_rms(errors: &[Vector3<f64>], rows: &[usize]) -> [f64; 3] {
    let mut s = [0.0; 3];
    for &i in rows {
        for (a, v) in s.iter_mut().enumerate() {
            *v += errors[i][a].powi(2);
        }
    }
    s.map(|v| (v / rows.len().max(1) as f64).sqrt())
}

/// Residual samples of `rows`: their inputs, and the kinematic errors already computed for every
/// row (no second pass through the kinematics).
/// With `gate` (the identified model and the physics of a CA-SOMM gate that reads it), each
/// row's physics features too.
fn samples(
    data: &[Measurement],
    errors: &[Vector3<f64>],
    rows: &[usize],
    gate: Option<(&CalibratedModel, &GatePhysics)>,
) -> Samples {
    let s = Samples::new(
        rows.iter().map(|&i| inputs_of(&data[i].sample)).collect(),
        rows.iter().map(|&i| errors[i].into()).collect(),
    );
    match gate {
        Some((model, p)) => {
            let picked: Vec<&Sample> = rows.iter().map(|&i| &data[i].sample).collect();
            with_gate_physics(s, &model.robot, Some(p), &picked)
        }
        None => s,
    }
}

/// One kinematic identification (shared by every model with the same kinematic settings).
#[derive(Debug)]
pub struct KinematicRun {
    /// Column label (`LM`, `BFGS`, `LM 2`, …).
    pub label: String,
    /// Settings.
    pub settings: KinematicSettings,
    /// The identification.
    pub calibration: KinematicCalibration,
    /// Its errors on every row.
    pub errors: Vec<Vector3<f64>>,
    /// Seconds it took.
    pub seconds: f64,
}

/// One model built.
#[derive(Debug)]
pub struct ModelRun {
    /// Name.
    pub name: String,
    /// Index of its kinematic stage in [`Outcome::kinematics`].
    pub kinematic: usize,
    /// The residual model, if the model has one.
    pub residual: Option<ResidualModel>,
    /// Errors of the whole model on every row.
    pub errors: Vec<Vector3<f64>>,
    /// Seconds its residual training took.
    pub residual_seconds: f64,
}

/// Everything an experiment produced.
#[derive(Debug)]
pub struct Outcome {
    /// The experiment.
    pub experiment: Experiment,
    /// The nominal table.
    pub nominal: Robot,
    /// The twin, if the data come from one.
    pub twin: Option<TwinConfig>,
    /// The measurements.
    pub data: MeasurementSet,
    /// Whether the measurements were generated in memory from the twin.
    pub generated: bool,
    /// The split.
    pub splits: Splits,
    /// Nominal table with base and tool fitted on the kinematic rows: "before".
    pub before: Vec<Vector3<f64>>,
    /// Distinct kinematic identifications.
    pub kinematics: Vec<KinematicRun>,
    /// The models, in the experiment's order.
    pub models: Vec<ModelRun>,
    /// Seconds per phase.
    pub timings: Timings,
}

/// Seconds per phase.
#[derive(Debug, Clone, Default, Serialize)]
pub struct Timings {
    /// Loading or generating the data.
    pub data_s: f64,
    /// Every kinematic identification.
    pub kinematic_s: f64,
    /// Every residual training.
    pub residual_s: f64,
    /// Drawing the plots and writing the report.
    pub report_s: f64,
    /// The whole run.
    pub total_s: f64,
}

fn key_error(e: &Experiment, invalid: Invalid) -> PipelineError {
    crate::error::invalid(&e.source, invalid)
}

/// The nominal table, the twin (if any), the measurements, and whether they were generated
/// from the twin.
fn load_data(
    experiment: &Experiment,
    observer: &dyn Observer,
) -> Result<(Robot, Option<TwinConfig>, MeasurementSet, bool)> {
    Ok(match &experiment.data {
        DataSource::Files {
            robot,
            measurements,
        } => {
            let nominal = Robot::load(robot)?;
            let data = MeasurementSet::read(measurements, nominal.dof())?;
            (nominal, None, data, false)
        }
        DataSource::Twin {
            twin,
            robot,
            measurements,
        } => {
            let twin = TwinConfig::load(twin)?;
            let nominal = match robot {
                Some(path) => Robot::load(path)?,
                None => twin.nominal.clone(),
            };
            let (data, generated) = match measurements {
                Some(path) => (MeasurementSet::read(path, nominal.dof())?, false),
                None => {
                    observer.message(&format!(
                        "generating the twin's measurements ({})",
                        twin.name
                    ));
                    (twin.generate()?.measurements, true)
                }
            };
            (nominal, Some(twin), data, generated)
        }
    })
}

/// Every distinct kinematic stage of the experiment's models, identified once: the runs, and
/// each model's run.
fn identify_all(
    experiment: &Experiment,
    nominal: &Robot,
    data: &MeasurementSet,
    obs: &Observations,
    loaded_obs: &Observations,
    observer: &dyn Observer,
) -> Result<(Vec<KinematicRun>, Vec<usize>)> {
    let mut kinematics: Vec<KinematicRun> = Vec::new();
    let mut model_kin = Vec::new();
    for m in &experiment.models {
        if let Some(i) = kinematics
            .iter()
            .position(|k| k.settings == m.stages.kinematic)
        {
            model_kin.push(i);
            continue;
        }
        let settings = m.stages.kinematic.clone();
        let mut solver = settings.solver.name().to_uppercase();
        if settings.compliance.is_some() {
            solver += "+C";
        }
        let same = kinematics
            .iter()
            .filter(|k| {
                k.settings.solver == settings.solver
                    && k.settings.compliance.is_some() == settings.compliance.is_some()
            })
            .count();
        let label = if same == 0 {
            solver
        } else {
            format!("{solver} {}", same + 1)
        };
        let k0 = Instant::now();
        let rows = if settings.compliance.is_some() {
            loaded_obs
        } else {
            obs
        };
        let calibration = calibrate_kinematics(nominal, rows, &settings)?;
        let seconds = k0.elapsed().as_secs_f64();
        observer.message(&format!(
            "kinematic {label}: {} points, mean {:.3} → {:.3} mm, {} iterations, {:.2} s",
            calibration.report.points,
            calibration.report.before.mean,
            calibration.report.after.mean,
            calibration.report.iterations,
            seconds
        ));
        let errors = physical_model(&calibration).residuals(&data.rows);
        model_kin.push(kinematics.len());
        kinematics.push(KinematicRun {
            label,
            settings,
            calibration,
            errors,
            seconds,
        });
    }
    Ok((kinematics, model_kin))
}

/// Runs every stage of every model of `experiment`; `observer` hears a line per step and the
/// epochs of each residual model's training.
pub fn run(experiment: &Experiment, observer: &dyn Observer) -> Result<Outcome> {
    let say = |line: &str| observer.message(line);
    let start = Instant::now();
    let (nominal, twin, data, generated) = load_data(experiment, observer)?;
    let data_s = start.elapsed().as_secs_f64();
    let splits = Splits::new(
        &data.rows,
        &experiment.split,
        twin.as_ref().map(|t| t.loads.untrained.as_slice()),
        experiment.seed,
    )
    .map_err(|e| key_error(experiment, e))?;
    let sizes: Vec<String> = splits
        .sizes()
        .iter()
        .map(|(s, n)| format!("{} {n}", s.name()))
        .collect();
    say(&format!(
        "{} rows, {} + {} configurations, split (seed {}): {}",
        data.len(),
        splits.trained_configurations.len(),
        splits.untrained_configurations.len(),
        experiment.seed,
        sizes.join(", ")
    ));

    let kin_rows: Vec<&Measurement> = splits
        .kinematic_rows
        .iter()
        .map(|&i| &data.rows[i])
        .collect();
    let obs = Observations::from_rows(nominal.dof(), kin_rows.iter().copied());
    let aligned = align(&nominal, &obs)?;
    let before = CalibratedModel::kinematic(aligned.clone()).residuals(&data.rows);

    // Elasto-geometric identifications see every load of the trained configurations (GA10).
    let train_rows = group_rows(&splits, "GA10");
    let loaded_obs =
        Observations::from_rows(nominal.dof(), train_rows.iter().map(|&i| &data.rows[i]));
    let t = Instant::now();
    let (kinematics, model_kin) =
        identify_all(experiment, &nominal, &data, &obs, &loaded_obs, observer)?;
    let kinematic_s = t.elapsed().as_secs_f64();

    let t = Instant::now();
    let val_rows = group_rows(&splits, "GB20");
    let mut models = Vec::new();
    for (i, (m, &k)) in experiment.models.iter().zip(&model_kin).enumerate() {
        let kin = &kinematics[k];
        let Some(stage) = &m.stages.residual else {
            models.push(ModelRun {
                name: m.name.clone(),
                kinematic: k,
                residual: None,
                errors: kin.errors.clone(),
                residual_seconds: 0.0,
            });
            continue;
        };
        let physical = physical_model(&kin.calibration);
        let settings = gate_ready(&stage.settings, &physical);
        let physics = settings.classifier.physics();
        let gate = physics.as_ref().map(|p| (&physical, p));
        let train = samples(&data.rows, &kin.errors, &train_rows, gate);
        let val = samples(&data.rows, &kin.errors, &val_rows, gate);
        if train.is_empty() || val.is_empty() {
            return Err(key_error(
                experiment,
                Invalid::new(
                    "split",
                    format!(
                        "model `{}` needs training (GA10) and validation (GB20) rows; this split has {} and {}",
                        m.name,
                        train.len(),
                        val.len()
                    ),
                ),
            ));
        }
        observer.start(
            &format!(
                "[{}/{}] {}, epochs (at most)",
                i + 1,
                experiment.models.len(),
                m.name
            ),
            ResidualModel::max_epochs(&stage.settings),
        );
        let r0 = Instant::now();
        let model = ResidualModel::fit(&settings, &train, &val, observer);
        observer.finish();
        let model = model?;
        let residual_seconds = r0.elapsed().as_secs_f64();
        let every: Vec<usize> = (0..data.rows.len()).collect();
        let predicted = model.predict(&samples(&data.rows, &kin.errors, &every, gate));
        let errors: Vec<Vector3<f64>> = kin
            .errors
            .iter()
            .zip(&predicted)
            .map(|(e, p)| e - Vector3::new(p[0], p[1], p[2]))
            .collect();
        say(&format!(
            "{}: {} trained in {:.1} s; GB20 mean {:.3} → {:.3} mm",
            m.name,
            stage.settings.kind.name(),
            residual_seconds,
            stats(&kin.errors, &val_rows).mean,
            stats(&errors, &val_rows).mean
        ));
        models.push(ModelRun {
            name: m.name.clone(),
            kinematic: k,
            residual: Some(model),
            errors,
            residual_seconds,
        });
    }
    let residual_s = t.elapsed().as_secs_f64();
    Ok(Outcome {
        experiment: experiment.clone(),
        nominal,
        twin,
        data,
        generated,
        splits,
        before,
        kinematics,
        models,
        timings: Timings {
            data_s,
            kinematic_s,
            residual_s,
            report_s: 0.0,
            total_s: start.elapsed().as_secs_f64(),
        },
    })
}

/// `results.json`: what ran and every figure, machine-readable.
#[derive(Debug, Serialize)]
pub struct Summary<'a> {
    /// Experiment name.
    pub experiment: String,
    /// Its description.
    pub description: Option<String>,
    /// robocal's version.
    pub robocal_version: &'static str,
    /// Seed of the split.
    pub seed: u64,
    /// Where the data came from.
    pub data: DataSummary,
    /// The split.
    pub split: SplitSummary<'a>,
    /// Nominal table (base and tool fitted) per group of rows.
    pub before: BTreeMap<String, ErrorStats>,
    /// Each kinematic identification.
    pub kinematic: Vec<KinematicSummary>,
    /// Each model.
    pub models: Vec<ModelSummary>,
    /// Table 4: the identified parameters beside the twin's truth and the nominal table.
    pub table4: Vec<Table4Row>,
    /// Seconds per phase (wall clock; the one part that differs between identical runs).
    pub timings: Timings,
}

/// The data in `results.json`.
#[derive(Debug, Serialize)]
pub struct DataSummary {
    /// Twin description, if any.
    pub twin: Option<std::path::PathBuf>,
    /// Twin seed, if any.
    pub twin_seed: Option<u64>,
    /// Whether the rows were generated in memory from the twin.
    pub generated_from_twin: bool,
    /// Measurement file, if read from one.
    pub measurements: Option<std::path::PathBuf>,
    /// Rows.
    pub rows: usize,
    /// Distinct configurations.
    pub configurations: usize,
    /// Distinct loads, kg.
    pub loads: Vec<f64>,
}

/// The split in `results.json`: the split's members and loads, with the size of each set.
#[derive(Debug, Serialize)]
pub struct SplitSummary<'a> {
    /// Rows per set.
    pub sizes: BTreeMap<String, usize>,
    /// Kinematic rows fitted (trained configurations at the kinematic load).
    pub kinematic_fit_rows: usize,
    /// Kinematic rows held out (untrained configurations at the kinematic load).
    pub kinematic_held_out_rows: usize,
    /// Configurations and loads of the split.
    #[serde(flatten)]
    pub split: &'a Splits,
}

/// One kinematic identification in `results.json`.
#[derive(Debug, Serialize)]
pub struct KinematicSummary {
    /// Column label.
    pub label: String,
    /// Models that use it.
    pub models: Vec<String>,
    /// The identification's own report (parameters, σ, identifiability, fit).
    pub report: KinematicReport,
    /// Cross-validation: the untrained configurations at the kinematic load.
    pub held_out: ErrorStats,
    /// Seconds.
    pub seconds: f64,
}

/// One model in `results.json`.
#[derive(Debug, Serialize)]
pub struct ModelSummary {
    /// Name.
    pub name: String,
    /// Label of its kinematic stage.
    pub kinematic: String,
    /// Residual model kind, if any.
    pub residual: Option<&'static str>,
    /// Kinematics alone, per group.
    pub after_kinematic: BTreeMap<String, ErrorStats>,
    /// The whole model, per group.
    pub after: BTreeMap<String, ErrorStats>,
    /// RMS of the signed X, Y, Z errors on the Table 6 rows, kinematics alone and whole model.
    pub table6_axis_rms: [[f64; 3]; 2],
    /// Mean error of the whole model at each load over the untrained configurations.
    pub mean_by_load: Vec<(f64, f64)>,
    /// Networks: axes, epochs run, best epoch.
    pub networks: Vec<NetworkSummary>,
    /// CA-SOMM: threshold and the classifier's accuracy per group.
    pub classifier: Option<ClassifierSummary>,
    /// Seconds the residual training took.
    pub residual_seconds: f64,
    /// The paper's Table 6 row that corresponds, if any: (label, mean/std/max).
    pub paper_table6: Option<(&'static str, [f64; 3])>,
}

/// One network in `results.json`.
#[derive(Debug, Serialize)]
pub struct NetworkSummary {
    /// Axes it predicts (`x`, `xyz`, …).
    pub axes: String,
    /// Hidden layers.
    pub hidden: Vec<usize>,
    /// Epochs run.
    pub epochs: usize,
    /// Epoch whose weights were kept.
    pub best_epoch: usize,
}

/// The CA-SOMM classifier in `results.json`.
#[derive(Debug, Serialize)]
pub struct ClassifierSummary {
    /// Axis error at or above which a row is class B, mm.
    pub threshold: f64,
    /// Accuracy on GA10 (training), GB20 (validation), test.
    pub accuracy: BTreeMap<String, f64>,
    /// Its classes, what it reads and splits on.
    pub gate: Option<GateSummary>,
}

/// One parameter of Table 4.
#[derive(Debug, Serialize)]
pub struct Table4Row {
    /// Parameter name.
    pub name: String,
    /// `mm` or `deg`.
    pub unit: &'static str,
    /// Nominal value.
    pub nominal: f64,
    /// The twin's true value (the paper's identified Table 4 for the bundled twin).
    pub truth: Option<f64>,
    /// Identified value per kinematic label (`None`: held fixed).
    pub identified: Vec<(String, Option<f64>)>,
    /// Standard deviation of the first kinematic identification.
    pub std: Option<f64>,
}

impl Outcome {
    /// Whether the experiment is on the paper's robot (the robot file named `PMC6VA030`): only
    /// then do the reports print the paper's numbers beside ours.
    pub fn is_papers(&self) -> bool {
        self.nominal.name == "PMC6VA030"
    }

    /// Rows of a named group.
    pub fn rows(&self, group: &str) -> Vec<usize> {
        group_rows(&self.splits, group)
    }

    /// Statistics of `errors` per group.
    pub fn by_group(&self, errors: &[Vector3<f64>]) -> BTreeMap<String, ErrorStats> {
        GROUPS
            .iter()
            .map(|g| (g.to_string(), stats(errors, &self.rows(g))))
            .collect()
    }

    /// Mean error per load over the untrained configurations.
    pub fn mean_by_load(&self, errors: &[Vector3<f64>]) -> Vec<(f64, f64)> {
        let mut loads: Vec<f64> = self.data.loads();
        loads.sort_by(f64::total_cmp);
        let untrained_rows = self.splits.rows(&[Set::Gb20, Set::Gb10, Set::Gb30]);
        loads
            .iter()
            .map(|&l| {
                let rows: Vec<usize> = untrained_rows
                    .iter()
                    .copied()
                    .filter(|&i| self.data.rows[i].sample.load == l)
                    .collect();
                (l, stats(errors, &rows).mean)
            })
            .collect()
    }

    /// The class (0 = A, 1 = B) a model's CA-SOMM gate gives each of `rows`; `None` without a
    /// gate.
    pub fn gate_classes(&self, model: &ModelRun, rows: &[usize]) -> Option<Vec<usize>> {
        let (residual, raw) = self.residual_samples(model, rows)?;
        let c = residual.classifier()?;
        let encoded = residual.encoding.encode_all(&raw.inputs);
        Some(c.classify(&c.rows(&encoded, &raw)))
    }

    /// A model's residual model, and `rows` as its samples: inputs, the kinematic errors, and
    /// the physics rows its gate reads (from the model's identified table); `None` without a
    /// residual model.
    fn residual_samples<'a>(
        &self,
        model: &'a ModelRun,
        rows: &[usize],
    ) -> Option<(&'a ResidualModel, Samples)> {
        let kin = &self.kinematics[model.kinematic];
        let residual = model.residual.as_ref()?;
        let physical = physical_model(&kin.calibration);
        let physics = residual.gate_physics();
        let gate = physics.as_ref().map(|p| (&physical, p));
        Some((residual, samples(&self.data.rows, &kin.errors, rows, gate)))
    }

    /// The CA-SOMM gate of a model, summarised on its training rows (GA10).
    fn gate(&self, model: &ModelRun) -> Option<GateSummary> {
        let (residual, train) = self.residual_samples(model, &self.rows("GA10"))?;
        gate_summary(residual, self.nominal.dof(), &train)
    }

    /// Classifier accuracy of a model on a group.
    fn accuracy(&self, model: &ModelRun, group: &str) -> Option<f64> {
        let (residual, rows) = self.residual_samples(model, &self.rows(group))?;
        residual.classifier_accuracy(&rows)
    }

    /// Table 4 rows: every joint parameter (base and tool frames are left to `results.json`'s
    /// kinematic reports).
    pub fn table4(&self) -> Vec<Table4Row> {
        let mut rows = Vec::new();
        for id in self.nominal.param_ids() {
            if matches!(
                id,
                ParamId::Base(_) | ParamId::Tool(_) | ParamId::ToolRot(_) | ParamId::Point { .. }
            ) {
                continue;
            }
            let name = id.to_string();
            let report = |k: &KinematicRun| {
                k.calibration
                    .report
                    .parameters
                    .iter()
                    .find(|p| p.name == name)
                    .cloned()
            };
            let first = self.kinematics.first().and_then(report);
            rows.push(Table4Row {
                unit: id.file_unit_name(),
                nominal: id.to_file_units(self.nominal.param(id)),
                truth: self
                    .twin
                    .as_ref()
                    .filter(|t| t.truth.has_param(id))
                    .map(|t| id.to_file_units(t.truth.param(id))),
                identified: self
                    .kinematics
                    .iter()
                    .map(|k| {
                        let value = report(k)
                            .filter(|p| p.identified_flag)
                            .map(|p| p.identified);
                        (k.label.clone(), value)
                    })
                    .collect(),
                std: first.and_then(|p| p.std),
                name,
            });
        }
        rows
    }

    /// The machine-readable summary.
    pub fn summary(&self) -> Summary<'_> {
        let e = &self.experiment;
        let s = &self.splits;
        let mut loads = self.data.loads();
        loads.sort_by(f64::total_cmp);
        let configurations = s.trained_configurations.len() + s.untrained_configurations.len();
        let table6 = self.rows("table6");
        Summary {
            experiment: e.name.clone(),
            description: e.description.clone(),
            robocal_version: env!("CARGO_PKG_VERSION"),
            seed: e.seed,
            data: DataSummary {
                twin: e.data.twin().map(Path::to_path_buf),
                twin_seed: self.twin.as_ref().map(|t| t.seed),
                generated_from_twin: self.generated,
                measurements: e.data.measurements().map(Path::to_path_buf),
                rows: self.data.len(),
                configurations,
                loads,
            },
            split: SplitSummary {
                sizes: s
                    .sizes()
                    .iter()
                    .map(|(set, n)| (set.name().to_string(), *n))
                    .collect(),
                kinematic_fit_rows: s.kinematic_rows.len(),
                kinematic_held_out_rows: s.kinematic_held_out_rows.len(),
                split: s,
            },
            before: self.by_group(&self.before),
            kinematic: self
                .kinematics
                .iter()
                .enumerate()
                .map(|(k, run)| KinematicSummary {
                    label: run.label.clone(),
                    models: self
                        .models
                        .iter()
                        .filter(|m| m.kinematic == k)
                        .map(|m| m.name.clone())
                        .collect(),
                    report: run.calibration.report.clone(),
                    held_out: stats(&run.errors, &s.kinematic_held_out_rows),
                    seconds: run.seconds,
                })
                .collect(),
            models: self
                .models
                .iter()
                .zip(&e.models)
                .map(|(m, plan)| {
                    let kin = &self.kinematics[m.kinematic];
                    ModelSummary {
                        name: m.name.clone(),
                        kinematic: kin.label.clone(),
                        residual: m.residual.as_ref().map(|r| r.kind().name()),
                        after_kinematic: self.by_group(&kin.errors),
                        after: self.by_group(&m.errors),
                        table6_axis_rms: [
                            axis_rms(&kin.errors, &table6),
                            axis_rms(&m.errors, &table6),
                        ],
                        mean_by_load: self.mean_by_load(&m.errors),
                        networks: m
                            .residual
                            .iter()
                            .flat_map(|r| r.nets())
                            .map(|n| NetworkSummary {
                                axes: n.axes_name(),
                                hidden: n.settings.hidden.clone(),
                                epochs: n.report.epochs,
                                best_epoch: n.report.best_epoch,
                            })
                            .collect(),
                        classifier: m.residual.as_ref().and_then(|r| r.classifier()).map(|c| {
                            ClassifierSummary {
                                threshold: c.threshold,
                                accuracy: ["GA10", "GB20", "test"]
                                    .iter()
                                    .filter_map(|g| Some((g.to_string(), self.accuracy(m, g)?)))
                                    .collect(),
                                gate: self.gate(m),
                            }
                        }),
                        residual_seconds: m.residual_seconds,
                        paper_table6: plan.paper_row(),
                    }
                })
                .collect(),
            table4: self.table4(),
            timings: self.timings.clone(),
        }
    }
}
