//! The EtherCAT slave controller (ESC) of the virtual AKD: its register and RAM space and the
//! datagram service as the hardware does it, without the drive's firmware (the PDI side, in
//! [`super::VirtualAkd`]).
//!
//! The register values at power-up are the real drive's, read in the SOEM capture and under
//! TwinCAT: type 0x04 revision 0x02 build 0x0043 (an ESC20-class controller with 3 FMMUs,
//! 4 sync managers and 4 KiB of RAM at 0x1000–0x1FFF), port descriptor 0x0F, features 0x0184,
//! DL control byte 2 (RX FIFO size) 0x07, DL status 0x5613, PDI control 0x0C08, SII control
//! 0x0020 (EEPROM emulated by the PDI, 4-byte reads). What the hardware does by itself is here: the
//! SII interface reading the EEPROM image, DC receive-time latching and the system time, the
//! sync managers' buffer protection, FMMU mapping of logical datagrams, and the AL control
//! register behaving like a mailbox (a second write before the firmware read the first is
//! refused, as the real drive refuses SOEM's quick second write of 0x0120).

use crate::ethercat::frame::{Addressing, Command, DatagramMut};
use crate::ethercat::registers::{self as reg, fmmu_reg, sii_reg, sm_reg};
use crate::sim::sync_manager::{self, SyncManager, CONTROL_WATCHDOG, SM_COUNT};

/// Number of FMMUs of the AKD's ESC: a master needs two for process data (outputs, inputs)
/// and may use the third for the mailbox-in status bit.
pub const FMMU_COUNT: u8 = 3;
/// ESC build (register 0x0002) of the real drive.
pub const ESC_BUILD: u16 = 0x0043;
/// DL control byte 2 at power-up: the RX FIFO size, 7 (the ESC's default, no reduction).
const DL_CONTROL_FIFO_SIZE: u8 = 0x07;
/// First byte of process RAM.
pub const RAM_START: usize = 0x1000;
/// One past the last byte of process RAM (4 KiB).
pub const RAM_END: usize = 0x2000;
/// Size of the address space a datagram can reach: ADO up to 0xFFFF plus its length, which
/// the frame header's 11-bit length bounds (a link may bring a frame longer than Ethernet's).
const SPACE: usize = 0x10000 + 0x07FF;
/// DL status of the last drive of a line: port 0 link and communication, port 1 loop closed.
const DL_STATUS_LAST: u16 = 0x5613;
/// DL status of a drive with a successor: port 1 also has link and communication, loop open.
const DL_STATUS_FORWARDING: u16 = 0x5A33;

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
    memory: Box<[u8]>,
    sii: Vec<u8>,
    al_control_locked: bool,
    events: Events,
}

/// Whether the master may write the byte at `addr` (ETG.1000.4 register access types, as
/// implemented by Beckhoff ESCs; most identification and status registers are read-only).
fn master_writable(addr: usize) -> bool {
    match addr {
        0x0010..=0x0011 | 0x0100..=0x0103 | 0x0108..=0x0109 | 0x0120..=0x0121 | 0x0200..=0x0201 => true,
        0x0400..=0x0401 | 0x0410..=0x0411 | 0x0420..=0x0421 | 0x0500 | 0x0502..=0x050F => true,
        0x0600..=0x06FF | 0x0920..=0x092B | 0x0930..=0x0935 | 0x0980..=0x0981 => true,
        0x0990..=0x0997 | 0x09A0..=0x09A7 | RAM_START..=0x1FFF => true,
        0x0800..=0x081F => !matches!((addr - 0x0800) % 8, 5 | 7),
        _ => false,
    }
}

fn touches(at: usize, len: usize, register: u16, register_len: usize) -> bool {
    let r = register as usize;
    at < r + register_len && r < at + len
}

impl Esc {
    /// An ESC at power-up serving the EEPROM `sii`; `has_successor` tells whether another
    /// drive follows on port 1 (it sets the DL status).
    pub fn new(sii: Vec<u8>, has_successor: bool) -> Self {
        let mut memory = vec![0u8; SPACE].into_boxed_slice();
        memory[0x0000] = 0x04;
        memory[0x0001] = 0x02;
        memory[0x0002..0x0004].copy_from_slice(&ESC_BUILD.to_le_bytes());
        memory[0x0004] = FMMU_COUNT;
        memory[0x0005] = SM_COUNT;
        memory[0x0006] = ((RAM_END - RAM_START) / 1024) as u8;
        memory[0x0007] = 0x0F;
        memory[0x0008..0x000A].copy_from_slice(&0x0184u16.to_le_bytes());
        memory[reg::DL_CONTROL as usize + 2] = DL_CONTROL_FIFO_SIZE;
        let alias = sii.get(8..10).map_or(0, |w| u16::from_le_bytes([w[0], w[1]]));
        memory[0x0012..0x0014].copy_from_slice(&alias.to_le_bytes());
        memory[0x0130] = 0x01;
        memory[0x0140..0x0142].copy_from_slice(&0x0C08u16.to_le_bytes());
        memory[0x0400..0x0402].copy_from_slice(&0x09C2u16.to_le_bytes());
        memory[0x0420..0x0422].copy_from_slice(&1000u16.to_le_bytes());
        memory[0x0502..0x0504].copy_from_slice(&sii_reg::EMULATION.to_le_bytes());
        let mut esc = Esc { memory, sii, al_control_locked: false, events: Events::default() };
        esc.set_successor(has_successor);
        esc
    }

    /// The EEPROM it serves.
    pub fn sii(&self) -> &[u8] {
        &self.sii
    }

    /// Whether a drive answers on port 1 (a cable pulled out behind it, or plugged back in):
    /// the DL status shows port 1's link and whether its loop is closed.
    pub fn set_successor(&mut self, has_successor: bool) {
        let dl_status = if has_successor { DL_STATUS_FORWARDING } else { DL_STATUS_LAST };
        self.memory[0x0110..0x0112].copy_from_slice(&dl_status.to_le_bytes());
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
        let (read, write) = self.gate(at, len, read, write);
        let write = write && !(self.al_control_locked && touches(at, len, reg::AL_CONTROL, 2));
        if read {
            self.refresh_system_time(at, len, arrival);
        }
        let repeat_before = old_repeat_bits(self, at, len);
        for (i, byte) in dg.data.iter_mut().enumerate() {
            let addr = at + i;
            let old = self.memory[addr];
            if write && master_writable(addr) {
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
        }
        (read, write)
    }

    /// Whether a read and a write of `[at, at + len)` pass the sync managers: a full mailbox
    /// refuses writes from the master, an empty one refuses reads, and a buffer the firmware
    /// deactivated refuses both. Memory no enabled sync manager covers is free, and so are the
    /// registers below [`RAM_START`]: an ESC's sync managers work on process memory only, so a
    /// sync manager a master set over the registers (a broadcast write may do that) never
    /// blocks them.
    fn gate(&self, at: usize, len: usize, read: bool, write: bool) -> (bool, bool) {
        let (mut read, mut write) = (read, write);
        if at + len <= RAM_START {
            return (read, write);
        }
        for n in 0..SM_COUNT {
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
        if at + len <= RAM_START {
            return;
        }
        for n in 0..SM_COUNT {
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
            self.al_control_locked = true;
            self.events.al_control = Some(self.u16_at(reg::AL_CONTROL));
        }
        if touches(at, len, reg::RX_ERROR_COUNTERS, 0x14) {
            self.memory[0x0300..0x0314].fill(0);
        }
        if touches(at, len, reg::SII_CONTROL, 2) {
            self.sii_command();
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

    /// Executes the command written to SII control: a read copies 4 bytes of the EEPROM at the
    /// word address into SII data at once (the drive emulates the EEPROM, never busy); other
    /// commands are refused with the error bit, as an emulated EEPROM cannot be written here.
    fn sii_command(&mut self) {
        let control = self.u16_at(reg::SII_CONTROL);
        let mut status = sii_reg::EMULATION | (control & sii_reg::WRITE_ENABLE);
        if control & sii_reg::CMD_READ != 0 {
            let a = reg::SII_ADDRESS as usize;
            let word = u32::from_le_bytes([self.memory[a], self.memory[a + 1], self.memory[a + 2], self.memory[a + 3]]);
            for i in 0..4 {
                let byte = (word as usize).checked_mul(2).and_then(|b| self.sii.get(b + i)).copied().unwrap_or(0xFF);
                self.memory[reg::SII_DATA as usize + i] = byte;
            }
        } else if control & (sii_reg::CMD_WRITE | sii_reg::CMD_RELOAD) != 0 {
            status |= sii_reg::ERROR_ACK;
        }
        self.memory[reg::SII_CONTROL as usize..reg::SII_CONTROL as usize + 2].copy_from_slice(&status.to_le_bytes());
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
    /// then inputs are put into it. Start and end bits mask the first and last byte.
    fn logical(&mut self, dg: &mut DatagramMut<'_>) -> (bool, bool) {
        let command = dg.header.command;
        let start = dg.header.logical_address() as u64;
        let end = start + dg.data.len() as u64;
        let (mut did_read, mut did_write) = (false, false);
        for pass_reads in [false, true] {
            for n in 0..FMMU_COUNT {
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
                let p_start = u16::from_le_bytes([r[8], r[9]]) as usize;
                let (from, to) = (start.max(l_start), end.min(l_start + f_len));
                if f_len == 0 || from >= to {
                    continue;
                }
                let p_from = p_start + (from - l_start) as usize;
                let count = (to - from) as usize;
                let (read_ok, write_ok) = self.gate(p_from, count, pass_reads, !pass_reads);
                if !(read_ok || write_ok) {
                    continue;
                }
                for i in 0..count {
                    let logical = from + i as u64;
                    let mut mask = 0xFFu8;
                    if logical == l_start {
                        mask &= 0xFFu8 << start_bit;
                    }
                    if logical == l_start + f_len - 1 {
                        mask &= 0xFFu8 >> (7 - end_bit);
                    }
                    let d = (logical - start) as usize;
                    let p = p_from + i;
                    if pass_reads {
                        // An FMMU may map past the end of the memory: nothing answers there.
                        if let Some(&byte) = self.memory.get(p) {
                            dg.data[d] = (dg.data[d] & !mask) | (byte & mask);
                        }
                    } else if (RAM_START..RAM_END).contains(&p) {
                        self.memory[p] = (self.memory[p] & !mask) | (dg.data[d] & mask);
                    }
                }
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
