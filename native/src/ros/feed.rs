//! The node's periodic publications, made by a thread of their own from the cycle's last
//! snapshot: [`Feed`].
//!
//! A feed has streams, each a message kind and a period. Its thread sleeps to the next stream's
//! deadline (absolute, on the monotonic clock; a late wake-up does not push the next one back),
//! reads the cycle's snapshot, drive states and statistics once for every stream due then,
//! makes each due message, serialised ([`crate::ros::msgs`]), and
//!
//! - hands them to whoever publishes them ([`Feed::take`], which waits without holding
//!   anything the feed's thread needs: Python waits there with the GIL released), at most
//!   [`MAX_WAITING`] at a time, the oldest dropped and counted beyond;
//! - with [`Feed::record`], queues the same bytes in a bag writer, at their stamp;
//! - says when the cycle has pushed new events (each once), so that they are taken when there are
//!   some rather than polled for; an input change among them comes back as one more DriveIO
//!   message, made at once ([`Feed::input_change`]).
//!
//! Stamps are ROS time: the monotonic clock plus the offset the node keeps up to date (the
//! `offset_ns` given to [`Feed::new`]), the same offset that stamps the recorded cycles.
//!
//! # Another publication
//!
//! A message the node publishes at a rate, or when something in the process image changes, is
//! one more [`Kind`]: its serde struct in [`crate::ros::msgs`] (fields as its .msg file), a
//! `Kind` variant with what it needs (a joint), and its making in the thread's `message` from
//! that wake-up's reading (the snapshot's inputs of every joint are decoded once there; a kind
//! published on change keeps what it last sent beside the unwrapped positions and makes a
//! message only when the decoded value differs, checked at each wake-up). Python then adds the stream
//! (`Feed.add_*`), maps its id to the topic's publisher, and publishes the bytes it is handed:
//! a few µs per message and nothing per cycle, whatever the message holds.

use std::collections::VecDeque;
use std::sync::atomic::{AtomicBool, AtomicI64, AtomicU64, Ordering};
use std::sync::{Arc, Condvar, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use super::{Device, Joint};
use crate::cycle::{lock, timing, CycleThread, Snapshot};
use crate::drive::ds402::{Mode, State};
use crate::drive::io::{DriveIo, Switch};
use crate::drive::objects::DriveInputs;
use crate::drive::scaling::PositionUnwrap;
use crate::ethercat::device::ChannelValue;
use crate::ethercat::pdo::Direction;
use crate::ros::bag_writer::BagWriter;
use crate::ros::msgs::{self, Header};

/// Messages waiting to be taken, beyond which the oldest is dropped.
pub const MAX_WAITING: usize = 256;
/// How often the thread looks for the cycle's events when no stream is due sooner.
pub const EVENT_CHECK: Duration = Duration::from_millis(10);

/// What a stream publishes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kind {
    /// sensor_msgs/JointState of every joint, all of one cycle.
    JointStates,
    /// akd_ros/DriveStatus of the joint at this index.
    DriveStatus(usize),
    /// akd_ros/DriveIO of the joint at this index, of the cycle the snapshot holds.
    DriveIo(usize),
    /// akd_ros/DeviceIO of the device at this index, of the cycle the snapshot holds.
    DeviceIo(usize),
}

/// What the feed's thread and its callers share.
struct FeedShared {
    cycle: Arc<CycleThread>,
    joints: Vec<Joint>,
    devices: Vec<Device>,
    offset_ns: Arc<AtomicI64>,
    active: AtomicBool,
    stopped: Mutex<bool>,
    stop: Condvar,
    outbox: Mutex<Outbox>,
    ready: Condvar,
    recording: Mutex<Vec<(usize, Arc<BagWriter>, usize)>>,
    dropped: AtomicU64,
}

impl FeedShared {
    /// The ROS time (ns) of a monotonic time: the stamp of a message made of it.
    fn ros_ns(&self, monotonic_ns: u64) -> i64 {
        monotonic_ns as i64 + self.offset_ns.load(Ordering::Relaxed)
    }

    /// The I/O of `joint`'s drive in `snapshot`, read by its mapping (none where it has none).
    fn drive_io_of(&self, joint: usize, snapshot: &Snapshot) -> DriveIo {
        self.cycle.drive_io(snapshot, self.joints[joint].slave).unwrap_or_default()
    }

    /// `joint`'s akd_ros/DriveIO of `drive` as its cycle showed it, stamped with that cycle's
    /// wake-up on the ROS clock: the digital inputs with the CiA 402 switches, hardware enable,
    /// analog input and outputs as sent, with the joint's names.
    fn drive_io(&self, joint: usize, drive: &DriveIo) -> Vec<u8> {
        let j = &self.joints[joint];
        let inputs = drive.input_levels().unwrap_or_default();
        let outputs = drive.output_levels().unwrap_or_default();
        let (input_names, input_numbers, named_inputs) = named(&inputs, &j.io.input_names, &j.io.input_numbers);
        let (output_names, output_numbers, named_outputs) = named(&outputs, &j.io.output_names, &j.io.output_numbers);
        let switch = |s: Switch| drive.digital_inputs.is_some_and(|w| s.active(w));
        let volts = |counts: Option<i16>| counts.map_or(f64::NAN, |c| c as f64 * j.io.volts_per_count);
        let message = msgs::DriveIo {
            header: Header::at(self.ros_ns(drive.time_ns)),
            joint: &j.name,
            cycle: drive.cycle,
            digital_inputs_mapped: drive.digital_inputs.is_some(),
            digital_inputs: drive.digital_inputs.unwrap_or(0),
            negative_limit: switch(Switch::NegativeLimit),
            positive_limit: switch(Switch::PositiveLimit),
            home_switch: switch(Switch::Home),
            interlock: switch(Switch::Interlock),
            inputs,
            input_names,
            input_numbers,
            named_inputs,
            hardware_enable: drive.hardware_enable() as u8,
            analog_input: volts(drive.analog_input),
            digital_outputs_mapped: drive.digital_outputs.is_some(),
            digital_outputs: drive.digital_outputs.unwrap_or(0),
            outputs,
            output_names,
            output_numbers,
            named_outputs,
            analog_output: volts(drive.analog_output),
        };
        msgs::to_cdr(&message, 256)
    }

    /// `device`'s akd_ros/DeviceIO of `snapshot`, stamped with its cycle; with `levels` (a
    /// change the cycle thread reported, in its cycle `cycle`), its inputs of one bit at those
    /// levels, its first in bit 0.
    fn device_io(&self, device: usize, snapshot: &Snapshot, levels: Option<(u64, u64)>) -> Vec<u8> {
        let (cycle, d) = (&self.cycle, &self.devices[device]);
        let channels = cycle.channels(d.slave).unwrap_or_default();
        let values = cycle.channel_values(snapshot, d.slave).unwrap_or_default();
        let (mut input_names, mut inputs, mut output_names, mut outputs) =
            (Vec::new(), Vec::new(), Vec::new(), Vec::new());
        let mut bit_input = 0;
        for (c, v) in channels.iter().zip(values) {
            let value = match (c.direction, levels) {
                (Direction::Tx, Some((_, levels))) if c.is_bit() && bit_input < 64 => {
                    bit_input += 1;
                    ChannelValue::Bit(levels >> (bit_input - 1) & 1 == 1)
                }
                _ => v,
            };
            let (names, values) = if c.direction == Direction::Tx {
                (&mut input_names, &mut inputs)
            } else {
                (&mut output_names, &mut outputs)
            };
            names.push(c.name.clone());
            values.push(value.as_f64());
        }
        let cycle_number = levels.map_or(snapshot.cycle, |(cycle, _)| cycle);
        let message = msgs::DeviceIo {
            header: Header::at(self.ros_ns(snapshot.time_ns)),
            device: &d.name,
            product: &d.product,
            slave: d.slave,
            cycle: cycle_number,
            fresh: snapshot.fresh || levels.is_some(),
            input_names: &input_names,
            inputs: &inputs,
            output_names: &output_names,
            outputs: &outputs,
        };
        msgs::to_cdr(&message, 128 + 40 * channels.len())
    }

    fn hand_over(&self, made: Vec<(usize, i64, Vec<u8>)>, events: bool) {
        for (stream, writer, topic) in lock(&self.recording).iter() {
            for (_, stamp_ns, data) in made.iter().filter(|m| m.0 == *stream) {
                writer.write(*topic, *stamp_ns, data.clone());
            }
        }
        let made_none = made.is_empty();
        let mut outbox = lock(&self.outbox);
        for (stream, _, data) in made {
            if outbox.messages.len() == MAX_WAITING {
                outbox.messages.pop_front();
                self.dropped.fetch_add(1, Ordering::Relaxed);
            }
            outbox.messages.push_back((stream, data));
        }
        let wake = !made_none || events;
        outbox.events |= events;
        drop(outbox);
        if wake {
            self.ready.notify_all();
        }
    }
}

#[derive(Default)]
struct Outbox {
    messages: VecDeque<(usize, Vec<u8>)>,
    events: bool,
    closed: bool,
}

/// The node's periodic publications (see the module).
pub struct Feed {
    shared: Arc<FeedShared>,
    streams: Mutex<Vec<(Kind, Duration)>>,
    started: AtomicBool,
    thread: Mutex<Option<JoinHandle<()>>>,
}

/// What [`Feed::take`] gives: the messages made since the last call, each (stream, bytes), and
/// whether the cycle pushed events since it last said so.
pub type Taken = (Vec<(usize, Vec<u8>)>, bool);

impl Feed {
    /// A feed of `joints` and `devices` of `cycle`, inactive and without streams; `offset_ns`
    /// is the ROS minus monotonic time it stamps with.
    pub fn new(cycle: Arc<CycleThread>, joints: Vec<Joint>, devices: Vec<Device>, offset_ns: Arc<AtomicI64>) -> Feed {
        Feed {
            shared: Arc::new(FeedShared {
                cycle,
                joints,
                devices,
                offset_ns,
                active: AtomicBool::new(false),
                stopped: Mutex::new(false),
                stop: Condvar::new(),
                outbox: Mutex::default(),
                ready: Condvar::new(),
                recording: Mutex::default(),
                dropped: AtomicU64::new(0),
            }),
            streams: Mutex::default(),
            started: AtomicBool::new(false),
            thread: Mutex::new(None),
        }
    }

    /// The joints.
    pub fn joints(&self) -> &[Joint] {
        &self.shared.joints
    }

    /// Adds a stream of `kind` every `period`; its id, or `None` once [`start`](Feed::start)ed
    /// (the thread has taken the streams).
    pub fn add(&self, kind: Kind, period: Duration) -> Option<usize> {
        if self.started.load(Ordering::Acquire) {
            return None;
        }
        let mut streams = lock(&self.streams);
        streams.push((kind, period));
        Some(streams.len() - 1)
    }

    /// Starts the thread.
    pub fn start(&self) -> std::io::Result<()> {
        let mut thread = lock(&self.thread);
        if !self.started.swap(true, Ordering::AcqRel) {
            let maker = Maker::new(self.shared.clone(), lock(&self.streams).clone());
            *thread = Some(std::thread::Builder::new().name("akd-feed".into()).spawn(move || maker.run())?);
        }
        Ok(())
    }

    /// Makes messages (`true`) or none (`false`, the default).
    pub fn set_active(&self, active: bool) {
        self.shared.active.store(active, Ordering::Release);
    }

    /// Every message of stream `stream` is also queued in `writer` as topic `topic`.
    pub fn record(&self, stream: usize, writer: Arc<BagWriter>, topic: usize) {
        lock(&self.shared.recording).push((stream, writer, topic));
    }

    /// Waits up to `timeout` for messages or events and takes them.
    pub fn take(&self, timeout: Duration) -> Taken {
        let outbox = lock(&self.shared.outbox);
        let (mut outbox, _) = self
            .shared
            .ready
            .wait_timeout_while(outbox, timeout, |o| o.messages.is_empty() && !o.events && !o.closed)
            .unwrap_or_else(|p| p.into_inner());
        let events = std::mem::take(&mut outbox.events);
        (outbox.messages.drain(..).collect(), events)
    }

    /// Hands out (and records) at once the DriveIO of the change of a drive's inputs that the
    /// cycle thread reported (an input change event: `cycle`, its wake-up `time_ns`, and what
    /// it read of 0x60FD and the statusword), on `stream`, which makes its joint's DriveIO at a
    /// rate; the analog input and the outputs are the last snapshot's. An edge is so published
    /// in its own message, stamped with its cycle, not a period later or lost between two.
    /// `false` when `stream` makes no DriveIO, or the feed is inactive.
    pub fn input_change(&self, stream: usize, cycle: u64, time_ns: u64, digital_inputs: u32, statusword: u16) -> bool {
        let kind = lock(&self.streams).get(stream).map(|s| s.0);
        let (Some(Kind::DriveIo(joint)), true) = (kind, self.shared.active.load(Ordering::Acquire)) else {
            return false;
        };
        let shared = &self.shared;
        let now =
            shared.drive_io_of(joint, &shared.cycle.snapshot()).with_inputs(cycle, time_ns, digital_inputs, statusword);
        let stamp_ns = shared.ros_ns(time_ns);
        let message = shared.drive_io(joint, &now);
        shared.hand_over(vec![(stream, stamp_ns, message)], false);
        true
    }

    /// The devices.
    pub fn devices(&self) -> &[Device] {
        &self.shared.devices
    }

    /// Hands out (and records) at once, on `stream`, which makes a device's DeviceIO at a rate,
    /// the DeviceIO of a change of its inputs of one bit that the cycle thread reported (a
    /// device inputs event: `cycle`, its wake-up `time_ns` and the `levels`), stamped with that
    /// cycle; its other channels are the last snapshot's. `false` when `stream` makes no
    /// DeviceIO, or the feed is inactive.
    pub fn device_input_change(&self, stream: usize, cycle: u64, time_ns: u64, levels: u64) -> bool {
        let kind = lock(&self.streams).get(stream).map(|s| s.0);
        let (Some(Kind::DeviceIo(device)), true) = (kind, self.shared.active.load(Ordering::Acquire)) else {
            return false;
        };
        let shared = &self.shared;
        let snapshot = Snapshot { time_ns, ..shared.cycle.snapshot() };
        let message = shared.device_io(device, &snapshot, Some((cycle, levels)));
        shared.hand_over(vec![(stream, shared.ros_ns(time_ns), message)], false);
        true
    }

    /// Messages dropped because nobody took them in time.
    pub fn dropped(&self) -> u64 {
        self.shared.dropped.load(Ordering::Relaxed)
    }

    /// Stops the thread; [`take`](Feed::take) returns at once from then on.
    pub fn stop(&self) {
        *lock(&self.shared.stopped) = true;
        self.shared.stop.notify_all();
        lock(&self.shared.outbox).closed = true;
        self.shared.ready.notify_all();
        if let Some(thread) = lock(&self.thread).take() {
            let _ = thread.join();
        }
    }
}

impl Drop for Feed {
    fn drop(&mut self) {
        self.stop();
    }
}

/// The names and numbers of the named inputs or outputs and their `levels`; none where the
/// mapping does not carry them (`levels` empty).
fn named<'a>(levels: &[bool], names: &'a [String], numbers: &'a [u8]) -> (&'a [String], &'a [u8], Vec<bool>) {
    if levels.is_empty() {
        return (&[], &[], Vec::new());
    }
    // JointIo keeps every number within the drive's inputs or outputs.
    (names, numbers, numbers.iter().map(|&n| levels[n as usize - 1]).collect())
}

/// What one wake-up read of the cycle, once for every stream due.
struct Reading {
    snapshot: Snapshot,
    inputs: Vec<DriveInputs>,
    stamp_ns: i64,
}

/// The thread's side: the streams with their deadlines, and what their messages keep.
struct Maker {
    shared: Arc<FeedShared>,
    streams: Vec<(Kind, Duration, Instant)>,
    /// Each joint's position, unwrapped across the 32-bit wrap.
    unwrapped: Vec<PositionUnwrap>,
    names: Vec<String>,
    /// The cycle's events pushed when it last said there were new ones.
    said: u64,
}

impl Maker {
    fn new(shared: Arc<FeedShared>, streams: Vec<(Kind, Duration)>) -> Maker {
        let now = Instant::now();
        let names = shared.joints.iter().map(|j| j.name.clone()).collect();
        Maker {
            unwrapped: vec![PositionUnwrap::default(); shared.joints.len()],
            streams: streams.into_iter().map(|(kind, period)| (kind, period, now + period)).collect(),
            shared,
            names,
            said: 0,
        }
    }

    fn run(mut self) {
        loop {
            let next = self
                .streams
                .iter()
                .map(|s| s.2)
                .min()
                .map_or(Instant::now() + EVENT_CHECK, |due| due.min(Instant::now() + EVENT_CHECK));
            let stopped = lock(&self.shared.stopped);
            let (stopped, _) = self
                .shared
                .stop
                .wait_timeout_while(stopped, next.saturating_duration_since(Instant::now()), |s| !*s)
                .unwrap_or_else(|p| p.into_inner());
            if *stopped {
                return;
            }
            drop(stopped);
            let now = Instant::now();
            let due: Vec<Kind> = self.streams.iter().filter(|s| s.2 <= now).map(|s| s.0).collect();
            for (_, period, deadline) in self.streams.iter_mut().filter(|s| s.2 <= now) {
                // Absolute deadlines; a very late wake-up skips what it missed.
                *deadline = (*deadline + *period).max(now);
            }
            if !self.shared.active.load(Ordering::Acquire) {
                continue;
            }
            // Each event is said once, whoever takes it: a later look finds it said.
            let pushed = self.shared.cycle.events_pushed();
            let events = pushed > self.said;
            self.said = pushed;
            let made = if due.is_empty() { Vec::new() } else { self.make(&due) };
            if !made.is_empty() || events {
                self.shared.hand_over(made, events);
            }
        }
    }

    /// The messages of the streams due, each (stream, stamp, bytes).
    fn make(&mut self, due: &[Kind]) -> Vec<(usize, i64, Vec<u8>)> {
        let reading = self.read();
        let kinds: Vec<Kind> = self.streams.iter().map(|s| s.0).collect();
        let due = kinds.into_iter().enumerate().filter(|(_, kind)| due.contains(kind));
        due.map(|(stream, kind)| (stream, reading.stamp_ns, self.message(kind, &reading))).collect()
    }

    fn read(&mut self) -> Reading {
        let cycle = &self.shared.cycle;
        let snapshot = cycle.snapshot();
        let inputs =
            self.shared.joints.iter().map(|j| cycle.drive_inputs(&snapshot, j.slave).unwrap_or_default()).collect();
        let stamp_ns = self.shared.ros_ns(timing::now_ns());
        Reading { snapshot, inputs, stamp_ns }
    }

    fn message(&mut self, kind: Kind, reading: &Reading) -> Vec<u8> {
        match kind {
            Kind::JointStates => self.joint_states(reading),
            Kind::DriveStatus(joint) => self.drive_status(joint, reading),
            Kind::DriveIo(joint) => self.shared.drive_io(joint, &self.shared.drive_io_of(joint, &reading.snapshot)),
            Kind::DeviceIo(device) => self.shared.device_io(device, &reading.snapshot, None),
        }
    }

    /// Every joint's position (unwrapped), velocity and effort in SI; velocity or effort left
    /// empty unless every joint's drive maps it (as JointState leaves what is not all known).
    fn joint_states(&mut self, reading: &Reading) -> Vec<u8> {
        let joints = &self.shared.joints;
        let mut position = Vec::with_capacity(joints.len());
        for (k, (joint, inputs)) in joints.iter().zip(&reading.inputs).enumerate() {
            let counts = self.unwrapped[k].next(inputs.position_actual.unwrap_or(0));
            position.push(joint.scale.position_to_si(counts as f64));
        }
        let every = |si: &dyn Fn(&Joint, &DriveInputs) -> Option<f64>| -> Vec<f64> {
            joints.iter().zip(&reading.inputs).map(|(j, i)| si(j, i)).collect::<Option<_>>().unwrap_or_default()
        };
        let velocity = every(&|j, i| Some(j.scale.velocity_to_si(i.velocity_actual?.into())));
        let effort = every(&|j, i| Some(j.scale.torque_to_si(i.torque_actual?.into())));
        let message = msgs::JointState {
            header: Header::at(reading.stamp_ns),
            name: &self.names,
            position: &position,
            velocity: &velocity,
            effort: &effort,
        };
        msgs::to_cdr(&message, 64 + joints.len() * 48)
    }

    /// The drive's state, mode and following error, and the cycle's counters and timing.
    fn drive_status(&self, joint: usize, reading: &Reading) -> Vec<u8> {
        let cycle = &self.shared.cycle;
        let j = &self.shared.joints[joint];
        let inputs = &reading.inputs[joint];
        let status = cycle.drive_status(j.slave).ok();
        let shown = inputs.mode_display.and_then(Mode::from_i8);
        let mode = shown.or_else(|| cycle.mode_set(j.slave).and_then(Mode::from_i8)).map(Mode::snake_name);
        let stats = cycle.stats();
        let (period, exchange) = (stats.period.summary(), stats.exchange.summary());
        let message = msgs::DriveStatus {
            header: Header::at(reading.stamp_ns),
            joint: &j.name,
            ds402_state: &State::message_name(status.and_then(|s| s.state())),
            statusword: status.map_or(0, |s| s.statusword),
            mode: mode.as_deref().unwrap_or(""),
            mode_of_operation: shown.map_or(0, |m| m as i8),
            following_error: inputs.following_error.map_or(f64::NAN, |e| j.scale.velocity_to_si(e.into())),
            homed: !j.homes || cycle.homing_status(j.slave).is_ok_and(|s| s.homed),
            cycles: stats.cycles.load(Ordering::Relaxed),
            overruns: stats.overruns.load(Ordering::Relaxed),
            lost_frames: stats.lost_frames.load(Ordering::Relaxed),
            wkc_errors: stats.wkc_errors.load(Ordering::Relaxed),
            period_mean: period.mean_ns as f64 * 1e-9,
            period_max: period.max_ns as f64 * 1e-9,
            exchange_p99: exchange.p99_ns as f64 * 1e-9,
        };
        msgs::to_cdr(&message, 160)
    }
}
