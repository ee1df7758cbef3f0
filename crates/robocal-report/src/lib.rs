//! Pictures and tables of a calibrated model on measured data: the errors before and after, by
//! load, by configuration, their distributions and the predicted spread, as PNG and SVG figures,
//! `statistics.json`, `report.md` and a self-contained `report.html` (`robocal report`,
//! `robocal calibrate --report`); and the drawing primitives the experiments' figures use.
//!
//! It depends on the model ([`robocal_model::CalibratedModel`]) and the data, never on how the
//! model was made.

pub mod data_report;
pub mod error;
pub mod plots;

pub use data_report::{DataReport, DataRole, write_data_report};
pub use error::{ReportError, Result};
