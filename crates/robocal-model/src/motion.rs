//! Play that follows the order of motion (`motion.toml`): a joint with play stands behind its
//! reading in the direction it last moved in, by half its play.

use std::borrow::Cow;
use std::path::Path;

use robocal_data::Sample;
use serde::{Deserialize, Serialize};

use crate::error::{ModelError, Result};

/// The model directory's file of the play that follows the order of motion.
pub const MOTION_FILE: &str = "motion.toml";

/// Per joint, how far (deg) the joint stands behind its reading in the direction of its last
/// move ([`Sample::last_move`]): the joint is at `reading − play × last_move`. Rows without an
/// order (no `seq`) are read as they are: the middle of the play.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MotionPlay {
    /// One per joint, deg.
    pub play: Vec<f64>,
}

impl MotionPlay {
    /// The sample at the joint angles it stands at: its readings less the play in the
    /// direction of its last move, with the last move spent (so that reading it again changes
    /// nothing). A sample without a last move is given back as it is.
    pub fn read<'a>(&self, s: &'a Sample) -> Cow<'a, Sample> {
        if s.last_move.is_empty() {
            return Cow::Borrowed(s);
        }
        let mut read = s.clone();
        for ((q, play), side) in read.joints.iter_mut().zip(&self.play).zip(&s.last_move) {
            *q -= play * side;
        }
        read.last_move.clear();
        Cow::Owned(read)
    }

    /// The command that puts a joint at `joints` (deg) after a move in the directions
    /// `last_move`: the joints plus the play they will stand behind by. Without a last move
    /// (an empty vector), the joints themselves.
    pub fn command(&self, joints: &[f64], last_move: &[f64]) -> Vec<f64> {
        let mut q = joints.to_vec();
        for ((q, play), side) in q.iter_mut().zip(&self.play).zip(last_move) {
            *q += play * side;
        }
        q
    }

    /// What to say of `rows` of `file` that carry no order while the play asks for one: they
    /// are read at the middle of the play. `None` where every row has an order.
    pub fn warning<'a>(
        &self,
        file: &Path,
        rows: impl IntoIterator<Item = &'a Sample>,
    ) -> Option<String> {
        let unordered = rows.into_iter().filter(|s| s.last_move.is_empty()).count();
        (unordered > 0).then(|| {
            format!(
                "{}: {unordered} rows without an order (`seq`), while the model's joints stand behind their readings in the direction of their last move (motion.toml): those rows are read at the middle of the play",
                file.display()
            )
        })
    }

    /// The file form, with a header saying what it is.
    pub fn to_toml_string(&self) -> String {
        "# Per joint, how far (deg) the joint stands behind its reading in the direction it last\n\
         # moved in (rows ordered by `seq`); rows without an order are read as they are.\n"
            .to_string()
            + &toml::to_string(self).unwrap_or_default()
    }

    /// Reads `motion.toml` of a model for a robot with `dof` joints.
    pub fn load(file: &Path, dof: usize) -> Result<Self> {
        let text = std::fs::read_to_string(file).map_err(|source| ModelError::NotAModel {
            file: file.to_path_buf(),
            source,
        })?;
        let motion: Self = toml::from_str(&text).map_err(|e| ModelError::DomainToml {
            file: file.to_path_buf(),
            message: e.to_string().trim_end().replace('\n', " "),
        })?;
        let invalid = |message: String| ModelError::Domain {
            file: file.to_path_buf(),
            key: "play".into(),
            message,
        };
        if motion.play.len() != dof {
            return Err(invalid(format!(
                "{} values for a robot with {dof} joints",
                motion.play.len()
            )));
        }
        if let Some(v) = motion.play.iter().find(|v| !v.is_finite()) {
            return Err(invalid(format!("{v}: every value must be a finite number")));
        }
        Ok(motion)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_reading_stands_behind_in_the_direction_of_the_last_move_once() {
        let play = MotionPlay {
            play: vec![0.5, 0.25],
        };
        let s = Sample {
            pose: "p".into(),
            joints: vec![10.0, 20.0],
            load: 0.0,
            line: 0,
            target: String::new(),
            seq: Some(3),
            last_move: vec![1.0, -1.0],
        };
        let read = play.read(&s);
        assert_eq!(read.joints, vec![9.5, 20.25]);
        assert_eq!(play.command(&read.joints, &s.last_move), s.joints);
        assert_eq!(play.read(&read).joints, read.joints);
        let unordered = Sample {
            last_move: Vec::new(),
            ..s.clone()
        };
        assert_eq!(play.read(&unordered).joints, s.joints);
    }

    #[test]
    fn the_file_reads_back_and_names_a_bad_value() {
        let dir = tempfile::tempdir().unwrap();
        let file = dir.path().join(MOTION_FILE);
        let play = MotionPlay {
            play: vec![0.1, -0.03125, 0.0],
        };
        std::fs::write(&file, play.to_toml_string()).unwrap();
        assert_eq!(MotionPlay::load(&file, 3).unwrap(), play);
        let e = MotionPlay::load(&file, 2).unwrap_err().to_string();
        assert!(e.contains("motion.toml") && e.contains("`play`") && e.contains("3 values"));
        std::fs::write(&file, "play = [0.1, nan, 0]\n").unwrap();
        let e = MotionPlay::load(&file, 3).unwrap_err().to_string();
        assert!(e.contains("finite"), "{e}");
    }
}
