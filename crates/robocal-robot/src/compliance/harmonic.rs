//! Transmission error: Fourier harmonics of a joint's own angle, held beyond the readings' reach.

/// One transmission harmonic of one joint: `Δq = sin · sin(k q) + cos · cos(k q)`, rad, with
/// `q` the joint angle held within [`Self::reach`] when it has one.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Harmonic {
    /// 0-based joint.
    pub joint: usize,
    /// Order `k` (1: once per turn of the joint).
    pub order: u32,
    /// Sine coefficient, rad.
    pub sin: f64,
    /// Cosine coefficient, rad.
    pub cos: f64,
    /// The joint angles (rad, `[lo, hi]`) over which the harmonic is continued periodically;
    /// beyond them it keeps its value at the nearer end. `None`: every angle. Identification
    /// sets it to the joint's readings widened by [`HARMONIC_REACH`] of their span at each end:
    /// over a narrow window a harmonic may be fitting an effect it does not model (backlash,
    /// a deflection), and continued far beyond the readings it would miss by millimetres. The
    /// default calibration lifts joint 1's where its blocks of joint 1 show the harmonics
    /// predicting beyond the readings better than held (`robocal-pipeline`'s selection).
    pub reach: Option<[f64; 2]>,
}

/// How far beyond a joint's readings its identified harmonics are continued periodically, as a
/// fraction of the readings' span (at each end); farther out they are held at the value they
/// reach there. A quarter is as far as the default calibration's blocks of joint 1 test
/// extrapolation: five blocks over the readings, each end block predicted from the other four,
/// a quarter of their span beyond them.
pub const HARMONIC_REACH: f64 = 0.25;

impl Harmonic {
    /// Order `order` of joint `joint` with zero coefficients, continued at every angle.
    pub fn zero(joint: usize, order: u32) -> Self {
        Self {
            joint,
            order,
            sin: 0.0,
            cos: 0.0,
            reach: None,
        }
    }

    /// The angle (rad) the harmonic is evaluated at for joint angle `q`: `q` held within
    /// [`Self::reach`].
    pub fn angle(&self, q: f64) -> f64 {
        self.reach.map_or(q, |[lo, hi]| q.clamp(lo, hi))
    }

    /// `(sin(k q'), cos(k q'))` at the held angle `q'` ([`Self::angle`]).
    pub fn basis(&self, q: f64) -> (f64, f64) {
        (f64::from(self.order) * self.angle(q)).sin_cos()
    }

    /// Its joint error at joint angle `q`, rad.
    pub fn value(&self, q: f64) -> f64 {
        self.value_on(self.basis(q))
    }

    /// Its joint error on its basis `(sin, cos)` at some joint angle ([`Self::basis`]), rad.
    pub fn value_on(&self, (s, c): (f64, f64)) -> f64 {
        self.sin * s + self.cos * c
    }

    /// Whether `other` is evaluated at the same angles with the same basis — same joint, order
    /// and reach —, whatever its coefficients: whether its [`Self::basis`] is this one's at every
    /// joint angle.
    pub fn same_basis(&self, other: &Harmonic) -> bool {
        (self.joint, self.order, self.reach) == (other.joint, other.order, other.reach)
    }

    /// What holding the harmonic beyond its reach may miss at joint angle `q`, as a variance
    /// (rad²): the mean square, over the harmonic's phase, of the difference between its value
    /// at `q` and at the held angle, `A² (1 − cos(k d))` with `A` its amplitude and `d` the
    /// distance from `q` to the held angle (0 within the reach). Beyond the reach the model
    /// claims nothing of the harmonic but its size: if it is a gear's, it moves on there, by a
    /// turn of phase the readings did not show.
    pub fn held_variance(&self, q: f64) -> f64 {
        let d = q - self.angle(q);
        (self.sin * self.sin + self.cos * self.cos) * (1.0 - (f64::from(self.order) * d).cos())
    }

    /// The reach for readings from `lo` to `hi` (rad): widened by [`HARMONIC_REACH`] of the
    /// span at each end.
    pub fn reach_of(lo: f64, hi: f64) -> [f64; 2] {
        let margin = HARMONIC_REACH * (hi - lo).max(0.0);
        [lo - margin, hi + margin]
    }
}

/// The name of a harmonic's sine or cosine coefficient: `j3.h2.sin`, `j3.h2.cos`.
pub fn harmonic_name(joint: usize, order: u32, cos: bool) -> String {
    let which = if cos { "cos" } else { "sin" };
    format!("j{}.h{order}.{which}", joint + 1)
}

/// Highest harmonic order a file may give.
pub const MAX_HARMONIC_ORDER: u32 = 64;
