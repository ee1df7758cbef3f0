//! `robocal`: calibrate industrial robots from laser-tracker measurements.
//!
//! A thin binary over the library crates: arguments are parsed here, turned into validated
//! settings and handed to the crates. Errors reach the user as one paragraph on stderr and a
//! non-zero exit status.

mod cli;
mod commands;

use std::process::ExitCode;

use clap::Parser;

fn main() -> ExitCode {
    let cli = cli::Cli::parse();
    match commands::run(cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(err) => {
            eprintln!(
                "robocal: error: {}",
                robocal_calibration::message(err.as_ref())
            );
            ExitCode::FAILURE
        }
    }
}
