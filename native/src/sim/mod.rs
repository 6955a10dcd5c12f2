//! The virtual AKD: a Kollmorgen AKD on EtherCAT as the master sees it, faithful to the real
//! drive (its SII, register values, AL status codes, object dictionary and mailbox timing).
//!
//! Each [`VirtualAkd`] is an ESC ([`esc`]) plus the drive's firmware on the PDI side: the AL
//! state machine ([`al_machine`]), the mailbox server ([`mailbox_server`]) over the object dictionary ([`od`]), the
//! process image ([`process_data`]), the process-data watchdog ([`watchdog`]), and the drive firmware
//! ([`drive`]: CiA 402 state machine, modes, supervision and [`faults`]) with its motor and
//! load ([`motion`]) and simulated digital inputs and latch ([`digital_inputs`]); [`pll`] tells
//! what its synchronisation (SYNC0 or SM2) was told; [`firmware`] is what its processor does at
//! the ESC's PDI side. A [`VirtualBus`] is a line of them, or of the slaves a
//! [`SimLine`] names ([`slave`]): AKDs and Beckhoff terminals built from their real EEPROMs
//! ([`terminal`], [`terminal_sii`], on the ESCs of [`esc_hardware`]). It serves EtherCAT frames
//! in place, with time passed in by the caller so that a run is deterministic. [`in_process`] serves a bus to a master in this process through
//! the link trait; [`server`] serves one on UDP or on a network interface.
//! [`control`] lets tests and the simulator command inject faults, set inputs and query a
//! drive while another thread owns the bus and serves its frames, and make the bus fail as
//! in the field: a drive power-cycled ([`VirtualAkd::power_cycle`]), and on the [`line`](mod@line)
//! frames lost or corrupted, wrong working counters, a cable pulled out.
//! [`VirtualBus::with_mailbox_size`] builds drives whose SII declares a smaller mailbox than
//! the real drive's 1 KiB, so that segmented SDO transfers and fragmented SDO information,
//! which the real drive's objects never need, can be exercised.

pub mod al_machine;
pub mod control;
pub mod digital_inputs;
pub mod drive;
pub mod eoe_server;
pub mod esc;
pub mod esc_hardware;
pub mod faults;
pub mod firmware;
pub mod foe_server;
pub mod homing;
pub mod in_process;
pub mod line;
pub mod mailbox_server;
pub mod missed_frames;
pub mod motion;
pub mod od;
pub mod pll;
pub mod process_data;
pub mod server;
pub mod setpoint_trace;
pub mod sii_image;
pub mod slave;
pub mod sync_manager;
pub mod terminal;
pub mod terminal_sii;
pub mod terminals;
pub mod watchdog;

use crate::error::{FrameError, Result, SettingError};
use crate::ethercat::al::{AlState, AlStatusCode};
use crate::ethercat::frame::{self, DatagramMut};
use crate::ethercat::line_health::registers::PORTS;
use crate::ethercat::link_spec::{MissedFrames, Pace, SimLine, SimProduct};
use crate::ethercat::pdo;
use crate::ethercat::sii::Identity;
use crate::sim::esc::{Arrival, Esc, Events};
pub use crate::sim::slave::VirtualSlave;
use crate::sim::sync_manager::{SyncManager, MIN_MAILBOX_SIZE};

/// How long the drive's firmware takes to react, in ns of bus time.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Timing {
    /// From a write of AL control until the firmware handles the request (and the master may
    /// write AL control again).
    pub al_request_ns: u64,
    /// The same for the first request of PreOp in Init after power-up: the firmware sets up
    /// its mailbox and object dictionary first, AL status reading Init all that time.
    pub first_init_to_preop_ns: u64,
    /// The same for a later request of PreOp in Init.
    pub init_to_preop_ns: u64,
    /// From a complete mailbox write until the reply is in the mailbox-in buffer, for the first
    /// message after power-up.
    pub first_mailbox_ns: u64,
    /// The same for the later messages.
    pub mailbox_ns: u64,
    /// How the firmware judges missed frames: by time, as the real drive, or by frames lost.
    pub missed_frames: MissedFrames,
    /// From an EoE Set IP Parameter request until the drive's response.
    pub eoe_set_ip_ns: u64,
    /// From that response until the drive announces its address (a broadcast ARP request).
    pub eoe_announce_ns: u64,
}

impl Timing {
    /// The real drive's pace (docs/virtual_akd.md has the evidence):
    /// - Init→PreOp: under TwinCAT a real AKD took 16-19 ms for its first Init→PreOp after
    ///   power-up (issue 28: it read Init for about 16 ms, PreOp by about 19 ms), 17.5 ms here,
    ///   and 3-6 ms for later ones, 4.5 ms here; the drive of the SOEM capture, powered up long
    ///   before, was in PreOp 4.2-6.2 ms after its request.
    /// - the other AL requests: PreOp→SafeOp answered within 4.9 ms in the SOEM capture.
    /// - mailbox: under TwinCAT the first reply after that first PreOp came 25-50 ms after the
    ///   request (TwinCAT, polling SM1 every 16 ms or so, found it empty once or twice first):
    ///   30 ms here, which such polling finds empty once or twice too. The SOEM capture's 35
    ///   replies appear 0.56 to 2.9 ms after the request, its first one too, most by 1.3 ms. A
    ///   fixed 1 ms puts 19 of them in the window the capture allows, as any delay from 0.8 to
    ///   1.3 ms does; a firmware task running every 1 ms would explain 27, but its phase is
    ///   unknown, and counted from the drive's first frame it fits the replay worse (23 of the
    ///   capture's mailbox status polls on the other side, against 19).
    /// - EoE: under TwinCAT a real AKD answered Set IP Parameter about 25 ms after the request
    ///   and sent its gratuitous ARP about 18 ms after that (issue 15).
    pub const REAL_DRIVE: Timing = Timing {
        al_request_ns: 4_500_000,
        first_init_to_preop_ns: 17_500_000,
        init_to_preop_ns: 4_500_000,
        first_mailbox_ns: 30_000_000,
        mailbox_ns: 1_000_000,
        missed_frames: MissedFrames::Late,
        eoe_set_ip_ns: 25_000_000,
        eoe_announce_ns: 18_000_000,
    };
    /// No delay: each request is handled before the next frame (`pace=immediate`).
    pub const IMMEDIATE: Timing = Timing {
        al_request_ns: 0,
        first_init_to_preop_ns: 0,
        init_to_preop_ns: 0,
        first_mailbox_ns: 0,
        mailbox_ns: 0,
        missed_frames: MissedFrames::Late,
        eoe_set_ip_ns: 0,
        eoe_announce_ns: 0,
    };

    /// The timing of drives at `pace` that judge missed frames by `missed_frames`.
    pub fn of(pace: Pace, missed_frames: MissedFrames) -> Timing {
        let base = match pace {
            Pace::Real => Timing::REAL_DRIVE,
            Pace::Immediate => Timing::IMMEDIATE,
        };
        Timing { missed_frames, ..base }
    }
}

impl Default for Timing {
    fn default() -> Self {
        Timing::REAL_DRIVE
    }
}

/// Time a frame takes through one drive and its cable, ns.
const FORWARD_DELAY_NS: u64 = 500;

/// The real AKD's standard mailbox: 1 KiB each way.
pub const AKD_MAILBOX_SIZE: u16 = 0x0400;

/// The SII image of the AKD with `identity` declaring a standard mailbox of `size` bytes each
/// way (the sync manager category says the same), everything else as the real drive's.
fn sii_with_mailbox_size(identity: Identity, size: u16) -> Result<Vec<u8>, crate::ethercat::sii::SiiError> {
    let mut sii = crate::ethercat::sii::Sii::parse(&sii_image::akd_sii_of(identity))?;
    let mailbox = &mut sii.header.standard_mailbox;
    (mailbox.receive_size, mailbox.send_size) = (size, size);
    for category in &mut sii.categories {
        if let crate::ethercat::sii::Category::SyncManagers(sms) = category {
            for sm in sms.iter_mut().take(2) {
                sm.length = size;
            }
        }
    }
    sii.encode()
}

/// What a drive's firmware has done since power-up that makes it quicker the next time
/// ([`Timing`]'s first and later Init→PreOp and mailbox replies).
#[derive(Clone, Copy, Debug, Default)]
struct Warm {
    /// It went from Init to PreOp.
    been_in_preop: bool,
    /// It took a mailbox message.
    answered_mailbox: bool,
}

/// One virtual AKD.
pub struct VirtualAkd {
    esc: Esc,
    al: al_machine::AlMachine,
    od: od::ObjectDictionary,
    mailbox: mailbox_server::MailboxServer,
    watchdog: watchdog::Watchdog,
    timing: Timing,
    mailbox_size: u16,
    pending_al: Option<(u16, u64)>,
    pending_mailbox: Option<u64>,
    outputs_fresh: bool,
    /// Bus time of the last complete write of the outputs.
    outputs_at_ns: u64,
    /// Frames in a row the line lost before they reached this drive.
    frames_lost: u64,
    identity: Identity,
    has_successor: bool,
    warm: Warm,
    drive: drive::DriveFirmware,
    rx_image: process_data::Image,
    tx_image: process_data::Image,
}

impl VirtualAkd {
    /// A drive at power-up reporting `identity` in its SII and its object 0x1018;
    /// `has_successor` tells whether another drive follows on port 1.
    pub fn new(identity: Identity, has_successor: bool, timing: Timing) -> Self {
        Self::with_sii(sii_image::akd_sii_of(identity), identity, AKD_MAILBOX_SIZE, has_successor, timing)
    }

    /// A drive at power-up that declares a standard mailbox of `mailbox_size` bytes each way
    /// instead of the real AKD's 1 KiB, so that SDO values and SDO information replies longer
    /// than a mailbox go in segments and fragments. The drive then expects sync managers 0 and
    /// 1 of at most that size. `mailbox_size` is 64 ([`MIN_MAILBOX_SIZE`]) to 1024
    /// ([`AKD_MAILBOX_SIZE`]).
    pub fn with_mailbox_size(
        identity: Identity,
        mailbox_size: u16,
        has_successor: bool,
        timing: Timing,
    ) -> Result<Self> {
        if !(MIN_MAILBOX_SIZE..=AKD_MAILBOX_SIZE).contains(&mailbox_size) {
            return Err(
                SettingError::MailboxSize { size: mailbox_size, min: MIN_MAILBOX_SIZE, max: AKD_MAILBOX_SIZE }.into()
            );
        }
        let sii = sii_with_mailbox_size(identity, mailbox_size)?;
        Ok(Self::with_sii(sii, identity, mailbox_size, has_successor, timing))
    }

    fn with_sii(sii: Vec<u8>, identity: Identity, mailbox_size: u16, has_successor: bool, timing: Timing) -> Self {
        let mut esc = Esc::new(sii, has_successor);
        firmware::deactivate_sync_managers(&mut esc);
        VirtualAkd {
            esc,
            al: al_machine::AlMachine::power_up(),
            od: od::ObjectDictionary::akd_of(identity),
            mailbox: mailbox_server::MailboxServer::with_eoe_delays(timing.eoe_set_ip_ns, timing.eoe_announce_ns),
            watchdog: watchdog::Watchdog::default(),
            timing,
            mailbox_size,
            pending_al: None,
            pending_mailbox: None,
            outputs_fresh: false,
            outputs_at_ns: 0,
            frames_lost: 0,
            identity,
            has_successor,
            warm: Warm::default(),
            drive: drive::DriveFirmware::default(),
            rx_image: Vec::new(),
            tx_image: Vec::new(),
        }
    }

    /// The drive loses its power and comes back, as a real AKD does: ESC and firmware at
    /// power-up (AL Init, station address 0, sync managers, FMMUs and mailbox cleared, the
    /// object dictionary and its mappings at their defaults, CiA 402 Not ready to switch on,
    /// not homed), with the same EEPROM, identity, timing and homing set-up.
    pub fn power_cycle(&mut self) {
        let sii = self.esc.sii().to_vec();
        // The reference is the machine's; the zero homing found there is the drive's, and gone.
        let homing = self.drive().homing_setup();
        *self = Self::with_sii(sii, self.identity, self.mailbox_size, self.has_successor, self.timing);
        self.drive_mut().set_homing(homing);
    }

    /// The drive as one powered up long before, that has been to PreOp and answered its mailbox
    /// since: its next Init→PreOp and mailbox reply take the later ones' time ([`Timing`]), as
    /// the drive of the SOEM capture did.
    pub fn warm_up(&mut self) {
        self.warm = Warm { been_in_preop: true, answered_mailbox: true };
    }

    /// The F125 a real AKD would have raised where this one judges missed frames by
    /// [`MissedFrames::Warn`].
    pub fn would_be_f125(&self) -> missed_frames::WouldBeF125 {
        self.drive.would_be_f125()
    }

    /// The AL state, the error flag and the AL status code.
    pub fn al_status(&self) -> (AlState, bool, u16) {
        (self.al.state(), self.al.error(), self.al.status_code())
    }

    /// The ESC's register and RAM space.
    pub fn registers(&self) -> &[u8] {
        self.esc.memory()
    }

    /// The object dictionary.
    pub fn od(&self) -> &od::ObjectDictionary {
        &self.od
    }

    /// The mailbox server, to inject faults into its protocols (a busy FoE).
    pub fn mailbox_mut(&mut self) -> &mut mailbox_server::MailboxServer {
        &mut self.mailbox
    }

    /// The object dictionary, to set what the drive reports (tests, fault injection).
    pub fn od_mut(&mut self) -> &mut od::ObjectDictionary {
        &mut self.od
    }

    /// What the drive's synchronisation was told: SYNC0, FBUS.PARAM02, its cycle time.
    pub fn sync_state(&self) -> pll::SyncState {
        pll::SyncState::of(self.esc.memory(), &self.od)
    }

    /// The outputs the master's last frames wrote into SM2, laid out by the drive's RxPDO
    /// mapping, while the drive takes them (Op); `None` in the other states.
    pub fn received_outputs(&self) -> Option<(&[pdo::PdoEntry], &[u8])> {
        if self.al.state() != AlState::Op {
            return None;
        }
        let base = crate::drive::pdo::AKD_PROCESS_OUT as usize;
        let outputs = self.esc.memory().get(base..base + pdo::bit_len(&self.rx_image) / 8)?;
        Some((&self.rx_image, outputs))
    }

    /// The drive firmware: CiA 402 state, motor, inputs.
    pub fn drive(&self) -> &drive::DriveFirmware {
        &self.drive
    }

    /// The drive firmware, for fault injection and the simulated inputs.
    pub fn drive_mut(&mut self) -> &mut drive::DriveFirmware {
        &mut self.drive
    }

    /// A frame the line carried did not reach the drive.
    fn miss_frame(&mut self) {
        self.frames_lost += 1;
    }

    /// Queues an emergency message, as the drive sends on a fault.
    pub fn emergency(&mut self, emergency: &crate::ethercat::coe::Emergency) {
        let size = SyncManager::read(self.esc.memory(), 1).length as usize;
        self.mailbox.emergency(emergency, size);
    }

    /// Serves one datagram passing the drive at bus time `now_ns`.
    fn serve(&mut self, dg: &mut DatagramMut<'_>, now_ns: u64, arrival: Arrival) {
        self.esc.serve(dg, arrival);
        let events = self.esc.take_events();
        if events != Events::default() {
            self.schedule(events, now_ns);
        }
    }

    fn schedule(&mut self, events: Events, now_ns: u64) {
        if let Some(control) = events.al_control {
            let to_preop = self.al.state() == AlState::Init && AlState::from_bits(control) == Some(AlState::PreOp);
            let delay = match (to_preop, self.warm.been_in_preop) {
                (true, false) => self.timing.first_init_to_preop_ns,
                (true, true) => self.timing.init_to_preop_ns,
                (false, _) => self.timing.al_request_ns,
            };
            self.pending_al = Some((control, now_ns + delay));
        }
        if events.mailbox_written {
            let delay = if self.warm.answered_mailbox { self.timing.mailbox_ns } else { self.timing.first_mailbox_ns };
            self.warm.answered_mailbox = true;
            self.pending_mailbox = Some(now_ns + delay);
        }
        if events.watchdog_trigger {
            self.watchdog.trigger(now_ns);
        }
        if events.outputs_written {
            self.outputs_fresh = true;
            self.outputs_at_ns = now_ns;
            self.frames_lost = 0;
        }
        if events.repeat_request {
            firmware::repeat_reply(&mut self.esc, &mut self.mailbox);
        }
    }

    /// The firmware's work between frames: AL requests, mailbox, watchdog, process data.
    pub fn poll(&mut self, now_ns: u64) {
        if let Some((control, due)) = self.pending_al {
            if due <= now_ns {
                self.pending_al = None;
                self.esc.release_al_control();
                self.handle_al_control(control, now_ns);
            }
        }
        if let Some(due) = self.pending_mailbox {
            if due <= now_ns {
                self.pending_mailbox = None;
                firmware::take_request(&mut self.esc, &mut self.mailbox, &mut self.od, self.al.state(), now_ns);
            }
        }
        firmware::offer_reply(&mut self.esc, &mut self.mailbox);
        if self.al.state() == AlState::Op && self.watchdog.expired(now_ns, self.esc.memory_mut()) {
            self.al.fail(AlState::SafeOp, AlStatusCode::SM_WATCHDOG);
            self.watchdog.stop();
            self.write_al_status();
        }
        let fresh = self.al.state() == AlState::Op && self.outputs_fresh;
        if fresh {
            process_data::apply_outputs(&mut self.od, self.esc.memory(), &self.rx_image);
        }
        self.outputs_fresh = false;
        let bus = drive::Bus {
            received: fresh.then_some(drive::Received { at_ns: self.outputs_at_ns, image: &self.rx_image }),
            process_data_expected: matches!(self.al.state(), AlState::SafeOp | AlState::Op),
            watchdog_ns: watchdog::timeout_ns(self.esc.memory()),
            missed_frames: self.timing.missed_frames,
            frames_lost: self.frames_lost,
        };
        if let Some(emergency) = self.drive.run(&mut self.od, now_ns, bus) {
            self.emergency(&emergency);
        }
        if self.al.state() >= AlState::SafeOp && self.al.state() != AlState::Bootstrap {
            process_data::refresh_inputs(&self.od, self.esc.memory_mut(), &self.tx_image);
        }
    }

    /// The firmware's IP stack (EoE) at bus time `now_ns`: the replies due and the frames it
    /// sends, into the mailbox. It runs once a frame has gone back, never in front of one: the
    /// real drive's ESC answers a frame in hardware while its processor does this work.
    pub fn run_ip_stack(&mut self, now_ns: u64) {
        if self.al.state() != AlState::Init && self.al.state() != AlState::Bootstrap {
            self.mailbox.poll(now_ns, firmware::reply_size(&self.esc));
            firmware::offer_reply(&mut self.esc, &mut self.mailbox);
        }
    }

    fn handle_al_control(&mut self, control: u16, now_ns: u64) {
        let (od, memory, mailbox_size) = (&self.od, self.esc.memory(), self.mailbox_size);
        let transition = self.al.request(control, |from, to| match (from, to) {
            (AlState::Init, AlState::PreOp) => sync_manager::check_mailbox(memory, mailbox_size),
            (AlState::PreOp, AlState::SafeOp) => process_data::check_safeop(od, memory),
            _ => Ok(()),
        });
        if let Some(t) = transition {
            self.warm.been_in_preop |= t.to == AlState::PreOp;
            firmware::enter_state(&mut self.esc, &mut self.mailbox, t.to);
            if t.to == AlState::Init || t.to == AlState::Bootstrap {
                self.pending_mailbox = None;
            }
            if t.from == AlState::PreOp && t.to == AlState::SafeOp {
                (self.rx_image, self.tx_image) = process_data::images(&self.od);
            }
            // The watchdog runs only for a master whose SM2 asks for it (control bit 6); the
            // AKD's SII gives 0x24, without it.
            let triggered = SyncManager::read(self.esc.memory(), 2).control & sync_manager::CONTROL_WATCHDOG != 0;
            if t.to == AlState::Op && triggered {
                self.watchdog.trigger(now_ns);
            } else {
                self.watchdog.stop();
            }
        }
        self.write_al_status();
    }

    fn write_al_status(&mut self) {
        firmware::write_al_status(&mut self.esc, &self.al);
    }
}

/// A line of virtual slaves, as a real bus: frames pass slave 0, 1, ... in order. A line of
/// AKDs ([`new`](Self::new), [`with_timing`](Self::with_timing)) or of the slaves a
/// [`SimLine`] names, AKDs and Beckhoff terminals ([`of_line`](Self::of_line)). The `i`-th AKD
/// of a line reports the identity [`sii_image::identity`]`(i)`: the real drive's, with a serial
/// number of its own.
pub struct VirtualBus {
    slaves: Vec<VirtualSlave>,
    line: line::Line,
}

impl VirtualBus {
    /// `count` virtual AKDs at power-up, with the real drive's timing.
    pub fn new(count: usize) -> Self {
        Self::with_timing(count, Timing::REAL_DRIVE)
    }

    /// `count` virtual AKDs reacting with `timing`.
    pub fn with_timing(count: usize, timing: Timing) -> Self {
        let slaves = (0..count).map(|i| VirtualAkd::new(sii_image::identity(i), i + 1 < count, timing));
        Self::of_slaves(slaves.map(VirtualSlave::Akd).collect())
    }

    /// The slaves `line` names, in order, at power-up, the AKDs reacting with `timing`; refused
    /// when a terminal's SII image cannot be read.
    pub fn of_line(line: &SimLine, timing: Timing) -> Result<Self> {
        let count = line.len();
        let mut akds = 0;
        let mut slaves = Vec::with_capacity(count);
        for (i, &product) in line.products().iter().enumerate() {
            slaves.push(VirtualSlave::of(product, akds, i + 1 < count, timing)?);
            akds += usize::from(product == SimProduct::Akd);
        }
        Ok(Self::of_slaves(slaves))
    }

    /// A line of `slaves` in order (built by the caller, e.g. a terminal serving an image a
    /// test changed).
    pub fn of_slaves(mut slaves: Vec<VirtualSlave>) -> Self {
        // Each slave behind another saw its link come up after it reset.
        for slave in slaves.iter_mut().skip(1) {
            slave.esc_mut().link_came_up();
        }
        let line = line::Line::new(slaves.len());
        VirtualBus { slaves, line }
    }

    /// `count` virtual AKDs reacting with `timing` whose SII declares a standard mailbox of
    /// `mailbox_size` bytes (see [`VirtualAkd::with_mailbox_size`]): a master reading the SII
    /// as usual then transfers long SDO values in segments and SDO information in fragments.
    pub fn with_mailbox_size(count: usize, timing: Timing, mailbox_size: u16) -> Result<Self> {
        let slaves = (0..count)
            .map(|i| VirtualAkd::with_mailbox_size(sii_image::identity(i), mailbox_size, i + 1 < count, timing));
        Ok(Self::of_slaves(slaves.map(|s| s.map(VirtualSlave::Akd)).collect::<Result<_>>()?))
    }

    /// Number of slaves.
    pub fn len(&self) -> usize {
        self.slaves.len()
    }

    /// Whether the line has no slave.
    pub fn is_empty(&self) -> bool {
        self.slaves.is_empty()
    }

    /// The products of the line's slaves, in order.
    pub fn products(&self) -> Vec<SimProduct> {
        self.slaves.iter().map(VirtualSlave::product).collect()
    }

    /// Slave `i`. Panics when `i` is not below [`len`](Self::len).
    pub fn at(&self, i: usize) -> &VirtualSlave {
        &self.slaves[i]
    }

    /// Slave `i`, to change it. Panics when `i` is not below [`len`](Self::len).
    pub fn at_mut(&mut self, i: usize) -> &mut VirtualSlave {
        &mut self.slaves[i]
    }

    /// The AKD at position `i`. Panics when `i` is not below [`len`](Self::len) or names a
    /// terminal (never on a line of AKDs).
    pub fn slave(&self, i: usize) -> &VirtualAkd {
        self.slaves[i].akd().unwrap_or_else(|| panic!("slave {i} is no AKD"))
    }

    /// The AKD at position `i`, to change it (tests, fault injection). Panics as
    /// [`slave`](Self::slave) does.
    pub fn slave_mut(&mut self, i: usize) -> &mut VirtualAkd {
        self.slaves[i].akd_mut().unwrap_or_else(|| panic!("slave {i} is no AKD"))
    }

    /// Slave `position` loses its power and comes back as at power-up: its neighbours lose
    /// their links to it meanwhile (and count them); behind another slave, its link comes up
    /// after its reset, as at the line's power-up. Panics when `position` is not below
    /// [`len`](Self::len).
    pub fn power_cycle(&mut self, position: usize) {
        if position > 0 {
            self.slaves[position - 1].esc_mut().set_link(1, false);
        }
        if let Some(next) = self.slaves.get_mut(position + 1) {
            next.esc_mut().set_link(0, false);
        }
        let links = self.links_of(position);
        let slave = &mut self.slaves[position];
        slave.power_cycle();
        slave.esc_mut().power_up_links(links);
        if position > 0 {
            slave.esc_mut().link_came_up();
        }
        self.apply_links();
    }

    /// The links slave `position`'s ports have through the line's cables: port 0 through the
    /// one in front of it, port 1 through the one in front of the next slave; the virtual line
    /// is a daisy chain, its slaves' other ports without a cable.
    fn links_of(&self, position: usize) -> [bool; PORTS] {
        [self.line.plugged(position), self.line.plugged(position + 1), false, false]
    }

    /// Sets every slave's links as the cables are.
    fn apply_links(&mut self) {
        for position in 0..self.slaves.len() {
            let links = self.links_of(position);
            let esc = self.slaves[position].esc_mut();
            for (port, up) in links.into_iter().enumerate() {
                esc.set_link(port, up);
            }
        }
    }

    /// Every AKD of the line as one powered up long before ([`VirtualAkd::warm_up`]).
    pub fn warm_up(&mut self) {
        for slave in &mut self.slaves {
            if let Some(akd) = slave.akd_mut() {
                akd.warm_up();
            }
        }
    }

    /// The line in front of the drives, as its faults left it.
    pub fn line(&self) -> &line::Line {
        &self.line
    }

    /// Starts a burst of lost frames, corrupted replies or wrong working counters.
    pub fn start_burst(&mut self, burst: line::Burst) {
        self.line.start(burst);
    }

    /// Pulls the cable in front of drive `position` out, or plugs it back in: frames reach
    /// only the drives in front of the first cable out, and the last of those closes its port
    /// 1; the ports at both ends of the cable lose their link (and count it). Panics when
    /// `position` is not below [`len`](Self::len).
    pub fn set_cable(&mut self, position: usize, plugged: bool) {
        self.line.set_cable(position, plugged);
        self.apply_links();
    }

    /// Makes the cable into `port` of slave `position` spoil the next `frames` frames entering
    /// there, one in every `every` ([`line::Line::spoil_port`]). Panics when `position` is not
    /// below [`len`](Self::len) or `port` is no port (below 4).
    pub fn spoil_port(&mut self, position: usize, port: usize, frames: u64, every: u64) {
        self.line.spoil_port(position, port, frames, every);
    }

    /// Lets bus time `now_ns` pass with no frame: every drive's firmware runs up to it (the
    /// motors move, supervision counts missed frames).
    pub fn advance(&mut self, now_ns: u64) {
        for slave in &mut self.slaves {
            slave.poll(now_ns);
            slave.run_ip_stack(now_ns);
        }
    }

    /// Serves an EtherCAT payload (frame header and datagrams) in place at bus time `now_ns`,
    /// through the drives its line reaches, and tells whether it comes back (see [`line`](mod@line)),
    /// then lets the drives' IP stacks run. A malformed frame is refused untouched.
    pub fn process(&mut self, payload: &mut [u8], now_ns: u64) -> Result<line::Delivery, FrameError> {
        let delivery = self.answer(payload, now_ns)?;
        self.run_ip_stacks(now_ns);
        Ok(delivery)
    }

    /// The drives' IP stacks at bus time `now_ns` (see [`VirtualAkd::run_ip_stack`]): for a
    /// server to run once it has sent back the frame [`answer`](Self::answer) served.
    pub fn run_ip_stacks(&mut self, now_ns: u64) {
        for slave in &mut self.slaves {
            slave.run_ip_stack(now_ns);
        }
    }

    /// [`process`](Self::process) without the IP stacks' work: the frame as the ESCs answer it.
    ///
    /// The frame enters each slave at port 0 on its way out, and each slave but the last of
    /// those it reaches at port 1 on its way back, from the slave behind it. A faulty cable
    /// there may spoil it ([`line::Line::spoil_port`]): the ESC counts an invalid frame at that
    /// port and marks the frame, every ESC after it counts a forwarded error, none takes it
    /// (an ESC discards what an invalid frame asked), and the master never gets it.
    pub fn answer(&mut self, payload: &mut [u8], now_ns: u64) -> Result<line::Delivery, FrameError> {
        frame::validate(payload)?;
        if self.line.carry() {
            for slave in &mut self.slaves {
                slave.miss_frame();
            }
            self.advance(now_ns);
            return Ok(line::Delivery::Lost);
        }
        let reach = self.line.reach();
        let last = reach as u64 - 1;
        let mut spoiled = false;
        for (i, slave) in self.slaves.iter_mut().enumerate() {
            if i >= reach {
                slave.miss_frame();
                slave.poll(now_ns);
                continue;
            }
            slave.poll(now_ns);
            if spoiled {
                slave.esc_mut().count_forwarded_error(0);
            } else if self.line.spoils(i, 0) {
                slave.esc_mut().count_invalid_frame(0);
                spoiled = true;
            }
            if spoiled {
                slave.miss_frame();
                continue;
            }
            let i = i as u64;
            let arrival = Arrival {
                port0_ns: now_ns + i * FORWARD_DELAY_NS,
                port1_ns: (i < last).then_some(now_ns + (2 * last - i) * FORWARD_DELAY_NS),
            };
            frame::for_each_datagram_mut(payload, |dg| slave.serve(dg, now_ns, arrival))?;
        }
        for i in (0..reach - 1).rev() {
            let esc = self.slaves[i].esc_mut();
            if spoiled {
                esc.count_forwarded_error(1);
            } else if self.line.spoils(i, 1) {
                esc.count_invalid_frame(1);
                spoiled = true;
            }
        }
        if spoiled {
            self.line.count_spoiled();
            return Ok(line::Delivery::Lost);
        }
        self.line.spoil(payload);
        Ok(line::Delivery::Returned)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ethercat::frame::{Command, FrameBuilder};
    use crate::ethercat::line_health::registers::ErrorCounts;

    /// One datagram through `bus` at `now`: its data and working counter.
    pub(super) fn exchange(
        bus: &mut VirtualBus,
        now: u64,
        command: Command,
        adp: u16,
        ado: u16,
        data: &[u8],
    ) -> (Vec<u8>, u16) {
        served(VirtualBus::process, bus, now, (command, adp, ado), data)
    }

    type Serve = fn(&mut VirtualBus, &mut [u8], u64) -> Result<line::Delivery, FrameError>;

    /// One datagram in a frame that `serve` takes through `bus`: its data and working counter.
    fn served(
        serve: Serve,
        bus: &mut VirtualBus,
        now: u64,
        (command, adp, ado): (Command, u16, u16),
        data: &[u8],
    ) -> (Vec<u8>, u16) {
        let mut buf = [0u8; 1500];
        let mut b = FrameBuilder::new(&mut buf);
        let slot = b.push(command, 0, adp, ado, data).unwrap();
        let len = b.finish();
        serve(bus, &mut buf[..len], now).unwrap();
        (slot.data(&buf[..len]).unwrap().to_vec(), slot.wkc(&buf[..len]).unwrap())
    }

    fn to_preop(bus: &mut VirtualBus) {
        exchange(bus, 0, Command::Bwr, 0, 0x0800, &[0x00, 0x18, 0x00, 0x04, 0x26, 0x00, 0x01, 0x00]);
        exchange(bus, 0, Command::Bwr, 0, 0x0808, &[0x00, 0x1C, 0x00, 0x04, 0x22, 0x00, 0x01, 0x00]);
        exchange(bus, 0, Command::Bwr, 0, 0x0120, &[0x02, 0x00]);
    }

    #[test]
    fn a_line_counts_and_addresses_every_drive() {
        let mut bus = VirtualBus::with_timing(3, Timing::IMMEDIATE);
        assert_eq!(exchange(&mut bus, 0, Command::Brd, 0, 0x0000, &[0, 0]), (vec![0x04, 0x02], 3));
        for i in 0..3u16 {
            exchange(&mut bus, 0, Command::Apwr, 0u16.wrapping_sub(i), 0x0010, &(0x1001 + i).to_le_bytes());
        }
        assert_eq!(exchange(&mut bus, 0, Command::Fprd, 0x1003, 0x0010, &[0, 0]), (vec![0x03, 0x10], 1));
        assert_eq!(exchange(&mut bus, 0, Command::Aprd, 0xFFFF, 0x0110, &[0, 0]).0, vec![0x33, 0x5A]);
        assert_eq!(exchange(&mut bus, 0, Command::Aprd, 0xFFFE, 0x0110, &[0, 0]).0, vec![0x13, 0x56]);
    }

    #[test]
    fn a_broadcast_read_ors_every_drives_value_and_a_configured_read_gives_one() {
        let mut bus = VirtualBus::with_timing(3, Timing::IMMEDIATE);
        for i in 0..3u16 {
            exchange(&mut bus, 0, Command::Apwr, 0u16.wrapping_sub(i), 0x0010, &(0x1001 + i).to_le_bytes());
        }
        // Drive 2 of 3 alone to PreOp (Init 0x01, PreOp 0x02).
        exchange(&mut bus, 0, Command::Fpwr, 0x1002, 0x0800, &[0x00, 0x18, 0x00, 0x04, 0x26, 0x00, 0x01, 0x00]);
        exchange(&mut bus, 0, Command::Fpwr, 0x1002, 0x0808, &[0x00, 0x1C, 0x00, 0x04, 0x22, 0x00, 0x01, 0x00]);
        exchange(&mut bus, 0, Command::Fpwr, 0x1002, 0x0120, &[0x02, 0x00]);
        assert_eq!(exchange(&mut bus, 10_000_000, Command::Brd, 0, 0x0130, &[0, 0]), (vec![0x03, 0x00], 3));
        assert_eq!(exchange(&mut bus, 10_000_000, Command::Fprd, 0x1002, 0x0130, &[0, 0]), (vec![0x02, 0x00], 1));
        assert_eq!(exchange(&mut bus, 10_000_000, Command::Fprd, 0x1003, 0x0130, &[0, 0]), (vec![0x01, 0x00], 1));
        // What the datagram brought is ORed in too, as a later slave on the line finds it.
        assert_eq!(exchange(&mut bus, 10_000_000, Command::Brd, 0, 0x0130, &[0x10, 0x00]), (vec![0x13, 0x00], 3));
    }

    #[test]
    fn a_mailbox_moved_past_the_end_of_memory_is_read_as_far_as_it_exists() {
        // Found by fuzzing (native/fuzz, virtual_akd): SM0 set to start 0xFFFF, 0xFFFF bytes
        // after a message was written and before the firmware took it.
        let mut bus = VirtualBus::new(1);
        to_preop(&mut bus);
        assert_eq!(exchange(&mut bus, 20_000_000, Command::Brd, 0, 0x0130, &[0, 0]).0, vec![0x02, 0x00]);
        let mut message = [0u8; 0x400];
        message[..16].copy_from_slice(&[10, 0, 0, 0, 0, 0x13, 0x00, 0x20, 0x40, 0x00, 0x10, 0x00, 0, 0, 0, 0]);
        assert_eq!(exchange(&mut bus, 20_000_000, Command::Bwr, 0, 0x1800, &message).1, 1);
        assert_eq!(exchange(&mut bus, 20_000_000, Command::Bwr, 0, 0x0800, &[0xFF, 0xFF, 0xFF, 0xFF]).1, 1);
        assert_eq!(exchange(&mut bus, 40_000_000, Command::Brd, 0, 0x0130, &[0, 0]), (vec![0x02, 0x00], 1));
    }

    #[test]
    fn a_mailbox_in_shrunk_after_preop_gets_replies_cut_to_it() {
        // Found by fuzzing (native/fuzz, virtual_akd): SM1 set to 4 bytes in PreOp, then an SDO
        // upload; the reply was sized for a mailbox smaller than its headers.
        let mut bus = VirtualBus::new(1);
        bus.slave_mut(0).warm_up();
        to_preop(&mut bus);
        assert_eq!(exchange(&mut bus, 20_000_000, Command::Brd, 0, 0x0130, &[0, 0]).0, vec![0x02, 0x00]);
        assert_eq!(exchange(&mut bus, 20_000_000, Command::Bwr, 0, 0x080A, &[4, 0]).1, 1);
        let mut message = [0u8; 0x400];
        message[..16].copy_from_slice(&[10, 0, 0, 0, 0, 0x13, 0x00, 0x20, 0x40, 0x08, 0x10, 0x00, 0, 0, 0, 0]);
        assert_eq!(exchange(&mut bus, 20_000_000, Command::Bwr, 0, 0x1800, &message).1, 1);
        assert_eq!(exchange(&mut bus, 40_000_000, Command::Brd, 0, 0x0130, &[0, 0]), (vec![0x02, 0x00], 1));
        // The reply's first four bytes, all that SM1 holds: the mailbox header's length and address.
        assert_eq!(exchange(&mut bus, 40_000_000, Command::Brd, 0, 0x1C00, &[0; 4]), (vec![0x0A, 0, 0, 0], 1));
    }

    #[test]
    fn al_requests_take_the_firmwares_time() {
        let mut bus = VirtualBus::new(1);
        to_preop(&mut bus);
        // Init for 17.5 ms after the request, as a real AKD under TwinCAT (about 16 ms Init, 19 ms PreOp).
        assert_eq!(exchange(&mut bus, 17_499_999, Command::Brd, 0, 0x0130, &[0, 0]).0, vec![0x01, 0x00]);
        assert_eq!(exchange(&mut bus, 17_500_000, Command::Brd, 0, 0x0130, &[0, 0]).0, vec![0x02, 0x00]);
        // SafeOp with the power-up mapping (17 bytes each way) is refused as the real drive does.
        exchange(&mut bus, 18_000_000, Command::Bwr, 0, 0x0810, &[0x00, 0x11, 17, 0, 0x24, 0, 1, 0]);
        exchange(&mut bus, 18_000_000, Command::Bwr, 0, 0x0818, &[0x40, 0x11, 17, 0, 0x20, 0, 1, 0]);
        exchange(&mut bus, 18_000_000, Command::Bwr, 0, 0x0120, &[0x04, 0x00]);
        // Other requests take 4.5 ms (PreOp→SafeOp refused within 4.9 ms in the SOEM capture).
        assert_eq!(exchange(&mut bus, 22_499_999, Command::Brd, 0, 0x0130, &[0, 0]).0, vec![0x02, 0x00]);
        let (status, _) = exchange(&mut bus, 22_500_000, Command::Brd, 0, 0x0130, &[0; 6]);
        assert_eq!(status, vec![0x12, 0, 0, 0, 0x1D, 0]);
    }

    #[test]
    fn init_to_preop_runs_at_a_pace_of_its_own() {
        // A drive of another pace there: Init for 16 ms after the request, other requests as usual.
        let timing = Timing { first_init_to_preop_ns: 16_000_000, ..Timing::REAL_DRIVE };
        let mut bus = VirtualBus::with_timing(1, timing);
        to_preop(&mut bus);
        for t in [4_500_000, 10_000_000, 15_999_999] {
            assert_eq!(exchange(&mut bus, t, Command::Brd, 0, 0x0130, &[0, 0]).0, vec![0x01, 0x00], "at {t} ns");
        }
        // AL control stays the firmware's until then: a second write is refused.
        assert_eq!(exchange(&mut bus, 15_999_999, Command::Bwr, 0, 0x0120, &[0x02, 0x00]).1, 0);
        assert_eq!(exchange(&mut bus, 16_000_000, Command::Brd, 0, 0x0130, &[0, 0]).0, vec![0x02, 0x00]);
        exchange(&mut bus, 16_000_000, Command::Bwr, 0, 0x0120, &[0x01, 0x00]);
        assert_eq!(exchange(&mut bus, 20_499_999, Command::Brd, 0, 0x0130, &[0, 0]).0, vec![0x02, 0x00]);
        assert_eq!(exchange(&mut bus, 20_500_000, Command::Brd, 0, 0x0130, &[0, 0]).0, vec![0x01, 0x00]);
        // The next Init→PreOp takes a later request's 4.5 ms (3-6 ms under TwinCAT).
        exchange(&mut bus, 21_000_000, Command::Bwr, 0, 0x0120, &[0x02, 0x00]);
        assert_eq!(exchange(&mut bus, 25_499_999, Command::Brd, 0, 0x0130, &[0, 0]).0, vec![0x01, 0x00]);
        assert_eq!(exchange(&mut bus, 25_500_000, Command::Brd, 0, 0x0130, &[0, 0]).0, vec![0x02, 0x00]);
        // So does the first after a power cycle once more: 16 ms.
        bus.slave_mut(0).power_cycle();
        to_preop(&mut bus);
        assert_eq!(exchange(&mut bus, 15_999_999, Command::Brd, 0, 0x0130, &[0, 0]).0, vec![0x01, 0x00]);
    }

    #[test]
    fn refuses_init_to_preop_without_mailbox_sync_managers() {
        let mut bus = VirtualBus::with_timing(1, Timing::IMMEDIATE);
        exchange(&mut bus, 0, Command::Bwr, 0, 0x0120, &[0x02, 0x00]);
        assert_eq!(exchange(&mut bus, 1, Command::Brd, 0, 0x0130, &[0; 6]).0, vec![0x11, 0, 0, 0, 0x17, 0]);
        exchange(&mut bus, 2, Command::Bwr, 0, 0x0120, &[0x08, 0x00]);
        exchange(&mut bus, 3, Command::Bwr, 0, 0x0120, &[0x18, 0x00]);
        assert_eq!(exchange(&mut bus, 4, Command::Brd, 0, 0x0130, &[0; 6]).0, vec![0x11, 0, 0, 0, 0x11, 0]);
    }

    #[test]
    fn a_mailbox_round_trip() {
        let mut bus = VirtualBus::new(1);
        to_preop(&mut bus);
        let mut request = vec![0u8; 0x400];
        request[..16].copy_from_slice(&[0x0A, 0, 0, 0, 0, 0x23, 0x00, 0x20, 0x40, 0x00, 0x1C, 0x03, 0, 0, 0, 0]);
        let reply_of_counter =
            |counter: u8| [0x0A, 0, 0, 0, 0, counter, 0x00, 0x30, 0x4F, 0x00, 0x1C, 0x03, 0x03, 0, 0, 0];
        // The first message after power-up is answered 30 ms on (25-50 ms under TwinCAT), the
        // next ones 1 ms on (the SOEM capture's 0.56-2.9 ms).
        for (t, delay, counter) in [(18_000_000, 30_000_000, 0x23), (50_000_000, 1_000_000, 0x33)] {
            request[5] = counter;
            assert_eq!(exchange(&mut bus, t, Command::Bwr, 0, 0x1800, &request).1, 1);
            // SM1 not full (bit 3) until then.
            assert_eq!(exchange(&mut bus, t + delay - 1, Command::Brd, 0, 0x080D, &[0, 0]).0[0] & 0x08, 0);
            assert_eq!(exchange(&mut bus, t + delay, Command::Brd, 0, 0x080D, &[0, 0]).0, vec![0x09, 0x01]);
            let (reply, wkc) = exchange(&mut bus, t + delay + 500_000, Command::Brd, 0, 0x1C00, &[0; 0x400]);
            assert_eq!((&reply[..16], wkc), (&reply_of_counter(counter)[..], 1));
            assert_eq!(exchange(&mut bus, t + delay + 600_000, Command::Brd, 0, 0x080D, &[0, 0]).0, vec![0x02, 0x01]);
        }
    }

    #[test]
    fn a_frame_is_answered_before_the_ip_stack_works() {
        let mut bus = VirtualBus::with_timing(1, Timing::IMMEDIATE);
        to_preop(&mut bus);
        let mut request = vec![0u8; 0x400];
        let parameters = crate::ethercat::eoe::IpParameters { ip: Some([192, 0, 2, 10].into()), ..Default::default() };
        crate::ethercat::eoe::write_set_ip_request(&mut request, 1, &parameters).unwrap();
        exchange(&mut bus, 1, Command::Bwr, 0, 0x1800, &request);
        // The frame that lets the firmware take the request finds SM1 empty (status bit 3 clear):
        // the response is the IP stack's, which runs after the frame went back.
        let sm1_status = (Command::Brd, 0, 0x080D);
        assert_eq!(served(VirtualBus::answer, &mut bus, 2, sm1_status, &[0]).0, [0x00]);
        assert_eq!(served(VirtualBus::answer, &mut bus, 3, sm1_status, &[0]).0, [0x00]);
        bus.run_ip_stacks(3);
        assert_eq!(served(VirtualBus::answer, &mut bus, 4, sm1_status, &[0]).0[0] & 0x08, 0x08);
        // An EoE Set IP Parameter response (frame type 3), result 0.
        let (reply, _) = exchange(&mut bus, 5, Command::Brd, 0, 0x1C00, &[0; 0x400]);
        assert_eq!((reply[5] & 0x0F, reply[6] & 0x0F, &reply[8..10]), (0x02, 0x03, &[0, 0][..]));
    }

    #[test]
    fn a_small_mailbox_is_declared_in_the_sii_and_expected_at_init_to_preop() {
        // Re-encoding with the real size gives the real image: only the mailbox size changes.
        assert_eq!(sii_with_mailbox_size(sii_image::IDENTITY, AKD_MAILBOX_SIZE).unwrap(), sii_image::akd_sii());
        let sii =
            crate::ethercat::sii::Sii::parse(&sii_with_mailbox_size(sii_image::identity(3), 64).unwrap()).unwrap();
        assert_eq!(sii.identity(), sii_image::identity(3));
        let mb = sii.header.standard_mailbox;
        assert_eq!((mb.receive_offset, mb.receive_size, mb.send_offset, mb.send_size), (0x1800, 64, 0x1C00, 64));
        let sms: Vec<_> = sii.sync_managers().iter().map(|sm| sm.length).collect();
        assert_eq!(sms, [64, 64, 0, 0]);
        // Sync managers of the real drive's 1 KiB are refused, 64 bytes accepted.
        let mut bus = VirtualBus::with_mailbox_size(1, Timing::IMMEDIATE, 64).unwrap();
        to_preop(&mut bus);
        assert_eq!(exchange(&mut bus, 1, Command::Brd, 0, 0x0130, &[0; 6]).0, vec![0x11, 0, 0, 0, 0x17, 0]);
        exchange(&mut bus, 2, Command::Bwr, 0, 0x0120, &[0x11, 0x00]);
        exchange(&mut bus, 3, Command::Bwr, 0, 0x0800, &[0x00, 0x18, 64, 0, 0x26, 0x00, 0x01, 0x00]);
        exchange(&mut bus, 3, Command::Bwr, 0, 0x0808, &[0x00, 0x1C, 64, 0, 0x22, 0x00, 0x01, 0x00]);
        exchange(&mut bus, 4, Command::Bwr, 0, 0x0120, &[0x02, 0x00]);
        assert_eq!(exchange(&mut bus, 5, Command::Brd, 0, 0x0130, &[0; 6]).0, vec![0x02, 0, 0, 0, 0, 0]);
    }

    #[test]
    fn a_mailbox_size_out_of_range_is_named() {
        for size in [32, 2048] {
            let Err(e) = VirtualBus::with_mailbox_size(1, Timing::IMMEDIATE, size) else { panic!("{size} accepted") };
            assert!(e.to_string().contains(&format!("{size} bytes: allowed are 64 to 1024")), "{e}");
        }
    }

    /// Payload of one BRD of the AL status.
    fn al_status_frame() -> (Vec<u8>, crate::ethercat::frame::Slot) {
        let mut buf = vec![0u8; 64];
        let mut b = FrameBuilder::new(&mut buf);
        let slot = b.push(Command::Brd, 0, 0, 0x0130, &[0, 0]).unwrap();
        let len = b.finish();
        buf.truncate(len);
        (buf, slot)
    }

    #[test]
    fn a_power_cycled_drive_answers_as_at_power_up() {
        let mut bus = VirtualBus::with_timing(2, Timing::IMMEDIATE);
        exchange(&mut bus, 0, Command::Apwr, 0xFFFF, 0x0010, &0x1002u16.to_le_bytes());
        to_preop(&mut bus);
        exchange(&mut bus, 1, Command::Brd, 0, 0x0130, &[0, 0]);
        bus.slave_mut(1).drive_mut().inject(faults::Fault::SyncLost);
        bus.advance(2);
        assert_eq!(bus.slave(1).al_status().0, AlState::PreOp);
        bus.slave_mut(1).power_cycle();
        assert_eq!(bus.slave(1).al_status(), (AlState::Init, false, 0));
        assert_eq!(bus.slave(1).drive().state(), crate::drive::ds402::State::NotReadyToSwitchOn);
        assert_eq!(bus.slave(1).drive().fault(), None);
        assert_eq!(exchange(&mut bus, 3, Command::Aprd, 0xFFFF, 0x0010, &[0, 0]), (vec![0, 0], 1));
        let fresh = VirtualBus::new(2);
        assert_eq!(bus.slave(1).registers()[0x0800..0x0820], fresh.slave(1).registers()[0x0800..0x0820]);
        assert_ne!(bus.slave(0).registers()[0x0800..0x0820], fresh.slave(0).registers()[0x0800..0x0820]);
        // The other drive kept its state, and the drive its identity and place on the line.
        assert_eq!(bus.slave(0).al_status().0, AlState::PreOp);
        assert_eq!(bus.slave(1).od().get(0x1018, 4), fresh.slave(1).od().get(0x1018, 4));
        assert_eq!(exchange(&mut bus, 3, Command::Aprd, 0xFFFF, 0x0110, &[0, 0]).0, vec![0x13, 0x56]);
    }

    #[test]
    fn a_pulled_cable_ends_the_line_until_plugged_back() {
        let mut bus = VirtualBus::with_timing(3, Timing::IMMEDIATE);
        bus.set_cable(1, false);
        assert_eq!(exchange(&mut bus, 0, Command::Brd, 0, 0x0000, &[0, 0]).1, 1);
        // Drive 0 closed its port 1 (loop closed, no link).
        assert_eq!(exchange(&mut bus, 0, Command::Aprd, 0, 0x0110, &[0, 0]).0, vec![0x13, 0x56]);
        assert_eq!(exchange(&mut bus, 0, Command::Aprd, 0xFFFF, 0x0000, &[0, 0]).1, 0);
        bus.set_cable(1, true);
        assert_eq!(exchange(&mut bus, 0, Command::Brd, 0, 0x0000, &[0, 0]).1, 3);
        assert_eq!(exchange(&mut bus, 0, Command::Aprd, 0, 0x0110, &[0, 0]).0, vec![0x33, 0x5A]);
        // With the first cable out no ESC returns anything.
        bus.set_cable(0, false);
        let (mut frame, _) = al_status_frame();
        assert_eq!(bus.process(&mut frame, 0), Ok(line::Delivery::Lost));
    }

    #[test]
    fn bursts_lose_corrupt_and_miscount_exactly_the_frames_asked() {
        let mut bus = VirtualBus::with_timing(3, Timing::IMMEDIATE);
        let (sent, slot) = al_status_frame();
        let serve = |bus: &mut VirtualBus| {
            let mut frame = sent.clone();
            let delivery = bus.process(&mut frame, 0).unwrap();
            (delivery, frame::validate(&frame).is_ok(), slot.wkc(&frame).unwrap())
        };
        bus.start_burst(line::Burst::Lost(2));
        bus.start_burst(line::Burst::Corrupted(1));
        bus.start_burst(line::Burst::WrongWkc(2));
        use line::Delivery::{Lost, Returned};
        assert_eq!(serve(&mut bus), (Lost, true, 0));
        assert_eq!(serve(&mut bus), (Lost, true, 0));
        // The master's codec refuses the corrupted reply: its length no longer adds up.
        assert_eq!(serve(&mut bus), (Returned, false, 2));
        assert_eq!(serve(&mut bus), (Returned, true, 2));
        assert_eq!(serve(&mut bus), (Returned, true, 3));
        assert_eq!(bus.line().pending(), (0, 0, 0));
        // The line counts what it did; the wrong working counter and the corruption hit the
        // same (third) reply.
        let counts = line::LineCounts { frames: 5, lost: 2, corrupted: 1, wrong_wkc: 2, spoiled: 0 };
        assert_eq!(bus.line().counts(), counts);
        bus.set_cable(0, false);
        assert_eq!(serve(&mut bus), (Lost, true, 0));
        assert_eq!(bus.line().counts(), line::LineCounts { frames: 6, lost: 3, ..counts });
    }

    /// Slave `position`'s error counters as counted since power-up.
    fn counted(bus: &VirtualBus, position: usize) -> ErrorCounts<u64> {
        bus.at(position).esc().counted()
    }

    /// The error counters' registers of slave `position`, read by the master.
    fn counter_registers(bus: &mut VirtualBus, position: u16) -> ErrorCounts<u8> {
        let (block, wkc) = exchange(bus, 0, Command::Aprd, 0u16.wrapping_sub(position), 0x0300, &[0; 20]);
        assert_eq!(wkc, 1);
        ErrorCounts::decode(&block.try_into().unwrap())
    }

    #[test]
    fn a_bad_cable_into_a_port_0_counts_there_and_forwarded_after_it_and_loses_the_frame() {
        let mut bus = VirtualBus::with_timing(6, Timing::IMMEDIATE);
        let (sent, _) = al_status_frame();
        // Slave 2 to slave 3: every second frame entering slave 3's port 0 spoiled, twice.
        bus.spoil_port(3, 0, 2, 2);
        let deliveries: Vec<_> = (0..6).map(|_| bus.process(&mut sent.clone(), 0).unwrap()).collect();
        use line::Delivery::{Lost, Returned};
        assert_eq!(deliveries, [Returned, Lost, Returned, Lost, Returned, Returned]);
        assert_eq!(bus.line().counts().spoiled, 2);
        assert_eq!(counted(&bus, 3).ports[0].invalid_frames, 2);
        assert_eq!(counted(&bus, 3).processing_unit, 2);
        // After it on the way out, then back through every port 1 to the master.
        for (slave, port) in [(4, 0), (5, 0), (4, 1), (3, 1), (2, 1), (1, 1), (0, 1)] {
            assert_eq!(counted(&bus, slave).ports[port].forwarded_errors, 2, "slave {slave} port {port}");
        }
        assert_eq!(counted(&bus, 2).ports[0], Default::default(), "in front of the fault: nothing");
        assert_eq!(counted(&bus, 5).ports[1], Default::default(), "the last slave's port 1 is closed");
        // The registers say the same.
        assert_eq!(counter_registers(&mut bus, 4).ports[0].forwarded_errors, 2);
        assert_eq!(counter_registers(&mut bus, 3).processing_unit, 2);
    }

    #[test]
    fn a_bad_cable_into_a_port_1_is_the_return_path_from_the_slave_behind() {
        let mut bus = VirtualBus::with_timing(6, Timing::IMMEDIATE);
        let (sent, slot) = al_status_frame();
        bus.spoil_port(3, 1, 1, 1);
        let mut frame = sent.clone();
        assert_eq!(bus.process(&mut frame, 0), Ok(line::Delivery::Lost));
        assert_eq!(counted(&bus, 3).ports[1].invalid_frames, 1);
        assert_eq!(counted(&bus, 3).processing_unit, 0, "frames from port 1 do not pass the processing unit");
        for slave in 0..3 {
            assert_eq!(counted(&bus, slave).ports[1].forwarded_errors, 1);
        }
        for slave in 4..6 {
            assert_eq!(counted(&bus, slave), ErrorCounts::default(), "slave {slave} served it unspoiled");
        }
        // Every slave had served it on its way out: the drives took it, the master did not.
        let mut frame = sent.clone();
        assert_eq!(bus.process(&mut frame, 0), Ok(line::Delivery::Returned));
        assert_eq!(slot.wkc(&frame).unwrap(), 6);
    }

    #[test]
    fn a_write_clears_the_counters_its_register_names_and_a_read_write_reads_them_first() {
        let mut bus = VirtualBus::with_timing(3, Timing::IMMEDIATE);
        let (sent, _) = al_status_frame();
        bus.spoil_port(1, 0, 300, 1);
        for _ in 0..300 {
            bus.process(&mut sent.clone(), 0).unwrap();
        }
        bus.set_cable(2, false);
        bus.set_cable(2, true);
        let counts = counter_registers(&mut bus, 1);
        // 300 counted, the registers stopped at 0xFF.
        assert_eq!(
            (counts.ports[0].invalid_frames, counts.processing_unit, counts.ports[1].lost_links),
            (0xFF, 0xFF, 1)
        );
        assert_eq!(counted(&bus, 1).ports[0].invalid_frames, 300);
        // A write of the processing unit's counter clears it alone.
        exchange(&mut bus, 0, Command::Apwr, 0xFFFF, 0x030C, &[0]);
        let counts = counter_registers(&mut bus, 1);
        assert_eq!((counts.ports[0].invalid_frames, counts.processing_unit, counts.ports[1].lost_links), (0xFF, 0, 1));
        // A read-write of the whole block reads what it clears.
        let (read, wkc) = exchange(&mut bus, 0, Command::Aprw, 0xFFFF, 0x0300, &[0; 20]);
        assert_eq!((read[0], read[0x10 + 1], wkc), (0xFF, 1, 3));
        assert_eq!(counter_registers(&mut bus, 1), ErrorCounts::default());
        assert_eq!(counted(&bus, 1).ports[0].invalid_frames, 300, "what it counted since power-up stays");
    }

    #[test]
    fn a_link_lost_counts_at_both_ends_of_its_cable_and_a_power_cycle_at_the_neighbours() {
        let mut bus = VirtualBus::with_timing(3, Timing::IMMEDIATE);
        bus.set_cable(2, false);
        assert_eq!(exchange(&mut bus, 0, Command::Aprd, 0xFFFF, 0x0110, &[0, 0]).0, vec![0x13, 0x56]);
        bus.set_cable(2, true);
        assert_eq!(exchange(&mut bus, 0, Command::Aprd, 0xFFFF, 0x0110, &[0, 0]).0, vec![0x33, 0x5A]);
        assert_eq!((counted(&bus, 1).ports[1].lost_links, counted(&bus, 2).ports[0].lost_links), (1, 1));
        bus.power_cycle(1);
        assert_eq!((counted(&bus, 0).ports[1].lost_links, counted(&bus, 2).ports[0].lost_links), (1, 2));
        assert_eq!(counted(&bus, 1), ErrorCounts::default(), "a fresh ESC");
        assert_eq!(exchange(&mut bus, 0, Command::Aprd, 0xFFFF, 0x0110, &[0, 0]).0, vec![0x33, 0x5A]);
    }

    #[test]
    fn terminals_count_at_their_escs_ports_too() {
        let line = "ek1100,el1004,el2004,akd".parse().unwrap();
        let mut bus = VirtualBus::of_line(&line, Timing::IMMEDIATE).unwrap();
        let (sent, _) = al_status_frame();
        bus.spoil_port(2, 0, 1, 1);
        assert_eq!(bus.process(&mut sent.clone(), 0), Ok(line::Delivery::Lost));
        assert_eq!(counted(&bus, 2).ports[0].invalid_frames, 1);
        assert_eq!(counted(&bus, 3).ports[0].forwarded_errors, 1);
        assert_eq!(counted(&bus, 0).ports[1].forwarded_errors, 1, "the EK1100's E-bus port");
        // The EL2004's ET1200 has no port 2: it never has a link there.
        assert!(!bus.at(2).esc().has_port(2) && bus.at(2).esc().has_port(3));
        assert!(bus.at(0).esc().has_port(2) && !bus.at(0).esc().link(2));
    }

    #[test]
    fn malformed_frames_are_refused_untouched() {
        let mut bus = VirtualBus::new(2);
        let mut garbage = [0x0C, 0x10, 0x07, 0x00, 0, 0, 0x30, 0x01, 0x02];
        let before = garbage;
        assert!(bus.process(&mut garbage, 0).is_err());
        assert_eq!(garbage, before);
        assert_eq!(bus.line().counts().frames, 0, "not carried");
    }
}
