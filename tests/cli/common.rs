//! Helpers shared by the end-to-end tests of the binary.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// Runs the `robocal` binary in the repository root.
pub fn robocal(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_robocal"))
        .args(args)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .expect("the binary runs")
}

/// Writes `text` to `dir/name` (creating folders) and returns the path.
pub fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let path = dir.join(name);
    if let Some(parent) = path.parent() {
        std::fs::create_dir_all(parent).unwrap();
    }
    std::fs::write(&path, text).unwrap();
    path
}

pub fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// The rows of a measurement file's text whose configuration (counted from 0 in order of
/// appearance) and load `keep` accepts, with the header.
pub fn select_rows(text: &str, keep: impl Fn(usize, f64) -> bool) -> String {
    let mut lines = text.lines();
    let header = lines.next().unwrap();
    let load_col = header.split(',').position(|c| c == "load").unwrap();
    let mut out = format!("{header}\n");
    let mut poses: Vec<&str> = Vec::new();
    for line in lines {
        let pose = line.split(',').next().unwrap();
        if !poses.contains(&pose) {
            poses.push(pose);
        }
        let load: f64 = line.split(',').nth(load_col).unwrap().parse().unwrap();
        if keep(poses.len() - 1, load) {
            out += line;
            out += "\n";
        }
    }
    out
}

/// The bundled twin measurements, as text.
pub fn twin_rows() -> String {
    std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("datasets/pmc6va030/measurements.csv"),
    )
    .unwrap()
}

/// A model directory's `report.json`.
pub fn report(model: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(model.join("report.json")).unwrap()).unwrap()
}

/// `calibrate` of the bundled robot file on `data` into `model` with the stage file `stage`.
pub fn calibrate_with(data: &Path, model: &Path, stage: &Path) -> Output {
    robocal(&[
        "calibrate",
        "--robot",
        "configs/robots/pmc6va030.toml",
        "--data",
        s(data),
        "--out",
        s(model),
        "--config",
        s(stage),
    ])
}
