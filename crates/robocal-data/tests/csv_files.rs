//! Measurement CSV: round trips and one test per kind of bad input, each checking the error kind
//! and that it names the line and column.

use std::path::{Path, PathBuf};

use nalgebra::Vector3;
use proptest::prelude::*;
use robocal_data::{
    DataError, Measurement, MeasurementSet, Sample, SampleSet, read_targets, samples_from_arrays,
};

fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, text).unwrap();
    path
}

fn read_err(text: &str, joints: usize) -> DataError {
    let dir = tempfile::tempdir().unwrap();
    let path = write(dir.path(), "m.csv", text);
    let err = MeasurementSet::read(&path, joints).unwrap_err();
    assert!(
        err.to_string().contains("m.csv"),
        "the error names the file: {err}"
    );
    err
}

const HEADER: &str = "pose,q1,q2,q3,load,x,y,z\n";

#[test]
fn column_order_is_free_and_extra_columns_are_ignored() {
    let dir = tempfile::tempdir().unwrap();
    let path = write(
        dir.path(),
        "m.csv",
        "z,note,load,q3,q1,pose,q2,y,x\n3.5, hi ,2,30,10,p1,20,2.5,1.5\n",
    );
    let set = MeasurementSet::read(&path, 3).unwrap();
    let row = &set.rows[0];
    assert_eq!(row.sample.pose, "p1");
    assert_eq!(row.sample.joints, vec![10.0, 20.0, 30.0]);
    assert_eq!(row.sample.load, 2.0);
    assert_eq!(row.sample.line, 2);
    assert_eq!(row.position, Vector3::new(1.5, 2.5, 3.5));
}

#[test]
fn samples_do_not_need_positions() {
    let dir = tempfile::tempdir().unwrap();
    let path = write(dir.path(), "in.csv", "pose,q1,load\na,1,0\nb,2,0.5\n");
    let set = SampleSet::read(&path, 1).unwrap();
    assert_eq!(set.rows.len(), 2);
    assert!(matches!(
        MeasurementSet::read(&path, 1),
        Err(DataError::MissingColumn { column, .. }) if column == "x"
    ));
}

#[test]
fn missing_column() {
    let err = read_err("pose,q1,q2,q3,x,y,z\np,1,2,3,4,5,6\n", 3);
    assert!(
        matches!(&err, DataError::MissingColumn { column, .. } if column == "load"),
        "{err}"
    );
    assert!(err.to_string().contains("line 1"));
    let err = read_err("pose,q1,q3,load,x,y,z\np,1,2,3,4,5,6\n", 3);
    assert!(
        matches!(&err, DataError::MissingColumn { column, .. } if column == "q2"),
        "{err}"
    );
}

#[test]
fn duplicate_column() {
    let err = read_err("pose,q1,q2,q3,load,x,y,x,z\np,1,2,3,0,4,5,6,7\n", 3);
    assert!(
        matches!(&err, DataError::DuplicateColumn { column, index: 8, .. } if column == "x"),
        "{err}"
    );
    assert!(err.to_string().contains("line 1, column 8"));
}

#[test]
fn non_numeric_value() {
    let err = read_err(&format!("{HEADER}p,1,2,3,0,4,5,6\np,1,2,3,5,4,abc,6\n"), 3);
    assert!(
        matches!(&err, DataError::NotANumber { line: 3, column, value, .. } if column == "y" && value == "abc"),
        "{err}"
    );
    assert!(err.to_string().contains("line 3, column `y`"));
}

#[test]
fn nan_inf_and_overflow() {
    for bad in ["NaN", "inf", "-inf", "1e400"] {
        let err = read_err(&format!("{HEADER}p,1,{bad},3,0,4,5,6\n"), 3);
        assert!(
            matches!(&err, DataError::NonFinite { line: 2, column, .. } if column == "q2"),
            "{bad}: {err}"
        );
    }
}

#[test]
fn empty_value() {
    let err = read_err(&format!("{HEADER}p,1,,3,0,4,5,6\n"), 3);
    assert!(
        matches!(&err, DataError::EmptyValue { line: 2, column, .. } if column == "q2"),
        "{err}"
    );
    let err = read_err(&format!("{HEADER},1,2,3,0,4,5,6\n"), 3);
    assert!(
        matches!(&err, DataError::EmptyValue { line: 2, column, .. } if column == "pose"),
        "{err}"
    );
}

#[test]
fn wrong_joint_count() {
    let err = read_err(&format!("{HEADER}p,1,2,3,0,4,5,6\n"), 6);
    assert!(matches!(
        err,
        DataError::JointCountMismatch {
            expected: 6,
            found: 3,
            ..
        }
    ));
    let err = read_err("pose,q1,q2,q3,q4,load,x,y,z\np,1,2,3,4,0,4,5,6\n", 3);
    assert!(matches!(
        err,
        DataError::JointCountMismatch {
            expected: 3,
            found: 4,
            ..
        }
    ));
}

#[test]
fn negative_load() {
    let err = read_err(&format!("{HEADER}p,1,2,3,-0.5,4,5,6\n"), 3);
    assert!(matches!(err, DataError::NegativeLoad { line: 2, value, .. } if value == -0.5));
}

#[test]
fn empty_file_and_header_only() {
    assert!(matches!(read_err("", 3), DataError::Empty { .. }));
    assert!(matches!(read_err("\n  \n", 3), DataError::Empty { .. }));
    assert!(matches!(read_err(HEADER, 3), DataError::NoRows { .. }));
}

/// Lines are named alike whatever ends them: `\n`, `\r\n` (tracker software on Windows) or
/// a lone `\r`; the rows read keep their lines too (a bad shot is named by it).
#[test]
fn line_numbers_with_every_line_ending() {
    for end in ["\n", "\r\n", "\r"] {
        let rows = [
            "p,1,2,3,0,4,5,6",
            "q,1,2,3,0,4,5,6",
            "r,1,2,3,0,4,5,6",
            "s,1,2,3,0,4,abc,6",
        ];
        let text = format!("pose,q1,q2,q3,load,x,y,z{end}{}{end}", rows.join(end));
        let err = read_err(&text, 3);
        assert!(
            matches!(&err, DataError::NotANumber { line: 5, column, .. } if column == "y"),
            "{end:?}: {err}"
        );
        let ragged = format!(
            "pose,q1,q2,q3,load,x,y,z{end}{}{end}p,1{end}",
            rows[..3].join(end)
        );
        assert!(
            matches!(read_err(&ragged, 3), DataError::Malformed { line: 5, .. }),
            "{end:?}"
        );
        let dir = tempfile::tempdir().unwrap();
        let good = format!("pose,q1,q2,q3,load,x,y,z{end}{}{end}", rows[..3].join(end));
        let path = write(dir.path(), "m.csv", &good);
        let set = MeasurementSet::read(&path, 3).unwrap();
        let lines: Vec<u64> = set.rows.iter().map(|r| r.sample.line).collect();
        assert_eq!(lines, [2, 3, 4], "{end:?}");
    }
}

#[test]
fn ragged_row() {
    let err = read_err(&format!("{HEADER}p,1,2,3,0,4,5\n"), 3);
    assert!(matches!(err, DataError::Malformed { line: 2, .. }), "{err}");
}

#[test]
fn same_pose_with_different_joints() {
    let err = read_err(
        &format!("{HEADER}p,1,2,3,0,4,5,6\nq,1,2,3,0,4,5,6\np,1,2,3.5,5,4,5,6\n"),
        3,
    );
    assert!(
        matches!(
            err,
            DataError::InconsistentPose {
                line: 4,
                first_line: 2,
                ..
            }
        ),
        "{err}"
    );
}

#[test]
fn missing_file() {
    let err = MeasurementSet::read("/nonexistent/m.csv", 3).unwrap_err();
    assert!(matches!(err, DataError::Io { .. }));
}

#[test]
fn targets_need_unique_ids() {
    let dir = tempfile::tempdir().unwrap();
    let path = write(
        dir.path(),
        "t.csv",
        "id,q1,load,x,y,z\nt1,0,0,1,2,3\nt2,5,1,1,2,3\n",
    );
    assert_eq!(read_targets(&path, 1).unwrap().len(), 2);
    let path = write(
        dir.path(),
        "t.csv",
        "id,q1,load,x,y,z\nt1,0,0,1,2,3\nt1,0,0,1,2,3\n",
    );
    assert!(matches!(
        read_targets(&path, 1),
        Err(DataError::DuplicateId {
            line: 3,
            first_line: 2,
            ..
        })
    ));
}

#[test]
fn failed_write_leaves_existing_file_untouched() {
    let dir = tempfile::tempdir().unwrap();
    let path = write(dir.path(), "keep.csv", "old contents\n");
    let result = robocal_data::write_atomically(&path, |w| {
        w.write_all(b"partial")?;
        Err(std::io::Error::other("disk full"))
    });
    assert!(matches!(result, Err(DataError::Write { .. })));
    assert_eq!(std::fs::read_to_string(&path).unwrap(), "old contents\n");
    let leftovers = std::fs::read_dir(dir.path()).unwrap().count();
    assert_eq!(leftovers, 1, "no temporary file is left behind");
}

fn finite() -> impl Strategy<Value = f64> {
    prop_oneof![
        -1e6..1e6f64,
        any::<f64>().prop_filter("finite", |v| v.is_finite())
    ]
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]
    #[test]
    fn write_then_read_gives_the_same_set(
        rows in prop::collection::vec(
            ("[a-z0-9 ,\"_-]{1,8}", prop::collection::vec(finite(), 4), 0.0..30.0f64, prop::array::uniform3(finite())),
            1..20,
        )
    ) {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("round.csv");
        // Give every row its own pose id so the one-reading-per-pose rule holds: the row's
        // number and a dot (not in the ids' alphabet) before it, so that `z1` of row 3 and `z` of
        // row 13 stay apart.
        let rows: Vec<Measurement> = rows
            .into_iter()
            .enumerate()
            .map(|(i, (pose, joints, load, p))| Measurement {
                sample: Sample { pose: format!("{i}.{}", pose.trim()), joints, load, line: i as u64 + 2, target: String::new(), seq: None, last_move: Vec::new() },
                position: Vector3::from(p),
                orientation: None,
            })
            .collect();
        let set = MeasurementSet { source: path.clone(), joint_count: 4, rows };
        set.write(&path).unwrap();
        let back = MeasurementSet::read(&path, 4).unwrap();
        prop_assert_eq!(back, set);
    }
}

/// Rows from arrays (the Python bindings) read as the same rows from a file: the same poses,
/// joints, loads and points, and the file's checks with the array row as the line.
#[test]
fn rows_from_arrays_are_the_rows_of_the_same_file() {
    let dir = tempfile::tempdir().unwrap();
    let path = write(
        dir.path(),
        "m.csv",
        "pose,q1,q2,load,x,y,z\na,1,2,0,10,11,12\na,1,2,5,10.5,11,12\nb,3,4,0,20,21,22\n",
    );
    let file = MeasurementSet::read(&path, 2).unwrap();
    let joints = vec![vec![1.0, 2.0], vec![1.0, 2.0], vec![3.0, 4.0]];
    let loads = vec![0.0, 5.0, 0.0];
    let source = Path::new("(arrays)");
    let samples = samples_from_arrays(source, None, joints.clone(), loads.clone()).unwrap();
    // Without ids, one id per distinct joint reading.
    let ids: Vec<&str> = samples.iter().map(|s| s.pose.as_str()).collect();
    assert_eq!(ids, ["c1", "c1", "c2"]);
    let named = samples_from_arrays(
        source,
        Some(vec!["a".into(), "a".into(), "b".into()]),
        joints.clone(),
        loads.clone(),
    )
    .unwrap();
    let points = vec![[10.0, 11.0, 12.0], [10.5, 11.0, 12.0], [20.0, 21.0, 22.0]];
    let set = MeasurementSet::from_arrays(source, named, points.clone()).unwrap();
    assert_eq!(set.rows.len(), file.rows.len());
    for (a, b) in set.rows.iter().zip(&file.rows) {
        assert_eq!(
            (&a.sample.pose, &a.sample.joints, a.sample.load, a.position),
            (&b.sample.pose, &b.sample.joints, b.sample.load, b.position)
        );
    }
    // The file's checks, row i as line i + 1.
    let mut bad = joints.clone();
    bad[1][1] = f64::NAN;
    let err = samples_from_arrays(source, None, bad, loads.clone()).unwrap_err();
    assert_eq!(
        err.to_string(),
        "(arrays): line 2, column `q2`: `NaN` is not a finite number"
    );
    let err = samples_from_arrays(source, None, joints.clone(), vec![0.0, -1.0, 0.0]).unwrap_err();
    assert!(
        matches!(err, DataError::NegativeLoad { line: 2, .. }),
        "{err}"
    );
    let err = samples_from_arrays(
        source,
        Some(vec!["a".into(), "b".into(), "a".into()]),
        joints.clone(),
        loads.clone(),
    )
    .unwrap_err();
    assert!(
        matches!(
            err,
            DataError::InconsistentPose {
                line: 3,
                first_line: 1,
                ..
            }
        ),
        "{err}"
    );
    let samples = samples_from_arrays(source, None, joints, loads).unwrap();
    let mut points = points;
    points[2][2] = f64::INFINITY;
    let err = MeasurementSet::from_arrays(source, samples, points).unwrap_err();
    assert!(err.to_string().contains("line 3, column `z`"), "{err}");
    assert!(samples_from_arrays(source, None, Vec::new(), Vec::new()).is_err());
}

/// A `seq` column orders the rows: each row gets the direction each joint last moved in,
/// in the order of `seq` rather than of the file, with the rows of one pose alike.
#[test]
fn seq_gives_each_row_its_joints_last_moves() {
    let dir = tempfile::tempdir().unwrap();
    let path = write(
        dir.path(),
        "m.csv",
        "pose,seq,q1,q2,load,x,y,z\nb,1,10,5,0,1,2,3\na,0,0,5,0,1,2,3\nc,2,4,9,0,1,2,3\nc,2,4,9,0,1,2,3\n",
    );
    let set = MeasurementSet::read(&path, 2).unwrap();
    let moves: Vec<&Vec<f64>> = set.rows.iter().map(|r| &r.sample.last_move).collect();
    assert_eq!(
        moves,
        [
            &vec![1.0, 0.0],
            &vec![0.0, 0.0],
            &vec![-1.0, 1.0],
            &vec![-1.0, 1.0]
        ]
    );
    assert_eq!(set.rows[0].sample.seq, Some(1));
    let samples = SampleSet::read(&path, 2).unwrap();
    assert_eq!(samples.rows[2].last_move, vec![-1.0, 1.0]);
    let plain = write(
        dir.path(),
        "p.csv",
        "pose,q1,q2,load,x,y,z\na,0,5,0,1,2,3\n",
    );
    let plain = MeasurementSet::read(&plain, 2).unwrap();
    assert!(plain.rows[0].sample.last_move.is_empty() && plain.rows[0].sample.seq.is_none());
}

#[test]
fn a_bad_seq_is_named() {
    let text = "pose,seq,q1,q2,load,x,y,z\na,0,0,5,0,1,2,3\nb,1.5,1,5,0,1,2,3\n";
    let e = read_err(text, 2).to_string();
    assert!(
        e.contains("line 3") && e.contains("`seq`") && e.contains("1.5"),
        "{e}"
    );
    let text = "pose,seq,q1,q2,load,x,y,z\na,0,0,5,0,1,2,3\nb,,1,5,0,1,2,3\n";
    let e = read_err(text, 2).to_string();
    assert!(e.contains("line 3") && e.contains("`seq`"), "{e}");
    let text = "pose,seq,q1,q2,load,x,y,z\na,0,0,5,0,1,2,3\nb,0,1,5,0,1,2,3\n";
    let e = read_err(text, 2);
    assert!(
        matches!(
            e,
            DataError::InconsistentSeq {
                line: 3,
                first_line: 2,
                seq: 0,
                ..
            }
        ),
        "{e}"
    );
}
