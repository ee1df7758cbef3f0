//! The split of section IV-E and Fig. 9 of the paper: configurations trained/untrained, loads
//! trained/untrained, and the five sets GA10, GA20, GB20, GB10, GB30.

use robocal_data::Invalid;
use std::collections::HashSet;

use rand::SeedableRng;
use rand::seq::SliceRandom;
use rand_chacha::ChaCha8Rng;
use robocal_data::Measurement;
use serde::Serialize;

use crate::experiment::SplitDesign;

/// The set a measured row belongs to.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize)]
pub enum Set {
    /// Trained configuration × trained load: training.
    Ga10,
    /// Trained configuration × untrained load: test.
    Ga20,
    /// Untrained configuration × one of the validation loads (trained loads): validation.
    Gb20,
    /// Untrained configuration × the other trained loads: test.
    Gb10,
    /// Untrained configuration × untrained load: test.
    Gb30,
}

impl Set {
    /// Every set, in the paper's order.
    pub const ALL: [Set; 5] = [Set::Ga10, Set::Ga20, Set::Gb20, Set::Gb10, Set::Gb30];

    /// Whether its rows are of trained configurations.
    pub fn trained_configurations(self) -> bool {
        matches!(self, Set::Ga10 | Set::Ga20)
    }

    /// What its rows are, in words (report captions), e.g. `trained configurations at
    /// untrained loads (test)`.
    pub fn description(self) -> &'static str {
        match self {
            Set::Ga10 => "trained configurations at trained loads (training)",
            Set::Ga20 => "trained configurations at untrained loads (test)",
            Set::Gb20 => "untrained configurations at the validation loads (validation)",
            Set::Gb10 => "untrained configurations at the other trained loads (test)",
            Set::Gb30 => "untrained configurations at untrained loads (test)",
        }
    }

    /// The paper's name.
    pub fn name(self) -> &'static str {
        match self {
            Set::Ga10 => "GA10",
            Set::Ga20 => "GA20",
            Set::Gb20 => "GB20",
            Set::Gb10 => "GB10",
            Set::Gb30 => "GB30",
        }
    }
}

/// A split of a measurement set's rows (serialised without the per-row lists).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Splits {
    /// Trained configurations (pose ids), in the order the seed drew them.
    pub trained_configurations: Vec<String>,
    /// Untrained configurations.
    pub untrained_configurations: Vec<String>,
    /// Trained loads, kg, ascending.
    pub trained_loads: Vec<f64>,
    /// Untrained loads, kg, ascending.
    pub untrained_loads: Vec<f64>,
    /// The trained loads whose untrained-configuration rows validate (GB20), ascending.
    pub validation_loads: Vec<f64>,
    /// Load of the kinematic rows, kg.
    pub kinematic_load: f64,
    /// The set of every row, in row order.
    #[serde(skip)]
    pub set_of_row: Vec<Set>,
    /// Rows (indices) the kinematic stage fits: trained configurations at the kinematic load.
    #[serde(skip)]
    pub kinematic_rows: Vec<usize>,
    /// Untrained configurations at the kinematic load: the kinematic cross-validation.
    #[serde(skip)]
    pub kinematic_held_out_rows: Vec<usize>,
}

impl Splits {
    /// Splits `rows` as `design` says, drawing configurations and validation loads with `seed`.
    /// `default_untrained` serves when the design lists no untrained loads. Errors: (key in
    /// `[split]`, message).
    pub fn new(
        rows: &[Measurement],
        design: &SplitDesign,
        default_untrained: Option<&[f64]>,
        seed: u64,
    ) -> Result<Self, Invalid> {
        let err = |k: &str, m: String| Invalid::new(k, m).within("split");
        let mut configurations: Vec<&str> = Vec::new();
        let mut seen = HashSet::new();
        for r in rows {
            if seen.insert(r.sample.pose.as_str()) {
                configurations.push(r.sample.pose.as_str());
            }
        }
        let n = configurations.len();
        if design.trained_configurations >= n {
            return Err(err(
                "trained_configurations",
                format!(
                    "{} leaves no untrained configuration: the data hold {n}",
                    design.trained_configurations
                ),
            ));
        }
        let mut loads: Vec<f64> = rows.iter().map(|r| r.sample.load).collect();
        loads.sort_by(f64::total_cmp);
        loads.dedup();
        let untrained: Vec<f64> = match (&design.untrained_loads, default_untrained) {
            (Some(l), _) => l.clone(),
            (None, Some(l)) => l.to_vec(),
            (None, None) => Vec::new(),
        };
        for l in &untrained {
            if !loads.contains(l) {
                return Err(err(
                    "untrained_loads",
                    format!("{l} kg is not a load of the data (loads: {loads:?})"),
                ));
            }
        }
        let trained: Vec<f64> = loads
            .iter()
            .copied()
            .filter(|l| !untrained.contains(l))
            .collect();
        if design.validation_loads >= trained.len() {
            return Err(err(
                "validation_loads",
                format!(
                    "{} of the {} trained loads leaves none for GB10",
                    design.validation_loads,
                    trained.len()
                ),
            ));
        }
        let kinematic_load = match design.kinematic_load {
            Some(l) if trained.contains(&l) => l,
            Some(l) => {
                return Err(err(
                    "kinematic_load",
                    format!("{l} kg is not a trained load of the data (trained: {trained:?})"),
                ));
            }
            None => trained[0],
        };
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        configurations.shuffle(&mut rng);
        let mut drawn = trained.clone();
        drawn.shuffle(&mut rng);
        let mut validation: Vec<f64> = drawn[..design.validation_loads].to_vec();
        validation.sort_by(f64::total_cmp);
        let (t, u) = configurations.split_at(design.trained_configurations);
        let trained_cfg: HashSet<&str> = t.iter().copied().collect();
        let mut set_of_row = Vec::with_capacity(rows.len());
        let mut kinematic_rows = Vec::new();
        let mut kinematic_held_out_rows = Vec::new();
        for (i, r) in rows.iter().enumerate() {
            let cfg = trained_cfg.contains(r.sample.pose.as_str());
            let load = r.sample.load;
            let set = match (cfg, untrained.contains(&load), validation.contains(&load)) {
                (true, false, _) => Set::Ga10,
                (true, true, _) => Set::Ga20,
                (false, true, _) => Set::Gb30,
                (false, false, true) => Set::Gb20,
                (false, false, false) => Set::Gb10,
            };
            set_of_row.push(set);
            if load == kinematic_load {
                if cfg {
                    kinematic_rows.push(i);
                } else {
                    kinematic_held_out_rows.push(i);
                }
            }
        }
        let mut untrained_sorted = untrained;
        untrained_sorted.sort_by(f64::total_cmp);
        Ok(Self {
            trained_configurations: t.iter().map(|s| s.to_string()).collect(),
            untrained_configurations: u.iter().map(|s| s.to_string()).collect(),
            trained_loads: trained,
            untrained_loads: untrained_sorted,
            validation_loads: validation,
            kinematic_load,
            set_of_row,
            kinematic_rows,
            kinematic_held_out_rows,
        })
    }

    /// Rows (indices) in any of `sets`, in row order.
    pub fn rows(&self, sets: &[Set]) -> Vec<usize> {
        self.set_of_row
            .iter()
            .enumerate()
            .filter(|(_, s)| sets.contains(s))
            .map(|(i, _)| i)
            .collect()
    }

    /// Number of rows in each set, in the paper's order.
    pub fn sizes(&self) -> Vec<(Set, usize)> {
        Set::ALL
            .iter()
            .map(|&s| (s, self.set_of_row.iter().filter(|&&r| r == s).count()))
            .collect()
    }
}
