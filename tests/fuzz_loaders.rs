//! Fuzzing the loaders (proptest): CSV-like text for the measurement, sample and target readers,
//! and mutated TOML for the robot, compliance, stage, twin and experiment loaders. Whatever the
//! text, a loader returns a value or an error that names the file; it never panics.
//!
//! `cargo test` runs a few hundred cases; `just fuzz` runs many more in release
//! (`PROPTEST_CASES`). A failing case found this way becomes a regression test below.

use std::path::Path;

use proptest::prelude::*;
use robocal_calibration::Stages;
use robocal_data::{MeasurementSet, SampleSet, read_targets};
use robocal_pipeline::Experiment;
use robocal_robot::{Compliance, Robot};
use robocal_twin::TwinConfig;

/// A CSV field: numbers of every kind, special values, text, quoted commas, empties.
fn field() -> impl Strategy<Value = String> {
    prop_oneof![
        (-1e4f64..1e4).prop_map(|v| v.to_string()),
        (0u32..30).prop_map(|v| v.to_string()),
        prop::sample::select(vec![
            "nan",
            "NaN",
            "inf",
            "-inf",
            "1e400",
            "-1e400",
            "",
            " ",
            "-5",
            "0",
            "1e-320",
            "+3",
            "0x10",
            "1,5",
            "\"1,5\"",
            "\"a\"\"b\"",
            "é",
            "\u{feff}1",
            "--",
            ".",
            "1e",
            "\"",
        ])
        .prop_map(String::from),
        "[a-z0-9_]{0,6}",
    ]
}

/// A header: the usual columns, shuffled, some missing, some twice, some unknown.
fn header() -> impl Strategy<Value = Vec<String>> {
    let names = vec![
        "pose", "id", "q1", "q2", "q3", "q4", "q5", "q6", "q7", "load", "x", "y", "z", "extra", "",
        "Q1", " x",
    ];
    prop::collection::vec(prop::sample::select(names), 0..14)
        .prop_map(|v| v.into_iter().map(String::from).collect())
}

fn csv_text() -> impl Strategy<Value = String> {
    prop_oneof![
        (
            header(),
            prop::collection::vec(prop::collection::vec(field(), 0..14), 0..6)
        )
            .prop_map(|(h, rows)| {
                let mut t = h.join(",");
                for r in rows {
                    t.push('\n');
                    t += &r.join(",");
                }
                t
            }),
        ".{0,200}",
    ]
}

const ROBOT: &str = include_str!("../configs/robots/pmc6va030.toml");
const TWIN: &str = include_str!("../configs/twin/arm5.toml");
const STAGE: &str = "[kinematic]\nsolver = \"lm\"\nmax_iterations = 50\n[compliance]\njoints = [2, 3]\npayload_com = [0.0, 0.0, 50.0]\n[residual]\nmodel = \"ca-somm\"\nseed = 3\n[residual.x]\nhidden = [4, 4]\nactivation = \"relu\"\nlearning_rate = 1e-3\n[residual.classifier]\ngate = \"soft\"\n";
const EXPERIMENT: &str = include_str!("../configs/experiments/table6.toml");
const COMPLIANCE: &str = "gravity = [0.0, 0.0, -9.80665]\npayload_com = [100.0, 0.0, 60.0]\ncompliance = [0.0, 0.07, 0.14, 0.38, 0.48, 0.57]\n";

/// One edit of a line-based text.
#[derive(Debug, Clone)]
enum Edit {
    Delete(usize),
    Duplicate(usize),
    Replace(usize, String),
    SetValue(usize, String),
    Truncate(usize),
}

fn edit() -> impl Strategy<Value = Edit> {
    let token = prop_oneof![
        field(),
        prop::sample::select(vec![
            "[1.0, 2.0]",
            "[]",
            "[0.0, 0.0]",
            "true",
            "\"x\"",
            "{}",
            "[[joint]]",
            "[base]",
            "nan",
            "1e400",
            "-1",
            "0",
            "[1, 2, 3, 4, 5, 6, 7]",
            "\"\u{0}\"",
        ])
        .prop_map(String::from),
    ];
    prop_oneof![
        (0usize..200).prop_map(Edit::Delete),
        (0usize..200).prop_map(Edit::Duplicate),
        (0usize..200, token.clone()).prop_map(|(i, t)| Edit::Replace(i, t)),
        (0usize..200, token).prop_map(|(i, t)| Edit::SetValue(i, t)),
        (0usize..5000).prop_map(Edit::Truncate),
    ]
}

/// `text` with `edits` applied, line by line.
fn mutate(text: &str, edits: &[Edit]) -> String {
    let mut lines: Vec<String> = text.lines().map(String::from).collect();
    for e in edits {
        let n = lines.len().max(1);
        match e {
            Edit::Delete(i) if !lines.is_empty() => {
                lines.remove(i % n);
            }
            Edit::Duplicate(i) if !lines.is_empty() => {
                let l = lines[i % n].clone();
                lines.insert(i % n, l);
            }
            Edit::Replace(i, t) if !lines.is_empty() => lines[i % n] = t.clone(),
            Edit::SetValue(i, t) if !lines.is_empty() => {
                let l = &mut lines[i % n];
                if let Some(eq) = l.find('=') {
                    *l = format!("{}= {t}", &l[..eq]);
                }
            }
            Edit::Truncate(at) => {
                let joined = lines.join("\n");
                let mut cut = (*at).min(joined.len());
                while !joined.is_char_boundary(cut) {
                    cut -= 1;
                }
                lines = joined[..cut].lines().map(String::from).collect();
            }
            _ => {}
        }
    }
    lines.join("\n")
}

/// Writes `text` to `name` in a fresh directory (the twin's relative `nominal` path resolves
/// against the configs folder copy made beside it).
fn file(dir: &Path, name: &str, text: &str) -> std::path::PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, text).unwrap();
    path
}

/// The error of a failed load names the file.
fn names_file<T, E: std::fmt::Display>(
    result: Result<T, E>,
    name: &str,
) -> Result<(), TestCaseError> {
    if let Err(e) = result {
        let text = e.to_string();
        prop_assert!(text.contains(name), "{text}");
    }
    Ok(())
}

proptest! {
    #[test]
    fn csv_loaders_never_panic(text in csv_text(), joints in 1usize..8) {
        let dir = tempfile::tempdir().unwrap();
        let path = file(dir.path(), "in.csv", &text);
        names_file(MeasurementSet::read(&path, joints), "in.csv")?;
        names_file(SampleSet::read(&path, joints), "in.csv")?;
        names_file(read_targets(&path, joints), "in.csv")?;
    }

    #[test]
    fn toml_loaders_never_panic(edits in prop::collection::vec(edit(), 1..6)) {
        let dir = tempfile::tempdir().unwrap();
        std::fs::create_dir_all(dir.path().join("robots")).unwrap();
        std::fs::create_dir_all(dir.path().join("twin")).unwrap();
        std::fs::write(dir.path().join("robots/arm5.toml"), include_str!("../configs/robots/arm5.toml")).unwrap();
        let robot = file(dir.path(), "robot.toml", &mutate(ROBOT, &edits));
        names_file(Robot::load(&robot), "robot.toml")?;
        let compliance = file(dir.path(), "compliance.toml", &mutate(COMPLIANCE, &edits));
        names_file(Compliance::load(&compliance, 6), "compliance.toml")?;
        let stage = file(dir.path(), "stage.toml", &mutate(STAGE, &edits));
        names_file(Stages::load(&stage), "stage.toml")?;
        let twin = file(&dir.path().join("twin"), "twin.toml", &mutate(TWIN, &edits));
        // A valid twin also designs its poses; only the loader is under test.
        names_file(TwinConfig::load(&twin), "twin")?;
        let experiment = file(dir.path(), "experiment.toml", &mutate(EXPERIMENT, &edits));
        names_file(Experiment::load(&experiment), "experiment.toml")?;
    }
}
