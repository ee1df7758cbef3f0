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
            eprintln!("robocal: error: {}", message(&err));
            ExitCode::FAILURE
        }
    }
}

/// The error and its causes as one line, each cause once: library errors already quote their
/// source (`{path}: cannot read: {source}`), so a cause whose text is already in the message is
/// not repeated.
fn message(err: &anyhow::Error) -> String {
    let mut text = String::new();
    for cause in err.chain() {
        let part = cause.to_string();
        if text.contains(&part) {
            continue;
        }
        if !text.is_empty() {
            text.push_str(": ");
        }
        text.push_str(&part);
    }
    text
}
