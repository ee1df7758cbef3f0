//! `robocal run`: an experiment from its TOML file to its report folder.

use std::path::Path;

use anyhow::Result;
use robocal_pipeline::{Experiment, run as run_experiment, write_report};

use super::terminal::Terminal;

/// Runs the experiment, prints its tables on stdout and writes the report folder.
pub fn run(experiment: &Path, out: Option<&Path>) -> Result<()> {
    let plan = Experiment::load(experiment)?;
    let mut outcome = run_experiment(&plan, &Terminal::default())?;
    let written = write_report(&mut outcome, out)?;
    super::print_out(&format!("{}\n", written.tables))?;
    eprintln!(
        "robocal: report written to {} ({:.1} s in all)",
        written.dir.display(),
        outcome.timings.total_s + outcome.timings.report_s
    );
    Ok(())
}
