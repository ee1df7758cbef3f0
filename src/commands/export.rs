//! `robocal export`.

use std::path::Path;

use anyhow::{Context, Result, bail};
use robocal_data::{Measurement, MeasurementSet, write_atomically};
use robocal_model::export::{
    PARITY_CONFIGURATIONS, PARITY_TOLERANCE_MM, json_table, not_carried, urdf_parity, urdf_text,
};
use robocal_model::{CalibratedModel, REPORT_FILE};

use crate::cli::ExportFormat;

/// Writes the model's table in `format` to `out`, after checking it.
pub fn run(model_dir: &Path, format: ExportFormat, out: &Path, data: Option<&Path>) -> Result<()> {
    let model = CalibratedModel::load(model_dir)?;
    let text = match format {
        ExportFormat::Urdf => {
            let text = urdf_text(&model.robot)
                .map_err(|e| anyhow::anyhow!("{}: cannot write the URDF: {e}", out.display()))?;
            let worst = urdf_parity(&model.robot, &text).map_err(|e| {
                anyhow::anyhow!("{}: the URDF does not read back: {e}", out.display())
            })?;
            if worst > PARITY_TOLERANCE_MM {
                bail!(
                    "{}: the URDF's forward kinematics differ from the model's table by {worst:.3e} mm (tolerance {PARITY_TOLERANCE_MM:e}); nothing written",
                    out.display()
                );
            }
            eprintln!(
                "robocal: the URDF read back (urdf-rs) reproduces the table on {PARITY_CONFIGURATIONS} configurations over the joint limits: largest difference {worst:.2e} mm"
            );
            text
        }
        ExportFormat::Json => {
            let report_path = model_dir.join(REPORT_FILE);
            let report: Option<serde_json::Value> = match std::fs::read_to_string(&report_path) {
                Ok(t) => Some(
                    serde_json::from_str(&t)
                        .with_context(|| format!("{}: not JSON", report_path.display()))?,
                ),
                Err(_) => None,
            };
            serde_json::to_string_pretty(&json_table(&model, report.as_ref()))? + "\n"
        }
    };
    super::ensure_parent(out)?;
    let said = super::replacing(out);
    write_atomically(out, |w| w.write_all(text.as_bytes()))?;
    said();
    let missing = not_carried(&model);
    if missing.is_empty() {
        eprintln!("robocal: the model is its kinematic table: the export carries all of it");
    } else {
        let cost = match data {
            Some(path) => {
                let set = MeasurementSet::read(path, model.dof())?;
                let rows: Vec<&Measurement> = set.rows.iter().collect();
                let table = CalibratedModel::kinematic(model.robot.clone()).stats(&rows);
                let whole = model.stats(&rows);
                format!(
                    ": on {} ({} rows) the table alone leaves {:.4} mm mean ({:.4} max), the whole model {:.4} ({:.4})",
                    path.display(),
                    rows.len(),
                    table.mean,
                    table.max,
                    whole.mean,
                    whole.max
                )
            }
            None => "; give --data FILE to see the error that leaves".to_string(),
        };
        eprintln!(
            "robocal: the export cannot carry {}{cost}",
            missing.join(", ")
        );
    }
    eprintln!("robocal: wrote {}", out.display());
    Ok(())
}
