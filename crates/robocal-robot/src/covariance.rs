//! The identified parameters' covariance, and what it makes of a predicted point's spread.
//!
//! An identification leaves each parameter it determines with an uncertainty, and the
//! parameters with correlations: `C = σ² (JᵀJ + P)⁻¹` (the residuals' variance `σ²`, the
//! Jacobian `J` of the points over the identified parameters, `P` the priors' rows). A point
//! predicted at a command `q` moves with them: to first order its covariance is
//! `J(q) C J(q)ᵀ`, and its standard deviation (the root sum of the three axes' variances, as a
//! Gaussian process residual gives it) is `√tr(J(q) C J(q)ᵀ)`. [`ParameterCovariance::directions`]
//! factors `C = A Aᵀ` (its eigenvectors times the roots of its eigenvalues), so that the point's
//! variance is `Σ_k |J(q) a_k|²`, each term a central difference of the prediction along one
//! column `a_k`: no Jacobian of the model is needed, and no linearisation beyond the
//! parameters' own spread.

use nalgebra::{DMatrix, SymmetricEigen};
use serde::{Deserialize, Serialize};

use crate::compliance::{ErrorParam, JointErrors, payload_com_name};
use crate::params::ParamId;
use crate::table::Robot;

/// One identified parameter: a table entry or a joint-error coefficient.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Parameter {
    /// A parameter of the table (MDH entry, base, tool, named point).
    Table(ParamId),
    /// A coefficient of the joint errors.
    Error(ErrorParam),
}

/// The covariance of the identified parameters (internal units: mm, rad, and the joint
/// errors' own), by their stable names.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ParameterCovariance {
    /// The identified parameters' names (`j2.beta`, `base.x`, `j3.h2.sin`, `j2.compliance`), in
    /// the order of the matrix's rows and columns.
    pub parameters: Vec<String>,
    /// The covariance, one row per parameter, internal units.
    pub matrix: Vec<Vec<f64>>,
}

impl ParameterCovariance {
    /// A covariance of `parameters` (`matrix`, `k × k`), made exactly symmetric (an inverse
    /// computed by solves is symmetric only to round-off, which an ill-conditioned fit
    /// magnifies).
    pub fn new(parameters: Vec<String>, matrix: &DMatrix<f64>) -> Self {
        let k = matrix.nrows().min(matrix.ncols());
        let matrix = (0..k)
            .map(|i| {
                (0..k)
                    .map(|j| 0.5 * (matrix[(i, j)] + matrix[(j, i)]))
                    .collect()
            })
            .collect();
        Self { parameters, matrix }
    }

    /// The first fault as (field, message): a matrix that is not square over the parameters,
    /// not finite, not symmetric, with a negative variance; a name twice.
    pub fn check(&self) -> std::result::Result<(), (String, String)> {
        let k = self.parameters.len();
        let fault = |field: &str, message: String| Err((field.to_string(), message));
        if self.matrix.len() != k || self.matrix.iter().any(|row| row.len() != k) {
            return fault(
                "matrix",
                format!("must be {k} rows of {k} numbers, one per parameter"),
            );
        }
        for (i, name) in self.parameters.iter().enumerate() {
            if self.parameters[..i].contains(name) {
                return fault("parameters", format!("`{name}` is named twice"));
            }
        }
        for (i, row) in self.matrix.iter().enumerate() {
            for (j, &v) in row.iter().enumerate() {
                if !v.is_finite() {
                    return fault(
                        "matrix",
                        format!("row {}, column {}: not finite", i + 1, j + 1),
                    );
                }
                // Asymmetry against the scale of the two variances (a correlation's part in a
                // million): what a matrix written with fewer digits still passes.
                let w = self.matrix[j][i];
                let scale = (self.matrix[i][i] * self.matrix[j][j]).abs().sqrt();
                if !w.is_finite() || (v - w).abs() > 1e-6 * scale {
                    return fault(
                        "matrix",
                        format!("not symmetric at row {}, column {}", i + 1, j + 1),
                    );
                }
            }
            if row[i] < 0.0 {
                return fault(
                    "matrix",
                    format!("the variance of `{}` is negative", self.parameters[i]),
                );
            }
        }
        Ok(())
    }

    /// Each named parameter as a parameter of `robot` and its joint errors `errors`: an error
    /// names the first name neither has.
    pub fn resolve(
        &self,
        robot: &Robot,
        errors: Option<&JointErrors>,
    ) -> std::result::Result<Vec<Parameter>, String> {
        let mut known: Vec<(String, Parameter)> = (robot.param_ids().into_iter())
            .map(|id| (id.to_string(), Parameter::Table(id)))
            .collect();
        if let Some(e) = errors {
            known.extend((e.params().into_iter()).map(|p| (e.param_name(p), Parameter::Error(p))));
            known.extend((0..3).map(|axis| {
                (
                    payload_com_name(axis),
                    Parameter::Error(ErrorParam::PayloadCom(axis)),
                )
            }));
        }
        (self.parameters.iter())
            .map(|name| {
                (known.iter())
                    .find(|(n, _)| n == name)
                    .map(|&(_, p)| p)
                    .ok_or_else(|| {
                        format!("`{name}` is no parameter of the model's table or joint errors")
                    })
            })
            .collect()
    }

    /// Columns `a_k` with `C = Σ_k a_k a_kᵀ` (an eigenvector times the root of its eigenvalue,
    /// the nonpositive ones left out).
    pub fn directions(&self) -> Vec<Vec<f64>> {
        let k = self.parameters.len();
        if k == 0 {
            return Vec::new();
        }
        let c = DMatrix::from_fn(k, k, |i, j| 0.5 * (self.matrix[i][j] + self.matrix[j][i]));
        let eigen = SymmetricEigen::new(c);
        (0..k)
            .filter(|&i| eigen.eigenvalues[i] > 0.0)
            .map(|i| {
                let root = eigen.eigenvalues[i].sqrt();
                eigen
                    .eigenvectors
                    .column(i)
                    .iter()
                    .map(|v| v * root)
                    .collect()
            })
            .collect()
    }
}

/// `robot` and `errors` with `step[i]` added to each parameter `parameters[i]` (a table entry the
/// table lacks is left as it is: [`ParameterCovariance::resolve`] finds only the table's).
pub fn displaced(
    robot: &Robot,
    errors: Option<&JointErrors>,
    parameters: &[Parameter],
    step: &[f64],
) -> (Robot, Option<JointErrors>) {
    let mut robot = robot.clone();
    let mut errors = errors.cloned();
    for (&p, &d) in parameters.iter().zip(step) {
        match p {
            Parameter::Table(id) => {
                let v = robot.param(id);
                let _ = robot.set_param(id, v + d);
            }
            Parameter::Error(e) => {
                if let Some(errors) = errors.as_mut() {
                    let v = errors.param(e);
                    errors.set_param(e, v + d);
                }
            }
        }
    }
    (robot, errors)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cov(matrix: Vec<Vec<f64>>) -> ParameterCovariance {
        let parameters = (0..matrix.len()).map(|i| format!("p{i}")).collect();
        ParameterCovariance { parameters, matrix }
    }

    #[test]
    fn directions_rebuild_the_matrix() {
        let c = cov(vec![
            vec![4.0, 1.0, 0.5],
            vec![1.0, 2.0, -0.3],
            vec![0.5, -0.3, 0.2],
        ]);
        // Two parameters the data can only tell together (a singular matrix): still rebuilt.
        let singular = cov(vec![vec![1.0, 1.0], vec![1.0, 1.0]]);
        for c in [&c, &singular] {
            c.check().unwrap();
            let a = c.directions();
            let k = c.parameters.len();
            for i in 0..k {
                for j in 0..k {
                    let s: f64 = a.iter().map(|d| d[i] * d[j]).sum();
                    assert!((s - c.matrix[i][j]).abs() < 1e-12, "{i} {j}: {s}");
                }
            }
        }
    }

    /// An inverse computed by solves, symmetric only to round-off, is stored exactly symmetric.
    #[test]
    fn a_matrix_symmetric_to_round_off_is_made_exactly_symmetric() {
        let mut m = DMatrix::from_row_slice(2, 2, &[1e-12, 3e-13, 3e-13 * (1.0 + 1e-7), 2e-12]);
        let c = ParameterCovariance::new(vec!["a".into(), "b".into()], &m);
        assert_eq!(c.matrix[0][1], c.matrix[1][0]);
        c.check().unwrap();
        // As written by hand, asymmetric beyond round-off: refused.
        m[(1, 0)] = 6e-13;
        let raw = ParameterCovariance {
            parameters: c.parameters.clone(),
            matrix: vec![vec![m[(0, 0)], m[(0, 1)]], vec![m[(1, 0)], m[(1, 1)]]],
        };
        assert_eq!(raw.check().unwrap_err().0, "matrix");
    }

    #[test]
    fn faults_are_named() {
        let field = |c: ParameterCovariance| c.check().unwrap_err().0;
        assert_eq!(field(cov(vec![vec![1.0, 0.0], vec![0.0]])), "matrix");
        assert_eq!(field(cov(vec![vec![1.0, 0.2], vec![0.3, 1.0]])), "matrix");
        assert_eq!(field(cov(vec![vec![-1.0]])), "matrix");
        assert_eq!(field(cov(vec![vec![f64::NAN]])), "matrix");
        let mut twice = cov(vec![vec![1.0, 0.0], vec![0.0, 1.0]]);
        twice.parameters = vec!["a".into(), "a".into()];
        assert_eq!(field(twice), "parameters");
    }
}
