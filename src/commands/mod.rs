//! The subcommands, each turning validated settings into library calls.

mod calibrate;
mod compensate;
mod evaluate;
mod export;
mod import;
mod model;
mod plan;
mod predict;
mod report;
mod run;
mod simulate;
mod terminal;

use std::io::Write;
use std::path::Path;

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
            report,
            options,
        } => calibrate::run(
            &robot,
            &data,
            validate.as_deref(),
            &out,
            config.as_deref(),
            robocal_calibration::Checks {
                force,
                keep_outliers,
            },
            report.as_deref(),
            &options,
        ),
        Command::Report { model, data, out } => report::run(&model, &data, &out),
        Command::Predict {
            source,
            data,
            out,
            sigma,
        } => predict::run(&source, &data, &out, sigma),
        Command::Evaluate {
            source,
            data,
            json,
            per_pose,
        } => evaluate::run(&source, &data, json, per_pose.as_deref()),
        Command::Compensate {
            model,
            targets,
            out,
            frame,
            tool,
        } => compensate::run(&model, &targets, &out, &frame, tool.as_deref()),
        Command::Simulate { twin, out, poses } => simulate::run(&twin, &out, poses.as_deref()),
        Command::Export {
            model,
            format,
            out,
            data,
        } => export::run(&model, format, &out, data.as_deref()),
        Command::Import {
            urdf,
            dh,
            convention,
            base,
            tip,
            tool,
            out,
        } => import::run(
            urdf.as_deref(),
            dh.as_deref().zip(convention),
            base.as_deref(),
            tip.as_deref(),
            tool.as_deref(),
            &out,
        ),
        Command::Plan {
            robot,
            count,
            out,
            config,
            candidates,
        } => plan::run(
            &robot,
            &count,
            &out,
            config.as_deref(),
            candidates.as_deref(),
        ),
        Command::Run { experiment, out } => run::run(&experiment, out.as_deref()),
    }
}

/// `--tool x,y,z`: three finite numbers, mm, in the frame `frame` names.
pub fn tool_point(text: &str, frame: &str) -> Result<nalgebra::Vector3<f64>> {
    let values: Vec<f64> = text
        .split(',')
        .map(|v| v.trim().parse::<f64>())
        .collect::<std::result::Result<_, _>>()
        .ok()
        .filter(|v: &Vec<f64>| v.len() == 3 && v.iter().all(|x| x.is_finite()))
        .ok_or_else(|| anyhow::anyhow!("--tool {text}: give three numbers x,y,z (mm, {frame})"))?;
    Ok(nalgebra::Vector3::new(values[0], values[1], values[2]))
}

/// Creates the folder an output file goes into, when it does not exist yet.
pub fn ensure_parent(out: &Path) -> Result<()> {
    if let Some(parent) = out.parent().filter(|p| !p.as_os_str().is_empty()) {
        std::fs::create_dir_all(parent)
            .map_err(|e| anyhow::anyhow!("{}: cannot create the folder: {e}", parent.display()))?;
    }
    Ok(())
}

/// Warns (stderr) when rows of `file` lie outside the joint readings and loads `model` was
/// calibrated on: predictions there are extrapolation.
pub fn warn_outside<'a>(
    model: &robocal_model::CalibratedModel,
    file: &Path,
    rows: impl IntoIterator<Item = &'a robocal_data::Sample>,
) {
    let rows: Vec<&robocal_data::Sample> = rows.into_iter().collect();
    if let Some(w) = (model.domain.as_ref()).and_then(|d| d.warning(file, rows.iter().copied())) {
        eprintln!("robocal: warning: {w}");
    }
    if let Some(w) = (model.motion.as_ref()).and_then(|m| m.warning(file, rows.iter().copied())) {
        eprintln!("robocal: warning: {w}");
    }
}

/// Outputs are replaced atomically when they exist (the documented rule); the replacement is
/// said on stderr. Call before writing: the returned closure says it after a successful write.
pub fn replacing(out: &Path) -> impl FnOnce() + '_ {
    let existed = out.exists();
    move || {
        if existed {
            eprintln!("robocal: {} existed and was replaced", out.display());
        }
    }
}

/// Writes `text` to stdout. A reader that went away (`robocal evaluate … | head -3`) ends the
/// output, not the command: a broken pipe is no error, where `println!` would panic.
pub(crate) fn print_out(text: &str) -> Result<()> {
    let mut out = std::io::stdout().lock();
    match out.write_all(text.as_bytes()).and_then(|()| out.flush()) {
        Err(e) if e.kind() != std::io::ErrorKind::BrokenPipe => Err(e.into()),
        _ => Ok(()),
    }
}
