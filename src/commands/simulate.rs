//! `robocal simulate`.

use std::path::Path;

use anyhow::Result;
use robocal_twin::{PointStatus, TwinConfig};

/// Generates the twin's dataset into `out` and says what it wrote.
pub fn run(twin: &Path, out: &Path) -> Result<()> {
    let config = TwinConfig::load(twin)?;
    let said = super::replacing(out);
    let data = config.write_dataset(out)?;
    said();
    let d = &data.design;
    let kept = d.count(PointStatus::Kept);
    eprintln!(
        "robocal: {} grid points: {} kept, {} measurable but not chosen, {} unreachable, {} near-singular",
        d.points.len(),
        kept,
        d.count(PointStatus::NotChosen),
        d.count(PointStatus::Unreachable),
        d.count(PointStatus::NearSingular),
    );
    if kept < config.poses.count {
        eprintln!(
            "robocal: warning: {} configurations asked for, only {kept} are measurable",
            config.poses.count
        );
    }
    eprintln!(
        "robocal: wrote {} rows ({} configurations × {} loads) to {}",
        data.measurements.len(),
        kept,
        config.loads.all().len(),
        out.display()
    );
    Ok(())
}
