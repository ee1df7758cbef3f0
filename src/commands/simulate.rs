//! `robocal simulate`.

use std::path::Path;

use anyhow::Result;
use robocal_data::{SampleSet, check_targets, write_dir_atomically};
use robocal_twin::{PointStatus, TwinConfig};

/// Generates the twin's dataset into `out` (its own pose design, or the rows of `poses`) and
/// says what it wrote.
pub fn run(twin: &Path, out: &Path, poses: Option<&Path>) -> Result<()> {
    let config = TwinConfig::load(twin)?;
    if let Some(poses) = poses {
        let samples = SampleSet::read(poses, config.truth.dof())?;
        check_targets(poses, &samples.rows, &config.truth.point_names())?;
        let (measured, truth) = config.measure_samples(&samples.rows);
        let said = super::replacing(out);
        write_dir_atomically(out, |dir| -> Result<()> {
            measured.write(dir.join("measurements.csv"))?;
            truth.write(dir.join("truth.csv"))?;
            Ok(())
        })?;
        said();
        eprintln!(
            "robocal: measured the {} rows of {} on the twin: wrote measurements.csv (with tracker noise) and truth.csv to {}",
            measured.len(),
            poses.display(),
            out.display()
        );
        return Ok(());
    }
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
        "robocal: wrote {} rows ({} configurations × {} loads{}) to {}",
        data.measurements.len(),
        kept,
        config.loads.all().len(),
        match config.truth.points.len() {
            0 => String::new(),
            n => format!(" × {} reflectors", n + 1),
        },
        out.display()
    );
    Ok(())
}
