//! The cycle thread's handle, [`CycleThread`]: what the other threads (Python's among them)
//! call to start the thread, give it set-points and requests, read what it publishes, and stop
//! it. It never touches the master while the thread runs; it works on [`CycleShared`].

use std::borrow::Cow;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{mpsc, Arc};
use std::thread::JoinHandle;
use std::time::Duration;

use super::acyclic::{MailboxService, SdoSlot};
use super::devices::{DeviceLoop, DeviceShared};
use super::events::{CommandTimeoutAction, Event, Events, Refusal, RefusalReason};
use super::run::{homing_objects, run, DriveLoop, Loop};
use super::samples::{Sample, Samples};
use super::seqlock::SeqBytes;
use super::stats::CycleStats;
use super::supervision::Gaps;
use super::{
    command_timeout, dc_status, eoe_frames, handshake, homing, latch, line_health, lock, recovery, rt, sequencer,
    timing, trajectory_player, CycleShared, RealTime, HEADER_LEN,
};
use crate::drive::io::DriveIo;
use crate::drive::objects::DriveInputs;
use crate::drive::trajectory::{JointLimits, Knot, Limit, Limits, Scale, Setpoint, Trajectory};
use crate::error::{Error, Result, SettingError, TrajectoryError, Unavailable};
use crate::ethercat::device::{self, Channel, ChannelValue};
use crate::ethercat::master::cyclic::ImageSlot;
use crate::ethercat::master::Master;
use crate::ethercat::pdo::{Direction, PdoEntry};

/// What a stopped cycle means for a set-point.
const SETPOINTS_STOPPED: &str = "set-points no longer go out";

/// How a cycle thread runs.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Config {
    /// The period, [`timing::MIN_PERIOD`]..=[`timing::MAX_PERIOD`].
    pub period: Duration,
    /// How the thread runs on the host.
    pub realtime: RealTime,
    /// FBUS.PARAM02 as the clock set-up left it in each slave, by position, as
    /// [`AkdLine`](crate::drive::akd::AkdLine) gives it; [`CycleThread::dc_status`] shows it (a
    /// slave not in it as `None`, unknown).
    pub fbus_param02: Vec<Option<u32>>,
    /// How often every slave's links and error counters are read beside the cycle
    /// ([`super::line_health`]); `None`: never.
    pub line_health: Option<Duration>,
}

impl Config {
    /// A cycle of `period` with no real-time settings, reading the line's health four times a
    /// second.
    pub fn new(period: Duration) -> Self {
        Config {
            period,
            realtime: RealTime::default(),
            fbus_param02: Vec::new(),
            line_health: Some(super::line_health::DEFAULT_INTERVAL),
        }
    }
}

/// What the cycle thread published after one cycle.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Snapshot {
    /// Cycles done when it was taken (the first cycle is 1; 0 before any).
    pub cycle: u64,
    /// When the cycle woke up, on the monotonic clock (ns).
    pub time_ns: u64,
    /// The cyclic LRW's working counter (0 when the frame was lost).
    pub wkc: u16,
    /// Whether this cycle's exchange succeeded; if not, the inputs are the last good ones.
    pub fresh: bool,
    /// The whole input image; [`CycleThread::inputs_of`] cuts out one slave's.
    pub inputs: Vec<u8>,
    /// The whole output image as this cycle sent it: the set-points with what the DS402
    /// sequencer wrote over them; [`CycleThread::outputs_of`] cuts out one slave's.
    pub outputs: Vec<u8>,
}

/// How long a drive request may take by default before it is reported stuck.
const DEFAULT_REQUEST_TIMEOUT: Duration = Duration::from_secs(1);

/// The drives of `master` that can be sequenced, with their objects' offsets in the whole
/// images and their latch where mapped; for the others, why not.
fn sequenced_drives(
    master: &Master,
) -> Vec<std::result::Result<(sequencer::Offsets, Option<latch::LatchObjects>), Unavailable>> {
    master
        .slaves()
        .iter()
        .map(|slave| {
            let position = slave.position;
            let process_data = slave.process_data.as_ref().ok_or(Unavailable::NoMapping { slave: position })?;
            // A mapped slave has its slot once the image exists, which the cycle's start needs.
            let slot = master
                .image_slot(position)
                .map_err(|_| Unavailable::NoProcessData { slave: position, with_data: None })?;
            let rx: Vec<_> = process_data.outputs.entries().collect();
            let tx: Vec<_> = process_data.inputs.entries().collect();
            let offsets = sequencer::Offsets::find(&rx, &tx).map_err(|e| match e {
                Unavailable::NotSequenced { missing, .. } => {
                    Unavailable::NotSequenced { slave: Some(position), missing }
                }
                other => other,
            })?;
            let latch = latch::LatchObjects::find(&rx, &tx, slot.out_offset, slot.in_offset);
            Ok((offsets.shifted(slot.out_offset, slot.in_offset), latch))
        })
        .collect()
}

/// Where object `index:subindex` sits in the whole input image, where slave `position` maps it.
fn input_offset(master: &Master, position: u16, (index, subindex): (u16, u8)) -> Option<usize> {
    let inputs: Vec<_> = master.slaves().get(position as usize)?.process_data.as_ref()?.inputs.entries().collect();
    let (at, _) = crate::ethercat::pdo::find(&inputs, index, subindex)?;
    Some(master.image_slot(position).ok()?.in_offset + at)
}

/// A cycle thread: it runs from [`start`](CycleThread::start) to [`stop`](CycleThread::stop).
pub struct CycleThread {
    shared: Arc<CycleShared>,
    /// Taken by [`stop`](CycleThread::stop), which may come from another thread than callers
    /// waiting on the cycle (they see it stopped and end); the cycle thread never locks these.
    thread: std::sync::Mutex<Option<JoinHandle<Option<Master>>>>,
    recovery: std::sync::Mutex<Option<JoinHandle<()>>>,
    halted: AtomicBool,
    slots: Vec<Option<ImageSlot>>,
    warnings: Vec<String>,
    /// Open while the thread runs: the CPUs' wake-up latency it holds (PM QoS).
    cpu_latency: std::sync::Mutex<Option<std::fs::File>>,
    period: Duration,
    /// Per slave: whether it is sequenced, or why not.
    sequenced: Vec<std::result::Result<(), Unavailable>>,
    /// Per slave: the latch objects, where mapped.
    latch_objects: Vec<Option<latch::LatchObjects>>,
    /// Per slave: the drive's objects, where sequenced.
    offsets: Vec<Option<sequencer::Offsets>>,
    /// Per slave: the mapping's entries, outputs and inputs, where mapped.
    mappings: Vec<Option<(Vec<PdoEntry>, Vec<PdoEntry>)>>,
    /// Per slave: its channels, named as its SII names its PDO entries (none without process
    /// data).
    channels: Vec<Vec<Channel>>,
    trajectories: trajectory_player::Caller,
    /// Each slave's product as its SII names it.
    products: Vec<String>,
    /// Per slave: the joint's limits, handed down once; every motion of the drive is judged by
    /// them (an INT32 target's range, at any speed, where none were).
    joint_limits: std::sync::RwLock<Vec<Option<JointLimits>>>,
}

impl CycleThread {
    /// Starts cycling `master` (its bus in Op, its process image laid out). The output image
    /// starts as the master holds it, so nothing changes at the start. A bad period, priority
    /// or CPU, or a master without a process image, is refused and the master handed back
    /// with the error. Real-time settings that are not permitted become [`warnings`](Self::warnings).
    pub fn start(mut master: Master, config: Config) -> std::result::Result<CycleThread, Box<(Error, Master)>> {
        let checked = timing::period_ns(config.period).and_then(|period_ns| {
            rt::check(config.realtime.priority, config.realtime.cpu)?;
            if master.cyclic_frame_in_flight() {
                return Err(Unavailable::CyclicFrameInFlight.into());
            }
            let outputs = master.output_image()?.to_vec();
            let inputs_len = master.input_image()?.len();
            Ok((period_ns, outputs, inputs_len))
        });
        let (period_ns, outputs, inputs_len) = match checked {
            Ok(c) => c,
            Err(e) => return Err(Box::new((e, master))),
        };
        let count = master.slaves().len();
        let slots = (0..count as u16).map(|p| master.image_slot(p).ok()).collect();
        let found = sequenced_drives(&master);
        let sequenced_count = found.iter().filter(|f| f.is_ok()).count();
        let sequenced = found.iter().map(|f| f.as_ref().map(|_| ()).map_err(Clone::clone)).collect();
        let latch_objects = found.iter().map(|f| f.as_ref().ok().and_then(|f| f.1)).collect();
        let offsets = found.iter().map(|f| f.as_ref().ok().map(|f| f.0)).collect();
        let channels: Vec<Vec<Channel>> = master
            .slaves()
            .iter()
            .map(|s| s.process_data.as_ref().map_or_else(Vec::new, |d| device::channels(&s.sii, d)))
            .collect();
        // Every slave the cycle does not sequence is a device beside the drives.
        let mut devices: Vec<DeviceLoop> = found
            .iter()
            .enumerate()
            .filter(|(_, f)| f.is_err())
            .map(|(p, _)| DeviceLoop::new(p as u16, master.image_slot(p as u16).ok(), &channels[p]))
            .collect();
        let mut drives: Vec<DriveLoop> = found
            .into_iter()
            .enumerate()
            .filter_map(|(p, f)| {
                let (offsets, latch) = f.ok()?;
                let digital_inputs = input_offset(&master, p as u16, crate::drive::io::DIGITAL_INPUTS);
                Some(DriveLoop {
                    position: p as u16,
                    drive: sequencer::SequencedDrive::new(offsets),
                    latch: latch.map(latch::Latch::new),
                    inputs: crate::drive::io::InputWatch::new(digital_inputs, offsets.statusword),
                    ..DriveLoop::default()
                })
            })
            .collect();
        // AL status and mailbox status ride in the cyclic frame; without room for them the
        // cycle runs on, unsupervised, and says so.
        let mut start_warnings = Vec::new();
        let supervised = master.set_supervision(true);
        if let Err(e) = &supervised {
            start_warnings.push(format!(
                "AL state and mailbox supervision is off: {e}; a lost drive is seen by its frames only, and not \
                 brought back"
            ));
        }
        let mut mailbox = MailboxService::new(&master);
        // The ports each slave's ESC has, for the line's health; without them it is not read.
        let (ports, line_health_interval) = match master.port_descriptors() {
            Ok(ports) => (ports, config.line_health.filter(|i| !i.is_zero())),
            Err(e) => {
                start_warnings.push(format!("the line's links and error counters are not read: {e}"));
                (Vec::new(), None)
            }
        };
        let products =
            master.slaves().iter().map(|s| s.sii.order().or(s.sii.name()).unwrap_or("unnamed").to_owned()).collect();
        let mappings = master
            .slaves()
            .iter()
            .map(|s| s.process_data.as_ref().map(|d| (d.outputs.entries().collect(), d.inputs.entries().collect())))
            .collect();
        let shared = Arc::new(CycleShared {
            stop: AtomicBool::new(false),
            setpoints: SeqBytes::new(outputs.len(), &outputs),
            snapshot: SeqBytes::new(HEADER_LEN + inputs_len + outputs.len(), &[]),
            stats: CycleStats::new(period_ns),
            drives: (0..count).map(|_| sequencer::SequencerShared::default()).collect(),
            request_timeout_ns: AtomicU64::new(DEFAULT_REQUEST_TIMEOUT.as_nanos() as u64),
            latches: (0..count).map(|_| latch::LatchShared::default()).collect(),
            handshakes: (0..count).map(|_| handshake::HandshakeShared::default()).collect(),
            command_timeouts: (0..count).map(|_| command_timeout::CommandTimeoutShared::default()).collect(),
            homings: (0..count).map(|_| homing::HomingShared::default()).collect(),
            events: Events::default(),
            samples: Samples::for_drives(sequenced_count),
            sdo: SdoSlot::default(),
            eoe: eoe_frames::EoeFrames::default(),
            quick_stop_on_fault: AtomicBool::new(false),
            dc: dc_status::DcStatusShared::new(master.clock(), &config.fbus_param02),
            trajectories: trajectory_player::PlayerShared::new(count),
            relay: Arc::default(),
            recovery: (0..count).map(|_| recovery::SlaveRecovery::default()).collect(),
            devices: (0..count).map(|_| DeviceShared::default()).collect(),
            supervised: supervised.is_ok(),
            line_health: line_health::LineHealthShared::new(ports, line_health_interval),
        });
        let recoverer = recoverer(&mut master, &shared, &drives, &devices, config.period);
        // The master goes to the thread once it exists, so a failed spawn can hand it back.
        let (master_tx, master_rx) = mpsc::sync_channel::<Master>(1);
        let (ready_tx, ready_rx) = mpsc::sync_channel(1);
        let spawned = {
            let shared = shared.clone();
            let mut player = trajectory_player::Player::new(count);
            let mut relay_buffers = recovery::RelayBuffers::default();
            let mut line_reader = line_health::LineHealthReader::new(count, &shared.line_health);
            std::thread::Builder::new().name("akd-cycle".into()).spawn(move || {
                let mut master = master_rx.recv().ok()?;
                let mut warnings = start_warnings;
                warnings.extend(config.realtime.priority.and_then(rt::set_fifo_priority));
                warnings.extend(config.realtime.cpu.and_then(rt::set_affinity));
                if config.realtime.lock_memory {
                    warnings.extend(rt::lock_memory());
                }
                // The starting thread waits for this message; it cannot be gone.
                let _ = ready_tx.send(warnings);
                let timeout = master.replace_timeout(config.period);
                let mut ready = Loop {
                    master: &mut master,
                    shared: &shared,
                    drives: &mut drives,
                    devices: &mut devices,
                    gaps: Gaps::default(),
                };
                run(
                    &mut ready,
                    (&mut mailbox, &mut relay_buffers, &mut line_reader),
                    &mut player,
                    (period_ns, config.realtime.pipelined),
                );
                shared.relay.end();
                master.replace_timeout(timeout);
                // The master goes on without the thread: plain exchanges, no status reads.
                let _ = master.set_supervision(false);
                Some(master)
            })
        };
        let thread = match spawned {
            Ok(t) => t,
            Err(source) => {
                return Err(Box::new((Error::Io { context: "starting the cycle thread".into(), source }, master)))
            }
        };
        // The thread is waiting for it.
        let _ = master_tx.send(master);
        let mut warnings = ready_rx.recv().unwrap_or_default();
        let cpu_latency =
            config.realtime.cpu_latency_us.and_then(|us| rt::hold_cpu_latency(us).map_err(|w| warnings.push(w)).ok());
        let recovery = {
            let shared = shared.clone();
            std::thread::Builder::new()
                .name("akd-recovery".into())
                .spawn(move || recoverer.run(&shared.recovery, &shared.stop))
                .ok()
        };
        let joint_limits = std::sync::RwLock::new(vec![None; count]);
        Ok(CycleThread {
            shared,
            thread: std::sync::Mutex::new(Some(thread)),
            recovery: std::sync::Mutex::new(recovery),
            halted: AtomicBool::new(false),
            slots,
            warnings,
            cpu_latency: std::sync::Mutex::new(cpu_latency),
            period: config.period,
            sequenced,
            latch_objects,
            offsets,
            joint_limits,
            mappings,
            channels,
            trajectories: trajectory_player::Caller::default(),
            products,
        })
    }

    /// The real-time settings that were asked for and not permitted, one sentence each.
    pub fn warnings(&self) -> &[String] {
        &self.warnings
    }

    /// Slaves on the bus, with process data or not.
    pub fn slave_count(&self) -> u16 {
        self.slots.len() as u16
    }

    /// The period.
    pub fn period(&self) -> Duration {
        self.period
    }

    fn slot(&self, position: u16) -> Result<ImageSlot> {
        self.slots.get(position as usize).copied().flatten().ok_or_else(|| {
            Error::from(Unavailable::NoProcessData {
                slave: position,
                with_data: Some((0..self.slots.len() as u16).filter(|&p| self.slots[p as usize].is_some()).collect()),
            })
        })
    }

    /// Sets the outputs of the slave at `position` from the next cycle on; `data` must have
    /// their exact length. Lock-free: the cycle thread never waits for it.
    pub fn set_outputs(&self, position: u16, data: &[u8]) -> Result<()> {
        self.check_running(SETPOINTS_STOPPED)?;
        let slot = self.slot(position)?;
        slot.check_outputs_len(position, data.len())?;
        self.shared.setpoints.write().write_bits(slot.out_start_bit(), data, slot.out_bits);
        self.shared.drives[position as usize].setpoint_written();
        self.shared.command_timeouts[position as usize].target_written();
        Ok(())
    }

    fn sequenced(&self, position: u16) -> Result<&sequencer::SequencerShared> {
        match self.sequenced.get(position as usize) {
            None => Err(Error::NoSuchSlave { position, count: self.slave_count() }),
            Some(Err(why)) => Err(why.clone().into()),
            Some(Ok(())) => Ok(&self.shared.drives[position as usize]),
        }
    }

    /// Asks the drive at `position` for `request`, taken in the next cycle (replacing one
    /// under way). Lock-free. Refused for a drive whose mapping cannot be sequenced and once
    /// the cycle is stopped.
    pub fn request(&self, position: u16, request: sequencer::Request) -> Result<()> {
        let drive = self.sequenced(position)?;
        if self.stopped() {
            let consequence = format!("{} can no longer be sequenced", request.name()).into();
            return Err(Unavailable::CycleStopped { consequence }.into());
        }
        drive.request(request);
        self.shared.command_timeouts[position as usize].release();
        Ok(())
    }

    /// Asks the drive at `position` for a fault reset if it shows a fault (Fault, or Fault
    /// reaction active: the edge then comes once it is in Fault); gives whether it did. A drive
    /// without a fault is left as it is: a reset never takes power from a drive that runs.
    pub fn reset_fault(&self, position: u16) -> Result<bool> {
        use crate::drive::ds402::State;
        let state = self.sequenced(position)?.status().state();
        if !matches!(state, Some(State::Fault | State::FaultReactionActive)) {
            return Ok(false);
        }
        self.request(position, sequencer::Request::FaultReset)?;
        Ok(true)
    }

    /// Arms (`arm`) or disarms the latch edges in `edges` (bits as [`latch::edge_bit`]) of the
    /// drive at `position`; refused for a drive whose mapping carries no latch or no position
    /// for one of the edges.
    pub fn arm_latch(&self, position: u16, edges: u8, arm: bool) -> Result<()> {
        self.sequenced(position)?;
        let objects = self.latch_objects[position as usize]
            .ok_or_else(|| Error::from(Unavailable::NoLatch { slave: position }))?;
        let missing = edges & !objects.readable();
        if arm && missing != 0 {
            return Err(
                Unavailable::LatchEdgesUnreadable { slave: position, missing, readable: objects.readable() }.into()
            );
        }
        self.shared.latches[position as usize].set(edges, arm);
        Ok(())
    }

    /// Every slave's links and error counters as the reads beside the cycle found them so far
    /// ([`super::line_health`]).
    pub fn line_health(&self) -> crate::ethercat::line_health::LineReading {
        self.shared.line_health.reading()
    }

    /// Each slave's product as its SII names it (its order number, else its name), by position.
    pub fn products(&self) -> &[String] {
        &self.products
    }

    /// Latch and fault events since the last call, oldest first.
    pub fn events(&self) -> Vec<Event> {
        self.shared.events.drain()
    }

    /// Whether an event waits to be taken (lock-free: a publisher's thread asks it often).
    pub fn events_pending(&self) -> bool {
        self.shared.events.pending()
    }

    /// Events pushed since the cycle started (lock-free): a new one since a look made it grow.
    pub fn events_pushed(&self) -> u64 {
        self.shared.events.pushed()
    }

    /// Events lost because nobody took them and the ring filled up.
    pub fn events_dropped(&self) -> u64 {
        self.shared.events.dropped()
    }

    /// One record per cycle and sequenced drive since the last call, oldest first.
    pub fn samples(&self) -> Vec<Sample> {
        self.shared.samples.drain()
    }

    /// Records lost because nobody took them and the ring filled up.
    pub fn samples_dropped(&self) -> u64 {
        self.shared.samples.dropped()
    }

    /// Reads `index:subindex` of the slave at `position` through the cycle thread, beside the
    /// process data. Waits (the caller, not the cycle) for the answer.
    pub fn sdo_read(&self, position: u16, index: u16, subindex: u8) -> Result<Vec<u8>> {
        self.check_slave(position)?;
        self.shared.sdo.transfer(position, index, subindex, None, || self.running())
    }

    /// The drive's error code (0x603F): the CiA 402 code of its last fault, read beside the cycle.
    pub fn drive_error_code(&self, position: u16) -> Result<u16> {
        let (index, subindex) = crate::drive::ds402::ERROR_CODE;
        Ok(crate::drive::ds402::error_code(&self.sdo_read(position, index, subindex)?)?)
    }

    /// Writes `data` to `index:subindex` of the slave at `position` through the cycle thread.
    pub fn sdo_write(&self, position: u16, index: u16, subindex: u8, data: &[u8]) -> Result<()> {
        self.check_slave(position)?;
        self.shared.sdo.transfer(position, index, subindex, Some(data), || self.running()).map(|_| ())
    }

    /// Queues one Ethernet frame for the IP stack of the drive at `position`, carried in EoE
    /// fragments in the cycles no SDO transfer needs; `false` when the queue was full and the
    /// frame was dropped (counted in [`eoe_dropped`](Self::eoe_dropped)).
    pub fn eoe_send(&self, position: u16, frame: &[u8]) -> Result<bool> {
        self.check_slave(position)?;
        let (len, max) = (frame.len(), crate::ethercat::eoe::MAX_FRAME_LEN);
        if len > max {
            return Err(crate::error::EoeError::FrameTooLong { len, max }.into());
        }
        Ok(self.shared.eoe.send(position, frame))
    }

    /// The next Ethernet frame a drive's IP stack sent, waiting up to `timeout`: the drive's
    /// position and the frame.
    pub fn eoe_receive(&self, timeout: Duration) -> Option<(u16, Vec<u8>)> {
        self.shared.eoe.receive(timeout)
    }

    /// Ethernet frames dropped because a queue was full: (to the drives, from the drives).
    pub fn eoe_dropped(&self) -> (u64, u64) {
        self.shared.eoe.dropped()
    }

    /// Refuses once the cycle is stopped, saying what that means for the call.
    fn check_running(&self, consequence: &'static str) -> Result<()> {
        match self.stopped() {
            true => Err(Unavailable::CycleStopped { consequence: consequence.into() }.into()),
            false => Ok(()),
        }
    }

    fn check_slave(&self, position: u16) -> Result<()> {
        self.check_running("use the master's own SDO access")?;
        self.check_position(position)?;
        if recovery::busy(&self.shared.recovery[position as usize]) {
            return Err(Unavailable::Recovering { slave: position }.into());
        }
        Ok(())
    }

    /// Sets the mode of operation of the drive at `position` — through 0x6060 in the outputs
    /// where mapped, else by SDO — and holds its target at the actual position until the next
    /// set-point, so the new mode starts where the axis is.
    pub fn set_mode(&self, position: u16, mode: i8) -> Result<()> {
        let drive = self.sequenced(position)?;
        self.check_not_driven(position, "a mode change")?;
        match self.offsets[position as usize].and_then(|o| o.mode) {
            Some(at) => self.shared.setpoints.write().write(at, &[mode as u8]),
            None => self.sdo_write(position, 0x6060, 0, &[mode as u8])?,
        }
        self.shared.recovery[position as usize].set_mode(mode);
        drive.hold();
        self.shared.command_timeouts[position as usize].release();
        Ok(())
    }

    /// The mode of operation last set on the drive at `position` ([`set_mode`](Self::set_mode),
    /// or its display when the cycle started), `None` before either.
    pub fn mode_set(&self, position: u16) -> Option<i8> {
        self.shared.recovery.get(position as usize).and_then(recovery::SlaveRecovery::mode)
    }

    /// Sets or clears halt (controlword bit 8) on the drive at `position`.
    pub fn set_halt(&self, position: u16, halt: bool) -> Result<()> {
        self.sequenced(position)?.set_halt(halt);
        Ok(())
    }

    /// Asks the drive at `position` for the set-point handshake (see [`handshake`]): `bits`
    /// (within [`handshake::ALLOWED_BITS`], with bit 4: 0x0030 for a profile-position
    /// set-point changed at once, 0x0010 to start homing) raised from statusword bit 12 clear
    /// until bit 12 is set, then lowered; stuck when bit 12 does not clear within the request
    /// time-out, or is not set within `timeout` of the raise (the request time-out when `None`;
    /// homing may take long). Replaces one under way; returns its number. Lock-free.
    pub fn start_setpoint(&self, position: u16, bits: u16, timeout: Option<Duration>) -> Result<u32> {
        self.sequenced(position)?;
        self.check_running("no set-point handshake can run")?;
        if bits & !handshake::ALLOWED_BITS != 0 || bits & crate::drive::ds402::controlword::NEW_SETPOINT == 0 {
            return Err(SettingError::HandshakeBits { bits }.into());
        }
        let clear_timeout = self.request_timeout();
        Ok(self.shared.handshakes[position as usize].start(bits, clear_timeout, timeout.unwrap_or(clear_timeout)))
    }

    /// The set-point handshake last asked for at `position`, as the cycle thread last published
    /// it. Lock-free.
    pub fn setpoint_status(&self, position: u16) -> Result<handshake::HandshakeStatus> {
        self.sequenced(position)?;
        Ok(self.shared.handshakes[position as usize].status())
    }

    /// Waits (the caller, polling every millisecond) until the set-point handshake last asked
    /// for at `position` is done, and returns its status; a [`Error::Timeout`] saying why when
    /// it is stuck, when `timeout` passes first (the handshake goes on in the cycle until its
    /// own time-out) or when the cycle stops.
    pub fn wait_setpoint(&self, position: u16, timeout: Option<Duration>) -> Result<handshake::HandshakeStatus> {
        let deadline = timeout.map(|t| std::time::Instant::now() + t);
        loop {
            let status = self.setpoint_status(position)?;
            let what = match status.progress {
                handshake::Progress::Done => return Ok(status),
                handshake::Progress::Idle => return Err(Unavailable::NoHandshake { position }.into()),
                handshake::Progress::Stuck(_) => status.stuck_reason(),
                handshake::Progress::InProgress if !self.running() => {
                    Some(status.describe("cut short: the cycle stopped"))
                }
                handshake::Progress::InProgress if deadline.is_some_and(|d| std::time::Instant::now() >= d) => {
                    Some(status.describe("still in progress"))
                }
                handshake::Progress::InProgress => None,
            };
            if let Some(what) = what {
                return Err(Error::Timeout { what: format!("drive {position}: {what}").into() });
            }
            std::thread::sleep(Duration::from_millis(1));
        }
    }

    /// Starts homing the drive at `position` in the cycle thread (see [`homing`]): with the
    /// method and speeds set in the drive, ended timed out (and halted) when not attained within
    /// `timeout`, then back to the mode the set-points carry without a step. The drive must be
    /// sequenced, in Operation enabled, with 0x6060 in its outputs and 0x6061 in its inputs.
    /// Replaces one under way; returns its number. Lock-free.
    pub fn start_homing(&self, position: u16, timeout: Duration) -> Result<u32> {
        let status = self.sequenced(position)?.status();
        self.check_running("no homing can run")?;
        let o = self.offsets[position as usize].unwrap_or_default();
        if homing_objects(&o).is_none() {
            return Err(Unavailable::HomingUnmapped { slave: position }.into());
        }
        if status.state() != Some(crate::drive::ds402::State::OperationEnabled) {
            let state = status.state().map_or("no valid state", crate::drive::ds402::State::name);
            return Err(Unavailable::HomingNotEnabled { slave: position, state }.into());
        }
        self.check_not_driven(position, "a homing")?;
        self.shared.command_timeouts[position as usize].release();
        Ok(self.shared.homings[position as usize].start(timeout.as_nanos().min(u64::MAX as u128) as u64))
    }

    /// Cancels the homing under way on the drive at `position`: halted, then back to the mode
    /// the set-points carry. Lock-free.
    pub fn cancel_homing(&self, position: u16) -> Result<()> {
        self.sequenced(position)?;
        self.shared.homings[position as usize].cancel();
        Ok(())
    }

    /// The homing of the drive at `position` as the cycle thread last published it, with its
    /// homed flag. Lock-free.
    pub fn homing_status(&self, position: u16) -> Result<homing::HomingStatus> {
        self.sequenced(position)?;
        Ok(self.shared.homings[position as usize].status())
    }

    /// Sets the command time-out of the drive at `position` (see [`command_timeout`]): when a
    /// non-zero velocity (profile velocity) or torque (profile torque) stream stops for
    /// `timeout` while the drive is in Operation enabled, `action` is taken and an
    /// [`Event::CommandTimeout`] pushed; `None` turns it off, which is always allowed. A time-out
    /// is refused for a mapping without target velocity 0x60FF or target torque 0x6071, or
    /// without the mode (0x6060 or 0x6061): the thread could not see the stream it watches.
    pub fn set_command_timeout(
        &self,
        position: u16,
        timeout: Option<Duration>,
        action: CommandTimeoutAction,
    ) -> Result<()> {
        self.sequenced(position)?;
        let o = self.offsets[position as usize].unwrap_or_default();
        let missing = [
            (o.velocity_target.is_none() && o.torque_target.is_none())
                .then_some("target velocity 0x60FF or target torque 0x6071 in the outputs"),
            (o.mode.is_none() && o.mode_display.is_none())
                .then_some("modes of operation 0x6060 in the outputs or its display 0x6061 in the inputs"),
        ];
        if let Some(what) = missing.into_iter().flatten().next().filter(|_| timeout.is_some_and(|t| !t.is_zero())) {
            return Err(Unavailable::CommandTimeoutUnwatched { slave: position, missing: what }.into());
        }
        self.shared.command_timeouts[position as usize].set(timeout.map(|t| (t, action)));
        Ok(())
    }

    /// The command time-out of the drive at `position` as the cycle thread last published it.
    pub fn command_timeout_status(&self, position: u16) -> Result<command_timeout::CommandTimeoutStatus> {
        self.sequenced(position)?;
        Ok(self.shared.command_timeouts[position as usize].status())
    }

    /// Sets one mapped output object `index:subindex` of the slave at `position` (its exact
    /// size) from the next cycle on, leaving the other outputs as they are. A mode's command
    /// object ([`Mode::is_command_object`](crate::drive::ds402::Mode::is_command_object)) is a
    /// set-point write that releases a held target; any other output (the drive's I/O, a
    /// latch control) leaves the target held.
    pub fn set_object(&self, position: u16, index: u16, subindex: u8, data: &[u8]) -> Result<()> {
        self.check_running(SETPOINTS_STOPPED)?;
        let slot = self.slot(position)?;
        let (rx, _) = self.mapping(position)?;
        let (offset, entry) = crate::ethercat::pdo::find(rx, index, subindex)
            .ok_or_else(|| Error::from(Unavailable::NotInOutputs { slave: position, index, subindex }))?;
        if entry.byte_len() != data.len() {
            return Err(
                SettingError::EntryLength { index, subindex, expected: entry.byte_len(), given: data.len() }.into()
            );
        }
        let command = crate::drive::ds402::Mode::is_command_object(index, subindex);
        if command && self.sequenced.get(position as usize).is_some_and(|s| s.is_ok()) {
            self.check_not_driven(position, "a set-point")?;
            self.check_step(position, slot.out_offset + offset, data)?;
        }
        self.shared.setpoints.write().write(slot.out_offset + offset, data);
        if let (Some(Ok(())), true) = (self.sequenced.get(position as usize), command) {
            self.shared.drives[position as usize].setpoint_written();
            if command_timeout::TARGETS.contains(&(index, subindex)) {
                self.shared.command_timeouts[position as usize].target_written();
            }
        }
        Ok(())
    }

    /// Plays a joint trajectory in the cycle thread: joint j on the drive at `slaves[j]`,
    /// `points` at `times_ns` from the start (one knot per joint each; see
    /// [`Trajectory::new`]), within `limits` (counts, one per joint; an INT32 target's range
    /// when `None`), from `start_ns` on the monotonic clock (`None`: now). Every drive must be
    /// sequenced, in Operation enabled, and in interpolated position (0x60C1:01) or cyclic
    /// synchronous position (0x607A) with that target mapped (without a mode display mapped,
    /// every position target mapped is written). The trajectory is validated and its plan
    /// allocated here; a bad one is refused before anything moves. It takes over from the
    /// trajectory in force at its start, without a step. Returns its id; waits (the caller,
    /// not the cycle) at most a few cycles for the thread to take the one handed before.
    ///
    /// Judged by `tolerances` (one per joint) where given: FollowJointTrajectory's path and goal
    /// tolerances, its goal time tolerance, and how each joint stops
    /// ([`stop_trajectory`](Self::stop_trajectory), a path violation).
    pub fn follow_trajectory(
        &self,
        slaves: &[u16],
        times_ns: &[u64],
        points: &[Vec<Knot>],
        start_ns: Option<u64>,
        tolerances: Option<trajectory_player::Tolerances>,
    ) -> Result<u32> {
        self.check_running("no trajectory can play")?;
        let limits: Vec<Limits> = slaves.iter().map(|&slave| self.limits_of(slave).0).collect();
        let trajectory = Trajectory::new(slaves.len(), times_ns, points, Some(&limits))?;
        let joints = slaves
            .iter()
            .enumerate()
            .map(|(joint, &slave)| {
                if let Some(first) = slaves[..joint].iter().position(|&s| s == slave) {
                    return Err(TrajectoryError::DriveTwice { slave, first, second: joint }.into());
                }
                self.trajectory_joint(joint, slave)
            })
            .collect::<Result<Vec<_>>>()?;
        if let Some(t) = tolerances.as_ref().filter(|t| t.joints.len() != slaves.len()) {
            let (given, joints) = (t.joints.len(), slaves.len());
            return Err(TrajectoryError::PerJointCount { what: "tolerance", given, joints }.into());
        }
        for &slave in slaves {
            if self.shared.homings[slave as usize].status().phase.under_way() {
                return Err(Unavailable::Driven { slave, what: "a trajectory", trajectory: None }.into());
            }
        }
        if start_ns.is_none_or(|start| start <= crate::cycle::timing::now_ns() + 2 * self.period.as_nanos() as u64) {
            self.judge_take_over(slaves, &trajectory)?;
        }
        let id = self.trajectories.next_id();
        let mut plan = trajectory_player::Plan::judged(id, start_ns, joints, trajectory, tolerances);
        let status = plan.status();
        let deadline = std::time::Instant::now() + 10 * self.period + Duration::from_millis(100);
        loop {
            self.shared.trajectories.collect(|ended| self.trajectories.note(ended));
            plan = match self.shared.trajectories.give(plan) {
                Ok(()) => break,
                Err(plan) => plan,
            };
            if !self.running() || std::time::Instant::now() >= deadline {
                return Err(Error::Timeout { what: "the cycle thread to take the trajectory handed before".into() });
            }
            std::thread::sleep(Duration::from_micros(100));
        }
        self.trajectories.handed(status, slaves.to_vec());
        Ok(status.id)
    }

    /// Judges, before it is handed over, how `trajectory` (on drives `slaves`) would take over
    /// now: each drive's segment to the first point from its set-point in force (the running
    /// trajectory's, else the target last sent, at rest), and that no drive of the running
    /// trajectory that this one does not drive is moving. The cycle thread judges the same at
    /// the take-over itself, from the exact set-points then.
    fn judge_take_over(&self, slaves: &[u16], trajectory: &Trajectory) -> Result<()> {
        let snapshot = self.snapshot();
        for (joint, &slave) in slaves.iter().enumerate() {
            let sent = || {
                let at = self.offsets[slave as usize].and_then(|o| o.targets.into_iter().flatten().next())?;
                Some(crate::cycle::image::i32_at(&snapshot.outputs, at) as f64)
            };
            let from = self
                .shared
                .trajectories
                .setpoint(slave)
                .or_else(|| sent().map(|position| Setpoint { position, ..Setpoint::default() }));
            if let Some(breach) = from.and_then(|from| trajectory.lead_in_breach(joint, from)) {
                return Err(Trajectory::lead_in_error(joint, breach).into());
            }
        }
        let left = (0..self.slave_count()).filter(|s| !slaves.contains(s)).find_map(|slave| {
            let setpoint = self.shared.trajectories.setpoint(slave)?;
            (setpoint.velocity != 0.0).then_some((slave, setpoint.velocity))
        });
        if let Some((slave, velocity)) = left {
            let (_, scale, name) = self.limits_of(slave);
            let velocity = scale.words(Limit::Velocity, velocity);
            return Err(TrajectoryError::LeavesMoving { slave, name, velocity }.into());
        }
        Ok(())
    }

    /// What `refusal` (of a trajectory at its take-over) means, in the joint's words.
    pub fn refusal_text(&self, refusal: &Refusal) -> String {
        let (limits, scale, name) = self.limits_of(refusal.slave);
        let joint = name.unwrap_or_else(|| format!("drive {}", refusal.slave));
        let value = refusal.value as f64;
        let (limit, allowed) = match refusal.why {
            RefusalReason::Position => {
                let end = if value > limits.max { limits.max } else { limits.min };
                return format!(
                    "{joint}'s segment to the first point, from its set-point at the take-over, would reach {}, past \
                     its limit {}",
                    scale.words(Limit::Position, value),
                    scale.words(Limit::Position, end)
                );
            }
            RefusalReason::Velocity => (Limit::Velocity, limits.max_velocity),
            RefusalReason::Acceleration | RefusalReason::VelocityStep => (Limit::Acceleration, limits.max_acceleration),
            RefusalReason::LeftMoving => {
                return format!(
                    "{joint} was moving at {} in the trajectory in force, which this one would have replaced \
                     without driving it",
                    scale.words(Limit::Velocity, value)
                );
            }
        };
        if refusal.why == RefusalReason::VelocityStep {
            return format!(
                "{joint}'s set-point velocity would step by {} at the take-over, past its max_acceleration {}",
                scale.magnitude(Limit::Velocity, value),
                scale.magnitude(limit, allowed)
            );
        }
        format!(
            "{joint}'s segment to the first point, from its set-point at the take-over, would reach {}, past its {} \
             {}",
            scale.words(limit, value),
            limit.name(),
            scale.magnitude(limit, allowed)
        )
    }

    /// Hands down the limits of the joint on the drive at `position`, by which the cycle judges
    /// every motion of it from then on: trajectories (every point and the path between them),
    /// and the set-points of a cyclic position mode (the step to each from the target last
    /// sent, taken within one cycle).
    pub fn set_joint_limits(&self, position: u16, joint: JointLimits) -> Result<()> {
        self.check_position(position)?;
        if let Some(e) = joint.check() {
            return Err(e.into());
        }
        let mut all = self.joint_limits.write().unwrap_or_else(|poisoned| poisoned.into_inner());
        all[position as usize] = Some(joint);
        Ok(())
    }

    /// The limits of the joint on the drive at `slave`, how its values read and its name (an
    /// INT32 target's range at any speed, counts, no name, where none were handed down).
    pub fn limits_of(&self, slave: u16) -> (Limits, Scale, Option<String>) {
        let all = self.joint_limits.read().unwrap_or_else(|poisoned| poisoned.into_inner());
        match all.get(slave as usize) {
            Some(Some(joint)) => (joint.limits, joint.scale, Some(joint.name.clone())),
            _ => (Limits::TARGET, Scale::COUNTS, None),
        }
    }

    /// Refuses `what` for the drive at `position` while a trajectory in force or a homing
    /// under way drives it.
    fn check_not_driven(&self, position: u16, what: &'static str) -> Result<()> {
        if self.shared.homings.get(position as usize).is_some_and(|h| h.status().phase.under_way()) {
            return Err(Unavailable::Driven { slave: position, what, trajectory: None }.into());
        }
        if let Some(id) = self.trajectories.driving(&self.shared.trajectories, position) {
            return Err(Unavailable::Driven { slave: position, what, trajectory: Some(id) }.into());
        }
        Ok(())
    }

    /// Refuses a position target `data` written at `at` in the outputs of the drive at
    /// `position` in a cyclic position mode whose step from the target last sent, which the
    /// drive takes within one cycle, would go past the joint's velocity or acceleration limit.
    fn check_step(&self, position: u16, at: usize, data: &[u8]) -> Result<()> {
        let Some(o) = self.offsets[position as usize] else { return Ok(()) };
        let Ok(bytes) = <[u8; 4]>::try_from(data) else { return Ok(()) };
        if !o.targets.contains(&Some(at)) {
            return Ok(());
        }
        let status = self.drive_status(position)?;
        // A set-point written while the drive is not enabled never goes out: the target is held at the actual
        // position until one is written after the enable.
        if status.state() != Some(crate::drive::ds402::State::OperationEnabled) {
            return Ok(());
        }
        let mode = status.mode_display.or_else(|| self.mode_set(position));
        use crate::drive::ds402::Mode;
        let cyclic = [Mode::CyclicSynchronousPosition, Mode::InterpolatedPosition];
        if !mode.and_then(Mode::from_i8).is_some_and(|m| cyclic.contains(&m)) {
            return Ok(());
        }
        let (limits, scale, name) = self.limits_of(position);
        let sent = crate::cycle::image::i32_at(&self.snapshot().outputs, at);
        let step = i32::from_le_bytes(bytes).wrapping_sub(sent) as f64;
        let period_s = self.period.as_secs_f64();
        // Within a cycle the drive moves the step at a constant velocity, from rest and back to it.
        let (velocity, acceleration) = (step / period_s, step / (period_s * period_s));
        let past = [
            (Limit::Velocity, velocity, limits.max_velocity),
            (Limit::Acceleration, acceleration, limits.max_acceleration),
        ]
        .into_iter()
        .find(|(_, value, allowed)| value.abs() > allowed * 1.000_001 && step.abs() > 1.0);
        let Some((limit, value, allowed)) = past else { return Ok(()) };
        let joint = name.map_or_else(|| format!("drive {position}"), |n| format!("joint {n}"));
        let most = match limit {
            Limit::Acceleration => allowed * period_s * period_s,
            _ => allowed * period_s,
        };
        Err(Unavailable::StepPastLimit {
            slave: position,
            detail: format!(
                "in a cyclic position mode the drive takes the step of {} from the target last sent within one cycle \
                 ({} s), {} {}, past {joint}'s {} {}; a step may be at most {}: stream set-points every cycle, or \
                 move by a trajectory, which the cycle interpolates",
                scale.magnitude(Limit::Position, step),
                period_s,
                if limit == Limit::Velocity { "a velocity of" } else { "an acceleration of" },
                scale.magnitude(limit, value),
                limit.name(),
                scale.magnitude(limit, allowed),
                scale.magnitude(Limit::Position, most),
            ),
        }
        .into())
    }

    /// The drive at `slave` as joint `joint` of a trajectory, or why it cannot be one.
    fn trajectory_joint(&self, joint: usize, slave: u16) -> Result<trajectory_player::Joint> {
        let not_ready = |why: String| trajectory_player::not_ready(joint, slave, why);
        let status = self.sequenced(slave).map_err(|e| not_ready(e.to_string()))?.status();
        if status.state() != Some(crate::drive::ds402::State::OperationEnabled) {
            let state = status.state().map_or("no valid state", crate::drive::ds402::State::name);
            return Err(not_ready(format!("it is in {state}, not Operation enabled; enable it first")));
        }
        let o = self.offsets[slave as usize].unwrap_or_default();
        let [target_position, ip_setpoint] = o.targets;
        let targets = match status.mode_display.map(crate::drive::ds402::Mode::from_i8) {
            None => o.targets,
            Some(Some(crate::drive::ds402::Mode::InterpolatedPosition)) => [ip_setpoint, None],
            Some(Some(crate::drive::ds402::Mode::CyclicSynchronousPosition)) => [target_position, None],
            Some(mode) => {
                let mode =
                    mode.map_or_else(|| format!("mode {}", status.mode_display.unwrap_or(0)), |m| m.name().into());
                return Err(not_ready(format!(
                    "it is in {mode}; a trajectory needs interpolated position (7) or cyclic synchronous position (8)"
                )));
            }
        };
        if targets.iter().all(Option::is_none) {
            return Err(not_ready(
                "its outputs carry no position target of its mode (0x60C1:01 for interpolated position, 0x607A for \
                 cyclic synchronous position)"
                    .into(),
            ));
        }
        Ok(trajectory_player::Joint {
            slave,
            targets,
            statusword: o.statusword,
            actual: o.actual,
            velocity_actual: o.velocity_actual,
        })
    }

    /// The trajectory `id` (from [`follow_trajectory`](Self::follow_trajectory)) as the cycle
    /// thread last published it: pending, running (the point approached, the time since its
    /// start) or how it ended. The statuses of the last [`trajectory_player::KEPT`] are kept.
    pub fn trajectory_status(&self, id: u32) -> Result<trajectory_player::TrajectoryStatus> {
        self.trajectories.status(&self.shared.trajectories, id)
    }

    /// Brings trajectory `id` to a standstill in the cycle thread, each joint at its stop
    /// deceleration; it then ends "stopped". Nothing for a trajectory that is not in force.
    pub fn stop_trajectory(&self, id: u32) {
        self.trajectories.stop(&self.shared.trajectories, id);
    }

    /// The drive at `slave`'s set-point and actual values as the trajectory in force judges
    /// them (see [`trajectory_player::PlayerShared::followed`]); `None` while none drives it.
    pub fn trajectory_followed(&self, slave: u16) -> Option<[f64; 4]> {
        self.shared.trajectories.followed(slave)
    }

    /// The mapping of the slave at `position`: its output entries and input entries, in wire
    /// order.
    pub fn mapping(&self, position: u16) -> Result<&(Vec<PdoEntry>, Vec<PdoEntry>)> {
        self.slot(position)?;
        self.mappings[position as usize].as_ref().ok_or(Unavailable::NoMapping { slave: position }.into())
    }

    /// Where the recovery of the slave at `position` stands: whether it is lost and being
    /// brought back, the attempts, the recoveries so far and why the last attempt failed.
    pub fn recovery_status(&self, position: u16) -> Result<recovery::RecoveryStatus> {
        self.check_position(position)?;
        Ok(self.shared.recovery[position as usize].status())
    }

    /// Frames the recovery thread had the cycle thread send, and those lost.
    pub fn relayed_frames(&self) -> (u64, u64) {
        self.shared.relay.counts()
    }

    fn check_position(&self, position: u16) -> Result<()> {
        if position >= self.slave_count() {
            return Err(Error::NoSuchSlave { position, count: self.slave_count() });
        }
        Ok(())
    }

    /// The drive's status as the cycle thread last published it. Lock-free.
    pub fn drive_status(&self, position: u16) -> Result<sequencer::DriveStatus> {
        Ok(self.sequenced(position)?.status())
    }

    /// Whether a fault on one drive quick-stops the others (off by default: each drive on its
    /// own). On, the cycle that sees a drive enter Fault or leave Op asks every other drive
    /// being enabled or enabled, and not in Fault itself, for a quick stop, as an arm needs:
    /// its joints stop together in that cycle rather than when some other thread gets to it.
    /// The faulting drive's own event is the only one reported; the others show the request
    /// in their status (`drive_status`), and nothing re-enables them.
    pub fn set_quick_stop_on_fault(&self, on: bool) {
        self.shared.quick_stop_on_fault.store(on, Ordering::Relaxed);
    }

    /// Sets how long a drive request may take before it is reported stuck (from the next
    /// request on).
    pub fn set_request_timeout(&self, timeout: Duration) {
        self.shared.request_timeout_ns.store(timeout.as_nanos().min(u64::MAX as u128) as u64, Ordering::Relaxed);
    }

    /// How long a drive request may take before it is reported stuck.
    pub fn request_timeout(&self) -> Duration {
        Duration::from_nanos(self.shared.request_timeout_ns.load(Ordering::Relaxed))
    }

    /// The outputs of the slave at `position` as last set (the set-points; for a sequenced
    /// drive, the controlword and held target that go out are in [`Snapshot::outputs`]), from
    /// bit 0 of the first byte.
    pub fn outputs(&self, position: u16) -> Result<Vec<u8>> {
        let slot = self.slot(position)?;
        let mut image = vec![0; self.shared.setpoints.len()];
        self.shared.setpoints.read(&mut image);
        Ok(slot.outputs_in(&image))
    }

    /// The channels of the slave at `position`, named after its PDO entries as its SII names
    /// them ([`crate::ethercat::device`]): outputs, then inputs; empty for a slave without
    /// process data.
    pub fn channels(&self, position: u16) -> Result<&[Channel]> {
        self.check_position(position)?;
        Ok(&self.channels[position as usize])
    }

    /// The value of every channel of the slave at `position` in `snapshot`, in the order of
    /// [`channels`](Self::channels): inputs as read, outputs as that cycle sent them.
    pub fn channel_values(&self, snapshot: &Snapshot, position: u16) -> Result<Vec<ChannelValue>> {
        let channels = self.channels(position)?;
        let Some(slot) = self.slots[position as usize] else { return Ok(Vec::new()) };
        Ok(channels
            .iter()
            .map(|c| match c.direction {
                Direction::Rx => c.read(&snapshot.outputs, slot.out_start_bit()),
                Direction::Tx => c.read(&snapshot.inputs, slot.in_start_bit()),
            })
            .collect())
    }

    /// What the inputs of the drive at `position` say in `snapshot`, read by its mapping.
    pub fn drive_inputs(&self, snapshot: &Snapshot, position: u16) -> Result<DriveInputs> {
        let (_, tx) = self.mapping(position)?;
        let read = DriveInputs::read(tx, &self.inputs_of(snapshot, position)?);
        Ok(DriveInputs { cycle: snapshot.cycle, time_ns: snapshot.time_ns, fresh: snapshot.fresh, ..read })
    }

    /// The I/O of the drive at `position` in `snapshot`, read by its mapping: its inputs as
    /// read, its outputs as that cycle sent them.
    pub fn drive_io(&self, snapshot: &Snapshot, position: u16) -> Result<DriveIo> {
        let (rx, tx) = self.mapping(position)?;
        let outputs = self.outputs_of(snapshot, position)?;
        let read = DriveIo::read(rx, tx, &outputs, &self.inputs_of(snapshot, position)?);
        Ok(DriveIo { cycle: snapshot.cycle, time_ns: snapshot.time_ns, fresh: snapshot.fresh, ..read })
    }

    /// The device at `position`, where it has process data: a slave the cycle does not
    /// sequence (a drive's outputs are its objects', set with [`set_object`](Self::set_object)).
    fn device(&self, position: u16) -> Result<Option<ImageSlot>> {
        self.check_running(SETPOINTS_STOPPED)?;
        self.check_position(position)?;
        if self.sequenced[position as usize].is_ok() {
            return Err(Unavailable::DriveChannels { slave: position }.into());
        }
        Ok(self.slots[position as usize])
    }

    /// Sets output channels of the device at `position` by name from the next cycle on, every
    /// one or none: each name must be one of its outputs and each value one it takes
    /// ([`Channel::encode`]); the other outputs keep their values. Lock-free for the cycle.
    pub fn set_channels(&self, position: u16, values: &[(&str, ChannelValue)]) -> Result<()> {
        let slot = self.device(position)?;
        let channels = &self.channels[position as usize];
        let outputs =
            || channels.iter().filter(|c| c.direction == Direction::Rx).map(|c| c.name.clone()).collect::<Vec<_>>();
        let mut writes = Vec::with_capacity(values.len());
        for &(name, value) in values {
            let channel =
                channels.iter().find(|c| c.name == name && c.direction == Direction::Rx).ok_or_else(|| {
                    let is_input = channels.iter().any(|c| c.name == name);
                    Unavailable::NoSuchOutput { slave: position, name: name.to_owned(), outputs: outputs(), is_input }
                })?;
            let raw = channel.encode(value).map_err(|error| Unavailable::ChannelValue { slave: position, error })?;
            writes.push((channel, raw));
        }
        // A slave without process data has no channel: its first name was refused.
        let (Some(slot), false) = (slot, writes.is_empty()) else { return Ok(()) };
        let mut w = self.shared.setpoints.write();
        for (channel, raw) in writes {
            w.write_bits(
                slot.out_start_bit() + channel.bit,
                &raw.to_le_bytes(),
                usize::from(channel.entry.bits).min(64),
            );
        }
        Ok(())
    }

    /// Switches every output of the device at `position` off (its bits 0) from the next cycle
    /// on, until they are set again; nothing for a device without outputs.
    pub fn switch_outputs_off(&self, position: u16) -> Result<()> {
        let Some(slot) = self.device(position)? else { return Ok(()) };
        let mut w = self.shared.setpoints.write();
        for n in (0..slot.out_bits).step_by(64) {
            w.write_bits(slot.out_start_bit() + n, &[0; 8], (slot.out_bits - n).min(64));
        }
        Ok(())
    }

    /// The last cycle's snapshot.
    pub fn snapshot(&self) -> Snapshot {
        let mut bytes = vec![0; self.shared.snapshot.len()];
        self.shared.snapshot.read(&mut bytes);
        let (header, images) = bytes.split_at(HEADER_LEN);
        let (inputs, outputs) = images.split_at(images.len() - self.shared.setpoints.len());
        Snapshot {
            cycle: u64::from_le_bytes(header[0..8].try_into().expect("8 bytes")),
            time_ns: u64::from_le_bytes(header[8..16].try_into().expect("8 bytes")),
            wkc: u16::from_le_bytes([header[16], header[17]]),
            fresh: header[18] != 0,
            inputs: inputs.to_vec(),
            outputs: outputs.to_vec(),
        }
    }

    /// The outputs the slave at `position` was sent in `snapshot`'s cycle, from bit 0 of the
    /// first byte: the snapshot's own bytes for a slave laid out in whole bytes (a drive), a copy
    /// for one packed beside others.
    pub fn outputs_of<'a>(&self, snapshot: &'a Snapshot, position: u16) -> Result<Cow<'a, [u8]>> {
        let slot = self.slot(position)?;
        Ok(match slot.out_bit {
            0 => Cow::Borrowed(&snapshot.outputs[slot.out_offset..slot.out_offset + slot.out_bits.div_ceil(8)]),
            _ => Cow::Owned(slot.outputs_in(&snapshot.outputs)),
        })
    }

    /// The inputs of the slave at `position` in `snapshot`, from bit 0 of the first byte, as
    /// [`outputs_of`](Self::outputs_of) gives the outputs.
    pub fn inputs_of<'a>(&self, snapshot: &'a Snapshot, position: u16) -> Result<Cow<'a, [u8]>> {
        let slot = self.slot(position)?;
        Ok(match slot.in_bit {
            0 => Cow::Borrowed(&snapshot.inputs[slot.in_offset..slot.in_offset + slot.in_bits.div_ceil(8)]),
            _ => Cow::Owned(slot.inputs_in(&snapshot.inputs)),
        })
    }

    /// The distributed clocks: SYNC0's set-up and every drive's last system-time difference;
    /// `None` when the bus runs without them. Lock-free.
    pub fn dc_status(&self) -> Option<dc_status::DcStatus> {
        self.shared.dc.status()
    }

    /// The statistics, updated by the thread every cycle.
    pub fn stats(&self) -> &CycleStats {
        &self.shared.stats
    }

    /// Whether the thread still runs.
    pub fn running(&self) -> bool {
        !self.stopped() && lock(&self.thread).as_ref().is_some_and(|t| !t.is_finished())
    }

    /// Stops the thread after its current cycle and hands the master back. The last snapshot
    /// and the statistics stay readable; set-points are refused from then on.
    pub fn stop(&self) -> Result<Master> {
        if self.stopped() {
            return Err(Unavailable::CycleAlreadyStopped.into());
        }
        self.halt().ok_or(Unavailable::CyclePanicked.into())
    }

    /// Whether [`stop`](Self::stop) was called.
    pub fn stopped(&self) -> bool {
        self.halted.load(Ordering::Acquire)
    }

    fn halt(&self) -> Option<Master> {
        self.halted.store(true, Ordering::Release);
        self.shared.stop.store(true, Ordering::Release);
        let thread = lock(&self.thread).take();
        let master = thread?.join().ok().flatten();
        if let Some(recovery) = lock(&self.recovery).take() {
            let _ = recovery.join();
        }
        lock(&self.cpu_latency).take();
        master
    }
}

impl Drop for CycleThread {
    /// A cycle thread dropped without [`stop`](CycleThread::stop) stops, and its master closes.
    fn drop(&mut self) {
        self.halt();
    }
}

/// The recovery thread's work, made while the master is still this thread's: each sequenced
/// drive, and the mode in force (its display 0x6061, read now: a drive that lost power has
/// forgotten it, and 0x6060 reads 0 where mapped outputs carry "no change"), and each device,
/// which gets no mode.
fn recoverer(
    master: &mut Master,
    shared: &CycleShared,
    drives: &[DriveLoop],
    devices: &[DeviceLoop],
    period: Duration,
) -> recovery::Recoverer {
    let mut recovered = vec![false; master.slaves().len()];
    for d in devices {
        recovered[d.position as usize] = true;
    }
    for d in drives {
        let position = d.position as usize;
        if let Ok([mode]) = master.slave_mut(d.position).and_then(|mut s| s.sdo_read(0x6061, 0)).as_deref() {
            shared.recovery[position].set_mode(*mode as i8);
        }
        recovered[position] = true;
    }
    recovery::Recoverer::new(master, shared.relay.clone(), period, recovered)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ethercat::al::AlState;
    use crate::sim::in_process::InProcess;

    fn master_in_op(count: usize) -> Master {
        let mut m = Master::new(Box::new(InProcess::new(count)), Duration::from_millis(100));
        m.scan().unwrap();
        m.request_state(AlState::Op, Duration::from_secs(5)).unwrap();
        m
    }

    fn wait_for_cycle(cycle: &CycleThread, after: u64) -> Snapshot {
        loop {
            let s = cycle.snapshot();
            if s.cycle > after {
                return s;
            }
            std::thread::sleep(Duration::from_millis(1));
        }
    }

    #[test]
    fn refuses_a_period_out_of_range_and_hands_the_master_back() {
        let (error, master) =
            *CycleThread::start(master_in_op(1), Config::new(Duration::from_micros(100))).err().unwrap();
        assert!(error.to_string().contains("250 µs ..= 10000 µs"), "{error}");
        let (error, _) = *CycleThread::start(
            master,
            Config {
                realtime: RealTime { priority: Some(0), ..RealTime::default() },
                ..Config::new(Duration::from_millis(1))
            },
        )
        .err()
        .unwrap();
        assert!(error.to_string().contains("1..=99"), "{error}");
    }

    #[test]
    fn refuses_a_master_without_process_image() {
        let mut m = Master::new(Box::new(InProcess::new(1)), Duration::from_millis(100));
        m.scan().unwrap();
        let (error, _) = *CycleThread::start(m, Config::new(Duration::from_millis(1))).err().unwrap();
        assert!(error.to_string().contains("no process image"), "{error}");
    }

    #[test]
    fn cycles_sets_outputs_and_hands_the_master_back() {
        let mut master = master_in_op(2);
        // Outputs set before the start go on unchanged.
        master.slave_mut(1).unwrap().set_outputs(&[0x44, 0x33, 0x22, 0x11, 0x0F, 0]).unwrap();
        let cycle = CycleThread::start(master, Config::new(Duration::from_micros(500))).map_err(|e| e.0).unwrap();
        assert!(cycle.running());
        assert_eq!(cycle.outputs(1).unwrap(), [0x44, 0x33, 0x22, 0x11, 0x0F, 0]);
        cycle.set_outputs(0, &[0x78, 0x56, 0x34, 0x12, 0x06, 0]).unwrap();
        assert!(cycle.set_outputs(0, &[1, 2]).unwrap_err().to_string().contains("6 bytes of outputs, 2 given"));
        assert!(cycle.set_outputs(5, &[0; 6]).unwrap_err().to_string().contains("slave 5 has no process data"));
        let first = wait_for_cycle(&cycle, 0);
        let later = wait_for_cycle(&cycle, first.cycle + 20);
        assert!(later.time_ns > first.time_ns);
        assert!(later.fresh);
        assert_eq!(later.wkc, 6);
        assert_eq!(cycle.inputs_of(&later, 1).unwrap().len(), 6);
        // No drive was asked for anything: the set-points go out as written.
        assert_eq!(*cycle.outputs_of(&later, 0).unwrap(), [0x78, 0x56, 0x34, 0x12, 0x06, 0]);
        let stats = cycle.stats();
        assert!(stats.period.summary().count >= 20);
        assert!(stats.wake_latency.summary().count >= 21);
        assert!(stats.exchange.summary().count >= 21);
        let mut master = cycle.stop().unwrap();
        assert!(cycle.stop().err().unwrap().to_string().contains("already stopped"));
        assert!(cycle.set_outputs(0, &[0; 6]).unwrap_err().to_string().contains("the cycle is stopped"));
        let cycles = master.stats().cycles;
        assert_eq!(cycle.stats().cycles.load(Ordering::Relaxed), cycle.snapshot().cycle);
        assert!(cycles > later.cycle, "{cycles}");
        assert_eq!((master.stats().lost_frames, master.stats().wkc_errors), (0, 0));
        // The set-points reached the drives: read back from their object dictionaries.
        // 0x1701 carries the interpolation set-point 0x60C1:01, then the controlword.
        assert_eq!(master.slave_mut(0).unwrap().sdo_read(0x60C1, 1).unwrap(), 0x1234_5678u32.to_le_bytes());
        assert_eq!(master.slave_mut(0).unwrap().sdo_read(0x6040, 0).unwrap(), [0x06, 0]);
        assert_eq!(master.slave_mut(1).unwrap().sdo_read(0x60C1, 1).unwrap(), 0x1122_3344u32.to_le_bytes());
        // The master works on after the thread: the bus goes down.
        master.request_state(AlState::Init, Duration::from_secs(5)).unwrap();
    }
}
