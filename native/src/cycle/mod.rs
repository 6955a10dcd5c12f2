//! The real-time cycle thread: it owns a [`Master`](crate::ethercat::master::Master) whose bus is in Op and exchanges its
//! process image every period, sleeping to absolute deadlines on the monotonic clock.
//!
//! Other threads (Python among them) never touch the master while it cycles: they write
//! set-points into a lock-free buffer that the thread copies into the output image before each
//! exchange, and read snapshots (cycle count, time, working counter, inputs) that the thread
//! publishes after it. Statistics are atomics the thread updates and anyone reads. Nothing in
//! the loop allocates, takes a lock or needs the GIL; the thread never waits on another one.
//! (A failed exchange comes back as an [`Error`](crate::error::Error) whose text allocates: only in a cycle that
//! already went wrong, and counted.) Failed cycles do not stop the thread: what to do about
//! them is the caller's decision, made from the counters and snapshots.
//! [`CycleThread::stop`] hands the master back, e.g. to bring the bus down.
//!
//! Drives whose mapping carries controlword and statusword are sequenced in the loop by
//! [`sequencer`]: [`CycleThread::request`] asks for enable, disable, quick stop or fault reset,
//! [`CycleThread::drive_status`] tells how far it is. The set-point handshake of profile
//! position and the start of homing run there too ([`handshake`],
//! [`CycleThread::start_setpoint`]), and so does the command time-out of velocity and torque
//! streams ([`command_timeout`], [`CycleThread::set_command_timeout`]), and joint trajectories
//! are followed there ([`trajectory_player`], [`CycleThread::follow_trajectory`]).
//!
//! [`CycleThread`] is the handle the other threads hold (`handle.rs`), the loop is the thread's
//! own (`run.rs`), and what both share is here.
//!
//! [`timing`] holds the deadlines, [`rt`] the real-time settings, [`stats`] the statistics,
//! [`seqlock`] the lock-free buffers, [`sequencer`] the drive sequencer, [`supervision`] the
//! fault supervision, [`latch`] the position latch, [`acyclic`] the mailbox traffic beside
//! the cycle and [`dc_status`] the distributed clocks ([`CycleThread::dc_status`]); [`samples`]
//! the per-cycle records, which [`crate::ros::cycle_sample`] serialises for the bag.
//!
//! A slave the loop loses (no answer, or out of Op) is reported and its drive disabled there;
//! [`recovery`] brings it back beside the cycle ([`CycleThread::recovery_status`]), its power
//! stage off, while the other drives cycle on. The slaves it does not sequence, the devices
//! beside the drives (terminals), are run by [`devices`]: their inputs' edges reported, their
//! outputs switched off where the loop decides it, their presence judged and their recovery
//! asked for as a drive's.
//!
//! A few times a second the thread also reads every slave's links and error counters in a frame
//! beside its own ([`line_health`], [`CycleThread::line_health`]), when no mailbox or recovery
//! frame took the cycle's room.
//!
//! By default each cycle waits for its frame's return. [`RealTime::pipelined`] sends the frame
//! without waiting and takes its return at the next wake-up, before anything else: the outputs
//! are written from inputs as old as when waiting (the last return), the frame still leaves
//! right after the wake-up, and the round trip costs the cycle neither time nor CPU, so a lost
//! frame no longer holds it for up to a period. What a cycle read is published a period later.

use std::sync::atomic::{AtomicBool, AtomicU64};
use std::sync::Arc;

pub use handle::{Config, CycleThread, Snapshot};
pub use rt::RealTime;

pub mod acyclic;
pub mod command;
pub mod command_timeout;
pub mod dc_status;
pub mod devices;
pub mod eoe_frames;
pub mod events;
mod handle;
pub mod handshake;
pub mod homing;
pub mod image;
pub mod latch;
pub mod line_health;
pub mod recovery;
pub mod ring;
pub mod rt;
mod run;
pub mod samples;
pub mod seqlock;
pub mod sequencer;
pub mod stats;
pub mod supervision;
pub mod timing;
pub mod trajectory_player;

use acyclic::SdoSlot;
use events::Events;
use samples::Samples;
use seqlock::SeqBytes;
use stats::CycleStats;
/// A lock that a panicking holder left is still the same handle (the cycle's callers and the
/// node's feed: neither leaves what it guards half changed).
pub(crate) fn lock<T>(m: &std::sync::Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|p| p.into_inner())
}

/// The snapshot header's layout: cycle (u64), time (u64), working counter (u16), whether the
/// cycle's inputs are fresh (u8); the input image follows, then the output image as sent.
const HEADER_LEN: usize = 8 + 8 + 2 + 1;

/// What the thread and the other threads share.
struct CycleShared {
    stop: AtomicBool,
    setpoints: SeqBytes,
    snapshot: SeqBytes,
    stats: CycleStats,
    /// One per slave, sequenced or not.
    drives: Vec<sequencer::SequencerShared>,
    /// How long a drive request may take before it is reported stuck (ns).
    request_timeout_ns: AtomicU64,
    /// One per slave: the latch edges armed.
    latches: Vec<latch::LatchShared>,
    /// One per slave: the set-point handshake asked for.
    handshakes: Vec<handshake::HandshakeShared>,
    /// One per slave: the command time-out.
    command_timeouts: Vec<command_timeout::CommandTimeoutShared>,
    /// One per slave: its homing.
    homings: Vec<homing::HomingShared>,
    events: Events,
    samples: Samples,
    sdo: SdoSlot,
    /// Ethernet frames to and from the drives' IP stacks (EoE beside the process data).
    eoe: eoe_frames::EoeFrames,
    /// Whether a fault on one drive quick-stops the others ([`CycleThread::set_quick_stop_on_fault`]).
    quick_stop_on_fault: AtomicBool,
    dc: dc_status::DcStatusShared,
    trajectories: trajectory_player::PlayerShared,
    /// Frames of the recovery thread, sent by the cycle thread.
    relay: Arc<recovery::Relay>,
    /// One per slave: its recovery.
    recovery: Vec<recovery::SlaveRecovery>,
    /// One per slave: what a device beside the drives asks of the loop.
    devices: Vec<devices::DeviceShared>,
    /// Whether the cyclic frame reads every slave's AL status: without, no drive's presence can
    /// be judged, and none is taken as lost.
    supervised: bool,
    /// Every slave's links and error counters, read beside the cycle.
    line_health: line_health::LineHealthShared,
}
