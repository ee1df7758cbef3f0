//! `robocal compensate`: corrected joint commands for targets.

use std::io::Write;
use std::path::Path;

use anyhow::{Context, Result, bail};
use nalgebra::{Matrix3, Vector3};
use robocal_compensate::{CompensationOptions, compensate};
use robocal_data::{Sample, csv_text, fixed6, read_targets, write_atomically};
use robocal_model::CalibratedModel;
use robocal_robot::{TomlFault, rpy_to_matrix};
use serde::Deserialize;

/// A user frame file: the frame's origin (mm) and fixed-axis roll, pitch, yaw (deg) in the
/// robot base frame {0}.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct UserFrame {
    #[serde(deserialize_with = "robocal_robot::exact::array")]
    xyz: [f64; 3],
    #[serde(deserialize_with = "robocal_robot::exact::array")]
    rpy: [f64; 3],
}

/// The transform from the targets' frame to the world frame: (rotation, origin).
fn frame_to_world(frame: &str, model: &CalibratedModel) -> Result<(Matrix3<f64>, Vector3<f64>)> {
    let base = (model.robot.base_rotation(), model.robot.base.xyz);
    match frame {
        "world" => Ok((Matrix3::identity(), Vector3::zeros())),
        "base" => Ok(base),
        file => {
            let path = Path::new(file);
            let text = std::fs::read_to_string(path).with_context(|| {
                format!("--frame {file}: not `world`, `base` or a readable user-frame file")
            })?;
            let user: UserFrame =
                toml::from_str(&text).map_err(|e| TomlFault::of(path, &text, &e))?;
            if user.xyz.iter().chain(&user.rpy).any(|v| !v.is_finite()) {
                bail!("{}: xyz and rpy must be finite numbers", path.display());
            }
            let rpy = Vector3::from(user.rpy).map(f64::to_radians);
            let (r, t) = (rpy_to_matrix(&rpy), Vector3::from(user.xyz));
            Ok((base.0 * r, base.0 * t + base.1))
        }
    }
}

/// Compensates every target, writes the commands of those that converged (atomically) and
/// fails naming the others.
pub fn run(
    model_dir: &Path,
    targets: &Path,
    out: &Path,
    frame: &str,
    tool: Option<&str>,
) -> Result<()> {
    let mut model = CalibratedModel::load(model_dir)?;
    let (rotation, origin) = frame_to_world(frame, &model)?;
    if let Some(tool) = tool {
        // The residual model was learned at the reflector; near the flange it is the same
        // joint-driven error, the kinematics carry the new point exactly.
        model.robot.tool = super::tool_point(tool, "flange frame")?;
    }
    let file = targets;
    let mut targets = read_targets(file, model.robot.dof())?;
    model.check_targets(file, targets.iter().map(|t| &t.sample))?;
    for t in &mut targets {
        t.position = rotation * t.position + origin;
    }
    let options = CompensationOptions::default();
    let mut rows = Vec::with_capacity(targets.len());
    let mut failed = Vec::new();
    let mut commands: Vec<Sample> = Vec::new();
    let mut worst: f64 = 0.0;
    for t in &targets {
        // A row naming a reflector puts that point on its target.
        match compensate(
            &model.for_target(&t.sample.target),
            &t.position,
            t.sample.load,
            &t.sample.joints,
            &options,
        ) {
            Ok(mut c) => {
                worst = worst.max(c.model_error);
                // Joints that stand behind their commands after a move: commanded beyond by
                // the play, in the program's order.
                if let Some(m) = &model.motion {
                    c.joints_deg = m.command(&c.joints_deg, &t.sample.last_move);
                }
                commands.push(Sample {
                    joints: c.joints_deg.clone(),
                    ..t.sample.clone()
                });
                rows.push((t.sample.pose.clone(), c.joints_deg));
            }
            Err(why) => failed.push(format!("{} (line {}): {why}", t.sample.pose, t.sample.line)),
        }
    }
    // The commands are the readings the model is applied at: warn where they leave its domain.
    super::warn_outside(&model, file, &commands);
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
