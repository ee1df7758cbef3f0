//! `robocal report` and `calibrate --report`: the pictures of a calibration on the user's own
//! rows, their statistics against an independent computation, bad input writing nothing.

use std::collections::BTreeMap;
use std::path::Path;

use crate::common::{calibrate_with, robocal, s, select_rows, twin_rows, write};

/// The figures of every report, and of a model that gives standard deviations (this physical
/// model's, from its parameters' covariance).
const STEMS: [&str; 6] = [
    "histogram",
    "per-pose",
    "axes-joints",
    "load",
    "workspace",
    "sigma",
];

fn json(path: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

/// Every figure as PNG and SVG, the texts, the SVGs inline in the page and nothing it loads.
fn assert_complete(dir: &Path) {
    for stem in STEMS {
        for ext in ["png", "svg"] {
            let f = dir.join(format!("{stem}.{ext}"));
            assert!(
                std::fs::metadata(&f).unwrap().len() > 1000,
                "{}",
                f.display()
            );
        }
    }
    let md = std::fs::read_to_string(dir.join("report.md")).unwrap();
    for stem in STEMS {
        assert!(md.contains(&format!("({stem}.png)")), "{md}");
    }
    let html = std::fs::read_to_string(dir.join("report.html")).unwrap();
    assert_eq!(html.matches("<svg").count(), STEMS.len());
    assert!(!html.contains("src=") && !html.contains("<?xml"));
    assert!(html.trim_end().ends_with("</html>"));
}

#[test]
fn report_draws_a_calibration_on_held_out_rows_and_its_numbers_match_evaluate() {
    let dir = tempfile::tempdir().unwrap();
    let rows = twin_rows();
    let train = write(
        dir.path(),
        "train.csv",
        &select_rows(&rows, |c, l| c < 120 && l <= 10.0),
    );
    let test = write(
        dir.path(),
        "test.csv",
        &select_rows(&rows, |c, l| c >= 120 && l <= 10.0),
    );
    let model = dir.path().join("model");
    let fit = dir.path().join("fit-report");
    let o = robocal(&[
        "calibrate",
        "--robot",
        "configs/robots/pmc6va030.toml",
        "--data",
        s(&train),
        "--out",
        s(&model),
        "--config",
        "configs/stages/compliance.toml",
        "--report",
        s(&fit),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(model.join("nominal.toml").exists());
    assert_complete(&fit);
    assert_eq!(json(&fit.join("statistics.json"))["role"], "training");

    let out = dir.path().join("reports/held-out");
    let o = robocal(&[
        "report",
        "--model",
        s(&model),
        "--data",
        s(&test),
        "--out",
        s(&out),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert_complete(&out);
    let stats = json(&out.join("statistics.json"));
    assert_eq!(stats["role"], "held-out");

    // The same errors through `evaluate`, and per load by hand from its per-row file.
    let per_pose = dir.path().join("errors.csv");
    let o = robocal(&[
        "evaluate",
        "--model",
        s(&model),
        "--data",
        s(&test),
        "--json",
        "--per-pose",
        s(&per_pose),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let evaluated: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    for key in ["count", "mean", "max", "rms"] {
        let (a, b) = (&stats["after"][key], &evaluated[key]);
        assert!(
            (a.as_f64().unwrap() - b.as_f64().unwrap()).abs() < 1e-9,
            "{key}: {a} vs {b}"
        );
    }
    let mut by_load: BTreeMap<String, (f64, usize)> = BTreeMap::new();
    for line in std::fs::read_to_string(&per_pose).unwrap().lines().skip(1) {
        let f: Vec<&str> = line.split(',').collect();
        let e = by_load.entry(f[2].to_string()).or_default();
        e.0 += f[6].parse::<f64>().unwrap();
        e.1 += 1;
    }
    let reported = stats["by_load"].as_array().unwrap();
    assert_eq!(reported.len(), by_load.len());
    for l in reported {
        let load = l["load"].as_f64().unwrap();
        let (sum, n) = by_load
            .iter()
            .find(|(k, _)| k.parse::<f64>().unwrap() == load)
            .map(|(_, v)| *v)
            .unwrap();
        assert_eq!(l["rows"].as_u64().unwrap() as usize, n);
        assert!((l["after"].as_f64().unwrap() - sum / n as f64).abs() < 1e-5);
    }
    // The σ check, by hand from `predict --sigma` and the measured points (6 decimals).
    let predicted = dir.path().join("predicted.csv");
    let o = robocal(&[
        "predict",
        "--model",
        s(&model),
        "--data",
        s(&test),
        "--out",
        s(&predicted),
        "--sigma",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let measured: Vec<[f64; 3]> = (std::fs::read_to_string(&test).unwrap().lines().skip(1))
        .map(|l| {
            let f: Vec<f64> = l.split(',').skip(8).map(|v| v.parse().unwrap()).collect();
            [f[0], f[1], f[2]]
        })
        .collect();
    let pairs: Vec<(f64, f64)> = (std::fs::read_to_string(&predicted).unwrap().lines().skip(1))
        .zip(&measured)
        .map(|(l, m)| {
            let f: Vec<f64> = l.split(',').skip(2).map(|v| v.parse().unwrap()).collect();
            let e = ((0..3).map(|k| (m[k] - f[k]).powi(2)).sum::<f64>()).sqrt();
            (e, f[3])
        })
        .collect();
    let n = pairs.len() as f64;
    let check = &stats["sigma"];
    let ratio = (pairs.iter().map(|(e, s)| (e / s).powi(2)).sum::<f64>() / n).sqrt();
    let within = |k: f64| pairs.iter().filter(|(e, s)| *e <= k * s).count() as f64 / n;
    let mean_sigma = pairs.iter().map(|p| p.1).sum::<f64>() / n;
    let got = |key: &str| check[key].as_f64().unwrap();
    assert!(
        (got("ratio_rms") / ratio - 1.0).abs() < 1e-3,
        "{check} vs {ratio}"
    );
    assert!((got("mean_sigma") - mean_sigma).abs() < 1e-5, "{check}");
    // A row within a micrometre of a boundary may fall either side after rounding.
    for (key, k) in [("within_one", 1.0), ("within_two", 2.0)] {
        assert!((got(key) - within(k)).abs() <= 2.0 / n, "{key}: {check}");
    }
    assert!((-1.0..=1.0).contains(&got("rank_correlation")), "{check}");
    let md = std::fs::read_to_string(out.join("report.md")).unwrap();
    assert!(md.contains("## How sure the model is"), "{md}");
    // Before is the registered nominal table: millimetres, against a fraction of one after.
    let (before, after) = (
        stats["before"]["mean"].as_f64().unwrap(),
        stats["after"]["mean"].as_f64().unwrap(),
    );
    assert!(before > 2.0 && after < 0.6 * before, "{before} {after}");
}

#[test]
fn a_bad_report_writes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("report");
    // No model there.
    let o = robocal(&[
        "report",
        "--model",
        s(&dir.path().join("none")),
        "--data",
        "datasets/pmc6va030/measurements.csv",
        "--out",
        s(&out),
    ]);
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("none: model directory not found"), "{err}");
    assert!(!out.exists());
    // A model, and data with a bad value: named by file, line and column.
    let model = dir.path().join("model");
    let train = write(
        dir.path(),
        "train.csv",
        &select_rows(&twin_rows(), |c, l| c < 60 && l == 0.0),
    );
    let o = calibrate_with(
        &train,
        &model,
        Path::new("configs/stages/kinematic-lm.toml"),
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let text = std::fs::read_to_string(&train).unwrap();
    let bad = text.replacen(",0,", ",zero,", 1);
    let bad = write(dir.path(), "bad.csv", &bad);
    let o = robocal(&[
        "report",
        "--model",
        s(&model),
        "--data",
        s(&bad),
        "--out",
        s(&out),
    ]);
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("bad.csv") && err.contains("line 2"), "{err}");
    assert!(!out.exists());
}
