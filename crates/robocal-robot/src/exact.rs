//! Fixed-length arrays in files, read strictly: `xyz = [1, 2, 3, 4]` is an error naming the key,
//! not three numbers and a fourth silently dropped (serde's array impl stops reading after `N`
//! and the TOML reader does not object to what is left).
//!
//! Use as `#[serde(deserialize_with = "robocal_robot::exact::array")]` (or `option` for an
//! `Option<[f64; N]>`, `arrays` for a `Vec<[f64; N]>`).
//!
//! ```
//! #[derive(serde::Deserialize)]
//! struct Frame {
//!     #[serde(deserialize_with = "robocal_robot::exact::array")]
//!     xyz: [f64; 3],
//! }
//! assert!(toml::from_str::<Frame>("xyz = [1.0, 2.0, 3.0]").is_ok());
//! let err = toml::from_str::<Frame>("xyz = [1.0, 2.0, 3.0, 4.0]").err().unwrap();
//! assert!(err.to_string().contains("3 numbers"), "{err}");
//! ```

use serde::de::{Deserialize, Deserializer, Error};

fn exact<const N: usize, E: Error>(values: Vec<f64>) -> Result<[f64; N], E> {
    let found = values.len();
    values.try_into().map_err(|_| {
        E::custom(format!(
            "expected {N} numbers, found {found}{}",
            if found > N { " (one too many?)" } else { "" }
        ))
    })
}

/// Deserialises exactly `N` numbers.
pub fn array<'de, D: Deserializer<'de>, const N: usize>(d: D) -> Result<[f64; N], D::Error> {
    exact(Vec::<f64>::deserialize(d)?)
}

/// Deserialises an optional array of exactly `N` numbers.
pub fn option<'de, D: Deserializer<'de>, const N: usize>(
    d: D,
) -> Result<Option<[f64; N]>, D::Error> {
    Option::<Vec<f64>>::deserialize(d)?.map(exact).transpose()
}

/// Deserialises a list of arrays of exactly `N` numbers each.
pub fn arrays<'de, D: Deserializer<'de>, const N: usize>(d: D) -> Result<Vec<[f64; N]>, D::Error> {
    Vec::<Vec<f64>>::deserialize(d)?
        .into_iter()
        .map(exact)
        .collect()
}
