//! Forward kinematics and analytic Jacobians (world frame, mm, rad).
//!
//! The Jacobians use the screw form: a rotation `s` about a unit axis `w` through `o` moves the
//! point `p` by `w × (p − o) ds`; a translation along `w` moves it by `w ds`. One forward pass
//! gives the point, a second pass writes every column, so nothing is allocated per entry.

use std::cell::Cell;

use nalgebra::{DMatrix, IsometryMatrix3, Matrix3, Matrix3xX, Rotation3, Translation3, Vector3};

use crate::table::{Joint, Robot};

/// A joint's axis in the world frame: unit direction, and a point on it (mm).
pub type Axis = (Vector3<f64>, Vector3<f64>);

/// A frame in the world frame: rotation, and origin (mm).
pub type Frame = (Matrix3<f64>, Vector3<f64>);

/// Rotation about x by an angle with cosine `c` and sine `s`.
#[inline]
fn rot_x(c: f64, s: f64) -> Matrix3<f64> {
    Matrix3::new(1.0, 0.0, 0.0, 0.0, c, -s, 0.0, s, c)
}

#[inline]
fn rot_y(c: f64, s: f64) -> Matrix3<f64> {
    Matrix3::new(c, 0.0, s, 0.0, 1.0, 0.0, -s, 0.0, c)
}

#[inline]
fn rot_z(c: f64, s: f64) -> Matrix3<f64> {
    Matrix3::new(c, -s, 0.0, s, c, 0.0, 0.0, 0.0, 1.0)
}

/// [`table_sin_cos`]'s memo holds `2^SIN_COS_BITS` angles.
const SIN_COS_BITS: u32 = 6;

/// A slot of a memo: a key (bits of angles) and the value computed for it; none in an empty slot.
type MemoSlot<K, V> = Cell<Option<(K, V)>>;

thread_local! {
    /// [`table_sin_cos`]'s memo: an angle's bits and its sine and cosine.
    static SIN_COS: [MemoSlot<u64, (f64, f64)>; 1 << SIN_COS_BITS] =
        const { [const { Cell::new(None) }; 1 << SIN_COS_BITS] };
}

/// What `memo` holds for `key` in the slot `hash` falls to (Fibonacci hashing; the memo's length
/// a power of two), or `compute()`, then held there: a hit returns what `compute` gave for the
/// same key.
#[inline]
fn recall<K: Copy + PartialEq, V: Copy>(
    memo: &[MemoSlot<K, V>],
    key: K,
    hash: u64,
    compute: impl FnOnce() -> V,
) -> V {
    let slot =
        (hash.wrapping_mul(0x9E37_79B9_7F4A_7C15) >> (64 - memo.len().trailing_zeros())) as usize;
    if let Some((k, v)) = memo[slot].get()
        && k == key
    {
        return v;
    }
    let v = compute();
    memo[slot].set(Some((key, v)));
    v
}

/// `angle.sin_cos()` for an angle of the table (α, β, the base's and the tool's angles), which
/// every configuration of a fit meets again: remembered per thread by the angle's bits, so that
/// the many configurations of one evaluation compute each once (the same values: a hit returns
/// what `sin_cos` gave for the same bits). The joints' angles vary and are not remembered.
#[inline]
fn table_sin_cos(angle: f64) -> (f64, f64) {
    let bits = angle.to_bits();
    SIN_COS.with(|memo| recall(memo, bits, bits, || angle.sin_cos()))
}

/// `R = RotZ(yaw) * RotY(pitch) * RotX(roll)` from `rpy = [roll, pitch, yaw]`, rad.
pub fn rpy_to_matrix(rpy: &Vector3<f64>) -> Matrix3<f64> {
    rpy_with(rpy, f64::sin_cos)
}

/// [`table_rpy_to_matrix`]'s memo holds `2^RPY_BITS` rotations.
const RPY_BITS: u32 = 2;

thread_local! {
    /// [`table_rpy_to_matrix`]'s memo: three angles' bits and their rotation.
    static RPY: [MemoSlot<[u64; 3], Matrix3<f64>>; 1 << RPY_BITS] =
        const { [const { Cell::new(None) }; 1 << RPY_BITS] };
}

/// [`rpy_to_matrix`] of the table's own angles (the base's, the tool's), their sines
/// remembered ([`table_sin_cos`]; a measured orientation's vary and are not), and the rotation
/// too, per thread by the angles' bits: every row of an evaluation builds the base's rotation
/// for its chain, its gravity and its point, from the same angles (a hit returns what the same
/// bits gave).
fn table_rpy_to_matrix(rpy: &Vector3<f64>) -> Matrix3<f64> {
    let bits = [rpy.x.to_bits(), rpy.y.to_bits(), rpy.z.to_bits()];
    let hash = bits[0] ^ bits[1].rotate_left(21) ^ bits[2].rotate_left(42);
    RPY.with(|memo| recall(memo, bits, hash, || rpy_with(rpy, table_sin_cos)))
}

/// [`rpy_to_matrix`] with the sines and cosines from `sin_cos`.
#[inline]
fn rpy_with(rpy: &Vector3<f64>, sin_cos: impl Fn(f64) -> (f64, f64)) -> Matrix3<f64> {
    let (sr, cr) = sin_cos(rpy.x);
    let (sp, cp) = sin_cos(rpy.y);
    let (sy, cy) = sin_cos(rpy.z);
    rot_z(cy, sy) * rot_y(cp, sp) * rot_x(cr, sr)
}

/// Roll, pitch, yaw (rad) of a rotation matrix, inverse of [`rpy_to_matrix`]
/// (pitch in [−π/2, π/2]).
pub fn matrix_to_rpy(r: &Matrix3<f64>) -> Vector3<f64> {
    let (roll, pitch, yaw) = Rotation3::from_matrix_unchecked(*r).euler_angles();
    Vector3::new(roll, pitch, yaw)
}

/// The rotation vector (axis × angle, rad; angle in [0, π]) of a rotation matrix: the log map,
/// precise for small angles (from the skew part) and large ones (angle by `atan2`).
pub fn rotation_vector(r: &Matrix3<f64>) -> Vector3<f64> {
    let skew = Vector3::new(
        r[(2, 1)] - r[(1, 2)],
        r[(0, 2)] - r[(2, 0)],
        r[(1, 0)] - r[(0, 1)],
    );
    let sin = 0.5 * skew.norm();
    let cos = 0.5 * (r.trace() - 1.0);
    let angle = sin.atan2(cos);
    if sin > 1e-6 {
        skew * (0.5 * angle / sin)
    } else if cos > 0.0 {
        // Near the identity: sin θ ≈ θ.
        skew * 0.5
    } else {
        // Near a half turn the skew part vanishes: the axis from the symmetric part.
        Rotation3::from_matrix_unchecked(*r).scaled_axis()
    }
}

/// The inverse of the left Jacobian of SO(3) at rotation vector `phi`: for a rotation
/// `exp(φ)` turned by a small world-frame `δ`, `log(exp(δ) exp(φ)) ≈ φ + J⁻¹(φ) δ`. With it the
/// Jacobian of a rotation residual `log(R Rₘᵀ)` is exact, not only near a zero residual.
pub fn left_jacobian_inverse(phi: &Vector3<f64>) -> Matrix3<f64> {
    let theta = phi.norm();
    let k = phi.cross_matrix();
    // 1/θ² − (1 + cos θ) / (2 θ sin θ), by its series near 0 (1/12 + θ²/720).
    let c = if theta < 1e-4 {
        1.0 / 12.0 + theta * theta / 720.0
    } else {
        1.0 / (theta * theta) - (1.0 + theta.cos()) / (2.0 * theta * theta.sin())
    };
    Matrix3::identity() - 0.5 * k + c * k * k
}

/// Frames met while walking through one joint's elementary transforms.
struct JointStep {
    /// Rotation of frame {i-1} (axis of α and direction of a: its x column).
    r0: Matrix3<f64>,
    /// Origin of frame {i-1}.
    o0: Vector3<f64>,
    /// Rotation after RotX(α) (axis of β: its y column).
    r1: Matrix3<f64>,
    /// Origin after TransX(a), on the joint axis.
    o2: Vector3<f64>,
    /// Rotation after RotY(β) (joint axis and direction of d: its z column).
    r3: Matrix3<f64>,
    /// Rotation of frame {i}.
    r: Matrix3<f64>,
    /// Origin of frame {i}.
    o: Vector3<f64>,
}

/// The rigid motion one table parameter gives the arm per unit ([`Robot::param_twists`]): a
/// point `y` moves by `w × y + v` (world frame, mm; `w` rad).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ParamTwist {
    /// The 0-based joint whose axis and links from its own outwards it moves (gravity stays);
    /// `None` for the base's, which move the whole arm and the gravity fixed in its frame.
    pub joint: Option<usize>,
    /// Angular rate, rad per unit.
    pub w: Vector3<f64>,
    /// Linear rate at the world origin, mm per unit.
    pub v: Vector3<f64>,
    /// For a joint's parameter, the rate of the point its joint's axis starts from
    /// ([`Robot::axes_and_frames`], after the `a` offset), mm per unit: `a` slides it along
    /// the x axis before, the others leave it (α and β turn about lines through it, θ about
    /// the axis, `d` slides the links along the axis from it). Zero for the base's.
    pub origin: Vector3<f64>,
}

#[inline]
fn step(r0: Matrix3<f64>, o0: Vector3<f64>, joint: &Joint, q: f64) -> JointStep {
    let (sa, ca) = table_sin_cos(joint.alpha);
    let r1 = r0 * rot_x(ca, sa);
    let o2 = o0 + r0.column(0) * joint.a;
    let r3 = match joint.beta {
        Some(beta) => {
            let (sb, cb) = table_sin_cos(beta);
            r1 * rot_y(cb, sb)
        }
        None => r1,
    };
    let (st, ct) = (joint.theta + q).sin_cos();
    let r = r3 * rot_z(ct, st);
    let o = o2 + r3.column(2) * joint.d;
    JointStep {
        r0,
        o0,
        r1,
        o2,
        r3,
        r,
        o,
    }
}

/// Joint axes of one configuration, world frame.
#[derive(Debug, Clone, PartialEq)]
pub struct JointAxes {
    /// Per joint: unit axis and a point on it (mm).
    pub axes: Vec<(Vector3<f64>, Vector3<f64>)>,
    /// Rotation of the flange frame.
    pub flange_rotation: Matrix3<f64>,
    /// Target point, mm.
    pub point: Vector3<f64>,
}

/// Walks the chain joint by joint from the base frame, yielding each joint's frames.
struct Steps<'a> {
    joints: std::iter::Zip<std::slice::Iter<'a, Joint>, std::slice::Iter<'a, f64>>,
    r: Matrix3<f64>,
    o: Vector3<f64>,
}

impl Iterator for Steps<'_> {
    type Item = JointStep;

    #[inline]
    fn next(&mut self) -> Option<JointStep> {
        let (joint, &q) = self.joints.next()?;
        let s = step(self.r, self.o, joint, q);
        self.r = s.r;
        self.o = s.o;
        Some(s)
    }

    /// Exact (the joints left), so that what collects the steps allocates once.
    #[inline]
    fn size_hint(&self) -> (usize, Option<usize>) {
        self.joints.size_hint()
    }
}

impl Robot {
    /// The chain's joint steps for readings `q` (rad), base to tip, from the base rotation `rb`.
    #[inline]
    fn steps_from<'a>(&'a self, rb: Matrix3<f64>, q: &'a [f64]) -> Steps<'a> {
        Steps {
            joints: self.joints.iter().zip(q),
            r: rb,
            o: self.base.xyz,
        }
    }

    /// The chain's joint steps for readings `q` (rad), base to tip.
    #[inline]
    fn steps<'a>(&'a self, q: &'a [f64]) -> Steps<'a> {
        self.steps_from(self.base_rotation(), q)
    }

    /// Rotation of the base frame in the world frame.
    pub fn base_rotation(&self) -> Matrix3<f64> {
        table_rpy_to_matrix(&self.base.rpy)
    }

    /// Flange frame {n} in the world frame as (rotation, origin mm); `q` in rad, one per joint.
    #[inline]
    pub fn flange_frame(&self, q: &[f64]) -> (Matrix3<f64>, Vector3<f64>) {
        debug_assert_eq!(q.len(), self.dof(), "one joint value per joint");
        let rb = self.base_rotation();
        self.steps_from(rb, q)
            .last()
            .map_or((rb, self.base.xyz), |s| (s.r, s.o))
    }

    /// Flange pose in the world frame (translation in mm); `q` in rad.
    pub fn flange_pose(&self, q: &[f64]) -> IsometryMatrix3<f64> {
        let (r, o) = self.flange_frame(q);
        IsometryMatrix3::from_parts(Translation3::from(o), Rotation3::from_matrix_unchecked(r))
    }

    /// Measured target point (tool point) in the world frame, mm; `q` in rad.
    #[inline]
    pub fn point(&self, q: &[f64]) -> Vector3<f64> {
        let (r, o) = self.flange_frame(q);
        o + r * self.tool
    }

    /// Writes the 3 × P Jacobian of the world target point with respect to every parameter
    /// ([`Robot::param_ids`] order, internal units: mm/mm and mm/rad) into rows `row..row+3` of
    /// `out`, and returns the point (world, mm). `out` must have `param_count()` columns.
    pub fn write_param_jacobian(
        &self,
        q: &[f64],
        out: &mut DMatrix<f64>,
        row: usize,
    ) -> Vector3<f64> {
        self.write_param_jacobian_at(q, 0, out, row)
    }

    /// As [`Self::write_param_jacobian`] for target `t` ([`Robot::target_index`]): the point
    /// the row measures, with the columns of its offset (`tool.*` for the default point,
    /// `pointK.*` for a named one) and zeros in every other point's columns (all three rows of
    /// every column are written, so a buffer can be reused across rows).
    pub fn write_param_jacobian_at(
        &self,
        q: &[f64],
        t: usize,
        out: &mut DMatrix<f64>,
        row: usize,
    ) -> Vector3<f64> {
        debug_assert_eq!(out.ncols(), self.param_count());
        debug_assert!(row + 3 <= out.nrows());
        // One walk of the chain: the steps kept for the columns, which need the point.
        let rb = self.base_rotation();
        let steps: Vec<JointStep> = self.steps_from(rb, q).collect();
        let (flange, origin) = steps.last().map_or((rb, self.base.xyz), |s| (s.r, s.o));
        let p = origin + flange * self.target_point(t);
        let mut put = |col: usize, v: Vector3<f64>| {
            out[(row, col)] = v.x;
            out[(row + 1, col)] = v.y;
            out[(row + 2, col)] = v.z;
        };
        let mut col = 0;
        for (joint, s) in self.joints.iter().zip(&steps) {
            let wx = s.r0.column(0).into_owned();
            put(col, wx); // a
            put(col + 1, wx.cross(&(p - s.o0))); // alpha
            col += 2;
            if joint.beta.is_some() {
                let wy = s.r1.column(1).into_owned();
                put(col, wy.cross(&(p - s.o2)));
                col += 1;
            }
            let wz = s.r3.column(2).into_owned();
            put(col, wz); // d
            put(col + 1, wz.cross(&(p - s.o2))); // theta
            col += 2;
        }
        let rel = p - self.base.xyz;
        for axis in 0..3 {
            put(col + axis, Vector3::ith(axis, 1.0));
        }
        let (sy, cy) = table_sin_cos(self.base.rpy.z);
        put(col + 3, rb.column(0).cross(&rel)); // roll about R x̂
        put(col + 4, Vector3::new(-sy, cy, 0.0).cross(&rel)); // pitch about Rz(yaw) ŷ
        put(col + 5, Vector3::z().cross(&rel)); // yaw about world ẑ
        col += 6;
        // The offsets of the default point (target 0) and of each named point: the flange's
        // axes for the row's target, zero for the others.
        for target in 0..=self.points.len() {
            for axis in 0..3 {
                let v = if target == t {
                    flange.column(axis).into_owned()
                } else {
                    Vector3::zeros()
                };
                put(col + 3 * target + axis, v);
            }
        }
        // The tool frame's angles turn no point.
        if self.tool_rpy.is_some() {
            let col = col + 3 * (self.points.len() + 1);
            for axis in 0..3 {
                put(col + axis, Vector3::zeros());
            }
        }
        p
    }

    /// How each parameter ([`Robot::param_ids`] order, internal units) moves the arm at `q`
    /// (rad): the twist of a rigid motion, world frame, about the world origin — a point `y`
    /// moves by `ω × y + v` per unit ([`ParamTwist`]). A joint's parameter moves that joint's
    /// axis and every link frame from its own outwards (α turns about the x axis of the frame
    /// before, β about the y axis after α, θ about the joint axis; a and d slide along x and
    /// the axis); the base's move the whole arm; the tool's and the named points' move no axis
    /// and no frame (`None`). The column of [`Self::write_param_jacobian_at`] of a parameter
    /// with a twist is `ω × p + v` at the point `p`.
    pub fn param_twists(&self, q: &[f64]) -> Vec<Option<ParamTwist>> {
        let mut out = Vec::with_capacity(self.param_count());
        let zero = Vector3::zeros();
        let twist = |joint, w, v, origin| {
            Some(ParamTwist {
                joint,
                w,
                v,
                origin,
            })
        };
        for (index, (joint, s)) in self.joints.iter().zip(self.steps(q)).enumerate() {
            let j = Some(index);
            let wx = s.r0.column(0).into_owned();
            out.push(twist(j, zero, wx, wx)); // a
            out.push(twist(j, wx, s.o0.cross(&wx), zero)); // alpha
            if joint.beta.is_some() {
                let wy = s.r1.column(1).into_owned();
                out.push(twist(j, wy, s.o2.cross(&wy), zero));
            }
            let wz = s.r3.column(2).into_owned();
            out.push(twist(j, zero, wz, zero)); // d
            out.push(twist(j, wz, s.o2.cross(&wz), zero)); // theta
        }
        for axis in 0..3 {
            out.push(twist(None, zero, Vector3::ith(axis, 1.0), zero));
        }
        // Roll about R x̂, pitch about Rz(yaw) ŷ, yaw about world ẑ, through the base's origin.
        let rb = self.base_rotation();
        let (sy, cy) = table_sin_cos(self.base.rpy.z);
        let o = self.base.xyz;
        for w in [
            rb.column(0).into_owned(),
            Vector3::new(-sy, cy, 0.0),
            Vector3::z(),
        ] {
            out.push(twist(None, w, o.cross(&w), zero));
        }
        out.resize(self.param_count(), None);
        out
    }

    /// Orientation of the tool frame in the flange frame (`[tool] rpy`; identity without).
    pub fn tool_frame_rotation(&self) -> Matrix3<f64> {
        self.tool_rpy
            .as_ref()
            .map_or_else(Matrix3::identity, table_rpy_to_matrix)
    }

    /// Orientation of the tool frame in the world frame (what a 6-DoF probe reports); `q` in
    /// rad.
    pub fn tool_rotation(&self, q: &[f64]) -> Matrix3<f64> {
        self.flange_frame(q).0 * self.tool_frame_rotation()
    }

    /// Writes the 3 × P Jacobian of the tool frame's orientation with respect to every
    /// parameter ([`Robot::param_ids`] order; rad per internal unit) into rows `row..row+3` of
    /// `out` (every column written), and returns the tool frame's rotation. Column `j` is the
    /// world-frame rotation vector `ω` of a unit change of parameter `j`: `R' ≈ (I + [ω]×) R`.
    /// Lengths turn nothing; α turns about the x axis of the frame before it, β about the y axis
    /// after α, θ about the joint axis, the base angles and the tool's about their own axes.
    pub fn write_orientation_jacobian(
        &self,
        q: &[f64],
        out: &mut DMatrix<f64>,
        row: usize,
    ) -> Matrix3<f64> {
        debug_assert_eq!(out.ncols(), self.param_count());
        debug_assert!(row + 3 <= out.nrows());
        let mut put = |col: usize, v: Vector3<f64>| {
            out[(row, col)] = v.x;
            out[(row + 1, col)] = v.y;
            out[(row + 2, col)] = v.z;
        };
        let rb = self.base_rotation();
        let mut flange = rb;
        let mut col = 0;
        for (joint, s) in self.joints.iter().zip(self.steps_from(rb, q)) {
            put(col, Vector3::zeros()); // a
            put(col + 1, s.r0.column(0).into_owned()); // alpha
            col += 2;
            if joint.beta.is_some() {
                put(col, s.r1.column(1).into_owned());
                col += 1;
            }
            put(col, Vector3::zeros()); // d
            put(col + 1, s.r3.column(2).into_owned()); // theta
            col += 2;
            flange = s.r;
        }
        for axis in 0..3 {
            put(col + axis, Vector3::zeros());
        }
        let (sy, cy) = table_sin_cos(self.base.rpy.z);
        put(col + 3, rb.column(0).into_owned());
        put(col + 4, Vector3::new(-sy, cy, 0.0));
        put(col + 5, Vector3::z());
        col += 6;
        for k in 0..3 * (self.points.len() + 1) {
            put(col + k, Vector3::zeros());
        }
        col += 3 * (self.points.len() + 1);
        let tool = self.tool_frame_rotation();
        if let Some(rpy) = self.tool_rpy {
            let (sy, cy) = table_sin_cos(rpy.z);
            put(col, flange * tool.column(0)); // roll about the tool frame's own x̂
            put(col + 1, flange * Vector3::new(-sy, cy, 0.0)); // pitch about Rz(yaw) ŷ
            put(col + 2, flange.column(2).into_owned()); // yaw about the flange's ẑ
        }
        flange * tool
    }

    /// Target point and its 3 × P parameter Jacobian for one configuration (allocates the result).
    pub fn param_jacobian(&self, q: &[f64]) -> (Vector3<f64>, Matrix3xX<f64>) {
        let mut out = DMatrix::zeros(3, self.param_count());
        let p = self.write_param_jacobian(q, &mut out, 0);
        (p, Matrix3xX::from_column_slice(out.as_slice()))
    }

    /// Points and the stacked (3 m) × P parameter Jacobian of `m` configurations given row-major
    /// in `qs` (`m × dof` values, rad). Rows `3k..3k+3` belong to configuration `k`.
    pub fn param_jacobian_batch(&self, qs: &[f64]) -> (Vec<Vector3<f64>>, DMatrix<f64>) {
        let n = self.dof();
        let m = qs.len() / n;
        let mut out = DMatrix::zeros(3 * m, self.param_count());
        let points = qs
            .chunks_exact(n)
            .enumerate()
            .map(|(k, q)| self.write_param_jacobian(q, &mut out, 3 * k))
            .collect();
        (points, out)
    }

    /// As [`Self::param_jacobian_batch`] with each configuration's target ([`Robot::target_index`];
    /// one per configuration).
    pub fn param_jacobian_batch_at(
        &self,
        qs: &[f64],
        targets: &[usize],
    ) -> (Vec<Vector3<f64>>, DMatrix<f64>) {
        let n = self.dof();
        let m = qs.len() / n;
        let mut out = DMatrix::zeros(3 * m, self.param_count());
        let points = (qs.chunks_exact(n).zip(targets))
            .enumerate()
            .map(|(k, (q, &t))| self.write_param_jacobian_at(q, t, &mut out, 3 * k))
            .collect();
        (points, out)
    }

    /// 3 × n Jacobian of the world target point with respect to the joint readings (mm/rad).
    pub fn joint_jacobian(&self, q: &[f64]) -> Matrix3xX<f64> {
        let p = self.point(q);
        let mut jac = Matrix3xX::zeros(self.dof());
        for (i, s) in self.steps(q).enumerate() {
            jac.set_column(i, &s.r3.column(2).cross(&(p - s.o2)));
        }
        jac
    }

    /// Every link frame {1}..{n} in the world frame as (rotation, origin mm); `q` in rad.
    pub fn link_frames(&self, q: &[f64]) -> Vec<(Matrix3<f64>, Vector3<f64>)> {
        self.steps(q).map(|s| (s.r, s.o)).collect()
    }

    /// Every joint's axis (unit, and a point on it, mm) and every link frame {1}..{n}
    /// (rotation, origin mm), world frame, at command `q` (rad), in one pass.
    pub fn axes_and_frames(&self, q: &[f64]) -> (Vec<Axis>, Vec<Frame>) {
        self.steps(q)
            .map(|s| ((s.r3.column(2).into_owned(), s.o2), (s.r, s.o)))
            .unzip()
    }

    /// Joint 1's unit axis in the world frame (none for a robot without joints): the same for
    /// every reading, since joint 1 turns about it, so one step of the chain gives it.
    pub fn joint1_axis(&self) -> Option<Vector3<f64>> {
        let joint = self.joints.first()?;
        let s = step(self.base_rotation(), self.base.xyz, joint, 0.0);
        Some(s.r3.column(2).into_owned())
    }

    /// Joint axes for configuration `q`: the ingredients of the 6 × n geometric Jacobian.
    pub fn joint_axes(&self, q: &[f64]) -> JointAxes {
        let mut axes = Vec::with_capacity(self.dof());
        let (mut r, mut o) = (self.base_rotation(), self.base.xyz);
        for s in self.steps(q) {
            axes.push((s.r3.column(2).into_owned(), s.o2));
            r = s.r;
            o = s.o;
        }
        JointAxes {
            axes,
            flange_rotation: r,
            point: o + r * self.tool,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The memo gives `sin_cos`'s own bits: for many more angles than it has slots (so that
    /// slots are shared and overwritten), each asked several times in turns, for zeros of both
    /// signs, infinities and NaNs (among them the all-ones NaN, an empty slot's key before the
    /// slots held options). The rotations' memo gives the rotation of the angles' own sines,
    /// likewise.
    #[test]
    fn table_sin_cos_is_sin_cos_to_the_bit() {
        let mut angles: Vec<f64> = (0..500)
            .map(|k| -7.0 + 0.0281 * k as f64 + 1e-9 * (k % 7) as f64)
            .collect();
        angles.extend([
            0.0,
            -0.0,
            std::f64::consts::FRAC_PI_2,
            -std::f64::consts::FRAC_PI_2,
            f64::INFINITY,
            f64::NAN,
            f64::from_bits(u64::MAX),
            f64::from_bits(0x7ff0_0000_0000_0001),
        ]);
        let same = |a: (f64, f64), b: (f64, f64)| {
            a.0.to_bits() == b.0.to_bits() && a.1.to_bits() == b.1.to_bits()
                || (a.0.is_nan() && b.0.is_nan() && a.1.is_nan() && b.1.is_nan())
        };
        for round in 0..3 {
            for (k, &angle) in angles.iter().enumerate() {
                // The rotation of three of them, its memo shared and overwritten the same way.
                let rpy = Vector3::new(angle, angles[(k * 7) % angles.len()], -angle);
                for _ in 0..1 + (k + round) % 2 {
                    let r = table_rpy_to_matrix(&rpy);
                    let direct = rpy_with(&rpy, f64::sin_cos);
                    assert!(
                        (r.iter().zip(direct.iter()))
                            .all(|(a, b)| a.to_bits() == b.to_bits() || a.is_nan() && b.is_nan()),
                        "{rpy:?}"
                    );
                }
                // Every other angle twice in a row: a hit straight after its miss.
                for _ in 0..1 + (k + round) % 2 {
                    let (s, c) = table_sin_cos(angle);
                    assert!(
                        same((s, c), angle.sin_cos()),
                        "{angle} ({:#x}): {s}, {c}",
                        angle.to_bits()
                    );
                }
            }
        }
    }
}
