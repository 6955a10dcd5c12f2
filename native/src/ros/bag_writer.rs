//! A rosbag2 bag's MCAP files written by a thread of their own, so that recording every cycle of
//! every drive costs no other thread anything but handing over bytes, and a slow disk costs
//! records (dropped and counted), never a delay to whoever hands them over.
//!
//! A [`BagWriter`] takes, in the order given: topics (schema and channel of each), messages
//! already serialised, batches of per-cycle records, faults and the end. Its thread also pulls
//! per-cycle records itself from a [`CycleSource`] (a running cycle's records, see
//! `node::cycle_records`) every [`PULL_INTERVAL`], so the records of a cycle thread reach the
//! bag without passing through any other thread.
//!
//! - Per-cycle records go to the cycle topic every `decimation`-th cycle, and all of them into
//!   a ring of the last `black_box` seconds; a fault writes the records of its window that no
//!   earlier fault wrote to the black box topic. The records go into the open chunk at once; the
//!   chunk is closed and synced to the disk at the first fault, and at most once per
//!   `sync_interval` for the faults after it (coalesced: a host losing frames every few
//!   seconds costs one close and sync per interval, not one per fault and drive).
//! - Chunks close every `chunk_size` bytes or `flush_interval`; files split by size or by
//!   duration, each complete with every schema and channel.
//! - metadata.yaml and the `rosbag2` metadata record that ends each file are YAML the caller
//!   makes (the Python recorder, from a [`Report`]): a file that is split off or ended waits,
//!   parked, until [`BagWriter::finish`] gives that text.
//! - Handing over never blocks: a full queue drops and counts. An I/O failure is reported once
//!   (in the [`Report`]) and recording stops; what comes after is counted as dropped.
//! - [`BagWriter::hold`] stops the thread where it is until released: a disk that stalls, on
//!   demand, for tests and for measuring what a stall costs.

use std::collections::{BTreeMap, VecDeque};
use std::path::PathBuf;
use std::sync::{Arc, Condvar, Mutex, MutexGuard};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use crate::ros::bag_file::BagFile;

/// How often the thread takes records from its [`CycleSource`]: a cycle keeps two seconds.
pub const PULL_INTERVAL: Duration = Duration::from_millis(20);
/// rosbag2's schema encoding of a .msg definition.
const SCHEMA_ENCODING: &str = "ros2msg";
/// rosbag2's message encoding.
const MESSAGE_ENCODING: &str = "cdr";

/// Per-cycle records that a writer's thread takes for itself.
pub trait CycleSource: Send {
    /// Every record since the last call, each (time ns, serialised message), in time order.
    fn take(&mut self) -> Vec<(i64, Vec<u8>)>;
}

/// A topic: its name, the schema of its type and its channel's metadata.
#[derive(Clone, Debug)]
pub struct Topic {
    /// The absolute topic name.
    pub name: String,
    /// The type's full name, e.g. "sensor_msgs/msg/JointState".
    pub type_name: String,
    /// The type's complete definition (ros2msg).
    pub definition: Vec<u8>,
    /// The channel's metadata (rosbag2: offered_qos_profiles, topic_type_hash).
    pub metadata: BTreeMap<String, String>,
}

/// How a writer writes.
#[derive(Clone, Debug)]
pub struct Options {
    /// The folder the bag directory is made in.
    pub folder: PathBuf,
    /// The bag directory's name; `_2`, `_3`, ... is added when it exists.
    pub name: String,
    /// The chunks' compression; `None`: not compressed.
    pub compression: Option<mcap::Compression>,
    /// The MCAP header's profile and library.
    pub profile: String,
    /// The writing library's name.
    pub library: String,
    /// Bytes in a chunk that close it.
    pub chunk_size: usize,
    /// The age of a chunk that closes it.
    pub flush_interval: Duration,
    /// A file's size from which the next one starts.
    pub split_size: Option<u64>,
    /// A file's span (ns) from which the next one starts.
    pub split_duration_ns: Option<i64>,
    /// Messages, or batches of records, waiting beyond which the next is dropped.
    pub queue_size: usize,
    /// Every how many cycles a cycle's records go to the cycle topic (0: none).
    pub decimation: u64,
    /// Records per cycle (one per drive), which decimation keeps or drops together.
    pub samples_per_cycle: u64,
    /// The black box's window (ns); `None` without black box.
    pub black_box_ns: Option<i64>,
    /// Records the black box ring holds.
    pub ring_size: usize,
    /// The least time between two syncs for faults.
    pub sync_interval: Duration,
}

/// One MCAP file of the bag, as metadata.yaml lists it.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "python", derive(pyo3::IntoPyObject))]
pub struct FileInfo {
    /// Its path.
    pub path: PathBuf,
    /// Its first and last message's time (ns), once it has one.
    pub span: Option<(i64, i64)>,
    /// Its messages.
    pub messages: u64,
}

impl FileInfo {
    fn add(&mut self, first: i64, last: i64, count: u64) {
        self.span = Some(self.span.map_or((first, last), |(a, b)| (a.min(first), b.max(last))));
        self.messages += count;
    }
}

/// Where a writer stands, for whoever writes metadata.yaml (`BagWriter.report` in Python).
#[derive(Clone, Debug, Default)]
#[cfg_attr(feature = "python", derive(pyo3::IntoPyObject))]
pub struct Report {
    /// Grows with every change below.
    pub version: u64,
    /// The bag directory, once made.
    pub bag: Option<PathBuf>,
    /// Every file so far.
    pub files: Vec<FileInfo>,
    /// The messages of each topic the thread has added, in the order added.
    pub topic_messages: Vec<u64>,
    /// Files no longer written to, whose metadata record waits for [`BagWriter::finish`].
    pub parked: usize,
    /// The first I/O failure, which stopped recording.
    pub failure: Option<String>,
    /// The end was asked for: every file is parked, or none when none can be finished.
    pub closing: bool,
    /// The thread has ended.
    pub done: bool,
}

/// The writer's counters since it was made.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "python", derive(pyo3::IntoPyObject))]
pub struct Counters {
    /// Messages in the bag's closed chunks or in the open one.
    pub written: u64,
    /// Messages and records refused (queue full, recording stopped) or lost with a failed disk.
    pub dropped: u64,
    /// I/O failures.
    pub errors: u64,
    /// Faults whose black box was written.
    pub black_box_dumps: u64,
    /// Closes and syncs of the chunk for faults.
    pub black_box_syncs: u64,
}

enum Item {
    Topic(Topic),
    CycleTopics { cycle: Option<usize>, black_box: Option<usize> },
    Message { topic: usize, time_ns: i64, data: Vec<u8> },
    Records(Vec<(i64, Vec<u8>)>),
    Source(Box<dyn CycleSource>),
    Fault(i64),
    Finish(String),
    Close,
}

impl Item {
    /// Messages it carries, as counted when dropped.
    fn messages(&self) -> u64 {
        match self {
            Item::Message { .. } => 1,
            Item::Records(records) => records.len() as u64,
            _ => 0,
        }
    }
}

#[derive(Default)]
struct Inbox {
    items: Vec<Item>,
    /// Items that count against the queue's size (messages and batches of records).
    queued: usize,
    /// No item is taken any more (failed or closed).
    refusing: bool,
}

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|p| p.into_inner())
}

struct WriterShared {
    inbox: Mutex<Inbox>,
    arrived: Condvar,
    report: Mutex<Report>,
    reported: Condvar,
    held: Mutex<bool>,
    released: Condvar,
    counters: Mutex<Counters>,
    queue_size: usize,
}

impl WriterShared {
    fn push(&self, item: Item, wake: bool) -> bool {
        let mut inbox = lock(&self.inbox);
        let counted = matches!(item, Item::Message { .. } | Item::Records(_));
        let refused = if counted {
            inbox.refusing || inbox.queued >= self.queue_size
        } else {
            inbox.refusing && !matches!(item, Item::Finish(_))
        };
        if refused {
            let messages = item.messages();
            drop(inbox);
            lock(&self.counters).dropped += messages;
            return false;
        }
        inbox.queued += counted as usize;
        inbox.items.push(item);
        // Messages wait for the thread's next round; a control item, or a queue half full, wakes it.
        if wake || inbox.queued * 2 >= self.queue_size {
            self.arrived.notify_one();
        }
        true
    }

    fn update(&self, change: impl FnOnce(&mut Report)) {
        let mut report = lock(&self.report);
        change(&mut report);
        report.version += 1;
        self.reported.notify_all();
    }
}

/// A bag being written by its thread (see the module).
pub struct BagWriter {
    shared: Arc<WriterShared>,
    thread: Mutex<Option<JoinHandle<()>>>,
}

impl BagWriter {
    /// Starts the thread, which makes the bag directory and its first file.
    pub fn start(options: Options) -> std::io::Result<BagWriter> {
        let shared = Arc::new(WriterShared {
            inbox: Mutex::default(),
            arrived: Condvar::new(),
            report: Mutex::default(),
            reported: Condvar::new(),
            held: Mutex::new(false),
            released: Condvar::new(),
            counters: Mutex::default(),
            queue_size: options.queue_size,
        });
        let writer = Writer::new(shared.clone(), options);
        let thread = std::thread::Builder::new().name("akd-bag".into()).spawn(move || writer.run())?;
        Ok(BagWriter { shared, thread: Mutex::new(Some(thread)) })
    }

    /// Adds a topic, given its index (the topics' order).
    pub fn add_topic(&self, topic: Topic) {
        self.shared.push(Item::Topic(topic), true);
    }

    /// Names the per-cycle topic and the black box topic among the topics added (by index).
    pub fn set_cycle_topics(&self, cycle: Option<usize>, black_box: Option<usize>) {
        self.shared.push(Item::CycleTopics { cycle, black_box }, true);
    }

    /// Queues a serialised message of topic `topic` (its index) at `time_ns`; false when it
    /// was dropped (and counted).
    pub fn write(&self, topic: usize, time_ns: i64, data: Vec<u8>) -> bool {
        self.shared.push(Item::Message { topic, time_ns, data }, false)
    }

    /// Queues per-cycle records of consecutive cycles (time ns, serialised message); false
    /// when they were dropped (and counted).
    pub fn records(&self, records: Vec<(i64, Vec<u8>)>) -> bool {
        self.shared.push(Item::Records(records), false)
    }

    /// From now on the thread takes per-cycle records from `source` as well.
    pub fn attach(&self, source: Box<dyn CycleSource>) {
        self.shared.push(Item::Source(source), true);
    }

    /// A fault at `time_ns`: its black box is written (see the module).
    pub fn fault(&self, time_ns: i64) {
        self.shared.push(Item::Fault(time_ns), true);
    }

    /// The metadata record's text for the files parked so far, which the thread then ends.
    pub fn finish(&self, metadata: String) {
        self.shared.push(Item::Finish(metadata), true);
    }

    /// Asks for the end: what is queued is written, the open file parked; [`finish`] then ends
    /// the files and the thread.
    ///
    /// [`finish`]: BagWriter::finish
    pub fn close(&self) {
        self.shared.push(Item::Close, true);
    }

    /// Holds the thread where it is (`true`) until released (`false`).
    pub fn hold(&self, held: bool) {
        *lock(&self.shared.held) = held;
        self.shared.released.notify_all();
    }

    /// The report once its version passes `seen`, or the current one after `timeout`.
    pub fn report(&self, seen: u64, timeout: Duration) -> Report {
        let report = lock(&self.shared.report);
        let (report, _) = self
            .shared
            .reported
            .wait_timeout_while(report, timeout, |r| r.version <= seen)
            .unwrap_or_else(|p| p.into_inner());
        report.clone()
    }

    /// The counters.
    pub fn counters(&self) -> Counters {
        *lock(&self.shared.counters)
    }

    /// Waits up to `timeout` for the thread's end; whether it ended.
    pub fn join(&self, timeout: Duration) -> bool {
        let report = lock(&self.shared.report);
        let (report, _) =
            self.shared.reported.wait_timeout_while(report, timeout, |r| !r.done).unwrap_or_else(|p| p.into_inner());
        if !report.done {
            return false;
        }
        drop(report);
        // Done is the thread's last word: it returns right after.
        if let Some(thread) = lock(&self.thread).take() {
            let _ = thread.join();
        }
        true
    }
}

/// The open file: its channels by topic index.
struct Open {
    file: BagFile,
    schemas: BTreeMap<String, u16>,
    channels: Vec<u16>,
    index: usize,
}

/// What the thread works with.
struct Writer {
    shared: Arc<WriterShared>,
    options: Options,
    bag: Option<PathBuf>,
    topics: Vec<Topic>,
    open: Option<Open>,
    parked: Vec<BagFile>,
    files: Vec<FileInfo>,
    topic_messages: Vec<u64>,
    pending_bytes: usize,
    last_flush: Instant,
    cycle_topic: Option<usize>,
    black_box_topic: Option<usize>,
    /// Records taken so far: the next record's serial number.
    serial: u64,
    ring: VecDeque<(u64, i64, Vec<u8>)>,
    /// Runs [first, end) of serial numbers a fault wrote already, sorted.
    dumped: Vec<(u64, u64)>,
    source: Option<Box<dyn CycleSource>>,
    last_sync: Option<Instant>,
    sync_due: Option<Instant>,
    failed: bool,
    closing: bool,
    /// What the report says changed since it was last made.
    changed: bool,
    /// The files and the topics' messages as of the last closed chunk, which the report gives.
    closed: (Vec<FileInfo>, Vec<u64>),
}

impl Writer {
    fn new(shared: Arc<WriterShared>, options: Options) -> Writer {
        Writer {
            shared,
            bag: None,
            topics: Vec::new(),
            open: None,
            parked: Vec::new(),
            files: Vec::new(),
            topic_messages: Vec::new(),
            pending_bytes: 0,
            last_flush: Instant::now(),
            cycle_topic: None,
            black_box_topic: None,
            serial: 0,
            ring: VecDeque::with_capacity(options.ring_size.min(1 << 20)),
            dumped: Vec::new(),
            source: None,
            last_sync: None,
            sync_due: None,
            failed: false,
            closing: false,
            changed: false,
            closed: (Vec::new(), Vec::new()),
            options,
        }
    }

    fn run(mut self) {
        if let Err(e) = self.open_bag() {
            let bag = self.options.folder.join(&self.options.name);
            self.failed_because(format!("cannot open bag {}: {}", bag.display(), error_text(&e)));
        }
        self.report();
        loop {
            let items = self.wait();
            let mut faults = Vec::new();
            let mut finish = None;
            for item in items {
                match item {
                    Item::Fault(time_ns) => faults.push(time_ns),
                    Item::Finish(text) => finish = Some(text),
                    Item::Close => self.closing = true,
                    other => self.guarded(|w| w.handle(other)),
                }
            }
            self.guarded(|w| w.pull());
            if !faults.is_empty() {
                self.guarded(|w| w.black_box(&faults));
            }
            self.guarded(|w| w.flush_if_due());
            if self.closing && self.open.is_some() {
                // The end: the records the source has after this round are not the bag's.
                self.source = None;
                self.guarded(|w| w.park());
            }
            let finished = finish.is_some();
            if let Some(text) = finish {
                self.guarded(|w| w.finish_parked(&text));
            }
            let closed = self.closing && self.parked.is_empty();
            if self.closing {
                lock(&self.shared.inbox).refusing = true;
            }
            if self.closing || finished || std::mem::take(&mut self.changed) {
                self.report();
            }
            if closed {
                self.shared.update(|r| r.done = true);
                return;
            }
        }
    }

    /// Waits for items, a due deadline or the release of a hold; takes the items.
    fn wait(&mut self) -> Vec<Item> {
        let held = lock(&self.shared.held);
        drop(self.shared.released.wait_while(held, |h| *h).unwrap_or_else(|p| p.into_inner()));
        let deadline = self.next_deadline();
        let inbox = lock(&self.shared.inbox);
        let timeout = deadline.saturating_duration_since(Instant::now());
        let (mut inbox, _) = self
            .shared
            .arrived
            .wait_timeout_while(inbox, timeout, |i| i.items.is_empty())
            .unwrap_or_else(|p| p.into_inner());
        inbox.queued = 0;
        std::mem::take(&mut inbox.items)
    }

    fn next_deadline(&self) -> Instant {
        let mut deadline =
            Instant::now() + if self.source.is_some() { PULL_INTERVAL } else { self.options.flush_interval };
        if self.pending_bytes > 0 {
            deadline = deadline.min(self.last_flush + self.options.flush_interval);
        }
        self.sync_due.map_or(deadline, |due| deadline.min(due))
    }

    fn guarded(&mut self, action: impl FnOnce(&mut Writer) -> std::io::Result<()>) {
        if let Err(e) = action(self) {
            self.fail(e);
        }
    }

    fn fail(&mut self, error: std::io::Error) {
        let bag = self.bag.clone().unwrap_or_else(|| self.options.folder.join(&self.options.name));
        self.failed_because(format!("recording into {} stopped: {}", bag.display(), error_text(&error)));
    }

    /// Stops recording for the first failure, `text`; counts every one.
    fn failed_because(&mut self, text: String) {
        lock(&self.shared.counters).errors += 1;
        if self.failed {
            return;
        }
        self.failed = true;
        self.pending_bytes = 0;
        self.open = None;
        self.parked.clear();
        // What waits is lost with the failed disk.
        let mut inbox = lock(&self.shared.inbox);
        let lost: u64 = inbox.items.iter().map(Item::messages).sum();
        inbox.items.retain(|i| matches!(i, Item::Close | Item::Finish(_) | Item::Fault(_)));
        inbox.queued = 0;
        drop(inbox);
        lock(&self.shared.counters).dropped += lost;
        self.shared.update(|r| r.failure = Some(text));
    }

    /// Notes what the closed chunks hold, which the next report gives.
    fn closed_chunk(&mut self) {
        self.changed = true;
        self.closed = (self.files.clone(), self.topic_messages.clone());
    }

    fn report(&self) {
        let (files, counts) = self.closed.clone();
        let (parked, bag) = (self.parked.len(), self.bag.clone());
        let closing = self.closing;
        self.shared.update(|r| {
            r.files = files;
            r.topic_messages = counts;
            r.parked = parked;
            r.bag = bag;
            r.closing = closing;
        });
    }

    fn open_bag(&mut self) -> std::io::Result<()> {
        let o = &self.options;
        std::fs::create_dir_all(&o.folder)?;
        let mut number = 1;
        loop {
            let name = if number == 1 { o.name.clone() } else { format!("{}_{number}", o.name) };
            let bag = o.folder.join(&name);
            match std::fs::create_dir(&bag) {
                Ok(()) => {
                    self.options.name = name;
                    self.bag = Some(bag);
                    break;
                }
                Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => number += 1,
                Err(e) => return Err(e),
            }
        }
        self.open_file()?;
        self.closed_chunk();
        Ok(())
    }

    fn open_file(&mut self) -> std::io::Result<()> {
        let Some(bag) = self.bag.as_ref() else { return Ok(()) };
        let path = bag.join(format!("{}_{}.mcap", self.options.name, self.files.len()));
        let o = &self.options;
        let file = BagFile::create(&path, o.compression, &o.profile, &o.library).map_err(io_error)?;
        let mut open = Open { file, schemas: BTreeMap::new(), channels: Vec::new(), index: self.files.len() };
        for topic in &self.topics {
            add_channel(&mut open, topic)?;
        }
        self.files.push(FileInfo { path, ..FileInfo::default() });
        self.open = Some(open);
        Ok(())
    }

    fn handle(&mut self, item: Item) -> std::io::Result<()> {
        match item {
            Item::Topic(topic) => {
                if let Some(open) = self.open.as_mut() {
                    add_channel(open, &topic)?;
                }
                self.topics.push(topic);
                self.topic_messages.push(0);
                self.closed.1.push(0);
                self.changed = true;
            }
            Item::CycleTopics { cycle, black_box } => (self.cycle_topic, self.black_box_topic) = (cycle, black_box),
            Item::Message { topic, time_ns, data } => self.write(topic, &[(time_ns, &data)])?,
            Item::Records(records) => self.take_records(records)?,
            Item::Source(source) => self.source = Some(source),
            Item::Fault(_) | Item::Finish(_) | Item::Close => unreachable!("taken by run"),
        }
        Ok(())
    }

    /// Takes the records of the cycle source.
    fn pull(&mut self) -> std::io::Result<()> {
        let Some(source) = self.source.as_mut() else { return Ok(()) };
        let records = source.take();
        if records.is_empty() {
            return Ok(());
        }
        self.take_records(records)
    }

    /// Puts records of consecutive cycles into the ring, and every decimation-th cycle's to
    /// the cycle topic.
    fn take_records(&mut self, records: Vec<(i64, Vec<u8>)>) -> std::io::Result<()> {
        let (first, count) = (self.serial, records.len() as u64);
        self.serial += count;
        let decimation = self.options.decimation;
        if let (Some(topic), true) = (self.cycle_topic, decimation > 0) {
            let per_cycle = self.options.samples_per_cycle.max(1);
            let kept: Vec<(i64, &[u8])> = records
                .iter()
                .enumerate()
                .filter(|(i, _)| ((first + *i as u64) / per_cycle).is_multiple_of(decimation))
                .map(|(_, (t, data))| (*t, data.as_slice()))
                .collect();
            self.write(topic, &kept)?;
        }
        if self.options.black_box_ns.is_some() && self.black_box_topic.is_some() {
            for (i, (time_ns, data)) in records.into_iter().enumerate() {
                if self.ring.len() == self.options.ring_size {
                    self.ring.pop_front();
                }
                self.ring.push_back((first + i as u64, time_ns, data));
            }
        }
        Ok(())
    }

    /// Writes the black box of `faults` (ns): the records of their windows no fault wrote before.
    ///
    /// Faults may come out of time order (an emergency before the Fault state seen in an earlier
    /// cycle): each writes its whole window but no record written before. The ring holds
    /// consecutive serial numbers in cycle order, so windows and what was written are runs
    /// found by bisection, and a fault costs the records it writes, not the ring.
    fn black_box(&mut self, faults: &[i64]) -> std::io::Result<()> {
        let (Some(window_ns), Some(topic)) = (self.options.black_box_ns, self.black_box_topic) else {
            return Ok(());
        };
        let Some(&(first, ..)) = self.ring.front() else {
            self.count_dumps(faults.len());
            return Ok(());
        };
        self.dumped.retain(|&(_, end)| end > first);
        let windows: Vec<(u64, u64)> = faults
            .iter()
            .map(|&fault| {
                let start = self.ring.partition_point(|r| r.1 <= fault - window_ns) as u64;
                let end = self.ring.partition_point(|r| r.1 <= fault) as u64;
                (first + start, first + end)
            })
            .collect();
        let wanted = merged(windows.clone());
        // Out of the writer while what it holds is written, so it is not copied for that.
        let ring = std::mem::take(&mut self.ring);
        let mut taken: Vec<(i64, &[u8])> = Vec::new();
        for (start, end) in wanted {
            let mut at = start;
            for &(done_start, done_end) in self.dumped.iter().chain([(end, end)].iter()) {
                if done_end <= at {
                    continue;
                }
                let stop = done_start.min(end);
                taken.extend(
                    ring.range((at - first) as usize..(stop.max(at) - first) as usize).map(|r| (r.1, r.2.as_slice())),
                );
                at = at.max(done_end);
                if at >= end {
                    break;
                }
            }
        }
        self.dumped = merged(self.dumped.iter().copied().chain(windows).collect());
        // A failed writer counts them dropped.
        let written = self.write(topic, &taken);
        self.ring = ring;
        written?;
        if self.failed {
            return Ok(());
        }
        self.count_dumps(faults.len());
        let now = Instant::now();
        match self.last_sync {
            Some(last) if now < last + self.options.sync_interval => {
                self.sync_due.get_or_insert(last + self.options.sync_interval);
            }
            _ => self.sync(now)?,
        }
        Ok(())
    }

    fn count_dumps(&self, faults: usize) {
        if !self.failed {
            lock(&self.shared.counters).black_box_dumps += faults as u64;
        }
    }

    fn sync(&mut self, now: Instant) -> std::io::Result<()> {
        self.flush(true)?;
        self.last_sync = Some(now);
        self.sync_due = None;
        lock(&self.shared.counters).black_box_syncs += 1;
        Ok(())
    }

    /// Writes `records` (time ns, data) of `topic`, in time order, starting a new file where
    /// they reach the split duration.
    fn write(&mut self, topic: usize, records: &[(i64, &[u8])]) -> std::io::Result<()> {
        if records.is_empty() {
            return Ok(());
        }
        if self.failed || self.open.is_none() || topic >= self.topics.len() {
            lock(&self.shared.counters).dropped += records.len() as u64;
            return Ok(());
        }
        let mut start = 0;
        while start < records.len() {
            let mut end = records.len();
            if let Some(duration) = self.options.split_duration_ns {
                let open_index = self.open.as_ref().map_or(0, |o| o.index);
                let first = self.files[open_index].span.map_or(records[start].0, |(a, _)| a);
                end = start + records[start..].partition_point(|r| r.0 < first + duration);
                if end == start {
                    self.split()?;
                    continue;
                }
            }
            let batch = &records[start..end];
            let open = self.open.as_mut().expect("an open file");
            let channel = open.channels[topic];
            for &(time_ns, data) in batch {
                open.file.add_message(channel, time_ns as u64, data).map_err(io_error)?;
                self.pending_bytes += data.len();
            }
            self.files[open.index].add(batch[0].0, batch[batch.len() - 1].0, batch.len() as u64);
            self.topic_messages[topic] += batch.len() as u64;
            lock(&self.shared.counters).written += batch.len() as u64;
            start = end;
            if self.pending_bytes >= self.options.chunk_size {
                self.flush(false)?;
            }
        }
        Ok(())
    }

    fn flush_if_due(&mut self) -> std::io::Result<()> {
        let now = Instant::now();
        if self.sync_due.is_some_and(|due| now >= due) {
            return self.sync(now);
        }
        if self.pending_bytes > 0 && now >= self.last_flush + self.options.flush_interval {
            self.flush(false)?;
        }
        Ok(())
    }

    fn flush(&mut self, sync: bool) -> std::io::Result<()> {
        let Some(open) = self.open.as_mut() else { return Ok(()) };
        open.file.flush().map_err(io_error)?;
        if sync {
            open.file.sync()?;
        }
        self.pending_bytes = 0;
        self.last_flush = Instant::now();
        let size = open.file.size()?;
        self.closed_chunk();
        if self.options.split_size.is_some_and(|limit| size >= limit) {
            self.split()?;
        }
        Ok(())
    }

    /// Parks the open file and opens the next.
    fn split(&mut self) -> std::io::Result<()> {
        self.park()?;
        self.open_file()?;
        self.closed_chunk();
        Ok(())
    }

    /// Closes the open file's chunk and parks it until its metadata record is given.
    fn park(&mut self) -> std::io::Result<()> {
        if let Some(mut open) = self.open.take() {
            open.file.flush().map_err(io_error)?;
            self.pending_bytes = 0;
            self.parked.push(open.file);
            self.closed_chunk();
        }
        Ok(())
    }

    fn finish_parked(&mut self, metadata: &str) -> std::io::Result<()> {
        let entries = BTreeMap::from([
            ("serialized_metadata".to_owned(), metadata.to_owned()),
            ("ROS_DISTRO".to_owned(), ros_distro(metadata)),
        ]);
        for mut file in std::mem::take(&mut self.parked) {
            file.finish("rosbag2", entries.clone()).map_err(io_error)?;
        }
        Ok(())
    }
}

/// The ros_distro line of rosbag2's metadata YAML (the `ROS_DISTRO` entry beside it).
fn ros_distro(metadata: &str) -> String {
    metadata
        .lines()
        .find_map(|line| line.trim().strip_prefix("ros_distro:"))
        .map_or_else(String::new, |v| v.trim().trim_matches(|c| c == '\'' || c == '"').to_owned())
}

fn add_channel(open: &mut Open, topic: &Topic) -> std::io::Result<()> {
    let schema = match open.schemas.get(&topic.type_name) {
        Some(&id) => id,
        None => {
            let id = open.file.add_schema(&topic.type_name, SCHEMA_ENCODING, &topic.definition).map_err(io_error)?;
            open.schemas.insert(topic.type_name.clone(), id);
            id
        }
    };
    let channel = open.file.add_channel(schema, &topic.name, MESSAGE_ENCODING, &topic.metadata).map_err(io_error)?;
    open.channels.push(channel);
    Ok(())
}

/// Runs [first, end), sorted, overlapping and touching ones joined, empty ones left out.
fn merged(mut runs: Vec<(u64, u64)>) -> Vec<(u64, u64)> {
    runs.retain(|r| r.0 < r.1);
    runs.sort_unstable();
    let mut out: Vec<(u64, u64)> = Vec::with_capacity(runs.len());
    for (start, end) in runs {
        match out.last_mut() {
            Some(last) if start <= last.1 => last.1 = last.1.max(end),
            _ => out.push((start, end)),
        }
    }
    out
}

fn io_error(e: mcap::McapError) -> std::io::Error {
    match e {
        mcap::McapError::Io(e) => e,
        other => std::io::Error::other(other),
    }
}

/// An I/O error's text with every cause under it.
fn error_text(error: &std::io::Error) -> String {
    let mut text = error.to_string();
    let mut cause = std::error::Error::source(error);
    while let Some(e) = cause {
        text += &format!(": {e}");
        cause = e.source();
    }
    text
}

#[cfg(test)]
mod tests {
    use super::*;
    use mcap::MessageStream;
    use std::path::Path;

    fn options(dir: &Path) -> Options {
        Options {
            folder: dir.to_owned(),
            name: "bag".into(),
            compression: Some(mcap::Compression::Lz4),
            profile: "ros2".into(),
            library: "test".into(),
            chunk_size: 4000,
            flush_interval: Duration::from_secs(1),
            split_size: None,
            split_duration_ns: None,
            queue_size: 1000,
            decimation: 0,
            samples_per_cycle: 1,
            black_box_ns: Some(100),
            ring_size: 1000,
            sync_interval: Duration::from_secs(60),
        }
    }

    fn topic(name: &str) -> Topic {
        Topic {
            name: name.into(),
            type_name: "std_msgs/msg/UInt8".into(),
            definition: b"uint8 data".to_vec(),
            metadata: BTreeMap::new(),
        }
    }

    /// Waits for a report that `done` accepts.
    fn until(writer: &BagWriter, done: impl Fn(&Report) -> bool) -> Report {
        let mut seen = 0;
        loop {
            let report = writer.report(seen, Duration::from_secs(10));
            if done(&report) {
                return report;
            }
            assert!(report.version > seen, "no report in time: {report:?}");
            seen = report.version;
        }
    }

    fn messages(report: &Report) -> Vec<(String, u64)> {
        let mut out = Vec::new();
        for file in &report.files {
            let bytes = std::fs::read(&file.path).unwrap();
            out.extend(MessageStream::new(&bytes).unwrap().map(|m| {
                let m = m.unwrap();
                (m.channel.topic.clone(), m.log_time)
            }));
        }
        out
    }

    #[test]
    fn faults_together_write_their_windows_once_with_one_sync() {
        let dir = std::env::temp_dir().join(format!("akd_bag_writer_{}", std::process::id()));
        let writer = BagWriter::start(options(&dir)).unwrap();
        writer.add_topic(topic("/cycle"));
        writer.add_topic(topic("/black_box"));
        writer.set_cycle_topics(Some(0), Some(1));
        writer.records((0..1000).map(|i| (i, vec![0, 1, 0, 0, 7])).collect());
        // Out of order, overlapping, and one again: the records of (450, 600] and (800, 900], once each.
        writer.hold(true);
        for fault in [600, 550, 900, 600] {
            writer.fault(fault);
        }
        writer.hold(false);
        writer.close();
        until(&writer, |r| r.closing);
        writer.finish("ros_distro: jazzy\n".into());
        let report = until(&writer, |r| r.done);
        let times: Vec<u64> = messages(&report).into_iter().map(|(_, t)| t).collect();
        assert_eq!(times, (451..=600).chain(801..=900).collect::<Vec<u64>>());
        let counters = writer.counters();
        assert_eq!((counters.black_box_dumps, counters.black_box_syncs, counters.dropped), (4, 1, 0));
        assert!(writer.join(Duration::from_secs(5)));
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn runs_merge_when_they_overlap_or_touch() {
        assert_eq!(merged(vec![(5, 7), (1, 3), (3, 4), (6, 9), (10, 10)]), [(1, 4), (5, 9)]);
    }
}
