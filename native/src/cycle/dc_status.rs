//! Distributed clocks as the cycle sees them, for other threads: the set-up (SYNC0 cycle and
//! shift, reference clock, FBUS.PARAM02 per drive as the drive profile left it) as it was when
//! the cycle started, and every
//! slave's system-time difference, which the cyclic frame reads of one slave per cycle in turn
//! ([`crate::ethercat::master::cyclic`]) and the thread publishes in atomics after each exchange.

use std::sync::atomic::{AtomicI64, AtomicU64, Ordering};

use crate::ethercat::master::clocks::Clock;

/// A difference not read yet.
const UNREAD: i64 = i64::MIN;

/// The bus's distributed clocks while the cycle runs.
#[derive(Clone, Debug, PartialEq, Eq)]
// Python gets a dict keyed by the field names (akd_ros._native): renaming a field renames a key.
#[cfg_attr(feature = "python", derive(pyo3::IntoPyObject))]
pub struct DcStatus {
    /// SYNC0 cycle time, ns.
    pub cycle_ns: u32,
    /// SYNC0 shift from the cycle boundary, ns.
    pub shift_ns: i32,
    /// Position of the reference clock.
    pub reference_position: u16,
    /// Every slave with DC, in bus order, with its last system-time difference.
    pub drives: Vec<DcDrive>,
    /// System-time difference reads the cyclic frames carried since the set-up.
    pub difference_reads: u64,
    /// Of those, the ones a slave did not answer.
    pub difference_misses: u64,
}

/// One slave with DC while the cycle runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
// Python gets a dict keyed by the field names (akd_ros._native): renaming a field renames a key.
#[cfg_attr(feature = "python", derive(pyo3::IntoPyObject))]
pub struct DcDrive {
    /// Position on the bus.
    pub position: u16,
    /// FBUS.PARAM02 as the set-up left it, `None` when unknown
    /// ([`AkdSlave::set_drive_sync`](crate::drive::akd::AkdSlave::set_drive_sync) says when).
    pub fbus_param02: Option<u32>,
    /// The last system-time difference read (register 0x092C, ns, positive when the slave's
    /// copy is behind), `None` before the first read.
    #[cfg_attr(feature = "python", pyo3(item("system_time_difference_ns")))]
    pub time_difference_ns: Option<i64>,
}

/// What the thread publishes and the others read.
pub(super) struct DcStatusShared {
    /// The status as the set-up left it, before any read.
    setup: Option<DcStatus>,
    differences: Box<[AtomicI64]>,
    reads: AtomicU64,
    misses: AtomicU64,
}

impl DcStatusShared {
    /// For a master set up with `clock` (`None`: without distributed clocks), FBUS.PARAM02 in
    /// each slave by position `fbus_param02`.
    pub(super) fn new(clock: Option<&Clock>, fbus_param02: &[Option<u32>]) -> Self {
        let setup = clock.map(|c| DcStatus {
            cycle_ns: c.cycle_ns,
            shift_ns: c.shift_ns,
            reference_position: c.reference_position,
            drives: (c.slaves.iter())
                .map(|s| DcDrive {
                    position: s.position,
                    fbus_param02: fbus_param02.get(s.position as usize).copied().flatten(),
                    time_difference_ns: None,
                })
                .collect(),
            difference_reads: 0,
            difference_misses: 0,
        });
        DcStatusShared {
            differences: (0..setup.as_ref().map_or(0, |s| s.drives.len())).map(|_| AtomicI64::new(UNREAD)).collect(),
            setup,
            reads: AtomicU64::new(0),
            misses: AtomicU64::new(0),
        }
    }

    /// Publishes what the last exchange read (the cycle thread; no allocation).
    pub(super) fn publish(&self, clock: Option<&Clock>) {
        let Some(clock) = clock else { return };
        for (slot, slave) in self.differences.iter().zip(&clock.slaves) {
            slot.store(slave.time_difference_ns.unwrap_or(UNREAD), Ordering::Relaxed);
        }
        self.reads.store(clock.difference_reads, Ordering::Relaxed);
        self.misses.store(clock.difference_misses, Ordering::Relaxed);
    }

    /// The status, or `None` when the bus runs without distributed clocks.
    pub(super) fn status(&self) -> Option<DcStatus> {
        let mut status = self.setup.clone()?;
        for (drive, difference) in status.drives.iter_mut().zip(self.differences.iter()) {
            let d = difference.load(Ordering::Relaxed);
            drive.time_difference_ns = (d != UNREAD).then_some(d);
        }
        status.difference_reads = self.reads.load(Ordering::Relaxed);
        status.difference_misses = self.misses.load(Ordering::Relaxed);
        Some(status)
    }
}
