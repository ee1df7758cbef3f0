//! Python bindings of robocal (`import robocal`): robot tables, calibration, prediction,
//! compensation and model directories, numpy arrays in and out, in robocal's units (mm, deg,
//! kg). Every computation is the command line's own (`robocal_calibration::calibrate`,
//! `CalibratedModel::predict_with_sigma`, `robocal_compensate::compensate`), so Python and the
//! command line give the same numbers from the same rows; errors are `robocal.RobocalError`
//! (a `ValueError`) with the command line's messages.
//!
//! Built with maturin (`pip install ./crates/robocal-py`); tested from Python
//! (`crates/robocal-py/tests`, pytest). From Python, on the bundled UR5:
//!
//! ```python
//! import numpy as np, robocal
//! def rows(path):
//!     d = np.genfromtxt(path, delimiter=",", names=True, dtype=None, encoding="utf-8")
//!     q = np.column_stack([d[f"q{k}"] for k in range(1, 7)])
//!     return q, d["load"].astype(float), np.column_stack([d["x"], d["y"], d["z"]])
//! robot = robocal.Robot.load("datasets/ur5/robot.toml")
//! model = robocal.calibrate(robot, *rows("datasets/ur5/grid.csv"))
//! print(model.evaluate(*rows("datasets/ur5/random.csv")))   # error on 20 poses never seen, mm
//! model.save("ur5-model")
//! ```

use std::path::{Path, PathBuf};

use nalgebra::Vector3;
use numpy::ndarray::{Array1, Array2, ArrayView1, ArrayView2};
use numpy::{AllowTypeChange, IntoPyArray, PyArray1, PyArray2, PyArrayLike1, PyArrayLike2};
use pyo3::exceptions::{PyValueError, PyWarning};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use robocal_calibration::{CalibrationInput, Checks, calibrate as run_calibration};
use robocal_calibration::{DefaultOptions, Stages, Summary, message};
use robocal_compensate::{CompensationOptions, compensate};
use robocal_data::{ErrorStats, MeasurementSet, Sample, Silent, samples_from_arrays};
use robocal_model::{CalibratedModel, REPORT_FILE};
use robocal_report::{DataRole, write_data_report};
use robocal_robot::Robot;

pyo3::create_exception!(
    robocal,
    RobocalError,
    PyValueError,
    "A robocal error: bad input (named by file or array, row and column) or a calibration that cannot run."
);

/// The error as robocal's command line words it.
fn fail(err: impl std::error::Error + 'static) -> PyErr {
    RobocalError::new_err(message(&err))
}

/// A shape or argument error.
fn bad(text: String) -> PyErr {
    RobocalError::new_err(text)
}

type Matrix<'py> = PyArrayLike2<'py, f64, AllowTypeChange>;
type Column<'py> = PyArrayLike1<'py, f64, AllowTypeChange>;
/// Commands (rows × joints, deg) and the model's distance from each target (mm).
type Compensated<'py> = (Bound<'py, PyArray2<f64>>, Bound<'py, PyArray1<f64>>);

/// The rows of a (rows × width) array, checking the width.
fn rows_of(a: ArrayView2<f64>, name: &str, width: usize, what: &str) -> PyResult<Vec<Vec<f64>>> {
    if a.ncols() != width {
        return Err(bad(format!(
            "{name}: {} columns, {what} needs {width}",
            a.ncols()
        )));
    }
    Ok(a.rows().into_iter().map(|r| r.to_vec()).collect())
}

/// The loads: one per row, or a single number for every row.
fn loads_of(load: &Bound<'_, PyAny>, rows: usize) -> PyResult<Vec<f64>> {
    if let Ok(v) = load.extract::<f64>() {
        return Ok(vec![v; rows]);
    }
    let column: Column = load.extract()?;
    let v = column.as_array().to_vec();
    if v.len() != rows {
        return Err(bad(format!(
            "load: {} values for {rows} rows (give one per row, or one number)",
            v.len()
        )));
    }
    Ok(v)
}

/// Validated samples of `q` (rows × joints, deg) and `load` (kg), named `source` in messages.
fn samples(
    source: &str,
    q: ArrayView2<f64>,
    load: &Bound<'_, PyAny>,
    dof: usize,
    pose: Option<Vec<String>>,
    target: Option<Vec<String>>,
) -> PyResult<Vec<Sample>> {
    let joints = rows_of(q, "q", dof, &format!("a robot with {dof} joints"))?;
    let loads = loads_of(load, joints.len())?;
    if let Some(p) = &pose
        && p.len() != joints.len()
    {
        return Err(bad(format!(
            "pose: {} ids for {} rows",
            p.len(),
            joints.len()
        )));
    }
    if let Some(t) = &target
        && t.len() != joints.len()
    {
        return Err(bad(format!(
            "target: {} names for {} rows",
            t.len(),
            joints.len()
        )));
    }
    let mut rows = samples_from_arrays(Path::new(source), pose, joints, loads).map_err(fail)?;
    for (row, t) in rows.iter_mut().zip(target.into_iter().flatten()) {
        row.target = t;
    }
    Ok(rows)
}

/// A validated measurement set from arrays.
fn measurements(
    source: &str,
    q: ArrayView2<f64>,
    load: &Bound<'_, PyAny>,
    xyz: ArrayView2<f64>,
    dof: usize,
    pose: Option<Vec<String>>,
    target: Option<Vec<String>>,
) -> PyResult<MeasurementSet> {
    let samples = samples(source, q, load, dof, pose, target)?;
    let points = rows_of(xyz, "xyz", 3, "a point")?;
    if points.len() != samples.len() {
        return Err(bad(format!(
            "xyz: {} rows, q has {}",
            points.len(),
            samples.len()
        )));
    }
    let points = points.into_iter().map(|p| [p[0], p[1], p[2]]).collect();
    MeasurementSet::from_arrays(Path::new(source), samples, points).map_err(fail)
}

/// A TOML number (non-finite values as TOML writes them, so the table's check names the key).
fn number(v: f64) -> String {
    if v.is_nan() {
        "nan".into()
    } else if v.is_infinite() {
        if v > 0.0 { "inf" } else { "-inf" }.into()
    } else {
        format!("{v:?}")
    }
}

fn triple(v: ArrayView1<f64>, name: &str) -> PyResult<String> {
    if v.len() != 3 {
        return Err(bad(format!("{name}: {} values, give 3", v.len())));
    }
    Ok(format!(
        "[{}, {}, {}]",
        number(v[0]),
        number(v[1]),
        number(v[2])
    ))
}

/// A robot's kinematic table: modified DH (MDH) with Hayati β on parallel joints, a base frame
/// in the world (tracker) frame and the measured point (tool) in the flange frame. mm and deg.
#[pyclass(name = "Robot", module = "robocal", frozen)]
struct PyRobot {
    inner: Robot,
}

#[pymethods]
impl PyRobot {
    /// A table from arrays: `mdh` rows (a, alpha, d, theta) per joint, base to tip; `beta` one
    /// per joint (NaN: none); `limits` (joints × 2, deg); base `xyz` (mm) and `rpy` (deg,
    /// fixed-axis) in the world frame; `tool` the measured point in the flange frame (mm);
    /// `points` more reflectors by name (`{"smr2": [x, y, z]}`, flange frame, mm); `tool_rpy` a
    /// 6-DoF probe's frame in the flange frame (fixed-axis roll, pitch, yaw, deg).
    #[new]
    #[pyo3(signature = (mdh, *, beta=None, limits=None, base_xyz=None, base_rpy=None, tool=None, points=None, tool_rpy=None, name="robot"))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        mdh: Matrix,
        beta: Option<Column>,
        limits: Option<Matrix>,
        base_xyz: Option<Column>,
        base_rpy: Option<Column>,
        tool: Option<Column>,
        points: Option<std::collections::BTreeMap<String, Vec<f64>>>,
        tool_rpy: Option<Column>,
        name: &str,
    ) -> PyResult<Self> {
        let table = mdh.as_array();
        if table.ncols() != 4 || table.nrows() == 0 {
            return Err(bad(format!(
                "mdh: {} × {}: give one row (a, alpha, d, theta) per joint",
                table.nrows(),
                table.ncols()
            )));
        }
        let n = table.nrows();
        let beta = beta.map(|b| b.as_array().to_vec());
        if let Some(b) = &beta
            && b.len() != n
        {
            return Err(bad(format!(
                "beta: {} values for {n} joints (NaN where none)",
                b.len()
            )));
        }
        let limits = limits.map(|l| l.as_array().to_owned());
        if let Some(l) = &limits
            && (l.nrows() != n || l.ncols() != 2)
        {
            return Err(bad(format!(
                "limits: {} × {}, give {n} × 2 (min, max deg)",
                l.nrows(),
                l.ncols()
            )));
        }
        let mut text = format!("name = {}\n", toml::Value::String(name.to_string()));
        for (j, row) in table.rows().into_iter().enumerate() {
            text += &format!(
                "\n[[joint]]\na = {}\nalpha = {}\nd = {}\ntheta = {}\n",
                number(row[0]),
                number(row[1]),
                number(row[2]),
                number(row[3])
            );
            if let Some(b) = beta.as_ref().map(|b| b[j]).filter(|b| !b.is_nan()) {
                text += &format!("beta = {}\n", number(b));
            }
            if let Some(l) = &limits {
                text += &format!("limits = [{}, {}]\n", number(l[[j, 0]]), number(l[[j, 1]]));
            }
        }
        let zero = || Array1::<f64>::zeros(3);
        let xyz = base_xyz.map_or_else(zero, |v| v.as_array().to_owned());
        let rpy = base_rpy.map_or_else(zero, |v| v.as_array().to_owned());
        let tool = tool.map_or_else(zero, |v| v.as_array().to_owned());
        text += &format!(
            "\n[base]\nxyz = {}\nrpy = {}\n\n[tool]\nxyz = {}\n",
            triple(xyz.view(), "base_xyz")?,
            triple(rpy.view(), "base_rpy")?,
            triple(tool.view(), "tool")?
        );
        if let Some(r) = tool_rpy {
            text += &format!("rpy = {}\n", triple(r.as_array(), "tool_rpy")?);
        }
        if let Some(points) = points.filter(|p| !p.is_empty()) {
            text += "\n[tool.points]\n";
            for (n, p) in points {
                let key = toml::Value::String(n.clone()).to_string();
                let p = Array1::from(p);
                text += &format!("{key} = {}\n", triple(p.view(), &format!("points[{n}]"))?);
            }
        }
        Robot::from_toml_str(&text, "(arrays)")
            .map(|inner| Self { inner })
            .map_err(fail)
    }

    /// Reads a robot file (robot.toml).
    #[staticmethod]
    fn load(path: PathBuf) -> PyResult<Self> {
        Robot::load(&path).map(|inner| Self { inner }).map_err(fail)
    }

    /// The table of a URDF's serial chain from link `base` to link `tip` (defaults: its root and
    /// its one leaf), the measured point at the tip link's origin or at `tool` (mm, tip link's
    /// frame): the same forward kinematics at the same joint readings, in the base link's frame
    /// (`robocal import --urdf`).
    #[staticmethod]
    #[pyo3(signature = (path, *, base=None, tip=None, tool=None))]
    fn from_urdf(
        path: PathBuf,
        base: Option<&str>,
        tip: Option<&str>,
        tool: Option<Column>,
    ) -> PyResult<Self> {
        let tool = tool
            .map(|t| {
                triple(t.as_array(), "tool")
                    .map(|_| Vector3::from_iterator(t.as_array().iter().copied()))
            })
            .transpose()?;
        robocal_model::import::robot_from_urdf_file(&path, base, tip, tool)
            .map(|inner| Self { inner })
            .map_err(bad)
    }

    /// The table of a DH table typed from a manual: a CSV of `d, a, alpha, theta` per joint (mm,
    /// deg), `convention` `"standard"` or `"modified"`, the measured point at `tool` (mm, in the
    /// last DH frame; default its origin) (`robocal import --dh`).
    #[staticmethod]
    #[pyo3(signature = (path, convention, *, tool=None))]
    fn from_dh(path: PathBuf, convention: &str, tool: Option<Column>) -> PyResult<Self> {
        use robocal_model::import::{Convention, read_dh, robot_from_dh};
        let convention = match convention {
            "standard" => Convention::Standard,
            "modified" => Convention::Modified,
            other => {
                return Err(bad(format!(
                    "convention: `{other}`: give \"standard\" or \"modified\""
                )));
            }
        };
        let tool = match tool {
            Some(t) => {
                triple(t.as_array(), "tool")?;
                Vector3::from_iterator(t.as_array().iter().copied())
            }
            None => Vector3::zeros(),
        };
        let rows = read_dh(&path).map_err(bad)?;
        let name = path
            .file_stem()
            .map_or("robot".into(), |s| s.to_string_lossy().into_owned());
        Ok(Self {
            inner: robot_from_dh(&name, &rows, convention, tool),
        })
    }

    /// Joints.
    #[getter]
    fn dof(&self) -> usize {
        self.inner.dof()
    }

    /// The table's name.
    #[getter]
    fn name(&self) -> String {
        self.inner.name.clone()
    }

    /// The measured point in the world frame for each row of `q` (rows × joints, deg): rows × 3,
    /// mm; of the named point `target` when given.
    #[pyo3(signature = (q, target=""))]
    fn forward<'py>(
        &self,
        py: Python<'py>,
        q: Matrix<'py>,
        target: &str,
    ) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let dof = self.inner.dof();
        let what = format!("a robot with {dof} joints");
        let rows = rows_of(q.as_array(), "q", dof, &what)?;
        let t = self.inner.target_index(target).ok_or_else(|| {
            let names = self.inner.point_names();
            bad(format!(
                "target: no point `{target}` (the robot's points: {})",
                names.join(", ")
            ))
        })?;
        let robot = self.inner.for_target(t);
        let mut out = Array2::zeros((rows.len(), 3));
        for (i, r) in rows.iter().enumerate() {
            let rad: Vec<f64> = r.iter().map(|d| d.to_radians()).collect();
            let p = robot.point(&rad);
            for a in 0..3 {
                out[[i, a]] = p[a];
            }
        }
        Ok(out.into_pyarray(py))
    }

    /// The table as a robot file's text.
    fn to_toml(&self) -> String {
        self.inner.to_toml_string()
    }

    /// Writes the table as a robot file.
    fn save(&self, path: PathBuf) -> PyResult<()> {
        std::fs::write(&path, self.inner.to_toml_string())
            .map_err(|e| bad(format!("{}: cannot write: {e}", path.display())))
    }

    fn __repr__(&self) -> String {
        format!("Robot({:?}, {} joints)", self.inner.name, self.inner.dof())
    }
}

/// A calibrated model: the identified table, its joint errors and residual model, as a model
/// directory holds them.
#[pyclass(name = "Model", module = "robocal", frozen)]
struct PyModel {
    inner: CalibratedModel,
    /// `report.json` without its layout stamp (what `save` writes back).
    report: serde_json::Value,
    /// The calibration's summary, for a model `calibrate` made.
    summary: Option<String>,
}

/// `report.json` of a model directory without the two keys `save` stamps.
fn read_report(dir: &Path) -> PyResult<serde_json::Value> {
    let file = dir.join(REPORT_FILE);
    let text = std::fs::read_to_string(&file)
        .map_err(|e| bad(format!("{}: cannot read: {e}", file.display())))?;
    let mut value: serde_json::Value = serde_json::from_str(&text)
        .map_err(|e| bad(format!("{}: invalid JSON: {e}", file.display())))?;
    if let Some(map) = value.as_object_mut() {
        map.remove("model_format");
        map.remove("robocal_version");
    }
    Ok(value)
}

/// `set` with a 6-DoF probe's orientations (rows × 3, deg) when given.
fn with_rpy(set: MeasurementSet, rpy: Option<Matrix<'_>>) -> PyResult<MeasurementSet> {
    let Some(rpy) = rpy else {
        return Ok(set);
    };
    let rows = rows_of(
        rpy.as_array(),
        "rpy",
        3,
        "an orientation (roll, pitch, yaw)",
    )?;
    if rows.len() != set.rows.len() {
        return Err(bad(format!(
            "rpy: {} rows, q has {}",
            rows.len(),
            set.rows.len()
        )));
    }
    set.with_orientations(rows.into_iter().map(|r| [r[0], r[1], r[2]]).collect())
        .map_err(fail)
}

fn stats_dict<'py>(py: Python<'py>, s: &ErrorStats) -> PyResult<Bound<'py, pyo3::types::PyDict>> {
    let d = pyo3::types::PyDict::new(py);
    d.set_item("count", s.count)?;
    d.set_item("mean", s.mean)?;
    d.set_item("std", s.std)?;
    d.set_item("rms", s.rms)?;
    d.set_item("max", s.max)?;
    Ok(d)
}

/// A Python warning when rows (`what`: the argument's name) lie outside the joint readings and
/// loads `model` was calibrated on: predictions there are extrapolation.
fn warn_outside<'a>(
    py: Python<'_>,
    model: &CalibratedModel,
    what: &str,
    rows: impl IntoIterator<Item = &'a Sample>,
) -> PyResult<()> {
    let rows: Vec<&Sample> = rows.into_iter().collect();
    let file = Path::new(what);
    let warnings = [
        (model.domain.as_ref()).and_then(|d| d.warning(file, rows.iter().copied())),
        (model.motion.as_ref()).and_then(|m| m.warning(file, rows.iter().copied())),
    ];
    for w in warnings.into_iter().flatten() {
        let text = std::ffi::CString::new(w).unwrap_or_default();
        PyErr::warn(py, &py.get_type::<PyWarning>(), &text, 1)?;
    }
    Ok(())
}

#[pymethods]
impl PyModel {
    /// Reads a model directory written by `robocal calibrate` or `Model.save`.
    #[staticmethod]
    fn load(dir: PathBuf) -> PyResult<Self> {
        let inner = CalibratedModel::load(&dir).map_err(fail)?;
        let report = read_report(&dir)?;
        Ok(Self {
            inner,
            report,
            summary: None,
        })
    }

    /// Writes the model directory (atomically: a complete new directory, or nothing).
    fn save(&self, dir: PathBuf) -> PyResult<()> {
        self.inner.save(&dir, &self.report).map_err(fail)
    }

    /// Joints.
    #[getter]
    fn dof(&self) -> usize {
        self.inner.dof()
    }

    /// The identified table.
    #[getter]
    fn robot(&self) -> PyRobot {
        PyRobot {
            inner: self.inner.robot.clone(),
        }
    }

    /// The joint readings and loads the model was calibrated on: `(joints, load)`, `joints` one
    /// `[low, high]` per joint (deg), `load` `[lightest, heaviest]` (kg); `None` for a model
    /// directory written without it. `predict`, `evaluate` and `compensate` warn of rows outside.
    #[getter]
    fn domain(&self) -> Option<(Vec<[f64; 2]>, [f64; 2])> {
        (self.inner.domain.as_ref()).map(|d| (d.joints.clone(), d.load))
    }

    /// The summary `robocal calibrate` ends with (the model chosen, its held-out error, the fit,
    /// the time, the warnings that matter most), for a model `calibrate` made; `None` for one
    /// read from a directory (its `report.json` holds the same).
    #[getter]
    fn summary(&self) -> Option<String> {
        self.summary.clone()
    }

    /// `report.json` as text (JSON): what ran, the statistics, every parameter with σ.
    #[getter]
    fn report(&self) -> String {
        serde_json::to_string_pretty(&self.report).unwrap_or_default()
    }

    /// The predicted point (world frame, mm) for each row of `q` (rows × joints, deg) under
    /// `load` (kg: one per row or one number). With `sigma=True`, also each point's standard
    /// deviation (mm; a model with a Gaussian-process residual: the GP's; a network the default
    /// calibration chose: the physics' with the network's spread; a physical model: its
    /// identified parameters'): `(points, sigma)`. `target`:
    /// one point name per row (`[tool.points]`; empty: the default point).
    #[pyo3(signature = (q, load, sigma=false, *, target=None))]
    fn predict<'py>(
        &self,
        py: Python<'py>,
        q: Matrix<'py>,
        load: &Bound<'py, PyAny>,
        sigma: bool,
        target: Option<Vec<String>>,
    ) -> PyResult<Bound<'py, PyAny>> {
        let rows = samples("q", q.as_array(), load, self.inner.dof(), None, target)?;
        self.inner
            .check_targets(Path::new("q"), &rows)
            .map_err(fail)?;
        warn_outside(py, &self.inner, "q", &rows)?;
        let (points, sigmas) = py.detach(|| self.inner.predict_with_sigma(&rows, sigma));
        let mut out = Array2::zeros((points.len(), 3));
        for (i, p) in points.iter().enumerate() {
            for a in 0..3 {
                out[[i, a]] = p[a];
            }
        }
        let out = out.into_pyarray(py).into_any();
        if !sigma {
            return Ok(out);
        }
        let s = sigmas.ok_or_else(|| {
            bad("sigma: this model gives no standard deviation (a model with a Gaussian-process residual gives the GP's, a physical model its parameters' covariance's; a network residual gives none, and a model directory without covariance.json has no covariance)".into())
        })?;
        Ok((out, Array1::from(s).into_pyarray(py))
            .into_pyobject(py)?
            .into_any())
    }

    /// The predicted orientation of the tool frame (a 6-DoF probe's; world frame, fixed-axis
    /// roll, pitch, yaw, deg) for each row of `q` (deg) under `load`: rows × 3.
    fn orientation<'py>(
        &self,
        py: Python<'py>,
        q: Matrix<'py>,
        load: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let rows = samples("q", q.as_array(), load, self.inner.dof(), None, None)?;
        let mut out = Array2::zeros((rows.len(), 3));
        for (i, s) in rows.iter().enumerate() {
            let a = self.inner.orientation_deg(s);
            for k in 0..3 {
                out[[i, k]] = a[k];
            }
        }
        Ok(out.into_pyarray(py))
    }

    /// Error statistics (mm) against measured points `xyz` (rows × 3): a dict with count, mean,
    /// std, rms, max, as `robocal evaluate --json` prints. `target` as in `predict`; with `rpy`
    /// (a 6-DoF probe's measured orientations, rows × 3, deg) also `orientation_deg`, the
    /// statistics of the angle between measured and predicted tool frames.
    #[pyo3(signature = (q, load, xyz, *, target=None, rpy=None))]
    fn evaluate<'py>(
        &self,
        py: Python<'py>,
        q: Matrix<'py>,
        load: &Bound<'py, PyAny>,
        xyz: Matrix<'py>,
        target: Option<Vec<String>>,
        rpy: Option<Matrix<'py>>,
    ) -> PyResult<Bound<'py, pyo3::types::PyDict>> {
        let set = with_rpy(
            measurements(
                "q",
                q.as_array(),
                load,
                xyz.as_array(),
                self.inner.dof(),
                None,
                target,
            )?,
            rpy,
        )?;
        self.inner
            .check_targets(&set.source, set.rows.iter().map(|m| &m.sample))
            .map_err(fail)?;
        warn_outside(py, &self.inner, "q", set.rows.iter().map(|m| &m.sample))?;
        let rows: Vec<_> = set.rows.iter().collect();
        let d = stats_dict(py, &self.inner.stats(&rows))?;
        if set.has_orientation() {
            let angles = ErrorStats::from_errors(&self.inner.orientation_errors(&rows));
            d.set_item("orientation_deg", stats_dict(py, &angles)?)?;
        }
        Ok(d)
    }

    /// Joint commands (rows × joints, deg) that put the model's point on each target (rows × 3,
    /// mm) under `load`, starting from `seed` (the program's commands, deg). `frame`: `world`
    /// (the tracker's, as measured) or `base` (the calibrated base frame); `tool`: a production
    /// tool point in the flange frame (mm) instead of the reflector. Returns `(commands,
    /// model_error)`; a target that cannot be reached gets NaN and a warning naming it. With
    /// several reflectors, `target` names the point each row puts on its target.
    #[pyo3(signature = (targets, seed, load, frame="world", tool=None, *, target=None))]
    #[allow(clippy::too_many_arguments)]
    fn compensate<'py>(
        &self,
        py: Python<'py>,
        targets: Matrix<'py>,
        seed: Matrix<'py>,
        load: &Bound<'py, PyAny>,
        frame: &str,
        tool: Option<Column<'py>>,
        target: Option<Vec<String>>,
    ) -> PyResult<Compensated<'py>> {
        let dof = self.inner.dof();
        let rows = samples("seed", seed.as_array(), load, dof, None, target)?;
        self.inner
            .check_targets(Path::new("seed"), &rows)
            .map_err(fail)?;
        let points = rows_of(targets.as_array(), "targets", 3, "a point")?;
        if points.len() != rows.len() {
            return Err(bad(format!(
                "targets: {} rows, seed has {}",
                points.len(),
                rows.len()
            )));
        }
        let mut model = self.inner.clone();
        if let Some(t) = tool {
            let t = t.as_array();
            if t.len() != 3 || !t.iter().all(|v| v.is_finite()) {
                return Err(bad(
                    "tool: give three finite numbers x, y, z (mm, flange frame)".into(),
                ));
            }
            model.robot.tool = Vector3::new(t[0], t[1], t[2]);
        }
        let (rotation, origin) = match frame {
            "world" => (nalgebra::Matrix3::identity(), Vector3::zeros()),
            "base" => (model.robot.base_rotation(), model.robot.base.xyz),
            other => {
                return Err(bad(format!("frame: `{other}`: give `world` or `base`")));
            }
        };
        let options = CompensationOptions::default();
        let results: Vec<_> = py.detach(|| {
            rows.iter()
                .zip(&points)
                .map(|(s, p)| {
                    let target = rotation * Vector3::new(p[0], p[1], p[2]) + origin;
                    let measuring = model.for_target(&s.target);
                    compensate(&measuring, &target, s.load, &s.joints, &options)
                })
                .collect()
        });
        let mut commands = Array2::from_elem((rows.len(), dof), f64::NAN);
        let mut errors = Array1::from_elem(rows.len(), f64::NAN);
        let mut failed = Vec::new();
        let mut reached = Vec::new();
        for (i, r) in results.into_iter().enumerate() {
            match r {
                Ok(c) => {
                    for (j, v) in c.joints_deg.iter().enumerate() {
                        commands[[i, j]] = *v;
                    }
                    errors[i] = c.model_error;
                    reached.push(Sample {
                        joints: c.joints_deg,
                        ..rows[i].clone()
                    });
                }
                Err(why) => failed.push(format!("row {}: {why}", i + 1)),
            }
        }
        // The commands are the readings the model is applied at.
        warn_outside(py, &self.inner, "commands", &reached)?;
        if !failed.is_empty() {
            let text = std::ffi::CString::new(format!(
                "{} target(s) could not be compensated (NaN): {}",
                failed.len(),
                failed.join("; ")
            ))
            .unwrap_or_default();
            PyErr::warn(py, &py.get_type::<PyWarning>(), &text, 1)?;
        }
        Ok((commands.into_pyarray(py), errors.into_pyarray(py)))
    }

    /// Writes the pictures of the model on measurements into the folder `out` (as
    /// `robocal report`): histograms, per pose, per axis against every joint, against load,
    /// over the workspace; report.md, report.html, statistics.json. Returns statistics.json's
    /// text.
    #[pyo3(signature = (q, load, xyz, out, training=false))]
    fn write_report<'py>(
        &self,
        py: Python<'py>,
        q: Matrix<'py>,
        load: &Bound<'py, PyAny>,
        xyz: Matrix<'py>,
        out: PathBuf,
        training: bool,
    ) -> PyResult<String> {
        let set = measurements(
            "(arrays)",
            q.as_array(),
            load,
            xyz.as_array(),
            self.inner.dof(),
            None,
            None,
        )?;
        let role = if training {
            DataRole::Training
        } else {
            DataRole::HeldOut
        };
        let report = py
            .detach(|| {
                let rows: Vec<_> = set.rows.iter().collect();
                write_data_report(&self.inner, "(Python)", &set.source, &rows, role, &out)
            })
            .map_err(fail)?;
        serde_json::to_string_pretty(&report).map_err(|e| bad(e.to_string()))
    }

    fn __repr__(&self) -> String {
        let mut parts = vec![format!("{} joints", self.inner.dof())];
        if self.inner.joint_errors.is_some() {
            parts.push("joint errors".into());
        }
        if let Some(r) = &self.inner.residual {
            parts.push(format!("{} residual", r.kind().name()));
        }
        format!("Model({})", parts.join(", "))
    }
}

/// Calibrates `robot` on measurements: joint readings `q` (rows × joints, deg), `load` (kg, one
/// per row or one number), measured points `xyz` (rows × 3, mm, tracker frame). As `robocal
/// calibrate`: the default chooses the stages by cross-validation; `config` a stage file;
/// `validate` a `(q, load, xyz)` tuple of held-out rows; `force` makes a model from data that
/// do not fit the robot file; `keep_outliers` keeps the bad shots. Rows with the same joint
/// readings are one configuration (or give `pose`, one id per row, as the CSV's `pose` column);
/// with several reflectors, `target` names each row's point (`[tool.points]`; empty: default);
/// a 6-DoF probe's orientations go in `rpy` (rows × 3, fixed-axis roll, pitch, yaw, deg).
/// The default calibration's options are keyword arguments named as the command line's
/// (`robocal calibrate --help`) and a stage file's `[default]`: `angle_weight` (mm per deg,
/// default 2: a 6-DoF probe's orientations), `budget` (s, default 120), `reproducible` (the
/// budget kept by counted work instead of the clock: the same model on every machine as fast as
/// the reference or faster), `tilt` (also try the bearings' tilt), `flank_search` (backlash
/// with its flanks searched where the physics it chose holds none), `runout` (the highest order
/// of the axis runouts tried; default 2, 0: none), `residual_frame` (`"joint1"` or `"world"`:
/// the frame its residual models learn in; by default `"joint1"`, and both, the held-out poses
/// choosing, where joint 1 lies more than 10° off the line of gravity).
/// The interpreter is free to run other threads meanwhile.
#[pyfunction]
#[pyo3(signature = (robot, q, load, xyz, *, config=None, validate=None, force=false, keep_outliers=false, pose=None, target=None, rpy=None, **options))]
#[allow(clippy::too_many_arguments)]
fn calibrate<'py>(
    py: Python<'py>,
    robot: &PyRobot,
    q: Matrix<'py>,
    load: &Bound<'py, PyAny>,
    xyz: Matrix<'py>,
    config: Option<PathBuf>,
    validate: Option<(Matrix<'py>, Bound<'py, PyAny>, Matrix<'py>)>,
    force: bool,
    keep_outliers: bool,
    pose: Option<Vec<String>>,
    target: Option<Vec<String>>,
    rpy: Option<Matrix<'py>>,
    options: Option<&Bound<'py, PyDict>>,
) -> PyResult<PyModel> {
    let started = std::time::Instant::now();
    let options = default_options(options)?;
    let dof = robot.inner.dof();
    let data = with_rpy(
        measurements(
            "(arrays)",
            q.as_array(),
            load,
            xyz.as_array(),
            dof,
            pose,
            target,
        )?,
        rpy,
    )?;
    let validation = validate
        .map(|(q, load, xyz)| {
            measurements(
                "(validation arrays)",
                q.as_array(),
                &load,
                xyz.as_array(),
                dof,
                None,
                None,
            )
        })
        .transpose()?;
    let stages = config
        .as_ref()
        .map(|c| Stages::load(c))
        .transpose()
        .map_err(fail)?;
    let calibration = py
        .detach(|| {
            let input = CalibrationInput {
                nominal: &robot.inner,
                robot_file: Path::new("(Python)"),
                data: &data,
                validation: validation.as_ref(),
                stages: stages.as_ref().zip(config.as_deref()),
                checks: Checks {
                    force,
                    keep_outliers,
                },
                options: &options,
            };
            run_calibration(&input, &Silent)
        })
        .map_err(fail)?;
    if let Some(why) = &calibration.implausible {
        let text =
            std::ffi::CString::new(format!("{why} (made anyway: force=True)")).unwrap_or_default();
        PyErr::warn(py, &py.get_type::<PyWarning>(), &text, 1)?;
    }
    let report = serde_json::to_value(&calibration.report).map_err(|e| bad(e.to_string()))?;
    let summary = Summary::new(&calibration.report, None, started.elapsed().as_secs_f64());
    Ok(PyModel {
        inner: calibration.model,
        report,
        summary: Some(summary.to_string()),
    })
}

/// The default calibration's options from `calibrate`'s keyword arguments, read as the stage
/// file's `[default]` table is (an unknown name or a value of the wrong kind is refused, named).
/// Each value is taken as Python gives it — None, a bool, a whole number (numpy's too), a finite
/// number or a string — and the spec decides what it may be.
fn default_options(options: Option<&Bound<'_, PyDict>>) -> PyResult<DefaultOptions> {
    let Some(options) = options else {
        return Ok(DefaultOptions::default());
    };
    let mut table = serde_json::Map::new();
    for (name, value) in options.iter() {
        let name: String = name.extract()?;
        let value = if value.is_none() {
            serde_json::Value::Null
        } else if let Ok(b) = value.extract::<bool>() {
            b.into()
        } else if let Ok(i) = value.extract::<i64>() {
            i.into()
        } else if let Ok(x) = value.extract::<f64>() {
            serde_json::Number::from_f64(x)
                .ok_or_else(|| bad(format!("calibrate: {name}: {x} is not a finite number")))?
                .into()
        } else if let Ok(s) = value.extract::<String>() {
            s.into()
        } else {
            return Err(bad(format!(
                "calibrate: {name}: {} is not a bool, a number or a string",
                value.repr()?
            )));
        };
        table.insert(name, value);
    }
    serde_json::from_value(table.into()).map_err(|e| bad(format!("calibrate: {e}")))
}

/// robocal: calibrate industrial robots from laser-tracker measurements (mm, deg, kg).
#[pymodule]
#[pyo3(name = "robocal")]
fn robocal_module(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyRobot>()?;
    m.add_class::<PyModel>()?;
    m.add_function(wrap_pyfunction!(calibrate, m)?)?;
    m.add("RobocalError", m.py().get_type::<RobocalError>())?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
