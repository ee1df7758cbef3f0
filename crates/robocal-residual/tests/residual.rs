//! Residual learning on synthetic data with known answers.

use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use robocal_data::Silent;
use robocal_residual::{
    Activation, ClassRule, Defaults, Encoding, Frame, Gate, GateInputs, NetSettings,
    PHYSICS_PER_JOINT, PerClass, RawResidualStage, ResidualError, ResidualKind, ResidualModel,
    ResidualSettings, Samples, Schedule, Split, gate_feature_names, two_means_threshold,
};

fn settings(hidden: Vec<usize>, lr: f64, epochs: usize) -> NetSettings {
    NetSettings {
        hidden,
        activation: Activation::Tanh,
        learning_rate: lr,
        batch_size: 50,
        max_epochs: epochs,
        patience: 1000,
        weight_decay: 0.0,
        schedule: Schedule::Constant,
        steps: None,
    }
}

/// `n` rows of 7 inputs uniform in [-1, 1] with `f` of them as the error on all three axes.
fn samples(n: usize, seed: u64, f: impl Fn(&[f64]) -> [f64; 3]) -> Samples {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let inputs: Vec<Vec<f64>> = (0..n)
        .map(|_| (0..7).map(|_| rng.random_range(-1.0..1.0)).collect())
        .collect();
    let errors = inputs.iter().map(|r| f(r)).collect();
    Samples::new(inputs, errors)
}

fn smooth(x: &[f64]) -> f64 {
    x[0].sin() + 0.5 * x[1] * x[2] - 0.3 * x[3] * x[3] + 0.2 * (x[4] + x[5]).cos() + 0.1 * x[6]
}

fn rms(model: &ResidualModel, s: &Samples, axis: usize) -> f64 {
    let p = model.predict(s);
    (p.iter()
        .zip(&s.errors)
        .map(|(p, e)| (p[axis] - e[axis]).powi(2))
        .sum::<f64>()
        / s.len() as f64)
        .sqrt()
}

fn std_of(s: &Samples, axis: usize) -> f64 {
    let n = s.len() as f64;
    let m = s.errors.iter().map(|e| e[axis]).sum::<f64>() / n;
    (s.errors.iter().map(|e| (e[axis] - m).powi(2)).sum::<f64>() / n).sqrt()
}

fn somm(axes: NetSettings, seed: u64) -> ResidualSettings {
    ResidualSettings {
        axes: [axes.clone(), axes.clone(), axes.clone()],
        mosm: axes,
        ..ResidualSettings::paper(ResidualKind::Somm, seed)
    }
}

#[test]
fn an_mlp_learns_a_smooth_function_of_seven_inputs() {
    let f = |x: &[f64]| [smooth(x), 0.0, 0.0];
    let (train, val, test) = (samples(800, 1, f), samples(200, 2, f), samples(300, 3, f));
    let mut s = somm(settings(vec![32, 32], 5e-3, 80), 7);
    s.kind = ResidualKind::Mosm;
    s.mosm = settings(vec![32, 32], 5e-3, 80);
    let model = ResidualModel::fit(&s, &train, &val, &Silent).unwrap();
    let (err, spread) = (rms(&model, &test, 0), std_of(&test, 0));
    // Stated tolerance: held-out RMS error under 10 % of the target's spread.
    assert!(err < 0.1 * spread, "rms {err} vs spread {spread}");
}

#[test]
fn training_is_deterministic_and_a_saved_model_predicts_bit_identically() {
    let f = |x: &[f64]| [smooth(x), x[0] - x[1], 0.3 * x[2]];
    let (train, val) = (samples(300, 4, f), samples(100, 5, f));
    let s = somm(settings(vec![8, 8], 3e-3, 4), 11);
    let a = ResidualModel::fit(&s, &train, &val, &Silent).unwrap();
    let b = ResidualModel::fit(&s, &train, &val, &Silent).unwrap();
    let (pa, pb) = (a.predict(&val), b.predict(&val));
    assert_eq!(pa, pb, "same seed, same model");
    let dir = tempfile::tempdir().unwrap();
    let mut a = a;
    // The spread the default calibration's folds find beside the physics' deviation travels
    // with the networks.
    a.spread_mm = Some(0.0375);
    a.save(dir.path()).unwrap();
    let loaded = ResidualModel::load(dir.path()).unwrap();
    assert_eq!(loaded.spread_mm, Some(0.0375));
    let pl = loaded.predict(&val);
    for (x, y) in pa.iter().flatten().zip(pl.iter().flatten()) {
        assert_eq!(x.to_bits(), y.to_bits());
    }
    // The plain-matrix inference agrees with burn's forward pass.
    for net in a.nets() {
        let x: Vec<f32> = (0..70)
            .map(|i| ((i * 37 % 23) as f32 - 11.0) / 7.0)
            .collect();
        let (dense, burn) = (net.predict_standardised(&x), net.burn_forward(&x));
        assert_eq!(dense.len(), burn.len());
        for (d, b) in dense.iter().zip(&burn) {
            assert!((d - b).abs() <= 1e-5 * (1.0 + b.abs()), "{d} vs {b}");
        }
    }
    // A different seed gives a different model.
    let c = ResidualModel::fit(
        &ResidualSettings {
            seed: 12,
            ..s.clone()
        },
        &train,
        &val,
        &Silent,
    )
    .unwrap();
    let pc = c.predict(&val);
    assert_ne!(pc, pa);
    // Trainings at once (as the cross-validation's folds run, one per core), the two seeds
    // interleaved: each gives the model its seed gives alone (burn's generator is one for the
    // whole process).
    for round in 0..3 {
        let at_once: Vec<_> = std::thread::scope(|scope| {
            let runs: Vec<_> = (0..6)
                .map(|i| {
                    let seeded = ResidualSettings {
                        seed: 11 + (i % 2),
                        ..s.clone()
                    };
                    let (train, val) = (&train, &val);
                    scope.spawn(move || {
                        ResidualModel::fit(&seeded, train, val, &Silent)
                            .unwrap()
                            .predict(val)
                    })
                })
                .collect();
            runs.into_iter().map(|r| r.join().unwrap()).collect()
        });
        for (i, p) in at_once.iter().enumerate() {
            let alone = if i % 2 == 0 { &pa } else { &pc };
            assert_eq!(
                p,
                alone,
                "round {round}, training {i} (seed {})",
                11 + i % 2
            );
        }
    }
}

#[test]
fn early_stopping_stops_and_keeps_the_best_epoch() {
    // Validation targets are the negated training targets: the validation loss is lowest early
    // and rises as the network learns the training data.
    let train = samples(400, 6, |x| [smooth(x), 0.0, 0.0]);
    let val = samples(100, 7, |x| [-smooth(x), 0.0, 0.0]);
    let mut net = settings(vec![16], 1e-2, 60);
    net.patience = 3;
    let mut s = somm(net.clone(), 3);
    s.kind = ResidualKind::Mosm;
    s.mosm = net;
    let model = ResidualModel::fit(&s, &train, &val, &Silent).unwrap();
    let r = &model.nets()[0].report;
    assert!(r.stopped_early, "{r:?}");
    assert_eq!(r.epochs, r.best_epoch + 3);
    let best = r
        .validation_loss
        .iter()
        .copied()
        .fold(f64::INFINITY, f64::min);
    assert_eq!(r.validation_loss[r.best_epoch - 1], best);
    // The model returned is the best epoch's: its validation loss (standardised MSE over all
    // three outputs, recomputed here) equals the best recorded.
    let net = &model.nets()[0];
    let p = model.predict(&val);
    let mse: f64 = p
        .iter()
        .zip(&val.errors)
        .map(|(p, e)| {
            (0..3)
                .map(|a| ((p[a] - e[a]) / net.output_scale.std[a]).powi(2))
                .sum::<f64>()
        })
        .sum::<f64>()
        / (3 * val.len()) as f64;
    assert!(
        (mse - best).abs() < 1e-4 * best.max(1e-3),
        "{mse} vs {best}"
    );
}

#[test]
fn ca_somm_separates_two_classes_and_beats_somm_on_a_bimodal_axis() {
    // X is bimodal: a jump of 2 where the third input passes 0.3, plus a smooth part.
    let f = |x: &[f64]| {
        let jump = if x[2] > 0.3 { 1.0 } else { -1.0 };
        [jump + 0.3 * smooth(x), 0.2 * x[0], 0.1 * x[1]]
    };
    let (train, val, test) = (samples(1200, 8, f), samples(300, 9, f), samples(400, 10, f));
    let t = two_means_threshold(&train.errors.iter().map(|e| e[0]).collect::<Vec<_>>()).unwrap();
    assert!(t.abs() < 0.6, "the split falls between the modes: {t}");
    let net = settings(vec![16, 16], 5e-3, 30);
    let plain = ResidualModel::fit(&somm(net.clone(), 5), &train, &val, &Silent).unwrap();
    let mut s = somm(net, 5);
    s.kind = ResidualKind::CaSomm;
    let gated = ResidualModel::fit(&s, &train, &val, &Silent).unwrap();
    let again = ResidualModel::fit(&s, &train, &val, &Silent).unwrap();
    assert_eq!(
        again.predict(&test),
        gated.predict(&test),
        "CA-SOMM training is deterministic too"
    );
    let accuracy = gated.classifier_accuracy(&test).unwrap();
    assert!(accuracy > 0.95, "classification accuracy {accuracy}");
    let (e_plain, e_gated) = (rms(&plain, &test, 0), rms(&gated, &test, 0));
    assert!(
        e_gated < 0.8 * e_plain,
        "CA-SOMM {e_gated} vs SOMM {e_plain}"
    );
    // Save and load keep the gate.
    let dir = tempfile::tempdir().unwrap();
    gated.save(dir.path()).unwrap();
    let loaded = ResidualModel::load(dir.path()).unwrap();
    assert_eq!(loaded.predict(&test), gated.predict(&test));

    // The soft gate weights the sets by the class shares of the leaf: shares are those of the
    // training rows (counted here independently), and where a leaf is pure it predicts exactly
    // as the hard gate.
    let mut soft = s.clone();
    soft.classifier.gate = Gate::Soft;
    let soft = ResidualModel::fit(&soft, &train, &val, &Silent).unwrap();
    let c = soft.classifier().unwrap();
    let labels: Vec<usize> = train
        .errors
        .iter()
        .map(|e| usize::from(e[0] >= c.threshold))
        .collect();
    for (leaf, share) in &c.leaf_share_b {
        let rows: Vec<usize> = (0..train.len())
            .filter(|&i| &c.leaf_path(&train.inputs[i]) == leaf)
            .collect();
        let b = rows.iter().filter(|&&i| labels[i] == 1).count();
        assert!(!rows.is_empty());
        assert_eq!(*share, b as f64 / rows.len() as f64, "leaf {leaf}");
    }
    let (hard_p, soft_p) = (gated.predict(&test), soft.predict(&test));
    let shares = c.share_b(&test.inputs);
    let pure = shares.iter().filter(|p| **p == 0.0 || **p == 1.0).count();
    assert!(pure > 0, "some leaf is pure on this separable set");
    for (i, p) in shares.iter().enumerate() {
        if *p == 0.0 || *p == 1.0 {
            assert_eq!(soft_p[i], hard_p[i]);
        }
    }
    soft.save(dir.path()).unwrap();
    assert_eq!(
        ResidualModel::load(dir.path()).unwrap().predict(&test),
        soft_p
    );
    // A tampered tree (linfa would index out of bounds or unwrap a missing branch) is refused.
    refused_after(dir.path(), "classifier", |m| {
        m["classifier"]["tree"]["root_node"]["feature_idx"] = 99.into();
    });
    refused_after(dir.path(), "classifier", |m| {
        m["classifier"]["tree"]["root_node"]["left_child"] = serde_json::Value::Null;
    });
    refused_after(dir.path(), "classifier", |m| {
        m["classifier"]["axis"] = 7.into();
    });

    // Per class on the classifier's axis only: Y and Z come from one network both sets share.
    let mut axis_only = s.clone();
    axis_only.classifier.per_class = PerClass::Axis;
    let m = ResidualModel::fit(&axis_only, &train, &val, &Silent).unwrap();
    let plain_p = plain.predict(&test);
    let m_p = m.predict(&test);
    for (a, b) in m_p.iter().zip(&plain_p) {
        assert_eq!(a[1], b[1], "Y is the SOMM network trained on every row");
        assert_eq!(a[2], b[2]);
    }
    assert!(rms(&m, &test, 0) < 0.8 * e_plain);
}

/// Edits the saved manifest in `dir`, checks that loading fails naming the file and
/// `needle`, and puts the manifest back.
fn refused_after(dir: &std::path::Path, needle: &str, edit: impl Fn(&mut serde_json::Value)) {
    let path = dir.join("residual.json");
    let original = std::fs::read_to_string(&path).unwrap();
    let mut m: serde_json::Value = serde_json::from_str(&original).unwrap();
    edit(&mut m);
    std::fs::write(&path, serde_json::to_string(&m).unwrap()).unwrap();
    let err = ResidualModel::load(dir).unwrap_err().to_string();
    assert!(
        err.contains("residual.json") && err.contains(needle),
        "{needle}: {err}"
    );
    std::fs::write(&path, original).unwrap();
    ResidualModel::load(dir).unwrap();
}

#[test]
fn bad_settings_and_bad_files_are_refused() {
    let train = samples(50, 1, |x| [x[0], 0.0, 0.0]);
    let mut s = somm(settings(vec![0], 1e-3, 2), 1);
    let err = ResidualModel::fit(&s, &train, &train, &Silent).unwrap_err();
    assert!(err.to_string().contains("x.hidden"), "{err}");
    s.axes[0] = settings(vec![4], -1.0, 2);
    let err = ResidualModel::fit(&s, &train, &train, &Silent).unwrap_err();
    assert!(err.to_string().contains("x.learning_rate"), "{err}");
    let dir = tempfile::tempdir().unwrap();
    let err = ResidualModel::load(dir.path()).unwrap_err();
    assert!(err.to_string().contains("residual.json"), "{err}");
    std::fs::write(dir.path().join("residual.json"), "{\"residual_format\": 9}").unwrap();
    let err = ResidualModel::load(dir.path()).unwrap_err();
    assert!(err.to_string().contains("residual_format 9"), "{err}");
    let _ = Split { x: &[], y: &[] };

    // Fields of a written model that would allocate without bound, read outside the model
    // directory, or divide by zero: each refused by the loader, naming the field.
    let s = somm(settings(vec![4], 1e-3, 2), 1);
    let model = ResidualModel::fit(&s, &train, &train, &Silent).unwrap();
    model.save(dir.path()).unwrap();
    refused_after(dir.path(), "nets[0].settings.hidden", |m| {
        m["nets"][0]["settings"]["hidden"] = serde_json::json!([1_000_000_000u64]);
    });
    refused_after(dir.path(), "nets[1].file", |m| {
        m["nets"][1]["file"] = "../../elsewhere.bpk".into();
    });
    refused_after(dir.path(), "inputs 0", |m| m["inputs"] = 0.into());
    refused_after(dir.path(), "spread_mm -0.01", |m| {
        m["spread_mm"] = (-0.01).into()
    });
    refused_after(dir.path(), "scaling", |m| {
        m["nets"][2]["input_scale"]["std"][0] = 0.0.into();
    });
    refused_after(dir.path(), "scaling", |m| {
        m["nets"][0]["output_scale"]["std"] = serde_json::json!([]);
    });
    let huge = settings(vec![5000], 1e-3, 2);
    let err = ResidualModel::fit(&somm(huge, 1), &train, &train, &Silent).unwrap_err();
    assert!(err.to_string().contains("x.hidden"), "{err}");
}

#[test]
fn tpe_search_tries_the_asked_trials_within_bounds_and_keeps_the_best() {
    let f = |x: &[f64]| [smooth(x), 0.0, 0.0];
    let (train, val) = (samples(300, 21, f), samples(100, 22, f));
    let mut s = somm(settings(vec![4], 1e-3, 5), 9);
    s.kind = ResidualKind::Mosm;
    s.mosm = settings(vec![4], 1e-3, 5);
    s.search = Some(robocal_residual::SearchSettings {
        trials: 5,
        layers: [1, 3],
        neurons: [4, 16],
        learning_rate: [1e-3, 1e-2],
    });
    let a = ResidualModel::fit(&s, &train, &val, &Silent).unwrap();
    let b = ResidualModel::fit(&s, &train, &val, &Silent).unwrap();
    assert_eq!(a.search, b.search, "seeded: the same trials");
    let log = &a.search[0];
    assert_eq!(log.trials.len(), 5);
    for t in &log.trials {
        assert!((1..=3).contains(&t.hidden.len()));
        assert!(t.hidden.iter().all(|n| (4..=16).contains(n)));
        assert!(t.learning_rate >= 1e-3 && t.learning_rate <= 1e-2);
    }
    let best = &log.trials[log.best];
    assert!(
        log.trials
            .iter()
            .all(|t| t.validation_loss >= best.validation_loss)
    );
    // The final network is trained with the best trial's settings, and the log is saved.
    assert_eq!(a.nets()[0].settings.hidden, best.hidden);
    assert_eq!(a.nets()[0].settings.learning_rate, best.learning_rate);
    let dir = tempfile::tempdir().unwrap();
    a.save(dir.path()).unwrap();
    assert_eq!(ResidualModel::load(dir.path()).unwrap().search, a.search);
}

/// The GP residual on the periodic encoding: it learns an error periodic in the angles
/// (inputs in degrees, the last one the load), its save/load round trip predicts the same to the
/// bit, its standard deviation grows away from the training poses, and a tampered file is
/// refused with the field named.
#[test]
fn a_gp_learns_a_periodic_error_round_trips_and_knows_where_it_has_not_been() {
    use robocal_residual::{Encoding, GpSettings};
    // Joints within ±90°; the error a function of sin/cos of the angles and the load.
    let f = |r: &[f64]| {
        let q: Vec<f64> = r[..6].iter().map(|d| d.to_radians()).collect();
        [
            0.2 * q[0].sin() + 0.1 * (q[1] + q[2]).cos() * (1.0 + 0.05 * r[6]),
            0.15 * (2.0 * q[3]).sin(),
            0.1 * q[4].cos() * q[5].sin(),
        ]
    };
    let make = |n: usize, seed: u64, range: f64| {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let inputs: Vec<Vec<f64>> = (0..n)
            .map(|_| {
                let mut r: Vec<f64> = (0..6).map(|_| rng.random_range(-range..range)).collect();
                r.push(rng.random_range(0.0..10.0));
                r
            })
            .collect();
        let errors = inputs.iter().map(|r| f(r)).collect();
        Samples::new(inputs, errors)
    };
    let train = make(300, 1, 90.0);
    let test = make(100, 2, 90.0);
    let mut s = ResidualSettings::gp(5);
    assert_eq!(s.encoding, Encoding::Periodic);
    s.gp = GpSettings {
        hyper_rows: 200,
        iterations: 40,
        ..GpSettings::default()
    };
    let model = ResidualModel::fit(&s, &train, &Samples::default(), &Silent).unwrap();
    for axis in 0..3 {
        let (left, spread) = (rms(&model, &test, axis), std_of(&test, axis));
        assert!(left < 0.25 * spread, "axis {axis}: {left} left of {spread}");
    }
    let dir = tempfile::tempdir().unwrap();
    model.save(dir.path()).unwrap();
    let loaded = ResidualModel::load(dir.path()).unwrap();
    let (a, sa) = model.predict_with_std(&test, true);
    let (b, sb) = loaded.predict_with_std(&test, true);
    assert_eq!(a, b);
    assert_eq!(sa, sb);
    // The frame its errors are in: the world's unless asked, left out of the file then; a
    // model in the frame turning with joint 1 says so and reads back so (from a stage's
    // `frame = "joint1"` too).
    assert_eq!((model.frame, loaded.frame), (Frame::World, Frame::World));
    let manifest = |d: &std::path::Path| -> serde_json::Value {
        serde_json::from_str(&std::fs::read_to_string(d.join("residual.json")).unwrap()).unwrap()
    };
    assert!(manifest(dir.path()).get("frame").is_none());
    let stage: RawResidualStage = toml::from_str("model = \"gp\"\nframe = \"joint1\"").unwrap();
    let mut turning = stage.validate(Defaults::Robocal).unwrap().settings;
    assert_eq!(turning.frame, Frame::Joint1);
    turning.gp = s.gp.clone();
    let turned = ResidualModel::fit(&turning, &train, &Samples::default(), &Silent).unwrap();
    assert_eq!(turned.frame, Frame::Joint1);
    let turned_dir = tempfile::tempdir().unwrap();
    turned.save(turned_dir.path()).unwrap();
    assert_eq!(manifest(turned_dir.path())["frame"], "joint1");
    assert_eq!(
        ResidualModel::load(turned_dir.path()).unwrap().frame,
        Frame::Joint1
    );
    assert!(toml::from_str::<RawResidualStage>("model = \"gp\"\nframe = \"tool\"").is_err());
    assert_eq!(Frame::parse("joint1"), Ok(Frame::Joint1));
    assert_eq!(
        Frame::parse("tool"),
        Err("`tool` is not a frame; use `world` or `joint1`".to_string())
    );
    // Far outside the trained joint range (±170° on every joint), the model is less sure.
    let far = make(100, 3, 170.0);
    let far: Vec<Vec<f64>> = far
        .inputs
        .into_iter()
        .filter(|r| r[..6].iter().any(|q| q.abs() > 120.0))
        .collect();
    let (_, s_far) = model.predict_with_std(&Samples::rows(far), true);
    let mean = |s: &[[f64; 3]]| s.iter().map(|v| v[0]).sum::<f64>() / s.len() as f64;
    let sa = sa.unwrap();
    assert!(mean(&s_far.unwrap()) > 2.0 * mean(&sa));
    // A factor on the deviations (what the default calibration's folds find) multiplies them,
    // leaves the corrections alone and is saved; a file written before it existed reads as 1.
    let mut scaled = model.clone();
    scaled.set_std_scale(2.5);
    let (c, sc) = scaled.predict_with_std(&test, true);
    assert_eq!(c, a);
    for (x, y) in sc.unwrap().iter().zip(&sa) {
        for k in 0..3 {
            assert!((x[k] - 2.5 * y[k]).abs() <= 1e-12 * y[k], "{x:?} {y:?}");
        }
    }
    let scaled_dir = tempfile::tempdir().unwrap();
    scaled.save(scaled_dir.path()).unwrap();
    let file = scaled_dir.path().join("residual.json");
    let mut json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&file).unwrap()).unwrap();
    assert_eq!(json["gp"]["std_scale"], 2.5);
    let (_, sl) = ResidualModel::load(scaled_dir.path())
        .unwrap()
        .predict_with_std(&test, true);
    assert_eq!(sl, scaled.predict_with_std(&test, true).1);
    json["gp"].as_object_mut().unwrap().remove("std_scale");
    std::fs::write(&file, json.to_string()).unwrap();
    let (_, old) = ResidualModel::load(scaled_dir.path())
        .unwrap()
        .predict_with_std(&test, true);
    assert_eq!(old.unwrap(), sa);
    json["gp"]["std_scale"] = (-1.0).into();
    std::fs::write(&file, json.to_string()).unwrap();
    let err = ResidualModel::load(scaled_dir.path())
        .unwrap_err()
        .to_string();
    assert!(err.contains("gp.std_scale"), "{err}");
    // A GP gives its own deviation: a spread beside the physics' is not its.
    json["gp"]["std_scale"] = 2.5.into();
    json["spread_mm"] = 0.02.into();
    std::fs::write(&file, json.to_string()).unwrap();
    let err = ResidualModel::load(scaled_dir.path())
        .unwrap_err()
        .to_string();
    assert!(err.contains("spread_mm"), "{err}");
    // The networks give no standard deviation.
    let text = std::fs::read_to_string(dir.path().join("residual.json")).unwrap();
    let mut json: serde_json::Value = serde_json::from_str(&text).unwrap();
    json["gp"]["axes"][1]["alpha"].as_array_mut().unwrap().pop();
    std::fs::write(dir.path().join("residual.json"), json.to_string()).unwrap();
    let err = ResidualModel::load(dir.path()).unwrap_err().to_string();
    assert!(
        err.contains("gp.axes[1]") && err.contains("residual.json"),
        "{err}"
    );
}

/// Weight decay is applied: a heavy L2 penalty pulls the network towards the standardised
/// mean, so its predictions spread far less than those of the same network trained without
/// it; robocal's network (decay, plateau schedule, epochs sized to the data) learns the smooth
/// function as well as the plain one, and both settings survive a save and load.
#[test]
fn weight_decay_shrinks_the_fit_and_robocal_networks_learn() {
    let f = |x: &[f64]| [smooth(x), 0.0, 0.0];
    let (train, val, test) = (
        samples(600, 21, f),
        samples(150, 22, f),
        samples(300, 23, f),
    );
    let spread = |m: &ResidualModel| {
        let p: Vec<f64> = m.predict(&test).iter().map(|p| p[0]).collect();
        let mean = p.iter().sum::<f64>() / p.len() as f64;
        (p.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / p.len() as f64).sqrt()
    };
    let plain = settings(vec![16], 5e-3, 40);
    let heavy = NetSettings {
        weight_decay: 5.0,
        ..plain.clone()
    };
    let free = ResidualModel::fit(&somm(plain, 3), &train, &val, &Silent).unwrap();
    let decayed = ResidualModel::fit(&somm(heavy, 3), &train, &val, &Silent).unwrap();
    assert!(
        spread(&decayed) < 0.3 * spread(&free),
        "decayed {} vs free {}",
        spread(&decayed),
        spread(&free)
    );
    let ours = ResidualModel::fit(&somm(NetSettings::robocal(), 3), &train, &val, &Silent).unwrap();
    let (err, target) = (rms(&ours, &test, 0), std_of(&test, 0));
    assert!(err < 0.1 * target, "rms {err} vs spread {target}");
    let dir = tempfile::tempdir().unwrap();
    ours.save(dir.path()).unwrap();
    let back = ResidualModel::load(dir.path()).unwrap();
    assert_eq!(back.nets()[0].settings, NetSettings::robocal());
    assert_eq!(back.predict(&test), ours.predict(&test));
}

/// Rows of three angles (degrees, ±170) and a load (0–5 kg) whose X error jumps by ±1 with the
/// sign of `torque` = 3 sin q1 + 2 cos q2 + load − 1 (oblique in the raw inputs), given to a
/// physics gate as its first physics feature (the other 14 are noise). Y and Z are smooth.
fn flank_samples(n: usize, seed: u64) -> Samples {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut s = Samples::default();
    for _ in 0..n {
        let q: Vec<f64> = (0..3).map(|_| rng.random_range(-170.0..170.0)).collect();
        let load = rng.random_range(0.0..5.0);
        let (q1, q2) = (f64::to_radians(q[0]), f64::to_radians(q[1]));
        let torque = 3.0 * q1.sin() + 2.0 * q2.cos() + load - 1.0;
        let jump = if torque >= 0.0 { 1.0 } else { -1.0 };
        let mut row = q.clone();
        row.push(load);
        s.inputs.push(row);
        s.errors
            .push([jump + 0.2 * q1.cos(), 0.3 * q2.sin(), 0.05 * load]);
        let mut physics = vec![torque];
        physics.extend((1..PHYSICS_PER_JOINT * 3).map(|_| rng.random_range(-1.0..1.0)));
        s.physics.push(physics);
    }
    s
}

#[test]
fn a_physics_gate_learns_a_flank_the_raw_angles_hide_and_the_fallback_keeps_what_pays() {
    let (train, val, test) = (
        flank_samples(1200, 21),
        flank_samples(300, 22),
        flank_samples(400, 23),
    );
    let net = settings(vec![16, 16], 5e-3, 40);
    let mut s = somm(net.clone(), 5);
    s.kind = ResidualKind::CaSomm;
    s.encoding = Encoding::Periodic;
    let raw_gate = ResidualModel::fit(&s, &train, &val, &Silent).unwrap();
    s.classifier.inputs = Some(GateInputs::Physics);
    s.classifier.gravity = Some([0.0, 0.0, -9.81]);
    s.classifier.payload_com = Some([0.0, 0.0, 50.0]);
    let physics_gate = ResidualModel::fit(&s, &train, &val, &Silent).unwrap();
    let (raw_acc, physics_acc) = (
        raw_gate.classifier_accuracy(&test).unwrap(),
        physics_gate.classifier_accuracy(&test).unwrap(),
    );
    assert!(
        physics_acc > 0.97 && physics_acc > raw_acc + 0.05,
        "physics gate {physics_acc}, angles {raw_acc}"
    );
    let c = physics_gate.classifier().unwrap();
    let names = gate_feature_names(GateInputs::Physics, Encoding::Periodic, 3);
    assert_eq!(
        names.len(),
        GateInputs::Physics.features(Encoding::Periodic, 4)
    );
    assert_eq!(
        names[c.splits()[0].0],
        "payload lever j1",
        "the root splits on the torque"
    );
    // Saved with its physics and read back, it predicts the same from the same physics rows.
    let dir = tempfile::tempdir().unwrap();
    physics_gate.save(dir.path()).unwrap();
    let back = ResidualModel::load(dir.path()).unwrap();
    assert_eq!(back.gate_physics(), physics_gate.gate_physics());
    assert_eq!(back.predict(&test), physics_gate.predict(&test));
    refused_after(dir.path(), "physics", |m| {
        m["classifier"]["physics"] = serde_json::Value::Null;
    });

    // Routed classes: each set trained on the rows the tree sends it.
    s.classifier.classes = Some(ClassRule::Routed);
    let routed = ResidualModel::fit(&s, &train, &val, &Silent).unwrap();
    let c = routed.classifier().unwrap();
    let encoded = Encoding::Periodic.encode_all(&train.inputs);
    let sent = c.classify(&c.rows(&encoded, &train));
    assert_eq!(c.class_rows[1], sent.iter().filter(|k| **k == 1).count());
    assert_eq!(c.training_classes(&encoded, &train), sent);

    // Tree search: the size kept is the best of the grid on the validation rows.
    s.classifier.tree_search = Some(true);
    let searched = ResidualModel::fit(&s, &train, &val, &Silent).unwrap();
    let c = searched.classifier().unwrap();
    let best = c
        .tree_search
        .iter()
        .map(|t| t.2)
        .fold(f64::NEG_INFINITY, f64::max);
    let kept = c
        .tree_search
        .iter()
        .find(|t| (t.0, t.1) == (c.max_depth, c.min_samples_leaf));
    assert_eq!(kept.map(|t| t.2), Some(best));
    assert!((searched.classifier_accuracy(&val).unwrap() - best).abs() < 1e-12);

    // Fallback: on the bimodal axis two classes pay; on a smooth one they are compared with a
    // SOMM, and the model kept is the one the decision names (two classes only when they leave
    // significantly less), with the validation error it recorded.
    s.classifier.fallback = Some(true);
    let mean_left = |m: &ResidualModel, set: &Samples| {
        let left = set.remaining(Some(&m.predict(set)));
        left.iter().sum::<f64>() / left.len() as f64
    };
    let kept = ResidualModel::fit(&s, &train, &val, &Silent).unwrap();
    let d = kept.gate_decision.unwrap();
    assert!(d.kept_two() && kept.classifier().is_some(), "{d}");
    assert!((mean_left(&kept, &val) - d.two_classes).abs() < 1e-12);
    let smooth_only = |set: &Samples| {
        let mut set = set.clone();
        for (e, row) in set.errors.iter_mut().zip(&set.inputs) {
            e[0] = 0.2 * row[0].to_radians().cos();
        }
        set
    };
    let (train, val) = (smooth_only(&train), smooth_only(&val));
    let m = ResidualModel::fit(&s, &train, &val, &Silent).unwrap();
    let d = m.gate_decision.unwrap();
    let left = mean_left(&m, &val);
    assert!(
        (left - d.two_classes.min(d.one_class)).abs() < 1e-12,
        "{d}: {left}"
    );
    assert_eq!(m.classifier().is_some(), d.kept_two());
    assert_eq!(
        m.kind(),
        if d.kept_two() {
            ResidualKind::CaSomm
        } else {
            ResidualKind::Somm
        }
    );
}

/// A gate that cannot split (leaves of more rows than there are) routes every row to one class:
/// an error naming the empty class without the fallback; with it, one SOMM on every row (no
/// classifier, no gate decision) that learns the smooth axes like a SOMM of the same settings,
/// and that says which class was left empty (in `residual.json` too; a class other than A or B
/// there is an error naming the field).
#[test]
fn routed_classes_left_empty_fall_back_to_one_somm() {
    let (train, val) = (flank_samples(300, 31), flank_samples(100, 32));
    let net = settings(vec![8], 5e-3, 10);
    let mut s = somm(net, 5);
    s.kind = ResidualKind::CaSomm;
    s.encoding = Encoding::Periodic;
    s.classifier.classes = Some(ClassRule::Routed);
    s.classifier.tree_search = Some(false);
    s.classifier.min_samples_leaf = 10_000;
    s.classifier.fallback = Some(false);
    let err = ResidualModel::fit(&s, &train, &val, &Silent).unwrap_err();
    assert!(matches!(err, ResidualError::EmptyClass { .. }), "{err}");
    assert!(
        err.to_string().contains("fewer than two training samples"),
        "{err}"
    );
    s.classifier.fallback = Some(true);
    let model = ResidualModel::fit(&s, &train, &val, &Silent).unwrap();
    assert!(model.classifier().is_none() && model.gate_decision.is_none());
    let ResidualError::EmptyClass { class } = err else {
        unreachable!()
    };
    assert_eq!(model.empty_class, class.chars().next());
    let why = model.fallback_decision().unwrap();
    assert!(
        why.contains(&format!("left class {class} with fewer than two")),
        "{why}"
    );
    let dir = tempfile::tempdir().unwrap();
    model.save(dir.path()).unwrap();
    let back = ResidualModel::load(dir.path()).unwrap();
    assert_eq!(back.empty_class, model.empty_class);
    assert_eq!(back.predict(&val), model.predict(&val));
    let manifest = dir.path().join("residual.json");
    let text = std::fs::read_to_string(&manifest).unwrap();
    let field = format!("\"empty_class\": \"{class}\"");
    assert!(text.contains(&field), "{text}");
    std::fs::write(&manifest, text.replace(&field, "\"empty_class\": \"C\"")).unwrap();
    let bad = ResidualModel::load(dir.path()).unwrap_err().to_string();
    assert!(
        bad.contains("empty_class 'C'") && bad.contains("residual.json"),
        "{bad}"
    );
    let mut plain = s.clone();
    plain.kind = ResidualKind::Somm;
    let one = ResidualModel::fit(&plain, &train, &val, &Silent).unwrap();
    assert_eq!(model.predict(&val), one.predict(&val));
}

/// A gate whose tree meets leaves where the classes weigh exactly the same is the same tree on
/// every fit. linfa settles such a leaf by its hash maps' order, which differs from one map to
/// the next within a run as between runs, and prunes siblings it predicts alike: here a leaf of
/// 15 rows of each class beside one of 15 A and 45 B rows (joint 1 at four values, nothing
/// else varying), so an unweighted tree kept or pruned their split by the draw — one fit in two.
#[test]
fn a_gate_with_tied_leaves_is_the_same_tree_on_every_fit() {
    let mut train = Samples::default();
    // (joint 1, rows of class A, rows of class B)
    for (q1, a, b) in [
        (-90.0, 30, 0),
        (-30.0, 15, 15),
        (30.0, 0, 30),
        (90.0, 15, 15),
    ] {
        for k in 0..a + b {
            train.inputs.push(vec![q1, 0.0, 0.0]);
            let x = if k < a {
                0.001 * k as f64
            } else {
                1.0 + 0.001 * k as f64
            };
            train.errors.push([x, 0.0, 0.0]);
        }
    }
    let mut s = somm(settings(vec![2], 5e-3, 1), 3);
    s.kind = ResidualKind::CaSomm;
    s.classifier.max_depth = 2;
    s.classifier.min_samples_leaf = 5;
    s.classifier.tree_search = Some(false);
    let gate = || {
        let model = ResidualModel::fit(&s, &train, &train, &Silent).unwrap();
        let c = model.classifier().unwrap();
        (c.splits(), c.classify(&train.inputs))
    };
    let first = gate();
    assert!(!first.0.is_empty(), "the tree splits");
    for fit in 1..12 {
        assert_eq!(gate(), first, "fit {fit} differs from the first");
    }
}

#[test]
fn an_averaged_somm_predicts_its_members_mean_and_round_trips() {
    let f = |x: &[f64]| [smooth(x), x[0] - x[1], 0.3 * x[2]];
    let (train, val, test) = (samples(300, 4, f), samples(100, 5, f), samples(40, 6, f));
    let s = ResidualSettings {
        members: 3,
        ..somm(settings(vec![8, 8], 3e-3, 4), 11)
    };
    let avg = ResidualModel::fit(&s, &train, &val, &Silent).unwrap();
    assert_eq!((avg.members(), avg.nets().len()), (3, 9));
    // Each member trained alone, as `member` seeds it (the first as a single SOMM of the same
    // seed): the average's prediction is their mean.
    assert_eq!(s.member(0).seed, 11);
    assert_eq!(s.member(2).seed, 2011);
    let alone: Vec<Vec<[f64; 3]>> = (0..3)
        .map(|m| {
            let one = ResidualModel::fit(&s.member(m), &train, &val, &Silent).unwrap();
            assert_eq!(one.members(), 1);
            one.predict(&test)
        })
        .collect();
    assert_ne!(alone[0], alone[1], "the members differ");
    let (mean, std) = avg.predict_with_std(&test, true);
    assert_eq!(std, None, "the members' spread is not given as a deviation");
    for i in 0..test.len() {
        for a in 0..3 {
            let m = (alone[0][i][a] + alone[1][i][a] + alone[2][i][a]) / 3.0;
            assert!((mean[i][a] - m).abs() <= 1e-12 * (1.0 + m.abs()), "{i} {a}");
        }
    }
    // Saved and read back: the same points, to the bit; the further members' files beside the
    // first's, which keeps a single SOMM's names.
    let dir = tempfile::tempdir().unwrap();
    avg.save(dir.path()).unwrap();
    for file in ["residual-x.bpk", "residual-z-2.bpk", "residual-y-3.bpk"] {
        assert!(dir.path().join(file).is_file(), "{file}");
    }
    let back = ResidualModel::load(dir.path()).unwrap();
    assert_eq!(back.members(), 3);
    assert_eq!(back.predict(&test), mean);
    // A manifest whose members do not match its networks, or with no member: refused, naming
    // the field.
    refused_after(dir.path(), "has 12 networks", |m| m["members"] = 4.into());
    refused_after(dir.path(), "members 0", |m| m["members"] = 0.into());
    // Settings: no members, more than the bound, several on another kind.
    for (members, kind, needle) in [
        (0, ResidualKind::Somm, "members"),
        (17, ResidualKind::Somm, "members"),
        (2, ResidualKind::Mosm, "only a somm"),
        (2, ResidualKind::Gp, "only a somm"),
    ] {
        let bad = ResidualSettings {
            members,
            kind,
            ..s.clone()
        };
        let err = ResidualModel::fit(&bad, &train, &val, &Silent).unwrap_err();
        assert!(
            err.to_string().contains(needle),
            "{members} {kind:?}: {err}"
        );
    }
    // Only SOMMs of the same inputs are averaged.
    let gp = ResidualModel::fit(
        &ResidualSettings::gp(1),
        &samples(40, 7, f),
        &Samples::default(),
        &Silent,
    )
    .unwrap();
    assert!(ResidualModel::average(vec![avg.clone(), gp]).is_err());
    assert!(ResidualModel::average(Vec::new()).is_err());
}
