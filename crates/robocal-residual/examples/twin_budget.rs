//! The twin's error budget and the shape of its residual (`just twin-budget [TWIN]`): generates
//! the twin's data in memory, calibrates the kinematics by LM on the unloaded rows, and prints
//! the before/after figures beside the paper's, the error against load, and how bimodal each
//! world axis of the residual is (section V-B2, Fig. 22 of the paper).
//!
//! Bimodality is judged by splitting each axis's residual into two groups with a one-dimensional
//! two-means and computing Ashman's D = √2 |μ₁ − μ₂| / √(σ₁² + σ₂²) (D > 2: two clearly
//! separated modes) and Sarle's coefficient b = (skew² + 1) / kurtosis (b > 5/9 hints at two
//! modes). Twin numbers, not a real robot's.

use robocal_data::ErrorStats;
use robocal_ident::{KinematicSettings, Observations, calibrate_kinematics};
use robocal_residual::two_means_threshold;
use robocal_twin::{BacklashSide, TwinConfig};

/// A text histogram over mean ± 3 std, 24 bins.
fn histogram(v: &[f64]) {
    let (m, s) = mean_std(v);
    let (lo, width) = (m - 3.0 * s, 6.0 * s / 24.0);
    let mut counts = [0usize; 24];
    for x in v {
        let k = ((x - lo) / width).floor();
        if (0.0..24.0).contains(&k) {
            counts[k as usize] += 1;
        }
    }
    let top = counts.iter().copied().max().unwrap_or(1).max(1);
    for (k, c) in counts.iter().enumerate() {
        println!(
            "    {:+.2} {}",
            lo + (k as f64 + 0.5) * width,
            "#".repeat(c * 50 / top)
        );
    }
}

fn mean_std(v: &[f64]) -> (f64, f64) {
    let n = v.len() as f64;
    let m = v.iter().sum::<f64>() / n;
    let s = (v.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (n - 1.0)).sqrt();
    (m, s)
}

/// How bimodal each world axis of the residual is, over the rows marked in `keep`.
fn shape(label: &str, residual: &[[f64; 3]], side: &[bool], keep: &[bool]) {
    let residual: Vec<[f64; 3]> = residual
        .iter()
        .zip(keep)
        .filter(|(_, k)| **k)
        .map(|(e, _)| *e)
        .collect();
    let side: Vec<bool> = side
        .iter()
        .zip(keep)
        .filter(|(_, k)| **k)
        .map(|(s, _)| *s)
        .collect();
    println!(
        "residual after calibration, {label}, {} rows (mm):",
        residual.len()
    );
    for (axis, name) in ["X", "Y", "Z"].iter().enumerate() {
        let v: Vec<f64> = residual.iter().map(|e| e[axis]).collect();
        if axis == 0 {
            histogram(&v);
        }
        let (m, s) = mean_std(&v);
        let t = two_means_threshold(&v).unwrap_or(m);
        let (lo, hi): (Vec<f64>, Vec<f64>) = v.iter().partition(|&&x| x < t);
        let ((m1, s1), (m2, s2)) = (mean_std(&lo), mean_std(&hi));
        let d = std::f64::consts::SQRT_2 * (m2 - m1).abs() / (s1 * s1 + s2 * s2).sqrt();
        let nf = v.len() as f64;
        let skew = v.iter().map(|x| ((x - m) / s).powi(3)).sum::<f64>() / nf;
        let kurt = v.iter().map(|x| ((x - m) / s).powi(4)).sum::<f64>() / nf;
        let b = (skew * skew + 1.0) / kurt;
        let agree = v
            .iter()
            .zip(&side)
            .filter(|&(&x, &s)| (x >= t) == s)
            .count() as f64
            / nf;
        let class_mean = |want: bool| {
            let g: Vec<f64> = v
                .iter()
                .zip(&side)
                .filter(|(_, s)| **s == want)
                .map(|(x, _)| *x)
                .collect();
            g.iter().sum::<f64>() / g.len().max(1) as f64
        };
        let (mp, mn) = (class_mean(true), class_mean(false));
        println!(
            "  {name}: mean {m:+.3} std {s:.3} | two-means at {t:+.3}: {:.3}±{:.3} ({}) / {:.3}±{:.3} ({}), Ashman D {d:.2}, Sarle b {b:.2} | side +: {mp:+.3}, side −: {mn:+.3}, groups match side {:.0} %",
            m1,
            s1,
            lo.len(),
            m2,
            s2,
            hi.len(),
            100.0 * agree.max(1.0 - agree)
        );
    }
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let path = std::env::args()
        .nth(1)
        .unwrap_or_else(|| "configs/twin/pmc6va030.toml".into());
    let twin = TwinConfig::load(&path)?;
    let nominal = twin.nominal.clone();
    let data = twin.generate()?.measurements;
    let n = twin.truth.dof();
    println!("{path} (seed {}): twin data, not a real robot's", twin.seed);
    let unloaded = Observations::from_rows(n, data.rows.iter().filter(|r| r.sample.load == 0.0));
    let cal = calibrate_kinematics(&nominal, &unloaded, &KinematicSettings::default())?;
    let r = &cal.report;
    println!(
        "unloaded, {} poses: before mean {:.3} max {:.3} (paper 3.704 / 7.909); after mean {:.3} std {:.3} max {:.3} (paper 0.383 / 0.161 / 0.556)",
        r.points, r.before.mean, r.before.max, r.after.mean, r.after.std, r.after.max
    );
    let loads = data.loads();
    let by_load: Vec<String> = loads
        .iter()
        .map(|&load| {
            let obs =
                Observations::from_rows(n, data.rows.iter().filter(|r| r.sample.load == load));
            format!(
                "{load}:{:.3}",
                ErrorStats::from_errors(&obs.errors(&cal.robot)).mean
            )
        })
        .collect();
    println!(
        "mean after calibration by load (kg:mm; paper ~0.94 at 20 kg): {}",
        by_load.join(" ")
    );

    let residual: Vec<[f64; 3]> = data
        .rows
        .iter()
        .map(|m| {
            let q: Vec<f64> = m.sample.joints.iter().map(|d| d.to_radians()).collect();
            let e = m.position - cal.robot.point(&q);
            [e.x, e.y, e.z]
        })
        .collect();
    // The side of the backlash whose flank the torque sets (the bimodal one), else the first.
    let switching = twin
        .backlash
        .iter()
        .find(|b| matches!(b.side, BacklashSide::Torque { .. }))
        .or(twin.backlash.first());
    let side: Vec<bool> = data
        .rows
        .iter()
        .map(|m| {
            let q: Vec<f64> = m.sample.joints.iter().map(|d| d.to_radians()).collect();
            switching.is_none_or(|b| twin.backlash_offset(&q, m.sample.load)[b.joint] >= 0.0)
        })
        .collect();
    if let Some(b) = switching {
        // That backlash's own displacement, before any calibration absorbs part of it.
        let untwisted = TwinConfig {
            backlash: twin
                .backlash
                .iter()
                .filter(|o| o.joint != b.joint)
                .copied()
                .collect(),
            ..twin.clone()
        };
        let raw: Vec<[f64; 3]> = data
            .rows
            .iter()
            .map(|m| {
                let q: Vec<f64> = m.sample.joints.iter().map(|d| d.to_radians()).collect();
                let e =
                    twin.true_point(&q, m.sample.load) - untwisted.true_point(&q, m.sample.load);
                [e.x, e.y, e.z]
            })
            .collect();
        shape(
            "backlash displacement alone",
            &raw,
            &side,
            &vec![true; raw.len()],
        );
    }
    let flipped: Vec<String> = loads
        .iter()
        .map(|&load| {
            let rows: Vec<bool> = data
                .rows
                .iter()
                .zip(&side)
                .filter(|(m, _)| m.sample.load == load)
                .map(|(_, s)| *s)
                .collect();
            format!(
                "{load}:{:.0}",
                100.0 * rows.iter().filter(|s| !**s).count() as f64 / rows.len() as f64
            )
        })
        .collect();
    println!(
        "rows on the negative side by load (kg:%): {}",
        flipped.join(" ")
    );
    let unloaded_rows: Vec<bool> = data.rows.iter().map(|m| m.sample.load == 0.0).collect();
    shape("unloaded rows", &residual, &side, &unloaded_rows);
    shape("all rows", &residual, &side, &vec![true; residual.len()]);
    Ok(())
}
