//! `robocal evaluate`.

use std::fmt::Write as _;
use std::path::Path;

use anyhow::Result;
use robocal_data::{ErrorStats, MeasurementSet, csv_text, fixed6, write_atomically};

use super::model;
use crate::cli::ModelSource;

/// A nominal table's mean error beyond which the data are probably in another frame, mm.
const OTHER_FRAME: f64 = 50.0;

/// Prints the statistics of the Euclidean error between predicted and measured points, and
/// the worst rows; writes every row's error to `per_pose` when given.
pub fn run(source: &ModelSource, data: &Path, json: bool, per_pose: Option<&Path>) -> Result<()> {
    let model = model::load(source)?;
    let set = MeasurementSet::read(data, model.robot.dof())?;
    model.check_targets(data, set.rows.iter().map(|m| &m.sample))?;
    super::warn_outside(&model, data, set.rows.iter().map(|m| &m.sample));
    let residuals = model.residuals(&set.rows);
    let errors: Vec<f64> = residuals.iter().map(|r| r.norm()).collect();
    let stats = ErrorStats::from_errors(&errors);
    // A 6-DoF probe's rows: the angle between measured and predicted tool frames, deg, per row
    // (none for a row without an orientation), and their statistics.
    let angles: Vec<Option<f64>> = if set.has_orientation() {
        set.rows
            .iter()
            .map(|m| model.orientation_error(m))
            .collect()
    } else {
        Vec::new()
    };
    let orientation = set
        .has_orientation()
        .then(|| ErrorStats::from_errors(&angles.iter().flatten().copied().collect::<Vec<_>>()));
    if let Some(path) = per_pose {
        let said = super::replacing(path);
        // A `target` column after `pose` when the rows name reflectors.
        let targets = set.rows.iter().any(|m| !m.sample.target.is_empty());
        write_atomically(path, |w| {
            let target_header = if targets { ",target" } else { "" };
            // A 6-DoF probe's file: each row's angle between measured and predicted tool frames.
            let angle_header = if orientation.is_some() {
                ",angle_deg"
            } else {
                ""
            };
            writeln!(
                w,
                "pose{target_header},line,load,dx,dy,dz,error{angle_header}"
            )?;
            for (i, ((m, r), e)) in set.rows.iter().zip(&residuals).zip(&errors).enumerate() {
                let pose = if targets {
                    format!(
                        "{},{}",
                        csv_text(&m.sample.pose),
                        csv_text(&m.sample.target)
                    )
                } else {
                    csv_text(&m.sample.pose)
                };
                write!(
                    w,
                    "{},{},{},{},{},{},{}",
                    pose,
                    m.sample.line,
                    m.sample.load,
                    fixed6(r.x),
                    fixed6(r.y),
                    fixed6(r.z),
                    fixed6(*e)
                )?;
                match angles.get(i) {
                    Some(Some(a)) => writeln!(w, ",{}", fixed6(*a))?,
                    Some(None) => writeln!(w, ",")?,
                    None => writeln!(w)?,
                }
            }
            Ok(())
        })?;
        said();
    }
    let mut text = String::new();
    if json {
        let mut value = serde_json::to_value(stats)?;
        if let (Some(o), Some(map)) = (&orientation, value.as_object_mut()) {
            map.insert("orientation_deg".into(), serde_json::to_value(o)?);
        }
        writeln!(text, "{value}")?;
    } else {
        writeln!(text, "count {}", stats.count)?;
        writeln!(text, "mean  {:.6} mm", stats.mean)?;
        writeln!(text, "std   {:.6} mm", stats.std)?;
        writeln!(text, "rms   {:.6} mm", stats.rms)?;
        writeln!(text, "max   {:.6} mm", stats.max)?;
        if let Some(o) = &orientation {
            writeln!(
                text,
                "orientation (angle between measured and predicted tool frames):"
            )?;
            writeln!(text, "  count {}", o.count)?;
            writeln!(text, "  mean  {:.6} deg", o.mean)?;
            writeln!(text, "  std   {:.6} deg", o.std)?;
            writeln!(text, "  rms   {:.6} deg", o.rms)?;
            writeln!(text, "  max   {:.6} deg", o.max)?;
        }
        let mut order: Vec<usize> = (0..errors.len()).collect();
        order.sort_by(|&a, &b| errors[b].total_cmp(&errors[a]));
        writeln!(text, "worst rows:")?;
        for &i in order.iter().take(5) {
            let m = &set.rows[i];
            writeln!(
                text,
                "  {:.6} mm  pose {} (line {}, load {} kg)",
                errors[i], m.sample.pose, m.sample.line, m.sample.load
            )?;
        }
    }
    super::print_out(&text)?;
    if source.robot.is_some() && stats.mean > OTHER_FRAME {
        eprintln!(
            "robocal: hint: a mean error of {:.1} mm from a robot file: its base is only a guess of where the robot stands in the tracker frame (and the table is nominal); `robocal calibrate` registers the base, or give data in the robot file's frame",
            stats.mean
        );
    }
    Ok(())
}
