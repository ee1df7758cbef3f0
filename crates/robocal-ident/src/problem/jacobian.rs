//! The residuals of an identification and their Jacobians: exact where the model's joints
//! deflect, to first order elsewhere; and the mean distance's gradient.

use super::observations::{ROWS_PER_TASK, RowBlock};
use super::setup::CalibrationProblem;
use faer::Mat;
use nalgebra::{DMatrix, Matrix3, Vector3};
use rayon::prelude::*;
use robocal_robot::{
    Compliance, DeflectionRates, JointErrors, JointField, ParamId, ParamTwist, Robot, RowTerms,
    Turns, left_jacobian_inverse, rotation_vector, turn_rotation, turned,
};

/// The residuals, their Jacobians and the mean distance's gradient.
impl CalibrationProblem<'_> {
    /// The unweighted residuals (position rows, then the rotation rows times the angle weight)
    /// of `robot` (deflected by `compliance`), with the Jacobian of every table parameter and
    /// of every identified joint-error coefficient (unscaled, internal units).
    ///
    /// `exact`: with the table's columns' second-order terms — the deflection's own dependence
    /// on the table (a compliance times the change of the torques it holds, taken at the
    /// command) and the turns' (their turn of every column and the motion of the runouts' axes
    /// and origins); without them, the first-order columns ([`Self::first_order_jacobian`]).
    pub(super) fn full_jacobian(
        &self,
        robot: &Robot,
        compliance: Option<&Compliance>,
        exact: bool,
    ) -> (Vec<f64>, DMatrix<f64>, DMatrix<f64>) {
        let rows = self.rows();
        let mut full = DMatrix::zeros(rows, robot.param_count());
        let mut cjac = DMatrix::zeros(rows, self.error_params().len());
        let mut r = Vec::with_capacity(rows);
        for block in self.jacobian_blocks(robot, compliance, exact) {
            let first = block.first;
            (full.view_mut((first, 0), block.full.shape())).copy_from(&block.full);
            (cjac.view_mut((first, 0), block.cjac.shape())).copy_from(&block.cjac);
            r.extend(block.r);
        }
        (r, full, cjac)
    }

    /// [`Self::full_jacobian`]'s rows as the tasks that computed them hold them: blocks of
    /// consecutive rows in order (the points' in blocks of [`ROWS_PER_TASK`], then the measured
    /// orientations' in one), each entry the same number the whole matrices hold, which a
    /// caller that copies every row into a matrix of its own needs not assemble first.
    pub(super) fn jacobian_blocks(
        &self,
        robot: &Robot,
        compliance: Option<&Compliance>,
        exact: bool,
    ) -> Vec<RowBlock> {
        let m = self.obs.len();
        let params = self.error_params();
        let targets = self.obs.target_indices(robot);
        let waves = compliance.and_then(|c| self.row_waves(c));
        // Each joint's `theta` column: the joint Jacobian's column (every joint is revolute), of
        // which a joint-error coefficient's column is the sum over the joints it turns, each
        // times its basis value.
        let theta: Vec<usize> = (robot.param_ids().iter().enumerate())
            .filter_map(|(col, id)| match id {
                ParamId::Joint {
                    field: JointField::Theta,
                    ..
                } => Some(col),
                _ => None,
            })
            .collect();
        // The points' rows, a block of them per task on every core (each row's entries are its
        // own: the same matrices on any number of cores), the blocks in order.
        let mut blocks: Vec<RowBlock> = (targets.par_chunks(ROWS_PER_TASK).enumerate())
            .map(|(b, block)| {
                let first = b * ROWS_PER_TASK;
                let mut full = DMatrix::zeros(3 * block.len(), robot.param_count());
                let mut cjac = DMatrix::zeros(3 * block.len(), params.len());
                let mut r = Vec::with_capacity(3 * block.len());
                // One row's terms after the other in the same buffers.
                let mut row = RowTerms::default();
                for (l, &t) in block.iter().enumerate() {
                    let i = first + l;
                    let (q, load) = (self.obs.joints(i), self.obs.loads[i]);
                    let p = match compliance {
                        Some(c) => {
                            let waves = waves.map(|w| w.row(i));
                            c.write_row_terms(robot, q, load, params, waves, &mut row);
                            let p =
                                robot.write_param_jacobian_at(&row.deflected, t, &mut full, 3 * l);
                            for &(k, j, phi) in &row.basis {
                                for a in 0..3 {
                                    cjac[(3 * l + a, k)] += full[(3 * l + a, theta[j])] * phi;
                                }
                            }
                            if exact {
                                let columns = (&mut full, &mut cjac);
                                exact_terms(
                                    robot,
                                    c,
                                    (q, load),
                                    &row.turns,
                                    p,
                                    &theta,
                                    columns,
                                    3 * l,
                                );
                            }
                            // A tilt turns the parts beyond its joint about the joint's origin
                            // (the geometry's columns leave out the micro-radians it turns them
                            // by).
                            for &(k, origin, turn) in &row.turn_basis {
                                let column = turn.cross(&(p - origin));
                                for a in 0..3 {
                                    cjac[(3 * l + a, k)] += column[a];
                                }
                            }
                            turned(&row.turns, p)
                        }
                        None => robot.write_param_jacobian_at(q, t, &mut full, 3 * l),
                    };
                    r.extend_from_slice((p - self.obs.points[i]).as_slice());
                }
                RowBlock {
                    first: 3 * first,
                    r,
                    full,
                    cjac,
                }
            })
            .collect();
        if self.oriented.is_empty() {
            return blocks;
        }
        // The measured orientations' rows, one block after the points'.
        let n = 3 * self.oriented.len();
        let mut full = DMatrix::zeros(n, robot.param_count());
        let mut cjac = DMatrix::zeros(n, params.len());
        let mut r = Vec::with_capacity(n);
        let w = self.obs.angle_weight;
        for (k, &i) in self.oriented.iter().enumerate() {
            let (q, load) = (self.obs.joints(i), self.obs.loads[i]);
            let row = 3 * k;
            let rot = match compliance {
                Some(c) => {
                    let (_, jac) = c.orientation_param_jacobian(robot, q, load, params);
                    cjac.view_mut((row, 0), (3, params.len())).copy_from(&jac);
                    let deflected = c.deflected(robot, q, load);
                    let rot = robot.write_orientation_jacobian(&deflected, &mut full, row);
                    if exact {
                        // The joints turn the tool frame about their axes (their `theta`
                        // columns).
                        let joints = joint_columns(&full, &theta, row);
                        let rates = c.deflection_rates(robot, q, load);
                        let twists = robot.param_twists(q);
                        add_deflection_rates(&twists, &rates, &joints, &mut full, row);
                    }
                    // The tilts and the runouts turn the parts beyond their joints, the tool
                    // frame with them.
                    if !c.has_turns() {
                        rot
                    } else {
                        turn_rotation(&c.turns(robot, q, load)) * rot
                    }
                }
                None => robot.write_orientation_jacobian(q, &mut full, row),
            };
            // r = log(R Rₘᵀ): a turn δ of R moves it by J⁻¹(r) δ (exact, not only near r = 0).
            let phi = self.rotation_residual(i, &rot);
            let jinv = left_jacobian_inverse(&phi) * w;
            let block = jinv * full.view((row, 0), (3, full.ncols()));
            full.view_mut((row, 0), (3, full.ncols())).copy_from(&block);
            let block = jinv * cjac.view((row, 0), (3, cjac.ncols()));
            cjac.view_mut((row, 0), (3, cjac.ncols())).copy_from(&block);
            r.extend_from_slice((phi * w).as_slice());
        }
        blocks.push(RowBlock {
            first: 3 * m,
            r,
            full,
            cjac,
        });
        blocks
    }

    /// The rotation residual of observation `i` for a predicted tool frame: the rotation vector
    /// `log(R Rₘᵀ)` from the measured frame to the predicted one, rad (zero without a measured
    /// frame), before any weight.
    pub(super) fn rotation_residual(&self, i: usize, predicted: &Matrix3<f64>) -> Vector3<f64> {
        self.obs.orientation(i).map_or_else(Vector3::zeros, |m| {
            rotation_vector(&(predicted * m.transpose()))
        })
    }

    /// Every point's unweighted error vector (predicted − measured), mm, at `u`.
    pub fn point_errors(&self, u: &[f64]) -> Vec<nalgebra::Vector3<f64>> {
        let robot = self.robot_at(u);
        let compliance = self.compliance_at(u);
        let waves = compliance.as_ref().and_then(|c| self.row_waves(c));
        // Every core's share of the rows (each point its own: the same errors on any number).
        (0..self.obs.len())
            .into_par_iter()
            .with_min_len(ROWS_PER_TASK)
            .map(|i| {
                let waves = waves.map(|w| w.row(i));
                self.obs
                    .predict_on_waves(&robot, compliance.as_ref(), waves, i)
                    - self.obs.points[i]
            })
            .collect()
    }

    /// Predicted minus measured coordinates, mm, `3m` entries (each point's times the root of its
    /// weight when the problem is weighted), then, for each observation with a measured
    /// orientation, the rotation vector from the measured to the predicted tool frame times the
    /// angle weight (mm-equivalent; times the point's weight root too).
    pub fn residuals(&self, u: &[f64]) -> Vec<f64> {
        let mut r: Vec<f64> = (self.point_errors(u).iter().enumerate())
            .flat_map(|(i, d)| {
                let d = d * self.root_weight(i);
                [d.x, d.y, d.z]
            })
            .collect();
        if !self.oriented.is_empty() {
            let robot = self.robot_at(u);
            let compliance = self.compliance_at(u);
            for &i in &self.oriented {
                let predicted = self.obs.predict_rotation(&robot, compliance.as_ref(), i);
                let w = self.obs.angle_weight * self.root_weight(i);
                r.extend_from_slice((self.rotation_residual(i, &predicted) * w).as_slice());
            }
        }
        r
    }

    /// Residuals and the `3m × k` Jacobian with respect to `u`, the one the solvers step on.
    ///
    /// The joint errors' columns are exact. The table's are taken at the deflected joint angles,
    /// to first order ([`Self::first_order_jacobian`]): they leave out the torques' own
    /// dependence on the table (a compliance times a torque's change) and the turns' (tilts',
    /// runouts') dependence on it; the residual is exact, so LM converges to a true optimum.
    /// [`Self::exact_jacobian`] has those terms; stepping on it, on the paper's arm with the
    /// runouts, the solves converge in tens of iterations where these crawl to 200, but the fits
    /// land elsewhere (6 of 24 development cases lower and 6 higher, ARM6H by up to 123 %), and
    /// without runouts it converges no faster (compliance and self-weight on the paper's arm: 33 iterations and
    /// 2.0 s against 26 and 1.2 s, the same cost to four digits).
    pub fn residuals_and_jacobian(&self, u: &[f64]) -> (Vec<f64>, Mat<f64>) {
        self.residuals_and_columns(u, false, 0)
    }

    /// Residuals and the Jacobian with the table's columns exact for every smooth term
    /// (checked against central differences): the torques' own dependence on the geometry (the
    /// joints deflect under torques taken at the command, whose lever arms the table sets:
    /// [`JointErrors::deflection_rates`] along each parameter's [`Robot::param_twists`]); every
    /// column turned with the point by the tilts' and runouts' turns; the motion of the
    /// runouts' axes and origins. Left out: the tilts' moments' dependence on the table; a
    /// backlash flank's switch (not differentiable).
    pub fn exact_jacobian(&self, u: &[f64]) -> (Vec<f64>, Mat<f64>) {
        self.residuals_and_columns(u, true, 0)
    }

    /// The Jacobian at `u` with the table's columns to first order: the geometry's at the
    /// deflected angles, without the deflection's and the turns' own dependence on the table
    /// (a compliance times a torque's change, micro-radians of turn; [`Self::exact_jacobian`]
    /// has them). The identifiability analysis decides on these: those small terms would make
    /// combinations the poses cannot tell apart (joint 6's offset and the payload's centre of
    /// mass, say) look barely determined, through the compliances alone, and be identified,
    /// ill-conditioned.
    pub fn first_order_jacobian(&self, u: &[f64]) -> Mat<f64> {
        self.residuals_and_columns(u, false, 0).1
    }

    /// [`Self::residuals_and_jacobian`], the table's columns `exact` or to first order, with
    /// `extra` rows of zeros below the residuals' (for the priors' rows, which the caller
    /// writes: the Jacobian is not copied to make room for them).
    pub(super) fn residuals_and_columns(
        &self,
        u: &[f64],
        exact: bool,
        extra: usize,
    ) -> (Vec<f64>, Mat<f64>) {
        let robot = self.robot_at(u);
        let compliance = self.compliance_at(u);
        let ng = self.selected.len();
        let rows = self.rows();
        let blocks = self.jacobian_blocks(&robot, compliance.as_ref(), exact);
        let mut r = Vec::with_capacity(rows);
        for block in &blocks {
            r.extend_from_slice(&block.r);
        }
        let weights: Option<Vec<f64>> = (self.root_weights.as_ref())
            .map(|_| (0..rows).map(|row| self.row_weight(row)).collect());
        if let Some(weights) = &weights {
            for (v, w) in r.iter_mut().zip(weights) {
                *v *= w;
            }
        }
        // Column by column, each block's part of it (the blocks hold their columns whole):
        // each entry its column's scale times its row's weight root, in that order (without
        // weights, times nothing: a product with 1 is the same number).
        let mut jac = Mat::zeros(rows + extra, self.unknowns());
        for (col, &scale) in self.scale.iter().enumerate() {
            let column = jac.col_as_slice_mut(col);
            for block in &blocks {
                let (matrix, j) = if col < ng {
                    (&block.full, self.selected[col])
                } else {
                    (&block.cjac, col - ng)
                };
                let n = matrix.nrows();
                let source = &matrix.as_slice()[j * n..(j + 1) * n];
                let out = &mut column[block.first..block.first + n];
                match &weights {
                    Some(weights) => {
                        let weights = &weights[block.first..block.first + n];
                        for ((o, v), w) in out.iter_mut().zip(source).zip(weights) {
                            *o = v * scale * w;
                        }
                    }
                    None => {
                        for (o, v) in out.iter_mut().zip(source) {
                            *o = v * scale;
                        }
                    }
                }
            }
        }
        (r, jac)
    }

    /// The paper's cost, eq. (15): mean Euclidean distance, mm (of the points: measured
    /// orientations take no part in it).
    pub fn mean_distance(&self, u: &[f64]) -> f64 {
        let r = self.residuals(u);
        let m = self.obs.len().max(1) as f64;
        r[..3 * self.obs.len()]
            .chunks_exact(3)
            .map(|c| (c[0] * c[0] + c[1] * c[1] + c[2] * c[2]).sqrt())
            .sum::<f64>()
            / m
    }

    /// [`Self::mean_distance`] and its gradient `(1/m) Σ J_iᵀ r_i / |r_i|`. Rigid problems go
    /// through the poses one at a time, each pose's 3 × P Jacobian block written into one small
    /// buffer (no `3m × k` matrix is formed); a point with a zero residual (where the cost is
    /// not differentiable) contributes nothing to the gradient.
    pub fn mean_distance_and_gradient(&self, u: &[f64]) -> (f64, Vec<f64>) {
        if self.compliance.is_some() {
            return self.mean_distance_and_gradient_from_jacobian(u);
        }
        let robot = self.robot_at(u);
        let m = self.obs.len();
        let mut block = DMatrix::zeros(3, robot.param_count());
        let mut cost = 0.0;
        let mut g = vec![0.0; self.selected.len()];
        let targets = self.obs.target_indices(&robot);
        for (i, &t) in targets.iter().enumerate() {
            let d = robot.write_param_jacobian_at(self.obs.joints(i), t, &mut block, 0)
                - self.obs.points[i];
            let norm = d.norm();
            cost += norm;
            if norm == 0.0 {
                continue;
            }
            let unit = d / norm;
            for ((gk, &col), &scale) in g.iter_mut().zip(&self.selected).zip(&self.scale) {
                let c = block.column(col);
                *gk += (c[0] * unit.x + c[1] * unit.y + c[2] * unit.z) * scale;
            }
        }
        let m = m.max(1) as f64;
        g.iter_mut().for_each(|gk| *gk /= m);
        (cost / m, g)
    }

    /// The mean distance and its gradient through the full residual Jacobian.
    pub(super) fn mean_distance_and_gradient_from_jacobian(&self, u: &[f64]) -> (f64, Vec<f64>) {
        let (r, jac) = self.residuals_and_jacobian(u);
        let m = self.obs.len().max(1) as f64;
        let mut cost = 0.0;
        let mut g = vec![0.0; self.unknowns()];
        for (i, d) in r[..3 * self.obs.len()].chunks_exact(3).enumerate() {
            let norm = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
            cost += norm;
            if norm == 0.0 {
                continue;
            }
            for (k, gk) in g.iter_mut().enumerate() {
                *gk += (0..3).map(|a| jac[(3 * i + a, k)] * d[a]).sum::<f64>() / norm;
            }
        }
        g.iter_mut().for_each(|gk| *gk /= m);
        (cost / m, g)
    }
}

/// The second-order terms of [`CalibrationProblem::exact_jacobian`] in the position rows
/// `row..row + 3` of the table's columns `full` and the joint errors' `cjac` for the command `q`
/// under `load` (the point `p` before the `turns`; the joint errors' columns written from the
/// `theta` columns, the turns' own not yet): every column turned with the point — the turns
/// move it by `Σ t × (p − a)`, linear in `p`, so a column that moves `p` moves the turned point
/// `(I + Σ [t]×)` times as much —, then the torques' and the runouts' dependence on the table.
#[allow(clippy::too_many_arguments)]
pub(super) fn exact_terms(
    robot: &Robot,
    model: &JointErrors,
    (q, load): (&[f64], f64),
    turns: &Turns,
    p: Vector3<f64>,
    theta: &[usize],
    (full, cjac): (&mut DMatrix<f64>, &mut DMatrix<f64>),
    row: usize,
) {
    if !turns.is_empty() {
        let sum: Vector3<f64> = turns.iter().map(|(t, _)| t).sum();
        let turn = Matrix3::identity() + sum.cross_matrix();
        for m in [&mut *full, &mut *cjac] {
            let turned = turn * m.rows(row, 3);
            m.rows_mut(row, 3).copy_from(&turned);
        }
    }
    let joints = joint_columns(full, theta, row);
    let twists = robot.param_twists(q);
    let rates = model.deflection_rates(robot, q, load);
    add_deflection_rates(&twists, &rates, &joints, full, row);
    add_runout_rates(model, &twists, turns, p, full, row);
}

/// Each joint's column (its `theta` column) in rows `row..row + 3` of `full`: how the point
/// (or the tool frame) moves as the joint turns, copied before the table's columns change.
pub(super) fn joint_columns(full: &DMatrix<f64>, theta: &[usize], row: usize) -> Vec<Vector3<f64>> {
    (theta.iter())
        .map(|&c| full.fixed_view::<3, 1>(row, c).into_owned())
        .collect()
}

/// Adds to the table's columns in rows `row..row + 3` of `full` what the deflection adds as the
/// table moves the gravity torques it holds: `Σ_j joints[j] · δd_j`, with `δd_j` the rate of
/// joint `j`'s deflection ([`JointErrors::deflection_rates`]) along each joint parameter's
/// `twists` at the command ([`Robot::param_twists`]) and `joints[j]` the rows' column of joint
/// `j`. The base's parameters turn gravity with the arm: they move no torque.
pub(super) fn add_deflection_rates(
    twists: &[Option<ParamTwist>],
    rates: &DeflectionRates,
    joints: &[Vector3<f64>],
    full: &mut DMatrix<f64>,
    row: usize,
) {
    if rates.is_empty() {
        return;
    }
    for (col, twist) in twists.iter().enumerate() {
        let Some(ParamTwist {
            joint: Some(k),
            w,
            v,
            ..
        }) = twist
        else {
            continue;
        };
        let mut column = full.fixed_view_mut::<3, 1>(row, col);
        for (joint, rate) in joints.iter().zip(rates) {
            let (rw, rv) = rate[*k];
            column += joint * (rw.dot(w) + rv.dot(v));
        }
    }
}

/// Adds to the table's position columns in rows `row..row + 3` of `full` how the runouts'
/// turns of the point `p` (before them) change as the table moves their axes and origins: a
/// parameter that moves runout joint `j`'s frame by the twist `(ω, v)` turns its turn `t` by
/// `ω × t` and slides its origin `a` by `δa` (`ω × a + v`; the twist's `origin` for a parameter
/// of joint `j` itself), moving `t × (p − a)` by `(ω × t) × (p − a) − t × δa` (the part through
/// `p` is in the column already).
/// Tilts (turns under gravity moments) are left out.
pub(super) fn add_runout_rates(
    model: &JointErrors,
    twists: &[Option<ParamTwist>],
    turns: &Turns,
    p: Vector3<f64>,
    full: &mut DMatrix<f64>,
    row: usize,
) {
    if model.runouts.is_empty() {
        return;
    }
    let runouts = model.runout_turns(turns);
    for (col, twist) in twists.iter().enumerate() {
        let Some(ParamTwist {
            joint,
            w,
            v,
            origin,
        }) = twist
        else {
            continue;
        };
        let from = joint.unwrap_or(0);
        let mut column = full.fixed_view_mut::<3, 1>(row, col);
        for (r, (t, a)) in model.runouts.iter().zip(runouts) {
            let j = r.wave.joint;
            if j >= from {
                let slide = if *joint == Some(j) {
                    *origin
                } else {
                    w.cross(a) + v
                };
                column += w.cross(t).cross(&(p - a)) - t.cross(&slide);
            }
        }
    }
}
