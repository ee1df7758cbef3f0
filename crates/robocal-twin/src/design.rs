//! Section IV-A pose design: a grid of points in the robot base frame, inverse kinematics on the
//! nominal table with a wrist-orientation policy, discarding unreachable and near-singular points.

use nalgebra::{DMatrix, Matrix3, Rotation3, Vector3};
use rand::seq::SliceRandom;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use robocal_robot::{Base, IkOptions, IkTarget, Robot};

use crate::config::TwinConfig;
use crate::error::{Result, TwinError};

/// What became of one grid point.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PointStatus {
    /// Measured: in the dataset.
    Kept,
    /// Measurable, left out by the seeded choice of `count` configurations.
    NotChosen,
    /// Inverse kinematics found no solution within the joint limits.
    Unreachable,
    /// Reachable but too close to a singularity.
    NearSingular,
}

impl PointStatus {
    /// Lower-case name for files.
    pub fn name(self) -> &'static str {
        match self {
            Self::Kept => "kept",
            Self::NotChosen => "not-chosen",
            Self::Unreachable => "unreachable",
            Self::NearSingular => "near-singular",
        }
    }
}

/// One grid point and its configuration.
#[derive(Debug, Clone, PartialEq)]
pub struct GridPoint {
    /// Pose id, `g001`.. in grid order (x slowest, z fastest).
    pub id: String,
    /// Grid position, mm, robot base frame.
    pub position: Vector3<f64>,
    /// Joint readings (deg, rounded to 1e-4 as a controller reports them) when reachable.
    pub joints_deg: Option<Vec<f64>>,
    /// Fate of the point.
    pub status: PointStatus,
    /// Smallest / largest singular value of the 6 × n pose Jacobian (0 when unreachable).
    pub conditioning: f64,
}

/// The pose design of a twin.
#[derive(Debug, Clone, PartialEq)]
pub struct PoseDesign {
    /// Every grid point in grid order.
    pub points: Vec<GridPoint>,
}

impl PoseDesign {
    /// The kept points, grid order.
    pub fn kept(&self) -> impl Iterator<Item = &GridPoint> {
        self.points.iter().filter(|p| p.status == PointStatus::Kept)
    }

    /// How many points have `status`.
    pub fn count(&self, status: PointStatus) -> usize {
        self.points.iter().filter(|p| p.status == status).count()
    }
}

/// Offsets (deg) of joints 2, 3 and 5 from the home seed, tried in order.
const SEED_VARIATIONS: [(f64, f64, f64); 5] = [
    (0.0, 0.0, 0.0),
    (-25.0, 0.0, 0.0),
    (0.0, 35.0, 0.0),
    (25.0, -35.0, 0.0),
    (-25.0, 35.0, -30.0),
];

fn axis_values(range: [f64; 2], step: f64) -> Vec<f64> {
    let n = ((range[1] - range[0]) / step + 1e-9).floor() as usize + 1;
    (0..n).map(|i| range[0] + step * i as f64).collect()
}

/// Ratio of smallest to largest singular value of the pose Jacobian (orientation rows scaled by
/// 1000 mm/rad), a scale-aware distance from singularity.
fn conditioning(robot: &Robot, q: &[f64]) -> f64 {
    let axes = robot.joint_axes(q);
    let n = q.len();
    let mut jac = DMatrix::zeros(6, n);
    for (i, (w, a)) in axes.axes.iter().enumerate() {
        jac.fixed_view_mut::<3, 1>(0, i)
            .copy_from(&w.cross(&(axes.point - a)));
        jac.fixed_view_mut::<3, 1>(3, i).copy_from(&(w * 1000.0));
    }
    let sv = jac.singular_values();
    let max = sv.max();
    if max > 0.0 { sv.min() / max } else { 0.0 }
}

impl TwinConfig {
    /// Runs the pose design: every grid point through IK on the nominal table (robot base frame),
    /// then the seeded choice of `count` configurations among the measurable ones.
    pub fn design_poses(&self) -> Result<PoseDesign> {
        let grid = &self.poses;
        // IK in the robot base frame: the nominal table with its base at identity.
        let robot = Robot {
            base: Base {
                xyz: Vector3::zeros(),
                rpy: Vector3::zeros(),
            },
            ..self.nominal.clone()
        };
        let home_rotation = robot.flange_frame(&grid.home).0;
        let mut rng = ChaCha8Rng::seed_from_u64(self.seed);
        let options = IkOptions::default();
        let mut points = Vec::new();
        for x in axis_values(grid.x, grid.step) {
            for y in axis_values(grid.y, grid.step) {
                for z in axis_values(grid.z, grid.step) {
                    // Draw the wrist policy for every point, reachable or not, so that the draws
                    // do not depend on which points the IK reaches.
                    let tilt_x = rng.random_range(-1.0..=1.0) * grid.tilt;
                    let tilt_y = rng.random_range(-1.0..=1.0) * grid.tilt;
                    let spin = rng.random_range(-1.0..=1.0) * grid.spin;
                    let azimuth = y.atan2(x);
                    let rotation: Matrix3<f64> =
                        *(Rotation3::from_axis_angle(&Vector3::z_axis(), azimuth)
                            * Rotation3::from_axis_angle(&Vector3::x_axis(), tilt_x)
                            * Rotation3::from_axis_angle(&Vector3::y_axis(), tilt_y))
                        .matrix()
                            * home_rotation
                            * *Rotation3::from_axis_angle(&Vector3::z_axis(), spin).matrix();
                    let position = Vector3::new(x, y, z);
                    // An arm with fewer than six joints cannot take an orientation of its
                    // choosing: it is asked for the position alone.
                    let target = if robot.dof() >= 6 {
                        IkTarget::Pose {
                            point: position,
                            rotation,
                        }
                    } else {
                        IkTarget::Point(position)
                    };
                    let id = format!("g{:03}", points.len() + 1);
                    // The home seed turned towards the point first, then a few elbow and wrist
                    // variations, as an operator jogging to a hard point would.
                    let mut best: Option<(Vec<f64>, f64)> = None;
                    for (d2, d3, d5) in SEED_VARIATIONS {
                        let mut seed = grid.home.clone();
                        seed[0] += azimuth;
                        if seed.len() >= 5 {
                            seed[1] += d2.to_radians();
                            seed[2] += d3.to_radians();
                            seed[4] += d5.to_radians();
                        }
                        let Ok(q) = robot.inverse_kinematics(&target, &seed, &options) else {
                            continue;
                        };
                        let deg: Vec<f64> = q
                            .iter()
                            .map(|v| (v.to_degrees() * 1e4).round() / 1e4)
                            .collect();
                        let rad: Vec<f64> = deg.iter().map(|d| d.to_radians()).collect();
                        if !robot.within_limits(&rad) {
                            continue;
                        }
                        let c = conditioning(&robot, &rad);
                        if best
                            .as_ref()
                            .is_none_or(|(_, bc)| *bc < grid.min_conditioning && c > *bc)
                        {
                            best = Some((deg, c));
                        }
                        if c >= grid.min_conditioning {
                            break;
                        }
                    }
                    let (solution, status, cond) = match best {
                        None => (None, PointStatus::Unreachable, 0.0),
                        Some((deg, c)) if c < grid.min_conditioning => {
                            (Some(deg), PointStatus::NearSingular, c)
                        }
                        Some((deg, c)) => (Some(deg), PointStatus::Kept, c),
                    };
                    points.push(GridPoint {
                        id,
                        position,
                        joints_deg: solution,
                        status,
                        conditioning: cond,
                    });
                }
            }
        }
        let mut measurable: Vec<usize> = (0..points.len())
            .filter(|&i| points[i].status == PointStatus::Kept)
            .collect();
        if measurable.is_empty() {
            return Err(TwinError::NoReachablePose {
                path: self.source.clone(),
            });
        }
        if measurable.len() > grid.count {
            measurable.shuffle(&mut rng);
            for &i in &measurable[grid.count..] {
                points[i].status = PointStatus::NotChosen;
            }
        }
        Ok(PoseDesign { points })
    }
}
