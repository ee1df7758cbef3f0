//! `robocal import`: the nominal tables of `configs/robots/` are their makers' DH tables
//! imported, and a refused chain writes nothing.

use std::path::Path;

use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use robocal_model::import::{Convention, read_dh, robot_from_dh};
use robocal_robot::Robot;

use crate::common::{robocal, s, write};

/// Each table made from a maker's published DH table names its source and moves as the DH
/// table imported again, through the command line, to 1e-9 mm.
#[test]
fn the_shipped_tables_are_their_makers_dh_tables() {
    let dir = tempfile::tempdir().unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(9);
    for (arm, convention) in [
        ("ur3", "standard"),
        ("ur5", "standard"),
        ("ur10", "standard"),
        ("ur3e", "standard"),
        ("ur5e", "standard"),
        ("ur10e", "standard"),
        ("wam", "standard"),
        ("panda", "modified"),
    ] {
        let shipped = format!("configs/robots/{arm}.toml");
        let text = std::fs::read_to_string(&shipped).unwrap();
        assert!(
            text.starts_with("# ") && text.contains("Source:"),
            "{shipped} names no source"
        );
        let robot = Robot::load(&shipped).unwrap();
        let csv = format!("configs/robots/dh/{arm}.csv");
        let out = dir.path().join(format!("{arm}.toml"));
        let mut args = vec![
            "import",
            "--dh",
            &csv,
            "--convention",
            convention,
            "--out",
            s(&out),
        ];
        if arm == "panda" {
            args.extend(["--tool", "0,0,107"]);
        }
        let o = robocal(&args);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let again = Robot::load(&out).unwrap();
        let rows = read_dh(Path::new(&csv)).unwrap();
        let kind = if convention == "standard" {
            Convention::Standard
        } else {
            Convention::Modified
        };
        // The Panda's measured point is its flange, 107 mm along the last axis.
        let tool = if arm == "panda" {
            nalgebra::Vector3::new(0.0, 0.0, 107.0)
        } else {
            Default::default()
        };
        let direct = robot_from_dh(arm, &rows, kind, tool);
        for _ in 0..50 {
            let q: Vec<f64> = (0..robot.dof())
                .map(|_| rng.random_range(-3.0..3.0))
                .collect();
            for other in [&again, &direct] {
                let e = (robot.point(&q) - other.point(&q)).norm();
                assert!(e < 1e-9, "{arm}: {e} mm");
            }
        }
    }
}

/// A URDF with a prismatic joint on the chain, and a DH table with a bad cell: a non-zero exit,
/// the file, the joint or the line and column named, nothing written.
#[test]
fn a_refused_import_names_the_fault_and_writes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let urdf = write(
        dir.path(),
        "slide.urdf",
        r#"<robot name="slide"><link name="a"/><link name="b"/><link name="c"/>
<joint name="turn" type="continuous"><parent link="a"/><child link="b"/><axis xyz="0 0 1"/></joint>
<joint name="rail" type="prismatic"><parent link="b"/><child link="c"/><axis xyz="1 0 0"/>
<limit lower="0" upper="1" effort="1" velocity="1"/></joint></robot>"#,
    );
    let out = dir.path().join("robot.toml");
    let o = robocal(&["import", "--urdf", s(&urdf), "--out", s(&out)]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success());
    assert!(
        err.contains("slide.urdf") && err.contains("`rail`") && err.contains("prismatic"),
        "{err}"
    );
    assert!(!out.exists());
    let dh = write(
        dir.path(),
        "dh.csv",
        "d,a,alpha,theta\n100,0,90,0\n0,x,0,0\n",
    );
    let o = robocal(&[
        "import",
        "--dh",
        s(&dh),
        "--convention",
        "standard",
        "--out",
        s(&out),
    ]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success());
    assert!(err.contains("dh.csv: line 3, column `a`: `x`"), "{err}");
    assert!(!out.exists());
    let o = robocal(&["import", "--dh", s(&dh), "--out", s(&out)]);
    assert!(!o.status.success(), "a DH table needs its convention");
}
