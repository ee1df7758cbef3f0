//! The default calibration's time budget, kept by the clock or by counted work.
//!
//! By the clock (the default) every decision of the budget — a candidate skipped before its folds,
//! abandoned during them, a fold's fit stopped — reads the time the selection has taken, so where
//! the budget binds a seed's model depends on the machine's pace (one case of the paper's arm,
//! three runs: two models). By counted work (`reproducible`) the same decisions read what the fits
//! and trainings have counted, turned into the seconds a reference machine of [`REFERENCE_CORES`]
//! cores takes for it: the same on every machine and any number of cores, so a seed gives one
//! model. The clock stays as a guard: no fit runs past the budget itself, and no candidate starts
//! once the clock is past what the counts say — on a machine slower than the reference the clock
//! then decides, and the model may again depend on it.

use std::sync::Mutex;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::{Duration, Instant};

use robocal_data::Observer;
use robocal_residual::{ResidualKind, ResidualStage};

/// The cores of the machine the counted budget is sized for (120 s for 1000 rows on 2 cores):
/// counted work turns into its seconds at this many cores' worth per second.
pub const REFERENCE_CORES: usize = 2;

/// Identification work ([`robocal_ident::Work`]: each evaluation's residuals and each Jacobian's
/// entries) one core of the reference machine does in a second. Measured on this project's
/// 2-core machine (every fold fit of two cases, the paper's arm and ARM7 with a
/// field): 13–21 M units/s for the compliances alone, 21–39 M/s for the candidates that spend the
/// budget (the joint-error blocks, the runouts the fastest per unit). The lower end of those, so
/// that the counted seconds run ahead of the clock's there and the clock's guard stays idle.
/// Timed one core at a time (24 candidates on three arms), the seconds counted at this
/// rate are 0.45–1.73× a fit's own: the count leaves out the work outside the solves and weighs a
/// residual row far below its cost.
pub const FIT_UNITS_PER_SECOND: f64 = 21e6;

/// A Gaussian process's training work (`training_seconds`: its likelihood evaluations × the
/// rows they are fitted on, cubed, and a third of the rows it conditions on, cubed) that the
/// reference machine does in a second of a training beside another fold's (its three axes'
/// fits together). Measured (every fold of three cases with a field, 80 evaluations):
/// 2.5e9 on ARM7 (486 rows), 2.7e9 on ARM5 (288), 3.4e9 on the paper's arm (2100 rows, 500 in
/// the likelihood); the paper's arm's, where the budget binds, counted a little ahead of its clock.
pub const GP_UNITS_PER_SECOND: f64 = 3.0e9;

/// A network's training work, epochs × rows × inputs (every network of the model together),
/// that the reference machine does in a second of a training beside another fold's. Measured
/// (SOMM, the same cases): 1.16e6 on the paper's arm, 1.22e6 on ARM7, 1.24e6 on
/// ARM5.
pub const NETWORK_UNITS_PER_SECOND: f64 = 1.15e6;

/// What the selection has spent, by the budget's measure.
pub(crate) struct Meter {
    start: Instant,
    budget: f64,
    /// Where the clock's guard ends a counted budget, seconds (the budget itself, but in tests).
    guard: f64,
    /// The counted seconds charged so far (`None`: by the clock).
    counted: Option<Mutex<f64>>,
}

impl Meter {
    /// A budget of `budget` seconds from now, kept by counted work where `reproducible`.
    pub(crate) fn new(budget: f64, reproducible: bool) -> Self {
        Self {
            start: Instant::now(),
            budget,
            guard: budget,
            counted: reproducible.then(|| Mutex::new(0.0)),
        }
    }

    /// A counted budget of `budget` seconds whose clock's guard is at `guard` seconds (tests: a
    /// budget that binds on counts within the guard however slow the machine running them).
    #[cfg(test)]
    pub(crate) fn guarded(budget: f64, guard: f64) -> Self {
        Self {
            guard,
            ..Self::new(budget, true)
        }
    }

    /// Whether the budget is kept by counted work.
    pub(crate) fn counts(&self) -> bool {
        self.counted.is_some()
    }

    /// Seconds the clock says the selection has taken.
    pub(crate) fn clock(&self) -> f64 {
        self.start.elapsed().as_secs_f64()
    }

    /// Seconds spent by the budget's measure: counted ones, or the clock's.
    pub(crate) fn spent(&self) -> f64 {
        match &self.counted {
            Some(c) => *c.lock().unwrap_or_else(|e| e.into_inner()),
            None => self.clock(),
        }
    }

    /// Charges `seconds` of counted work (nothing by the clock).
    pub(crate) fn charge(&self, seconds: f64) {
        if let Some(c) = &self.counted {
            *c.lock().unwrap_or_else(|e| e.into_inner()) += seconds;
        }
    }

    /// Whether `more` seconds (by the budget's measure) would run past the budget; counted, also
    /// when they would by the clock (the guard).
    pub(crate) fn over(&self, more: f64) -> bool {
        self.spent() + more > self.budget || (self.counts() && self.clock() + more > self.guard)
    }

    /// Seconds the budget has left, by its measure.
    pub(crate) fn left(&self) -> f64 {
        self.budget - self.spent()
    }

    /// When the budget ends by the clock: counted, no fit runs past it.
    pub(crate) fn end(&self) -> Instant {
        self.start + Duration::from_secs_f64(self.guard.max(0.0))
    }
}

/// What one candidate may spend: the selection's budget ([`Meter`]) less the seconds kept from
/// it for what comes after (the residual models, the final fit). Every decision of the budget
/// about a candidate — skipped before its folds, abandoned during them, a fold's fit stopped —
/// reads it.
#[derive(Clone, Copy)]
pub(crate) struct Allowance<'m> {
    meter: &'m Meter,
    reserve: f64,
}

impl<'m> Allowance<'m> {
    /// The whole budget `meter` keeps.
    pub(crate) fn new(meter: &'m Meter) -> Self {
        Self {
            meter,
            reserve: 0.0,
        }
    }

    /// This allowance with `seconds` more kept back.
    pub(crate) fn keeping(self, seconds: f64) -> Self {
        Self {
            reserve: self.reserve + seconds,
            ..self
        }
    }

    /// The meter it is kept by.
    pub(crate) fn meter(&self) -> &'m Meter {
        self.meter
    }

    /// The seconds kept back from it.
    pub(crate) fn reserve(&self) -> f64 {
        self.reserve
    }

    /// The budget itself, s.
    pub(crate) fn budget(&self) -> f64 {
        self.meter.budget
    }

    /// Whether `more` seconds (by the budget's measure) would run past it.
    pub(crate) fn over(&self, more: f64) -> bool {
        self.meter.over(more + self.reserve)
    }

    /// Seconds it has left, by the budget's measure.
    pub(crate) fn left(&self) -> f64 {
        self.meter.left() - self.reserve
    }
}

/// The reference machine's seconds for identification work of `units`, its folds on every one
/// of its cores.
pub(crate) fn fit_seconds(units: u64) -> f64 {
    units as f64 / (FIT_UNITS_PER_SECOND * REFERENCE_CORES as f64)
}

/// The work of training `stage` on `rows` rows of a `joints`-joint arm for `epochs` epochs (a
/// network's, as its training counted them; a GP has none and spends its likelihood
/// evaluations), in the reference machine's seconds of a training beside another fold's: a GP's
/// evaluations × (its likelihood's rows, at most `hyper_rows`)³ + (the rows it conditions on, at
/// most `max_rows`)³ / 3; a network's epochs × rows × inputs (sine and cosine of each joint, and
/// the load).
pub(crate) fn training_seconds(
    stage: &ResidualStage,
    rows: usize,
    joints: usize,
    epochs: u64,
) -> f64 {
    let gp = &stage.settings.gp;
    match stage.settings.kind {
        ResidualKind::Gp => {
            let fitted = rows.min(gp.hyper_rows) as f64;
            let conditioned = rows.min(gp.max_rows) as f64;
            (gp.iterations as f64 * fitted.powi(3) + conditioned.powi(3) / 3.0)
                / GP_UNITS_PER_SECOND
        }
        _ => epochs as f64 * rows as f64 * (2 * joints + 1) as f64 / NETWORK_UNITS_PER_SECOND,
    }
}

/// Counts the epochs a training reports (its progress's units), and says nothing.
#[derive(Default)]
pub(crate) struct Epochs(AtomicU64);

impl Epochs {
    /// The epochs counted.
    pub(crate) fn count(&self) -> u64 {
        self.0.load(Ordering::SeqCst)
    }
}

impl Observer for Epochs {
    fn advance(&self, units: u64) {
        self.0.fetch_add(units, Ordering::SeqCst);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Counted, the meter spends only what it is charged, and its guard holds where the clock is
    /// ahead of the counts; by the clock, charges count for nothing.
    #[test]
    fn a_counted_meter_spends_what_it_is_charged_and_keeps_the_clock_as_a_guard() {
        let counted = Meter::new(10.0, true);
        assert!(counted.counts());
        assert_eq!(counted.spent(), 0.0);
        counted.charge(4.0);
        counted.charge(2.5);
        assert_eq!(counted.spent(), 6.5);
        assert_eq!(counted.left(), 3.5);
        assert!(!counted.over(3.0));
        assert!(counted.over(3.6));
        // A budget the clock has already run past: the guard stops what the counts allow.
        let late = Meter::new(0.0, true);
        std::thread::sleep(Duration::from_millis(2));
        assert_eq!(late.spent(), 0.0);
        assert!(late.over(0.0));
        let clock = Meter::new(10.0, false);
        clock.charge(100.0);
        assert!(!clock.counts() && clock.spent() < 1.0 && !clock.over(1.0));
    }

    /// The reference seconds of counted work: identification on the reference machine's cores;
    /// a GP's likelihood evaluations × rows³ (at most `hyper_rows`) and its conditioning, a
    /// network's epochs × rows × inputs.
    #[test]
    fn counted_work_turns_into_the_reference_machines_seconds() {
        let units = (FIT_UNITS_PER_SECOND * REFERENCE_CORES as f64 * 3.0) as u64;
        assert!((fit_seconds(units) - 3.0).abs() < 1e-9);
        let gp = ResidualStage {
            settings: robocal_residual::ResidualSettings::gp(1),
            holdout: 0.2,
        };
        let (iterations, hyper) = (gp.settings.gp.iterations as f64, gp.settings.gp.hyper_rows);
        let seconds = training_seconds(&gp, 100, 6, 0);
        let by_hand = (iterations * 1e6 + 1e6 / 3.0) / GP_UNITS_PER_SECOND;
        assert!((seconds - by_hand).abs() < 1e-12 * by_hand);
        // Below `hyper_rows` eight times the work at twice the rows, whatever the epochs; past
        // it, the likelihood's rows held.
        assert!((training_seconds(&gp, 200, 6, 7) - 8.0 * seconds).abs() < 1e-12);
        let past = training_seconds(&gp, 2 * hyper, 6, 0);
        let held = (iterations * (hyper as f64).powi(3) + (2.0 * hyper as f64).powi(3) / 3.0)
            / GP_UNITS_PER_SECOND;
        assert!((past - held).abs() < 1e-12 * held);
        let somm = ResidualStage {
            settings: robocal_residual::ResidualSettings::robocal(ResidualKind::Somm, 1),
            holdout: 0.2,
        };
        assert_eq!(
            training_seconds(&somm, 500, 6, 40),
            40.0 * 500.0 * 13.0 / NETWORK_UNITS_PER_SECOND
        );
        let epochs = Epochs::default();
        epochs.advance(3);
        epochs.advance(4);
        assert_eq!(epochs.count(), 7);
    }
}
