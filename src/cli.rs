//! Command-line arguments (`docs/guide.md` and `docs/formats.md`).

use std::path::PathBuf;

use clap::{Args, Parser, Subcommand};

/// Calibrate industrial robots from laser-tracker measurements (lengths mm, angles deg, mass kg).
#[derive(Debug, Parser)]
#[command(name = "robocal", version, about)]
pub struct Cli {
    /// What to do.
    #[command(subcommand)]
    pub command: Command,
}

/// The model a command predicts with: a calibrated model directory or a plain robot table.
#[derive(Debug, Args)]
#[group(required = true, multiple = false)]
pub struct ModelSource {
    /// Calibrated model directory written by `robocal calibrate`.
    #[arg(long, value_name = "MODEL_DIR")]
    pub model: Option<PathBuf>,
    /// Robot table (robot.toml); the nominal table alone is used.
    #[arg(long, value_name = "ROBOT_TOML")]
    pub robot: Option<PathBuf>,
}

/// Subcommands.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// Identify a calibrated model from measurements and write MODEL_DIR.
    Calibrate {
        /// Nominal robot table (robot.toml).
        #[arg(long, value_name = "ROBOT_TOML")]
        robot: PathBuf,
        /// Training measurements (CSV).
        #[arg(long, value_name = "CSV")]
        data: PathBuf,
        /// Held-out measurements to report the error on (CSV).
        #[arg(long, value_name = "CSV")]
        validate: Option<PathBuf>,
        /// Model directory to write (replaced atomically).
        #[arg(long, value_name = "MODEL_DIR")]
        out: PathBuf,
        /// Stage config (TOML), e.g. configs/stages/kinematic-bfgs.toml.
        #[arg(long, value_name = "STAGE_TOML")]
        config: Option<PathBuf>,
        /// Write the model even when the data do not fit the robot file (positions in inches
        /// or metres, angles in radians, swapped joint columns: refused without it).
        #[arg(long)]
        force: bool,
        /// Keep the bad shots found in the fit (they are still named on stderr and in
        /// report.json).
        #[arg(long)]
        keep_outliers: bool,
        /// Also write the pictures of the calibration on the training data into DIR (as
        /// `robocal report` does; the fit, not the accuracy on new poses).
        #[arg(long, value_name = "DIR")]
        report: Option<PathBuf>,
        /// Weight of a 6-DoF probe's orientation residuals (rows with rx, ry, rz), mm per
        /// degree; default: a stage config's `[kinematic] angle_weight`, else noise_mm /
        /// noise_deg (0.02 / 0.01 = 2).
        #[arg(long, value_name = "MM_PER_DEG")]
        angle_weight: Option<f64>,
        /// Time budget of the default calibration (no `--config`), s: candidates whose folds
        /// would run past it are skipped or abandoned and named in report.json [default: 120]
        #[arg(long, value_name = "SECONDS")]
        budget: Option<f64>,
        /// Keep the default calibration's budget (no `--config`) by counted work instead of
        /// the clock: the same model for the same data and seed on every machine at least as
        /// fast as the reference (2 cores, this project's), where the budget cuts the search;
        /// the clock still ends it at the budget
        #[arg(long)]
        reproducible: bool,
        /// The default calibration (no `--config`) also tries the bearings' tilt under the
        /// gravity moment (a tilting compliance per joint), last, on the physics it chose;
        /// kept only where it lowers the held-out error
        #[arg(long)]
        tilt: bool,
        /// The default calibration (no `--config`) also tries backlash with its flanks searched
        /// where the physics it chose holds none: for a joint whose play rests on the flank its
        /// torque presses and turns at a configuration's lightest or heaviest loads only; kept
        /// only where it lowers the held-out error
        #[arg(long)]
        flank_search: bool,
        /// The highest order of the axis runouts the default calibration (no `--config`) tries
        /// on the physics the joint-error blocks reached (the parts beyond each joint turning
        /// across its axis periodically in its angle; four coefficients per joint and order);
        /// kept only where it lowers the held-out error [default: 2; 0: not tried]
        #[arg(long, value_name = "ORDERS")]
        runout: Option<u32>,
        /// The frame the default calibration's (no `--config`) residual models learn in:
        /// `joint1` (turning with joint 1 about its axis: an error that turns with the arm is
        /// carried to joint-1 angles never measured) or `world` (the tracker's X, Y, Z). Without
        /// it: `joint1`, and both, the held-out poses choosing, where joint 1 lies more than 10°
        /// off the line of gravity (a wall, an inclined pedestal); naming one tries only it
        #[arg(long, value_name = "FRAME")]
        residual_frame: Option<String>,
    },
    /// Predict the target point (world frame) for every row of a CSV.
    Predict {
        /// Which model to use.
        #[command(flatten)]
        source: ModelSource,
        /// Input CSV: pose, q1..qN, load (x, y, z not needed).
        #[arg(long, value_name = "CSV")]
        data: PathBuf,
        /// Output CSV: pose, load, x, y, z (and sigma).
        #[arg(long, value_name = "CSV")]
        out: PathBuf,
        /// Add a column `sigma`: each point's standard deviation, mm (a model with a
        /// Gaussian-process residual: the GP's, with what holding a harmonic beyond its reach
        /// may miss; a network residual: the physics' deviation with the spread its folds
        /// found beside it; a physical model: its identified parameters').
        #[arg(long)]
        sigma: bool,
    },
    /// Compare predictions with measured x, y, z: count, mean, std, RMS, max of the error (mm).
    Evaluate {
        /// Which model to use.
        #[command(flatten)]
        source: ModelSource,
        /// Measurement CSV: pose, q1..qN, load, x, y, z.
        #[arg(long, value_name = "CSV")]
        data: PathBuf,
        /// Also write every row's error: pose, line, load, dx, dy, dz (measured − predicted),
        /// error (mm).
        #[arg(long, value_name = "CSV")]
        per_pose: Option<PathBuf>,
        /// Print one JSON object with keys count, mean, std, rms, max.
        #[arg(long)]
        json: bool,
    },
    /// Joint commands that put the calibrated model's target point on each target.
    Compensate {
        /// Calibrated model directory written by `robocal calibrate`.
        #[arg(long, value_name = "MODEL_DIR")]
        model: PathBuf,
        /// Targets CSV: id, q1..qN (seed command, deg), load, x, y, z (target, mm, in the
        /// frame --frame names).
        #[arg(long, value_name = "CSV")]
        targets: PathBuf,
        /// Output CSV: id, q1..qN (deg), targets that failed left out (and named on stderr).
        #[arg(long, value_name = "CSV")]
        out: PathBuf,
        /// Frame of the targets: `world` (the tracker's, as measured), `base` (the robot base
        /// frame {0} of the calibrated model), or a user-frame file (TOML: `xyz` mm and `rpy`
        /// deg of the user frame in {0}, as a robot controller's user frame).
        #[arg(long, value_name = "world|base|FILE", default_value = "world")]
        frame: String,
        /// The point to put on the targets, in the flange frame, mm (a production tool instead
        /// of the reflector the model was measured with), e.g. `--tool 0,0,250`.
        #[arg(long, value_name = "X,Y,Z", allow_hyphen_values = true)]
        tool: Option<String>,
    },
    /// Generate a digital twin's measurement files (every configuration at every load).
    Simulate {
        /// Twin description (TOML).
        #[arg(long, value_name = "TWIN_TOML")]
        twin: PathBuf,
        /// Output directory (replaced atomically).
        #[arg(long, value_name = "DIR")]
        out: PathBuf,
        /// Measure these poses (`pose,q1..qN,load`, e.g. from `robocal plan`) instead of the
        /// twin's own pose design.
        #[arg(long, value_name = "POSES_CSV")]
        poses: Option<PathBuf>,
    },
    /// Export a calibrated model's kinematic table: a URDF (checked by reading it back and
    /// comparing its forward kinematics with the model's) or a plain JSON MDH/β table with
    /// standard deviations; says what the table cannot carry.
    Export {
        /// Model directory written by `calibrate`.
        #[arg(long, value_name = "MODEL_DIR")]
        model: PathBuf,
        /// `urdf` or `json`.
        #[arg(long, value_name = "FORMAT")]
        format: ExportFormat,
        /// Output file (replaced atomically).
        #[arg(long, value_name = "FILE")]
        out: PathBuf,
        /// Measurements (e.g. the training file) on which to state the error the table alone
        /// leaves beside the whole model's.
        #[arg(long, value_name = "CSV")]
        data: Option<PathBuf>,
    },
    /// The pictures of a calibration on measurements: error histograms before and after, error
    /// per pose, signed error per axis against every joint angle, error against load and over
    /// the workspace (PNG and SVG), report.md, a self-contained report.html and
    /// statistics.json.
    Report {
        /// Model directory written by `calibrate`.
        #[arg(long, value_name = "MODEL_DIR")]
        model: PathBuf,
        /// Measurements (CSV: pose, q1..qN, load, x, y, z), e.g. held-out poses.
        #[arg(long, value_name = "CSV")]
        data: PathBuf,
        /// Report folder (replaced atomically).
        #[arg(long, value_name = "DIR")]
        out: PathBuf,
    },
    /// Choose the configurations to measure (D-optimal for the parameters calibrate will
    /// identify) and say what accuracy they buy: writes POSES_CSV (`pose,q1..qN,load`) and
    /// plan.json beside it, prints the observability indices, every parameter's predicted
    /// standard deviation and the predicted position error, against random sets of the same
    /// size.
    Plan {
        /// Robot file (TOML) with joint limits.
        #[arg(long, value_name = "ROBOT_TOML")]
        robot: PathBuf,
        /// Configurations to choose; a comma list (`20,40,80`) prints the predicted-error
        /// curve and writes the largest set.
        #[arg(long, value_name = "K", value_delimiter = ',', required = true)]
        count: Vec<usize>,
        /// Output pose file (replaced atomically).
        #[arg(long, value_name = "POSES_CSV")]
        out: PathBuf,
        /// Plan settings (TOML): seed, loads, workspace, noise_mm, pool, check, model.
        #[arg(long, value_name = "PLAN_TOML")]
        config: Option<PathBuf>,
        /// Candidate configurations (`pose,q1..qN,load`; x, y, z ignored) instead of random
        /// ones within the joint limits.
        #[arg(long, value_name = "CSV")]
        candidates: Option<PathBuf>,
    },
    /// Run an experiment: its data, split and models; write reports/NAME/ (report.md,
    /// results.json, the resolved experiment, plots) and print the tables.
    Run {
        /// Experiment file (TOML), e.g. configs/experiments/paper.toml.
        #[arg(value_name = "EXPERIMENT_TOML")]
        experiment: PathBuf,
        /// Folder for the report folder, instead of the experiment's `output` (default reports).
        #[arg(long, value_name = "DIR")]
        out: Option<PathBuf>,
    },
}

/// What `robocal export` writes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum ExportFormat {
    /// URDF (metres, radians): base, one revolute joint per table row, the measured point.
    Urdf,
    /// A plain MDH/β table with standard deviations (mm, deg).
    Json,
}
