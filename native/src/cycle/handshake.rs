//! The set-point handshake of profile position and the start of homing, run by the cycle
//! thread for each sequenced drive: controlword bit 4 (new set-point, or start homing) answered
//! by statusword bit 12 (set-point acknowledged, or homing attained).
//!
//! A caller asks for controlword bits (bit 4, with bit 5 change set immediately or bit 6
//! relative where wanted) and a time-out. From statusword bit 12 clear the thread raises them
//! together with the sequencer's own bits, keeps them until bit 12 is set, then lowers them, so
//! that the next request makes a new rising edge. It raises them no earlier than the cycle after
//! it took the request, so a target written before the request is in the outputs by then, and
//! the bits of a request that replaces one under way go out low for that cycle first.
//!
//! The handshake is stuck, and the bits go low, when the drive is not (or no longer) in
//! Operation enabled, when bit 12 does not clear within the clearing time-out (the request
//! time-out) or is not set within the request's own time-out from the raise (which homing may
//! make long), or in homing when the drive shows a homing error (statusword bit 13). Requests and status
//! pass through atomics: nothing here locks, allocates or waits.

use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Duration;

use crate::drive::ds402::{controlword as cw, statusword as sw, Mode, State};

/// The controlword bits a handshake may raise: 4 (new set-point; start homing), 5 (change set
/// immediately) and 6 (target relative). Bit 4 must be among them.
pub const ALLOWED_BITS: u16 = cw::NEW_SETPOINT | cw::CHANGE_IMMEDIATELY | cw::RELATIVE;

named_variants! {
    /// Why a handshake is stuck.
    #[repr(u8)]
    pub enum Stuck {
        /// The drive is not, or no longer, in Operation enabled.
        NotEnabled = 1 => "the drive is not in Operation enabled",
        /// Statusword bit 12 stayed set for the clearing time-out, so the bits were not raised.
        NeverCleared = 2 => "statusword bit 12 stayed set for the request time-out (the handshake starts from bit 12 \
            clear; in homing it is the homing attained of an earlier homing)",
        /// Statusword bit 12 was not set within the time-out from the raise.
        NeverSet = 3 => "statusword bit 12 (set-point acknowledged, or homing attained) was not set within the \
            time-out after the bits were raised",
        /// The drive shows a homing error (statusword bit 13) while homing.
        HomingError = 4 => "homing error (statusword bit 13)",
    }
    /// Why, in one clause.
    fn describe;
}

/// How far a handshake is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Progress {
    /// None was asked for yet.
    Idle,
    /// Waiting for bit 12 to clear, or raised and waiting for it to be set.
    InProgress,
    /// Bit 12 was set and the bits are lowered again.
    Done,
    /// Given up, the bits lowered.
    Stuck(Stuck),
}

/// A drive's handshake as the cycle thread last published it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct HandshakeStatus {
    /// Which request it is (counted from 1; 0 before any).
    pub request: u32,
    /// The controlword bits asked for.
    pub bits: u16,
    /// How far it is.
    pub progress: Progress,
    /// The statusword the thread saw last while it was under way (at its end once it ended).
    pub statusword: u16,
}

impl HandshakeStatus {
    /// Why it is stuck, with the drive's state and statusword; `None` when it is not.
    pub fn stuck_reason(&self) -> Option<String> {
        let Progress::Stuck(why) = self.progress else { return None };
        Some(format!("{}: {}", self.describe("stuck"), why.describe()))
    }

    /// "set-point handshake (controlword bits …) `how` in `state` (statusword …)".
    pub fn describe(&self, how: &str) -> String {
        let state = State::from_statusword(self.statusword).map_or("no valid state", State::name);
        format!(
            "set-point handshake (controlword bits 0x{:04X}) {how} in {state} (statusword 0x{:04X})",
            self.bits, self.statusword
        )
    }

    fn pack(self) -> u64 {
        let (progress, why) = match self.progress {
            Progress::Idle => (0u64, 0u64),
            Progress::InProgress => (1, 0),
            Progress::Done => (2, 0),
            Progress::Stuck(why) => (3, why as u64),
        };
        (self.request as u64) << 32
            | (self.bits as u64 & 0xFF) << 24
            | progress << 20
            | why << 16
            | self.statusword as u64
    }

    fn unpack(v: u64) -> HandshakeStatus {
        let why = Stuck::ALL.into_iter().find(|s| *s as u64 == (v >> 16) & 0xF);
        let progress = match ((v >> 20) & 0xF, why) {
            (1, _) => Progress::InProgress,
            (2, _) => Progress::Done,
            (3, Some(why)) => Progress::Stuck(why),
            _ => Progress::Idle,
        };
        HandshakeStatus { request: (v >> 32) as u32, bits: (v >> 24) as u8 as u16, progress, statusword: v as u16 }
    }
}

/// What a drive's handshake shares with other threads: all atomics.
#[derive(Default)]
pub struct HandshakeShared {
    /// The request counter (high 32 bits) and its bits (low 16).
    request: AtomicU64,
    /// How long the last request may wait for bit 12 to clear (ns).
    clear_timeout_ns: AtomicU64,
    /// How long the last request may wait for bit 12 once the bits are raised (ns).
    timeout_ns: AtomicU64,
    /// The published [`HandshakeStatus`], packed.
    status: AtomicU64,
}

impl HandshakeShared {
    /// Asks for a handshake raising `bits` (within [`ALLOWED_BITS`], with bit 4) that ends stuck
    /// when bit 12 does not clear within `clear_timeout` or is not set within `timeout` of the
    /// raise; it replaces one under way. Returns its number.
    pub fn start(&self, bits: u16, clear_timeout: Duration, timeout: Duration) -> u32 {
        let ns = |t: Duration| t.as_nanos().min(u64::MAX as u128) as u64;
        self.clear_timeout_ns.store(ns(clear_timeout), Ordering::Release);
        self.timeout_ns.store(ns(timeout), Ordering::Release);
        let next = |r: u64| ((r >> 32) as u32).wrapping_add(1);
        let before = self
            .request
            .fetch_update(Ordering::AcqRel, Ordering::Acquire, |r| Some((next(r) as u64) << 32 | bits as u64));
        // The closure never refuses.
        next(before.unwrap_or_else(|r| r))
    }

    /// The handshake last asked for as the cycle thread last published it; one not yet taken
    /// shows as in progress.
    pub fn status(&self) -> HandshakeStatus {
        let request = self.request.load(Ordering::Acquire);
        let status = HandshakeStatus::unpack(self.status.load(Ordering::Acquire));
        if (request >> 32) as u32 == status.request {
            return status;
        }
        HandshakeStatus {
            request: (request >> 32) as u32,
            bits: request as u16,
            progress: Progress::InProgress,
            ..status
        }
    }
}

#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
enum Phase {
    #[default]
    Idle,
    /// Taken in this cycle: the bits stay low.
    Taken,
    /// Waiting for bit 12 to clear.
    Clearing,
    /// The bits go out; waiting for bit 12.
    Raised,
    Done,
    Stuck(Stuck),
}

impl Phase {
    fn under_way(self) -> bool {
        matches!(self, Phase::Taken | Phase::Clearing | Phase::Raised)
    }
}

/// The handshake of one drive, kept by the cycle thread.
#[derive(Clone, Debug, Default)]
pub struct Handshake {
    request: u32,
    bits: u16,
    phase: Phase,
    /// When it was taken, then when the bits were raised.
    started_ns: u64,
    clear_timeout_ns: u64,
    timeout_ns: u64,
    statusword: u16,
}

impl Handshake {
    /// One cycle: takes a new request from `shared`, moves the handshake on from the statusword
    /// and mode display read this cycle, and publishes its status.
    pub fn observe(&mut self, shared: &HandshakeShared, statusword: u16, mode_display: Option<i8>, now_ns: u64) {
        let request = shared.request.load(Ordering::Acquire);
        let was_under_way = self.phase.under_way();
        if (request >> 32) as u32 != self.request {
            self.request = (request >> 32) as u32;
            self.bits = request as u16;
            self.clear_timeout_ns = shared.clear_timeout_ns.load(Ordering::Acquire);
            self.timeout_ns = shared.timeout_ns.load(Ordering::Acquire);
            self.started_ns = now_ns;
            self.phase = Phase::Taken;
        } else {
            let next = self.next(statusword, mode_display, now_ns);
            if next == Phase::Raised && self.phase != Phase::Raised {
                self.started_ns = now_ns;
            }
            self.phase = next;
        }
        // The statusword of the cycle that ended it stays, to say why.
        if was_under_way || self.phase.under_way() {
            self.statusword = statusword;
        }
        shared.status.store(self.status().pack(), Ordering::Release);
    }

    fn next(&self, statusword: u16, mode_display: Option<i8>, now_ns: u64) -> Phase {
        if !self.phase.under_way() {
            return self.phase;
        }
        let acknowledged = statusword & sw::MODE_SPECIFIC_12 != 0;
        let waited = now_ns.saturating_sub(self.started_ns);
        let homing = mode_display == Some(Mode::Homing as i8);
        match self.phase {
            _ if State::from_statusword(statusword) != Some(State::OperationEnabled) => Phase::Stuck(Stuck::NotEnabled),
            Phase::Raised if homing && statusword & sw::MODE_SPECIFIC_13 != 0 => Phase::Stuck(Stuck::HomingError),
            Phase::Raised if acknowledged => Phase::Done,
            Phase::Raised if waited >= self.timeout_ns => Phase::Stuck(Stuck::NeverSet),
            Phase::Raised => Phase::Raised,
            _ if !acknowledged => Phase::Raised,
            _ if waited >= self.clear_timeout_ns => Phase::Stuck(Stuck::NeverCleared),
            _ => Phase::Clearing,
        }
    }

    /// The published status.
    pub fn status(&self) -> HandshakeStatus {
        let progress = match self.phase {
            Phase::Idle => Progress::Idle,
            Phase::Taken | Phase::Clearing | Phase::Raised => Progress::InProgress,
            Phase::Done => Progress::Done,
            Phase::Stuck(why) => Progress::Stuck(why),
        };
        HandshakeStatus { request: self.request, bits: self.bits, progress, statusword: self.statusword }
    }

    /// The controlword bits to add in this cycle.
    pub fn bits(&self) -> u16 {
        if self.phase == Phase::Raised {
            self.bits
        } else {
            0
        }
    }

    /// Adds the raised bits to the controlword at `controlword` in `outputs`.
    pub fn apply(&self, outputs: &mut [u8], controlword: usize) {
        let bits = self.bits();
        if bits != 0 {
            let word = u16::from_le_bytes([outputs[controlword], outputs[controlword + 1]]) | bits;
            outputs[controlword..controlword + 2].copy_from_slice(&word.to_le_bytes());
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const TIMEOUT: Duration = Duration::from_millis(10);
    const MS: u64 = 1_000_000;
    const ENABLED: u16 = 0x0027;

    fn run(h: &mut Handshake, shared: &HandshakeShared, statusword: u16, mode: i8, t_ms: u64) -> (Progress, u16) {
        h.observe(shared, statusword, Some(mode), t_ms * MS);
        (h.status().progress, h.bits())
    }

    #[test]
    fn raises_the_bits_the_cycle_after_it_took_them_and_lowers_them_at_bit_12() {
        let (mut h, shared) = (Handshake::default(), HandshakeShared::default());
        assert_eq!(shared.status().progress, Progress::Idle);
        assert_eq!(shared.start(0x0030, TIMEOUT, TIMEOUT), 1);
        assert_eq!(
            shared.status(),
            HandshakeStatus { request: 1, bits: 0x30, progress: Progress::InProgress, statusword: 0 }
        );
        assert_eq!(run(&mut h, &shared, ENABLED, 1, 0), (Progress::InProgress, 0));
        assert_eq!(run(&mut h, &shared, ENABLED, 1, 1), (Progress::InProgress, 0x30));
        assert_eq!(run(&mut h, &shared, ENABLED, 1, 2), (Progress::InProgress, 0x30));
        assert_eq!(run(&mut h, &shared, ENABLED | 0x1000, 1, 3), (Progress::Done, 0));
        assert_eq!(shared.status().progress, Progress::Done);
    }

    #[test]
    fn starts_from_bit_12_clear_or_gets_stuck_saying_so() {
        let (mut h, shared) = (Handshake::default(), HandshakeShared::default());
        shared.start(0x0030, TIMEOUT, TIMEOUT);
        run(&mut h, &shared, ENABLED | 0x1000, 1, 0);
        assert_eq!(run(&mut h, &shared, ENABLED | 0x1000, 1, 5), (Progress::InProgress, 0));
        assert_eq!(run(&mut h, &shared, ENABLED, 1, 6), (Progress::InProgress, 0x30));
        shared.start(0x0030, TIMEOUT, TIMEOUT);
        run(&mut h, &shared, ENABLED | 0x1000, 1, 20);
        assert_eq!(run(&mut h, &shared, ENABLED | 0x1000, 1, 30), (Progress::Stuck(Stuck::NeverCleared), 0));
        let why = shared.status().stuck_reason().unwrap();
        assert!(why.starts_with("set-point handshake (controlword bits 0x0030) stuck in Operation enabled"), "{why}");
        assert!(why.contains("bit 12 stayed set"), "{why}");
    }

    #[test]
    fn a_drive_not_enabled_or_a_homing_error_ends_it_stuck() {
        let (mut h, shared) = (Handshake::default(), HandshakeShared::default());
        shared.start(0x0010, TIMEOUT, TIMEOUT);
        run(&mut h, &shared, 0x0040, 6, 0);
        assert_eq!(run(&mut h, &shared, 0x0040, 6, 1), (Progress::Stuck(Stuck::NotEnabled), 0));
        assert!(shared.status().stuck_reason().unwrap().contains("stuck in Switch on disabled"));
        shared.start(0x0010, TIMEOUT, TIMEOUT);
        run(&mut h, &shared, ENABLED, 6, 2);
        assert_eq!(run(&mut h, &shared, ENABLED, 6, 3), (Progress::InProgress, 0x10));
        assert_eq!(run(&mut h, &shared, ENABLED | 0x2000, 6, 4), (Progress::Stuck(Stuck::HomingError), 0));
        // Bit 13 in profile position is a following error, not the end of the handshake.
        shared.start(0x0030, TIMEOUT, TIMEOUT);
        run(&mut h, &shared, ENABLED, 1, 5);
        assert_eq!(run(&mut h, &shared, ENABLED | 0x2000, 1, 6), (Progress::InProgress, 0x30));
        // The time-out counts from the raise.
        assert_eq!(run(&mut h, &shared, ENABLED | 0x2000, 1, 15), (Progress::InProgress, 0x30));
        assert_eq!(run(&mut h, &shared, ENABLED | 0x2000, 1, 16), (Progress::Stuck(Stuck::NeverSet), 0));
    }

    #[test]
    fn a_request_replacing_one_under_way_goes_out_low_first() {
        let (mut h, shared) = (Handshake::default(), HandshakeShared::default());
        shared.start(0x0030, TIMEOUT, TIMEOUT);
        run(&mut h, &shared, ENABLED, 1, 0);
        assert_eq!(run(&mut h, &shared, ENABLED, 1, 1).1, 0x30);
        assert_eq!(shared.start(0x0010, TIMEOUT, TIMEOUT), 2);
        assert_eq!(run(&mut h, &shared, ENABLED, 1, 2), (Progress::InProgress, 0));
        assert_eq!(run(&mut h, &shared, ENABLED, 1, 3), (Progress::InProgress, 0x10));
    }

    #[test]
    fn status_packs_and_unpacks() {
        let stuck = Stuck::ALL.map(Progress::Stuck);
        for progress in [Progress::Idle, Progress::InProgress, Progress::Done].into_iter().chain(stuck) {
            let s = HandshakeStatus { request: u32::MAX, bits: 0x70, progress, statusword: 0xBEEF };
            assert_eq!(HandshakeStatus::unpack(s.pack()), s);
        }
    }
}
