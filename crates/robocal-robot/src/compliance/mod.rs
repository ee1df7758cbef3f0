//! Joint errors: how far each joint really turns from its reading, the non-geometric physics of
//! a calibrated model. One family, [`JointErrors`], of terms that are each a known function of
//! the command and the load times an identified coefficient:
//!
//! - **compliance under the payload** (below);
//! - **transmission error**: Fourier harmonics of the joint's own angle,
//!   `Δq_i = Σ_k s_ik sin(k q_i) + c_ik cos(k q_i)` ([`Harmonic`]);
//! - **self-weight compliance**: the joint's deflection under the gravity torque of the links
//!   beyond it. The links' masses and centres of mass and the joint's compliance combine into
//!   coefficients of the torques that a unit mass at each link frame's origin, and a unit first
//!   moment along each of its axes, would put on the joint ([`SelfWeight`]); which of these the
//!   poses can separate (from each other and from the geometry) the identifiability analysis
//!   decides. It needs no payload: one load is enough;
//! - **backlash**: a joint with play rests on one flank, `Δq_i = ±b_i` (`b_i` half the play,
//!   [`Backlash`]): on the flank of its approach from home (`+b_i` at or above the home reading,
//!   `−b_i` below), or on the flank its gravity torque presses (the sign of a linear function of
//!   the joint's gravity-torque features: the link weights', the payload's and a constant
//!   preload, [`Flank::Torque`]);
//! - **tilting compliance**: a joint's bearing and reducer tilt, about the joint's origin and
//!   across its axis, by a compliance times the gravity moment across the axis of the payload
//!   and of the links' weights beyond it ([`Tilt`]). Not a turn of the joint: the parts beyond
//!   it turn about an axis perpendicular to the joint's, so the point moves by
//!   `t × (p − a)` (`t` the tilt, rad, `a` the joint's origin) after the joint angles' errors;
//! - **axis runout** (tilt error motion): a bearing's races and a reducer's output are not
//!   perfectly round nor square to the axis, so the parts beyond the joint turn across its axis
//!   by Fourier harmonics of the joint's angle ([`Runout`]), moving the point like a tilt.
//!
//! A joint whose gear and bearings give under torque turns by `compliance × torque`. The torque
//! that changes with the payload is gravity's on the payload's centre of mass,
//! `τ_i = w_i · ((c − a_i) × m g)`, with `w_i` the joint axis through `a_i` and `c` the payload's
//! centre of mass (world frame). The model's point for a command `q` under `m` kg is the rigid
//! table's point at `q + compliance ∘ τ(q, m)`: with no load it is the rigid table.
//!
//! Every term is evaluated at the command `q`, and the model's point is the rigid table's at
//! `q + Δq(q, m)`, moved by the tilts where there are any.
//!
//! ```
//! use robocal_robot::{Compliance, Robot};
//! let robot = Robot::from_toml_str(
//!     "name = \"arm\"\n[base]\nxyz = [0, 0, 0]\nrpy = [0, 0, 0]\n[tool]\nxyz = [1000, 0, 0]\n\
//!      [[joint]]\na = 0\nalpha = 90\nd = 0\ntheta = 0\n",
//!     "arm.toml",
//! )?;
//! // A horizontal joint holding 10 kg one metre out: 98 N·m, turning it by 98 × 1e-5 rad, so
//! // the point sinks by about 0.98 mm.
//! let payload = [1000.0, 0.0, 0.0].into(); // centre of mass at the point, flange frame
//! let c = Compliance::new(vec![1e-5], [0.0, 0.0, -9.80665].into(), payload);
//! let t = c.torques(&robot, &[0.0], 10.0);
//! assert!((t[0].abs() - 98.0665).abs() < 1e-9);
//! let sag = robot.point(&[0.0]).z - c.point(&robot, &[0.0], 10.0).z;
//! assert!((sag - 0.980665).abs() < 1e-3);
//! # Ok::<(), robocal_robot::RobotError>(())
//! ```

mod backlash;
mod evaluate;
mod file;
mod gravity;
mod harmonic;
mod model;
mod payload;
mod runout;
mod self_weight;
mod terms;
mod tilt;

pub use backlash::{Backlash, Flank, backlash_name, payload_mass_feature, torque_side};
pub use file::{
    RawBacklash, RawCompliance, RawHarmonic, RawLinkWeight, RawRunout, RawSelfWeight, RawTilt,
};
pub use gravity::{MomentPart, TORQUE_FEATURES_PER_LINK};
pub use harmonic::{HARMONIC_REACH, Harmonic, MAX_HARMONIC_ORDER, harmonic_name};
pub use model::{
    Compliance, DEG_PER_KNM, DeflectionRates, ErrorParam, JointErrors, RowTerms, Turns,
    turn_rotation, turned,
};
pub use payload::{compliance_name, payload_com_name};
pub use runout::{Across, Runout, runout_name};
pub use self_weight::{LinkWeight, SelfWeight, link_weight_name, self_weight_name};
pub use tilt::{Tilt, tilt_name};
