//! What the stages built: the identification, the residual model, the bad shots, and how the
//! default chose.

use crate::fit::physical_model;
use crate::outliers::OutlierReport;
use crate::residual_report::ResidualReport;
use crate::select::selection::Selection;
use crate::stages::Stages;
use robocal_ident::KinematicCalibration;
use robocal_model::CalibratedModel;
use robocal_residual::ResidualModel;

/// A calibrated model and what made it.
#[derive(Debug)]
pub struct Built {
    /// The kinematic (or elasto-geometric) identification in the model.
    pub kinematic: KinematicCalibration,
    /// The residual stage, if one is in the model.
    pub residual: Option<(ResidualModel, ResidualReport)>,
    /// The stages, as a stage config would give them.
    pub stages: Stages,
    /// How the default calibration chose the stages (absent with a stage config).
    pub selection: Option<Selection>,
    /// The bad shots found before the calibration (absent when not searched).
    pub outliers: Option<OutlierReport>,
    /// The play that follows the order of motion, when the default kept it.
    pub motion: Option<robocal_model::MotionPlay>,
}

impl Built {
    /// The calibrated model.
    pub fn model(&self) -> CalibratedModel {
        CalibratedModel {
            residual: self.residual.as_ref().map(|(m, _)| m.clone()),
            motion: self.motion.clone(),
            ..physical_model(&self.kinematic)
        }
    }
}
