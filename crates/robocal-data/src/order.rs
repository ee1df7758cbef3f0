//! The order in which rows were measured (`seq`), and the direction each joint last moved in
//! before a row: the flank a joint with play rests on.

use std::collections::BTreeMap;

use crate::csvio::Sample;

/// A joint reading that changes by no more than this (deg) between two poses has not moved:
/// its flank stays where its last move left it.
pub const MOVE_DEADBAND_DEG: f64 = 1e-3;

/// Sets every sample's [`Sample::last_move`] from the samples' `seq`: the rows of one `seq`
/// are one pose, and the pose before it is the one whose `seq` is one less. A joint's last
/// move is `+1` where its reading rose by more than [`MOVE_DEADBAND_DEG`] from the pose before
/// (or, where it did not move, the direction of its last move), `−1` where it fell, and `0`
/// (unknown) before its first move and after a gap in `seq` (poses measured in between that
/// the rows do not hold) until it moves again. Samples without a `seq` get no last move (an empty vector); where
/// none has one, nothing changes.
pub fn set_last_moves(samples: &mut [Sample]) {
    let mut by_seq: BTreeMap<i64, Vec<usize>> = BTreeMap::new();
    for (i, s) in samples.iter().enumerate() {
        if let Some(seq) = s.seq {
            by_seq.entry(seq).or_default().push(i);
        }
    }
    let Some(first) = by_seq.values().next().and_then(|rows| rows.first()) else {
        return;
    };
    let n = samples[*first].joints.len();
    let mut flank = vec![0.0; n];
    let mut previous: Option<(i64, Vec<f64>)> = None;
    for (&seq, rows) in &by_seq {
        let joints = samples[rows[0]].joints.clone();
        match &previous {
            Some((before, q_before)) if seq == before + 1 => {
                for (f, (q, p)) in flank.iter_mut().zip(joints.iter().zip(q_before)) {
                    if (q - p).abs() > MOVE_DEADBAND_DEG {
                        *f = (q - p).signum();
                    }
                }
            }
            // Poses measured in between that the file does not hold: every flank unknown.
            Some(_) => flank.fill(0.0),
            None => {}
        }
        for &i in rows {
            samples[i].last_move = flank.clone();
        }
        previous = Some((seq, joints));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample(seq: Option<i64>, joints: &[f64]) -> Sample {
        Sample {
            pose: String::new(),
            joints: joints.to_vec(),
            load: 0.0,
            line: 0,
            target: String::new(),
            seq,
            last_move: Vec::new(),
        }
    }

    #[test]
    fn a_joint_keeps_the_flank_of_its_last_move_in_the_order_of_seq() {
        // File order differs from the measurement order; rows 3 and 4 are one pose.
        let mut rows = vec![
            sample(Some(2), &[5.0, 1.0]),
            sample(Some(0), &[0.0, 0.0]),
            sample(Some(1), &[10.0, 1.0]),
            sample(Some(3), &[5.0, 1.0005]),
            sample(Some(3), &[5.0, 1.0005]),
        ];
        set_last_moves(&mut rows);
        assert_eq!(rows[1].last_move, vec![0.0, 0.0]);
        assert_eq!(rows[2].last_move, vec![1.0, 1.0]);
        assert_eq!(rows[0].last_move, vec![-1.0, 1.0]);
        // Within the deadband: the flank of the last move stays.
        assert_eq!(rows[3].last_move, vec![-1.0, 1.0]);
        assert_eq!(rows[4].last_move, rows[3].last_move);
    }

    #[test]
    fn rows_without_seq_get_no_last_move() {
        let mut rows = vec![sample(None, &[0.0]), sample(Some(0), &[1.0])];
        set_last_moves(&mut rows);
        assert!(rows[0].last_move.is_empty());
        assert_eq!(rows[1].last_move, vec![0.0]);
        let mut none = vec![sample(None, &[0.0])];
        set_last_moves(&mut none);
        assert!(none[0].last_move.is_empty());
    }

    #[test]
    fn a_gap_in_seq_leaves_every_flank_unknown_until_the_joint_moves() {
        let mut rows = vec![
            sample(Some(0), &[0.0, 0.0]),
            sample(Some(1), &[1.0, 1.0]),
            sample(Some(5), &[0.0, 1.0]),
            sample(Some(6), &[1.0, 1.0]),
        ];
        set_last_moves(&mut rows);
        assert_eq!(rows[1].last_move, vec![1.0, 1.0]);
        assert_eq!(rows[2].last_move, vec![0.0, 0.0]);
        assert_eq!(rows[3].last_move, vec![1.0, 0.0]);
    }
}
