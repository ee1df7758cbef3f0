//! Laser-tracker measurement sets for robocal: the CSV of `docs/formats.md` ("Measurements"),
//! validated at load with errors that name the file, line and column; atomic writing of output
//! files.
//!
//! ```
//! # let dir = tempfile::tempdir()?;
//! # let path = dir.path().join("m.csv");
//! std::fs::write(&path, "pose,q1,q2,load,x,y,z\np1,10,20,0,1,2,3\np1,10,20,5,1,2,2.5\n")?;
//! let set = robocal_data::MeasurementSet::read(&path, 2)?;
//! assert_eq!(set.len(), 2);
//! assert_eq!(set.loads(), vec![0.0, 5.0]);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

pub mod atomic;
pub mod csvio;
pub mod error;
pub mod observe;
pub mod order;
pub mod stats;

pub use atomic::{write_atomically, write_dir_atomically, write_text_in};
pub use csvio::{
    Measurement, MeasurementSet, ORIENTATION_COLUMNS, Prediction, Sample, SampleSet, Target,
    check_orientation, check_targets, csv_text, fixed6, read_targets, samples_from_arrays,
    write_predictions,
};
pub use error::{DataError, Invalid, Result, one_of};
pub use observe::{Lines, Observer, Silent};
pub use order::{MOVE_DEADBAND_DEG, set_last_moves};
pub use stats::{ErrorStats, SIGNIFICANCE, improves, robust_std};
