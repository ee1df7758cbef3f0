//! The saved form of a residual model: `residual.json` (the manifest: kind, input length,
//! encoding, each network's settings, scaling and training report, the classifier, the GP) and
//! one burn record per network, written into a directory the model crate owns.

use std::path::{Path, PathBuf};

use burn::module::Module;
use burn::prelude::Device;
use robocal_data::Invalid;
use serde::{Deserialize, Serialize};

use crate::casomm::CaSomm;
use crate::classifier::Classifier;
use crate::error::{ResidualError, Result};
use crate::gp::GpResidual;
use crate::mlp::{Mlp, NetSettings, TrainReport};
use crate::model::{Fitted, GateDecision, ResidualModel};
use crate::mosm::Mosm;
use crate::net::{AxisNet, SequentialIds};
use crate::samples::{Encoding, Frame, Standardizer};
use crate::search::SearchLog;
use crate::settings::{MAX_MEMBERS, ResidualKind};
use crate::somm::Somm;

/// Version of the saved residual model (`residual.json`).
pub const RESIDUAL_FORMAT: u32 = 1;

/// A model file's manifest entry for one network.
#[derive(Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct NetEntry {
    file: String,
    axes: Vec<usize>,
    settings: NetSettings,
    input_scale: Standardizer,
    output_scale: Standardizer,
    report: TrainReport,
}

#[derive(Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct Manifest {
    residual_format: u32,
    kind: ResidualKind,
    inputs: usize,
    nets: Vec<NetEntry>,
    classifier: Option<Classifier>,
    #[serde(default)]
    search: Vec<SearchLog>,
    #[serde(default, skip_serializing_if = "Encoding::is_raw")]
    encoding: Encoding,
    /// The frame the errors are in (absent: the world's).
    #[serde(default, skip_serializing_if = "Frame::is_world")]
    frame: Frame,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    gp: Option<GpResidual>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    gate_decision: Option<GateDecision>,
    /// `'A'` or `'B'`: CA-SOMM fell back to one SOMM because its gate left that class empty.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    empty_class: Option<char>,
    /// A SOMM averaging several sets of networks: how many (`nets` holds each set's X, Y, Z in
    /// turn). Absent: one.
    #[serde(default = "one", skip_serializing_if = "is_one")]
    members: usize,
    /// A network's spread beside the physics' deviation, mm ([`ResidualModel::spread_mm`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    spread_mm: Option<f64>,
}

fn one() -> usize {
    1
}

fn is_one(n: &usize) -> bool {
    *n == 1
}

/// Most inputs a residual model may take (joint angles and the load: 1 to 63 joints).
pub const MAX_INPUTS: usize = 64;

/// Manifest file name inside a model directory.
pub const MANIFEST: &str = "residual.json";

impl ResidualModel {
    fn net_file(&self, i: usize) -> String {
        let axis = ["x", "y", "z"];
        match self.kind() {
            // A further member's set: `residual-x-2.bpk`, …; the first keeps a single SOMM's names.
            ResidualKind::Somm | ResidualKind::Gp => match i / 3 {
                0 => format!("residual-{}.bpk", axis[i]),
                m => format!("residual-{}-{}.bpk", axis[i % 3], m + 1),
            },
            ResidualKind::Mosm => "residual-xyz.bpk".into(),
            ResidualKind::CaSomm => {
                format!("residual-{}-{}.bpk", ["a", "b"][i / 3], axis[i % 3])
            }
        }
    }

    /// Writes `residual.json` and one burn record per network into `dir` (an existing
    /// directory; the caller makes the whole directory atomic).
    pub fn save(&self, dir: &Path) -> Result<()> {
        let io = |path: PathBuf| move |source| ResidualError::Io { path, source };
        let mut entries = Vec::new();
        for (i, net) in self.nets().into_iter().enumerate() {
            let file = self.net_file(i);
            let path = dir.join(&file);
            // Burn draws parameter ids at random; numbered in order, the same network is the
            // same file.
            net.net
                .clone()
                .map(&mut SequentialIds(0))
                .save_file(&path)
                .map_err(|e| ResidualError::Format {
                    path: path.clone(),
                    message: format!("cannot write the network: {e}"),
                })?;
            entries.push(NetEntry {
                file,
                axes: net.axes.clone(),
                settings: net.settings.clone(),
                input_scale: net.input_scale.clone(),
                output_scale: net.output_scale.clone(),
                report: net.report.clone(),
            });
        }
        let manifest = Manifest {
            residual_format: RESIDUAL_FORMAT,
            kind: self.kind(),
            inputs: self.inputs,
            nets: entries,
            classifier: self.classifier().cloned(),
            search: self.search.clone(),
            encoding: self.encoding,
            frame: self.frame,
            gp: self.gp().cloned(),
            gate_decision: self.gate_decision,
            empty_class: self.empty_class,
            members: self.members(),
            spread_mm: self.spread_mm,
        };
        let path = dir.join(MANIFEST);
        let text = serde_json::to_string_pretty(&manifest).map_err(|e| ResidualError::Format {
            path: path.clone(),
            message: e.to_string(),
        })?;
        std::fs::write(&path, text + "\n").map_err(io(path))
    }

    /// Reads a model written by [`Self::save`] from `dir`.
    pub fn load(dir: &Path) -> Result<Self> {
        let path = dir.join(MANIFEST);
        let format = |message: String| ResidualError::Format {
            path: path.clone(),
            message,
        };
        let m = read_manifest(&path)?;
        check_manifest(&m).map_err(format)?;
        let features = m.encoding.features(m.inputs);
        let nets = load_nets(dir, m.nets, features, &format)?;
        let fitted = assemble(m.kind, m.classifier, m.gp, nets).map_err(format)?;
        Ok(Self {
            inputs: m.inputs,
            encoding: m.encoding,
            frame: m.frame,
            search: m.search,
            fitted,
            gate_decision: m.gate_decision,
            empty_class: m.empty_class,
            spread_mm: m.spread_mm,
        })
    }
}

/// The manifest at `path`, in the format this robocal reads.
fn read_manifest(path: &Path) -> Result<Manifest> {
    let text = std::fs::read_to_string(path).map_err(|source| ResidualError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    let format = |message: String| ResidualError::Format {
        path: path.to_path_buf(),
        message,
    };
    let version: serde_json::Value =
        serde_json::from_str(&text).map_err(|e| format(e.to_string()))?;
    match version
        .get("residual_format")
        .and_then(serde_json::Value::as_u64)
    {
        Some(v) if v == u64::from(RESIDUAL_FORMAT) => {}
        Some(v) => {
            return Err(format(format!(
                "residual_format {v}: this robocal reads format {RESIDUAL_FORMAT}"
            )));
        }
        None => return Err(format("no residual_format field".into())),
    }
    serde_json::from_value(version).map_err(|e| format(e.to_string()))
}

/// Whether the manifest's parts fit its kind — its members, networks, classifier, GP, spread,
/// empty class and inputs —; why not, in words.
fn check_manifest(m: &Manifest) -> std::result::Result<(), String> {
    let format = |message: String| message;
    if !(1..=MAX_MEMBERS).contains(&m.members) || (m.members > 1 && m.kind != ResidualKind::Somm) {
        return Err(format(format!(
            "members {}: a somm averages 1 to {MAX_MEMBERS} sets of networks, every other model has one",
            m.members
        )));
    }
    let expected = match m.kind {
        ResidualKind::Somm => 3 * m.members,
        ResidualKind::Mosm => 1,
        ResidualKind::CaSomm => 6,
        ResidualKind::Gp => 0,
    };
    if (m.kind == ResidualKind::Gp) != m.gp.is_some() {
        return Err(format(format!(
            "a {} model {} a `gp` section",
            m.kind.name(),
            if m.kind == ResidualKind::Gp {
                "needs"
            } else {
                "has no"
            }
        )));
    }
    if m.nets.len() != expected || (m.kind == ResidualKind::CaSomm) != m.classifier.is_some() {
        return Err(format(format!(
            "a {} model has {expected} networks{}",
            m.kind.name(),
            if m.kind == ResidualKind::CaSomm {
                " and a classifier"
            } else {
                ""
            }
        )));
    }
    let features = m.encoding.features(m.inputs);
    if let Some(c) = &m.classifier {
        c.check(c.inputs.features(m.encoding, m.inputs))
            .map_err(format)?;
    }
    if let Some(gp) = &m.gp {
        gp.check(features).map_err(format)?;
    }
    if let Some(spread) = m.spread_mm {
        if !(spread.is_finite() && spread >= 0.0) {
            return Err(format(format!(
                "spread_mm {spread}: must be finite and not negative (mm)"
            )));
        }
        if m.kind.gives_std() {
            return Err(format(
                "spread_mm: a GP gives its own standard deviation (gp.std_scale), not a spread beside the physics'".into(),
            ));
        }
    }
    if let Some(class) = m.empty_class {
        if !matches!(class, 'A' | 'B') {
            return Err(format(format!(
                "empty_class {class:?}: must be \"A\" or \"B\" (the CA-SOMM class its gate left empty)"
            )));
        }
        if m.kind != ResidualKind::Somm {
            return Err(format(format!(
                "empty_class {class:?}: only a CA-SOMM that fell back to one SOMM (kind \"somm\") has one, not a {} model",
                m.kind.name()
            )));
        }
    }
    if m.inputs == 0 || m.inputs > MAX_INPUTS {
        return Err(format(format!(
            "inputs {}: a residual model takes 1 to {MAX_INPUTS} inputs",
            m.inputs
        )));
    }
    Ok(())
}

/// The networks the manifest lists (`entries`), each read from its file in `dir` for
/// `features` inputs; `format` makes a fault of the manifest an error naming it.
fn load_nets(
    dir: &Path,
    entries: Vec<NetEntry>,
    features: usize,
    format: &dyn Fn(String) -> ResidualError,
) -> Result<Vec<AxisNet>> {
    let device = Device::flex();
    let mut nets = Vec::new();
    for (i, e) in entries.into_iter().enumerate() {
        if let Err(e) = e.settings.check() {
            let Invalid { key, message } = e.within(&format!("nets[{i}].settings"));
            return Err(format(format!("{key}: {message}")));
        }
        // The network file sits beside the manifest: a bare file name, nothing else.
        if std::path::Path::new(&e.file).file_name() != Some(std::ffi::OsStr::new(&e.file)) {
            return Err(format(format!(
                "nets[{i}].file {:?}: must be a file name in the model directory",
                e.file
            )));
        }
        if !e.input_scale.fits(features)
            || !e.output_scale.fits(e.axes.len())
            || e.axes.is_empty()
            || e.axes.iter().any(|a| *a > 2)
        {
            return Err(format(format!(
                "{}: scaling does not fit the network",
                e.file
            )));
        }
        let file = dir.join(&e.file);
        let net = Mlp::new(
            features,
            &e.settings.hidden,
            e.axes.len(),
            e.settings.activation,
            &device,
        )
        .try_load_file(&file)
        .map_err(|err| ResidualError::Format {
            path: file.clone(),
            message: format!("cannot read the network: {err}"),
        })?;
        nets.push(AxisNet {
            axes: e.axes,
            settings: e.settings,
            input_scale: e.input_scale,
            output_scale: e.output_scale,
            report: e.report,
            dense: net.dense(),
            net,
        });
    }
    Ok(nets)
}

/// The fitted model of `kind` from its networks, classifier and GP; why they do not make one,
/// in words.
fn assemble(
    kind: ResidualKind,
    classifier: Option<Classifier>,
    gp: Option<GpResidual>,
    mut nets: Vec<AxisNet>,
) -> std::result::Result<Fitted, String> {
    let shape = || format!("a {} model has other networks", kind.name());
    let three = |v: Vec<AxisNet>| -> std::result::Result<[AxisNet; 3], String> {
        v.try_into().map_err(|_| shape())
    };
    Ok(match (kind, classifier, gp) {
        (ResidualKind::Somm, _, _) => {
            let mut members = Vec::new();
            while !nets.is_empty() {
                let rest = nets.split_off(3.min(nets.len()));
                members.push(three(std::mem::replace(&mut nets, rest))?);
            }
            Fitted::Somm(Somm { members })
        }
        (ResidualKind::Mosm, _, _) => Fitted::Mosm(Mosm {
            net: nets.pop().ok_or_else(shape)?,
        }),
        (ResidualKind::CaSomm, Some(classifier), _) => {
            let b = nets.split_off(3.min(nets.len()));
            Fitted::CaSomm(CaSomm {
                classifier,
                sets: [Somm::single(three(nets)?), Somm::single(three(b)?)],
            })
        }
        (ResidualKind::Gp, _, Some(gp)) => Fitted::Gp(gp),
        _ => return Err(shape()),
    })
}
