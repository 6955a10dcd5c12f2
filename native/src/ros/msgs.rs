//! The ROS messages the crate serialises itself, so that what the node publishes and records at
//! the cycle's or the publication's rate leaves Python as bytes: each a serde struct whose fields
//! are those of its .msg file, in its order and with its types, laid out by `cdr-encoding` as
//! rosbag2 stores and rmw publishes them (CDR little endian behind its 4-byte encapsulation
//! header). No layout is written by hand: the serializer aligns every field.
//!
//! `tests/test_feed.py` and `tests/test_cycle_record.py` compare each message's bytes with
//! rclpy's serialisation of the same message and read them back with rosbags, so a .msg file that
//! changes without its struct here fails there.

use serde::Serialize;

/// The encapsulation header of CDR little endian (RTPS's `CDR_LE`, options 0).
const CDR_LE_HEADER: [u8; 4] = [0x00, 0x01, 0x00, 0x00];
const NS_PER_S: i64 = 1_000_000_000;

/// `message` serialised as CDR little endian behind its encapsulation header; `capacity` is a
/// hint of its size.
pub fn to_cdr<T: Serialize>(message: &T, capacity: usize) -> Vec<u8> {
    let mut data = Vec::with_capacity(CDR_LE_HEADER.len() + capacity);
    data.extend_from_slice(&CDR_LE_HEADER);
    // Writing into a Vec cannot fail, and every field of these messages has a CDR type.
    cdr_encoding::to_writer::<_, byteorder::LittleEndian, _>(&mut data, message).expect("a ROS message serialises");
    data
}

/// builtin_interfaces/Time.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub struct Time {
    /// Seconds since the epoch (negative before it).
    pub sec: i32,
    /// Nanoseconds within that second.
    pub nanosec: u32,
}

impl Time {
    /// The time `ns` nanoseconds after the epoch.
    pub fn from_ns(ns: i64) -> Time {
        Time { sec: ns.div_euclid(NS_PER_S) as i32, nanosec: ns.rem_euclid(NS_PER_S) as u32 }
    }
}

/// std_msgs/Header.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct Header<'a> {
    /// When.
    pub stamp: Time,
    /// The frame (empty where none applies).
    pub frame_id: &'a str,
}

impl Header<'_> {
    /// A header stamped `ns` (ROS time, ns) without a frame.
    pub fn at(ns: i64) -> Header<'static> {
        Header { stamp: Time::from_ns(ns), frame_id: "" }
    }
}

/// sensor_msgs/JointState.
#[derive(Debug, Serialize)]
pub struct JointState<'a> {
    /// Stamp and frame.
    pub header: Header<'a>,
    /// The joints.
    pub name: &'a [String],
    /// rad or m, one per joint.
    pub position: &'a [f64],
    /// rad/s or m/s, one per joint, or none.
    pub velocity: &'a [f64],
    /// N·m or N, one per joint, or none.
    pub effort: &'a [f64],
}

/// akd_ros/DriveStatus.
#[derive(Debug, Serialize)]
pub struct DriveStatus<'a> {
    /// Stamp.
    pub header: Header<'a>,
    /// The joint the drive moves.
    pub joint: &'a str,
    /// The CiA 402 state, snake case.
    pub ds402_state: &'a str,
    /// 0x6041.
    pub statusword: u16,
    /// The mode's name.
    pub mode: &'a str,
    /// 0x6061.
    pub mode_of_operation: i8,
    /// rad or m.
    pub following_error: f64,
    /// Homing attained since the drive was last lost (always, for a joint that is not homed).
    pub homed: bool,
    /// Cycles since the cycle thread started.
    pub cycles: u64,
    /// Cycles that ended after their next deadline.
    pub overruns: u64,
    /// Frames that did not come back.
    pub lost_frames: u64,
    /// Frames with a wrong working counter.
    pub wkc_errors: u64,
    /// s.
    pub period_mean: f64,
    /// s.
    pub period_max: f64,
    /// s.
    pub exchange_p99: f64,
}

/// akd_ros/DriveIO.
#[derive(Debug, Serialize)]
pub struct DriveIo<'a> {
    /// Stamped with the cycle whose process image this is.
    pub header: Header<'a>,
    /// The joint the drive moves.
    pub joint: &'a str,
    /// That cycle's number.
    pub cycle: u64,
    /// Whether the mapping carries 0x60FD.
    pub digital_inputs_mapped: bool,
    /// 0x60FD.
    pub digital_inputs: u32,
    /// 0x60FD bit 0.
    pub negative_limit: bool,
    /// 0x60FD bit 1.
    pub positive_limit: bool,
    /// 0x60FD bit 2.
    pub home_switch: bool,
    /// 0x60FD bit 3.
    pub interlock: bool,
    /// Digital inputs 1..7, input 1 first.
    pub inputs: Vec<bool>,
    /// The names the joint gives inputs.
    pub input_names: &'a [String],
    /// Their numbers (1..7).
    pub input_numbers: &'a [u8],
    /// Their levels.
    pub named_inputs: Vec<bool>,
    /// DriveIO.HARDWARE_ENABLE_*.
    pub hardware_enable: u8,
    /// V; NaN where the mapping lacks 0x3470:04.
    pub analog_input: f64,
    /// Whether the mapping carries 0x60FE:01.
    pub digital_outputs_mapped: bool,
    /// 0x60FE:01 as sent.
    pub digital_outputs: u32,
    /// Digital outputs 1..2, output 1 first.
    pub outputs: Vec<bool>,
    /// The names the joint gives outputs.
    pub output_names: &'a [String],
    /// Their numbers (1..2).
    pub output_numbers: &'a [u8],
    /// Their levels.
    pub named_outputs: Vec<bool>,
    /// V as sent; NaN where the mapping lacks 0x3470:03.
    pub analog_output: f64,
}

/// akd_ros/DeviceIO.
#[derive(Debug, Serialize)]
pub struct DeviceIo<'a> {
    /// Stamped with the cycle whose process image this is.
    pub header: Header<'a>,
    /// Its name in the parameters file.
    pub device: &'a str,
    /// Its order number as its SII gives it.
    pub product: &'a str,
    /// Its position on the line.
    pub slave: u16,
    /// That cycle's number.
    pub cycle: u64,
    /// Whether that cycle's exchange succeeded.
    pub fresh: bool,
    /// Its input channels' names.
    pub input_names: &'a [String],
    /// Their values.
    pub inputs: &'a [f64],
    /// Its output channels' names.
    pub output_names: &'a [String],
    /// Their values as sent.
    pub outputs: &'a [f64],
}

/// akd_ros/CycleSample.
#[derive(Debug, Serialize)]
pub struct CycleSample<'a> {
    /// The cycle's wake-up time.
    pub stamp: Time,
    /// The cycle's number.
    pub cycle: u64,
    /// The joint.
    pub joint: &'a str,
    /// rad or m.
    pub position: f64,
    /// rad/s or m/s.
    pub velocity: f64,
    /// N·m or N.
    pub torque: f64,
    /// The set-point of the active mode, SI.
    pub command: f64,
    /// rad or m.
    pub following_error: f64,
    /// 0x6064, counts.
    pub position_counts: i32,
    /// 0x6041.
    pub statusword: u16,
    /// 0x6061.
    pub mode_of_operation: i8,
    /// ns since the previous cycle started.
    pub period_ns: u32,
    /// ns from sending the frame to its return.
    pub exchange_ns: u32,
    /// The process data frame's working counter.
    pub wkc: u16,
}

/// diagnostic_msgs/KeyValue.
#[derive(Debug, Serialize)]
pub struct KeyValue<'a> {
    /// The key.
    pub key: &'a str,
    /// Its value, as text.
    pub value: &'a str,
}

/// diagnostic_msgs/DiagnosticStatus.
#[derive(Debug, Serialize)]
pub struct DiagnosticStatus<'a> {
    /// OK=0, WARN=1, ERROR=2, STALE=3.
    pub level: u8,
    /// What it is the status of.
    pub name: &'a str,
    /// A summary.
    pub message: &'a str,
    /// The hardware it is about.
    pub hardware_id: &'a str,
    /// The values.
    pub values: Vec<KeyValue<'a>>,
}

/// diagnostic_msgs/DiagnosticArray.
#[derive(Debug, Serialize)]
pub struct DiagnosticArray<'a> {
    /// Stamp.
    pub header: Header<'a>,
    /// One status per component.
    pub status: Vec<DiagnosticStatus<'a>>,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_joint_state_aligns_its_sequences_after_the_header() {
        let names = ["a".to_owned(), "bc".to_owned()];
        let data = to_cdr(
            &JointState { header: Header::at(-1), name: &names, position: &[1.5, -2.0], velocity: &[], effort: &[] },
            64,
        );
        assert_eq!(data[..4], CDR_LE_HEADER);
        let body = &data[4..];
        let u32_at = |at: usize| u32::from_le_bytes(body[at..at + 4].try_into().unwrap());
        // One nanosecond before the epoch: second -1 and its last nanosecond.
        assert_eq!((u32_at(0) as i32, u32_at(4)), (-1, 999_999_999));
        // frame_id "": its length with the NUL, then the NUL.
        assert_eq!((u32_at(8), body[12]), (1, 0));
        // name: two strings, each its length with the NUL, its bytes and the NUL.
        assert_eq!((u32_at(16), u32_at(20), &body[24..26]), (2, 2, &b"a\0"[..]));
        assert_eq!((u32_at(28), &body[32..35]), (3, &b"bc\0"[..]));
        // position: its count, then the doubles aligned to 8.
        assert_eq!(u32_at(36), 2);
        assert_eq!(f64::from_le_bytes(body[40..48].try_into().unwrap()), 1.5);
        assert_eq!((u32_at(56), u32_at(60), body.len()), (0, 0, 64));
    }
}
