//! Generating a twin dataset: every kept configuration at every load, noisy and noise-free.

use std::collections::HashMap;
use std::fmt::Write as _;
use std::path::Path;

use nalgebra::Vector3;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use robocal_data::{Measurement, MeasurementSet, Sample, write_dir_atomically, write_text_in};
use robocal_robot::matrix_to_rpy;

use crate::config::{BacklashSide, TwinConfig};
use crate::design::{PointStatus, PoseDesign};
use crate::error::Result;

/// A generated dataset.
#[derive(Debug, Clone, PartialEq)]
pub struct TwinDataset {
    /// Measured rows (with noise), pose-major, loads ascending.
    pub measurements: MeasurementSet,
    /// The same rows without noise.
    pub truth: MeasurementSet,
    /// The pose design the rows come from.
    pub design: PoseDesign,
}

fn round6(v: f64) -> f64 {
    let r = (v * 1e6).round() / 1e6;
    if r == 0.0 { 0.0 } else { r }
}

/// Stream offset that keeps the noise draws independent of the pose-design draws.
const NOISE_STREAM: u64 = 0x006e_6f69_7365;

/// Stream offset of the noise of measured pose files ([`TwinConfig::measure_samples`]).
const POSES_STREAM: u64 = 0x0070_6f73_6573;

impl TwinConfig {
    /// Generates every kept configuration at every load. Byte-for-byte deterministic for a given
    /// twin file: readings are rounded to 1e-4 deg and positions to 1e-6 mm.
    pub fn generate(&self) -> Result<TwinDataset> {
        let design = self.design_poses()?;
        let loads = self.loads.all();
        let mut rng = ChaCha8Rng::seed_from_u64(self.seed ^ NOISE_STREAM);
        let mut measured = Vec::new();
        let mut truth = Vec::new();
        // Every load, and at each every reflector: the default point, then the named
        // points of the truth's `[tool.points]` (their rows name them in `target`).
        let targets = self.truth.target_names();
        // With play that follows the order of motion: every pose and load in the order
        // generated, and each one's last moves as a measurement file's `seq` gives them.
        let mut ordered: Vec<Sample> = Vec::new();
        if self.motion.is_some() {
            for deg in design.kept().filter_map(|p| p.joints_deg.as_ref()) {
                for _ in &loads {
                    ordered.push(Sample {
                        joints: deg.clone(),
                        seq: Some(ordered.len() as i64),
                        ..Sample::default()
                    });
                }
            }
            robocal_data::set_last_moves(&mut ordered);
        }
        let mut ordered = ordered.into_iter();
        for point in design.kept() {
            let Some(deg) = &point.joints_deg else {
                continue;
            };
            for &load in &loads {
                let (seq, last_move) = match ordered.next() {
                    Some(s) => (s.seq, s.last_move),
                    None => (None, Vec::new()),
                };
                // The joints stand behind their readings by the play, in the direction they
                // last moved in.
                let q: Vec<f64> = (deg.iter().enumerate())
                    .map(|(j, d)| {
                        let play = self.motion.as_ref().map_or(0.0, |p| p[j]);
                        (d - play * last_move.get(j).copied().unwrap_or(0.0)).to_radians()
                    })
                    .collect();
                // One reflector: the combined noise as always (the bundled datasets stay
                // byte-identical). Several: the robot's repeatability error once per pose and
                // load, shared by its reflectors, the tracker's per reflector.
                let robot = (targets.len() > 1).then(|| self.draw_repeatability(&mut rng));
                for target in &targets {
                    let sample = Sample {
                        pose: point.id.clone(),
                        joints: deg.clone(),
                        load,
                        line: 0,
                        target: target.to_string(),
                        seq,
                        last_move: last_move.clone(),
                    };
                    let point = self.true_point_of(&q, load, target);
                    let exact = point.map(round6);
                    let noisy = match robot {
                        Some(robot) => self.add_tracker_noise(point, robot, &mut rng),
                        None => self.add_noise(point, &mut rng),
                    }
                    .map(round6);
                    let (exact_rpy, noisy_rpy) = self.probe_reading(&q, load, &mut rng);
                    truth.push(Measurement {
                        sample: sample.clone(),
                        position: exact,
                        orientation: exact_rpy,
                    });
                    measured.push(Measurement {
                        sample,
                        position: noisy,
                        orientation: noisy_rpy,
                    });
                }
            }
        }
        let n = self.truth.dof();
        Ok(TwinDataset {
            measurements: MeasurementSet {
                source: "measurements.csv".into(),
                joint_count: n,
                rows: measured,
            },
            truth: MeasurementSet {
                source: "truth.csv".into(),
                joint_count: n,
                rows: truth,
            },
            design,
        })
    }

    /// A 6-DoF probe's reading of the tool frame at reading `q` (rad) under `load`, as
    /// fixed-axis roll, pitch, yaw in degrees rounded to 1e-6: the exact one and the noisy one
    /// (no draw, and `None`, when the truth has no `[tool] rpy`).
    fn probe_reading(
        &self,
        q: &[f64],
        load: f64,
        rng: &mut ChaCha8Rng,
    ) -> (Option<Vector3<f64>>, Option<Vector3<f64>>) {
        let Some(r) = self.true_rotation(q, load) else {
            return (None, None);
        };
        let degrees = |m: &nalgebra::Matrix3<f64>| matrix_to_rpy(m).map(|a| round6(a.to_degrees()));
        (
            Some(degrees(&r)),
            Some(degrees(&self.add_probe_noise(r, rng))),
        )
    }

    /// Measures the given `samples` (readings in degrees, each at its load), as the twin's
    /// tracker would: the noisy rows and the noise-free ones, in the samples' order (positions
    /// rounded to 1e-6 mm; the noise seeded from the twin's seed, a stream of its own).
    pub fn measure_samples(&self, samples: &[Sample]) -> (MeasurementSet, MeasurementSet) {
        let mut rng = ChaCha8Rng::seed_from_u64(self.seed ^ NOISE_STREAM ^ POSES_STREAM);
        let mut measured = Vec::with_capacity(samples.len());
        let mut truth = Vec::with_capacity(samples.len());
        // With several reflectors, one repeatability error per pose and load (see `generate`).
        let several = !self.truth.points.is_empty();
        let mut robot_errors: HashMap<(String, u64), Vector3<f64>> = HashMap::new();
        for sample in samples {
            let point = self.true_point_of(&sample.joints_rad(), sample.load, &sample.target);
            let (exact_rpy, noisy_rpy) =
                self.probe_reading(&sample.joints_rad(), sample.load, &mut rng);
            truth.push(Measurement {
                sample: sample.clone(),
                position: point.map(round6),
                orientation: exact_rpy,
            });
            let noisy = if several {
                let key = (sample.pose.clone(), sample.load.to_bits());
                let robot = *robot_errors
                    .entry(key)
                    .or_insert_with(|| self.draw_repeatability(&mut rng));
                self.add_tracker_noise(point, robot, &mut rng)
            } else {
                self.add_noise(point, &mut rng)
            };
            measured.push(Measurement {
                sample: sample.clone(),
                position: noisy.map(round6),
                orientation: noisy_rpy,
            });
        }
        let n = self.truth.dof();
        let set = |source: &str, rows| MeasurementSet {
            source: source.into(),
            joint_count: n,
            rows,
        };
        (set("measurements.csv", measured), set("truth.csv", truth))
    }

    /// Generates the dataset and writes `measurements.csv`, `truth.csv`, `grid.csv` and
    /// `README.md` into `out`, atomically.
    pub fn write_dataset(&self, out: &Path) -> Result<TwinDataset> {
        let data = self.generate()?;
        write_dir_atomically(out, |dir| -> Result<()> {
            data.measurements.write(dir.join("measurements.csv"))?;
            data.truth.write(dir.join("truth.csv"))?;
            write_text_in(dir, out, "grid.csv", &grid_csv(&data.design))?;
            write_text_in(dir, out, "README.md", &self.readme(&data))?;
            Ok(())
        })?;
        Ok(data)
    }

    fn readme(&self, data: &TwinDataset) -> String {
        let d = &data.design;
        let kept = d.count(PointStatus::Kept);
        let mut s = String::new();
        let _ = writeln!(s, "# {} — generated twin data\n", self.name);
        let _ = writeln!(
            s,
            "These files were written by `robocal simulate --twin {}` (seed {}). They come from\n\
             robocal's digital twin, **not from a real robot**: a simulated arm whose true geometry is\n\
             the identified table of Hsiao et al. (IEEE Access 2020, Table 4), measured by a simulated\n\
             laser tracker. Regenerating them with the same twin file gives the same bytes.\n",
            self.source.display(),
            self.seed
        );
        let _ = writeln!(s, "## Files\n");
        let _ = writeln!(
            s,
            "- `measurements.csv` — `pose,q1..q{n},load,x,y,z`: {rows} rows, {kept} configurations × {loads} loads. \
             Joint readings are what the controller reports (deg); x, y, z are tracker readings (mm, tracker frame) with noise.\n\
             - `truth.csv` — the same rows without measurement noise (the arm's true reflector position).\n\
             - `grid.csv` — every point of the pose grid (robot base frame, mm) and what became of it.\n",
            n = self.truth.dof(),
            rows = data.measurements.len(),
            loads = self.loads.all().len(),
        );
        let _ = writeln!(s, "## Pose design\n");
        let _ = writeln!(
            s,
            "{} grid points (x {:?}, y {:?}, z {:?} mm, step {} mm, robot base frame); inverse kinematics on the \
             nominal table `{}` with the wrist tilted up to ±{:.1}° and spun up to ±{:.1}° (seeded).\n\
             - kept: {kept}\n- measurable but not chosen: {}\n- unreachable within the joint limits: {}\n- near-singular: {}\n",
            d.points.len(),
            self.poses.x,
            self.poses.y,
            self.poses.z,
            self.poses.step,
            self.nominal_path.display(),
            self.poses.tilt.to_degrees(),
            self.poses.spin.to_degrees(),
            d.count(PointStatus::NotChosen),
            d.count(PointStatus::Unreachable),
            d.count(PointStatus::NearSingular),
        );
        if kept < self.poses.count {
            let _ = writeln!(
                s,
                "**Fewer configurations than asked for**: {} were asked for, only {kept} are measurable.\n",
                self.poses.count
            );
        }
        let _ = writeln!(s, "## Loads (kg)\n");
        let _ = writeln!(
            s,
            "- trained: {:?}\n- untrained: {:?}\n",
            self.loads.trained, self.loads.untrained
        );
        let _ = writeln!(s, "## What the twin contains\n");
        let on = |b: bool| if b { "on" } else { "off" };
        let backlash = if self.backlash.is_empty() {
            "off".to_string()
        } else {
            self.backlash
                .iter()
                .map(|b| {
                    let side = match b.side {
                        BacklashSide::Approach { .. } => "the side of its approach from home",
                        BacklashSide::Torque { .. } => {
                            "the sense of its torque (preload + gravity of links and payload)"
                        }
                    };
                    format!(
                        "joint {}, {:.3} deg, flank set by {side}",
                        b.joint + 1,
                        b.width.to_degrees()
                    )
                })
                .collect::<Vec<_>>()
                .join("; ")
        };
        let _ = writeln!(
            s,
            "- true geometry: the paper's Table 4; base and reflector as in `[truth]` of the twin file\n\
             - joint compliance (gravity torque of links and payload / joint stiffness): {}\n\
             - gear transmission error (1st and 2nd harmonic per joint): {}\n\
             - backlash: {}\n\
             - measurement noise (tracker accuracy and robot repeatability): {}\n",
            on(self.compliance.is_some()),
            on(self.gear.is_some()),
            backlash,
            on(self.noise.is_some()),
        );
        if self.beyond.is_some() {
            let _ = writeln!(
                s,
                "- beyond robocal's model family (`[beyond]`): tilt of each joint's bearing under the gravity moment \
                 across its axis, axis runout at twice the joint angle, the gears' third harmonic, the wrist's coupled \
                 transmission error\n"
            );
        }
        s
    }
}

fn grid_csv(design: &PoseDesign) -> String {
    let mut s = String::from("pose,x,y,z,status,conditioning\n");
    for p in &design.points {
        let _ = writeln!(
            s,
            "{},{},{},{},{},{:.4}",
            p.id,
            p.position.x,
            p.position.y,
            p.position.z,
            p.status.name(),
            p.conditioning
        );
    }
    s
}
