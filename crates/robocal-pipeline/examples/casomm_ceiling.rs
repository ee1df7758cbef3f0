//! How far CA-SOMM can go on the bundled twin (`just casomm-ceiling`): the paper's Table 6
//! experiment, then what an oracle that knows the twin's joint-4 flank would give.
//!
//! The twin's X error is bimodal because joint 4 rests on one flank of its backlash or the
//! other, as the sign of its gravity torque says; the jump that the flank makes at the
//! reflector has an X component whose size and sign follow the pose. Printed: how often the
//! classes CA-SOMM learns (the two-means threshold of the X error, or the two modes) agree
//! with the flank and with the sign of the jump's X component, and the Table 6 error of
//! CA-SOMMs whose classes and gate are those oracles (the twin's truth: the best any
//! classifier could do), beside SOMM and CA-SOMM; then how often robocal's CA-SOMM gate (the
//! paper experiment's "BFGS + CA-SOMM (robocal)") routes a Table 6 row by the flank and by the
//! sign of the jump. Twin numbers, not a real robot's.
//!
//! ```sh
//! cargo run --release -p robocal-pipeline --example casomm_ceiling
//! ```

use std::path::Path;

use robocal_calibration::physical_model;
use robocal_data::Silent;
use robocal_model::gate_physics_rows;
use robocal_pipeline::{Experiment, run};
use robocal_residual::{Residual, ResidualKind, ResidualSettings, Samples, Somm, inputs_of};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    let experiment = Experiment::load(&root.join("configs/experiments/paper.toml"))?;
    let o = run(&experiment, &Silent)?;
    let twin = o.twin.as_ref().ok_or("the experiment has no twin")?;
    let kin = &o.kinematics[0];
    let rows = &o.data.rows;
    // Per row: the flank of joint 4 (true: positive) and the X jump it makes, mm.
    let flank: Vec<bool> = rows
        .iter()
        .map(|m| twin.backlash_offset(&m.sample.joints_rad(), m.sample.load)[3] > 0.0)
        .collect();
    let jump_x: Vec<f64> = rows
        .iter()
        .map(|m| {
            let q = m.sample.joints_rad();
            let offset = twin.backlash_offset(&q, m.sample.load)[3];
            twin.truth.joint_jacobian(&q)[(0, 3)] * offset
        })
        .collect();
    let (train, val, test) = (o.rows("GA10"), o.rows("GB20"), o.rows("table6"));
    println!(
        "rows: GA10 {}, GB20 {}, Table 6 {}; on the negative flank: {:.1} % of GA10",
        train.len(),
        val.len(),
        test.len(),
        100.0 * train.iter().filter(|&&i| !flank[i]).count() as f64 / train.len() as f64
    );
    let x: Vec<f64> = train.iter().map(|&i| kin.errors[i].x).collect();
    let t = robocal_residual::two_means_threshold(&x).ok_or("no threshold")?;
    let agree = |label: &dyn Fn(usize) -> bool, truth: &dyn Fn(usize) -> bool| {
        let same = train.iter().filter(|&&i| label(i) == truth(i)).count() as f64;
        100.0 * (same / train.len() as f64).max(1.0 - same / train.len() as f64)
    };
    println!(
        "threshold classes (X ≥ {t:.3} mm) agree with the flank on {:.1} % of GA10, with the sign of the X jump on {:.1} %",
        agree(&|i| kin.errors[i].x >= t, &|i| flank[i]),
        agree(&|i| kin.errors[i].x >= t, &|i| jump_x[i] > 0.0)
    );
    let mean_jump = train.iter().map(|&i| jump_x[i].abs()).sum::<f64>() / train.len() as f64;
    println!("mean |X jump| {mean_jump:.3} mm (half the flank-to-flank distance along X)");

    let settings = ResidualSettings::paper(ResidualKind::Somm, 2020);
    let samples = |set: &[usize], keep: &dyn Fn(usize) -> bool| {
        let picked: Vec<usize> = set.iter().copied().filter(|&i| keep(i)).collect();
        Samples::new(
            picked.iter().map(|&i| inputs_of(&rows[i].sample)).collect(),
            picked.iter().map(|&i| kin.errors[i].into()).collect(),
        )
    };
    let mean_left = |predict: &dyn Fn(usize) -> [f64; 3]| {
        test.iter()
            .map(|&i| {
                let p = predict(i);
                (kin.errors[i] - nalgebra::Vector3::from(p)).norm()
            })
            .sum::<f64>()
            / test.len() as f64
    };
    let by_flank = |i: usize| flank[i];
    let by_jump = |i: usize| jump_x[i] > 0.0;
    let oracles: [(&str, &dyn Fn(usize) -> bool); 2] = [
        ("the flank", &by_flank),
        ("the sign of the X jump", &by_jump),
    ];
    for (name, class) in oracles {
        let sets: Vec<Somm> = [false, true]
            .iter()
            .map(|&b| {
                Somm::fit(
                    &settings.axes,
                    &samples(&train, &|i| class(i) == b),
                    &samples(&val, &|i| class(i) == b),
                    2020,
                    if b { 10 } else { 0 },
                    &Silent,
                )
            })
            .collect();
        let e = mean_left(&|i| {
            let set = &sets[usize::from(class(i))];
            let row = Samples::rows(vec![inputs_of(&rows[i].sample)]);
            set.predict(&row.inputs, &row, false).0[0]
        });
        println!("oracle CA-SOMM, classes and gate = {name}: Table 6 mean {e:.3} mm");
    }
    for m in &o.models {
        if !m.name.starts_with("BFGS") {
            continue;
        }
        let mean = test.iter().map(|&i| m.errors[i].norm()).sum::<f64>() / test.len() as f64;
        println!("{}: Table 6 mean {mean:.3} mm", m.name);
        let Some(residual) = &m.residual else {
            continue;
        };
        let Some(c) = residual.classifier() else {
            continue;
        };
        let kin = &o.kinematics[m.kinematic];
        let picked: Vec<&robocal_data::Sample> = test.iter().map(|&i| &rows[i].sample).collect();
        let mut raw = Samples::new(
            picked.iter().map(|s| inputs_of(s)).collect(),
            test.iter().map(|&i| kin.errors[i].into()).collect(),
        );
        if let Some(p) = residual.gate_physics() {
            raw.physics = gate_physics_rows(&physical_model(&kin.calibration).robot, &p, &picked);
        }
        let encoded = residual.encoding.encode_all(&raw.inputs);
        let routed = c.classify(&c.rows(&encoded, &raw));
        let share = |truth: &dyn Fn(usize) -> bool| {
            let same = (test.iter().zip(&routed))
                .filter(|&(&i, &r)| truth(i) == (r == 1))
                .count() as f64
                / test.len() as f64;
            100.0 * same.max(1.0 - same)
        };
        println!(
            "    its gate ({} inputs) routes {:.1} % of the Table 6 rows by the flank, {:.1} % by the sign of the X jump; {:.1} % agree with the X threshold's classes",
            c.inputs.name(),
            share(&by_flank),
            share(&by_jump),
            100.0 * c.accuracy(&c.rows(&encoded, &raw), &raw)
        );
    }
    Ok(())
}
