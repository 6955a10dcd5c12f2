//! The command time-out, run by the cycle thread for each sequenced drive: a drive that a
//! stream of set-points commands a non-zero velocity (profile velocity) or torque (profile
//! torque) is stopped when no target write comes for the time-out while it is in Operation
//! enabled — halted (controlword bit 8, released by the next target write) or quick-stopped
//! (held in Quick stop active until enabled again) — and one event says so.
//!
//! A position target never times out: it is where the axis stays. A zero velocity or torque
//! is a standstill and does not either; nor does a drive in another mode. The time-out is
//! armed by a target write (of 0x60FF or 0x6071, or of the whole outputs) and judged every
//! cycle against the mode of operation (0x6060 in the outputs where written, else the mode
//! display 0x6061) and the target the user wrote, so a write that arrives before the drive
//! shows a new mode still counts. The watchdog's halt is its own: a halt the user set stays as it is.
//!
//! Configuration and status pass through atomics: nothing here locks, allocates or waits.

use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::time::Duration;

use crate::cycle::events::{CommandTimeoutAction, CommandedTarget, Event, Events};
use crate::cycle::image::{i16_at, i32_at};
use crate::cycle::sequencer::{self, Offsets, Request};
use crate::drive::ds402::{controlword as cw, Mode, State};

/// The targets whose writes feed the time-out: target velocity 0x60FF and target torque 0x6071.
pub const TARGETS: [(u16, u8); 2] = [(0x60FF, 0), (0x6071, 0)];

/// What a drive's command time-out shares with other threads: all atomics.
#[derive(Default)]
pub struct CommandTimeoutShared {
    /// The time-out in ns (0: off) shifted left by 2, the action in the low 2 bits.
    config: AtomicU64,
    /// Target writes counted.
    writes: AtomicU64,
    /// Asks the thread to forget the stream and lift its own halt.
    release: AtomicBool,
    /// Published by the thread: bit 0 armed, bit 1 halted, the time-outs counted above.
    status: AtomicU64,
}

/// A drive's command time-out as the cycle thread last published it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CommandTimeoutStatus {
    /// The time-out and its action, `None` when off.
    pub config: Option<(Duration, CommandTimeoutAction)>,
    /// Whether a non-zero velocity or torque stream is being watched.
    pub armed: bool,
    /// Whether the watchdog's halt is on.
    pub halted: bool,
    /// The time-outs so far.
    pub timeouts: u64,
}

impl CommandTimeoutShared {
    /// Sets the time-out and its action, or turns it off (`None` or a zero time-out); the
    /// stream is forgotten and the watchdog's halt lifted, so a stream is watched from its next
    /// write.
    pub fn set(&self, config: Option<(Duration, CommandTimeoutAction)>) {
        let packed = config.filter(|(timeout, _)| !timeout.is_zero()).map_or(0, |(timeout, action)| {
            let ns = timeout.as_nanos().clamp(1, (u64::MAX >> 2) as u128) as u64;
            ns << 2 | action as u64
        });
        self.config.store(packed, Ordering::Release);
        self.release();
    }

    fn config(&self) -> Option<(u64, CommandTimeoutAction)> {
        let packed = self.config.load(Ordering::Acquire);
        let action = CommandTimeoutAction::try_from((packed & 3) as u8).ok()?;
        Some((packed >> 2, action))
    }

    /// Notes a write of the velocity or torque target (or of the whole outputs); call it after
    /// the write is complete, so the thread finds the value once it counts the write.
    pub fn target_written(&self) {
        self.writes.fetch_add(1, Ordering::Release);
    }

    /// The target writes counted so far; the cycle thread reads it before it copies the
    /// set-points, so a write it counts is in its copy.
    pub fn writes(&self) -> u64 {
        self.writes.load(Ordering::Acquire)
    }

    /// Forgets the stream and lifts the watchdog's halt from the next cycle (a request, a mode
    /// change: the node's enable, disable, quick stop and set_mode).
    pub fn release(&self) {
        self.release.store(true, Ordering::Release);
    }

    /// The status as the thread last published it.
    pub fn status(&self) -> CommandTimeoutStatus {
        let status = self.status.load(Ordering::Acquire);
        CommandTimeoutStatus {
            config: self.config().map(|(ns, action)| (Duration::from_nanos(ns), action)),
            armed: status & 1 != 0,
            halted: status & 2 != 0,
            timeouts: status >> 2,
        }
    }
}

/// The command time-out of one drive, kept by the cycle thread.
#[derive(Clone, Debug, Default)]
pub struct CommandTimeout {
    writes: u64,
    last_write_ns: u64,
    /// A target write came since the last time-out or release.
    stream: bool,
    halted: bool,
    /// The targets as the user last wrote them.
    velocity: i32,
    torque: i16,
    timeouts: u64,
}

/// Where the thread is in its cycle: its number and wake-up time, the slave, what it read.
#[derive(Clone, Copy, Debug)]
pub struct Seen<'a> {
    /// The cycle and its wake-up time (ns).
    pub now: (u64, u64),
    /// The slave's position on the bus.
    pub slave: u16,
    /// The target writes counted before this cycle's copy of the set-points, `None` when the
    /// copy did not succeed (the outputs hold the last cycle's then).
    pub writes: Option<u64>,
    /// The output image as copied from the set-points, before the sequencer writes over it.
    pub outputs: &'a [u8],
    /// The input image.
    pub inputs: &'a [u8],
    /// The statusword read this cycle.
    pub statusword: u16,
}

impl CommandTimeout {
    /// One cycle: notes target writes, and when a non-zero stream stopped for the time-out in
    /// Operation enabled, halts or asks `drive` for a quick stop and pushes one event.
    pub fn observe(
        &mut self,
        shared: &CommandTimeoutShared,
        o: &Offsets,
        drive: &sequencer::SequencerShared,
        events: &Events,
        seen: Seen,
    ) {
        let config = shared.config();
        if shared.release.swap(false, Ordering::AcqRel) || config.is_none() {
            self.stream = false;
            self.halted = false;
        }
        let enabled = State::from_statusword(seen.statusword) == Some(State::OperationEnabled);
        if !enabled {
            self.halted = false;
        }
        if let Some(writes) = seen.writes {
            self.velocity = o.velocity_target.map_or(0, |at| i32_at(seen.outputs, at));
            self.torque = o.torque_target.map_or(0, |at| i16_at(seen.outputs, at));
            if writes != self.writes {
                self.writes = writes;
                self.last_write_ns = seen.now.1;
                self.stream = config.is_some();
                self.halted = false;
            }
        }
        // 0x6060 in the outputs holds 0 until a mode is written there (the drive keeps the one
        // set by SDO then); the display says which that is.
        let mode = o.mode.and_then(|at| Mode::from_i8(seen.outputs[at] as i8));
        let commanded = match mode.or_else(|| o.mode_display.and_then(|at| Mode::from_i8(seen.inputs[at] as i8))) {
            Some(Mode::ProfileVelocity) => Some((CommandedTarget::Velocity, self.velocity)),
            Some(Mode::ProfileTorque) => Some((CommandedTarget::Torque, self.torque as i32)),
            _ => None,
        }
        .filter(|(_, value)| *value != 0);
        let armed = self.stream && commanded.is_some();
        if let (true, Some((timeout_ns, action)), Some((target, value))) = (armed, config, commanded) {
            if seen.now.1.saturating_sub(self.last_write_ns) >= timeout_ns {
                self.stream = false;
                if enabled {
                    match action {
                        CommandTimeoutAction::Halt => self.halted = true,
                        CommandTimeoutAction::QuickStop => drive.request(Request::QuickStop),
                    }
                    self.timeouts += 1;
                    events.push(Event::CommandTimeout {
                        cycle: seen.now.0,
                        time_ns: seen.now.1,
                        slave: seen.slave,
                        target,
                        value,
                        timeout_us: (timeout_ns / 1000).min(u32::MAX as u64) as u32,
                        statusword: seen.statusword,
                        action,
                    });
                }
            }
        }
        let status = (self.stream && commanded.is_some()) as u64 | (self.halted as u64) << 1 | self.timeouts << 2;
        shared.status.store(status, Ordering::Release);
    }

    /// Adds the watchdog's halt to the controlword at `controlword` in `outputs` while it is on.
    pub fn apply(&self, outputs: &mut [u8], controlword: usize) {
        if self.halted {
            outputs[controlword + 1] |= (cw::HALT >> 8) as u8;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const MS: u64 = 1_000_000;
    const ENABLED: u16 = 0x0027;

    /// Outputs: controlword 0..2, velocity 2..6, torque 6..8, mode 8; inputs: mode display 0.
    fn offsets() -> Offsets {
        Offsets { velocity_target: Some(2), torque_target: Some(6), mode: Some(8), ..Offsets::default() }
    }

    struct Rig {
        shared: CommandTimeoutShared,
        drive: sequencer::SequencerShared,
        events: Events,
        watch: CommandTimeout,
        outputs: [u8; 9],
        cycle: u64,
    }

    impl Rig {
        fn new(mode: Mode) -> Rig {
            let mut outputs = [0; 9];
            outputs[8] = mode as i8 as u8;
            let shared = CommandTimeoutShared::default();
            shared.set(Some((Duration::from_millis(5), CommandTimeoutAction::Halt)));
            let (drive, events) = (sequencer::SequencerShared::default(), Events::default());
            Rig { shared, drive, events, watch: CommandTimeout::default(), outputs, cycle: 0 }
        }

        fn write_velocity(&mut self, v: i32) {
            self.outputs[2..6].copy_from_slice(&v.to_le_bytes());
            self.shared.target_written();
        }

        /// One cycle at `t_ms`; whether the watchdog's halt goes out.
        fn cycle(&mut self, t_ms: u64, statusword: u16) -> bool {
            self.cycle += 1;
            let seen = Seen {
                now: (self.cycle, t_ms * MS),
                slave: 0,
                writes: Some(self.shared.writes()),
                outputs: &self.outputs,
                inputs: &[0],
                statusword,
            };
            self.watch.observe(&self.shared, &offsets(), &self.drive, &self.events, seen);
            let mut out = self.outputs;
            self.watch.apply(&mut out, 0);
            u16::from_le_bytes([out[0], out[1]]) & cw::HALT != 0
        }
    }

    #[test]
    fn a_stopped_velocity_stream_halts_until_the_next_write() {
        let mut r = Rig::new(Mode::ProfileVelocity);
        r.write_velocity(1000);
        assert!(!r.cycle(0, ENABLED));
        assert!(r.shared.status().armed);
        assert!(!r.cycle(4, ENABLED));
        assert!(r.cycle(5, ENABLED));
        assert!(r.cycle(50, ENABLED), "the halt holds until the next write");
        let status = r.shared.status();
        assert_eq!((status.armed, status.halted, status.timeouts), (false, true, 1));
        let events = r.events.drain();
        assert_eq!(
            events,
            [Event::CommandTimeout {
                cycle: 3,
                time_ns: 5 * MS,
                slave: 0,
                target: CommandedTarget::Velocity,
                value: 1000,
                timeout_us: 5000,
                statusword: ENABLED,
                action: CommandTimeoutAction::Halt,
            }]
        );
        r.write_velocity(1000);
        assert!(!r.cycle(51, ENABLED));
        assert!(r.cycle(56, ENABLED));
        assert_eq!(r.events.drain().len(), 1);
    }

    #[test]
    fn zero_position_modes_disabled_drives_and_off_never_time_out() {
        let mut r = Rig::new(Mode::ProfileVelocity);
        r.write_velocity(0);
        r.cycle(0, ENABLED);
        assert!(!r.cycle(100, ENABLED));
        let mut r = Rig::new(Mode::CyclicSynchronousPosition);
        r.write_velocity(1000);
        r.cycle(0, ENABLED);
        assert!(!r.cycle(100, ENABLED));
        let mut r = Rig::new(Mode::ProfileVelocity);
        r.write_velocity(1000);
        r.cycle(0, 0x0040);
        assert!(!r.cycle(100, 0x0040));
        // Once expired while not enabled, the stream is forgotten: enabling later does not halt.
        assert!(!r.cycle(101, ENABLED));
        let mut r = Rig::new(Mode::ProfileVelocity);
        r.shared.set(None);
        r.write_velocity(1000);
        r.cycle(0, ENABLED);
        assert!(!r.cycle(100, ENABLED));
        assert!(r.events.drain().is_empty());
        assert_eq!(r.shared.status().config, None);
    }

    #[test]
    fn quick_stop_asks_the_sequencer_and_a_release_lifts_the_halt() {
        let mut r = Rig::new(Mode::ProfileTorque);
        r.shared.set(Some((Duration::from_millis(5), CommandTimeoutAction::QuickStop)));
        r.outputs[6..8].copy_from_slice(&(-100i16).to_le_bytes());
        r.shared.target_written();
        r.cycle(0, ENABLED);
        assert!(!r.cycle(5, ENABLED), "no halt: a quick stop");
        assert_eq!(r.drive.status().request, Some(Request::QuickStop));
        let [Event::CommandTimeout { target, value, action, .. }] = r.events.drain()[..] else { panic!() };
        assert_eq!((target, value, action), (CommandedTarget::Torque, -100, CommandTimeoutAction::QuickStop));
        r.shared.set(Some((Duration::from_millis(5), CommandTimeoutAction::Halt)));
        r.shared.target_written();
        r.cycle(10, ENABLED);
        assert!(r.cycle(15, ENABLED));
        r.shared.release();
        assert!(!r.cycle(16, ENABLED));
    }
}
