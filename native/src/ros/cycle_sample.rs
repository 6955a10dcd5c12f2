//! A [`Sample`] as the ROS message `akd_ros/msg/CycleSample`, serialised as rosbag2 stores it
//! (CDR, little endian, behind its 4-byte encapsulation header), so that recording every cycle
//! of every drive costs the recorder one copy per record instead of a Python message built and
//! serialised field by field.
//!
//! The message's fields and their order are those of `msg/CycleSample.msg`; `cdr-encoding`
//! lays them out with CDR's alignment. A test in `tests/test_cycle_record.py` compares these
//! bytes with rclpy's serialisation of the same message.

use crate::cycle::samples::Sample;
use crate::drive::ds402::{CommandKind, Mode};
use crate::drive::scaling::JointScaling;
use crate::ros::msgs::{self, Time};

/// `sample` of `joint` as a serialised `akd_ros/msg/CycleSample` stamped `stamp_ns` (ROS time,
/// ns); its command is the target of the mode the drive shows (NaN in a mode without one).
pub fn encode(sample: &Sample, joint: &str, scale: &JointScaling, stamp_ns: i64) -> Vec<u8> {
    let position = |counts: i32| scale.position_to_si(counts.into());
    let per_count = |counts: i32| scale.velocity_to_si(counts.into());
    let torque = |value: i16| scale.torque_to_si(value.into());
    let command = match Mode::from_i8(sample.mode).and_then(Mode::command) {
        Some(CommandKind::Position) => position(sample.target_position),
        Some(CommandKind::Velocity) => per_count(sample.target_velocity),
        Some(CommandKind::Torque) => torque(sample.target_torque),
        None => f64::NAN,
    };
    let message = msgs::CycleSample {
        stamp: Time::from_ns(stamp_ns),
        cycle: sample.cycle,
        joint,
        position: position(sample.position),
        velocity: per_count(sample.velocity),
        torque: torque(sample.torque),
        command,
        following_error: per_count(sample.following_error),
        position_counts: sample.position,
        statusword: sample.statusword,
        mode_of_operation: sample.mode,
        period_ns: sample.period_ns,
        exchange_ns: sample.exchange_ns,
        wkc: sample.wkc,
    };
    msgs::to_cdr(&message, 96 + joint.len())
}

/// The records of joint `rows` (each the joint's index in `joints`, which gives its name and
/// scale, and its sample) as (ROS time ns, serialised CycleSample), cycle by cycle and within a
/// cycle in the order of `joints`; each stamped with its cycle's wake-up time plus `offset_ns`
/// (ROS minus monotonic time).
pub fn encode_rows(
    mut rows: Vec<(usize, Sample)>,
    joints: &[(&str, JointScaling)],
    offset_ns: i64,
) -> Vec<(i64, Vec<u8>)> {
    // Stable: a drive's records of one cycle stay in the order they were taken.
    rows.sort_by_key(|&(k, sample)| (sample.cycle, k));
    rows.iter()
        .map(|(k, sample)| {
            let (joint, scale) = joints[*k];
            let stamp_ns = sample.time_ns as i64 + offset_ns;
            (stamp_ns, encode(sample, joint, &scale, stamp_ns))
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    // 0.5 m per count, 1.0 m at count 0, 0.25 N per torque unit (to rounding).
    const SCALE: JointScaling = JointScaling {
        counts_per_revolution: 1,
        gear_ratio: 1.0,
        direction: 1,
        offset: 1.0,
        lead: Some(0.5),
        peak_torque: 125.0 / std::f64::consts::TAU,
    };

    fn sample(mode: Mode) -> Sample {
        Sample {
            cycle: 7,
            time_ns: 0,
            slave: 0,
            period_ns: 250_000,
            exchange_ns: 40_000,
            wkc: 3,
            fresh: true,
            lost: false,
            statusword: 0x1237,
            mode: mode as i8,
            position: 100,
            velocity: -8,
            torque: 40,
            following_error: 2,
            target_position: 104,
            target_velocity: 12,
            target_torque: -20,
        }
    }

    fn f64_at(data: &[u8], at: usize) -> f64 {
        f64::from_le_bytes(data[at..at + 8].try_into().unwrap())
    }

    #[test]
    fn fields_sit_where_cdr_aligns_them_after_the_header() {
        let data = encode(&sample(Mode::CyclicSynchronousPosition), "j1", &SCALE, -1);
        assert_eq!(data[..4], [0, 1, 0, 0]);
        let body = &data[4..];
        // One nanosecond before the epoch: second -1 and its last nanosecond.
        assert_eq!(i32::from_le_bytes(body[0..4].try_into().unwrap()), -1);
        assert_eq!(u32::from_le_bytes(body[4..8].try_into().unwrap()), 999_999_999);
        assert_eq!(u64::from_le_bytes(body[8..16].try_into().unwrap()), 7);
        // The string: its length with the NUL, its bytes, the NUL, then padding to 8.
        assert_eq!(u32::from_le_bytes(body[16..20].try_into().unwrap()), 3);
        assert_eq!(&body[20..23], b"j1\0");
        assert_eq!(f64_at(body, 24), 51.0);
        assert_eq!(f64_at(body, 32), -4.0);
        assert!((f64_at(body, 40) - 10.0).abs() < 1e-12);
        assert_eq!(f64_at(body, 48), 53.0);
        assert_eq!(f64_at(body, 56), 1.0);
        assert_eq!(i32::from_le_bytes(body[64..68].try_into().unwrap()), 100);
        assert_eq!(u16::from_le_bytes(body[68..70].try_into().unwrap()), 0x1237);
        assert_eq!(body[70] as i8, 8);
        assert_eq!(u32::from_le_bytes(body[72..76].try_into().unwrap()), 250_000);
        assert_eq!(u32::from_le_bytes(body[76..80].try_into().unwrap()), 40_000);
        assert_eq!(u16::from_le_bytes(body[80..82].try_into().unwrap()), 3);
        assert_eq!(body.len(), 82);
    }

    #[test]
    fn the_command_is_the_target_of_the_mode_shown() {
        let command = |mode| f64_at(&encode(&sample(mode), "j1", &SCALE, 0)[4..], 48);
        assert_eq!(command(Mode::ProfileVelocity), 6.0);
        assert!((command(Mode::ProfileTorque) + 5.0).abs() < 1e-12);
        assert!(command(Mode::Homing).is_nan());
    }
}
