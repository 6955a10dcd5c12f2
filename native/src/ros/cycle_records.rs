//! A running cycle's per-cycle records of the node's joints, as a bag writer's
//! [`CycleSource`]: taken from the cycle's ring by the writer's thread and serialised there as
//! akd_ros/CycleSample, stamped on the ROS clock by the offset the node keeps up to date.

use std::sync::atomic::{AtomicI64, Ordering};
use std::sync::Arc;

use super::Joint;
use crate::cycle::CycleThread;
use crate::ros::bag_writer::CycleSource;
use crate::ros::cycle_sample;

/// The records of `joints` of `cycle`; a cycle's records of drives that are no joint are
/// left out.
pub struct CycleRecords {
    cycle: Arc<CycleThread>,
    joints: Vec<Joint>,
    /// ROS minus monotonic time (ns).
    offset_ns: Arc<AtomicI64>,
}

impl CycleRecords {
    /// Records of `joints` of `cycle`, stamped with `offset_ns` added to their monotonic times.
    pub fn new(cycle: Arc<CycleThread>, joints: Vec<Joint>, offset_ns: Arc<AtomicI64>) -> Self {
        CycleRecords { cycle, joints, offset_ns }
    }
}

impl CycleSource for CycleRecords {
    fn take(&mut self) -> Vec<(i64, Vec<u8>)> {
        let rows = self
            .cycle
            .samples()
            .into_iter()
            .filter_map(|s| self.joints.iter().position(|j| j.slave == s.slave).map(|k| (k, s)))
            .collect();
        let named: Vec<_> = self.joints.iter().map(|j| (j.name.as_str(), j.scale)).collect();
        cycle_sample::encode_rows(rows, &named, self.offset_ns.load(Ordering::Relaxed))
    }
}
