//! The kinematic stage of a stage config (`robocal calibrate --config FILE`), raw and validated.

use robocal_data::{Invalid, one_of};
use serde::{Deserialize, Serialize};

use crate::calibrate::{
    ComplianceSettings, JointErrorSettings, KinematicSettings, Loss, SolverKind,
};

/// `[kinematic]` as written.
#[derive(Debug, Clone, Serialize, Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub struct RawKinematicStage {
    /// `"lm"` (least squares, Levenberg–Marquardt) or `"bfgs"` (the paper's mean distance).
    pub solver: Option<String>,
    /// Parameter names to identify; absent: all.
    pub parameters: Option<Vec<String>>,
    /// Iteration limit.
    pub max_iterations: Option<u64>,
    /// Relative column norm below which a parameter counts as unidentifiable.
    pub rank_tolerance: Option<f64>,
    /// `"squared"` (least squares, the default) or `"huber"` (robust to a few wild points).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub loss: Option<String>,
    /// Weight of a measured orientation's residual (a 6-DoF probe's `rx, ry, rz`), mm per
    /// deg; absent: `noise_mm / noise_deg`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub angle_weight: Option<f64>,
    /// The tracker's position noise, mm per coordinate (1σ).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub noise_mm: Option<f64>,
    /// The probe's angular noise, deg per axis (1σ).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub noise_deg: Option<f64>,
}

impl RawKinematicStage {
    /// Validates into settings; errors name the key.
    pub fn validate(&self) -> Result<KinematicSettings, Invalid> {
        let mut s = KinematicSettings::default();
        if let Some(solver) = &self.solver {
            s.solver = SolverKind::from_name(solver).ok_or_else(|| {
                Invalid::new(
                    "kinematic.solver",
                    format!(
                        "`{solver}` is not a solver; use {}",
                        one_of(&SolverKind::ALL.map(SolverKind::name))
                    ),
                )
            })?;
        }
        if let Some(loss) = &self.loss {
            s.loss = match loss.as_str() {
                "squared" => Loss::Squared,
                "huber" => Loss::Huber,
                other => {
                    return Err(Invalid::new(
                        "kinematic.loss",
                        format!(
                            "`{other}` is not a loss; use {}",
                            one_of(&["squared", "huber"])
                        ),
                    ));
                }
            };
        }
        if let Some(params) = &self.parameters {
            if params.is_empty() {
                return Err(Invalid::new("kinematic.parameters", "lists no parameter"));
            }
            s.parameters = Some(params.clone());
        }
        if let Some(n) = self.max_iterations {
            if n == 0 {
                return Err(Invalid::new(
                    "kinematic.max_iterations",
                    "must be at least 1",
                ));
            }
            s.max_iterations = n;
        }
        if let Some(t) = self.rank_tolerance {
            if !(t.is_finite() && t > 0.0 && t < 1.0) {
                return Err(Invalid::new(
                    "kinematic.rank_tolerance",
                    "must lie between 0 and 1",
                ));
            }
            s.rank_tolerance = t;
        }
        let positive = |key: &str, v: f64, unit: &str| {
            if v.is_finite() && v > 0.0 {
                Ok(v)
            } else {
                Err(Invalid::new(
                    key,
                    format!("must be a positive number ({unit})"),
                ))
            }
        };
        if let Some(w) = self.angle_weight {
            s.angle_weight = Some(positive("kinematic.angle_weight", w, "mm per deg")?);
        }
        if let Some(v) = self.noise_mm {
            s.noise_mm = positive("kinematic.noise_mm", v, "mm")?;
        }
        if let Some(v) = self.noise_deg {
            s.noise_deg = positive("kinematic.noise_deg", v, "deg")?;
        }
        Ok(s)
    }
}

/// `[compliance]` as written: joint compliances identified with the geometry (LM or BFGS, the
/// kinematic stage's solver), on the points of every load.
#[derive(Debug, Clone, Serialize, Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub struct RawComplianceStage {
    /// Joints (counted from 1) whose compliance is identified; absent: the joints that carry
    /// the payload's gravity torque in the data.
    pub joints: Option<Vec<usize>>,
    /// Gravity in the robot base frame {0}, m/s² (default `[0, 0, -9.80665]`).
    #[serde(default, deserialize_with = "robocal_robot::exact::option")]
    pub gravity: Option<[f64; 3]>,
    /// The payload's centre of mass in the flange frame, mm (default: the measured point).
    #[serde(default, deserialize_with = "robocal_robot::exact::option")]
    pub payload_com: Option<[f64; 3]>,
    /// Identify the payload's centre of mass with the compliances, starting from `payload_com`
    /// (default false).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub identify_payload_com: Option<bool>,
}

impl RawComplianceStage {
    /// Validates into settings; errors name the key.
    pub fn validate(&self) -> Result<ComplianceSettings, Invalid> {
        let mut s = ComplianceSettings::default();
        if let Some(joints) = &self.joints {
            s.joints = Some(joint_list("compliance.joints", joints)?);
        }
        if let Some(g) = self.gravity {
            if g.iter().any(|v| !v.is_finite()) || g.iter().all(|v| *v == 0.0) {
                return Err(Invalid::new(
                    "compliance.gravity",
                    "must be a finite, non-zero vector (m/s², robot base frame)",
                ));
            }
            s.gravity = g.into();
        }
        if let Some(c) = self.payload_com {
            if c.iter().any(|v| !v.is_finite()) {
                return Err(Invalid::new(
                    "compliance.payload_com",
                    "must be finite (mm, flange frame)",
                ));
            }
            s.payload_com = Some(c.into());
        }
        s.identify_payload_com = self.identify_payload_com.unwrap_or(false);
        Ok(s)
    }

    /// The table that gives `settings` back, every default written out (`payload_com` stays
    /// absent when it is the measured point's default).
    pub fn from_settings(settings: &ComplianceSettings) -> Self {
        Self {
            joints: settings
                .joints
                .as_ref()
                .map(|j| j.iter().map(|j| j + 1).collect()),
            gravity: Some(settings.gravity.into()),
            payload_com: settings.payload_com.map(Into::into),
            identify_payload_com: settings.identify_payload_com.then_some(true),
        }
    }
}

/// `[joint_errors]` as written: transmission harmonics, self-weight and backlash terms
/// identified with the geometry (the kinematic stage's solver and rows).
#[derive(Debug, Clone, Serialize, Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub struct RawJointErrorStage {
    /// Highest harmonic order per joint (default 2; 0: none).
    pub harmonics: Option<u32>,
    /// Joints (counted from 1) with harmonics; absent: every joint.
    pub joints: Option<Vec<usize>>,
    /// Self-weight terms (default false).
    pub self_weight: Option<bool>,
    /// The links' weights shared by the joints they load, through the joints' compliances
    /// (default false; needs `[compliance]`).
    pub link_weights: Option<bool>,
    /// Backlash of every joint (default false): on the flank of the approach from home, or on
    /// the flank the torque presses where that explains more (see `backlash_torque`).
    pub backlash: Option<bool>,
    /// Whether a joint's backlash may rest on the flank its torque presses (default true; only
    /// with `backlash = true`).
    pub backlash_torque: Option<bool>,
    /// The readings (deg, one per joint) the measurement program moved the joints out from to
    /// every pose; absent: 0 for every joint. Only with `backlash = true`.
    pub backlash_home: Option<Vec<f64>>,
    /// A torque flank's preload searched where its step explains most beyond the joint's own
    /// terms, its direction fitted again without them (default false; only with
    /// `backlash = true` and the torque flank allowed).
    pub flank_search: Option<bool>,
    /// Tilting compliances of every joint (default false; needs `[compliance]`).
    pub tilt: Option<bool>,
    /// Axis runouts of every joint up to this order (default 0: none; at most
    /// [`MAX_HARMONICS`]): the parts beyond each joint turning across its axis periodically in
    /// its angle.
    pub runout: Option<u32>,
    /// The harmonics under a Gaussian prior whose spread the data choose (default true; only
    /// with harmonics and the `lm` solver).
    pub harmonic_prior: Option<bool>,
}

/// Highest harmonic order a stage may ask for.
pub const MAX_HARMONICS: u32 = 8;

impl RawJointErrorStage {
    /// Validates into settings; errors name the key.
    pub fn validate(&self) -> Result<JointErrorSettings, Invalid> {
        let mut s = JointErrorSettings::default();
        if let Some(h) = self.harmonics {
            if h > MAX_HARMONICS {
                return Err(Invalid::new(
                    "joint_errors.harmonics",
                    format!("at most {MAX_HARMONICS}"),
                ));
            }
            s.harmonics = h;
        }
        if let Some(joints) = &self.joints {
            s.harmonic_joints = Some(joint_list("joint_errors.joints", joints)?);
        }
        s.self_weight = self.self_weight.unwrap_or(false);
        s.link_weights = self.link_weights.unwrap_or(false);
        s.backlash = self.backlash.unwrap_or(false);
        s.tilt = self.tilt.unwrap_or(false);
        if let Some(r) = self.runout {
            if r > MAX_HARMONICS {
                return Err(Invalid::new(
                    "joint_errors.runout",
                    format!("at most {MAX_HARMONICS}"),
                ));
            }
            s.runout = r;
        }
        if let Some(prior) = self.harmonic_prior {
            if s.harmonics == 0 {
                return Err(Invalid::new(
                    "joint_errors.harmonic_prior",
                    "is given, but no harmonics are identified: set harmonics = 1 or more",
                ));
            }
            s.harmonic_prior = prior;
        }
        // The backlash settings mean nothing without backlash.
        for (key, given) in [
            (
                "joint_errors.backlash_torque",
                self.backlash_torque.is_some(),
            ),
            ("joint_errors.backlash_home", self.backlash_home.is_some()),
            ("joint_errors.flank_search", self.flank_search.is_some()),
        ] {
            if given && !s.backlash {
                return Err(Invalid::new(
                    key,
                    "is given, but backlash is not identified: add backlash = true",
                ));
            }
        }
        if let Some(torque) = self.backlash_torque {
            s.backlash_torque = torque;
        }
        if let Some(search) = self.flank_search {
            if search && !s.backlash_torque {
                return Err(Invalid::new(
                    "joint_errors.flank_search",
                    "searches the flank the torque presses, which backlash_torque = false forbids",
                ));
            }
            s.flank_search = search;
        }
        if let Some(home) = &self.backlash_home {
            if home.is_empty() || home.iter().any(|h| !h.is_finite()) {
                return Err(Invalid::new(
                    "joint_errors.backlash_home",
                    "must list one finite reading (deg) per joint",
                ));
            }
            s.backlash_home = Some(home.iter().map(|h| h.to_radians()).collect());
        }
        Ok(s)
    }

    /// The table that gives `settings` back.
    pub fn from_settings(settings: &JointErrorSettings) -> Self {
        Self {
            harmonics: Some(settings.harmonics),
            joints: (settings.harmonic_joints.as_ref()).map(|j| j.iter().map(|j| j + 1).collect()),
            self_weight: Some(settings.self_weight),
            link_weights: settings.link_weights.then_some(true),
            backlash: Some(settings.backlash),
            backlash_torque: Some(settings.backlash_torque),
            backlash_home: (settings.backlash_home.as_ref())
                .map(|h| h.iter().map(|h| h.to_degrees()).collect()),
            flank_search: settings.flank_search.then_some(true),
            tilt: settings.tilt.then_some(true),
            runout: (settings.runout > 0).then_some(settings.runout),
            harmonic_prior: (settings.harmonics > 0 && !settings.harmonic_prior).then_some(false),
        }
    }
}

/// A list of joints counted from 1, as 0-based indices in ascending order; errors name `key`.
fn joint_list(key: &str, joints: &[usize]) -> Result<Vec<usize>, Invalid> {
    if joints.is_empty() {
        return Err(Invalid::new(key, "lists no joint"));
    }
    if joints.contains(&0) {
        return Err(Invalid::new(key, "joints are counted from 1"));
    }
    let mut sorted = joints.to_vec();
    sorted.sort_unstable();
    sorted.dedup();
    if sorted.len() != joints.len() {
        return Err(Invalid::new(key, "names a joint twice"));
    }
    Ok(sorted.iter().map(|j| j - 1).collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn stage(
        backlash: Option<bool>,
        torque: Option<bool>,
        search: Option<bool>,
    ) -> RawJointErrorStage {
        RawJointErrorStage {
            backlash,
            backlash_torque: torque,
            flank_search: search,
            ..RawJointErrorStage::default()
        }
    }

    /// `flank_search` turns the search on, goes back into the table it came from, and is
    /// refused, naming the key, without backlash or with the torque flank forbidden.
    #[test]
    fn flank_search_is_validated_and_given_back() {
        let s = stage(Some(true), None, Some(true)).validate().unwrap();
        assert!(s.flank_search && s.backlash_torque);
        assert_eq!(
            RawJointErrorStage::from_settings(&s).flank_search,
            Some(true)
        );
        let plain = stage(Some(true), None, None).validate().unwrap();
        assert!(!plain.flank_search);
        assert_eq!(RawJointErrorStage::from_settings(&plain).flank_search, None);
        for bad in [
            stage(None, None, Some(true)),
            stage(Some(true), Some(false), Some(true)),
        ] {
            let err = bad.validate().unwrap_err();
            assert_eq!(err.key, "joint_errors.flank_search", "{err:?}");
        }
    }
}
