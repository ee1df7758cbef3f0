//! A trained residual model: what the kinematic and joint-error model leaves, as a function of
//! the joint angles and the load.
//!
//! Each kind of model is one type in its own module that implements [`Residual`] (prediction on
//! encoded rows): [`Somm`], [`Mosm`], [`CaSomm`], [`GpResidual`]. [`ResidualModel`] holds one
//! of them ([`Fitted`]) with what every kind shares — the input length, the encoding, the
//! hyper-parameter search log — trains the one its [`ResidualSettings`] name
//! ([`ResidualModel::fit`]) and predicts on raw input rows. Its saved form is in
//! [`persist`](crate::persist).
//!
//! Adding a model: a module with its type, its `fit` and `impl Residual`; a [`ResidualKind`]
//! and a [`Fitted`] variant; its files in `persist`.

use robocal_data::{ErrorStats, Observer, SIGNIFICANCE, Silent, improves};

use crate::casomm::CaSomm;
use crate::classifier::{Classifier, GatePhysics};
use crate::error::{ResidualError, Result};
use crate::gp::GpResidual;
use crate::mlp::NetSettings;
use crate::mosm::Mosm;
use crate::net::AxisNet;
use crate::residual::Residual;
use crate::samples::{Encoding, Frame, Samples};
use crate::search::{SearchLog, search};
use crate::settings::{ResidualKind, ResidualSettings};
use crate::somm::Somm;

/// The fitted model of each kind.
#[derive(Debug, Clone)]
pub enum Fitted {
    /// One network per axis.
    Somm(Somm),
    /// One three-output network.
    Mosm(Mosm),
    /// A classifier and two SOMM sets.
    CaSomm(CaSomm),
    /// A Gaussian process per axis.
    Gp(GpResidual),
}

impl Fitted {
    /// The model behind the trait.
    pub fn model(&self) -> &dyn Residual {
        match self {
            Self::Somm(m) => m,
            Self::Mosm(m) => m,
            Self::CaSomm(m) => m,
            Self::Gp(m) => m,
        }
    }

    /// Which kind.
    pub fn kind(&self) -> ResidualKind {
        match self {
            Self::Somm(_) => ResidualKind::Somm,
            Self::Mosm(_) => ResidualKind::Mosm,
            Self::CaSomm(_) => ResidualKind::CaSomm,
            Self::Gp(_) => ResidualKind::Gp,
        }
    }
}

/// A trained residual model.
#[derive(Debug, Clone)]
pub struct ResidualModel {
    /// Length of an input row (joint angles, then the load).
    pub inputs: usize,
    /// How input rows are encoded before the model sees them.
    pub encoding: Encoding,
    /// The frame its errors are in ([`Frame`]): the caller turns them to the world's (the
    /// model's predictions are in this frame).
    pub frame: Frame,
    /// The hyper-parameter searches that chose the networks' settings (empty without search).
    pub search: Vec<SearchLog>,
    /// The model.
    pub fitted: Fitted,
    /// CA-SOMM with a fallback: whether two classes or one were kept, and the validation
    /// errors that decided it.
    pub gate_decision: Option<GateDecision>,
    /// CA-SOMM with a fallback whose gate left a class (`'A'` or `'B'`) with fewer than two
    /// training rows: the model is one SOMM on every row, and this says why.
    pub empty_class: Option<char>,
    /// A model that gives no standard deviation of its own (a network): the spread of what it
    /// leaves beside the physics' deviation, as the folds' held-out rows found it (mm, the root
    /// of the three axes' variances together; it holds the tracker's noise too). The model's
    /// point then has the standard deviation `√(σ_physics² + spread_mm²)`. `None`: not
    /// estimated (a model fitted without folds, or one that gives its own).
    pub spread_mm: Option<f64>,
}

/// CA-SOMM's fallback decision: the two classes' error on the validation rows against a SOMM
/// trained on every row. The two classes are kept only when they lower the SOMM's error by
/// more than [`SIGNIFICANCE`] standard errors of the difference, taken over the validation
/// configurations (rows with the same joint angles): the rule every stage of the default
/// calibration meets.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GateDecision {
    /// Mean Euclidean error left on the validation rows by the two classes, mm.
    pub two_classes: f64,
    /// By a SOMM on every row, mm.
    pub one_class: f64,
    /// Validation rows.
    pub rows: usize,
    /// The classifier's accuracy on them.
    pub accuracy: f64,
    /// Whether the two classes' improvement is significant (and they were kept).
    pub significant: bool,
}

impl GateDecision {
    /// Whether the two classes were kept.
    pub fn kept_two(&self) -> bool {
        self.significant
    }
}

impl std::fmt::Display for GateDecision {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let (two, one, rows) = (self.two_classes, self.one_class, self.rows);
        let accuracy = 100.0 * self.accuracy;
        if self.kept_two() {
            write!(
                f,
                "two classes kept: they leave {two:.4} mm mean on the {rows} validation rows, a SOMM on every row {one:.4} mm (significant; classifier accuracy {accuracy:.1} %)"
            )
        } else {
            write!(
                f,
                "one class kept: a SOMM on every row leaves {one:.4} mm mean on the {rows} validation rows, the two classes {two:.4} mm (not lower by {SIGNIFICANCE} standard errors; classifier accuracy {accuracy:.1} %)"
            )
        }
    }
}

impl ResidualModel {
    /// CA-SOMM's fallback in words, when it acted: the validation errors that decided between
    /// two classes and one, or the class the gate left (nearly) empty.
    pub fn fallback_decision(&self) -> Option<String> {
        match (self.gate_decision, self.empty_class) {
            (Some(d), _) => Some(d.to_string()),
            (None, Some(class)) => Some(format!(
                "one class kept: the gate left class {class} with fewer than two training rows (the residual the physics left is not split by it), so one SOMM learns every row"
            )),
            (None, None) => None,
        }
    }

    /// Trains the model `settings` describe on `train_set`, early-stopping on `validation`
    /// (raw input rows; with their physics rows when a gate reads physics). `progress`
    /// advances by one per epoch of every network.
    pub fn fit(
        settings: &ResidualSettings,
        train_set: &Samples,
        validation: &Samples,
        progress: &dyn Observer,
    ) -> Result<Self> {
        settings.check()?;
        if settings.members > 1 {
            let members = (0..settings.members)
                .map(|m| Self::fit(&settings.member(m), train_set, validation, progress))
                .collect::<Result<Vec<_>>>()?;
            return Self::average(members);
        }
        let inputs = match train_set.inputs.first() {
            Some(r) => r.len(),
            None => return Err(ResidualError::Data("no training samples".into())),
        };
        if train_set
            .inputs
            .iter()
            .chain(&validation.inputs)
            .any(|r| r.len() != inputs)
        {
            return Err(ResidualError::Data(
                "input rows of different lengths".into(),
            ));
        }
        let seed = settings.seed;
        let encoding = settings.encoding;
        let (raw_train, raw_validation) = (train_set, validation);
        let (train_set, validation) = (&train_set.encoded(encoding), &validation.encoded(encoding));
        let (settings, search) = if settings.kind == ResidualKind::Gp {
            (settings.clone(), Vec::new())
        } else {
            Self::searched(settings, train_set, validation)
        };
        // A SOMM on every row: the kind, or CA-SOMM's fallback when a class is left empty.
        let somm = || Somm::fit(&settings.axes, train_set, validation, seed, 0, progress);
        let mut empty_class = None;
        let fitted = match settings.kind {
            ResidualKind::Somm => Fitted::Somm(somm()),
            ResidualKind::Mosm => Fitted::Mosm(Mosm::fit(
                &settings.mosm,
                train_set,
                validation,
                seed,
                progress,
            )),
            ResidualKind::CaSomm => match CaSomm::fit(
                &settings.classifier,
                &settings.axes,
                train_set,
                validation,
                raw_train,
                raw_validation,
                seed,
                progress,
            ) {
                Ok(gated) => Fitted::CaSomm(gated),
                // The gate routes (nearly) every row to one class, as on a residual the
                // physics left unimodal: with the fallback, one SOMM on every row.
                Err(ResidualError::EmptyClass { class })
                    if settings.classifier.fallback == Some(true) =>
                {
                    progress.message(&format!(
                        "CA-SOMM: class {class} has fewer than two training rows; one SOMM on every row instead"
                    ));
                    empty_class = class.chars().next();
                    Fitted::Somm(somm())
                }
                Err(e) => return Err(e),
            },
            ResidualKind::Gp => Fitted::Gp(GpResidual::fit(&settings.gp, train_set, seed)?),
        };
        let mut model = Self {
            inputs,
            encoding,
            frame: settings.frame,
            search,
            fitted,
            gate_decision: None,
            empty_class,
            spread_mm: None,
        };
        if matches!(model.fitted, Fitted::CaSomm(_))
            && settings.classifier.fallback == Some(true)
            && !validation.is_empty()
        {
            model.keep_classes_that_pay(&settings, train_set, raw_validation, progress);
        }
        Ok(model)
    }

    /// One SOMM averaging the networks of `members` (SOMMs on the same inputs and encoding), in
    /// their order.
    pub fn average(members: Vec<Self>) -> Result<Self> {
        let Some(first) = members.first() else {
            return Err(ResidualError::Data("no members to average".into()));
        };
        let (inputs, encoding, frame) = (first.inputs, first.encoding, first.frame);
        let mut sets = Vec::new();
        let mut search = Vec::new();
        for m in members {
            if m.inputs != inputs || m.encoding != encoding || m.frame != frame {
                return Err(ResidualError::Data(
                    "members with different inputs, encodings or frames cannot be averaged".into(),
                ));
            }
            match m.fitted {
                Fitted::Somm(s) if m.empty_class.is_none() => sets.extend(s.members),
                other => {
                    return Err(ResidualError::Data(format!(
                        "only SOMMs are averaged, not a {} model",
                        other.kind().name()
                    )));
                }
            }
            search.extend(m.search);
        }
        Ok(Self {
            inputs,
            encoding,
            frame,
            search,
            fitted: Fitted::Somm(Somm { members: sets }),
            gate_decision: None,
            empty_class: None,
            spread_mm: None,
        })
    }

    /// CA-SOMM's fallback: a SOMM trained on every row beside the two sets; the two sets are
    /// kept only when they beat it significantly on the validation rows ([`GateDecision`]),
    /// and the decision is recorded.
    fn keep_classes_that_pay(
        &mut self,
        settings: &ResidualSettings,
        train_set: &Samples,
        raw_validation: &Samples,
        progress: &dyn Observer,
    ) {
        let encoded = raw_validation.encoded(self.encoding);
        let somm = Somm::fit(
            &settings.axes,
            train_set,
            &encoded,
            settings.seed,
            0,
            progress,
        );
        let two = raw_validation.remaining(Some(&self.predict(raw_validation)));
        let one = raw_validation.remaining(Some(
            &somm.predict(&encoded.inputs, raw_validation, false).0,
        ));
        let decision = GateDecision {
            two_classes: ErrorStats::from_errors(&two).mean,
            one_class: ErrorStats::from_errors(&one).mean,
            rows: raw_validation.len(),
            accuracy: self.classifier_accuracy(raw_validation).unwrap_or(f64::NAN),
            significant: improves(&one, &two, &raw_validation.configurations()),
        };
        if !decision.kept_two() {
            self.fitted = Fitted::Somm(somm);
        }
        self.gate_decision = Some(decision);
    }

    /// The settings after the TPE search `settings.search` asks for (each network searched on
    /// the whole training set; CA-SOMM's two sets share the result), and the search logs.
    fn searched(
        settings: &ResidualSettings,
        train_set: &Samples,
        validation: &Samples,
    ) -> (ResidualSettings, Vec<SearchLog>) {
        let mut tuned = settings.clone();
        let Some(s) = &settings.search else {
            return (tuned, Vec::new());
        };
        let seed = settings.seed;
        let score = |axes: Vec<usize>, offset: u64| {
            move |ns: &NetSettings| {
                let net = AxisNet::fit(
                    axes.clone(),
                    ns,
                    train_set,
                    validation,
                    seed + offset,
                    &Silent,
                );
                net.report
                    .validation_loss
                    .iter()
                    .copied()
                    .fold(f64::INFINITY, f64::min)
            }
        };
        let mut logs = Vec::new();
        if settings.kind == ResidualKind::Mosm {
            let (best, log) = search(
                &settings.mosm,
                s,
                vec![0, 1, 2],
                seed + 100,
                score(vec![0, 1, 2], 0),
            );
            tuned.mosm = best;
            logs.push(log);
        } else {
            for a in 0..3 {
                let (best, log) = search(
                    &settings.axes[a],
                    s,
                    vec![a],
                    seed + 100 + a as u64,
                    score(vec![a], a as u64),
                );
                tuned.axes[a] = best;
                logs.push(log);
            }
        }
        (tuned, logs)
    }

    /// Epochs the training of `settings` can take at most: the length of a progress bar.
    pub fn max_epochs(settings: &ResidualSettings) -> u64 {
        let axes: usize = settings.axes.iter().map(|s| s.max_epochs).sum();
        (match settings.kind {
            ResidualKind::Somm => axes * settings.members.max(1),
            ResidualKind::Mosm => settings.mosm.max_epochs,
            ResidualKind::CaSomm => 2 * axes,
            ResidualKind::Gp => 0,
        }) as u64
    }

    /// Predicted error (mm, world X/Y/Z) for each row of `rows` (raw input rows, and their
    /// physics rows when the gate reads physics: [`Self::gate_physics`]; errors not read).
    pub fn predict(&self, rows: &Samples) -> Vec<[f64; 3]> {
        self.predict_with_std(rows, false).0
    }

    /// Predicted error (mm, world X/Y/Z) for each row, and — for a model that knows how sure
    /// it is (the GP) and when `std` is asked for — the standard deviation of each axis's
    /// correction (mm).
    pub fn predict_with_std(
        &self,
        rows: &Samples,
        std: bool,
    ) -> (Vec<[f64; 3]>, Option<Vec<[f64; 3]>>) {
        let encoded = self.encoding.encode_all(&rows.inputs);
        self.fitted.model().predict(&encoded, rows, std)
    }

    /// The gravity and payload a gate reading physics was trained with: the caller computes
    /// each row's physics features with them before [`Self::predict`]. `None`: no such gate.
    pub fn gate_physics(&self) -> Option<GatePhysics> {
        self.classifier().and_then(|c| c.physics)
    }

    /// Which model.
    pub fn kind(&self) -> ResidualKind {
        self.fitted.kind()
    }

    /// Its networks in saved order: SOMM X, Y, Z; MOSM one; CA-SOMM A's X, Y, Z then B's.
    pub fn nets(&self) -> Vec<&AxisNet> {
        self.fitted.model().nets()
    }

    /// The share of `samples` (raw input rows, as [`Self::predict`] takes them) whose class
    /// the CA-SOMM gate gets right; `None` without a gate.
    pub fn classifier_accuracy(&self, samples: &Samples) -> Option<f64> {
        (self.classifier()).map(|c| {
            let encoded = self.encoding.encode_all(&samples.inputs);
            c.accuracy(&c.rows(&encoded, samples), samples)
        })
    }

    /// The CA-SOMM gate (it classifies encoded rows).
    pub fn classifier(&self) -> Option<&Classifier> {
        match &self.fitted {
            Fitted::CaSomm(m) => Some(&m.classifier),
            _ => None,
        }
    }

    /// The Gaussian process.
    pub fn gp(&self) -> Option<&GpResidual> {
        match &self.fitted {
            Fitted::Gp(m) => Some(m),
            _ => None,
        }
    }

    /// Multiplies the standard deviations the model gives from now on by `scale` (the GP's
    /// [`GpResidual::std_scale`]; a model that gives none is left as it is).
    pub fn set_std_scale(&mut self, scale: f64) {
        if let Fitted::Gp(m) = &mut self.fitted {
            m.std_scale = scale;
        }
    }

    /// How many sets of networks a SOMM averages (1 for every other model).
    pub fn members(&self) -> usize {
        match &self.fitted {
            Fitted::Somm(m) => m.members.len(),
            _ => 1,
        }
    }
}
