//! The real arms' datasets bundled in `datasets/` (converted by `scripts/datasets/convert.py`):
//! each file reads as robocal's measurement format, the maker's nominal table reproduces the
//! source's targets from the converted joints to the source's rounding, and the conversion run
//! again on the source files gives the bundled files byte for byte.

use std::path::{Path, PathBuf};
use std::process::Command;

use robocal_data::MeasurementSet;
use robocal_robot::Robot;

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// The rows' source targets (`x_t, y_t, z_t`, mm) in file order.
fn targets(path: &Path) -> Vec<[f64; 3]> {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let col = |name: &str| header.iter().position(|c| *c == name).unwrap();
    let (x, y, z) = (col("x_t"), col("y_t"), col("z_t"));
    lines
        .map(|l| {
            let f: Vec<&str> = l.split(',').collect();
            [x, y, z].map(|c| f[c].parse::<f64>().unwrap())
        })
        .collect()
}

/// RMS and largest distance (mm) between the nominal table's point at each row's joints and the
/// source's target of that row.
fn nominal_against_targets(arm: &str, file: &str) -> (f64, f64, usize) {
    let dir = root().join("datasets").join(arm);
    let robot = Robot::load(dir.join("robot.toml")).unwrap();
    let set = MeasurementSet::read(dir.join(file), robot.dof()).unwrap();
    let targets = targets(&dir.join(file));
    assert_eq!(set.rows.len(), targets.len());
    let d: Vec<f64> = (set.rows.iter().zip(&targets))
        .map(|(m, t)| {
            let p = robot.point(&m.sample.joints_rad());
            ((p.x - t[0]).powi(2) + (p.y - t[1]).powi(2) + (p.z - t[2]).powi(2)).sqrt()
        })
        .collect();
    let rms = (d.iter().map(|v| v * v).sum::<f64>() / d.len() as f64).sqrt();
    (rms, d.iter().cloned().fold(0.0, f64::max), d.len())
}

#[test]
fn the_ur5_nominal_table_reproduces_the_source_targets() {
    // The source's targets were computed with UR's table; the 13 µm left are its rounding of the
    // published lengths and of the tool point (a link 0.01 mm off moves the point about that).
    let (rms, max, n) = nominal_against_targets("ur5", "grid.csv");
    assert_eq!(n, 1000);
    assert!(
        rms < 0.02 && max < 0.05,
        "UR5 grid: rms {rms} mm, max {max} mm"
    );
    let (rms, max, n) = nominal_against_targets("ur5", "random.csv");
    assert_eq!(n, 20);
    assert!(
        rms < 0.02 && max < 0.05,
        "UR5 random: rms {rms} mm, max {max} mm"
    );
}

#[test]
fn the_wam_nominal_table_reproduces_the_source_targets() {
    let (rms, max, n) = nominal_against_targets("wam", "grid.csv");
    assert_eq!(n, 216);
    assert!(
        rms < 0.001 && max < 0.005,
        "WAM grid: rms {rms} mm, max {max} mm"
    );
    let (rms, max, n) = nominal_against_targets("wam", "random.csv");
    assert_eq!(n, 20);
    assert!(
        rms < 0.001 && max < 0.005,
        "WAM random: rms {rms} mm, max {max} mm"
    );
}

#[test]
fn a_measured_point_is_the_target_plus_the_source_difference() {
    // The source's first grid row of the UR5: target (-430.32784075885013, -6.2740647628546,
    // -98.6368469428076), dif (-2.144122241149887, -3.5212622371454003, 0.8144149428075877).
    let set = MeasurementSet::read(root().join("datasets/ur5/grid.csv"), 6).unwrap();
    let p = set.rows[0].position;
    let want = [
        -430.32784075885013 + -2.144122241149887,
        -6.2740647628546 + -3.5212622371454003,
        -98.6368469428076 + 0.8144149428075877,
    ];
    for k in 0..3 {
        assert!(
            (p[k] - want[k]).abs() < 1e-9,
            "axis {k}: {} against {}",
            p[k],
            want[k]
        );
    }
    assert_eq!(set.rows[0].sample.pose, "g0000");
}

/// The conversion, run on the source files where this machine has them (`../shared/data`
/// beside the repository, as on the development machines and CI), writes the bundled files
/// byte for byte.
#[test]
fn the_conversion_gives_the_bundled_files() {
    let source = root().join("../shared/data");
    if !source.join("serial_robots_datasets").is_dir() {
        eprintln!(
            "no source files at {}: conversion not rerun",
            source.display()
        );
        return;
    }
    let out = tempfile::tempdir().unwrap();
    let status = Command::new("python3")
        .arg(root().join("scripts/datasets/convert.py"))
        .arg(&source)
        .arg("--out")
        .arg(out.path())
        .output()
        .expect("python3 runs");
    assert!(
        status.status.success(),
        "{}",
        String::from_utf8_lossy(&status.stderr)
    );
    for arm in ["ur5", "wam"] {
        for file in ["robot.toml", "grid.csv", "random.csv", "targets.csv"] {
            let made = std::fs::read(out.path().join(arm).join(file)).unwrap();
            let bundled = std::fs::read(root().join("datasets").join(arm).join(file)).unwrap();
            assert!(
                made == bundled,
                "datasets/{arm}/{file} differs from the conversion"
            );
        }
    }
}
