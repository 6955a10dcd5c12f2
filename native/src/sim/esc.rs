//! The EtherCAT slave controller (ESC) of a virtual slave: its register and RAM space and the
//! datagram service as the hardware does it, without the firmware (the PDI side, in
//! [`super::VirtualAkd`] and [`super::terminal`]).
//!
//! What differs from one ESC to another is its [`EscHardware`]: the AKD's register values at
//! power-up are the real drive's, read in the SOEM capture and under TwinCAT: type 0x04
//! revision 0x02 build 0x0043 (an ESC20-class controller with 3 FMMUs, 4 sync managers and 4 KiB
//! of RAM at 0x1000–0x1FFF), port descriptor 0x0F, features 0x0184, DL control byte 2 (RX FIFO
//! size) 0x07, DL status 0x5613, PDI control 0x0C08, SII control 0x0020 (EEPROM emulated by the
//! PDI, 4-byte reads); the Beckhoff terminals' ET1100 and ET1200 are described in
//! [`super::esc_hardware`]. What the hardware does by itself is here: the SII interface reading
//! the EEPROM image (at once where the PDI emulates it, after the EEPROM's read time where it is
//! real), DC receive-time latching and the system time, the sync managers' buffer protection,
//! FMMU mapping of logical datagrams bit by bit, the AL control register behaving like a mailbox
//! (a second write before the firmware read the first is refused, as the real drive refuses
//! SOEM's quick second write of 0x0120), or, where the EEPROM sets device emulation (PDI
//! control bit 8, the terminals without a processor), AL control copied to AL status at once;
//! and an ET1200's digital output register 0x0F00, which a sync manager may guard as it guards
//! process RAM.
//!
//! Its ports are those its port descriptor names, each with a link or not: the DL status shows
//! them (a port with a link open with communication, one without closed), a link lost at a port
//! whose loop is on auto counts in its lost link counter, and the frames a line carries count in
//! the error counters as their path through the ports meets a fault (see
//! [`crate::ethercat::line_health`] and [`super::VirtualBus`]): an invalid frame at the port it
//! entered by, a frame another ESC marked invalid as a forwarded error, either at port 0 also in
//! the processing unit's counter. Each counter stops at 0xFF and is cleared by a write as the
//! ESC's registers say; beside the registers the ESC keeps what it counted since power-up,
//! never cleared, for a test to compare a master's counts with.

use crate::ethercat::frame::{Addressing, Command, DatagramMut};
use crate::ethercat::line_health::registers::{cleared_by_write, Counter, DlStatus, ErrorCounts, PORTS};
use crate::ethercat::registers::{self as reg, fmmu_reg, sii_reg, sm_reg};
pub use crate::sim::esc_hardware::RAM_START;
use crate::sim::esc_hardware::{EscHardware, SiiInterface};
use crate::sim::sync_manager::{self, SyncManager, CONTROL_WATCHDOG, SM_COUNT};

/// DL control byte 2 at power-up: the RX FIFO size, 7 (the ESC's default, no reduction).
const DL_CONTROL_FIFO_SIZE: u8 = 0x07;
/// Size of the address space a datagram can reach: ADO up to 0xFFFF plus its length, which
/// the frame header's 11-bit length bounds (a link may bring a frame longer than Ethernet's).
const SPACE: usize = 0x10000 + 0x07FF;
/// An ET1200's digital output data (0x0F00-0x0F03), where a digital I/O PDI takes its outputs.
pub const DIGITAL_OUTPUTS: std::ops::Range<usize> = 0x0F00..0x0F04;
/// PDI control (0x0140) low byte of a digital I/O PDI.
const PDI_DIGITAL_IO: u16 = 0x04;
/// PDI control (0x0140) bit 8: device emulation, AL control copied to AL status by the ESC.
pub const PDI_DEVICE_EMULATION: u16 = 0x0100;
/// AL control bits an ESC in device emulation copies to AL status: the state and the error
/// acknowledge, which then reads as the error flag.
const AL_MIRRORED: u16 = 0x001F;
/// ECAT event request (0x0210) bit 2: the DL status changed, until the master reads it.
const DL_STATUS_EVENT: u8 = 0x04;

/// What the firmware has to react to after a datagram: the ESC raises these as events.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Events {
    /// AL control was written with this value.
    pub al_control: Option<u16>,
    /// The master completed a write of the mailbox-out buffer (SM0).
    pub mailbox_written: bool,
    /// The master completed a read of the mailbox-in buffer (SM1).
    pub mailbox_read: bool,
    /// The master toggled SM1's repeat request.
    pub repeat_request: bool,
    /// The master completed a write of the output buffer (SM2).
    pub outputs_written: bool,
    /// That write restarts the process-data watchdog (SM2 control bit 6).
    pub watchdog_trigger: bool,
}

/// When a frame passes this ESC, in the ESC's local clock (ns).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Arrival {
    /// The frame reaches port 0.
    pub port0_ns: u64,
    /// The frame comes back at port 1 from the following drives (none for the last drive).
    pub port1_ns: Option<u64>,
}

/// The register and RAM space of one ESC.
pub struct Esc {
    hardware: EscHardware,
    memory: Box<[u8]>,
    sii: Vec<u8>,
    al_control_locked: bool,
    /// Local time until which an EEPROM read keeps the SII interface busy.
    sii_busy_until_ns: u64,
    events: Events,
    /// Which ports have a link.
    links: [bool; PORTS],
    /// What the error counters counted since power-up, never cleared.
    counted: ErrorCounts<u64>,
}

/// Whether the master may write the byte at `addr` of an ESC whose process RAM ends at
/// `ram_end` and whose digital outputs, if any, the master writes (ETG.1000.4 register access
/// types, as implemented by Beckhoff ESCs; most identification and status registers are
/// read-only).
fn master_writable(addr: usize, ram_end: usize, digital_outputs: bool) -> bool {
    match addr {
        0x0010..=0x0011 | 0x0100..=0x0103 | 0x0108..=0x0109 | 0x0120..=0x0121 | 0x0200..=0x0201 => true,
        0x0400..=0x0401 | 0x0410..=0x0411 | 0x0420..=0x0421 | 0x0500 | 0x0502..=0x050F => true,
        0x0600..=0x06FF | 0x0920..=0x092B | 0x0930..=0x0935 | 0x0980..=0x0981 => true,
        0x0990..=0x0997 | 0x09A0..=0x09A7 => true,
        0x0800..=0x087F => !matches!((addr - 0x0800) % 8, 5 | 7),
        _ => (RAM_START..ram_end).contains(&addr) || (digital_outputs && DIGITAL_OUTPUTS.contains(&addr)),
    }
}

fn touches(at: usize, len: usize, register: u16, register_len: usize) -> bool {
    let r = register as usize;
    at < r + register_len && r < at + len
}

impl Esc {
    /// The AKD's ESC at power-up serving the EEPROM `sii`; `has_successor` tells whether another
    /// slave follows on port 1 (it sets the DL status).
    pub fn new(sii: Vec<u8>, has_successor: bool) -> Self {
        Self::with_hardware(crate::sim::esc_hardware::AKD, sii, has_successor)
    }

    /// An ESC of kind `hardware` at power-up serving the EEPROM `sii`; `has_successor` as for
    /// [`new`](Self::new).
    pub fn with_hardware(hardware: EscHardware, sii: Vec<u8>, has_successor: bool) -> Self {
        let mut memory = vec![0u8; SPACE].into_boxed_slice();
        memory[0x0000] = hardware.esc_type;
        memory[0x0001] = hardware.revision;
        memory[0x0002..0x0004].copy_from_slice(&hardware.build.to_le_bytes());
        memory[0x0004] = hardware.fmmus;
        memory[0x0005] = hardware.sync_managers;
        memory[0x0006] = hardware.ram_kib;
        memory[0x0007] = hardware.port_descriptor;
        memory[0x0008..0x000A].copy_from_slice(&hardware.features.to_le_bytes());
        memory[reg::DL_CONTROL as usize + 2] = DL_CONTROL_FIFO_SIZE;
        let word = |w: usize| sii.get(2 * w..2 * w + 2).map_or(0, |b| u16::from_le_bytes([b[0], b[1]]));
        // EEPROM word 4: the configured station alias.
        memory[0x0012..0x0014].copy_from_slice(&word(4).to_le_bytes());
        memory[0x0130] = 0x01;
        let pdi_control = hardware.pdi_control.unwrap_or_else(|| word(0));
        memory[0x0140..0x0142].copy_from_slice(&pdi_control.to_le_bytes());
        memory[0x0400..0x0402].copy_from_slice(&0x09C2u16.to_le_bytes());
        memory[0x0420..0x0422].copy_from_slice(&1000u16.to_le_bytes());
        let mut esc = Esc {
            hardware,
            memory,
            sii,
            al_control_locked: false,
            sii_busy_until_ns: 0,
            events: Events::default(),
            links: [true, has_successor, false, false],
            counted: ErrorCounts::default(),
        };
        esc.refresh_sii_status(0);
        esc.refresh_dl_status();
        // What the DL status is at power-up is no change of it.
        esc.memory[reg::ECAT_EVENT_REQUEST as usize] = 0;
        esc
    }

    /// The link on port 0 came up after the ESC's reset, as it does for a slave behind another
    /// one at power-up: the DL status changed, and the event says so until the master reads
    /// the DL status (the EL1004 behind an EK1100 showed it in the SOEM capture, through every
    /// datagram's IRQ word once SOEM set the event mask).
    pub fn link_came_up(&mut self) {
        self.memory[reg::ECAT_EVENT_REQUEST as usize] |= DL_STATUS_EVENT;
    }

    /// What kind of ESC it is.
    pub fn hardware(&self) -> &EscHardware {
        &self.hardware
    }

    /// Whether the EEPROM set device emulation (PDI control bit 8): the ESC itself copies AL
    /// control to AL status, there being no processor to do it.
    pub fn device_emulation(&self) -> bool {
        self.u16_at(reg::PDI_CONTROL) & PDI_DEVICE_EMULATION != 0
    }

    /// Whether the EEPROM set a digital I/O PDI: outputs from 0x0F00, inputs into 0x1000.
    pub fn digital_io(&self) -> bool {
        self.u16_at(reg::PDI_CONTROL) & 0x00FF == PDI_DIGITAL_IO
    }

    /// The first address a sync manager guards: process RAM, and an ET1200's digital outputs
    /// before it where its PDI is digital I/O.
    fn guarded_start(&self) -> usize {
        if self.digital_io() {
            DIGITAL_OUTPUTS.start
        } else {
            RAM_START
        }
    }

    /// The EEPROM it serves.
    pub fn sii(&self) -> &[u8] {
        &self.sii
    }

    /// Whether `port` has a link (a cable plugged in with a powered slave at its other end, or
    /// pulled out): the DL status shows it, and a link lost at a port whose loop is on auto (or
    /// auto-close, DL control) counts in its lost link counter. A port the ESC lacks never
    /// has one.
    pub fn set_link(&mut self, port: usize, up: bool) {
        let up = up && self.has_port(port);
        let was = std::mem::replace(&mut self.links[port], up);
        let loop_setting = self.memory[reg::DL_CONTROL as usize + 1] >> (2 * port) & 0x03;
        if was && !up && loop_setting <= 1 {
            self.count(Counter::LostLinks(port));
        }
        self.refresh_dl_status();
    }

    /// The links its ports have as it powers up: no change of a link, nothing counted.
    pub fn power_up_links(&mut self, links: [bool; PORTS]) {
        self.links = std::array::from_fn(|port| links[port] && self.has_port(port));
        self.refresh_dl_status();
    }

    /// Whether `port` has a link.
    pub fn link(&self, port: usize) -> bool {
        self.links[port]
    }

    /// Whether the ESC has `port` (its port descriptor names it).
    pub fn has_port(&self, port: usize) -> bool {
        port < PORTS && crate::ethercat::line_health::registers::PortDescriptor(self.hardware.port_descriptor).has(port)
    }

    fn refresh_dl_status(&mut self) {
        let dl_status = DlStatus::with_links(self.hardware.dl_status_pdi, self.links).0;
        if dl_status != self.u16_at(reg::DL_STATUS) {
            self.memory[reg::ECAT_EVENT_REQUEST as usize] |= DL_STATUS_EVENT;
        }
        self.memory[reg::DL_STATUS as usize..reg::DL_STATUS as usize + 2].copy_from_slice(&dl_status.to_le_bytes());
    }

    /// Counts one event in `counter`: its register stops at 0xFF, what it counted since
    /// power-up goes on.
    pub fn count(&mut self, counter: Counter) {
        let at = usize::from(counter.register());
        self.memory[at] = self.memory[at].saturating_add(1);
        *self.counted.get_mut(counter) += 1;
    }

    /// A frame entered `port` invalid, this ESC the first to find it so (a CRC error): counted
    /// at the port, and in the processing unit when it entered port 0 (the one frames pass the
    /// processing unit from).
    pub fn count_invalid_frame(&mut self, port: usize) {
        self.count(Counter::InvalidFrames(port));
        if port == 0 {
            self.count(Counter::ProcessingUnit);
        }
    }

    /// A frame entered `port` marked invalid by an ESC before: a forwarded error, at port 0
    /// also the processing unit's.
    pub fn count_forwarded_error(&mut self, port: usize) {
        self.count(Counter::ForwardedErrors(port));
        if port == 0 {
            self.count(Counter::ProcessingUnit);
        }
    }

    /// What the error counters counted since power-up, never cleared (their registers stop at
    /// 0xFF and a master clears them).
    pub fn counted(&self) -> ErrorCounts<u64> {
        self.counted
    }

    /// The whole space, as the firmware (PDI) sees it.
    pub fn memory(&self) -> &[u8] {
        &self.memory
    }

    /// The whole space for the firmware (PDI) to write, e.g. AL status or the mailbox-in buffer.
    pub fn memory_mut(&mut self) -> &mut [u8] {
        &mut self.memory
    }

    /// A little-endian 16-bit register.
    pub fn u16_at(&self, addr: u16) -> u16 {
        let a = addr as usize;
        u16::from_le_bytes([self.memory[a], self.memory[a + 1]])
    }

    /// The events raised since the last call.
    pub fn take_events(&mut self) -> Events {
        std::mem::take(&mut self.events)
    }

    /// The firmware has read AL control: the master may write it again.
    pub fn release_al_control(&mut self) {
        self.al_control_locked = false;
    }

    /// Serves one datagram as it passes this ESC: addressing, memory access, ADP increment
    /// and working counter.
    pub fn serve(&mut self, dg: &mut DatagramMut<'_>, arrival: Arrival) {
        // Every ESC a datagram passes ORs its unmasked ECAT events into the IRQ word, as they
        // stand when the datagram's header passes.
        dg.header.irq |= self.u16_at(reg::ECAT_EVENT_REQUEST) & self.u16_at(reg::ECAT_EVENT_MASK);
        let h = dg.header;
        let command = h.command;
        let (did_read, did_write) = match command.addressing() {
            Addressing::AutoIncrement => {
                dg.header.adp = h.adp.wrapping_add(1);
                self.physical(dg, h.adp == 0, arrival)
            }
            Addressing::Configured => {
                let alias_enabled = self.memory[0x0103] & 0x01 != 0;
                let addressed = h.adp == self.u16_at(reg::STATION_ADDRESS)
                    || (alias_enabled && h.adp == self.u16_at(reg::STATION_ALIAS));
                self.physical(dg, addressed, arrival)
            }
            Addressing::Broadcast => {
                dg.header.adp = h.adp.wrapping_add(1);
                self.physical(dg, true, arrival)
            }
            Addressing::Logical => self.logical(dg),
            Addressing::None => (false, false),
        };
        dg.wkc = dg.wkc.wrapping_add(command.wkc_increment(did_read, did_write));
    }

    /// A physical access at ADO. ARMW/FRMW read at the addressed drive and write at all others.
    fn physical(&mut self, dg: &mut DatagramMut<'_>, addressed: bool, arrival: Arrival) -> (bool, bool) {
        let command = dg.header.command;
        let (read, write) = match command {
            Command::Armw | Command::Frmw => (addressed, !addressed),
            _ if addressed => (command.reads(), command.writes()),
            _ => return (false, false),
        };
        let broadcast = command.addressing() == Addressing::Broadcast;
        let at = dg.header.ado as usize;
        let len = dg.data.len();
        if self.hardware.lacks_any(at, len) {
            return (false, false);
        }
        let (read, write) = self.gate(at, len, read, write);
        let write = write && !(self.al_control_locked && touches(at, len, reg::AL_CONTROL, 2));
        if read {
            self.refresh_system_time(at, len, arrival);
            if touches(at, len, reg::SII_CONTROL, 2) {
                self.refresh_sii_status(arrival.port0_ns);
            }
        }
        let repeat_before = old_repeat_bits(self, at, len);
        let (ram_end, digital_outputs) = (self.hardware.ram_end(), self.digital_io());
        for (i, byte) in dg.data.iter_mut().enumerate() {
            let addr = at + i;
            let old = self.memory[addr];
            if write && master_writable(addr, ram_end, digital_outputs) {
                self.memory[addr] = *byte;
            }
            if read {
                // A broadcast read ORs every slave's value into the datagram (ETG.1000.4:
                // BRD, BRW), so a master reads in one datagram whether any slave has a bit set.
                *byte = if broadcast { *byte | old } else { old };
            }
        }
        if write {
            self.after_register_write(at, dg, arrival, repeat_before);
            self.after_ram_access(at, len, false);
        }
        if read {
            self.after_ram_access(at, len, true);
            if touches(at, len, reg::DL_STATUS, 2) {
                self.memory[reg::ECAT_EVENT_REQUEST as usize] &= !DL_STATUS_EVENT;
            }
        }
        (read, write)
    }

    /// Whether a read and a write of `[at, at + len)` pass the sync managers: a full mailbox
    /// refuses writes from the master, an empty one refuses reads, and a buffer the firmware
    /// deactivated refuses both. Memory no enabled sync manager covers is free, and so are the
    /// registers below [`RAM_START`] (but an ET1200's digital outputs): an ESC's sync managers
    /// work on process memory only, so a sync manager a master set over the registers (a
    /// broadcast write may do that) never blocks them.
    fn gate(&self, at: usize, len: usize, read: bool, write: bool) -> (bool, bool) {
        let (mut read, mut write) = (read, write);
        if at + len <= self.guarded_start() {
            return (read, write);
        }
        for n in 0..self.hardware.sync_managers {
            let sm = SyncManager::read(&self.memory, n);
            if sm.activate & sync_manager::ACTIVATE_ENABLE == 0 || sm.length == 0 || !sm.overlaps(at, len) {
                continue;
            }
            if !sm.active() {
                return (false, false);
            }
            if sm.is_mailbox() {
                if sm.master_writes() {
                    write &= !sm.full();
                    read = false;
                } else {
                    read &= sm.full();
                    write = false;
                }
            }
        }
        (read, write)
    }

    /// Completes transfers: the last byte of a buffer written or read by the master.
    fn after_ram_access(&mut self, at: usize, len: usize, was_read: bool) {
        if at + len <= self.guarded_start() {
            return;
        }
        for n in 0..self.hardware.sync_managers {
            let sm = SyncManager::read(&self.memory, n);
            if !sm.active() || !sm.covers_last_byte(at, len) || sm.master_writes() == was_read {
                continue;
            }
            match (sm.is_mailbox(), was_read) {
                (true, false) => {
                    sync_manager::mark_written(&mut self.memory, n);
                    self.events.mailbox_written = true;
                }
                (true, true) => {
                    sync_manager::mark_read(&mut self.memory, n);
                    self.events.mailbox_read = true;
                }
                (false, false) => {
                    self.events.outputs_written = true;
                    self.events.watchdog_trigger |= sm.control & CONTROL_WATCHDOG != 0;
                }
                (false, true) => {}
            }
        }
    }

    /// What the hardware does when particular registers are written.
    fn after_register_write(&mut self, at: usize, dg: &DatagramMut<'_>, arrival: Arrival, repeat_bits_before: u8) {
        let len = dg.data.len();
        let value_at = |addr: u16| (addr as usize).checked_sub(at).and_then(|i| dg.data.get(i)).copied();
        if touches(at, len, reg::AL_CONTROL, 2) {
            let control = self.u16_at(reg::AL_CONTROL);
            if self.device_emulation() {
                let status = (self.u16_at(reg::AL_STATUS) & !AL_MIRRORED) | (control & AL_MIRRORED);
                self.memory[reg::AL_STATUS as usize..reg::AL_STATUS as usize + 2]
                    .copy_from_slice(&status.to_le_bytes());
            } else {
                self.al_control_locked = true;
                self.events.al_control = Some(control);
            }
        }
        for cleared in cleared_by_write(at, len) {
            self.memory[cleared].fill(0);
        }
        if touches(at, len, reg::SII_CONTROL, 2) {
            self.sii_command(arrival.port0_ns);
        }
        if old_repeat_bits(self, at, len) != repeat_bits_before {
            self.events.repeat_request = true;
        }
        if touches(at, len, reg::DC_RECEIVE_TIME_PORT0, 4) {
            self.latch_receive_times(arrival);
        }
        if touches(at, len, reg::DC_SYSTEM_TIME, 8) {
            let received: [Option<u8>; 8] = std::array::from_fn(|i| value_at(reg::DC_SYSTEM_TIME + i as u16));
            self.compare_system_time(&received, arrival);
        }
    }

    /// Executes the command written to SII control at local time `now_ns`: a read copies 4
    /// bytes (8 from a real EEPROM) of the EEPROM at the word address into SII data, at once
    /// where the PDI emulates the EEPROM, the interface busy for the EEPROM's read time
    /// otherwise; other commands are refused with the error bit, as the EEPROM cannot be written
    /// here. A command while a read is busy is ignored, as the ESC ignores it.
    fn sii_command(&mut self, now_ns: u64) {
        let control = self.u16_at(reg::SII_CONTROL);
        if now_ns < self.sii_busy_until_ns {
            self.refresh_sii_status(now_ns);
            return;
        }
        let mut error = 0;
        if control & sii_reg::CMD_READ != 0 {
            let a = reg::SII_ADDRESS as usize;
            let word = u32::from_le_bytes([self.memory[a], self.memory[a + 1], self.memory[a + 2], self.memory[a + 3]]);
            let (bytes, read_ns) = match self.hardware.sii {
                SiiInterface::Emulated => (4, 0),
                SiiInterface::Eeprom { read_ns, .. } => (8, read_ns),
            };
            for i in 0..bytes {
                let byte = (word as usize).checked_mul(2).and_then(|b| self.sii.get(b + i)).copied().unwrap_or(0xFF);
                self.memory[reg::SII_DATA as usize + i] = byte;
            }
            self.sii_busy_until_ns = now_ns + read_ns;
        } else if control & (sii_reg::CMD_WRITE | sii_reg::CMD_RELOAD) != 0 {
            error = sii_reg::ERROR_ACK;
        }
        let status = self.sii_status(now_ns) | (control & sii_reg::WRITE_ENABLE) | error;
        let busy = if now_ns < self.sii_busy_until_ns { control & sii_reg::CMD_READ } else { 0 };
        self.memory[reg::SII_CONTROL as usize..reg::SII_CONTROL as usize + 2]
            .copy_from_slice(&(status | busy).to_le_bytes());
    }

    /// SII control as the interface shows it at local time `now_ns`, without the command and
    /// write-enable bits the master wrote: the read size, emulation, busy.
    fn sii_status(&self, now_ns: u64) -> u16 {
        match self.hardware.sii {
            SiiInterface::Emulated => sii_reg::EMULATION,
            SiiInterface::Eeprom { bit4_below_safeop, .. } => {
                let below_safeop =
                    self.memory[reg::AL_STATUS as usize] & 0x0F < crate::ethercat::al::AlState::SafeOp as u8;
                let bit4 = if bit4_below_safeop && below_safeop { 0x0010 } else { 0 };
                let busy = if now_ns < self.sii_busy_until_ns { sii_reg::BUSY } else { 0 };
                sii_reg::READ_8_BYTES | bit4 | busy
            }
        }
    }

    /// Brings SII control up to local time `now_ns` before the master reads it: a finished read
    /// clears busy and its command.
    fn refresh_sii_status(&mut self, now_ns: u64) {
        let a = reg::SII_CONTROL as usize;
        let kept = self.u16_at(reg::SII_CONTROL) & (sii_reg::WRITE_ENABLE | sii_reg::ERROR_ACK);
        let busy = self.sii_status(now_ns) & sii_reg::BUSY != 0;
        let command = if busy { self.u16_at(reg::SII_CONTROL) & sii_reg::CMD_READ } else { 0 };
        let value = self.sii_status(now_ns) | kept | command;
        self.memory[a..a + 2].copy_from_slice(&value.to_le_bytes());
    }

    fn system_time_offset(&self) -> u64 {
        let a = reg::DC_SYSTEM_TIME_OFFSET as usize;
        u64::from_le_bytes(self.memory[a..a + 8].try_into().expect("8 bytes"))
    }

    fn system_time(&self, local_ns: u64) -> u64 {
        local_ns.wrapping_add(self.system_time_offset())
    }

    fn refresh_system_time(&mut self, at: usize, len: usize, arrival: Arrival) {
        if touches(at, len, reg::DC_SYSTEM_TIME, 8) {
            let t = self.system_time(arrival.port0_ns);
            let a = reg::DC_SYSTEM_TIME as usize;
            self.memory[a..a + 8].copy_from_slice(&t.to_le_bytes());
        }
    }

    /// A write to receive time port 0 latches when the frame passed each port, and the local
    /// time of the processing unit (0x0918).
    fn latch_receive_times(&mut self, arrival: Arrival) {
        let a = reg::DC_RECEIVE_TIME_PORT0 as usize;
        self.memory[a..a + 4].copy_from_slice(&(arrival.port0_ns as u32).to_le_bytes());
        let port1 = arrival.port1_ns.map_or(0, |t| t as u32);
        self.memory[a + 4..a + 8].copy_from_slice(&port1.to_le_bytes());
        self.memory[a + 8..a + 16].fill(0);
        let e = reg::DC_RECEIVE_TIME_ECAT as usize;
        self.memory[e..e + 8].copy_from_slice(&arrival.port0_ns.to_le_bytes());
    }

    /// A write to the system time feeds the drift control: the time received plus the
    /// propagation delay from the reference clock (0x0928, ETG.1000.4 DC: the value left the
    /// reference that long ago) is compared with the local copy, the difference goes to 0x092C
    /// (bit 31 set when the local copy is ahead), and the local copy is pulled towards it.
    /// Bytes of the register the datagram did not cover (`None`) are the local copy's.
    fn compare_system_time(&mut self, received: &[Option<u8>; 8], arrival: Arrival) {
        let local = self.system_time(arrival.port0_ns);
        let mut bytes = local.to_le_bytes();
        for (b, r) in bytes.iter_mut().zip(received) {
            *b = r.unwrap_or(*b);
        }
        let d = reg::DC_SYSTEM_TIME_DELAY as usize;
        let delay = u32::from_le_bytes(self.memory[d..d + 4].try_into().expect("4 bytes"));
        let received = u64::from_le_bytes(bytes).wrapping_add(delay as u64);
        let difference = received.wrapping_sub(local) as i64;
        let magnitude = difference.unsigned_abs().min(0x7FFF_FFFF) as u32;
        let value = if difference <= 0 { magnitude | 0x8000_0000 } else { magnitude };
        let d = reg::DC_SYSTEM_TIME_DIFFERENCE as usize;
        self.memory[d..d + 4].copy_from_slice(&value.to_le_bytes());
        let offset = self.system_time_offset().wrapping_add(difference as u64);
        let o = reg::DC_SYSTEM_TIME_OFFSET as usize;
        self.memory[o..o + 8].copy_from_slice(&offset.to_le_bytes());
    }

    /// A logical access through the FMMUs: outputs are taken from the datagram as it arrived,
    /// then inputs are put into it. An FMMU maps bit by bit: its logical start and end bits
    /// bound its first and last logical byte, and its logical start bit goes to its physical
    /// start bit, so that a master may pack a few bits of each of several slaves into one
    /// logical byte (SOEM maps two EL2004s' 4 output bits to bits 0-3 and 4-7 of one byte).
    fn logical(&mut self, dg: &mut DatagramMut<'_>) -> (bool, bool) {
        let command = dg.header.command;
        let start = dg.header.logical_address() as u64;
        let end = start + dg.data.len() as u64;
        let (mut did_read, mut did_write) = (false, false);
        if start == end {
            // No byte to map: no FMMU is passed.
            return (false, false);
        }
        for pass_reads in [false, true] {
            for n in 0..self.hardware.fmmus {
                let f = reg::fmmu(n) as usize;
                let r = &self.memory[f..f + 16];
                let kind = r[fmmu_reg::TYPE];
                let wanted = if pass_reads { fmmu_reg::TYPE_READ } else { fmmu_reg::TYPE_WRITE };
                let allowed = if pass_reads { command.reads() } else { command.writes() };
                if r[fmmu_reg::ACTIVATE] & 0x01 == 0 || kind & wanted == 0 || !allowed {
                    continue;
                }
                let l_start = u32::from_le_bytes([r[0], r[1], r[2], r[3]]) as u64;
                let f_len = u16::from_le_bytes([r[4], r[5]]) as u64;
                let (start_bit, end_bit) = (r[fmmu_reg::LOGICAL_START_BIT] & 7, r[fmmu_reg::LOGICAL_END_BIT] & 7);
                let p_start = u16::from_le_bytes([r[8], r[9]]) as u64;
                let p_bit = r[fmmu_reg::PHYSICAL_START_BIT] & 7;
                if f_len == 0 {
                    continue;
                }
                // The FMMU's logical bits, and those the datagram carries of them.
                let first = l_start * 8 + u64::from(start_bit);
                let last = (l_start + f_len - 1) * 8 + u64::from(end_bit);
                let (from, to) = (first.max(start * 8), last.min(end * 8 - 1));
                if from > to {
                    continue;
                }
                // Logical bit b is physical bit b + shift.
                let shift = (p_start * 8 + u64::from(p_bit)) as i128 - first as i128;
                let physical = |bit: u64| (bit as i128 + shift) as u64;
                let (p_from, p_to) = ((physical(from) / 8) as usize, (physical(to) / 8) as usize);
                let count = p_to - p_from + 1;
                let (read_ok, write_ok) = self.gate(p_from, count, pass_reads, !pass_reads);
                if !(read_ok || write_ok) {
                    continue;
                }
                self.map_bits(dg, start, (from, to), shift, pass_reads);
                self.after_ram_access(p_from, count, pass_reads);
                if pass_reads {
                    did_read = true;
                } else {
                    did_write = true;
                }
            }
        }
        (did_read, did_write)
    }

    /// Copies logical bits `from..=to` of a datagram starting at logical byte `start` from
    /// their physical bits, `shift` bits on (`reading`), or to them; whole bytes where logical and physical bits
    /// line up, bit by bit where they do not. An FMMU may map past the end of the memory:
    /// nothing answers there; and the master writes process RAM (and a digital I/O ESC's
    /// outputs) only.
    fn map_bits(&mut self, dg: &mut DatagramMut<'_>, start: u64, (from, to): (u64, u64), shift: i128, reading: bool) {
        let (ram_end, digital_outputs) = (self.hardware.ram_end(), self.digital_io());
        let writable =
            |p: usize| (RAM_START..ram_end).contains(&p) || (digital_outputs && DIGITAL_OUTPUTS.contains(&p));
        let physical = |bit: u64| (bit as i128 + shift) as u64;
        let aligned = shift.rem_euclid(8) == 0;
        let mut bit = from;
        while bit <= to {
            let d = ((bit / 8) - start) as usize;
            let p = (physical(bit) / 8) as usize;
            let (mask, next) = if aligned {
                // The bits of this byte that lie in from..=to.
                let byte_last = (bit | 7).min(to);
                let width = byte_last - bit + 1;
                let mask = (((1u16 << width) - 1) << (bit % 8)) as u8;
                (mask, byte_last + 1)
            } else {
                (1u8 << (bit % 8), bit + 1)
            };
            let p_mask = if aligned { mask } else { 1u8 << (physical(bit) % 8) };
            if reading {
                if let Some(&byte) = self.memory.get(p) {
                    let value = if aligned {
                        byte & mask
                    } else if byte & p_mask != 0 {
                        mask
                    } else {
                        0
                    };
                    dg.data[d] = (dg.data[d] & !mask) | value;
                }
            } else if writable(p) {
                let value = if aligned {
                    dg.data[d] & mask
                } else if dg.data[d] & mask != 0 {
                    p_mask
                } else {
                    0
                };
                self.memory[p] = (self.memory[p] & !p_mask) | value;
            }
            bit = next;
        }
    }
}

/// The repeat-request bits of the mailbox sync managers a write at `[at, at + len)` touches,
/// to tell when the master toggles one.
fn old_repeat_bits(esc: &Esc, at: usize, len: usize) -> u8 {
    (0..SM_COUNT)
        .filter(|&n| touches(at, len, reg::sm(n) + sm_reg::ACTIVATE as u16, 1))
        .fold(0, |bits, n| bits | ((esc.memory[reg::sm(n) as usize + sm_reg::ACTIVATE] & sm_reg::ACTIVATE_REPEAT) << n))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ethercat::frame::{for_each_datagram_mut, FrameBuilder};

    const NOW: Arrival = Arrival { port0_ns: 1_000, port1_ns: None };

    fn run(esc: &mut Esc, command: Command, adp: u16, ado: u16, data: &[u8]) -> (Vec<u8>, u16) {
        let mut buf = [0u8; 1600];
        let mut b = FrameBuilder::new(&mut buf);
        let slot = b.push(command, 0, adp, ado, data).unwrap();
        let len = b.finish();
        for_each_datagram_mut(&mut buf[..len], |dg| esc.serve(dg, NOW)).unwrap();
        (slot.data(&buf[..len]).unwrap().to_vec(), slot.wkc(&buf[..len]).unwrap())
    }

    fn esc() -> Esc {
        Esc::new(crate::sim::sii_image::akd_sii(), false)
    }

    #[test]
    fn an_fmmu_mapping_past_the_end_of_memory_reads_nothing_there() {
        // Found by fuzzing (native/fuzz, virtual_akd): a read FMMU of 0xFFFF bytes from physical
        // 0xFFFF, read at logical offset 0x8000, points far past the ESC's memory.
        let mut e = esc();
        let fmmu = [0, 0, 0, 0, 0xFF, 0xFF, 0, 7, 0xFF, 0xFF, 0, fmmu_reg::TYPE_READ, 0x01, 0, 0, 0];
        assert_eq!(run(&mut e, Command::Apwr, 0, reg::fmmu(0), &fmmu).1, 1);
        assert_eq!(run(&mut e, Command::Lrd, 0x8000, 0x0000, &[0xAB, 0xCD]), (vec![0xAB, 0xCD], 1));
    }

    #[test]
    fn a_datagram_longer_than_ethernet_carries_is_served_to_its_end() {
        // A frame header announces up to 2047 bytes, more than an Ethernet frame carries, and a
        // link may bring such a frame all the same: its datagram at ADO 0xFFFF ends 2035 bytes on.
        let len = 0x07FF - crate::ethercat::frame::DATAGRAM_HEADER_LEN - crate::ethercat::frame::WKC_LEN;
        let mut frame = vec![0u8; 2 + 0x07FF];
        frame[..2].copy_from_slice(&(0x1000u16 | 0x07FF).to_le_bytes());
        frame[2..12].copy_from_slice(&[Command::Aprd as u8, 0, 0, 0, 0xFF, 0xFF, len as u8, (len >> 8) as u8, 0, 0]);
        let mut e = esc();
        for_each_datagram_mut(&mut frame, |dg| e.serve(dg, NOW)).unwrap();
        assert_eq!(u16::from_le_bytes([frame[12 + len], frame[13 + len]]), 1);
    }

    #[test]
    fn power_up_registers_are_the_real_drives() {
        let mut e = esc();
        assert_eq!(run(&mut e, Command::Brd, 0, 0x0000, &[0, 0]), (vec![0x04, 0x02], 1));
        // The ESC information registers as a real AKD answered TwinCAT.
        let information = [0x04, 0x02, 0x43, 0x00, 0x03, 0x04, 0x04, 0x0F, 0x84, 0x01];
        assert_eq!(run(&mut e, Command::Aprd, 0, 0x0000, &[0; 10]).0, information);
        assert_eq!(run(&mut e, Command::Aprd, 0, 0x0102, &[0]).0, vec![0x07]);
        assert_eq!(run(&mut e, Command::Aprd, 0, 0x0110, &[0, 0]).0, vec![0x13, 0x56]);
        assert_eq!(run(&mut e, Command::Aprd, 0, 0x0140, &[0, 0]).0, vec![0x08, 0x0C]);
        assert_eq!(run(&mut e, Command::Aprd, 0, 0x0130, &[0; 6]).0, vec![1, 0, 0, 0, 0, 0]);
        // Read-only registers stay as they are; the write still counts, as on a real ESC.
        assert_eq!(run(&mut e, Command::Apwr, 0, 0x0000, &[9, 9]).1, 1);
        assert_eq!(run(&mut e, Command::Aprd, 0, 0x0000, &[0, 0]).0, vec![0x04, 0x02]);
    }

    #[test]
    fn addressing_and_working_counters() {
        let mut e = esc();
        assert_eq!(run(&mut e, Command::Aprd, 1, 0x0000, &[0]).1, 0);
        assert_eq!(run(&mut e, Command::Apwr, 0, 0x0010, &[0x01, 0x10]).1, 1);
        assert_eq!(run(&mut e, Command::Fprd, 0x1001, 0x0010, &[0, 0]), (vec![0x01, 0x10], 1));
        assert_eq!(run(&mut e, Command::Fprd, 0x1002, 0x0010, &[0, 0]).1, 0);
        assert_eq!(run(&mut e, Command::Fprw, 0x1001, 0x0010, &[0x02, 0x10]), (vec![0x01, 0x10], 3));
        assert_eq!(run(&mut e, Command::Fprd, 0x1002, 0x0010, &[0, 0]).1, 1);
        // FRMW: the addressed drive reads, the others would write.
        assert_eq!(run(&mut e, Command::Frmw, 0x1002, 0x0010, &[0, 0]).1, 1);
    }

    #[test]
    fn a_sync_manager_set_over_the_registers_leaves_them_free() {
        let mut e = esc();
        // SM1 as a mailbox (read by the master, empty) at 0x0000: a real ESC gates process
        // memory only, so the registers stay readable and writable.
        assert_eq!(run(&mut e, Command::Apwr, 0, 0x0808, &[0, 0, 0, 4, 0x22, 0, 1, 0]).1, 1);
        assert_eq!(run(&mut e, Command::Aprd, 0, 0x0000, &[0, 0]), (vec![0x04, 0x02], 1));
        assert_eq!(run(&mut e, Command::Apwr, 0, 0x0010, &[0x01, 0x10]).1, 1);
        assert_eq!(run(&mut e, Command::Fprd, 0x1001, 0x0010, &[0, 0]), (vec![0x01, 0x10], 1));
    }

    #[test]
    fn sii_reads_four_bytes_at_the_word_address() {
        let mut e = esc();
        let image = crate::sim::sii_image::akd_sii();
        run(&mut e, Command::Apwr, 0, 0x0502, &[0x00, 0x01, 0x08, 0x00, 0x00, 0x00]);
        assert_eq!(run(&mut e, Command::Aprd, 0, 0x0502, &[0, 0]).0, vec![0x20, 0x00]);
        assert_eq!(run(&mut e, Command::Aprd, 0, 0x0508, &[0; 4]).0, image[16..20].to_vec());
        run(&mut e, Command::Apwr, 0, 0x0502, &[0x00, 0x02, 0x08, 0x00, 0x00, 0x00]);
        assert_eq!(run(&mut e, Command::Aprd, 0, 0x0502, &[0, 0]).0, vec![0x20, 0x20]);
    }

    #[test]
    fn al_control_is_refused_until_the_firmware_read_it() {
        let mut e = esc();
        assert_eq!(run(&mut e, Command::Bwr, 0, 0x0120, &[0x11]).1, 1);
        assert_eq!(e.take_events().al_control, Some(0x11));
        assert_eq!(run(&mut e, Command::Bwr, 0, 0x0120, &[0x11]).1, 0);
        e.release_al_control();
        assert_eq!(run(&mut e, Command::Bwr, 0, 0x0120, &[0x12]).1, 1);
    }

    #[test]
    fn mailbox_buffers_are_guarded() {
        let mut e = esc();
        run(&mut e, Command::Apwr, 0, 0x0800, &[0x00, 0x18, 0x00, 0x04, 0x26, 0x00, 0x01, 0x00]);
        run(&mut e, Command::Apwr, 0, 0x0808, &[0x00, 0x1C, 0x00, 0x04, 0x22, 0x00, 0x01, 0x00]);
        e.take_events();
        assert_eq!(run(&mut e, Command::Aprd, 0, 0x1C00, &[0; 0x400]).1, 0, "empty mailbox-in");
        assert_eq!(run(&mut e, Command::Apwr, 0, 0x1800, &[1; 0x400]).1, 1);
        assert!(e.take_events().mailbox_written);
        assert_eq!(run(&mut e, Command::Aprd, 0, 0x0805, &[0]).0, vec![0x09]);
        assert_eq!(run(&mut e, Command::Apwr, 0, 0x1800, &[2; 0x400]).1, 0, "full mailbox-out");
        sync_manager::mark_written(e.memory_mut(), 1);
        assert_eq!(run(&mut e, Command::Aprd, 0, 0x1C00, &[0; 0x400]).1, 1);
        assert!(e.take_events().mailbox_read);
        assert_eq!(run(&mut e, Command::Aprd, 0, 0x080D, &[0]).0, vec![0x02]);
    }

    #[test]
    fn fmmus_map_logical_to_physical_with_bit_masks() {
        let mut e = esc();
        // FMMU 0: logical 0x10000 (2 bytes) -> 0x1100, write; FMMU 1: 0x10002 (2) <- 0x1140, read.
        run(&mut e, Command::Apwr, 0, 0x0600, &[0, 0, 1, 0, 2, 0, 0, 7, 0x00, 0x11, 0, 2, 1, 0, 0, 0]);
        run(&mut e, Command::Apwr, 0, 0x0610, &[2, 0, 1, 0, 2, 0, 0, 3, 0x40, 0x11, 0, 1, 1, 0, 0, 0]);
        e.memory_mut()[0x1140..0x1142].copy_from_slice(&[0xFF, 0xFF]);
        let mut buf = [0u8; 64];
        let mut b = FrameBuilder::new(&mut buf);
        let slot = b.push(Command::Lrw, 0, 0x0000, 0x0001, &[0xAA, 0xBB, 0, 0]).unwrap();
        let len = b.finish();
        for_each_datagram_mut(&mut buf[..len], |dg| e.serve(dg, NOW)).unwrap();
        assert_eq!(slot.wkc(&buf[..len]).unwrap(), 3);
        // The read FMMU ends at bit 3 of its last byte.
        assert_eq!(slot.data(&buf[..len]).unwrap(), &[0xAA, 0xBB, 0xFF, 0x0F]);
        assert_eq!(&e.memory()[0x1100..0x1102], &[0xAA, 0xBB]);
        assert!(!e.take_events().outputs_written, "no sync manager covers 0x1100 yet");
    }

    #[test]
    fn dc_latches_and_system_time() {
        let mut e = esc();
        run(&mut e, Command::Bwr, 0, 0x0900, &[0; 4]);
        assert_eq!(run(&mut e, Command::Aprd, 0, 0x0900, &[0; 4]).0, 1_000u32.to_le_bytes().to_vec());
        assert_eq!(run(&mut e, Command::Aprd, 0, 0x0918, &[0; 8]).0, 1_000u64.to_le_bytes().to_vec());
        run(&mut e, Command::Apwr, 0, 0x0920, &5_000u64.to_le_bytes());
        assert_eq!(run(&mut e, Command::Aprd, 0, 0x0910, &[0; 8]).0, 6_000u64.to_le_bytes().to_vec());
        // FRMW from another drive writes 6_100: 100 ns ahead of the local copy.
        run(&mut e, Command::Frmw, 0x7777, 0x0910, &6_100u64.to_le_bytes());
        assert_eq!(run(&mut e, Command::Aprd, 0, 0x092C, &[0; 4]).0, 100u32.to_le_bytes().to_vec());
    }

    #[test]
    fn dc_drift_adds_the_propagation_delay_to_the_time_received() {
        let mut e = esc();
        run(&mut e, Command::Apwr, 0, 0x0920, &5_000u64.to_le_bytes());
        // 300 ns from the reference clock: its 5_800 is 6_100 by the time it arrives, and the
        // local copy reads 6_000, 100 ns behind.
        run(&mut e, Command::Apwr, 0, 0x0928, &300u32.to_le_bytes());
        run(&mut e, Command::Frmw, 0x7777, 0x0910, &5_800u64.to_le_bytes());
        assert_eq!(run(&mut e, Command::Aprd, 0, 0x092C, &[0; 4]).0, 100u32.to_le_bytes().to_vec());
        assert_eq!(run(&mut e, Command::Aprd, 0, 0x0910, &[0; 8]).0, 6_100u64.to_le_bytes().to_vec());
        // Received 5_650 + 300 = 5_950 against 6_100: the local copy is 150 ns ahead (bit 31).
        run(&mut e, Command::Frmw, 0x7777, 0x0910, &5_650u64.to_le_bytes());
        assert_eq!(run(&mut e, Command::Aprd, 0, 0x092C, &[0; 4]).0, (150u32 | 1 << 31).to_le_bytes().to_vec());
        // A write of the upper half only (no delay now): the lower half is the local copy's,
        // so the same upper half means no difference.
        run(&mut e, Command::Apwr, 0, 0x0928, &[0; 4]);
        run(&mut e, Command::Frmw, 0x7777, 0x0914, &[0, 0, 0, 0]);
        assert_eq!(run(&mut e, Command::Aprd, 0, 0x092C, &[0; 4]).0, 0x8000_0000u32.to_le_bytes().to_vec());
    }
}
