//! Identifiability of a parameter selection with a pose set: which parameters the measurements
//! cannot separate (redundant with others, or without effect), the condition number and an
//! observability index of the scaled Jacobian, and parameter standard deviations.

use faer::Mat;
use faer::linalg::solvers::Solve;
use robocal_robot::{
    Across, ErrorParam, JointErrors, JointField, MomentPart, ParamId, backlash_name,
    compliance_name, harmonic_name, link_weight_name, payload_com_name, runout_name,
    self_weight_name, tilt_name,
};

/// Result of [`analyse`].
#[derive(Debug, Clone, PartialEq)]
pub struct Identifiability {
    /// Positions (in the analysed selection) of the parameters that can be identified.
    pub identifiable: Vec<usize>,
    /// Positions of the parameters that cannot, each with the fraction of its column left after
    /// projecting out the identifiable ones (0 = exactly redundant).
    pub unidentifiable: Vec<(usize, f64)>,
    /// Largest over smallest singular value of the scaled Jacobian of the identifiable set.
    pub condition_number: f64,
    /// Borm & Menq's O1: geometric mean of the singular values over √(measured points).
    pub observability_index: f64,
}

/// One column of an identification Jacobian: a parameter of the table, or a joint's compliance.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Column {
    /// A geometric parameter.
    Param(ParamId),
    /// The compliance of a joint (0-based).
    Compliance(usize),
    /// A transmission harmonic's sine (`cos: false`) or cosine coefficient.
    Harmonic {
        /// 0-based joint.
        joint: usize,
        /// Order.
        order: u32,
        /// The cosine coefficient.
        cos: bool,
    },
    /// A self-weight coefficient.
    SelfWeight {
        /// 0-based joint that deflects.
        joint: usize,
        /// 0-based link whose weight.
        body: usize,
        /// Which unit quantity.
        part: MomentPart,
    },
    /// The half play of a joint's backlash (0-based).
    Backlash(usize),
    /// A link's weight shared by the joints it loads.
    LinkWeight {
        /// 0-based link.
        body: usize,
        /// Its mass or a first moment.
        part: MomentPart,
    },
    /// A coordinate (0: x, 1: y, 2: z) of the payload's centre of mass in the flange frame.
    PayloadCom(usize),
    /// The tilting compliance of a joint (0-based).
    Tilt(usize),
    /// A runout's sine (`cos: false`) or cosine coefficient.
    Runout {
        /// 0-based joint.
        joint: usize,
        /// Order.
        order: u32,
        /// The axis of the joint's link frame it turns about.
        across: Across,
        /// The cosine coefficient.
        cos: bool,
    },
}

impl Column {
    /// The column of a joint-error coefficient of `errors`.
    pub fn of_error(errors: &JointErrors, p: ErrorParam) -> Self {
        match p {
            ErrorParam::Compliance(j) => Self::Compliance(j),
            ErrorParam::HarmonicSin(i) | ErrorParam::HarmonicCos(i) => Self::Harmonic {
                joint: errors.harmonics[i].joint,
                order: errors.harmonics[i].order,
                cos: matches!(p, ErrorParam::HarmonicCos(_)),
            },
            ErrorParam::SelfWeight(i) => Self::SelfWeight {
                joint: errors.self_weight[i].joint,
                body: errors.self_weight[i].body,
                part: errors.self_weight[i].part,
            },
            ErrorParam::Backlash(i) => Self::Backlash(errors.backlash[i].joint),
            ErrorParam::LinkWeight(i) => Self::LinkWeight {
                body: errors.link_weights[i].body,
                part: errors.link_weights[i].part,
            },
            ErrorParam::PayloadCom(axis) => Self::PayloadCom(axis),
            ErrorParam::Tilt(i) => Self::Tilt(errors.tilts[i].joint),
            ErrorParam::RunoutSin(i) | ErrorParam::RunoutCos(i) => {
                let r = &errors.runouts[i];
                Self::Runout {
                    joint: r.wave.joint,
                    order: r.wave.order,
                    across: r.across,
                    cos: matches!(p, ErrorParam::RunoutCos(_)),
                }
            }
        }
    }
}

impl From<ParamId> for Column {
    fn from(id: ParamId) -> Self {
        Self::Param(id)
    }
}

impl std::fmt::Display for Column {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Param(id) => id.fmt(f),
            Self::Compliance(j) => f.write_str(&compliance_name(*j)),
            Self::Harmonic { joint, order, cos } => {
                f.write_str(&harmonic_name(*joint, *order, *cos))
            }
            Self::SelfWeight { joint, body, part } => {
                f.write_str(&self_weight_name(*joint, *body, *part))
            }
            Self::Backlash(j) => f.write_str(&backlash_name(*j)),
            Self::LinkWeight { body, part } => f.write_str(&link_weight_name(*body, *part)),
            Self::PayloadCom(axis) => f.write_str(&payload_com_name(*axis)),
            Self::Tilt(j) => f.write_str(&tilt_name(*j)),
            Self::Runout {
                joint,
                order,
                across,
                cos,
            } => f.write_str(&runout_name(*joint, *order, *across, *cos)),
        }
    }
}

/// Which parameters of a redundant group to keep: the base and tool frames first (they are
/// what the tracker set-up changes; the named points beside the tool point), then joint parameters from the base outwards, then joint
/// compliances (a compliance the geometry already explains is the one named).
fn priority(column: Column) -> (usize, usize, usize) {
    let id = match column {
        Column::Param(id) => id,
        Column::Compliance(j) => return (3, j, 0),
        Column::Harmonic { joint, order, cos } => {
            return (4, joint, 2 * order as usize + usize::from(cos));
        }
        Column::SelfWeight { joint, body, part } => {
            return (5, joint, 4 * body + part as usize);
        }
        Column::Backlash(j) => return (6, j, 0),
        Column::LinkWeight { body, part } => return (7, body, part as usize),
        Column::PayloadCom(axis) => return (8, axis, 0),
        Column::Tilt(j) => return (9, j, 0),
        Column::Runout {
            joint,
            order,
            across,
            cos,
        } => {
            return (
                10,
                joint,
                4 * order as usize + 2 * across.column() + usize::from(cos),
            );
        }
    };
    match id {
        ParamId::Base(a) => (0, 0, a),
        ParamId::Tool(a) => (1, 0, a),
        ParamId::ToolRot(a) => (1, 0, 3 + a),
        ParamId::Point { index, axis } => (1, index + 1, axis),
        ParamId::Joint { index, field } => {
            let f = match field {
                JointField::Theta => 0,
                JointField::A => 1,
                JointField::Alpha => 2,
                JointField::D => 3,
                JointField::Beta => 4,
            };
            (2, index, f)
        }
    }
}

/// Analyses the scaled Jacobian `jac` (3m × k) of the parameters `ids`.
///
/// Columns are taken in priority order (base, tool, then joints from the base) and
/// orthogonalised against those already accepted (classical Gram–Schmidt, twice: as good as the
/// modified one twice, and done a matrix–vector product at a time); a column whose remaining
/// norm is below `tolerance` times its own is redundant. This is a QR factorisation with the
/// pivot order set by the physics rather than by column norms, so that of a redundant pair (e.g.
/// `j1.d` and `base.z`) the joint parameter is the one named.
pub fn analyse<C: Copy + Into<Column>>(
    jac: &Mat<f64>,
    ids: &[C],
    tolerance: f64,
) -> Identifiability {
    let (rows, k) = (jac.nrows(), jac.ncols());
    let mut order: Vec<usize> = (0..k).collect();
    order.sort_by_key(|&j| priority(ids[j].into()));
    let norms: Vec<f64> = (0..k)
        .map(|j| (0..rows).map(|i| jac[(i, j)].powi(2)).sum::<f64>().sqrt())
        .collect();
    let largest = norms.iter().copied().fold(0.0, f64::max);
    // The accepted columns, orthonormal, in the first `accepted` columns.
    let mut basis = Mat::<f64>::zeros(rows, k);
    let mut accepted = 0;
    let mut identifiable = Vec::new();
    let mut unidentifiable = Vec::new();
    for &j in &order {
        let mut v = jac.col(j).to_owned();
        let norm0 = norms[j];
        for _ in 0..2 {
            if accepted > 0 {
                let b = basis.as_ref().subcols(0, accepted);
                let along = b.transpose() * &v;
                v -= b * along;
            }
        }
        let norm = v.norm_l2();
        // A column that is round-off next to the others has no effect, whatever its direction.
        let effective = norm0 > tolerance * largest;
        let fraction = if effective { norm / norm0 } else { 0.0 };
        if effective && fraction > tolerance {
            basis.col_mut(accepted).copy_from(v * (1.0 / norm));
            accepted += 1;
            identifiable.push(j);
        } else {
            unidentifiable.push((j, fraction));
        }
    }
    identifiable.sort_unstable();
    unidentifiable.sort_by_key(|(j, _)| *j);
    let sub = Mat::from_fn(rows, identifiable.len(), |i, c| jac[(i, identifiable[c])]);
    let sv = if identifiable.is_empty() {
        Vec::new()
    } else {
        sub.singular_values().unwrap_or_default()
    };
    let (max, min) = sv.iter().fold((0.0f64, f64::INFINITY), |(mx, mn), &s| {
        (mx.max(s), mn.min(s))
    });
    let condition_number = if min > 0.0 && min.is_finite() {
        max / min
    } else {
        f64::INFINITY
    };
    let points = (rows / 3).max(1) as f64;
    let observability_index = if sv.is_empty() {
        0.0
    } else {
        (sv.iter().map(|s| s.max(1e-300).ln()).sum::<f64>() / sv.len() as f64).exp() / points.sqrt()
    };
    Identifiability {
        identifiable,
        unidentifiable,
        condition_number,
        observability_index,
    }
}

/// Standard deviations of the parameters (in `u` units) from the covariance `σ² (JᵀJ)⁻¹`, with
/// `σ² = Σr² / (3m − k)`. `None` when there are no degrees of freedom left or JᵀJ is singular.
pub fn standard_deviations(jac: &Mat<f64>, residuals: &[f64]) -> Option<Vec<f64>> {
    posterior_standard_deviations(jac, residuals, &[])
}

/// Standard deviations under zero-mean Gaussian priors on some unknowns: the posterior's
/// covariance `σ² (JᵀJ + Σ dⱼ² eⱼeⱼᵀ)⁻¹`, where each prior `(j, dⱼ)` is a row `dⱼ uⱼ` appended to
/// the least squares (`dⱼ = σ/τⱼ` in `u` units) and `σ² = Σr² / (3m − k)` is the data's residuals'
/// (`jac` and `residuals` without the priors' rows). Without priors, [`standard_deviations`].
pub fn posterior_standard_deviations(
    jac: &Mat<f64>,
    residuals: &[f64],
    prior: &[(usize, f64)],
) -> Option<Vec<f64>> {
    deviations_of(&posterior_covariance(jac, residuals, prior)?)
}

/// The ridge [`ridged_standard_deviations`] adds where `JᵀJ` is singular, as a fraction of its
/// largest diagonal entry: a hundred times above the round-off of `JᵀJ` with a hundred unknowns
/// (`10⁻¹⁶ k`), and below the smallest eigenvalues other than the null ones seen on the twins
/// (about `10⁻¹⁰` of the column-normalised `JᵀJ`, among runouts and offsets, whose columns'
/// squared norms differed there by up to 70 times).
pub const NULL_RIDGE: f64 = 1e-12;

/// The data's standard deviations ([`standard_deviations`]), or where `JᵀJ` is singular, those
/// under a vanishing ridge: `σ² (JᵀJ + ε I)⁻¹`, `ε` [`NULL_RIDGE`] times `JᵀJ`'s largest
/// diagonal entry (`σ²` the data's, as [`posterior_standard_deviations`]'s). A direction the data
/// leave undetermined comes out some 10⁶ times as uncertain as the best determined unknown, so
/// that it tells a prior's spread next to nothing, where the data's covariance says nothing at
/// all; the determined directions keep the data's. `None` with no degrees of freedom left.
pub fn ridged_standard_deviations(jac: &Mat<f64>, residuals: &[f64]) -> Option<Vec<f64>> {
    standard_deviations(jac, residuals).or_else(|| null_ridged_standard_deviations(jac, residuals))
}

/// The deviations under the vanishing ridge alone ([`ridged_standard_deviations`]' second
/// step), for a caller that already found the data's own covariance singular
/// ([`standard_deviations`] `None`): the same numbers without forming `JᵀJ` and failing its
/// factorisation again. `None` with no degrees of freedom left.
pub fn null_ridged_standard_deviations(jac: &Mat<f64>, residuals: &[f64]) -> Option<Vec<f64>> {
    let largest = (0..jac.ncols())
        .map(|j| (0..jac.nrows()).map(|i| jac[(i, j)].powi(2)).sum::<f64>())
        .fold(0.0, f64::max);
    let d = (NULL_RIDGE * largest).sqrt();
    let ridge: Vec<(usize, f64)> = (0..jac.ncols()).map(|j| (j, d)).collect();
    posterior_standard_deviations(jac, residuals, &ridge)
}

/// The roots of a covariance's diagonal; `None` when one is not finite.
pub fn deviations_of(cov: &Mat<f64>) -> Option<Vec<f64>> {
    let std: Vec<f64> = (0..cov.nrows())
        .map(|i| cov[(i, i)].max(0.0).sqrt())
        .collect();
    std.iter().all(|s| s.is_finite()).then_some(std)
}

/// The posterior's covariance of the unknowns (`u` units), `σ² (JᵀJ + Σ dⱼ² eⱼeⱼᵀ)⁻¹`, as in
/// [`posterior_standard_deviations`]. `None` when there are no degrees of freedom left or the
/// matrix is singular.
pub fn posterior_covariance(
    jac: &Mat<f64>,
    residuals: &[f64],
    prior: &[(usize, f64)],
) -> Option<Mat<f64>> {
    let (rows, k) = (jac.nrows(), jac.ncols());
    if rows <= k || k == 0 {
        return None;
    }
    let ssr: f64 = residuals.iter().map(|r| r * r).sum();
    let sigma2 = ssr / (rows - k) as f64;
    let mut a: Mat<f64> = jac.transpose() * jac;
    for &(j, d) in prior {
        if j < k {
            a[(j, j)] += d * d;
        }
    }
    let llt = a.llt(faer::Side::Lower).ok()?;
    let inv = llt.solve(Mat::<f64>::identity(k, k));
    Some(Mat::from_fn(k, k, |i, j| sigma2 * inv[(i, j)]))
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// The analysis column by column, as an independent check: modified Gram–Schmidt twice,
    /// every dot product a loop. The identifiable columns and each redundant one's fraction.
    fn modified_gram_schmidt(
        jac: &Mat<f64>,
        ids: &[Column],
        tolerance: f64,
    ) -> (Vec<usize>, Vec<(usize, f64)>) {
        let (rows, k) = (jac.nrows(), jac.ncols());
        let mut order: Vec<usize> = (0..k).collect();
        order.sort_by_key(|&j| priority(ids[j]));
        let column_norm = |j: usize| (0..rows).map(|i| jac[(i, j)].powi(2)).sum::<f64>().sqrt();
        let largest = (0..k).map(column_norm).fold(0.0, f64::max);
        let mut basis: Vec<Vec<f64>> = Vec::new();
        let (mut identifiable, mut unidentifiable) = (Vec::new(), Vec::new());
        for &j in &order {
            let mut v: Vec<f64> = (0..rows).map(|i| jac[(i, j)]).collect();
            let norm0 = v.iter().map(|x| x * x).sum::<f64>().sqrt();
            for _ in 0..2 {
                for b in &basis {
                    let dot: f64 = v.iter().zip(b).map(|(x, y)| x * y).sum();
                    v.iter_mut().zip(b).for_each(|(x, y)| *x -= dot * y);
                }
            }
            let norm = v.iter().map(|x| x * x).sum::<f64>().sqrt();
            let effective = norm0 > tolerance * largest;
            let fraction = if effective { norm / norm0 } else { 0.0 };
            if effective && fraction > tolerance {
                v.iter_mut().for_each(|x| *x /= norm);
                basis.push(v);
                identifiable.push(j);
            } else {
                unidentifiable.push((j, fraction));
            }
        }
        identifiable.sort_unstable();
        unidentifiable.sort_by_key(|(j, _)| *j);
        (identifiable, unidentifiable)
    }

    /// The analysis against the column-by-column one on a Jacobian with planted redundancies:
    /// a column that another one repeats, one that is a combination of three others up to a
    /// part far below the tolerance, one just above it, and one of no effect. The same columns
    /// identifiable, the same named redundant, their fractions to 1e-9.
    #[test]
    fn analysis_matches_column_by_column_gram_schmidt() {
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        let (rows, k) = (600, 20);
        let mut jac = Mat::from_fn(rows, k, |_, _| rng.random_range(-1.0..1.0));
        let noise: Vec<f64> = (0..rows).map(|_| rng.random_range(-1.0..1.0)).collect();
        for i in 0..rows {
            // Column 13 (a joint's) repeats column 0 (the base's x) scaled: the joint's is named.
            jac[(i, 13)] = 2.5 * jac[(i, 0)];
            // Column 7: a combination of 2, 4 and 9, and a part far below the tolerance; the
            // last of them in priority order (9) is named.
            jac[(i, 7)] = jac[(i, 2)] - 0.3 * jac[(i, 4)] + 0.7 * jac[(i, 9)] + 1e-10 * noise[i];
            // Column 11: the same with a part above it.
            jac[(i, 11)] = jac[(i, 3)] + 0.5 * jac[(i, 5)] + 1e-4 * noise[i];
            // Column 16: round-off next to the others.
            jac[(i, 16)] = 1e-12 * noise[i];
        }
        let fields = [
            JointField::Theta,
            JointField::A,
            JointField::Alpha,
            JointField::D,
        ];
        let ids: Vec<Column> = (0..k)
            .map(|j| match j {
                0..3 => Column::Param(ParamId::Base(j)),
                _ => Column::Param(ParamId::Joint {
                    index: (j - 3) / 4,
                    field: fields[(j - 3) % 4],
                }),
            })
            .collect();
        let tolerance = 1e-6;
        let ident = analyse(&jac, &ids, tolerance);
        let (identifiable, unidentifiable) = modified_gram_schmidt(&jac, &ids, tolerance);
        assert_eq!(ident.identifiable, identifiable);
        let named: Vec<usize> = ident.unidentifiable.iter().map(|u| u.0).collect();
        assert_eq!(named, [9, 13, 16], "{:?}", ident.unidentifiable);
        for ((j, a), (i, b)) in ident.unidentifiable.iter().zip(&unidentifiable) {
            assert_eq!(j, i);
            assert!((a - b).abs() < 1e-9, "column {j}: {a} against {b}");
        }
        assert!([0, 7, 11].iter().all(|j| identifiable.contains(j)));
    }
}
