//! Identifications remembered by table, rows and settings, so that the candidates of a
//! selection and their folds share the fits they start from.

use super::frames::align;
use super::report::KinematicCalibration;
use super::settings::KinematicSettings;
use crate::error::Result;
use crate::problem::Observations;
use robocal_robot::Robot;

/// Alignments ([`align`]) and identifications already made, each with the table, rows and
/// settings it was made from ([`calibrate_kinematics_with`]): one calibration's identifications
/// (the first fit of the links' weights, the backlash flank rounds, the comparison of the tilts)
/// and the default calibration's candidates on one fold share them. Only what succeeded is
/// kept; each set of rows is kept once. Safe to share between threads (the lock is held for a
/// lookup or an insertion, never while fitting).
///
/// [`calibrate_kinematics_with`]: super::calibrate_kinematics_with
#[derive(Default)]
pub struct FitMemo(std::sync::Mutex<MemoEntries>);

/// What a [`FitMemo`] holds.
#[derive(Default)]
pub(super) struct MemoEntries {
    /// Every set of rows an entry was made from.
    pub(super) rows: Vec<Observations>,
    /// Alignments: the table, its rows (index into `rows`) and the aligned table.
    pub(super) aligned: Vec<(Robot, usize, Robot)>,
    /// Identifications: the table, its rows, the settings and the result.
    pub(super) fits: Vec<(Robot, usize, KinematicSettings, KinematicCalibration)>,
}

impl MemoEntries {
    /// The index of `obs` in `rows`, if held.
    pub(super) fn rows_of(&self, obs: &Observations) -> Option<usize> {
        self.rows.iter().position(|o| o == obs)
    }

    /// The index of `obs` in `rows`, added if not held.
    pub(super) fn keep_rows(&mut self, obs: &Observations) -> usize {
        self.rows_of(obs).unwrap_or_else(|| {
            self.rows.push(obs.clone());
            self.rows.len() - 1
        })
    }
}

impl FitMemo {
    /// Its entries, locked (a panic elsewhere while it was held leaves them usable: every
    /// entry is pushed whole).
    pub(super) fn entries(&self) -> std::sync::MutexGuard<'_, MemoEntries> {
        self.0.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// [`align`]`(robot, obs)`, remembered.
    pub(super) fn align(&self, robot: &Robot, obs: &Observations) -> Result<Robot> {
        {
            let e = self.entries();
            if let Some(k) = e.rows_of(obs)
                && let Some((_, _, aligned)) =
                    (e.aligned.iter()).find(|(r, o, _)| *o == k && r == robot)
            {
                return Ok(aligned.clone());
            }
        }
        let aligned = align(robot, obs)?;
        let mut e = self.entries();
        let k = e.keep_rows(obs);
        e.aligned.push((robot.clone(), k, aligned.clone()));
        Ok(aligned)
    }

    /// The identification of `nominal` from `obs` with `settings`, if remembered.
    pub(super) fn fit(
        &self,
        nominal: &Robot,
        obs: &Observations,
        settings: &KinematicSettings,
    ) -> Option<KinematicCalibration> {
        let settings = undated(settings);
        let e = self.entries();
        let k = e.rows_of(obs)?;
        (e.fits.iter())
            .find(|(r, o, s, _)| *o == k && *s == settings && r == nominal)
            .map(|(_, _, _, fit)| fit.clone())
    }

    /// Remembers `fit`, the identification of `nominal` from `obs` with `settings`.
    pub(super) fn remember(
        &self,
        nominal: &Robot,
        obs: &Observations,
        settings: &KinematicSettings,
        fit: &KinematicCalibration,
    ) {
        let mut e = self.entries();
        let k = e.keep_rows(obs);
        (e.fits).push((nominal.clone(), k, undated(settings), fit.clone()));
    }

    /// How many identifications it remembers.
    pub fn fits(&self) -> usize {
        self.entries().fits.len()
    }
}

/// `settings` as a [`FitMemo`] tells identifications apart: without their deadline and work count (a fit that
/// ended is the same whatever time it had to end by, so the candidates' folds, each with its own
/// deadline, share it), and without the flank search where no flank is chosen (no backlash, the
/// approach flanks alone, or the flanks given): the search candidate's folds share the fits its
/// rounds start from — the first fit without the links' weights and the fit on the approach
/// flanks — with the candidate without the search.
pub(crate) fn undated(settings: &KinematicSettings) -> KinematicSettings {
    let mut key = KinematicSettings {
        deadline: None,
        work: None,
        ..settings.clone()
    };
    if let Some(je) = key.joint_errors.as_mut()
        && (!je.backlash || !je.backlash_torque || je.flanks.is_some())
    {
        je.flank_search = false;
    }
    key
}
