//! The digital twin of a robot measured by a laser tracker.
//!
//! A "true robot" — a geometry that differs from the nominal table, joint compliance under the
//! gravity of its links and payload, gear transmission errors, backlash, measurement noise —
//! produces the measurement files a real tracker session would. The joint readings in the files
//! are the controller's (motor side); every non-geometric effect acts on the arm, not on them.
//! Everything is seeded and byte-for-byte deterministic.
//!
//! ```no_run
//! let twin = robocal_twin::TwinConfig::load("configs/twin/pmc6va030.toml")?;
//! let data = twin.generate()?;
//! println!("{} rows", data.measurements.len());
//! # Ok::<(), robocal_twin::TwinError>(())
//! ```

pub mod config;
pub mod design;
pub mod error;
pub mod generate;
pub mod physics;

pub use config::{
    Backlash, BacklashSide, Beyond, Gear, Loads, Masses, Noise, PoseGrid, Stiffness, TwinConfig,
};
pub use design::{GridPoint, PointStatus, PoseDesign};
pub use error::{Result, TwinError};
pub use generate::TwinDataset;
