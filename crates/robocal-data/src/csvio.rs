//! Reading and writing the measurement CSV of `docs/formats.md` ("Measurements").

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use nalgebra::Vector3;

use crate::atomic::write_atomically;
use crate::error::{DataError, Result};

/// One configuration under one load: what the controller reports, without a measured position.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Sample {
    /// Configuration id (`pose` column, or `id` for targets).
    pub pose: String,
    /// Joint readings from the controller, degrees, one per joint.
    pub joints: Vec<f64>,
    /// Payload mass at the end effector, kg (≥ 0).
    pub load: f64,
    /// 1-based line of the row in its file (0 when made in memory).
    pub line: u64,
    /// The point the row measures (`target` column): a name from the robot file's
    /// `[tool.points]`, or empty for the default point (`[tool] xyz`).
    pub target: String,
    /// Place in the order of measurement (`seq` column); rows of one pose share it. `None`
    /// where the file gives no order.
    pub seq: Option<i64>,
    /// The direction each joint last moved in before this row (`+1`, `−1`, or `0` before its
    /// first move), from the rows' `seq` ([`crate::order::set_last_moves`]); empty without an
    /// order.
    pub last_move: Vec<f64>,
}

impl Sample {
    /// Joint readings in radians, for the kinematics.
    pub fn joints_rad(&self) -> Vec<f64> {
        self.joints.iter().map(|d| d.to_radians()).collect()
    }
}

/// A measured row: a [`Sample`] and the tracker's reading of the target point.
#[derive(Debug, Clone, PartialEq)]
pub struct Measurement {
    /// Configuration, load and provenance.
    pub sample: Sample,
    /// Measured target position, mm, world (tracker) frame.
    pub position: Vector3<f64>,
    /// Measured orientation of the tool frame (a 6-DoF probe's `rx, ry, rz`), fixed-axis roll,
    /// pitch, yaw in the world frame, deg; `None` for a row without.
    pub orientation: Option<Vector3<f64>>,
}

/// The orientation columns of a 6-DoF probe, in order.
pub const ORIENTATION_COLUMNS: [&str; 3] = ["rx", "ry", "rz"];

/// Largest magnitude of a roll or yaw, deg (both ±180 and 0..360 conventions pass).
pub const ROLL_YAW_LIMIT: f64 = 360.0;

/// Largest magnitude of a pitch, deg (fixed-axis roll-pitch-yaw puts pitch in [−90, 90]).
pub const PITCH_LIMIT: f64 = 90.0;

/// A measured orientation (`rx, ry, rz`, deg) checked against its ranges: roll and yaw within
/// ±[`ROLL_YAW_LIMIT`], pitch within ±[`PITCH_LIMIT`]; non-finite or out of range is an error
/// naming `path`, `line` and the column.
pub fn check_orientation(path: &Path, line: u64, angles: [f64; 3]) -> Result<Vector3<f64>> {
    for (k, &value) in angles.iter().enumerate() {
        let column = ORIENTATION_COLUMNS[k].to_string();
        if !value.is_finite() {
            return Err(DataError::NonFinite {
                path: path.to_path_buf(),
                line,
                column,
                value: value.to_string(),
            });
        }
        let (limit, range) = if k == 1 {
            (PITCH_LIMIT, "pitch within ±90")
        } else {
            (ROLL_YAW_LIMIT, "within ±360")
        };
        if value.abs() > limit {
            return Err(DataError::AngleOutOfRange {
                path: path.to_path_buf(),
                line,
                column,
                value,
                range,
            });
        }
    }
    Ok(Vector3::from(angles))
}

/// A validated measurement file: rows in file order.
#[derive(Debug, Clone, PartialEq)]
pub struct MeasurementSet {
    /// Where the rows came from (for messages and reports).
    pub source: PathBuf,
    /// Number of joints of every row.
    pub joint_count: usize,
    /// Rows in file order.
    pub rows: Vec<Measurement>,
}

/// A validated file of samples without (or ignoring) positions: input of `predict`.
#[derive(Debug, Clone, PartialEq)]
pub struct SampleSet {
    /// Where the rows came from.
    pub source: PathBuf,
    /// Number of joints of every row.
    pub joint_count: usize,
    /// Rows in file order.
    pub rows: Vec<Sample>,
    /// Whether the file has the orientation columns `rx, ry, rz` (then `predict` writes them).
    pub orientation: bool,
}

/// A compensation target: a seed command and the world position the target point must reach.
#[derive(Debug, Clone, PartialEq)]
pub struct Target {
    /// Target id, seed joints (deg) and load.
    pub sample: Sample,
    /// Required target position, mm, world frame.
    pub position: Vector3<f64>,
}

/// Which columns a reader needs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Layout {
    /// `pose`, q, `load`, `x`, `y`, `z`.
    Measurements,
    /// `pose`, q, `load`; positions ignored.
    Samples,
    /// `id`, q, `load`, `x`, `y`, `z`; ids unique.
    Targets,
}

struct Columns {
    id: usize,
    target: Option<usize>,
    seq: Option<usize>,
    joints: Vec<usize>,
    load: usize,
    xyz: Option<[usize; 3]>,
    /// `rx, ry, rz`, when the header has them (all three, or an error).
    orientation: Option<[usize; 3]>,
    names: Vec<String>,
}

fn find_columns(
    path: &Path,
    header: &csv::StringRecord,
    n: usize,
    layout: Layout,
) -> Result<Columns> {
    let names: Vec<String> = header.iter().map(|h| h.trim().to_string()).collect();
    let mut index: HashMap<&str, usize> = HashMap::new();
    for (i, name) in names.iter().enumerate() {
        if index.insert(name.as_str(), i).is_some() {
            return Err(DataError::DuplicateColumn {
                path: path.to_path_buf(),
                column: name.clone(),
                index: i + 1,
            });
        }
    }
    let missing = |column: &str| DataError::MissingColumn {
        path: path.to_path_buf(),
        column: column.to_string(),
    };
    let id_name = if layout == Layout::Targets {
        "id"
    } else {
        "pose"
    };
    let id = *index.get(id_name).ok_or_else(|| missing(id_name))?;
    let load = *index.get("load").ok_or_else(|| missing("load"))?;
    let joint_numbers: Vec<usize> = names
        .iter()
        .filter_map(|name| name.strip_prefix('q')?.parse::<usize>().ok())
        .filter(|&k| k >= 1)
        .collect();
    let highest = joint_numbers.iter().copied().max().unwrap_or(0);
    let contiguous = joint_numbers.len() == highest;
    if contiguous && highest != n {
        return Err(DataError::JointCountMismatch {
            path: path.to_path_buf(),
            expected: n,
            found: highest,
        });
    }
    let mut joints = Vec::with_capacity(n);
    for k in 1..=n {
        let name = format!("q{k}");
        joints.push(*index.get(name.as_str()).ok_or_else(|| missing(&name))?);
    }
    if !contiguous {
        // q1..qn are present but a higher-numbered joint column is too.
        return Err(DataError::JointCountMismatch {
            path: path.to_path_buf(),
            expected: n,
            found: highest,
        });
    }
    let xyz = match layout {
        Layout::Samples => None,
        Layout::Measurements | Layout::Targets => Some([
            *index.get("x").ok_or_else(|| missing("x"))?,
            *index.get("y").ok_or_else(|| missing("y"))?,
            *index.get("z").ok_or_else(|| missing("z"))?,
        ]),
    };
    let found: Vec<Option<usize>> = ORIENTATION_COLUMNS
        .iter()
        .map(|c| index.get(c).copied())
        .collect();
    let orientation = match (found[0], found[1], found[2]) {
        (Some(a), Some(b), Some(c)) => Some([a, b, c]),
        (None, None, None) => None,
        _ => {
            let name = |want: bool| {
                ORIENTATION_COLUMNS
                    .iter()
                    .zip(&found)
                    .find(|(_, f)| f.is_some() == want)
                    .map_or(String::new(), |(c, _)| (*c).to_string())
            };
            return Err(DataError::PartialOrientation {
                path: path.to_path_buf(),
                present: name(true),
                missing: name(false),
            });
        }
    };
    Ok(Columns {
        id,
        target: index.get("target").copied(),
        seq: index.get("seq").copied(),
        orientation,
        joints,
        load,
        xyz,
        names,
    })
}

struct Parsed {
    sample: Sample,
    position: Option<Vector3<f64>>,
    orientation: Option<Vector3<f64>>,
}

/// Where each line of a file starts, to name a record's line from its byte offset: the csv
/// crate's own line count stays one short after every `\r\n` (BurntSushi/rust-csv#395), and
/// tracker software on Windows writes `\r\n`. A line ends at `\n`, at `\r\n`, or at a lone
/// `\r`, as the reader takes them.
struct LineStarts<'a> {
    bytes: &'a [u8],
    starts: Vec<usize>,
}

impl<'a> LineStarts<'a> {
    fn of(bytes: &'a [u8]) -> Self {
        let mut starts = vec![0];
        for (i, &b) in bytes.iter().enumerate() {
            if b == b'\n' || (b == b'\r' && bytes.get(i + 1) != Some(&b'\n')) {
                starts.push(i + 1);
            }
        }
        Self { bytes, starts }
    }

    /// The 1-based line of the record at byte `offset`: the reader may place a record's start
    /// on the end of the line before it (the `\n` of a `\r\n`), so line ends are skipped first.
    fn line_of(&self, offset: u64) -> u64 {
        let offset = usize::try_from(offset).unwrap_or(usize::MAX);
        let rest = self.bytes.get(offset..).unwrap_or_default();
        let first = offset
            + (rest.iter())
                .take_while(|b| matches!(b, b'\r' | b'\n'))
                .count();
        self.starts.partition_point(|&s| s <= first) as u64
    }
}

/// The rows of a file, and whether its header has the orientation columns.
fn read_rows(path: &Path, n: usize, layout: Layout) -> Result<(Vec<Parsed>, bool)> {
    let bytes = std::fs::read(path).map_err(|source| DataError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    if bytes.iter().all(u8::is_ascii_whitespace) {
        return Err(DataError::Empty {
            path: path.to_path_buf(),
        });
    }
    let lines = LineStarts::of(&bytes);
    let malformed = |e: csv::Error| DataError::Malformed {
        path: path.to_path_buf(),
        line: e.position().map_or(1, |p| lines.line_of(p.byte())),
        message: match e.kind() {
            csv::ErrorKind::UnequalLengths {
                expected_len, len, ..
            } => format!("{len} fields where the header has {expected_len}"),
            csv::ErrorKind::Utf8 { .. } => "not valid UTF-8 text".to_string(),
            _ => e.to_string(),
        },
    };
    let mut reader = csv::ReaderBuilder::new()
        .has_headers(true)
        .trim(csv::Trim::All)
        .from_reader(bytes.as_slice());
    let header = reader.headers().map_err(malformed)?.clone();
    let cols = find_columns(path, &header, n, layout)?;
    let orientation = cols.orientation.is_some();
    let mut rows = Vec::new();
    let mut first_seen: HashMap<String, (u64, Vec<f64>)> = HashMap::new();
    for record in reader.records() {
        let record = record.map_err(malformed)?;
        let line = record.position().map_or(0, |p| lines.line_of(p.byte()));
        let field = |i: usize| record.get(i).unwrap_or("");
        let number = |i: usize| cell_number(path, line, &cols.names[i], field(i));
        let pose = field(cols.id).to_string();
        if pose.is_empty() {
            return Err(DataError::EmptyValue {
                path: path.to_path_buf(),
                line,
                column: cols.names[cols.id].clone(),
            });
        }
        let joints = cols
            .joints
            .iter()
            .map(|&i| number(i))
            .collect::<Result<Vec<_>>>()?;
        let load = number(cols.load)?;
        if load < 0.0 {
            return Err(DataError::NegativeLoad {
                path: path.to_path_buf(),
                line,
                value: load,
            });
        }
        let position = match cols.xyz {
            Some([x, y, z]) => Some(Vector3::new(number(x)?, number(y)?, number(z)?)),
            None => None,
        };
        match first_seen.get(&pose) {
            Some((first_line, _)) if layout == Layout::Targets => {
                return Err(DataError::DuplicateId {
                    path: path.to_path_buf(),
                    line,
                    id: pose,
                    first_line: *first_line,
                });
            }
            Some((first_line, first_joints)) if *first_joints != joints => {
                return Err(DataError::InconsistentPose {
                    path: path.to_path_buf(),
                    line,
                    pose,
                    first_line: *first_line,
                });
            }
            Some(_) => {}
            None => {
                first_seen.insert(pose.clone(), (line, joints.clone()));
            }
        }
        let orientation = match cols.orientation {
            Some(columns) if layout == Layout::Measurements => {
                let filled = columns.map(|i| !field(i).is_empty());
                if filled.iter().all(|f| !f) {
                    None
                } else if let Some(k) = filled.iter().position(|f| !f) {
                    return Err(DataError::PartialOrientationRow {
                        path: path.to_path_buf(),
                        line,
                        column: ORIENTATION_COLUMNS[k].into(),
                    });
                } else {
                    let angles = [
                        number(columns[0])?,
                        number(columns[1])?,
                        number(columns[2])?,
                    ];
                    Some(check_orientation(path, line, angles)?)
                }
            }
            _ => None,
        };
        let target = cols.target.map_or("", field).to_string();
        let seq = match cols.seq {
            Some(i) => Some(cell_integer(path, line, &cols.names[i], field(i))?),
            None => None,
        };
        rows.push(Parsed {
            orientation,
            sample: Sample {
                pose,
                joints,
                load,
                line,
                target,
                seq,
                last_move: Vec::new(),
            },
            position,
        });
    }
    if rows.is_empty() {
        return Err(DataError::NoRows {
            path: path.to_path_buf(),
        });
    }
    check_seq_poses(path, &rows)?;
    let mut samples: Vec<Sample> = rows.iter().map(|p| p.sample.clone()).collect();
    crate::order::set_last_moves(&mut samples);
    for (row, s) in rows.iter_mut().zip(samples) {
        row.sample.last_move = s.last_move;
    }
    Ok((rows, orientation))
}

/// Rows that share a `seq` are one pose: their joint readings must agree.
fn check_seq_poses(path: &Path, rows: &[Parsed]) -> Result<()> {
    let mut first: HashMap<i64, &Sample> = HashMap::new();
    for s in rows.iter().map(|p| &p.sample) {
        let Some(seq) = s.seq else { continue };
        match first.get(&seq) {
            Some(f) if f.joints != s.joints => {
                return Err(DataError::InconsistentSeq {
                    path: path.to_path_buf(),
                    line: s.line,
                    seq,
                    first_line: f.line,
                });
            }
            Some(_) => {}
            None => {
                first.insert(seq, s);
            }
        }
    }
    Ok(())
}

/// The whole number in the cell of `column` on line `line` of `path`: refused, named, when
/// empty or not a whole number.
fn cell_integer(path: &Path, line: u64, column: &str, text: &str) -> Result<i64> {
    if text.is_empty() {
        return Err(DataError::EmptyValue {
            path: path.to_path_buf(),
            line,
            column: column.to_string(),
        });
    }
    text.parse().map_err(|_| DataError::NotAnInteger {
        path: path.to_path_buf(),
        line,
        column: column.to_string(),
        value: text.to_string(),
    })
}

/// The number in the cell of `column` on line `line` of `path`, whose text is `text`: refused,
/// named, when empty, not a number, or not finite.
fn cell_number(path: &Path, line: u64, column: &str, text: &str) -> Result<f64> {
    if text.is_empty() {
        return Err(DataError::EmptyValue {
            path: path.to_path_buf(),
            line,
            column: column.to_string(),
        });
    }
    let value: f64 = text.parse().map_err(|_| DataError::NotANumber {
        path: path.to_path_buf(),
        line,
        column: column.to_string(),
        value: text.to_string(),
    })?;
    if value.is_finite() {
        Ok(value)
    } else {
        Err(DataError::NonFinite {
            path: path.to_path_buf(),
            line,
            column: column.to_string(),
            value: text.to_string(),
        })
    }
}

impl MeasurementSet {
    /// Reads and validates a measurement file for a robot with `joint_count` joints.
    pub fn read(path: impl AsRef<Path>, joint_count: usize) -> Result<Self> {
        let path = path.as_ref();
        let rows = read_rows(path, joint_count, Layout::Measurements)?
            .0
            .into_iter()
            .filter_map(|p| {
                Some(Measurement {
                    position: p.position?,
                    sample: p.sample,
                    orientation: p.orientation,
                })
            })
            .collect();
        Ok(Self {
            source: path.to_path_buf(),
            joint_count,
            rows,
        })
    }

    /// Writes the set as CSV (`pose,q1..qN,load,x,y,z`), atomically, numbers in their shortest
    /// exact form so that reading the file back gives the same values.
    pub fn write(&self, path: impl AsRef<Path>) -> Result<()> {
        let targets = self.rows.iter().any(|r| !r.sample.target.is_empty());
        let orientation = self.has_orientation();
        let seq = self.rows.iter().all(|r| r.sample.seq.is_some()) && !self.rows.is_empty();
        write_atomically(path.as_ref(), |w| {
            write!(w, "pose")?;
            if targets {
                write!(w, ",target")?;
            }
            if seq {
                write!(w, ",seq")?;
            }
            for k in 1..=self.joint_count {
                write!(w, ",q{k}")?;
            }
            writeln!(
                w,
                ",load,x,y,z{}",
                if orientation { ",rx,ry,rz" } else { "" }
            )?;
            for row in &self.rows {
                write!(w, "{}", csv_text(&row.sample.pose))?;
                if targets {
                    write!(w, ",{}", csv_text(&row.sample.target))?;
                }
                if let Some(s) = row.sample.seq.filter(|_| seq) {
                    write!(w, ",{s}")?;
                }
                for q in &row.sample.joints {
                    write!(w, ",{q}")?;
                }
                let p = row.position;
                write!(w, ",{},{},{},{}", row.sample.load, p.x, p.y, p.z)?;
                match row.orientation {
                    Some(r) if orientation => writeln!(w, ",{},{},{}", r.x, r.y, r.z)?,
                    None if orientation => writeln!(w, ",,,")?,
                    _ => writeln!(w)?,
                }
            }
            Ok(())
        })
    }

    /// The same rows with a 6-DoF probe's orientations (`rx, ry, rz`, deg, one per row, in
    /// order), each checked as a file's ([`check_orientation`]; row `i` is its sample's line).
    pub fn with_orientations(mut self, angles: Vec<[f64; 3]>) -> Result<Self> {
        for (row, a) in self.rows.iter_mut().zip(angles) {
            row.orientation = Some(check_orientation(&self.source, row.sample.line, a)?);
        }
        Ok(self)
    }

    /// Whether any row carries a measured orientation (a 6-DoF probe's).
    pub fn has_orientation(&self) -> bool {
        self.rows.iter().any(|r| r.orientation.is_some())
    }

    /// Number of rows.
    pub fn len(&self) -> usize {
        self.rows.len()
    }

    /// Whether there are no rows (never true for a set read from a file).
    pub fn is_empty(&self) -> bool {
        self.rows.is_empty()
    }

    /// The distinct loads in the set, ascending, kg.
    pub fn loads(&self) -> Vec<f64> {
        let mut loads: Vec<f64> = self.rows.iter().map(|r| r.sample.load).collect();
        loads.sort_by(f64::total_cmp);
        loads.dedup();
        loads
    }
}

/// Rows given as arrays rather than a file (the Python bindings), validated as a file's are:
/// finite joints, loads and points, no negative load, a pose id with one set of joint readings.
/// Row `i` (from 0) is "line `i + 1`" of `source` in messages. Without `pose`, rows with the same
/// joint readings share an id (`c1`, `c2`, … in order of first appearance): all loads of a
/// configuration are one pose, as the default calibration's folds need.
pub fn samples_from_arrays(
    source: &Path,
    pose: Option<Vec<String>>,
    joints: Vec<Vec<f64>>,
    loads: Vec<f64>,
) -> Result<Vec<Sample>> {
    if joints.is_empty() {
        return Err(DataError::NoRows {
            path: source.to_path_buf(),
        });
    }
    let mut first_seen: HashMap<String, (u64, Vec<f64>)> = HashMap::new();
    let mut by_joints: Vec<(Vec<f64>, String)> = Vec::new();
    let mut rows = Vec::with_capacity(joints.len());
    for (i, (joints, load)) in joints.into_iter().zip(loads).enumerate() {
        let line = i as u64 + 1;
        let non_finite = |column: String, value: f64| DataError::NonFinite {
            path: source.to_path_buf(),
            line,
            column,
            value: value.to_string(),
        };
        if let Some((k, q)) = joints.iter().enumerate().find(|(_, q)| !q.is_finite()) {
            return Err(non_finite(format!("q{}", k + 1), *q));
        }
        if !load.is_finite() {
            return Err(non_finite("load".into(), load));
        }
        if load < 0.0 {
            return Err(DataError::NegativeLoad {
                path: source.to_path_buf(),
                line,
                value: load,
            });
        }
        let id = match &pose {
            Some(ids) => ids[i].clone(),
            None => match by_joints.iter().find(|(q, _)| *q == joints) {
                Some((_, id)) => id.clone(),
                None => {
                    let id = format!("c{}", by_joints.len() + 1);
                    by_joints.push((joints.clone(), id.clone()));
                    id
                }
            },
        };
        match first_seen.get(&id) {
            Some((first_line, first)) if *first != joints => {
                return Err(DataError::InconsistentPose {
                    path: source.to_path_buf(),
                    line,
                    pose: id,
                    first_line: *first_line,
                });
            }
            Some(_) => {}
            None => {
                first_seen.insert(id.clone(), (line, joints.clone()));
            }
        }
        rows.push(Sample {
            pose: id,
            joints,
            load,
            line,
            target: String::new(),
            seq: None,
            last_move: Vec::new(),
        });
    }
    Ok(rows)
}

impl MeasurementSet {
    /// A measurement set of rows given as arrays ([`samples_from_arrays`]) and their measured
    /// points (mm), which must be finite.
    pub fn from_arrays(
        source: &Path,
        samples: Vec<Sample>,
        positions: Vec<[f64; 3]>,
    ) -> Result<Self> {
        let joint_count = samples.first().map_or(0, |s| s.joints.len());
        let mut rows = Vec::with_capacity(samples.len());
        for (sample, p) in samples.into_iter().zip(positions) {
            if let Some((k, v)) = p.iter().enumerate().find(|(_, v)| !v.is_finite()) {
                return Err(DataError::NonFinite {
                    path: source.to_path_buf(),
                    line: sample.line,
                    column: ["x", "y", "z"][k].into(),
                    value: v.to_string(),
                });
            }
            rows.push(Measurement {
                sample,
                position: Vector3::from(p),
                orientation: None,
            });
        }
        Ok(Self {
            source: source.to_path_buf(),
            joint_count,
            rows,
        })
    }
}

/// Checks that every sample's `target` is empty (the default point) or one of `names` (the
/// robot file's `[tool.points]`).
pub fn check_targets<'a>(
    source: &Path,
    samples: impl IntoIterator<Item = &'a Sample>,
    names: &[&str],
) -> Result<()> {
    for s in samples {
        if !s.target.is_empty() && !names.contains(&s.target.as_str()) {
            return Err(DataError::UnknownTarget {
                path: source.to_path_buf(),
                line: s.line,
                target: s.target.clone(),
                known: if names.is_empty() {
                    "the robot file names no points (`[tool.points]`): leave `target` empty".into()
                } else {
                    format!("the robot file's points are {}", names.join(", "))
                },
            });
        }
    }
    Ok(())
}

impl SampleSet {
    /// Reads and validates a file of samples; `x, y, z` columns are not needed and are ignored.
    pub fn read(path: impl AsRef<Path>, joint_count: usize) -> Result<Self> {
        let path = path.as_ref();
        let (rows, orientation) = read_rows(path, joint_count, Layout::Samples)?;
        Ok(Self {
            source: path.to_path_buf(),
            joint_count,
            rows: rows.into_iter().map(|p| p.sample).collect(),
            orientation,
        })
    }
}

/// Reads and validates a targets file (`id, q1..qN, load, x, y, z`; ids unique).
pub fn read_targets(path: impl AsRef<Path>, joint_count: usize) -> Result<Vec<Target>> {
    let (rows, _) = read_rows(path.as_ref(), joint_count, Layout::Targets)?;
    Ok(rows
        .into_iter()
        .filter_map(|p| {
            Some(Target {
                position: p.position?,
                sample: p.sample,
            })
        })
        .collect())
}

/// Quotes a text field when CSV needs it.
pub fn csv_text(text: &str) -> String {
    if text.contains([',', '"', '\n', '\r']) || text.trim() != text {
        format!("\"{}\"", text.replace('"', "\"\""))
    } else {
        text.to_string()
    }
}

/// `v` with 6 decimals, without the sign of a value that rounds to zero.
pub fn fixed6(v: f64) -> String {
    let text = format!("{v:.6}");
    match text.strip_prefix('-') {
        Some(rest) if rest.bytes().all(|b| b == b'0' || b == b'.') => rest.to_string(),
        _ => text,
    }
}

/// A predicted point for one input row.
#[derive(Debug, Clone, PartialEq)]
pub struct Prediction {
    /// Pose id of the input row.
    pub pose: String,
    /// The point predicted (the input row's `target`; empty: the default point).
    pub target: String,
    /// Load of the input row, kg.
    pub load: f64,
    /// Predicted target position, mm, world frame.
    pub position: Vector3<f64>,
    /// Standard deviation of the predicted point (the root sum of the axes' variances), mm,
    /// when the model gives one.
    pub sigma: Option<f64>,
    /// Predicted orientation of the tool frame, fixed-axis roll, pitch, yaw in the world, deg
    /// (written as `rx, ry, rz` when every row has one).
    pub orientation: Option<Vector3<f64>>,
}

/// Writes `pose,load,x,y,z` with 6 decimals on x, y, z, atomically; with a `sigma` column
/// (6 decimals) when every row has one, then `rx, ry, rz` (deg, 6 decimals) when every row has
/// an orientation.
pub fn write_predictions(path: impl AsRef<Path>, rows: &[Prediction]) -> Result<()> {
    let sigma = !rows.is_empty() && rows.iter().all(|r| r.sigma.is_some());
    let orientation = !rows.is_empty() && rows.iter().all(|r| r.orientation.is_some());
    let targets = rows.iter().any(|r| !r.target.is_empty());
    write_atomically(path.as_ref(), |w| {
        writeln!(
            w,
            "pose{},load,x,y,z{}{}",
            if targets { ",target" } else { "" },
            if sigma { ",sigma" } else { "" },
            if orientation { ",rx,ry,rz" } else { "" }
        )?;
        for r in rows {
            let p = r.position;
            write!(w, "{}", csv_text(&r.pose))?;
            if targets {
                write!(w, ",{}", csv_text(&r.target))?;
            }
            write!(
                w,
                ",{},{},{},{}",
                r.load,
                fixed6(p.x),
                fixed6(p.y),
                fixed6(p.z)
            )?;
            if let Some(s) = r.sigma.filter(|_| sigma) {
                write!(w, ",{}", fixed6(s))?;
            }
            match r.orientation.filter(|_| orientation) {
                Some(a) => writeln!(w, ",{},{},{}", fixed6(a.x), fixed6(a.y), fixed6(a.z))?,
                None => writeln!(w)?,
            }
        }
        Ok(())
    })
}
