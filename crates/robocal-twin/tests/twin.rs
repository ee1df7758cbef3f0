//! The twin's physics, one effect at a time, its determinism, and bad twin files.

use std::path::{Path, PathBuf};

use nalgebra::Vector3;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use robocal_twin::{Backlash, BacklashSide, TwinConfig, TwinError};

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

fn twin() -> TwinConfig {
    TwinConfig::load(root().join("configs/twin/pmc6va030.toml")).expect("the bundled twin loads")
}

fn deg(q: [f64; 6]) -> Vec<f64> {
    q.iter().map(|d| d.to_radians()).collect()
}

const Q: [f64; 6] = [12.0, -55.0, -15.0, 20.0, 50.0, -30.0];

#[test]
fn geometry_only_twin_is_forward_kinematics_of_the_truth() {
    let t = twin().geometry_only();
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    for q in [Q, [0.0; 6], [-40.0, -70.0, 10.0, -90.0, 30.0, 120.0]] {
        let q = deg(q);
        assert_eq!(t.true_point(&q, 17.0), t.truth.point(&q));
        assert_eq!(t.measure(&q, 5.0, &mut rng), t.truth.point(&q));
    }
}

#[test]
fn compliance_droops_with_gravity_linearly_in_payload() {
    let base = twin();
    let t = TwinConfig {
        gear: None,
        backlash: Vec::new(),
        noise: None,
        ..base
    };
    let q = deg(Q);
    let p0 = t.true_point(&q, 0.0);
    let d10 = t.true_point(&q, 10.0) - p0;
    let d20 = t.true_point(&q, 20.0) - p0;
    let g = t.gravity_world().normalize();
    assert!(
        d20.dot(&g) > 0.0,
        "the payload pulls the point along gravity"
    );
    assert!(
        d20.norm() > 0.2 && d20.norm() < 3.0,
        "sized to tenths of a mm: {}",
        d20.norm()
    );
    assert!(
        (d20.norm() / d10.norm() - 2.0).abs() < 1e-3,
        "linear in payload"
    );
    // Joint deflection per kg of payload equals g × (moment arm) / stiffness on joint 2, whose axis
    // is (nearly) horizontal: the arm is the payload's distance from the axis across gravity, w × ĝ.
    let c = t.compliance.clone().unwrap();
    let axes = t.truth.joint_axes(&q);
    let (w, a) = axes.axes[1];
    let across = w.cross(&g);
    let arm_m = (t.payload_point(&q) - a).dot(&across).abs() / 1000.0;
    let per_kg = t.compliance_deflection(&q, 1.0)[1] - t.compliance_deflection(&q, 0.0)[1];
    assert!((per_kg.abs() - 9.80665 * arm_m / c.stiffness[1]).abs() < 1e-12);
    // Longer arm, bigger deflection: stretch the arm out.
    let q_far = deg([12.0, -20.0, -60.0, 20.0, 50.0, -30.0]);
    let axes_far = t.truth.joint_axes(&q_far);
    let arm_far = (t.payload_point(&q_far) - axes_far.axes[1].1)
        .dot(&across)
        .abs()
        / 1000.0;
    let per_kg_far =
        t.compliance_deflection(&q_far, 1.0)[1] - t.compliance_deflection(&q_far, 0.0)[1];
    assert!((per_kg_far / per_kg - arm_far / arm_m).abs() < 1e-9);
}

#[test]
fn gear_error_is_periodic_in_each_joint() {
    let t = TwinConfig {
        compliance: None,
        backlash: Vec::new(),
        noise: None,
        ..twin()
    };
    let g = t.gear.clone().unwrap();
    let q = deg(Q);
    let e = t.gear_error(&q);
    for i in 0..6 {
        let mut turned = q.clone();
        turned[i] += std::f64::consts::TAU;
        assert!((t.gear_error(&turned)[i] - e[i]).abs() < 1e-15);
        assert!(e[i].abs() <= g.amplitude_1[i] + g.amplitude_2[i]);
        // Zero mean over a turn of the joint.
        let mean: f64 = (0..360)
            .map(|k| {
                let mut r = q.clone();
                r[i] = (k as f64).to_radians();
                t.gear_error(&r)[i]
            })
            .sum::<f64>()
            / 360.0;
        assert!(mean.abs() < 1e-12);
        assert!(g.amplitude_1[i].to_degrees() >= 0.001 && g.amplitude_1[i].to_degrees() <= 0.05);
    }
    let moved = t.true_point(&q, 0.0) - t.truth.point(&q);
    assert!(
        moved.norm() > 0.01 && moved.norm() < 2.0,
        "{}",
        moved.norm()
    );
}

/// The twin with only the backlash entry of `joint` (0-based), no other effect, no noise.
fn backlash_only(joint: usize) -> (TwinConfig, Backlash) {
    let base = twin();
    let b = *base
        .backlash
        .iter()
        .find(|b| b.joint == joint)
        .expect("the bundled twin has this backlash");
    let t = TwinConfig {
        compliance: None,
        gear: None,
        noise: None,
        backlash: vec![b],
        ..base
    };
    (t, b)
}

#[test]
fn approach_backlash_flips_with_the_side_of_home() {
    let (t, b) = backlash_only(0);
    let BacklashSide::Approach { home } = b.side else {
        panic!("joint 1's flank is set by the approach from home");
    };
    let mut plus = deg(Q);
    plus[b.joint] = home + 1e-12;
    let mut minus = plus.clone();
    minus[b.joint] = home - 1e-12;
    assert_eq!(t.backlash_offset(&plus, 0.0)[b.joint], b.width / 2.0);
    assert_eq!(t.backlash_offset(&minus, 20.0)[b.joint], -b.width / 2.0);
    // The point jumps tangentially by about width × (distance from the joint-1 axis).
    let jump = t.true_point(&plus, 0.0) - t.true_point(&minus, 0.0);
    let axes = t.truth.joint_axes(&plus);
    let (w, a) = axes.axes[0];
    let radius = (axes.point - a - w * w.dot(&(axes.point - a))).norm();
    assert!((jump.norm() - b.width * radius).abs() < 0.01 * jump.norm());
    assert!(
        jump.dot(&w).abs() < 1e-3 * jump.norm(),
        "tangential, not along the axis"
    );
}

#[test]
fn torque_backlash_flips_when_the_payload_overcomes_the_preload() {
    let (t, b) = backlash_only(3);
    let BacklashSide::Torque { preload } = b.side else {
        panic!("joint 4's flank is set by its torque");
    };
    // A wrist pose whose payload pulls joint 4 against the preload: the torque per kg of payload
    // is negative there, so some load between 0 and 20 kg flips the flank.
    let q = (-90..=90)
        .step_by(15)
        .map(|q4| deg([10.0, -50.0, -20.0, f64::from(q4), 45.0, 30.0]))
        .find(|q| {
            let per_kg = t.gravity_torques(q, 1.0)[3] - t.gravity_torques(q, 0.0)[3];
            preload + t.gravity_torques(q, 0.0)[3] > 0.0
                && preload + t.gravity_torques(q, 20.0)[3] < 0.0
                && per_kg < 0.0
        })
        .expect("a pose where 20 kg overcomes the preload");
    let torque = |load: f64| preload + t.gravity_torques(&q, load)[3];
    // Gravity torque is linear in the load: the flank changes where the line crosses zero.
    let flip = -torque(0.0) / (torque(1.0) - torque(0.0));
    assert!(flip > 0.0 && flip < 20.0);
    assert_eq!(t.backlash_offset(&q, flip * 0.99)[3], b.width / 2.0);
    assert_eq!(t.backlash_offset(&q, flip * 1.01)[3], -b.width / 2.0);
    // Across the flip the point jumps by width × (distance from the joint-4 axis), beside the
    // payload's smooth pull, which this twin does not have (no compliance).
    let jump = t.true_point(&q, flip * 1.01) - t.true_point(&q, flip * 0.99);
    let axes = t.truth.joint_axes(&q);
    let (w, a) = axes.axes[3];
    let radius = (axes.point - a - w * w.dot(&(axes.point - a))).norm();
    assert!((jump.norm() - b.width * radius).abs() < 0.01 * jump.norm());
    // The same pose unloaded, and with the payload on the preload's side, stays on the + flank.
    assert_eq!(t.backlash_offset(&q, 0.0)[3], b.width / 2.0);
}

#[test]
fn noise_has_the_stated_standard_deviation() {
    let t = TwinConfig {
        compliance: None,
        gear: None,
        backlash: Vec::new(),
        ..twin()
    };
    let noise = t.noise.unwrap();
    let q = deg(Q);
    let p = t.true_point(&q, 0.0);
    let expected = noise.sigma(p.norm());
    let tracker = 0.016 + 0.0008 * p.norm() / 1000.0;
    assert!((expected - (tracker.powi(2) + (0.05f64 / 3.6).powi(2)).sqrt()).abs() < 1e-15);
    let mut rng = ChaCha8Rng::seed_from_u64(99);
    let n = 20_000;
    let mut sum = Vector3::zeros();
    let mut sq = 0.0;
    for _ in 0..n {
        let d = t.measure(&q, 0.0, &mut rng) - p;
        sum += d;
        sq += d.norm_squared();
    }
    let sigma = (sq / (3 * n) as f64).sqrt();
    assert!(
        (sigma / expected - 1.0).abs() < 0.02,
        "{sigma} vs {expected}"
    );
    assert!((sum / n as f64).norm() < 4.0 * expected / (n as f64).sqrt() * 3f64.sqrt());
}

#[test]
fn bundled_dataset_regenerates_byte_for_byte() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("pmc6va030");
    // The README quotes the twin path as given on the command line, from the repository root.
    std::env::set_current_dir(root()).unwrap();
    let data = TwinConfig::load("configs/twin/pmc6va030.toml")
        .unwrap()
        .write_dataset(&out)
        .unwrap();
    assert_eq!(data.measurements.len(), 168 * 21);
    for file in ["measurements.csv", "truth.csv", "grid.csv", "README.md"] {
        let committed = std::fs::read(root().join("datasets/pmc6va030").join(file)).unwrap();
        let fresh = std::fs::read(out.join(file)).unwrap();
        assert!(
            committed == fresh,
            "{file} differs from a fresh `robocal simulate`"
        );
    }
}

/// The bundled twin file edited by `edit`, loaded from a temporary directory.
fn load_edited(edit: impl Fn(String) -> String) -> Result<TwinConfig, TwinError> {
    let dir = tempfile::tempdir().unwrap();
    let text = std::fs::read_to_string(root().join("configs/twin/pmc6va030.toml")).unwrap();
    let text = edit(text).replace(
        "../robots/pmc6va030.toml",
        &root()
            .join("configs/robots/pmc6va030.toml")
            .display()
            .to_string(),
    );
    let path = dir.path().join("twin.toml");
    std::fs::write(&path, text).unwrap();
    TwinConfig::load(&path)
}

fn bad(edit: impl Fn(String) -> String) -> TwinError {
    let err = load_edited(edit).unwrap_err();
    assert!(
        err.to_string().contains("twin.toml"),
        "names the file: {err}"
    );
    err
}

#[test]
fn bad_twin_files_are_rejected_with_the_key() {
    let err = bad(|t| t.replace("seed = 20201217", "seed = 20201217\ncolour = \"red\""));
    assert!(
        err.to_string().contains("colour") && err.to_string().contains("line"),
        "{err}"
    );
    let err = bad(|t| t.replace("stiffness = [4.0e6", "stiffness = [-4.0e6"));
    assert!(
        matches!(&err, TwinError::InvalidValue { key, .. } if key == "compliance.stiffness"),
        "{err}"
    );
    let err = bad(|t| {
        t.replace(
            "trained = [0.0, 1.0, 3.0, 4.0, 6.0, 7.0, 9.0, 10.0, 12.0, 13.0, 15.0, 16.0, 18.0, 19.0, 20.0]",
            "trained = []",
        )
    });
    assert!(
        matches!(&err, TwinError::InvalidValue { key, .. } if key == "loads.trained"),
        "{err}"
    );
    let dir = tempfile::tempdir().unwrap();
    let text = std::fs::read_to_string(root().join("configs/twin/pmc6va030.toml"))
        .unwrap()
        .replace("x = [800.0, 1600.0]", "x = [8000.0, 9000.0]")
        .replace("step = 200.0", "step = 400.0")
        .replace(
            "../robots/pmc6va030.toml",
            &root()
                .join("configs/robots/pmc6va030.toml")
                .display()
                .to_string(),
        );
    let path = dir.path().join("far.toml");
    std::fs::write(&path, text).unwrap();
    let far = TwinConfig::load(&path).unwrap();
    assert!(matches!(
        far.generate(),
        Err(TwinError::NoReachablePose { .. })
    ));
    let err = bad(|t| t.replace("joint = 1\n", "joint = 9\n"));
    assert!(
        matches!(&err, TwinError::InvalidValue { key, .. } if key == "backlash[2].joint"),
        "{err}"
    );
    let err = bad(|t| t.replace("side = \"torque\"", "side = \"approach\""));
    assert!(
        matches!(&err, TwinError::InvalidValue { key, .. } if key == "backlash[1].side"),
        "{err}"
    );
    let err = bad(|t| t.replace("joint = 1\n", "joint = 4\n"));
    assert!(
        matches!(&err, TwinError::InvalidValue { key, message, .. } if key == "backlash[2].joint" && message.contains("already")),
        "{err}"
    );
    let err = bad(|t| t.replace("a = 800.882", "a = nan"));
    assert!(err.to_string().contains("truth.joint[3].a"), "{err}");
}

/// Several reflectors: every point measured at every pose and load, named in `target`; the
/// robot's repeatability error shared by the reflectors of one pose and load (the arm is in one
/// place), the tracker's drawn per reflector.
#[test]
fn reflectors_of_one_pose_share_the_robots_error() {
    let mut config = twin().geometry_only();
    config.noise = Some(robocal_twin::Noise {
        tracker_base: 0.0,
        tracker_per_metre: 0.0,
        repeatability: 0.05,
        probe_deg: 0.0,
    });
    config.poses.count = 6;
    let tool = config.truth.tool;
    config.truth.points = vec![
        (
            "smr2".into(),
            tool + nalgebra::Vector3::new(80.0, 0.0, -30.0),
        ),
        (
            "smr3".into(),
            tool + nalgebra::Vector3::new(-40.0, 70.0, -30.0),
        ),
    ];
    let data = config.generate().unwrap();
    let loads = config.loads.all().len();
    assert_eq!(data.measurements.len(), 6 * loads * 3);
    let targets: Vec<&str> = (data.measurements.rows.iter().take(3))
        .map(|m| m.sample.target.as_str())
        .collect();
    assert_eq!(targets, ["", "smr2", "smr3"]);
    let errors: Vec<_> = (data.measurements.rows.iter().zip(&data.truth.rows))
        .map(|(m, t)| m.position - t.position)
        .collect();
    for pose in errors.chunks(3) {
        assert!(pose[0].norm() > 1e-4, "the robot's error is drawn");
        assert!((pose[1] - pose[0]).norm() < 3e-6 && (pose[2] - pose[0]).norm() < 3e-6);
    }
    // The true points are the truth's: the named points sit where the plate puts them.
    let first = &data.truth.rows[..3];
    let q = first[0].sample.joints_rad();
    for (t, m) in first.iter().enumerate() {
        assert!((config.truth.for_target(t).point(&q) - m.position).norm() < 1e-6);
    }
}

/// The bundled twin's geometry with only `beyond` (every other effect and the noise off).
fn beyond_only(beyond: robocal_twin::Beyond) -> TwinConfig {
    TwinConfig {
        beyond: Some(beyond),
        ..twin().geometry_only()
    }
}

/// `[beyond]` with every entry zero but those `edit` sets.
fn no_beyond() -> robocal_twin::Beyond {
    robocal_twin::Beyond {
        tilt_stiffness: vec![0.0; 6],
        wobble: vec![0.0; 6],
        wobble_phase: vec![0.0; 6],
        harmonic_3: vec![0.0; 6],
        phase_3: vec![0.0; 6],
        coupling: vec![0.0; 6],
        coupling_phase: vec![0.0; 6],
    }
}

/// Bearing tilt: the parts beyond joint 2 turn about its origin by the gravity moment across
/// its axis over the tilting stiffness — against the moment summed here from the links' and
/// the payload's centres of mass and an exact rotation of the point.
#[test]
fn bearing_tilt_turns_the_arm_beyond_the_joint_by_the_moment_across_its_axis() {
    let k = 4.0e6;
    let t = beyond_only(robocal_twin::Beyond {
        tilt_stiffness: vec![0.0, k, 0.0, 0.0, 0.0, 0.0],
        ..no_beyond()
    });
    // Wrist turned sideways so that the moment has a part across joint 2's axis.
    let q = deg([25.0, -50.0, -20.0, 70.0, 60.0, 10.0]);
    let load = 15.0;
    let p = t.truth.point(&q);
    let moved = t.true_point(&q, load);
    // The moment about joint 2's origin, from the masses' positions in the link frames.
    let frames = t.truth.link_frames(&q);
    let (w, a) = t.truth.joint_axes(&q).axes[1];
    let g = t.gravity_world();
    let mut moment = Vector3::zeros();
    for ((r, o), (com, mass)) in frames[1..]
        .iter()
        .zip(t.masses.link_com[1..].iter().zip(&t.masses.link_mass[1..]))
    {
        moment += (o + r * com - a).cross(&(g * *mass)) * 1e-3;
    }
    let (r, o) = frames[5];
    moment += (o + r * t.masses.payload_com - a).cross(&(g * load)) * 1e-3;
    let across = moment - w * w.dot(&moment);
    assert!(across.norm() > 5.0, "the pose loads the bearing: {across}");
    let exact = a + nalgebra::Rotation3::new(across / k) * (p - a);
    let (d, e) = (moved - p, exact - p);
    assert!(d.norm() > 1e-3, "the tilt moves the point: {}", d.norm());
    assert!(
        (d - e).norm() < 1e-3 * e.norm(),
        "{d} against the exact rotation's {e}"
    );
    // Half as far on a bearing twice as stiff; the payload's share linear in the load.
    let stiffer = beyond_only(robocal_twin::Beyond {
        tilt_stiffness: vec![0.0, 2.0 * k, 0.0, 0.0, 0.0, 0.0],
        ..no_beyond()
    });
    assert!(((stiffer.true_point(&q, load) - p) * 2.0 - d).norm() < 1e-9);
    let share = |l: f64| t.true_point(&q, l) - t.true_point(&q, 0.0);
    assert!((share(20.0) - share(10.0) * 2.0).norm() < 1e-9);
}

/// Runout, a third harmonic and a coupled wrist lie outside robocal's model family: none is a
/// constant plus a first and second harmonic of its joint's angle (what the identified geometry
/// and the default's harmonics can take), and each has its stated size.
#[test]
fn effects_beyond_the_model_are_not_its_harmonics() {
    let phase = 0.7;
    let t = beyond_only(robocal_twin::Beyond {
        wobble: vec![0.0, 0.0, 0.0, 0.01f64.to_radians(), 0.0, 0.0],
        wobble_phase: vec![0.0, 0.0, 0.0, phase, 0.0, 0.0],
        harmonic_3: vec![0.0, 0.0, 0.005f64.to_radians(), 0.0, 0.0, 0.0],
        phase_3: vec![0.0, 0.0, 0.3, 0.0, 0.0, 0.0],
        coupling: vec![0.0, 0.0, 0.0, 0.0, 0.0, 0.02f64.to_radians()],
        coupling_phase: vec![0.0, 0.0, 0.0, 0.0, 0.0, -0.4],
        ..no_beyond()
    });
    // The joint errors in closed form.
    let q = deg(Q);
    let e = t.beyond_joint_error(&q);
    let third = 0.005f64.to_radians() * (3.0 * q[2] + 0.3).sin();
    let coupled = 0.02f64.to_radians() * (q[5] + q[4] - 0.4).sin();
    assert!((e[2] - third).abs() < 1e-15 && (e[5] - coupled).abs() < 1e-15);
    assert!(e[0] == 0.0 && e[1] == 0.0 && e[3] == 0.0 && e[4] == 0.0);
    // Joint 4's runout over a turn, in joint 3's frame (the frame before it, fixed while joint 4
    // turns): its size is the amplitude, across the axis, and a least-squares fit of a constant
    // and orders 1 and 2 of q4 leaves most of it.
    let angles: Vec<f64> = (0..24)
        .map(|k| k as f64 * std::f64::consts::TAU / 24.0)
        .collect();
    let mut turns = Vec::new();
    for &q4 in &angles {
        let mut q = deg(Q);
        q[3] = q4;
        let turn = t.beyond_turns(&q, 0.0)[3].0;
        let (w, _) = t.truth.joint_axes(&q).axes[3];
        assert!((turn.norm() - 0.01f64.to_radians()).abs() < 1e-12);
        assert!(turn.dot(&w).abs() < 1e-12);
        let r3 = t.truth.link_frames(&q)[2].0;
        turns.push(r3.transpose() * turn);
    }
    let basis = |q: f64| [1.0, q.cos(), q.sin(), (2.0 * q).cos(), (2.0 * q).sin()];
    let design = nalgebra::DMatrix::from_fn(angles.len(), 5, |i, j| basis(angles[i])[j]);
    for axis in 0..3 {
        let y = nalgebra::DVector::from_iterator(angles.len(), turns.iter().map(|t| t[axis]));
        let fit = design.clone().svd(true, true).solve(&y, 1e-12).unwrap();
        let left = (&y - &design * fit).norm();
        if y.norm() > 1e-9 {
            assert!(left > 0.9 * y.norm(), "axis {axis}: {left} of {}", y.norm());
        }
    }
}

#[test]
fn a_bad_beyond_section_is_named() {
    let section = "\n[beyond]\nenabled = true\ntilt_stiffness = [1.0e8, 1.0e8, 1.0e8, 1.0e7, 1.0e7, 1.0e7]\nwobble = [0.0, 0.0, 0.0, 0.0, 0.0, 0.0]\nwobble_phase = [0.0, 0.0, 0.0, 0.0, 0.0, 0.0]\nharmonic_3 = [0.0, 0.0, 0.0, 0.0, 0.0, 0.0]\nphase_3 = [0.0, 0.0, 0.0, 0.0, 0.0, 0.0]\ncoupling = [0.0, 0.0, 0.0, 0.0, 0.0, 0.01]\ncoupling_phase = [0.0, 0.0, 0.0, 0.0, 0.0, 0.0]\n";
    let good = load_edited(|t| t + section).unwrap().beyond.unwrap();
    assert_eq!(good.tilt_stiffness[3], 1.0e7);
    assert!((good.coupling[5] - 0.01f64.to_radians()).abs() < 1e-18);
    let err = bad(|t| t + &section.replace("coupling = [0.0,", "coupling = [0.01,"));
    assert!(
        matches!(&err, TwinError::InvalidValue { key, message, .. } if key == "beyond.coupling" && message.contains("joint 1")),
        "{err}"
    );
    let err = bad(|t| t + &section.replace("1.0e7, 1.0e7, 1.0e7]", "1.0e7, 1.0e7]"));
    assert!(
        matches!(&err, TwinError::InvalidValue { key, .. } if key == "beyond.tilt_stiffness"),
        "{err}"
    );
    let err = bad(|t| t + &section.replace("[1.0e8,", "[-1.0e8,"));
    assert!(
        matches!(&err, TwinError::InvalidValue { key, .. } if key == "beyond.tilt_stiffness"),
        "{err}"
    );
}

/// The grid laid around the base spans ± the grid's largest reach in x and y, keeps the rest,
/// and its configurations turn joint 1 through most of its turn, on both sides of zero (the
/// five-axis twin's grid lies ahead of its base, x 250…550 mm, y ±300: joint 1 within ±50°).
#[test]
fn a_grid_around_the_base_turns_joint_1_all_the_way_round() {
    let arm5 = TwinConfig::load(root().join("configs/twin/arm5.toml")).unwrap();
    let g = arm5.poses.around_base(40);
    assert_eq!((g.x, g.y, g.count), ([-550.0, 550.0], [-550.0, 550.0], 40));
    assert_eq!(
        (g.z, g.step, &g.home),
        (arm5.poses.z, arm5.poses.step, &arm5.poses.home)
    );
    let joint1 = |twin: &TwinConfig| -> [f64; 2] {
        let data = twin.generate().unwrap();
        (data.measurements.rows.iter()).fold([f64::MAX, f64::MIN], |[lo, hi], r| {
            [lo.min(r.sample.joints[0]), hi.max(r.sample.joints[0])]
        })
    };
    let around = joint1(&TwinConfig {
        poses: g,
        ..arm5.clone()
    });
    let [lo, hi] = joint1(&TwinConfig {
        poses: robocal_twin::PoseGrid {
            count: 40,
            ..arm5.poses.clone()
        },
        ..arm5.clone()
    });
    assert!(lo > -60.0 && hi < 60.0, "ahead of the base: {lo}..{hi}°");
    assert!(
        around[0] < -135.0 && around[1] > 135.0,
        "around: {around:?}°"
    );
}
