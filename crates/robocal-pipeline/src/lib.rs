//! Experiments from TOML: the data (a twin or measurement files), the split of the paper's
//! section IV-E, each model's stages in order, and a report with the paper's tables beside ours
//! and its figures redrawn.
//!
//! ```no_run
//! use robocal_data::Silent;
//! use robocal_pipeline::{Experiment, run, write_report};
//!
//! let experiment = Experiment::load("configs/experiments/paper.toml".as_ref())?;
//! let mut outcome = run(&experiment, &Silent)?;
//! let written = write_report(&mut outcome, None)?;
//! println!("{}\nreport in {}", written.tables, written.dir.display());
//! # Ok::<(), robocal_pipeline::PipelineError>(())
//! ```

pub mod error;
pub mod experiment;
pub mod figures;
pub mod paper;
pub mod report;
pub mod run;
pub mod split;

pub use error::{PipelineError, Result};
pub use experiment::{Experiment, ModelPlan, RawExperiment, SplitDesign};
pub use report::{Written, write_report};
pub use robocal_model::CalibratedModel;
pub use run::{Outcome, Summary, run};
pub use split::{Set, Splits};
