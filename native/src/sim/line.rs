//! The line between the master and the drives, and what goes wrong on it as in the field:
//! frames lost on the way, replies corrupted, working counters that do not add up, and a cable
//! pulled out in front of a drive.
//!
//! Each fault is a count of frames still to hit, so a test asks for exactly the burst it
//! wants; a count of 0 ends one. A pulled cable ends the line in front of its drive: frames
//! stop there, the drive before it closes its port 1 and returns them, so they come back with
//! the working counters of the drives before it only. The drives behind it keep their power:
//! their firmware keeps running on bus time and misses the frames (the watchdog and the
//! drive's own supervision see that), and they carry on where they were when replugged. With
//! the cable in front of the first drive pulled no ESC returns anything: every frame is lost.
//!
//! A faulty cable spoils frames entering one port of one slave, one in every so many frames
//! as a flaky connector does, as many as asked ([`Line::spoil_port`]): the slave's ESC counts it
//! there, marks it, and every ESC after it on the frame's way counts a forwarded error; the
//! master never gets it (its NIC drops a frame whose CRC is bad), see [`super::VirtualBus`].

use crate::ethercat::line_health::registers::PORTS;

/// What became of a frame sent down the line.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Delivery {
    /// It came back (served, possibly corrupted or with a wrong working counter).
    Returned,
    /// It did not come back: no reply at all.
    Lost,
}

/// A burst of frames a fault hits.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Burst {
    /// The next frames the line receives are lost before the first drive.
    Lost(u64),
    /// The next replies come back with the EtherCAT frame header's length one short, so a
    /// master's codec refuses them.
    Corrupted(u64),
    /// The next replies carry a wrong working counter in every datagram.
    WrongWkc(u64),
}

impl Burst {
    /// A count of frames as a caller gives it; refused when negative.
    pub fn frames(frames: i64) -> crate::error::Result<u64> {
        u64::try_from(frames).map_err(|_| crate::error::SettingError::FrameCount { frames }.into())
    }
}

/// What the line did to the frames it carried since it was laid, never reset: the virtual
/// AKDs' own count, for a master's counts to be checked against.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
// Python gets a dict keyed by the field names (Simulator.line_counts).
#[cfg_attr(feature = "python", derive(pyo3::IntoPyObject))]
pub struct LineCounts {
    /// Frames that reached the line (a malformed one, refused untouched, is not carried).
    pub frames: u64,
    /// Frames lost before the first drive: a burst, or the cable in front of it out.
    pub lost: u64,
    /// Replies corrupted (a frame lost too, for a master whose link refuses them).
    pub corrupted: u64,
    /// Replies given a wrong working counter.
    pub wrong_wkc: u64,
    /// Frames a faulty cable spoiled on their way ([`Line::spoil_port`]), lost to the master.
    pub spoiled: u64,
}

/// Frames a faulty cable spoils entering one port: `frames` more, one in every `every`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
struct Spoiling {
    frames: u64,
    every: u64,
    /// Frames that entered the port since the fault began.
    seen: u64,
}

/// The state of the line: bursts still pending, which cables are out, and its counts.
#[derive(Clone, Debug, Default)]
pub struct Line {
    lost: u64,
    corrupted: u64,
    wrong_wkc: u64,
    /// `pulled[i]`: the cable in front of drive `i` is out.
    pulled: Vec<bool>,
    /// `spoiling[i][port]`: what a faulty cable does to the frames entering that port of drive `i`.
    spoiling: Vec<[Spoiling; PORTS]>,
    counts: LineCounts,
}

impl Line {
    /// A line in front of `count` drives, every cable in.
    pub fn new(count: usize) -> Self {
        Line { pulled: vec![false; count], spoiling: vec![[Spoiling::default(); PORTS]; count], ..Line::default() }
    }

    /// Starts `burst`, replacing one of the same kind still pending.
    pub fn start(&mut self, burst: Burst) {
        match burst {
            Burst::Lost(n) => self.lost = n,
            Burst::Corrupted(n) => self.corrupted = n,
            Burst::WrongWkc(n) => self.wrong_wkc = n,
        }
    }

    /// Pulls the cable in front of drive `position` out (`plugged` false) or back in.
    /// Panics when `position` is not on the line (checked by the caller).
    pub fn set_cable(&mut self, position: usize, plugged: bool) {
        self.pulled[position] = !plugged;
    }

    /// Whether the cable in front of drive `position` is in; `false` past the line.
    pub fn plugged(&self, position: usize) -> bool {
        self.pulled.get(position).is_some_and(|p| !p)
    }

    /// Makes the cable into `port` of drive `position` spoil the next `frames` frames entering
    /// there, one in every `every` (at least 1), replacing a fault pending there. Panics when
    /// `position` is not on the line or `port` is no port (checked by the caller).
    pub fn spoil_port(&mut self, position: usize, port: usize, frames: u64, every: u64) {
        self.spoiling[position][port] = Spoiling { frames, every: every.max(1), seen: 0 };
    }

    /// A frame enters `port` of drive `position`: whether the cable there spoils it.
    pub fn spoils(&mut self, position: usize, port: usize) -> bool {
        let Some(s) = self.spoiling.get_mut(position).and_then(|p| p.get_mut(port)) else { return false };
        if s.frames == 0 {
            return false;
        }
        s.seen += 1;
        let hit = s.seen.is_multiple_of(s.every);
        s.frames -= u64::from(hit);
        hit
    }

    /// Frames still to spoil at `port` of drive `position`.
    pub fn spoiling(&self, position: usize, port: usize) -> u64 {
        self.spoiling.get(position).and_then(|p| p.get(port)).map_or(0, |s| s.frames)
    }

    /// Counts a frame a faulty cable spoiled.
    pub fn count_spoiled(&mut self) {
        self.counts.spoiled += 1;
    }

    /// How many drives a frame reaches: those in front of the first pulled cable.
    pub fn reach(&self) -> usize {
        self.pulled.iter().position(|&p| p).unwrap_or(self.pulled.len())
    }

    /// Frames still to lose, to corrupt, and to give a wrong working counter.
    pub fn pending(&self) -> (u64, u64, u64) {
        (self.lost, self.corrupted, self.wrong_wkc)
    }

    /// What the line did so far.
    pub fn counts(&self) -> LineCounts {
        self.counts
    }

    /// Takes the next frame onto the line: whether it is lost before the first drive, by a
    /// burst or because no drive is reached. Counts it.
    pub fn carry(&mut self) -> bool {
        self.counts.frames += 1;
        let lost = take(&mut self.lost) || self.reach() == 0;
        self.counts.lost += u64::from(lost);
        lost
    }

    /// Spoils a served `payload` as the pending bursts ask: a wrong working counter first, then
    /// the frame header's length one short. `payload` is a valid frame.
    pub fn spoil(&mut self, payload: &mut [u8]) {
        if take(&mut self.wrong_wkc) {
            self.counts.wrong_wkc += 1;
            // One less than the drives gave, or 1 where none answered: wrong either way.
            let wrong = crate::ethercat::frame::for_each_datagram_mut(payload, |dg| {
                dg.wkc = if dg.wkc == 0 { 1 } else { dg.wkc - 1 };
            });
            debug_assert!(wrong.is_ok(), "a served frame is valid: {wrong:?}");
        }
        if take(&mut self.corrupted) {
            self.counts.corrupted += 1;
            let header = u16::from_le_bytes([payload[0], payload[1]]);
            let len = header & 0x07FF;
            payload[..2].copy_from_slice(&((header & !0x07FF) | (len.wrapping_sub(1) & 0x07FF)).to_le_bytes());
        }
    }
}

fn take(count: &mut u64) -> bool {
    let hit = *count > 0;
    *count = count.saturating_sub(1);
    hit
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bursts_count_down_and_replace_each_other() {
        let mut line = Line::new(2);
        line.start(Burst::Lost(2));
        assert_eq!((line.carry(), line.carry(), line.carry()), (true, true, false));
        line.start(Burst::WrongWkc(5));
        line.start(Burst::WrongWkc(1));
        line.start(Burst::Corrupted(0));
        assert_eq!(line.pending(), (0, 0, 1));
    }

    #[test]
    fn a_negative_count_is_named() {
        assert_eq!(Burst::frames(3).unwrap(), 3);
        let e = Burst::frames(-1).unwrap_err().to_string();
        assert!(e.contains("-1 frames: allowed are 0 (ends the burst) or more"), "{e}");
    }

    #[test]
    fn the_first_pulled_cable_ends_the_line() {
        let mut line = Line::new(3);
        assert_eq!(line.reach(), 3);
        line.set_cable(2, false);
        line.set_cable(1, false);
        assert_eq!(line.reach(), 1);
        line.set_cable(1, true);
        assert_eq!(line.reach(), 2);
        line.set_cable(2, true);
        assert_eq!(line.reach(), 3);
    }

    #[test]
    fn a_faulty_cable_spoils_one_frame_in_every_so_many_as_many_as_asked() {
        let mut line = Line::new(2);
        line.spoil_port(1, 1, 2, 3);
        let hits: Vec<bool> = (0..9).map(|_| line.spoils(1, 1)).collect();
        assert_eq!(hits, [false, false, true, false, false, true, false, false, false]);
        assert!(!line.spoils(1, 0) && !line.spoils(7, 0), "other ports and past the line: never");
        line.spoil_port(0, 0, 1, 1);
        assert_eq!(line.spoiling(0, 0), 1);
        assert!(line.spoils(0, 0));
        assert_eq!(line.spoiling(0, 0), 0);
    }
}
