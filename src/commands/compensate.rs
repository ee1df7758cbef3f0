//! `robocal compensate`: corrected joint commands for targets.

use std::io::Write;
use std::path::Path;

use anyhow::{Result, bail};
use robocal_compensate::{CompensationOptions, compensate};
use robocal_data::{csv_text, fixed6, read_targets, write_atomically};
use robocal_model::CalibratedModel;

/// Compensates every target, writes the commands of those that converged (atomically) and
/// fails naming the others.
pub fn run(model_dir: &Path, targets: &Path, out: &Path) -> Result<()> {
    let model = CalibratedModel::load(model_dir)?;
    let targets = read_targets(targets, model.robot.dof())?;
    let options = CompensationOptions::default();
    let mut rows = Vec::with_capacity(targets.len());
    let mut failed = Vec::new();
    let mut worst: f64 = 0.0;
    for t in &targets {
        match compensate(
            &model,
            &t.position,
            t.sample.load,
            &t.sample.joints,
            &options,
        ) {
            Ok(c) => {
                worst = worst.max(c.model_error);
                rows.push((t.sample.pose.clone(), c.joints_deg));
            }
            Err(why) => failed.push(format!("{} (line {}): {why}", t.sample.pose, t.sample.line)),
        }
    }
    let dof = model.robot.dof();
    let said = super::replacing(out);
    write_atomically(out, |w: &mut dyn Write| {
        let header: Vec<String> = (1..=dof).map(|i| format!("q{i}")).collect();
        writeln!(w, "id,{}", header.join(","))?;
        for (id, q) in &rows {
            let values: Vec<String> = q.iter().map(|v| fixed6(*v)).collect();
            writeln!(w, "{},{}", csv_text(id), values.join(","))?;
        }
        Ok(())
    })?;
    said();
    eprintln!(
        "robocal: {} of {} targets compensated (model error at most {:.2e} mm), written to {}",
        rows.len(),
        targets.len(),
        worst,
        out.display()
    );
    if !failed.is_empty() {
        bail!(
            "{} target(s) could not be compensated and are not in {}:\n  {}",
            failed.len(),
            out.display(),
            failed.join("\n  ")
        );
    }
    Ok(())
}
