//! How long computations report to whoever runs them, as argmin's observers do: library code
//! never prints; it tells an [`Observer`], which the binary renders (lines on stderr, a progress
//! bar) and a library user may ignore ([`Silent`]) or collect.

/// Hears what a calibration, an experiment or a training does. Every method has an empty
/// default, so an observer implements only what it shows.
pub trait Observer: Sync {
    /// A line for the user (a candidate's score, a decision, a stage's result).
    fn message(&self, line: &str) {
        let _ = line;
    }
    /// A task of `length` units begins (`task` names it and its unit); it replaces the task
    /// before it.
    fn start(&self, task: &str, length: u64) {
        let _ = (task, length);
    }
    /// `units` more units of the current task are done.
    fn advance(&self, units: u64) {
        let _ = units;
    }
    /// The current task is over.
    fn finish(&self) {}
}

/// Hears nothing.
#[derive(Debug, Clone, Copy, Default)]
pub struct Silent;

impl Observer for Silent {}

/// Keeps every line it hears (tests, and library users who want the log).
#[derive(Debug, Default)]
pub struct Lines(pub std::sync::Mutex<Vec<String>>);

impl Lines {
    /// The lines heard so far.
    pub fn take(&self) -> Vec<String> {
        std::mem::take(
            &mut *self
                .0
                .lock()
                .unwrap_or_else(std::sync::PoisonError::into_inner),
        )
    }
}

impl Observer for Lines {
    fn message(&self, line: &str) {
        (self
            .0
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner))
        .push(line.to_string());
    }
}
