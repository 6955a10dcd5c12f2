//! What akd_node publishes and records from a running cycle, made off the Python path: the
//! node's Python side is woken at the publication rates with message bodies ready to hand to
//! its middleware, and never sees a cycle.
//!
//! - [`feed`]: a thread that, at each stream's rate, reads the cycle's last snapshot and
//!   statistics once and makes every message due from them (sensor_msgs/JointState of every
//!   joint, akd_ros/DriveStatus of one), serialised ([`crate::ros_msgs`]); Python takes them
//!   as bytes and publishes them, and a [`crate::bag_writer::BagWriter`] records the same bytes
//!   without Python. It also says when the cycle has events waiting, so Python takes those when
//!   there are some instead of polling.
//! - [`cycle_records`]: the cycle's per-cycle records as akd_ros/CycleSample messages, which a
//!   bag writer's thread takes for itself.

pub mod cycle_records;
pub mod feed;

use crate::cycle::record::JointScale;

/// A joint of the node: its drive's position on the bus, its name and how its drive units
/// become SI.
#[derive(Clone, Debug)]
pub struct Joint {
    /// The drive's position on the bus.
    pub slave: u16,
    /// The joint's name.
    pub name: String,
    /// Its scale.
    pub scale: JointScale,
    /// Whether it is homed by the drive (homing.method other than none); a joint that is not is
    /// always homed.
    pub homes: bool,
}
