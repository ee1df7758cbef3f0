//! The default calibration's options as a user gives them, one spec for every way in: the
//! command line flattens it into `calibrate`'s arguments (feature `cli`), Python takes its
//! fields as keyword arguments of `calibrate`, and a stage file's `[default]` table holds them
//! (the default calibration with these options). Checked once ([`DefaultOptions::check`]); a
//! new option is a field here and its place in [`DefaultOptions::apply`].

use std::path::Path;

use robocal_residual::Frame;
use serde::Deserialize;

use crate::error::{CalibrationError, Result};
use crate::select::settings::{AutoSettings, DEFAULT_BUDGET_SECONDS};

/// The default calibration's options. Every one is optional: what is not given keeps the
/// default's own setting.
#[derive(Debug, Clone, Default, PartialEq, Deserialize)]
#[cfg_attr(feature = "cli", derive(clap::Args))]
#[serde(deny_unknown_fields)]
pub struct DefaultOptions {
    /// Weight of a 6-DoF probe's orientation rows, mm per degree [default: 2].
    #[cfg_attr(feature = "cli", arg(long, value_name = "MM_PER_DEG"))]
    pub angle_weight: Option<f64>,
    /// Time budget of the default calibration, s [default: 120].
    #[cfg_attr(feature = "cli", arg(long, value_name = "SECONDS"))]
    pub budget: Option<f64>,
    /// Keep the budget by counted work instead of the clock: the same model on any machine.
    #[cfg_attr(feature = "cli", arg(long))]
    #[serde(default)]
    pub reproducible: bool,
    /// Also try the bearings' tilt under the gravity moment (kept where it pays).
    #[cfg_attr(feature = "cli", arg(long))]
    #[serde(default)]
    pub tilt: bool,
    /// Also try backlash with searched torque flanks where the chosen physics has none.
    #[cfg_attr(feature = "cli", arg(long))]
    #[serde(default)]
    pub flank_search: bool,
    /// Highest order of the axis runouts tried [default: 2; 0: none].
    #[cfg_attr(feature = "cli", arg(long, value_name = "ORDERS"))]
    pub runout: Option<u32>,
    /// Frame the residual models learn in: `joint1` or `world` [default: chosen by the folds].
    #[cfg_attr(feature = "cli", arg(long, value_name = "FRAME"))]
    pub residual_frame: Option<String>,
}

impl DefaultOptions {
    /// These options where given, `other`'s elsewhere (a switch is on where either turns it
    /// on): the command line's over a stage file's `[default]`.
    pub fn or(&self, other: &DefaultOptions) -> DefaultOptions {
        DefaultOptions {
            angle_weight: self.angle_weight.or(other.angle_weight),
            budget: self.budget.or(other.budget),
            reproducible: self.reproducible || other.reproducible,
            tilt: self.tilt || other.tilt,
            flank_search: self.flank_search || other.flank_search,
            runout: self.runout.or(other.runout),
            residual_frame: (self.residual_frame.clone()).or(other.residual_frame.clone()),
        }
    }

    /// Checks every value, and that a stage file's explicit stages (`stages`: the file, where
    /// one is given) are given no option of the default but the orientations' weight, which
    /// weighs a stage's rows too: each refusal names the option as the command line and Python
    /// spell it, and what to write in the stage file instead.
    pub fn check(&self, stages: Option<&Path>) -> Result<()> {
        let refuse = |message: String| Err(CalibrationError::Stage(message));
        if let Some(w) = self.angle_weight
            && !(w.is_finite() && w > 0.0)
        {
            return refuse(format!(
                "`--angle-weight` (or `angle_weight=` in Python): {w} is not a positive number of mm per degree"
            ));
        }
        if let Some(b) = self.budget
            && !(b.is_finite() && b > 0.0)
        {
            return refuse(format!(
                "the time budget (`--budget`, or `budget=` in Python): {b} is not a positive number of seconds"
            ));
        }
        if let Some(r) = self.runout
            && r > robocal_ident::MAX_HARMONICS
        {
            return refuse(format!(
                "--runout: {r} orders; at most {}",
                robocal_ident::MAX_HARMONICS
            ));
        }
        let frame = self.frame()?;
        let Some(file) = stages else {
            return Ok(());
        };
        let file = file.display();
        if self.budget.is_some() {
            return refuse(format!(
                "the time budget (`--budget`, or `budget=` in Python) is the default calibration's; {file} runs the stages it names and takes none"
            ));
        }
        if let Some(frame) = frame {
            return refuse(format!(
                "`--residual-frame` (or `residual_frame=` in Python) is the default calibration's; {file} runs the stages it names: add `frame = \"{}\"` to its [residual]",
                frame.name()
            ));
        }
        if self.tilt {
            return refuse(format!(
                "`--tilt` (or `tilt=True` in Python) is the default calibration's; {file} runs the stages it names: add `tilt = true` to its [joint_errors]"
            ));
        }
        if self.runout.is_some() {
            return refuse(format!(
                "`--runout` is the default calibration's; {file} runs the stages it names: add `runout = 2` to its [joint_errors]"
            ));
        }
        if self.flank_search {
            return refuse(format!(
                "`--flank-search` (or `flank_search=True` in Python) is the default calibration's; {file} runs the stages it names: add `backlash = true` and `flank_search = true` to its [joint_errors]"
            ));
        }
        Ok(())
    }

    /// The residual models' frame, when one is named.
    pub fn frame(&self) -> Result<Option<Frame>> {
        (self.residual_frame.as_deref())
            .map(|f| {
                Frame::parse(f).map_err(|e| {
                    CalibrationError::Stage(format!(
                        "`--residual-frame` (or `residual_frame=` in Python): {e}"
                    ))
                })
            })
            .transpose()
    }

    /// The default calibration's settings with these options applied to `auto` (checked
    /// before: [`Self::check`]).
    pub fn apply(&self, mut auto: AutoSettings) -> Result<AutoSettings> {
        auto.angle_weight = self.angle_weight;
        auto.budget_seconds = self.budget.unwrap_or(DEFAULT_BUDGET_SECONDS);
        auto.reproducible = self.reproducible;
        auto.tilt = self.tilt;
        auto.flank_search = self.flank_search;
        if let Some(orders) = self.runout {
            auto.runout = orders;
        }
        if let Some(frame) = self.frame()? {
            for stage in &mut auto.residuals {
                stage.settings.frame = frame;
            }
            auto.both_frames_off_gravity = false;
        }
        Ok(auto)
    }
}
