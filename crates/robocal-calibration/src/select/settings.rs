//! The default calibration's settings.

use nalgebra::Vector3;
use robocal_residual::{Frame, ResidualKind, ResidualSettings, ResidualStage};

use crate::outliers::OutlierSettings;
/// Settings of the default calibration.
#[derive(Debug, Clone, PartialEq)]
pub struct AutoSettings {
    /// Folds of the cross-validation over configurations (when no validation file is given).
    pub folds: usize,
    /// Seed of the folds (and of the residual models).
    pub seed: u64,
    /// Fewest configurations (in the data, or in each fold's training part) for which a
    /// residual model is tried (default 10: above it the paired test decides).
    pub min_residual_configurations: usize,
    /// Transmission harmonics up to this order tried with the geometry (0: not tried).
    pub harmonics: u32,
    /// Self-weight terms tried with the geometry.
    pub self_weight: bool,
    /// Backlash tried with the geometry (each joint on the flank of its approach from home or on
    /// the one its torque presses).
    pub backlash: bool,
    /// Tilting compliances tried last, on the chosen physics when it holds the compliances: the
    /// parts beyond each joint turning across its axis under the gravity moment of the payload
    /// and of the links' weights (when identified). Off by default: on the development twins
    /// the candidate was never kept, and on the paper's arm its folds took the time the GP
    /// needed; and one case beyond the model came out 12 % higher (ARM6H, joint-1
    /// extrapolation).
    pub tilt: bool,
    /// Axis runouts of orders 1 up to this one (every joint, about both axes across it; 0: not
    /// tried), tried on the physics the joint-error blocks reached, before the flank search and
    /// the tilts: the parts beyond each joint turning across its axis periodically in its angle.
    /// Default 2: orders 1 and 2, under the prior of their own spread, on
    /// the 72 development cases lowered the 18 the folds kept them on by 2–69 % (the rest
    /// identical); with the effects beyond the model four times as large, 15 of 16 lower by
    /// 13–58 %, one higher: ARM5W seed 0's joint-1 extrapolation, +9 %, where the harmonic
    /// reach then continued joint 1's harmonics. Order 1 alone: that case +32 %. 0 switches
    /// them off.
    pub runout: u32,
    /// Backlash with its flanks searched also tried where the physics the chain chose holds no
    /// backlash (the block with the regression's flanks was not kept): for a joint whose play
    /// rests on the flank its torque presses and turns far from the rows' middle torque (at a
    /// configuration's lightest or heaviest loads only), where the regression's flanks miss and
    /// the block gains nothing. Off by default: on the development twins it lowered ARM6H's
    /// error with every effect by 16–68 % and raised one case beyond the model by 7 %
    /// (`just accuracy`). With backlash chosen the search is tried either way.
    pub flank_search: bool,
    /// The residual models tried, each on top of the best physical model. By default a GP and
    /// robocal's networks, both in the frame turning with joint 1 (`Frame::Joint1`: against the
    /// world frame, on the 48 development cases 15 lower, by up to 21 %, one higher by 4 %, the
    /// rest identical).
    pub residuals: Vec<ResidualStage>,
    /// Where joint 1's axis lies more than [`JOINT1_GRAVITY_ANGLE_DEG`] from the line of gravity
    /// (an arm on a wall or an inclined pedestal), each residual model of `residuals` in the
    /// frame turning with joint 1 is also tried in the world frame, and the folds choose: the
    /// turned frame's gain rests on joint 1 standing along gravity (on by default; off when the
    /// user names the frame).
    ///
    /// [`JOINT1_GRAVITY_ANGLE_DEG`]: crate::select::JOINT1_GRAVITY_ANGLE_DEG
    pub both_frames_off_gravity: bool,
    /// Seconds the selection may take: a candidate whose folds would run past it (projected
    /// from its first fold) is abandoned, and none starts after it. The only setting that
    /// depends on the clock: far under budget, a seed gives the same model.
    pub budget_seconds: f64,
    /// The budget kept by counted work instead of the clock ([`budget`]): every decision of the
    /// budget reads what the fits and trainings counted, in the seconds a reference machine of
    /// [`REFERENCE_CORES`] cores takes for it, so a seed gives the same model on every machine
    /// as fast as the reference or faster (the clock stays a guard: never past the budget).
    /// Off by default.
    ///
    /// [`REFERENCE_CORES`]: crate::budget::REFERENCE_CORES
    /// [`budget`]: crate::budget
    pub reproducible: bool,
    /// The search for bad shots before everything else (none: every row is used).
    pub outliers: Option<OutlierSettings>,
    /// Weight of a 6-DoF probe's orientation residuals, mm per deg (`None`: the kinematic
    /// settings' default, `noise_mm / noise_deg`).
    pub angle_weight: Option<f64>,
    /// Weights of the rows of named points on their squared errors, for every fit
    /// ([`robocal_ident::KinematicSettings::target_weights`]); empty: every row weighs 1.
    pub target_weights: Vec<(String, f64)>,
    /// Gravity in the robot base frame {0}, m/s², for every candidate (`None`: decided once
    /// from the data before the candidates — the base's −z, or for an arm on a wall or a
    /// ceiling a levelled tracker's −z where a fit with the compliances says it fits better).
    pub gravity: Option<Vector3<f64>>,
}

/// Folds of the default cross-validation.
pub const DEFAULT_FOLDS: usize = 5;

/// The default selection's time budget, s.
pub const DEFAULT_BUDGET_SECONDS: f64 = 120.0;

impl Default for AutoSettings {
    fn default() -> Self {
        let seed = robocal_residual::DEFAULT_SEED;
        Self {
            folds: DEFAULT_FOLDS,
            seed,
            min_residual_configurations: 10,
            harmonics: 2,
            self_weight: true,
            backlash: true,
            tilt: false,
            runout: 2,
            flank_search: false,
            residuals: vec![
                ResidualStage {
                    settings: ResidualSettings {
                        frame: Frame::Joint1,
                        ..ResidualSettings::gp(seed)
                    },
                    holdout: 0.2,
                },
                ResidualStage {
                    settings: ResidualSettings {
                        frame: Frame::Joint1,
                        ..ResidualSettings::robocal(ResidualKind::Somm, seed)
                    },
                    holdout: 0.2,
                },
            ],
            both_frames_off_gravity: true,
            budget_seconds: DEFAULT_BUDGET_SECONDS,
            reproducible: false,
            outliers: Some(OutlierSettings::default()),
            angle_weight: None,
            target_weights: Vec::new(),
            gravity: None,
        }
    }
}

#[cfg(test)]
impl AutoSettings {
    /// The default's settings with the table alone in the chain (no joint-error blocks, runouts,
    /// residual models or bad-shot search): the stages before the chain, tested quickly.
    pub(crate) fn table_only() -> Self {
        Self {
            harmonics: 0,
            self_weight: false,
            backlash: false,
            runout: 0,
            residuals: Vec::new(),
            outliers: None,
            ..Self::default()
        }
    }
}
