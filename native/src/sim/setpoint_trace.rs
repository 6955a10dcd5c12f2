//! The set-points the virtual AKDs receive, traced to a file (`akd-sim --setpoint-trace FILE`):
//! for each drive in Op, every change of what its RxPDO carries of target position 0x607A, target
//! velocity 0x60FF, target torque 0x6071, controlword 0x6040 and modes of operation 0x6060
//! (those mapped), stamped with the time the frame carrying it reached the server.
//!
//! The serving thread only compares the values with the last ones and hands a change to a
//! bounded channel allocated up front ([`TraceSender`]); a writer thread of its own writes the file
//! ([`SetpointTrace`]). The writer polls the channel rather than waiting in it, so a hand-over
//! never has to wake a thread: the serving path makes no system call for the trace beyond
//! reading the two clocks. A change the writer could not take in time is dropped and counted.
//!
//! The file is JSON lines, one object per change, in the order the frames came:
//!
//! ```text
//! {"drive":0,"frame":5231,"index":143,"realtime_ns":1764660000123456789,"monotonic_ns":81234567890,
//!  "position":1234.5,"changed":["target_position"],"target_position":1669,"controlword":15,"modes_of_operation":8}
//! ```
//!
//! (one line in the file): `drive` its position on the line; `frame` the line's count of frames
//! carried so far ([`crate::sim::line::LineCounts::frames`]) and `index` the master's index in the
//! frame's first datagram (a master counts its cycles there); `realtime_ns` and `monotonic_ns`
//! CLOCK_REALTIME and CLOCK_MONOTONIC when the server received the frame; `position` the actual
//! position 0x6064 reports (counts, the model's fractional resolution) as the frame passed;
//! `changed` the names of the values that changed (all of those mapped in a drive's first line,
//! and after it left Op); then every value mapped, as its data type reads. The last line is
//! `{"end":{"changes":N,"dropped":M}}`: the changes written, and those dropped because the writer
//! fell behind.

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::mpsc::{self, Receiver, SyncSender, TryRecvError, TrySendError};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::Duration;

use crate::drive::objects;
use crate::error::{Error, Result, Unavailable};
use crate::ethercat::pdo::PdoEntry;
use crate::sim::VirtualBus;

/// The set-points traced, with their names in the file: index (subindex 0) and name.
pub const SETPOINTS: [(u16, &str); 5] = [
    (0x607A, "target_position"),
    (0x60FF, "target_velocity"),
    (0x6071, "target_torque"),
    (0x6040, "controlword"),
    (0x6060, "modes_of_operation"),
];

/// Changes that may wait for the writer: at 4 kHz with six drives changing every frame, more
/// than a second's worth.
pub const CAPACITY: usize = 32 * 1024;

/// How often the writer looks for changes when none are waiting.
const WRITER_POLL: Duration = Duration::from_millis(10);

/// The values of [`SETPOINTS`] one drive received, `None` where its mapping lacks one.
pub type Setpoints = [Option<i64>; SETPOINTS.len()];

/// Nanoseconds on `clock` (CLOCK_REALTIME since the Unix epoch, CLOCK_MONOTONIC since boot).
pub(crate) fn clock_ns(clock: libc::clockid_t) -> u64 {
    let mut ts = libc::timespec { tv_sec: 0, tv_nsec: 0 };
    // Both clocks always exist on Linux and `ts` is valid: this cannot fail.
    unsafe { libc::clock_gettime(clock, &mut ts) };
    ts.tv_sec as u64 * 1_000_000_000 + ts.tv_nsec as u64
}

/// When a frame reached the server, on both clocks.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Stamps {
    /// CLOCK_REALTIME, ns since the Unix epoch: comparable with another process's system clock.
    pub realtime_ns: u64,
    /// CLOCK_MONOTONIC, ns: never steps back.
    pub monotonic_ns: u64,
}

impl Stamps {
    /// Now.
    pub fn now() -> Self {
        Stamps { realtime_ns: clock_ns(libc::CLOCK_REALTIME), monotonic_ns: clock_ns(libc::CLOCK_MONOTONIC) }
    }
}

/// Which frame carried a change, and when it came.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Frame {
    /// The line's count of frames carried, this one included.
    pub number: u64,
    /// The index of its first datagram.
    pub index: u8,
    /// When it reached the server.
    pub received: Stamps,
}

/// One change of a drive's set-points.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Change {
    /// The drive's position on the line.
    pub drive: usize,
    /// The frame that carried it.
    pub frame: Frame,
    /// The actual position, counts.
    pub position: f64,
    /// Bit k: `SETPOINTS[k]` changed.
    pub changed: u8,
    /// Every set-point mapped.
    pub values: Setpoints,
}

/// What a finished trace holds.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
// Python gets a dict keyed by the field names (SetpointTrace.close).
#[cfg_attr(feature = "python", derive(pyo3::IntoPyObject))]
pub struct TraceSummary {
    /// Changes written.
    pub changes: u64,
    /// Changes dropped because the writer fell behind.
    pub dropped: u64,
}

/// The serving side of a trace: compares each drive's set-points with the last ones and hands
/// the changes over without waiting; allocates nothing once made.
pub struct TraceSender {
    to_writer: SyncSender<Change>,
    dropped: Arc<AtomicU64>,
    /// The last set-points of each drive.
    last: Vec<Setpoints>,
}

impl TraceSender {
    fn new(to_writer: SyncSender<Change>, dropped: Arc<AtomicU64>, drives: usize) -> Self {
        TraceSender { to_writer, dropped, last: vec![[None; SETPOINTS.len()]; drives] }
    }

    /// Notes drive `drive`'s set-points as `frame` left them, a change if they differ from the
    /// last ones; a drive not in Op (`received` None) has none, and its next ones are all new.
    /// A drive beyond those the sender was made for is not traced.
    pub fn record(&mut self, drive: usize, received: Option<(&[PdoEntry], &[u8])>, position: f64, frame: Frame) {
        let Some(last) = self.last.get_mut(drive) else { return };
        let values = received.map_or([None; SETPOINTS.len()], |(entries, outputs)| {
            SETPOINTS.map(|(index, _)| objects::read(entries, outputs, index, 0))
        });
        let changed = (0..SETPOINTS.len())
            .filter(|&k| values[k].is_some() && values[k] != last[k])
            .fold(0u8, |mask, k| mask | 1 << k);
        *last = values;
        if changed == 0 {
            return;
        }
        match self.to_writer.try_send(Change { drive, frame, position, changed, values }) {
            Ok(()) => {}
            Err(TrySendError::Full(_) | TrySendError::Disconnected(_)) => {
                self.dropped.fetch_add(1, Ordering::Relaxed);
            }
        }
    }

    /// Notes every drive's set-points after `bus` served `payload`, received at `received`; a
    /// drive is named by its position on the line (terminals have none).
    pub fn record_bus(&mut self, bus: &VirtualBus, payload: &[u8], received: Stamps) {
        let first = crate::ethercat::frame::parse(payload).ok().and_then(|mut d| d.next()).and_then(|d| d.ok());
        let index = first.map_or(0, |d| d.header.index);
        let frame = Frame { number: bus.line().counts().frames, index, received };
        for drive in 0..bus.len() {
            if let Some(akd) = bus.at(drive).akd() {
                self.record(drive, akd.received_outputs(), akd.drive().position(), frame);
            }
        }
    }
}

/// Writes one change as a line of the file.
fn write_change(out: &mut impl Write, change: &Change) -> std::io::Result<()> {
    let Change { drive, frame, position, changed, values } = change;
    write!(
        out,
        "{{\"drive\":{drive},\"frame\":{},\"index\":{},\"realtime_ns\":{},\"monotonic_ns\":{},\"position\":{position},\
         \"changed\":[",
        frame.number, frame.index, frame.received.realtime_ns, frame.received.monotonic_ns
    )?;
    let names = SETPOINTS.iter().enumerate().filter(|(k, _)| changed & 1 << k != 0);
    for (n, (_, (_, name))) in names.enumerate() {
        write!(out, "{}\"{name}\"", if n == 0 { "" } else { "," })?;
    }
    out.write_all(b"]")?;
    for ((_, name), value) in SETPOINTS.iter().zip(values) {
        if let Some(value) = value {
            write!(out, ",\"{name}\":{value}")?;
        }
    }
    out.write_all(b"}\n")
}

/// The writer: writes the changes as they come until every sender is gone, then the end line.
/// After a write error it keeps taking changes (so that they count as written nowhere, not as
/// waiting) and reports the first error at the end.
fn write_trace(file: File, changes: Receiver<Change>, dropped: &AtomicU64) -> std::io::Result<TraceSummary> {
    let mut out = BufWriter::new(file);
    let mut written = 0u64;
    let mut result = Ok(());
    loop {
        match changes.try_recv() {
            Ok(change) => {
                if result.is_ok() {
                    result = write_change(&mut out, &change);
                    written += 1;
                }
            }
            Err(TryRecvError::Empty) => {
                result = result.and_then(|()| out.flush());
                std::thread::sleep(WRITER_POLL);
            }
            Err(TryRecvError::Disconnected) => break,
        }
    }
    let summary = TraceSummary { changes: written, dropped: dropped.load(Ordering::Relaxed) };
    result?;
    writeln!(out, "{{\"end\":{{\"changes\":{},\"dropped\":{}}}}}", summary.changes, summary.dropped)?;
    out.into_inner().map_err(|e| e.into_error())?.sync_data()?;
    Ok(summary)
}

/// A trace file and its writer thread.
pub struct SetpointTrace {
    path: PathBuf,
    /// Until a server takes its [`TraceSender`].
    to_writer: Option<SyncSender<Change>>,
    dropped: Arc<AtomicU64>,
    /// `None` once finished.
    writer: Option<JoinHandle<std::io::Result<TraceSummary>>>,
}

impl SetpointTrace {
    /// Creates (or truncates) the trace file at `path` and starts its writer; an error names the
    /// file.
    pub fn create(path: impl AsRef<Path>) -> Result<Self> {
        let path = path.as_ref().to_path_buf();
        let context = |what: &str| format!("{what} set-point trace {}", path.display());
        let file = File::create(&path).map_err(|e| Error::io(context("creating"), e))?;
        let (to_writer, changes) = mpsc::sync_channel(CAPACITY);
        let dropped = Arc::new(AtomicU64::new(0));
        let counted = dropped.clone();
        let writer = std::thread::Builder::new()
            .name("setpoint-trace".into())
            .spawn(move || write_trace(file, changes, &counted))
            .map_err(|e| Error::io(context("starting the writer thread of"), e))?;
        Ok(SetpointTrace { path, to_writer: Some(to_writer), dropped, writer: Some(writer) })
    }

    /// The sender of a server of `drives` drives; one server per trace.
    pub fn sender(&mut self, drives: usize) -> Result<TraceSender> {
        let why = if self.writer.is_none() { "is closed" } else { "records a server already: one server per trace" };
        let to_writer = self
            .to_writer
            .take()
            .ok_or_else(|| Unavailable::SetpointTrace { path: self.path.display().to_string(), why })?;
        Ok(TraceSender::new(to_writer, self.dropped.clone(), drives))
    }

    /// Waits for the server recording (once it stopped, its sender is gone), writes what is
    /// left and the end line, and closes the file; an error names it.
    pub fn finish(&mut self) -> Result<TraceSummary> {
        self.to_writer = None;
        let Some(writer) = self.writer.take() else {
            return Err(Unavailable::SetpointTrace { path: self.path.display().to_string(), why: "is closed" }.into());
        };
        let written = writer.join().unwrap_or_else(|_| Err(std::io::Error::other("the writer thread panicked")));
        written.map_err(|e| Error::io(format!("writing set-point trace {}", self.path.display()), e))
    }
}

impl Drop for SetpointTrace {
    fn drop(&mut self) {
        // An owner that never finished still gets a complete file; a failure has nobody to tell.
        if self.writer.is_some() {
            let _ = self.finish();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ethercat::pdo::PdoEntry;

    /// 0x1724's outputs: target position, controlword, torque offset.
    const CSP: [PdoEntry; 3] =
        [PdoEntry::new(0x607A, 0, 32), PdoEntry::new(0x6040, 0, 16), PdoEntry::new(0x60B2, 0, 16)];

    fn outputs(target: i32, controlword: u16, torque_offset: i16) -> Vec<u8> {
        [&target.to_le_bytes()[..], &controlword.to_le_bytes(), &torque_offset.to_le_bytes()].concat()
    }

    fn frame(number: u64) -> Frame {
        Frame { number, index: number as u8, received: Stamps::now() }
    }

    fn temp_path(name: &str) -> PathBuf {
        std::env::temp_dir().join(format!("akd_setpoint_trace_{name}_{}.jsonl", std::process::id()))
    }

    #[test]
    fn only_changes_are_recorded_and_drops_are_counted() {
        let (to_writer, changes) = mpsc::sync_channel(3);
        let dropped = Arc::new(AtomicU64::new(0));
        let mut sender = TraceSender::new(to_writer, dropped.clone(), 2);
        let sent = [
            (0, Some(outputs(-5, 0x06, 7))), // first sight: every mapped value
            (0, Some(outputs(-5, 0x06, 9))), // the torque offset is not traced
            (1, None),                       // not in Op
            (0, Some(outputs(-5, 0x0F, 9))),
            (0, Some(outputs(100, 0x0F, 9))),
            (0, Some(outputs(200, 0x0F, 9))), // the channel is full: dropped
            (0, None),
            (0, Some(outputs(200, 0x0F, 9))), // back in Op: all new again, dropped too
        ];
        for (n, (drive, data)) in sent.iter().enumerate() {
            sender.record(*drive, data.as_deref().map(|d| (&CSP[..], d)), n as f64, frame(n as u64));
        }
        // A drive the sender was not made for is left out.
        sender.record(2, Some((&CSP, &outputs(1, 1, 1))), 0.0, frame(99));
        assert_eq!(dropped.load(Ordering::Relaxed), 2);
        drop(sender);
        let got: Vec<Change> = changes.iter().collect();
        let summary: Vec<_> = got.iter().map(|c| (c.frame.number, c.changed, c.values[0], c.values[3])).collect();
        assert_eq!(
            summary,
            [
                (0, 0b01001, Some(-5), Some(0x06)),
                (3, 0b01000, Some(-5), Some(0x0F)),
                (4, 0b00001, Some(100), Some(0x0F))
            ]
        );
        assert!(got.iter().all(|c| c.values[1].is_none() && c.values[2].is_none() && c.values[4].is_none()));
        assert!(got.windows(2).all(|w| w[0].frame.received.monotonic_ns <= w[1].frame.received.monotonic_ns));
        assert_eq!(got[1].position, 3.0);
    }

    #[test]
    fn the_file_holds_one_line_per_change_and_ends_with_the_counts() {
        let path = temp_path("lines");
        let (to_writer, changes) = mpsc::sync_channel(2);
        let dropped = Arc::new(AtomicU64::new(0));
        let mut sender = TraceSender::new(to_writer, dropped.clone(), 1);
        for (n, target) in [10, 20, 30].into_iter().enumerate() {
            sender.record(0, Some((&CSP, &outputs(target, 0x0F, 0))), 0.5, frame(n as u64 + 1));
        }
        drop(sender);
        let summary = write_trace(File::create(&path).unwrap(), changes, &dropped).unwrap();
        assert_eq!(summary, TraceSummary { changes: 2, dropped: 1 });
        let text = std::fs::read_to_string(&path).unwrap();
        std::fs::remove_file(&path).unwrap();
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(lines.len(), 3, "{text}");
        let first = lines[0];
        assert!(first.starts_with("{\"drive\":0,\"frame\":1,\"index\":1,\"realtime_ns\":"), "{first}");
        assert!(
            first.ends_with(",\"position\":0.5,\"changed\":[\"target_position\",\"controlword\"],\"target_position\":10,\"controlword\":15}"),
            "{first}"
        );
        assert!(lines[1].contains("\"changed\":[\"target_position\"],\"target_position\":20,"), "{}", lines[1]);
        assert_eq!(lines[2], "{\"end\":{\"changes\":2,\"dropped\":1}}");
    }

    #[test]
    fn a_trace_serves_one_recorder_and_finishes_once() {
        let path = temp_path("once");
        let mut trace = SetpointTrace::create(&path).unwrap();
        let mut sender = trace.sender(1).unwrap();
        let e = trace.sender(1).err().unwrap().to_string();
        assert!(e.contains("records a server already"), "{e}");
        sender.record(0, Some((&CSP, &outputs(1, 0x0F, 0))), 0.0, frame(1));
        drop(sender);
        assert_eq!(trace.finish().unwrap(), TraceSummary { changes: 1, dropped: 0 });
        assert!(trace.finish().unwrap_err().to_string().contains("is closed"));
        let text = std::fs::read_to_string(&path).unwrap();
        std::fs::remove_file(&path).unwrap();
        assert_eq!(text.lines().last(), Some("{\"end\":{\"changes\":1,\"dropped\":0}}"));
    }

    #[test]
    fn a_bad_path_is_named() {
        let e = SetpointTrace::create("/akd-no-such-dir/trace.jsonl").err().unwrap().to_string();
        assert!(e.starts_with("creating set-point trace /akd-no-such-dir/trace.jsonl: "), "{e}");
    }
}
