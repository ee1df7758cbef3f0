//! Compliance under the payload: each joint turns by its compliance times the gravity torque of
//! the payload (and of the links' weights, [`super::LinkWeight`]) about its axis.

/// The name of joint `joint`'s (0-based) payload compliance: `j2.compliance`.
pub fn compliance_name(joint: usize) -> String {
    format!("j{}.compliance", joint + 1)
}

/// The name of a coordinate (0: x, 1: y, 2: z) of the payload's centre of mass in the flange
/// frame: `payload_com.x`.
pub fn payload_com_name(axis: usize) -> String {
    format!("payload_com.{}", ["x", "y", "z"][axis])
}
