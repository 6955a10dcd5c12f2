//! The ROS side of the crate: what akd_node publishes and records, made off the Python path, so
//! that the node's Python side is woken at the publication rates with message bodies ready to
//! hand to its middleware, and never sees a cycle.
//!
//! - [`msgs`]: the ROS messages the crate serialises itself (CDR by `cdr-encoding`), and
//!   [`cycle_sample`] a cycle's record of one drive as akd_ros/CycleSample.
//! - [`bag_file`]: one MCAP file of a rosbag2 bag; [`bag_writer`]: the thread that writes a
//!   bag's files (topics, messages, per-cycle records, the black box).
//! - [`feed`]: a thread that, at each stream's rate, reads the cycle's last snapshot and
//!   statistics once and makes every message due from them (sensor_msgs/JointState of every
//!   joint, akd_ros/DriveStatus and akd_ros/DriveIO of one, akd_ros/DeviceIO of a device beside
//!   them); Python takes them as bytes and
//!   publishes them, and a [`bag_writer::BagWriter`] records the same bytes without Python. It
//!   also says when the cycle has events waiting, so Python takes those when there are some
//!   instead of polling.
//! - [`cycle_records`]: the cycle's per-cycle records as akd_ros/CycleSample messages, which a
//!   bag writer's thread takes for itself.
//! - [`line_diagnostics`]: what /diagnostics says of the line's links and error counters, a
//!   status of the line and one per slave.

pub mod bag_file;
pub mod bag_writer;
pub mod cycle_records;
pub mod cycle_sample;
pub mod feed;
pub mod line_diagnostics;
pub mod msgs;

use crate::drive::scaling::JointScaling;

/// A joint of the node: its drive's position on the bus, its name and how its drive units
/// become SI.
#[derive(Clone, Debug)]
pub struct Joint {
    /// The drive's position on the bus.
    pub slave: u16,
    /// The joint's name.
    pub name: String,
    /// Its scale.
    pub scale: JointScaling,
    /// Whether it is homed by the drive (homing.method other than none); a joint that is not is
    /// always homed.
    pub homes: bool,
    /// What its akd_ros/DriveIO says beside the drive's values.
    pub io: JointIo,
}

/// A device of the node beside its joints (a terminal): its position on the bus, its name in
/// the parameters file and what it is (from Python a dict with every key).
#[derive(Clone, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "python", derive(pyo3::FromPyObject), pyo3(from_item_all))]
pub struct Device {
    /// Its position on the bus.
    pub slave: u16,
    /// Its name.
    pub name: String,
    /// Its order number as its SII gives it (e.g. "EL1004").
    pub product: String,
}

/// The names a joint gives its drive's digital inputs and outputs, and its analog scale.
#[derive(Clone, Debug, PartialEq)]
pub struct JointIo {
    /// The named inputs.
    pub input_names: Vec<String>,
    /// Their AKD numbers (1..=[`crate::drive::io::INPUT_COUNT`]).
    pub input_numbers: Vec<u8>,
    /// The named outputs.
    pub output_names: Vec<String>,
    /// Their AKD numbers (1..=[`crate::drive::io::OUTPUT_COUNT`]).
    pub output_numbers: Vec<u8>,
    /// Volts per count of the analog input and output.
    pub volts_per_count: f64,
}

impl JointIo {
    /// Names `inputs` and `outputs` (name, AKD number); an error naming a number the AKD does
    /// not have, with the numbers it has.
    pub fn new(inputs: Vec<(String, u8)>, outputs: Vec<(String, u8)>, volts_per_count: f64) -> Result<JointIo, String> {
        for (kind, named, count) in
            [("input", &inputs, crate::drive::io::INPUT_COUNT), ("output", &outputs, crate::drive::io::OUTPUT_COUNT)]
        {
            if let Some((name, number)) = named.iter().find(|(_, n)| !(1..=count).contains(n)) {
                return Err(format!("{kind} {name} is number {number}: the AKD has digital {kind}s 1..{count}"));
            }
        }
        let (input_names, input_numbers) = inputs.into_iter().unzip();
        let (output_names, output_numbers) = outputs.into_iter().unzip();
        Ok(JointIo { input_names, input_numbers, output_names, output_numbers, volts_per_count })
    }
}
