//! Homing run by the cycle thread for one drive: into homing mode (6) through 0x6060 in the
//! outputs, the start (controlword bit 4) once the drive shows the mode, the wait for homing
//! attained (statusword bit 12) with the motion stopped (bit 10), and back to the mode the
//! set-points carry, bumpless. The drive homes by itself, with the method and speeds set in it.
//!
//! Nothing here allocates, locks or waits: requests (start with a time-out, cancel) come through
//! atomics and the status goes back through another. The steps, each a cycle or more:
//! - into homing: 0x6060 = 6 goes out over the set-points' mode, bit 4 low, until 0x6061 shows 6;
//! - homing: bit 4 high until bit 12 with bit 10 (attained and stopped), bit 13 (homing error),
//!   the time-out from the request, a cancel, or the drive leaving Operation enabled;
//! - stopping (time-out, cancel): halt (bit 8) until bit 10 says the motion stopped, at most the
//!   request time-out; a homing error waits for bit 10 the same way, without halt;
//! - back: the sequencer holds the target at the actual position (the new zero's coordinates)
//!   one cycle before 0x6060 goes back to the set-points' mode (where they carry 0, "no
//!   change", the mode the drive showed before homing), so both reach the drive in one frame
//!   and nothing jumps; done once 0x6061 shows that mode.
//!
//! The drive's `homed` flag is set when homing is attained and cleared when a homing starts and
//! when the drive is lost (a power cycle, a cable): the zero is the drive's, and gone with it.

use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};

use crate::drive::ds402::{controlword as cw, statusword as sw, Mode, State};

const HOMING: u8 = Mode::Homing as i8 as u8;

wire_codes! {
    /// How a homing ended.
    pub enum Outcome: u8, "homing outcome" {
        /// Homing attained (bit 12) and stopped (bit 10).
        Attained = 1 => "attained",
        /// The drive showed a homing error (bit 13).
        HomingError = 2 => "homing_error",
        /// Not attained within the time-out; halted.
        TimedOut = 3 => "timed_out",
        /// Canceled; halted.
        Canceled = 4 => "canceled",
        /// The drive left Operation enabled (fault, disable, quick stop, hardware enable low).
        NotEnabled = 5 => "not_enabled",
    }
}

impl Outcome {
    /// Why it failed, in one clause; `None` when attained.
    pub fn describe(self) -> Option<&'static str> {
        match self {
            Outcome::Attained => None,
            Outcome::HomingError => Some("the drive reported a homing error (statusword bit 13)"),
            Outcome::TimedOut => {
                Some("homing was not attained (statusword bit 12) within the time-out; the drive was halted")
            }
            Outcome::Canceled => Some("canceled; the drive was halted"),
            Outcome::NotEnabled => Some("the drive left Operation enabled"),
        }
    }
}

/// Where a drive's homing is.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Phase {
    /// None asked for yet.
    #[default]
    Idle,
    /// Taken; 0x6060 = 6 goes out until the drive shows it.
    Entering,
    /// Bit 4 is high; the drive homes.
    Homing,
    /// Ending with the outcome: waiting for the motion to stop (halted unless attained or a
    /// homing error).
    Stopping(Outcome),
    /// Ending: back to the set-points' mode.
    Leaving(Outcome),
    /// Ended.
    Done(Outcome),
}

impl Phase {
    fn pack(self) -> u64 {
        let (phase, outcome) = match self {
            Phase::Idle => (0, None),
            Phase::Entering => (1, None),
            Phase::Homing => (2, None),
            Phase::Stopping(o) => (3, Some(o)),
            Phase::Leaving(o) => (4, Some(o)),
            Phase::Done(o) => (5, Some(o)),
        };
        phase | outcome.map_or(0, |o| o as u64) << 4
    }

    fn unpack(v: u64) -> Phase {
        let outcome = Outcome::try_from(((v >> 4) & 0xF) as u8).ok();
        match (v & 0xF, outcome) {
            (1, _) => Phase::Entering,
            (2, _) => Phase::Homing,
            (3, Some(o)) => Phase::Stopping(o),
            (4, Some(o)) => Phase::Leaving(o),
            (5, Some(o)) => Phase::Done(o),
            _ => Phase::Idle,
        }
    }

    /// Whether a homing is under way (not idle, not done).
    pub fn under_way(self) -> bool {
        !matches!(self, Phase::Idle | Phase::Done(_))
    }
}

/// A drive's homing as the cycle thread last published it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct HomingStatus {
    /// Which homing (counted from 1; 0 before any).
    pub request: u32,
    /// Where it is.
    pub phase: Phase,
    /// The statusword last seen while it was under way.
    pub statusword: u16,
    /// Whether the drive is homed: attained since it was last lost.
    pub homed: bool,
}

impl HomingStatus {
    /// The homing state the statusword shows in homing mode (CiA 402 bits 13, 12, 10).
    pub fn homing_state(&self) -> &'static str {
        let s = self.statusword;
        match (s & sw::MODE_SPECIFIC_13 != 0, s & sw::MODE_SPECIFIC_12 != 0, s & sw::TARGET_REACHED != 0) {
            (true, _, _) => "error",
            (false, true, _) => "attained",
            (false, false, false) => "in_progress",
            (false, false, true) => "interrupted",
        }
    }
}

/// What a drive's homing shares with other threads: all atomics.
#[derive(Default)]
pub struct HomingShared {
    /// The request counter (high 32 bits) and the number of the last start asked (low 32): the
    /// last request is a start when both are equal, else a cancel. Carrying the last start
    /// beside the counter lets the cycle see a start it never took because a cancel came
    /// before its next cycle, and end it canceled instead of losing it.
    request: AtomicU64,
    timeout_ns: AtomicU64,
    /// The published status: request (high 32), phase, statusword (low 16).
    status: AtomicU64,
    homed: AtomicBool,
}

/// A request word: its counter and the number of the last start asked.
fn split(request: u64) -> (u32, u32) {
    ((request >> 32) as u32, request as u32)
}

impl HomingShared {
    fn ask(&self, start: bool) -> u32 {
        let next = |r: u64| {
            let (counter, last_start) = split(r);
            let counter = counter.wrapping_add(1);
            (counter as u64) << 32 | if start { counter } else { last_start } as u64
        };
        let before = self.request.fetch_update(Ordering::AcqRel, Ordering::Acquire, |r| Some(next(r)));
        // The closure never refuses.
        split(next(before.unwrap_or_else(|r| r))).0
    }

    /// Asks for a homing that ends timed out when not attained within `timeout_ns` of the
    /// cycle taking it; replaces one under way. Returns its number.
    pub fn start(&self, timeout_ns: u64) -> u32 {
        self.timeout_ns.store(timeout_ns, Ordering::Release);
        self.ask(true)
    }

    /// Cancels the homing under way, or asked and not yet taken (halted, then back to the
    /// set-points' mode).
    pub fn cancel(&self) {
        self.ask(false);
    }

    /// Clears the homed flag: the drive was lost, and its zero with it.
    pub fn forget(&self) {
        self.homed.store(false, Ordering::Release);
    }

    /// The status as last published; a start not yet taken shows as entering, even when a
    /// cancel followed it before the cycle took either.
    pub fn status(&self) -> HomingStatus {
        let (counter, last_start) = split(self.request.load(Ordering::Acquire));
        let v = self.status.load(Ordering::Acquire);
        let mut status = HomingStatus {
            request: (v >> 32) as u32,
            phase: Phase::unpack(v >> 16),
            statusword: v as u16,
            homed: self.homed.load(Ordering::Acquire),
        };
        if counter != status.request && (last_start.wrapping_sub(status.request) as i32) > 0 {
            status = HomingStatus { request: last_start, phase: Phase::Entering, ..status };
        }
        status
    }
}

/// Where the homing finds its objects in the whole images.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Objects {
    /// Controlword 0x6040 in the outputs.
    pub controlword: usize,
    /// Modes of operation 0x6060 in the outputs.
    pub mode: usize,
    /// Statusword 0x6041 in the inputs.
    pub statusword: usize,
    /// Modes of operation display 0x6061 in the inputs.
    pub mode_display: usize,
}

/// One drive's homing, kept by the cycle thread.
#[derive(Clone, Copy, Debug, Default)]
pub struct Homing {
    request: u32,
    phase: Phase,
    started_ns: u64,
    timeout_ns: u64,
    statusword: u16,
    /// When the phase began.
    phase_ns: u64,
    /// The mode the drive showed when homing was asked for.
    mode_before: u8,
    /// Cycles spent in the phase.
    cycles: u32,
    /// The number of the last start taken or ended unstarted.
    started: u32,
}

impl Homing {
    /// One cycle, after the set-points were copied into `outputs`: takes a request, moves on
    /// from the statusword and mode display in `inputs`, and publishes the status. `stop_ns`
    /// bounds the wait for the motion to stop. Returns whether the target is to be held at the
    /// actual position from the next cycle (the sequencer's hold, before the mode goes back).
    pub fn observe(
        &mut self,
        shared: &HomingShared,
        o: &Objects,
        (inputs, outputs): (&[u8], &[u8]),
        now_ns: u64,
        stop_ns: u64,
    ) -> bool {
        let statusword = u16::from_le_bytes([inputs[o.statusword], inputs[o.statusword + 1]]);
        let display = inputs[o.mode_display];
        let (counter, last_start) = split(shared.request.load(Ordering::Acquire));
        let mut hold = false;
        let next = if counter != self.request {
            self.request = counter;
            if last_start == counter {
                if !self.phase.under_way() {
                    self.mode_before = display;
                }
                self.started = counter;
                self.started_ns = now_ns;
                self.timeout_ns = shared.timeout_ns.load(Ordering::Acquire);
                shared.homed.store(false, Ordering::Release);
                Phase::Entering
            } else if self.phase.under_way() {
                self.ending(Outcome::Canceled)
            } else if last_start != self.started {
                // Asked and canceled between two cycles: it ends canceled, never started.
                self.started = last_start;
                Phase::Done(Outcome::Canceled)
            } else {
                self.phase
            }
        } else {
            self.next(statusword, display, self.mode_after(outputs[o.mode]), now_ns, stop_ns)
        };
        if next != self.phase {
            self.cycles = 0;
            self.phase_ns = now_ns;
            hold = matches!(next, Phase::Leaving(_));
            if next == Phase::Leaving(Outcome::Attained) || next == Phase::Done(Outcome::Attained) {
                shared.homed.store(true, Ordering::Release);
            }
        }
        self.cycles = self.cycles.saturating_add(1);
        // The statusword of homing mode, up to the cycle that ended it: it says why.
        let in_homing_mode = |p: Phase| matches!(p, Phase::Entering | Phase::Homing | Phase::Stopping(_));
        if in_homing_mode(self.phase) || in_homing_mode(next) {
            self.statusword = statusword;
        }
        self.phase = next;
        let packed = (self.request as u64) << 32 | self.phase.pack() << 16 | self.statusword as u64;
        shared.status.store(packed, Ordering::Release);
        hold
    }

    /// The mode to go back to: the set-points', unless they carry 0 (no change).
    fn mode_after(&self, set_mode: u8) -> u8 {
        if set_mode == 0 {
            self.mode_before
        } else {
            set_mode
        }
    }

    fn ending(&self, outcome: Outcome) -> Phase {
        match self.phase {
            Phase::Entering => Phase::Leaving(outcome),
            _ => Phase::Stopping(outcome),
        }
    }

    fn next(&self, statusword: u16, display: u8, mode_after: u8, now_ns: u64, stop_ns: u64) -> Phase {
        let enabled = State::from_statusword(statusword) == Some(State::OperationEnabled);
        let stopped = statusword & sw::TARGET_REACHED != 0;
        let timed_out = now_ns.saturating_sub(self.started_ns) >= self.timeout_ns;
        match self.phase {
            phase if !enabled && phase.under_way() => Phase::Done(Outcome::NotEnabled),
            Phase::Entering if display == HOMING && self.cycles >= 1 => Phase::Homing,
            Phase::Entering if timed_out => Phase::Leaving(Outcome::TimedOut),
            Phase::Homing if statusword & sw::MODE_SPECIFIC_13 != 0 => Phase::Stopping(Outcome::HomingError),
            Phase::Homing if statusword & sw::MODE_SPECIFIC_12 != 0 && stopped => Phase::Leaving(Outcome::Attained),
            Phase::Homing if timed_out => Phase::Stopping(Outcome::TimedOut),
            Phase::Stopping(o) if stopped || now_ns.saturating_sub(self.phase_ns) >= stop_ns => Phase::Leaving(o),
            Phase::Leaving(o) if self.cycles >= 2 && display == mode_after => Phase::Done(o),
            phase => phase,
        }
    }

    /// Writes homing's mode and controlword bits over the outputs.
    pub fn apply(&self, o: &Objects, outputs: &mut [u8]) {
        let (mode, bits) = match self.phase {
            Phase::Entering => (Some(HOMING), 0),
            Phase::Homing => (Some(HOMING), cw::NEW_SETPOINT),
            Phase::Stopping(Outcome::HomingError | Outcome::Attained) => (Some(HOMING), 0),
            Phase::Stopping(_) => (Some(HOMING), cw::HALT),
            // The cycle that asks for the hold still goes out in homing, halted where it was.
            Phase::Leaving(Outcome::Canceled | Outcome::TimedOut) if self.cycles == 1 => (Some(HOMING), cw::HALT),
            Phase::Leaving(_) if self.cycles == 1 => (Some(HOMING), 0),
            Phase::Leaving(_) => (Some(self.mode_after(outputs[o.mode])), 0),
            Phase::Idle | Phase::Done(_) => (None, 0),
        };
        if let Some(mode) = mode {
            outputs[o.mode] = mode;
        }
        if bits != 0 {
            let at = o.controlword;
            let word = u16::from_le_bytes([outputs[at], outputs[at + 1]]) | bits;
            outputs[at..at + 2].copy_from_slice(&word.to_le_bytes());
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const MS: u64 = 1_000_000;
    const ENABLED: u16 = 0x0237;
    /// Controlword at 0, mode at 2 in the outputs; statusword at 0, mode display at 2 in the inputs.
    const O: Objects = Objects { controlword: 0, mode: 2, statusword: 0, mode_display: 2 };
    const CSP: u8 = 8;

    /// One cycle with the drive showing `statusword` in mode `display`: (hold asked, the mode
    /// and controlword that go out).
    fn cycle(h: &mut Homing, shared: &HomingShared, statusword: u16, display: u8, t_ms: u64) -> (bool, u8, u16) {
        let mut outputs = [0x0F, 0, CSP];
        let inputs = [statusword as u8, (statusword >> 8) as u8, display];
        let hold = h.observe(shared, &O, (&inputs, &outputs), t_ms * MS, 10 * MS);
        h.apply(&O, &mut outputs);
        (hold, outputs[2], u16::from_le_bytes([outputs[0], outputs[1]]))
    }

    #[test]
    fn enters_homing_starts_waits_for_attained_and_stopped_and_goes_back_holding() {
        let (mut h, shared) = (Homing::default(), HomingShared::default());
        shared.homed.store(true, Ordering::Release);
        assert_eq!(shared.start(100 * MS), 1);
        assert_eq!(shared.status().phase, Phase::Entering);
        assert_eq!(cycle(&mut h, &shared, ENABLED, CSP, 0), (false, HOMING, 0x0F));
        assert!(!shared.status().homed, "a homing forgets the last zero");
        assert_eq!(cycle(&mut h, &shared, ENABLED | 0x0400, HOMING, 1), (false, HOMING, 0x1F));
        assert_eq!(shared.status().homing_state(), "interrupted");
        assert_eq!(cycle(&mut h, &shared, ENABLED, HOMING, 2), (false, HOMING, 0x1F));
        assert_eq!(shared.status().homing_state(), "in_progress");
        // Attained while still moving: bit 4 stays until the motion stopped.
        assert_eq!(cycle(&mut h, &shared, ENABLED | 0x1000, HOMING, 3), (false, HOMING, 0x1F));
        assert_eq!(cycle(&mut h, &shared, ENABLED | 0x1400, HOMING, 4), (true, HOMING, 0x0F));
        assert!(shared.status().homed);
        // The next cycle's frame carries the set-points' mode and the held target together.
        assert_eq!(cycle(&mut h, &shared, ENABLED | 0x1400, HOMING, 5), (false, CSP, 0x0F));
        assert_eq!(cycle(&mut h, &shared, ENABLED, CSP, 6), (false, CSP, 0x0F));
        let status = shared.status();
        assert_eq!(
            (status.phase, status.homed, status.homing_state()),
            (Phase::Done(Outcome::Attained), true, "attained")
        );
    }

    #[test]
    fn a_time_out_or_a_cancel_halts_a_homing_error_stops_and_a_disable_ends_it() {
        let (mut h, shared) = (Homing::default(), HomingShared::default());
        shared.start(5 * MS);
        cycle(&mut h, &shared, ENABLED, CSP, 0);
        cycle(&mut h, &shared, ENABLED, HOMING, 1);
        assert_eq!(cycle(&mut h, &shared, ENABLED, HOMING, 5), (false, HOMING, 0x10F));
        assert_eq!(shared.status().phase, Phase::Stopping(Outcome::TimedOut));
        assert_eq!(cycle(&mut h, &shared, ENABLED | 0x0400, HOMING, 6), (true, HOMING, 0x10F));
        assert_eq!(cycle(&mut h, &shared, ENABLED | 0x0400, HOMING, 7), (false, CSP, 0x0F));
        shared.start(100 * MS);
        cycle(&mut h, &shared, ENABLED, CSP, 10);
        cycle(&mut h, &shared, ENABLED, HOMING, 11);
        shared.cancel();
        assert_eq!(cycle(&mut h, &shared, ENABLED, HOMING, 12), (false, HOMING, 0x10F));
        // Not stopped within the stop time: back all the same.
        assert!(cycle(&mut h, &shared, ENABLED, HOMING, 22).0);
        assert_eq!(shared.status().phase, Phase::Leaving(Outcome::Canceled));
        shared.start(100 * MS);
        cycle(&mut h, &shared, ENABLED, CSP, 30);
        cycle(&mut h, &shared, ENABLED, HOMING, 31);
        assert_eq!(cycle(&mut h, &shared, ENABLED | 0x2000, HOMING, 32), (false, HOMING, 0x0F));
        assert!(cycle(&mut h, &shared, ENABLED | 0x2400, HOMING, 33).0);
        assert_eq!(shared.status().homing_state(), "error");
        shared.start(100 * MS);
        cycle(&mut h, &shared, ENABLED, CSP, 40);
        assert_eq!(cycle(&mut h, &shared, 0x0218, HOMING, 41), (false, CSP, 0x0F));
        assert_eq!(shared.status().phase, Phase::Done(Outcome::NotEnabled));
        assert!(!shared.status().homed);
    }

    #[test]
    fn a_start_canceled_before_the_cycle_took_it_ends_canceled_not_as_the_last_homing_did() {
        let (mut h, shared) = (Homing::default(), HomingShared::default());
        shared.cancel();
        cycle(&mut h, &shared, ENABLED, CSP, 0);
        assert_eq!(shared.status().phase, Phase::Idle, "a cancel with nothing asked changes nothing");
        shared.start(100 * MS);
        cycle(&mut h, &shared, ENABLED, CSP, 1);
        cycle(&mut h, &shared, ENABLED | 0x1400, HOMING, 2);
        cycle(&mut h, &shared, ENABLED | 0x1400, HOMING, 3);
        cycle(&mut h, &shared, ENABLED, CSP, 4);
        cycle(&mut h, &shared, ENABLED, CSP, 5);
        assert_eq!(shared.status().phase, Phase::Done(Outcome::Attained));
        let number = shared.start(100 * MS);
        shared.cancel();
        assert_eq!(
            (shared.status().request, shared.status().phase),
            (number, Phase::Entering),
            "not yet taken: not the last homing's outcome"
        );
        assert_eq!(cycle(&mut h, &shared, ENABLED, CSP, 6), (false, CSP, 0x0F), "nothing moves");
        assert_eq!(shared.status().phase, Phase::Done(Outcome::Canceled));
        assert!(shared.status().homed, "a homing never started leaves the last zero");
        shared.cancel();
        cycle(&mut h, &shared, ENABLED, CSP, 7);
        assert_eq!(shared.status().phase, Phase::Done(Outcome::Canceled), "a second cancel changes nothing");
    }
}
