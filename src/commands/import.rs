//! `robocal import`.

use std::path::Path;

use anyhow::{Result, anyhow};
use robocal_data::write_atomically;
use robocal_model::import::{Convention, read_dh, robot_from_dh, robot_from_urdf_file};
use robocal_robot::Robot;

use crate::cli::DhConvention;

/// Writes the robot file of a URDF's chain (or of a DH table and its convention) to `out`,
/// after reading it back.
pub fn run(
    urdf: Option<&Path>,
    dh: Option<(&Path, DhConvention)>,
    base: Option<&str>,
    tip: Option<&str>,
    tool: Option<&str>,
    out: &Path,
) -> Result<()> {
    let robot = match (urdf, dh) {
        (Some(path), _) => {
            let tool = tool
                .map(|t| super::tool_point(t, "the tip link's frame"))
                .transpose()?;
            robot_from_urdf_file(path, base, tip, tool)
                .map_err(|e| anyhow!("{e}; nothing written"))?
        }
        (None, Some((path, convention))) => {
            let tool = tool
                .map(|t| super::tool_point(t, "the last DH frame"))
                .transpose()?
                .unwrap_or_default();
            let rows = read_dh(path).map_err(|e| anyhow!("{e}; nothing written"))?;
            let name = path
                .file_stem()
                .map_or("robot".into(), |s| s.to_string_lossy());
            let convention = match convention {
                DhConvention::Standard => Convention::Standard,
                DhConvention::Modified => Convention::Modified,
            };
            robot_from_dh(&name, &rows, convention, tool)
        }
        (None, None) => return Err(anyhow!("give --urdf FILE or --dh FILE --convention ...")),
    };
    let text = robot.to_toml_string();
    // What is written must read back as a robot file.
    Robot::from_toml_str(&text, out)
        .map_err(|e| anyhow!("{}: the table does not read back: {e}", out.display()))?;
    super::ensure_parent(out)?;
    let said = super::replacing(out);
    write_atomically(out, |w| w.write_all(text.as_bytes()))?;
    said();
    let betas = (robot.joints.iter().enumerate())
        .filter(|(_, j)| j.beta.is_some())
        .map(|(i, _)| format!("j{}", i + 1))
        .collect::<Vec<_>>();
    eprintln!(
        "robocal: {} joints written to {}{}",
        robot.dof(),
        out.display(),
        if betas.is_empty() {
            String::new()
        } else {
            format!(
                " (a Hayati β on {}: its axis parallel, or nearly, to the one before)",
                betas.join(", ")
            )
        }
    );
    Ok(())
}
