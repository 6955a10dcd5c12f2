//! Distributed clocks as the cycle sees them, for other threads: the set-up (SYNC0 cycle and
//! shift, reference clock, FBUS.PARAM02 per drive) as it was when the cycle started, and every
//! slave's system-time difference, which the cyclic frame reads of one slave per cycle in turn
//! ([`crate::ethercat::master::cyclic`]) and the thread publishes in atomics after each exchange.

use std::sync::atomic::{AtomicI64, AtomicU64, Ordering};

use crate::ethercat::master::clocks::{Clock, DcSlave};

/// A difference not read yet.
const UNREAD: i64 = i64::MIN;

/// The bus's distributed clocks while the cycle runs.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct DcStatus {
    /// SYNC0 cycle time, ns.
    pub cycle_ns: u32,
    /// SYNC0 shift from the cycle boundary, ns.
    pub shift_ns: i32,
    /// Position of the reference clock.
    pub reference_position: u16,
    /// Every slave with DC, in bus order, with its last system-time difference.
    pub drives: Vec<DcSlave>,
    /// System-time difference reads the cyclic frames carried since the set-up.
    pub difference_reads: u64,
    /// Of those, the ones a slave did not answer.
    pub difference_misses: u64,
}

/// What the thread publishes and the others read.
pub(super) struct DcStatusShared {
    setup: Option<Clock>,
    differences: Box<[AtomicI64]>,
    reads: AtomicU64,
    misses: AtomicU64,
}

impl DcStatusShared {
    /// For a master set up with `clock` (`None`: without distributed clocks).
    pub(super) fn new(clock: Option<&Clock>) -> Self {
        let count = clock.map_or(0, |c| c.slaves.len());
        DcStatusShared {
            setup: clock.cloned(),
            differences: (0..count).map(|_| AtomicI64::new(UNREAD)).collect(),
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
        let setup = self.setup.as_ref()?;
        let drives = setup
            .slaves
            .iter()
            .zip(self.differences.iter())
            .map(|(slave, difference)| {
                let d = difference.load(Ordering::Relaxed);
                DcSlave { time_difference_ns: (d != UNREAD).then_some(d), ..*slave }
            })
            .collect();
        Some(DcStatus {
            cycle_ns: setup.cycle_ns,
            shift_ns: setup.shift_ns,
            reference_position: setup.reference_position,
            drives,
            difference_reads: self.reads.load(Ordering::Relaxed),
            difference_misses: self.misses.load(Ordering::Relaxed),
        })
    }
}
