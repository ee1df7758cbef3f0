//! `robocal plan`.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use robocal_data::{SampleSet, fixed6, write_atomically};
use robocal_plan::{PlanResult, PlanSettings, candidates_from_limits, plan};
use robocal_robot::Robot;

use super::terminal::Terminal;

/// Streams of the seed: candidates, check poses.
const CANDIDATES: u64 = 1;
const CHECKS: u64 = 2;

/// Plans `counts` configurations and writes the largest set to `out`, `plan.json` beside it.
pub fn run(
    robot_file: &Path,
    counts: &[usize],
    out: &Path,
    config: Option<&Path>,
    candidates: Option<&Path>,
) -> Result<()> {
    let robot = Robot::load(robot_file)?;
    let settings = match config {
        Some(path) => PlanSettings::load(path)?,
        None => PlanSettings::default(),
    };
    let terminal = Terminal::default();
    let limited = robot.joints.iter().all(|j| j.limits.is_some());
    let (pool, source) = match candidates {
        Some(path) => {
            let set = SampleSet::read(path, robot.dof())?;
            let mut seen = std::collections::HashSet::new();
            let pool: Vec<Vec<f64>> = (set.rows.iter())
                .filter(|s| seen.insert(s.pose.clone()))
                .map(|s| s.joints_rad())
                .collect();
            (
                pool,
                format!("{} ({} configurations)", path.display(), seen.len()),
            )
        }
        None => (
            candidates_from_limits(
                &robot,
                robot_file,
                &settings,
                settings.pool,
                CANDIDATES,
                &terminal,
            )?,
            format!(
                "{} random configurations within the joint limits of {}",
                settings.pool,
                robot_file.display()
            ),
        ),
    };
    let checks = if limited {
        candidates_from_limits(
            &robot,
            robot_file,
            &settings,
            settings.check,
            CHECKS,
            &terminal,
        )?
    } else {
        // A candidate file for a robot without limits: check on every candidate.
        pool.clone()
    };
    let result = plan(&robot, pool, source, &checks, counts, &settings, &terminal)?;
    let Some(largest) = result.plans.last() else {
        anyhow::bail!("--count: give one or more counts");
    };
    super::ensure_parent(out)?;
    let said = super::replacing(out);
    write_atomically(out, |w| {
        w.write_all(poses_csv(&robot, &result, &largest.chosen, &settings.loads).as_bytes())
    })?;
    said();
    let json = plan_json_path(out);
    let text = serde_json::to_string_pretty(&result).context("plan.json")? + "\n";
    write_atomically(&json, |w| w.write_all(text.as_bytes()))?;
    super::print_out(&summary(&result, &settings))?;
    eprintln!(
        "robocal: wrote {} configurations × {} loads to {} and the plan to {}",
        largest.count,
        settings.loads.len(),
        out.display(),
        json.display()
    );
    Ok(())
}

/// `plan.json` in the pose file's directory.
fn plan_json_path(out: &Path) -> PathBuf {
    out.with_file_name("plan.json")
}

/// The pose file: `pose,q1..qN,load`, every chosen configuration at every load.
fn poses_csv(robot: &Robot, result: &PlanResult, chosen: &[usize], loads: &[f64]) -> String {
    let n = robot.dof();
    let mut s = String::from("pose");
    for j in 1..=n {
        let _ = write!(s, ",q{j}");
    }
    s.push_str(",load\n");
    for (k, &c) in chosen.iter().enumerate() {
        for &load in loads {
            let _ = write!(s, "plan{:03}", k + 1);
            for v in &result.candidates[c] {
                let _ = write!(s, ",{}", fixed6(*v));
            }
            let _ = writeln!(s, ",{}", fixed6(load));
        }
    }
    s
}

/// What the plan buys, as printed.
fn summary(result: &PlanResult, settings: &PlanSettings) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "candidates: {}; {} check poses; loads {:?} kg; tracker noise {} mm per coordinate",
        result.candidate_source, result.check_count, result.loads, settings.noise_mm
    );
    let _ = writeln!(
        s,
        "{} parameters identified{}",
        result.parameters.len(),
        if result.fixed.is_empty() {
            String::new()
        } else {
            format!(
                "; held fixed (not identifiable): {}",
                result.fixed.join(", ")
            )
        }
    );
    let _ = writeln!(
        s,
        "\n| K | predicted error mean / max (mm) | random sets (median) | O1 | O1 random | O3 | O3 random | O4 | O4 random | exchanges |"
    );
    let _ = writeln!(s, "|---|---|---|---|---|---|---|---|---|---|");
    for p in &result.plans {
        let _ = writeln!(
            s,
            "| {} | {:.4} / {:.4} | {:.4} / {:.4} | {:.4} | {:.4} | {:.4} | {:.4} | {:.3e} | {:.3e} | {} |",
            p.count,
            p.predicted[0],
            p.predicted[1],
            p.predicted_random[0],
            p.predicted_random[1],
            p.planned.o1,
            p.random.o1,
            p.planned.o3,
            p.random.o3,
            p.planned.o4,
            p.random.o4,
            p.exchanges
        );
    }
    if let Some(p) = result.plans.last() {
        let _ = writeln!(
            s,
            "\nPredicted standard deviations with the {} planned configurations (random sets: median):\n\n| parameter | unit | planned | random |\n|---|---|---|---|",
            p.count
        );
        for q in &p.parameters {
            let _ = writeln!(
                s,
                "| {} | {} | {:.4} | {:.4} |",
                q.name, q.unit, q.planned, q.random
            );
        }
    }
    s
}
