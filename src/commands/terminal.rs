//! The binary's observer: library messages as `robocal: …` lines on stderr, tasks as a progress
//! bar (drawn only on a terminal), the lines printed above the bar.

use std::sync::Mutex;

use indicatif::{ProgressBar, ProgressStyle};
use robocal_data::Observer;

/// Renders what the library crates report.
#[derive(Default)]
pub struct Terminal {
    bar: Mutex<Option<ProgressBar>>,
}

impl Terminal {
    fn with_bar(&self, f: impl FnOnce(&mut Option<ProgressBar>)) {
        f(&mut self
            .bar
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner));
    }
}

impl Observer for Terminal {
    fn message(&self, line: &str) {
        self.with_bar(|bar| match bar {
            Some(b) => b.suspend(|| eprintln!("robocal: {line}")),
            None => eprintln!("robocal: {line}"),
        });
    }

    fn start(&self, task: &str, length: u64) {
        self.with_bar(|bar| {
            if let Some(b) = bar.take() {
                b.finish_and_clear();
            }
            let b = ProgressBar::new(length);
            b.set_style(
                ProgressStyle::with_template(&format!(
                    "robocal: {task} [{{bar:30}}] {{pos}}/{{len}} {{elapsed}}"
                ))
                .unwrap_or_else(|_| ProgressStyle::default_bar()),
            );
            *bar = Some(b);
        });
    }

    fn advance(&self, units: u64) {
        self.with_bar(|bar| {
            if let Some(b) = bar {
                b.inc(units);
            }
        });
    }

    fn finish(&self) {
        self.with_bar(|bar| {
            if let Some(b) = bar.take() {
                b.finish_and_clear();
            }
        });
    }
}
