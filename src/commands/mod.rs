//! The subcommands, each turning validated settings into library calls.

mod calibrate;
mod compensate;
mod evaluate;
mod model;
mod predict;
mod run;
mod simulate;
mod terminal;

use anyhow::Result;

use crate::cli::{Cli, Command};

/// Runs one parsed command line.
pub fn run(cli: Cli) -> Result<()> {
    match cli.command {
        Command::Calibrate {
            robot,
            data,
            validate,
            out,
            config,
            force,
            keep_outliers,
        } => calibrate::run(
            &robot,
            &data,
            validate.as_deref(),
            &out,
            config.as_deref(),
            calibrate::Checks {
                force,
                keep_outliers,
            },
        ),
        Command::Predict {
            source,
            data,
            out,
            sigma,
        } => predict::run(&source, &data, &out, sigma),
        Command::Evaluate { source, data, json } => evaluate::run(&source, &data, json),
        Command::Compensate {
            model,
            targets,
            out,
        } => compensate::run(&model, &targets, &out),
        Command::Simulate { twin, out } => simulate::run(&twin, &out),
        Command::Run { experiment, out } => run::run(&experiment, out.as_deref()),
    }
}
