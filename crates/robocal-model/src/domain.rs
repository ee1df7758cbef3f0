//! The joint readings and payloads a model was calibrated on (`domain.toml` in the model
//! directory): a prediction outside them is extrapolation, where nothing in the calibration
//! checked the model — joint-error terms and residual models are fitted only inside.

use std::fmt::Write as _;
use std::path::Path;

use robocal_data::Sample;
use serde::{Deserialize, Serialize};

use crate::error::{ModelError, Result};

/// The model directory's file.
pub const DOMAIN_FILE: &str = "domain.toml";

/// Per joint, the lowest and highest reading of the calibration's rows (deg), and the lightest
/// and heaviest payload (kg).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Domain {
    /// `[low, high]` of every joint, deg.
    pub joints: Vec<[f64; 2]>,
    /// `[lightest, heaviest]` payload, kg.
    pub load: [f64; 2],
}

/// How far (deg) a joint reading may lie beyond its calibrated range before [`Domain::warning`]
/// names it: half the tenth of a degree the warning states excesses in. A compensated command
/// moves each joint by the model's correction, hundredths of a degree, and a joint the
/// calibration held at one reading (a palletiser's locked wrist) would otherwise be warned of on
/// every row for a correction no tracker could tell from its reading. Predictions and the
/// calibration's own decisions use the exact range ([`Domain::excess`]).
pub const WARN_BEYOND_DEG: f64 = 0.05;

/// How far one row lies outside a [`Domain`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Excess {
    /// 0-based joint.
    pub joint: usize,
    /// The reading, deg.
    pub reading: f64,
    /// Degrees beyond the nearer end of the joint's range.
    pub beyond: f64,
}

impl Domain {
    /// The domain of `samples` (none when there are none).
    pub fn of<'a>(samples: impl IntoIterator<Item = &'a Sample>) -> Option<Self> {
        let mut domain: Option<Self> = None;
        for s in samples {
            let d = domain.get_or_insert_with(|| Self {
                joints: s.joints.iter().map(|&q| [q, q]).collect(),
                load: [s.load, s.load],
            });
            for (r, &q) in d.joints.iter_mut().zip(&s.joints) {
                *r = [r[0].min(q), r[1].max(q)];
            }
            d.load = [d.load[0].min(s.load), d.load[1].max(s.load)];
        }
        domain
    }

    /// The joints of `s` whose reading lies outside their range.
    pub fn excess(&self, s: &Sample) -> Vec<Excess> {
        (self.joints.iter().zip(&s.joints).enumerate())
            .filter_map(|(joint, (&[lo, hi], &q))| {
                let beyond = (lo - q).max(q - hi);
                (beyond > 0.0).then_some(Excess {
                    joint,
                    reading: q,
                    beyond,
                })
            })
            .collect()
    }

    /// `s` with every joint reading and the payload moved to the nearest point of the domain;
    /// `None` when `s` lies inside it (or has another number of joints).
    pub fn clamped(&self, s: &Sample) -> Option<Sample> {
        if s.joints.len() != self.joints.len()
            || (self.excess(s).is_empty() && self.load_excess(s) == 0.0)
        {
            return None;
        }
        let mut inside = s.clone();
        for (q, &[lo, hi]) in inside.joints.iter_mut().zip(&self.joints) {
            *q = q.clamp(lo, hi);
        }
        inside.load = inside.load.clamp(self.load[0], self.load[1]);
        Some(inside)
    }

    /// How far the payload of `s` lies outside the calibrated loads, kg (0 inside).
    pub fn load_excess(&self, s: &Sample) -> f64 {
        (self.load[0] - s.load).max(s.load - self.load[1]).max(0.0)
    }

    /// A warning naming how many of `rows` (read from `file`) lie outside the domain, for each
    /// joint (and the load) how many and how far, and the first such row; none when every row
    /// lies inside, or within [`WARN_BEYOND_DEG`] of a joint's range.
    pub fn warning<'a>(
        &self,
        file: &Path,
        rows: impl IntoIterator<Item = &'a Sample>,
    ) -> Option<String> {
        let rows: Vec<&Sample> = rows.into_iter().collect();
        let dof = self.joints.len();
        // Per joint: rows outside, the farthest reading and how far beyond.
        let mut joints: Vec<(usize, f64, f64)> = vec![(0, 0.0, 0.0); dof];
        let (mut loads, mut load_far) = (0usize, (0.0f64, 0.0f64));
        let mut outside = 0;
        let mut first: Option<&Sample> = None;
        for &s in &rows {
            let mut excess = self.excess(s);
            excess.retain(|e| e.beyond >= WARN_BEYOND_DEG);
            let load = self.load_excess(s);
            if excess.is_empty() && load == 0.0 {
                continue;
            }
            outside += 1;
            first.get_or_insert(s);
            for e in excess {
                let j = &mut joints[e.joint];
                j.0 += 1;
                if e.beyond > j.2 {
                    (j.1, j.2) = (e.reading, e.beyond);
                }
            }
            if load > 0.0 {
                loads += 1;
                if load > load_far.1 {
                    load_far = (s.load, load);
                }
            }
        }
        let first = first?;
        let mut parts = Vec::new();
        for (j, &(n, reading, beyond)) in joints.iter().enumerate() {
            if n > 0 {
                let [lo, hi] = self.joints[j].map(r4);
                parts.push(format!(
                    "q{} on {n} (up to {}°, {beyond:.1}° beyond the calibrated {lo}..{hi}°)",
                    j + 1,
                    r4(reading)
                ));
            }
        }
        if loads > 0 {
            parts.push(format!(
                "load on {loads} (up to {} kg, {:.3} kg beyond the calibrated {}..{} kg)",
                r4(load_far.0),
                load_far.1,
                r4(self.load[0]),
                r4(self.load[1])
            ));
        }
        let mut text = format!(
            "{}: {outside} of {} rows lie outside the joint readings and loads the model was calibrated on — ",
            file.display(),
            rows.len()
        );
        text += &parts.join("; ");
        let _ = write!(
            text,
            " (first: line {}, pose `{}`). Their predictions are extrapolation: nothing in the calibration checked the model there, and joint-error terms and residual models are fitted only inside.",
            first.line, first.pose
        );
        Some(text)
    }

    /// The file form, with a header saying what it is.
    pub fn to_toml_string(&self) -> String {
        "# The joint readings (deg, per joint [low, high]) and payloads (kg) this model was\n\
         # calibrated on; predict, evaluate and compensate warn for rows outside them.\n"
            .to_string()
            + &toml::to_string(self).unwrap_or_default()
    }

    /// Reads `domain.toml` of a model for a robot with `dof` joints.
    pub fn load(file: &Path, dof: usize) -> Result<Self> {
        let text = std::fs::read_to_string(file).map_err(|source| ModelError::NotAModel {
            file: file.to_path_buf(),
            source,
        })?;
        let invalid = |key: &str, message: String| ModelError::Domain {
            file: file.to_path_buf(),
            key: key.into(),
            message,
        };
        let domain: Self = toml::from_str(&text).map_err(|e| ModelError::DomainToml {
            file: file.to_path_buf(),
            message: e.to_string().trim_end().replace('\n', " "),
        })?;
        if domain.joints.len() != dof {
            return Err(invalid(
                "joints",
                format!(
                    "{} ranges for a robot with {dof} joints",
                    domain.joints.len()
                ),
            ));
        }
        let ranges = (domain.joints.iter().enumerate())
            .map(|(j, r)| (format!("joints[{}]", j + 1), r))
            .chain(std::iter::once(("load".to_string(), &domain.load)));
        for (key, &[lo, hi]) in ranges {
            if !(lo.is_finite() && hi.is_finite() && lo <= hi) {
                return Err(invalid(
                    &key,
                    format!("[{lo}, {hi}]: two finite numbers, the low one first"),
                ));
            }
        }
        Ok(domain)
    }
}

/// `x` to four decimals, printed shortest (46.1194, 12.5): the files' precision.
fn r4(x: f64) -> f64 {
    (x * 1e4).round() / 1e4
}
