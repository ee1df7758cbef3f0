//! Evaluating a joint-error model: the deflection of every joint, the point and orientation it
//! moves the tool to, and what a fit needs of each row (the basis of the coefficients, their
//! Jacobian, the rates under the table's parameters).

use nalgebra::{Matrix3, Matrix3xX, Vector3};

use super::gravity::{MomentPart, Pose, Quantity, unit_torque};
use super::model::{
    DeflectionRates, ErrorParam, JointErrors, RowTerms, turn_rotation, turned, turned_by,
};
use super::self_weight::LinkUnits;
use super::terms::PoseCache;
use crate::table::Robot;

/// The terms of one row that the deflection and the basis share ([`JointErrors::row_terms`]).
pub(super) struct RowShared {
    /// The gravity torque about every joint (N·m) that the compliances meet.
    pub(super) torques: Vec<f64>,
    /// Each link weight's unit torque about every joint up to its link's.
    pub(super) links: LinkUnits,
    /// The basis value of every self-weight term.
    pub(super) self_weight: Vec<f64>,
    /// The flank (`±1`) of every backlash term.
    pub(super) flanks: Vec<f64>,
}

/// `q` (rad) turned by the deflection `d` (rad), in `d`'s buffer (`d + q` is `q + d` to the bit).
pub(super) fn deflected_by(q: &[f64], mut d: Vec<f64>) -> Vec<f64> {
    deflect(q, &mut d);
    d
}

/// The deflection `d` (rad) turned into the angles the arm takes from `q` (rad), in place.
pub(super) fn deflect(q: &[f64], d: &mut [f64]) {
    for (d, q) in d.iter_mut().zip(q) {
        *d += q;
    }
}

impl JointErrors {
    /// For each of `params` (by position `k`), the joints it turns and its basis value there at
    /// command `q` (rad) under `load` kg, as entries `(k, joint, value)`: the coefficient's
    /// deflection of the joint per unit. Every term turns its one joint, except a link weight,
    /// which turns every joint up to its link's by the joint's compliance times its torque, and
    /// a coordinate of the payload's centre of mass, which turns every joint so.
    pub fn basis(
        &self,
        robot: &Robot,
        q: &[f64],
        load: f64,
        params: &[ErrorParam],
    ) -> Vec<(usize, usize, f64)> {
        self.basis_at(&self.pose(robot, q), load, params)
    }

    /// [`Self::basis`] at the command `pose` holds.
    pub(super) fn basis_at(
        &self,
        pose: &PoseCache,
        load: f64,
        params: &[ErrorParam],
    ) -> Vec<(usize, usize, f64)> {
        let mut out = Vec::new();
        let shared = self.shared_at(pose, load, params);
        self.basis_into(pose, load, params, &shared, &mut out);
        out
    }

    /// What the deflection and the basis at the command `pose` holds under `load` kg share,
    /// each computed once: the gravity torques the compliances meet, the links' unit torques,
    /// the self-weight basis and the backlash flanks.
    pub(super) fn shared_at(
        &self,
        pose: &PoseCache,
        load: f64,
        params: &[ErrorParam],
    ) -> RowShared {
        let links = self.link_weight_basis(pose, params);
        let torques = self.with_link_torques(self.torques_at(pose, load), |i, _, j| links.of(i)[j]);
        RowShared {
            torques,
            links,
            self_weight: self.self_weight_basis(pose, params),
            flanks: self.flanks(pose, load),
        }
    }

    /// [`Self::basis`] at the command `pose` holds, from its `shared` terms, written into `out`
    /// (emptied first, its capacity kept: a fit's rows fill one buffer in turn).
    pub(super) fn basis_into(
        &self,
        pose: &PoseCache,
        load: f64,
        params: &[ErrorParam],
        shared: &RowShared,
        out: &mut Vec<(usize, usize, f64)>,
    ) {
        let RowShared {
            torques,
            links,
            self_weight: sw,
            flanks,
        } = shared;
        out.clear();
        out.reserve(params.len());
        for (k, &p) in params.iter().enumerate() {
            match p {
                ErrorParam::Compliance(j) => out.push((k, j, torques[j])),
                ErrorParam::HarmonicSin(i) => {
                    out.push((k, self.harmonics[i].joint, pose.waves(self)[i].0));
                }
                ErrorParam::HarmonicCos(i) => {
                    out.push((k, self.harmonics[i].joint, pose.waves(self)[i].1));
                }
                ErrorParam::SelfWeight(i) => out.push((k, self.self_weight[i].joint, sw[i])),
                ErrorParam::Backlash(i) => out.push((k, self.backlash[i].joint, flanks[i])),
                ErrorParam::LinkWeight(i) => {
                    for (j, phi) in links.of(i).iter().enumerate() {
                        if self.values[j] != 0.0 {
                            out.push((k, j, self.values[j] * phi));
                        }
                    }
                }
                // The payload's torque per mm of its centre of mass along the flange's axis,
                // on every joint (none without a load).
                ErrorParam::PayloadCom(axis) if load != 0.0 => {
                    let Pose { axes, frames, g } = pose.get();
                    let flange = frames.last().expect("an arm has a joint");
                    let part = [MomentPart::X, MomentPart::Y, MomentPart::Z][axis];
                    for (j, axis) in axes.iter().enumerate() {
                        if self.values[j] != 0.0 {
                            let phi = load * 1e-3 * unit_torque(axis, flange, g, part);
                            out.push((k, j, self.values[j] * phi));
                        }
                    }
                }
                // A tilt or a runout turns no joint ([`Self::turn_basis_into`]), nor a coordinate
                // of the payload's centre of mass without a load.
                ErrorParam::PayloadCom(_)
                | ErrorParam::Tilt(_)
                | ErrorParam::RunoutSin(_)
                | ErrorParam::RunoutCos(_) => {}
            }
        }
    }

    /// How far each joint turns from command `q` (rad) under `load` kg, rad: compliance ×
    /// torque of the payload and of the links' weights, plus the harmonics, the self-weight
    /// terms and the backlash.
    pub fn deflection(&self, robot: &Robot, q: &[f64], load: f64) -> Vec<f64> {
        self.deflection_at(&self.pose(robot, q), load)
    }

    /// [`Self::deflection`] at the command `pose` holds.
    pub(super) fn deflection_at(&self, pose: &PoseCache, load: f64) -> Vec<f64> {
        self.deflection_of(
            pose,
            &self.load_torques_at(pose, load),
            &self.flanks(pose, load),
        )
    }

    /// How far each joint turns from the command `pose` holds (rad): compliance × the gravity
    /// `torques`, plus the harmonics, the self-weight terms and the backlash on its `flanks`.
    pub(super) fn deflection_of(
        &self,
        pose: &PoseCache,
        torques: &[f64],
        flanks: &[f64],
    ) -> Vec<f64> {
        let mut d: Vec<f64> = (self.values.iter().zip(torques))
            .map(|(c, t)| c * t)
            .collect();
        self.add_joint_terms(pose, None, flanks, &mut d);
        d
    }

    /// [`Self::deflection_of`] written into `d` (emptied first, its capacity kept), from the
    /// row's gravity torques, self-weight basis and flanks.
    pub(super) fn deflection_into(
        &self,
        pose: &PoseCache,
        (torques, sw, flanks): (&[f64], &[f64], &[f64]),
        d: &mut Vec<f64>,
    ) {
        d.clear();
        d.extend((self.values.iter().zip(torques)).map(|(c, t)| c * t));
        self.add_joint_terms(pose, Some(sw), flanks, d);
    }

    /// Adds to the compliances' deflection `d` (rad) the harmonics at the command `pose` holds,
    /// the self-weight terms on their basis (`sw`, [`Self::self_weight_basis`]; computed here
    /// without it) and the backlash on its `flanks`.
    pub(super) fn add_joint_terms(
        &self,
        pose: &PoseCache,
        sw: Option<&[f64]>,
        flanks: &[f64],
        d: &mut [f64],
    ) {
        if !self.harmonics.is_empty() {
            for (h, &basis) in self.harmonics.iter().zip(pose.waves(self)) {
                d[h.joint] += h.value_on(basis);
            }
        }
        for (i, t) in self.self_weight.iter().enumerate() {
            if t.value != 0.0 {
                d[t.joint] += t.value * sw.map_or_else(|| t.basis_at(&pose.get()), |sw| sw[i]);
            } else if d[t.joint] == 0.0 && d[t.joint].is_sign_negative() {
                // A term at zero adds ±0: that leaves every sum as it is but −0, which +0 turns
                // +0 — the one case its basis (not computed: `sw` holds 0 for it) decides.
                d[t.joint] += t.value * t.basis_at(&pose.get());
            }
        }
        for (b, s) in self.backlash.iter().zip(flanks) {
            d[b.joint] += b.value * s;
        }
    }

    /// The joint angles the arm really takes for command `q` (rad) under `load` kg, rad.
    pub fn deflected(&self, robot: &Robot, q: &[f64], load: f64) -> Vec<f64> {
        self.deflected_at(&self.pose(robot, q), load)
    }

    /// [`Self::deflected`] at the command `pose` holds.
    pub(super) fn deflected_at(&self, pose: &PoseCache, load: f64) -> Vec<f64> {
        if self.holds_still(load) {
            return pose.q.to_vec();
        }
        deflected_by(pose.q, self.deflection_at(pose, load))
    }

    /// Whether no joint turns under `load` kg: no load and no term that acts without one.
    pub(super) fn holds_still(&self, load: f64) -> bool {
        load == 0.0 && !self.has_configuration_terms()
    }

    /// What one row of an identification needs at command `q` (rad) under `load` kg, the arm's
    /// frames at `q` computed once for all: the joint angles the arm really takes
    /// ([`Self::deflected`]), the basis of `params` there ([`Self::basis`]), the tilting joints'
    /// turns ([`Self::turns`]) and the turns of `params` per unit.
    pub fn row_terms(
        &self,
        robot: &Robot,
        q: &[f64],
        load: f64,
        params: &[ErrorParam],
    ) -> RowTerms {
        let mut out = RowTerms::default();
        self.row_terms_into(&self.pose(robot, q), load, params, &mut out);
        out
    }

    /// [`Self::row_terms`] with the bases of the model's waves at `q` given, as
    /// [`Self::wave_bases`] computes them (the same terms to the bit; none computed again).
    pub fn row_terms_on_waves(
        &self,
        robot: &Robot,
        q: &[f64],
        load: f64,
        params: &[ErrorParam],
        waves: &[(f64, f64)],
    ) -> RowTerms {
        let mut out = RowTerms::default();
        self.write_row_terms(robot, q, load, params, Some(waves), &mut out);
        out
    }

    /// [`Self::row_terms`] (with the bases of the model's waves at `q` given, as
    /// [`Self::row_terms_on_waves`], or computed) written into `out`, whose vectors are emptied
    /// and filled again, their capacity kept: a fit's rows, one after the other, allocate none
    /// of them again. The same terms to the bit.
    pub fn write_row_terms(
        &self,
        robot: &Robot,
        q: &[f64],
        load: f64,
        params: &[ErrorParam],
        waves: Option<&[(f64, f64)]>,
        out: &mut RowTerms,
    ) {
        self.row_terms_into(&self.pose_on(robot, q, waves), load, params, out);
    }

    /// [`Self::row_terms`] at the command `pose` holds, written into `out`.
    pub(super) fn row_terms_into(
        &self,
        pose: &PoseCache,
        load: f64,
        params: &[ErrorParam],
        out: &mut RowTerms,
    ) {
        let q = pose.q;
        let shared = self.shared_at(pose, load, params);
        if self.holds_still(load) {
            out.deflected.clear();
            out.deflected.extend_from_slice(q);
        } else {
            let RowShared {
                torques,
                self_weight,
                flanks,
                ..
            } = &shared;
            self.deflection_into(pose, (torques, self_weight, flanks), &mut out.deflected);
            deflect(q, &mut out.deflected);
        }
        self.basis_into(pose, load, params, &shared, &mut out.basis);
        self.turns_into(pose, load, &mut out.turns);
        self.turn_basis_into(pose, load, params, &mut out.turn_basis);
    }

    /// How each joint's deflection at command `q` (rad) under `load` kg changes with the
    /// table's parameters, through the gravity torques it holds ([`DeflectionRates`]): the
    /// payload's and the links' weights' times the joint's compliance, and the self-weight
    /// terms. The harmonics and the backlash (a flank is constant between its switches) do not
    /// move with the table.
    pub fn deflection_rates(&self, robot: &Robot, q: &[f64], load: f64) -> DeflectionRates {
        let compliant = self.values.iter().any(|&c| c != 0.0);
        if !compliant && self.self_weight.is_empty() {
            return Vec::new();
        }
        let pose = self.pose(robot, q);
        let Pose { axes, frames, g } = pose.get();
        let dof = axes.len();
        let zero = (Vector3::zeros(), Vector3::zeros());
        let mut out = vec![vec![zero; dof]; dof];
        for (j, row) in out.iter_mut().enumerate() {
            // Every torque term joint `j` deflects by: (its link, quantity, coefficient).
            let mut terms: Vec<(usize, Quantity, f64)> = Vec::new();
            let c = self.values[j];
            if c != 0.0 {
                if load != 0.0 {
                    let (r, o) = frames.last().expect("an arm has a joint");
                    let com = o + r * self.payload_com;
                    terms.push((dof - 1, Quantity::Point(com), c * load));
                }
                for lw in self.link_weights.iter().filter(|lw| lw.body >= j) {
                    let quantity = Quantity::of(&frames[lw.body], lw.part);
                    terms.push((lw.body, quantity, c * lw.value));
                }
            }
            for t in self.self_weight.iter().filter(|t| t.joint == j) {
                terms.push((t.body, Quantity::of(&frames[t.body], t.part), t.value));
            }
            if terms.is_empty() {
                continue;
            }
            // A parameter of joint `k <= j` moves the axis and every term together; one of
            // `k > j` moves the terms on links `k` and beyond alone.
            let mut together = Vector3::zeros();
            let mut alone = vec![zero; dof];
            for (body, quantity, coefficient) in terms {
                let (t, (aw, av)) = quantity.rates(&axes[j], g);
                together += t * coefficient;
                alone[body].0 += aw * coefficient;
                alone[body].1 += av * coefficient;
            }
            for entry in row.iter_mut().take(j + 1) {
                *entry = (together, Vector3::zeros());
            }
            let mut from = zero;
            for k in (j + 1..dof).rev() {
                from.0 += alone[k].0;
                from.1 += alone[k].1;
                row[k] = from;
            }
        }
        out
    }

    /// Jacobian of the point with respect to each of `params` (mm per internal unit), and the
    /// point, at command `q` under `load`: column `k` is the sum, over the joints the coefficient
    /// turns, of the joint Jacobian's column at the deflected angles times its basis value there,
    /// plus, over the tilting joints it turns the parts beyond, `t × (p − a)` (`t` its turn per
    /// unit, `a` the joint's origin; the tilts' and runouts' own effect on the other columns,
    /// micro-radians times the column, is left out).
    pub fn param_jacobian(
        &self,
        robot: &Robot,
        q: &[f64],
        load: f64,
        params: &[ErrorParam],
    ) -> (Vector3<f64>, Matrix3xX<f64>) {
        let row = self.row_terms(robot, q, load, params);
        let joint = robot.joint_jacobian(&row.deflected);
        let p = robot.point(&row.deflected);
        let mut jac = Matrix3xX::zeros(params.len());
        for (k, j, phi) in row.basis {
            let mut column = jac.column_mut(k);
            column += joint.column(j) * phi;
        }
        for (k, a, t) in row.turn_basis {
            let mut column = jac.column_mut(k);
            column += t.cross(&(p - a));
        }
        (turned(&row.turns, p), jac)
    }

    /// Jacobian of the tool frame's orientation with respect to each of `params` (rad per
    /// internal unit, world-frame rotation vectors), and the tool frame's rotation, at command
    /// `q` under `load`: column `k` is the sum, over the joints the coefficient turns, of the
    /// joint's axis at the deflected angles times its basis value there, plus its turns per unit
    /// of the tilting joints.
    pub fn orientation_param_jacobian(
        &self,
        robot: &Robot,
        q: &[f64],
        load: f64,
        params: &[ErrorParam],
    ) -> (Matrix3<f64>, Matrix3xX<f64>) {
        let row = self.row_terms(robot, q, load, params);
        let axes = robot.joint_axes(&row.deflected);
        let mut jac = Matrix3xX::zeros(params.len());
        for (k, j, phi) in row.basis {
            let mut column = jac.column_mut(k);
            column += axes.axes[j].0 * phi;
        }
        for (k, _, t) in row.turn_basis {
            let mut column = jac.column_mut(k);
            column += t;
        }
        (
            turn_rotation(&row.turns) * axes.flange_rotation * robot.tool_frame_rotation(),
            jac,
        )
    }

    /// The tool frame's orientation for command `q` (rad) under `load` kg, world frame.
    pub fn rotation(&self, robot: &Robot, q: &[f64], load: f64) -> Matrix3<f64> {
        let pose = self.pose(robot, q);
        let r = robot.tool_rotation(&self.deflected_at(&pose, load));
        if !self.has_turns() {
            return r;
        }
        turn_rotation(&self.turns_at(&pose, load)) * r
    }

    /// The model's target point for command `q` (rad) under `load` kg, mm, world frame.
    pub fn point(&self, robot: &Robot, q: &[f64], load: f64) -> Vector3<f64> {
        self.point_at(&self.pose(robot, q), load)
    }

    /// [`Self::point`] with the bases of the model's waves at `q` given, as [`Self::wave_bases`]
    /// computes them (the same point to the bit; none computed again).
    pub fn point_on_waves(
        &self,
        robot: &Robot,
        q: &[f64],
        load: f64,
        waves: &[(f64, f64)],
    ) -> Vector3<f64> {
        self.point_at(&self.pose_on(robot, q, Some(waves)), load)
    }

    /// [`Self::point`] at the command `pose` holds.
    pub(super) fn point_at(&self, pose: &PoseCache, load: f64) -> Vector3<f64> {
        let p = pose.robot.point(&self.deflected_at(pose, load));
        if !self.has_turns() {
            return p;
        }
        turned_by(self.each_turn(pose, load), p)
    }

    /// Jacobian of the point with respect to each joint's compliance (mm per rad/(N·m)), and
    /// the point, at command `q` under `load`: column `i` is the joint Jacobian's column at the
    /// deflected angles times the torque on joint `i`.
    pub fn jacobian(&self, robot: &Robot, q: &[f64], load: f64) -> (Vector3<f64>, Matrix3xX<f64>) {
        let every: Vec<ErrorParam> = (0..self.values.len()).map(ErrorParam::Compliance).collect();
        self.param_jacobian(robot, q, load, &every)
    }
}
