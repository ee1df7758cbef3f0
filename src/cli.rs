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
        /// Write the model even when the data do not fit the robot file (units, joint order).
        #[arg(long)]
        force: bool,
        /// Keep the bad shots found (still named on stderr and in report.json).
        #[arg(long)]
        keep_outliers: bool,
        /// Also write `robocal report`'s pictures of the fit on the training rows into DIR.
        #[arg(long, value_name = "DIR")]
        report: Option<PathBuf>,
        /// The default calibration's options.
        #[command(flatten)]
        options: robocal_calibration::DefaultOptions,
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
        /// Add a column `sigma`: each point's standard deviation, mm.
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
        /// Also write every row's error (measured − predicted, mm) to this CSV.
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
        /// Frame of the targets: `world` (the tracker's), `base`, or a user-frame TOML file.
        #[arg(long, value_name = "world|base|FILE", default_value = "world")]
        frame: String,
        /// The point to put on the targets, flange frame, mm (e.g. `--tool 0,0,250`).
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
        /// Measure these poses (`pose,q1..qN,load`, e.g. from `robocal plan`).
        #[arg(long, value_name = "POSES_CSV")]
        poses: Option<PathBuf>,
    },
    /// Export the calibrated kinematic table as URDF or JSON (with standard deviations).
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
        /// Measurements on which to state the error the table alone leaves.
        #[arg(long, value_name = "CSV")]
        data: Option<PathBuf>,
    },
    /// Write a robot file from a URDF's serial chain or a DH table typed from a manual.
    Import {
        /// A URDF: the revolute chain from the base link to the tip link.
        #[arg(
            long,
            value_name = "URDF",
            required_unless_present = "dh",
            conflicts_with = "dh"
        )]
        urdf: Option<PathBuf>,
        /// A DH table (CSV: d, a, alpha, theta per joint; mm, deg).
        #[arg(long, value_name = "CSV", requires = "convention")]
        dh: Option<PathBuf>,
        /// How the DH table is meant: `standard` (distal) or `modified` (Craig's, robocal's).
        #[arg(long, value_name = "CONVENTION")]
        convention: Option<DhConvention>,
        /// The URDF link the chain starts from (default: its root link).
        #[arg(long, value_name = "LINK", conflicts_with = "dh")]
        base: Option<String>,
        /// The URDF link the chain ends at (default: its one leaf link).
        #[arg(long, value_name = "LINK", conflicts_with = "dh")]
        tip: Option<String>,
        /// The measured point in the tip link's frame (URDF) or the last DH frame, mm.
        #[arg(long, value_name = "X,Y,Z", allow_hyphen_values = true)]
        tool: Option<String>,
        /// The robot file to write (replaced atomically).
        #[arg(long, value_name = "ROBOT_TOML")]
        out: PathBuf,
    },
    /// Figures and tables of a calibrated model on measurements (report.html, PNG, SVG).
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
    /// Choose the configurations to measure (I-optimal by default) and predict their error.
    Plan {
        /// Robot file (TOML) with joint limits.
        #[arg(long, value_name = "ROBOT_TOML")]
        robot: PathBuf,
        /// Configurations to choose; a comma list (`20,40,80`) prints the curve.
        #[arg(long, value_name = "K", value_delimiter = ',', required = true)]
        count: Vec<usize>,
        /// Output pose file (replaced atomically).
        #[arg(long, value_name = "POSES_CSV")]
        out: PathBuf,
        /// Plan settings (TOML): seed, loads, workspace, noise_mm, pool, check, model.
        #[arg(long, value_name = "PLAN_TOML")]
        config: Option<PathBuf>,
        /// Candidate configurations (`pose,q1..qN,load`) instead of random ones.
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

/// How a DH table typed from a manual is meant.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum DhConvention {
    /// Standard (distal) DH: `RotZ(θ + q) TransZ(d) TransX(a) RotX(α)` per joint.
    Standard,
    /// Modified (proximal, Craig's) DH: `RotX(α) TransX(a) RotZ(θ + q) TransZ(d)` per joint.
    Modified,
}

/// What `robocal export` writes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum ExportFormat {
    /// URDF (metres, radians): base, one revolute joint per table row, the measured point.
    Urdf,
    /// A plain MDH/β table with standard deviations (mm, deg).
    Json,
}
