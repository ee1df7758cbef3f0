//! Tilting compliance: the parts beyond a joint turn across its axis under the gravity moment
//! there; with the runouts, the turns that move the point without turning a joint.

/// One joint's tilting compliance: the parts beyond joint `joint` turn about its origin by
/// `value × M⊥`, with `M⊥` the gravity moment (N·m, world frame) about the joint's origin of the
/// payload and of the links' weights beyond it ([`JointErrors::link_weights`]; none: the
/// payload's alone), less its component along the joint's axis (which turns the joint:
/// [`JointErrors::values`]). A bearing is round: one compliance for every direction across the
/// axis.
///
/// [`JointErrors::link_weights`]: crate::compliance::JointErrors::link_weights
/// [`JointErrors::values`]: crate::compliance::JointErrors::values
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Tilt {
    /// 0-based joint.
    pub joint: usize,
    /// Tilting compliance, rad/(N·m).
    pub value: f64,
}

/// The name of a joint's tilting compliance: `j2.tilt`.
pub fn tilt_name(joint: usize) -> String {
    format!("j{}.tilt", joint + 1)
}
