//! Recovery of a slave the cycle lost: one that stopped answering (power cycled, its cable
//! pulled, the line down) or left Op. The cycle thread notices it ([`Presence`]), asks the drive
//! for Switch on disabled and reports it; a recovery thread beside the cycle then brings the
//! slave back on a restoring master ([`Master::for_restore`]) whose frames the cycle thread
//! sends for it, one per cycle after its own exchange ([`Relay`]), so the other drives cycle
//! on: the master takes it to PreOp ([`Master::restore_to_preop`]), the drive profile writes its
//! mode and clock again ([`AkdSlave::restore`]), and the master takes it to Op
//! ([`Master::restore_to_op`]). When the slave is back in Op the cycle thread reports it and holds
//! its target at the actual position; its power stage stays off until it is enabled again.
//! Attempts repeat while the slave does not answer, and a slave that comes back in Op by itself
//! (a short cut of the line) is taken back without a restore.

use std::sync::atomic::{AtomicBool, AtomicU16, AtomicU32, AtomicU64, AtomicU8, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use crate::cycle::seqlock::SeqBytes;
use crate::drive::akd::{AkdLine, AkdSlave};
use crate::error::Result;
use crate::ethercat::frame::MAX_PAYLOAD_LEN;
use crate::ethercat::link::Link;
use crate::ethercat::master::restore::Restoring;
use crate::ethercat::master::Master;

/// Cycles without an answer after which a slave is taken as lost (the AKD's own limit).
pub const LOST_AFTER: u32 = crate::cycle::supervision::DRIVE_MISSED_FRAME_LIMIT;
/// How long the recovery thread waits after a failed attempt before the next.
pub const RETRY_INTERVAL: Duration = Duration::from_millis(200);
/// How often the recovery thread looks whether the cycle thread lost a slave, while none is lost.
const IDLE_POLL: Duration = Duration::from_millis(20);
/// How often it looks while one is.
const RECOVERING_POLL: Duration = Duration::from_millis(2);

const FREE: u8 = 0;
const ASKED: u8 = 1;
const TAKEN: u8 = 2;
const DONE: u8 = 3;

/// The hand-over of one frame between the recovery thread and the cycle thread.
pub struct Relay {
    state: AtomicU8,
    request: SeqBytes,
    request_len: AtomicU16,
    reply: SeqBytes,
    /// The reply's length; 0 when the frame was lost.
    reply_len: AtomicU16,
    /// Set when the cycle thread ends: nobody serves frames any more.
    ended: AtomicBool,
    /// Frames sent for the recovery thread, and those that did not come back.
    frames: AtomicU64,
    lost: AtomicU64,
}

impl Default for Relay {
    fn default() -> Self {
        Relay {
            state: AtomicU8::new(FREE),
            request: SeqBytes::new(MAX_PAYLOAD_LEN, &[]),
            request_len: AtomicU16::new(0),
            reply: SeqBytes::new(MAX_PAYLOAD_LEN, &[]),
            reply_len: AtomicU16::new(0),
            ended: AtomicBool::new(false),
            frames: AtomicU64::new(0),
            lost: AtomicU64::new(0),
        }
    }
}

/// The cycle thread's buffers for relayed frames, allocated before it starts.
pub struct RelayBuffers {
    tx: Box<[u8; MAX_PAYLOAD_LEN]>,
    rx: Box<[u8; MAX_PAYLOAD_LEN]>,
}

impl Default for RelayBuffers {
    fn default() -> Self {
        RelayBuffers { tx: Box::new([0; MAX_PAYLOAD_LEN]), rx: Box::new([0; MAX_PAYLOAD_LEN]) }
    }
}

impl Relay {
    /// In the cycle thread, after its exchange: sends the frame waiting, if any, and hands its
    /// reply back. It is counted here and with the master's frames (a loss too), as the mailbox
    /// frames beside the cycle are.
    pub fn serve(&self, master: &mut Master, buffers: &mut RelayBuffers) {
        if self.state.compare_exchange(ASKED, TAKEN, Ordering::AcqRel, Ordering::Acquire).is_err() {
            return;
        }
        let len = (self.request_len.load(Ordering::Relaxed) as usize).min(MAX_PAYLOAD_LEN);
        self.request.read(&mut buffers.tx[..]);
        self.frames.fetch_add(1, Ordering::Relaxed);
        let n = match master.relay(&buffers.tx[..len], &mut buffers.rx[..]) {
            Ok(n) => n,
            Err(_) => {
                self.lost.fetch_add(1, Ordering::Relaxed);
                0
            }
        };
        self.reply.write().write(0, &buffers.rx[..n]);
        self.reply_len.store(n as u16, Ordering::Relaxed);
        self.state.store(DONE, Ordering::Release);
    }

    /// The cycle thread ended.
    pub fn end(&self) {
        self.ended.store(true, Ordering::Release);
    }

    /// Frames relayed, and those lost.
    pub fn counts(&self) -> (u64, u64) {
        (self.frames.load(Ordering::Relaxed), self.lost.load(Ordering::Relaxed))
    }
}

/// A link whose frames the cycle thread sends between its exchanges.
pub struct RelayLink {
    relay: Arc<Relay>,
    describe: String,
    /// The cycle's period: a frame waits at most a few for its turn.
    period: Duration,
}

impl RelayLink {
    /// A link through `relay`, described as the cycle's own link `describe` is.
    pub fn new(relay: Arc<Relay>, describe: String, period: Duration) -> Self {
        RelayLink { relay, describe: format!("{describe} (beside the cycle)"), period }
    }
}

impl Link for RelayLink {
    /// Asks the cycle thread to send `tx`; once it has ended, the frame is lost at once.
    fn send(&mut self, tx: &[u8]) -> Result<()> {
        if self.relay.ended.load(Ordering::Acquire) {
            return Ok(());
        }
        let len = tx.len().min(MAX_PAYLOAD_LEN);
        self.relay.request.write().write(0, &tx[..len]);
        self.relay.request_len.store(len as u16, Ordering::Relaxed);
        self.relay.state.store(ASKED, Ordering::Release);
        Ok(())
    }

    /// The return of the frame sent, once the cycle thread has sent it in its turn: a frame
    /// waits a few periods for that beyond `deadline`.
    fn receive(&mut self, rx: &mut [u8], deadline: Instant) -> Result<Option<usize>> {
        let deadline = deadline + 4 * self.period;
        loop {
            match self.relay.state.load(Ordering::Acquire) {
                DONE => break,
                FREE => return Ok(None),
                ASKED
                    if (Instant::now() >= deadline || self.relay.ended.load(Ordering::Acquire))
                        && self
                            .relay
                            .state
                            .compare_exchange(ASKED, FREE, Ordering::AcqRel, Ordering::Acquire)
                            .is_ok() =>
                {
                    return Ok(None);
                }
                _ => {}
            }
            std::thread::sleep(Duration::from_micros(50));
        }
        let n = self.relay.reply_len.load(Ordering::Relaxed) as usize;
        let mut reply = [0u8; MAX_PAYLOAD_LEN];
        self.relay.reply.read(&mut reply);
        self.relay.state.store(FREE, Ordering::Release);
        if n == 0 {
            return Ok(None);
        }
        crate::ethercat::link::copy_reply(&reply[..n], rx).map(Some)
    }

    fn describe(&self) -> String {
        self.describe.clone()
    }

    fn awaited(&self) -> &'static str {
        "a frame sent beside the cycle"
    }
}

/// A slave's recovery as the cycle thread and the recovery thread share it.
#[derive(Default)]
pub struct SlaveRecovery {
    wanted: AtomicBool,
    /// Set while a restore runs: the slave may reach Op before the restore has handed its
    /// mailbox counter back.
    restoring: AtomicBool,
    attempts: AtomicU32,
    recoveries: AtomicU32,
    /// The mailbox counter of the last message to the slave, handed between the cycle's master
    /// and the recovery's, so that the slave never takes a new message for a repeat.
    mailbox_counter: AtomicU8,
    /// The mode of operation last set, which a restore writes to 0x6060 again; the cycle
    /// thread never takes this lock.
    mode: Mutex<Option<i8>>,
    /// Why the last attempt failed; the cycle thread never takes this lock.
    last_error: Mutex<Option<String>>,
}

/// Where a slave's recovery stands, for callers.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "python", derive(pyo3::IntoPyObject))]
pub struct RecoveryStatus {
    /// Whether the slave is lost and being brought back.
    pub recovering: bool,
    /// Attempts to restore it since it was lost.
    pub attempts: u32,
    /// Times a restore brought it back since the cycle started (one that came back by itself
    /// is not counted).
    pub recoveries: u32,
    /// Why the last attempt failed, if it did.
    pub last_error: Option<String>,
}

impl SlaveRecovery {
    /// Notes the mode last set, which a restore writes again.
    pub fn set_mode(&self, mode: i8) {
        *self.mode.lock().unwrap_or_else(|p| p.into_inner()) = Some(mode);
    }

    /// The mode last set.
    pub fn mode(&self) -> Option<i8> {
        *self.mode.lock().unwrap_or_else(|p| p.into_inner())
    }

    /// Where it stands.
    pub fn status(&self) -> RecoveryStatus {
        RecoveryStatus {
            recovering: self.wanted.load(Ordering::Acquire),
            attempts: self.attempts.load(Ordering::Relaxed),
            recoveries: self.recoveries.load(Ordering::Relaxed),
            last_error: self.last_error.lock().unwrap_or_else(|p| p.into_inner()).clone(),
        }
    }
}

/// What [`Presence::observe`] saw change.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PresenceChange {
    /// The slave is lost from this cycle on: `report` when nothing else reported it yet (a
    /// slave that left Op was reported as such).
    Lost {
        /// Whether to report it.
        report: bool,
        /// Cycles it went unanswered.
        missing: u32,
    },
    /// The slave is back in Op, lost since `since` (cycle, time ns).
    Back {
        /// When it was lost.
        since: (u64, u64),
    },
}

/// One slave's presence, as the cycle thread judges it every cycle.
#[derive(Clone, Copy, Debug, Default)]
pub struct Presence {
    missing: u32,
    lost: Option<(u64, u64)>,
}

impl Presence {
    /// Takes one cycle: whether the slave answered its supervision reads, and whether it is in
    /// Op. Lost after [`LOST_AFTER`] cycles unanswered or when it answers out of Op; back when
    /// it answers in Op again.
    pub fn observe(&mut self, answered: bool, in_op: bool, now: (u64, u64)) -> Option<PresenceChange> {
        if let Some(since) = self.lost {
            if in_op {
                *self = Presence::default();
                return Some(PresenceChange::Back { since });
            }
            return None;
        }
        if in_op {
            self.missing = 0;
            return None;
        }
        if answered {
            self.lost = Some(now);
            return Some(PresenceChange::Lost { report: false, missing: self.missing });
        }
        self.missing += 1;
        if self.missing >= LOST_AFTER {
            self.lost = Some(now);
            return Some(PresenceChange::Lost { report: true, missing: self.missing });
        }
        None
    }

    /// Whether the slave is lost.
    pub fn lost(&self) -> bool {
        self.lost.is_some()
    }
}

/// The recovery thread's side: the restoring master, the cycle's period and which slaves it
/// brings back.
pub struct Recoverer {
    master: Master,
    period: Duration,
    recovered: Vec<bool>,
}

impl Recoverer {
    /// A recoverer of `master`'s slaves, those `recovered` says, whose frames go through
    /// `relay`, cycling every `period`.
    pub fn new(master: &Master, relay: Arc<Relay>, period: Duration, recovered: Vec<bool>) -> Self {
        let link = RelayLink::new(relay, master.describe(), period);
        Recoverer { master: master.for_restore(Box::new(link)), period, recovered }
    }

    /// Brings the drive at `position` back to Op: the master's two halves of a restore, the
    /// drive profile's writes between them (its `mode` and its clock's side as the set-up gave
    /// it; the cycle time of a drive on the SM2 event is the cycle's period).
    fn restore(&mut self, position: u16, mode: Option<i8>) -> Result<()> {
        if self.master.restore_to_preop(position)? == Restoring::InOp {
            return Ok(());
        }
        let sync = self.master.drive_sync(position, self.period.as_nanos() as u32);
        self.master.slave_mut(position)?.restore(mode, sync)?;
        self.master.restore_to_op(position)
    }

    /// Runs until `stop`: restores every slave the cycle thread asks for, one at a time.
    pub fn run(mut self, slaves: &[SlaveRecovery], stop: &AtomicBool) {
        let mut next_try = vec![Instant::now(); slaves.len()];
        while !stop.load(Ordering::Acquire) {
            for (position, slave) in slaves.iter().enumerate() {
                if !self.recovered.get(position).is_some_and(|&r| r)
                    || !slave.wanted.load(Ordering::Acquire)
                    || Instant::now() < next_try[position]
                {
                    continue;
                }
                // 0 is no mode: the drive refuses it, and keeps its power-up mode.
                let mode = slave.mode.lock().unwrap_or_else(|p| p.into_inner()).filter(|&m| m != 0);
                let p = position as u16;
                self.master.set_mailbox_counter(p, slave.mailbox_counter.load(Ordering::Acquire));
                slave.attempts.fetch_add(1, Ordering::Relaxed);
                slave.restoring.store(true, Ordering::Release);
                let outcome = self.restore(p, mode);
                slave.mailbox_counter.store(self.master.mailbox_counter(p).unwrap_or(0), Ordering::Release);
                slave.restoring.store(false, Ordering::Release);
                let mut last_error = slave.last_error.lock().unwrap_or_else(|p| p.into_inner());
                match outcome {
                    Ok(()) => {
                        *last_error = None;
                        slave.recoveries.fetch_add(1, Ordering::Relaxed);
                        // Not asked again until the cycle thread sees it back or lost anew.
                        next_try[position] = Instant::now() + RETRY_INTERVAL;
                    }
                    Err(e) => {
                        *last_error = Some(e.to_string());
                        next_try[position] = Instant::now() + RETRY_INTERVAL;
                    }
                }
            }
            // Soon again while a slave is lost; rarely while none is (it cost 0.2-0.4 % of a core at 500 Hz).
            let lost = slaves.iter().any(|s| s.wanted.load(Ordering::Acquire));
            std::thread::sleep(if lost { RECOVERING_POLL } else { IDLE_POLL });
        }
    }
}

/// The cycle thread lost the slave (whose last mailbox message had `mailbox_counter`): the
/// recovery thread brings it back.
pub fn want(slave: &SlaveRecovery, mailbox_counter: u8) {
    slave.attempts.store(0, Ordering::Relaxed);
    slave.mailbox_counter.store(mailbox_counter, Ordering::Release);
    slave.wanted.store(true, Ordering::Release);
}

/// The cycle thread sees the slave back in Op: no more attempts. Gives the mailbox counter its
/// master goes on from.
pub fn done(slave: &SlaveRecovery) -> u8 {
    slave.wanted.store(false, Ordering::Release);
    slave.mailbox_counter.load(Ordering::Acquire)
}

/// Whether a restore of the slave is under way: it is not back before that ends.
pub fn restoring(slave: &SlaveRecovery) -> bool {
    slave.restoring.load(Ordering::Acquire)
}

/// Whether the slave is being brought back (its mailbox is the recovery's then).
pub fn busy(slave: &SlaveRecovery) -> bool {
    slave.wanted.load(Ordering::Acquire)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_slave_is_lost_after_the_limit_unanswered_and_back_when_it_answers_in_op() {
        let mut p = Presence::default();
        for cycle in 1..LOST_AFTER as u64 {
            assert_eq!(p.observe(false, false, (cycle, cycle)), None);
        }
        assert_eq!(p.observe(false, false, (8, 8)), Some(PresenceChange::Lost { report: true, missing: LOST_AFTER }));
        assert!(p.lost());
        // Answering out of Op (being restored) keeps it lost; Op brings it back.
        assert_eq!(p.observe(true, false, (9, 9)), None);
        assert_eq!(p.observe(true, true, (10, 10)), Some(PresenceChange::Back { since: (8, 8) }));
        assert!(!p.lost());
    }

    #[test]
    fn a_short_gap_is_forgotten_and_leaving_op_is_lost_at_once_without_a_second_report() {
        let mut p = Presence::default();
        assert_eq!(p.observe(false, false, (1, 1)), None);
        assert_eq!(p.observe(true, true, (2, 2)), None);
        for cycle in 3..3 + LOST_AFTER as u64 - 1 {
            assert_eq!(p.observe(false, false, (cycle, cycle)), None);
        }
        assert_eq!(
            p.observe(true, false, (20, 20)),
            Some(PresenceChange::Lost { report: false, missing: LOST_AFTER - 1 })
        );
    }

    #[test]
    fn a_relayed_frame_without_a_cycle_to_send_it_is_lost_not_waited_for() {
        let relay = Arc::new(Relay::default());
        relay.end();
        let mut link = RelayLink::new(relay, "sim".into(), Duration::from_millis(1));
        let err = link.exchange(&[0; 16], &mut [0; 64], Duration::from_millis(1)).unwrap_err();
        assert!(err.to_string().contains("beside the cycle"), "{err}");
        assert_eq!(link.describe(), "sim (beside the cycle)");
    }
}
