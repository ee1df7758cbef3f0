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

/// The bundled twin's file made runnable from a temporary directory: `count` configurations,
/// trained at 0 and 20 kg only, `[truth.tool]` followed by `truth_tool` (more keys or tables:
/// named points, a probe's `rpy`).
pub fn bundled_twin(count: usize, truth_tool: &str) -> String {
    let root = env!("CARGO_MANIFEST_DIR");
    let text = std::fs::read_to_string(Path::new(root).join("configs/twin/pmc6va030.toml"))
        .unwrap()
        .replace(
            "nominal = \"../robots/pmc6va030.toml\"",
            &format!("nominal = \"{root}/configs/robots/pmc6va030.toml\""),
        )
        .replace("count = 168", &format!("count = {count}"))
        .replace(
            "[truth.tool]\nxyz = [2.14, -1.37, 98.26]\n",
            &format!("[truth.tool]\nxyz = [2.14, -1.37, 98.26]\n{truth_tool}"),
        );
    let start = text.find("trained = [").unwrap();
    let end = start + text[start..].find("\nuntrained").unwrap();
    let end = end + 1 + text[end + 1..].find('\n').unwrap();
    format!(
        "{}trained = [0.0, 20.0]\nuntrained = []{}",
        &text[..start],
        &text[end..]
    )
}
