//! The master on a virtual line of Beckhoff terminals beside an AKD, each configured from what
//! its SII says of itself: every slave to Op, the terminals' few bits packed in the process
//! image as SOEM packs them, the working counter counting what the ESCs count, outputs reaching
//! the terminal's pins and its inputs the master, the EK1100 the reference clock, the terminals
//! whose ESC has no system time not synchronised, and a terminal brought back after a power
//! cycle.

use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use akd_native::drive::akd::{AkdLine, AkdSlave};
use akd_native::drive::pdo::Mapping;
use akd_native::ethercat::al::AlState;
use akd_native::ethercat::frame::{self, Command};
use akd_native::ethercat::link::Link;
use akd_native::ethercat::link_spec::{MissedFrames, Pace, SimLine};
use akd_native::ethercat::master::restore::Restoring;
use akd_native::ethercat::master::Master;
use akd_native::ethercat::registers;
use akd_native::sim::{Timing, VirtualBus};

#[path = "support/shared.rs"]
mod shared;
use shared::Shared;

const STEP: Duration = Duration::from_secs(5);

/// A master on `line` (a line spec) at the pace the tests want, the line shared with the test.
fn master_on(line: &str) -> (Master, Arc<Mutex<VirtualBus>>) {
    let line: SimLine = line.parse().unwrap();
    let bus = VirtualBus::of_line(&line, Timing::of(Pace::Immediate, MissedFrames::Lost)).unwrap();
    let bus = Arc::new(Mutex::new(bus));
    let mut m = Master::new(Box::new(Shared::new(bus.clone())), Duration::from_millis(100));
    assert_eq!(m.scan().unwrap(), line.len());
    (m, bus)
}

/// Cycles until `done` holds of the shared bus, or fails after a few seconds.
fn cycle_until(m: &mut Master, bus: &Mutex<VirtualBus>, done: impl Fn(&VirtualBus) -> bool) {
    let deadline = Instant::now() + STEP;
    while !done(&bus.lock().unwrap()) {
        assert!(Instant::now() < deadline, "not reached in time");
        m.exchange().unwrap();
        std::thread::sleep(Duration::from_millis(1));
    }
}

/// The FMMU registers of slave `position`'s FMMU `n`: logical start, length, start bit, end
/// bit, physical start.
fn fmmu(m: &mut Master, position: u16, n: u16) -> (u32, u16, u8, u8, u16) {
    let r = m.slave_mut(position).unwrap().read_register(0x0600 + 16 * n, 16).unwrap();
    (
        u32::from_le_bytes([r[0], r[1], r[2], r[3]]),
        u16::from_le_bytes([r[4], r[5]]),
        r[6],
        r[7],
        u16::from_le_bytes([r[8], r[9]]),
    )
}

#[test]
fn every_slave_of_a_line_goes_to_op_from_what_its_sii_says() {
    let (mut m, bus) = master_on("ek1100,el1004,el2004,el2004,el3102,akd");
    let names: Vec<_> = m.slaves().iter().map(|s| s.sii.order().unwrap_or("").to_owned()).collect();
    assert_eq!(names, ["EK1100", "EL1004", "EL2004", "EL2004", "EL3102", "AKD"]);
    m.request_state(AlState::PreOp, STEP).unwrap();
    m.slave_mut(5).unwrap().configure_pdo(Mapping::Fixed(0x1701), Mapping::Fixed(0x1B01)).unwrap();
    m.request_state(AlState::Op, STEP).unwrap();
    for position in 0..6 {
        assert_eq!(m.slave_mut(position).unwrap().al_status().unwrap().state(), Some(AlState::Op), "slave {position}");
    }
    // As SOEM maps two EL2004s: one logical byte, bits 0-3 and 4-7, from each one's SM0 at 0x0F00.
    assert_eq!(fmmu(&mut m, 2, 0), (0, 1, 0, 3, 0x0F00));
    assert_eq!(fmmu(&mut m, 3, 0), (0, 1, 4, 7, 0x0F00));
    let el2004 = m.slave_mut(2).unwrap().read_register(0x0800, 8).unwrap();
    assert_eq!((u16::from_le_bytes([el2004[0], el2004[1]]), el2004[2], el2004[4]), (0x0F00, 1, 0x44));
    // The AKD's outputs start on a byte of their own, after the EL2004s' shared one; the
    // inputs follow every slave's outputs: the EL1004's four bits, then the EL3102's six bytes.
    let outputs = m.output_image().unwrap().len() as u32;
    assert_eq!(fmmu(&mut m, 5, 0).0, 1);
    assert_eq!(fmmu(&mut m, 1, 0), (outputs, 1, 0, 3, 0x1000));
    assert_eq!(fmmu(&mut m, 4, 1).0, outputs + 1);
    // Counted as the ESCs count an LRW: 1 for inputs, 2 for outputs, 3 for both.
    assert_eq!(m.expected_wkc().unwrap(), 1 + 2 + 2 + 1 + 3);
    assert_eq!(m.exchange().unwrap(), 9);

    m.slave_mut(3).unwrap().set_outputs(&[0b0101]).unwrap();
    m.slave_mut(2).unwrap().set_outputs(&[0b0010]).unwrap();
    assert!(m
        .slave_mut(2)
        .unwrap()
        .set_outputs(&[0, 0])
        .unwrap_err()
        .to_string()
        .contains("1 bytes of outputs, 2 given"));
    cycle_until(&mut m, &bus, |b| b.at(3).terminal().unwrap().state().outputs == 0b0101);
    assert_eq!(bus.lock().unwrap().at(2).terminal().unwrap().state().outputs, 0b0010);
    assert_eq!(m.slave_mut(3).unwrap().outputs().unwrap(), [0b0101]);

    bus.lock().unwrap().at_mut(1).terminal_mut().unwrap().set_input(3, true);
    let deadline = Instant::now() + STEP;
    while m.slave_mut(1).unwrap().inputs().unwrap() != [0b0100] {
        assert!(Instant::now() < deadline, "the EL1004's input 3 never reached the master");
        m.exchange().unwrap();
        std::thread::sleep(Duration::from_millis(1));
    }
    bus.lock().unwrap().at_mut(4).terminal_mut().unwrap().set_analog_input(2, 5.0);
    let deadline = Instant::now() + STEP;
    loop {
        m.exchange().unwrap();
        let el3102 = m.slave_mut(4).unwrap().inputs().unwrap();
        if i16::from_le_bytes([el3102[4], el3102[5]]) > 16000 {
            break;
        }
        assert!(Instant::now() < deadline, "the EL3102's channel 2 never read 5 V: {el3102:?}");
        std::thread::sleep(Duration::from_millis(1));
    }
    m.request_state(AlState::Init, STEP).unwrap();
}

#[test]
fn the_coupler_is_the_reference_clock_and_terminals_without_system_time_are_not_synchronised() {
    // The EL3102 has CoE: FBUS.PARAM02 or 0x60C2 written to it would be refused (an SDO abort).
    let (mut m, _bus) = master_on("ek1100,el1004,el2004,el3102,akd");
    let dc: Vec<bool> = m.slaves().iter().map(|s| s.has_dc()).collect();
    // The ET1200 says it has DC (feature bit 2) and has no system time.
    assert_eq!(dc, [true, false, false, false, true]);
    assert!(m.slave_mut(1).unwrap().read_register(0x0008, 2).unwrap()[0] & 0x04 != 0);
    m.request_state(AlState::PreOp, STEP).unwrap();
    let fbus_param02 = m.configure_dc(1_000_000, 0).unwrap();
    assert_eq!(fbus_param02[..4], [None; 4], "nothing of the AKD's written to a terminal");
    assert!(fbus_param02[4].is_some(), "FBUS.PARAM02 written to the AKD");
    let clock = m.clock().unwrap().clone();
    assert_eq!(clock.reference_position, 0);
    assert_eq!(clock.slaves.iter().map(|s| s.position).collect::<Vec<_>>(), [0, 4]);
    m.slave_mut(4).unwrap().configure_pdo(Mapping::Fixed(0x1701), Mapping::Fixed(0x1B01)).unwrap();
    m.request_state(AlState::Op, STEP).unwrap();
    assert_eq!(m.exchange().unwrap(), m.expected_wkc().unwrap());
    m.request_state(AlState::Init, STEP).unwrap();
}

#[test]
fn a_terminal_found_with_its_error_flag_set_is_reset_to_init() {
    // A device-emulating ESC copies AL control to AL status, the acknowledge bit too: what the
    // scan's reset writes comes back as an error flag, which a master must clear itself.
    let (mut m, _bus) = master_on("ek1100,el2004");
    m.request_state(AlState::PreOp, STEP).unwrap();
    m.slave_mut(1).unwrap().write_register(0x0120, &0x12u16.to_le_bytes()).unwrap();
    assert_eq!(m.slave_mut(1).unwrap().al_status().unwrap().status, 0x12);
    m.scan().unwrap();
    assert_eq!(m.slaves()[1].found.status, 0x12);
    assert_eq!(m.slave_mut(1).unwrap().al_status().unwrap().status, 0x01);
    m.request_state(AlState::Op, STEP).unwrap();
}

#[test]
fn a_power_cycled_terminal_comes_back_with_its_outputs_where_they_were_in_the_image() {
    let (mut m, bus) = master_on("ek1100,el2004,el2004");
    m.request_state(AlState::Op, STEP).unwrap();
    let before = m.image_slot(2).unwrap();
    bus.lock().unwrap().power_cycle(2);
    let mut restoring = m.for_restore(Box::new(Shared::new(bus.clone())));
    assert_eq!(restoring.restore_to_preop(2).unwrap(), Restoring::InPreOp);
    restoring.restore_to_op(2).unwrap();
    assert_eq!(m.slave_mut(2).unwrap().al_status().unwrap().state(), Some(AlState::Op));
    assert_eq!(fmmu(&mut m, 2, 0), (0, 1, 4, 7, 0x0F00));
    assert_eq!(m.image_slot(2).unwrap(), before);
    m.slave_mut(2).unwrap().set_outputs(&[0b1000]).unwrap();
    cycle_until(&mut m, &bus, |b| b.at(2).terminal().unwrap().state().outputs == 0b1000);
    assert_eq!(m.exchange().unwrap(), m.expected_wkc().unwrap());
}

/// A link whose slave at `station` answers every read of its EEPROM's data with the bits
/// flipped, as a damaged EEPROM would.
struct DamagedEeprom {
    inner: Shared,
    station: u16,
}

impl Link for DamagedEeprom {
    fn send(&mut self, tx: &[u8]) -> akd_native::error::Result<()> {
        self.inner.send(tx)
    }

    fn receive(&mut self, rx: &mut [u8], deadline: Instant) -> akd_native::error::Result<Option<usize>> {
        let n = self.inner.receive(rx, deadline)?;
        if let Some(n) = n {
            let station = self.station;
            frame::for_each_datagram_mut(&mut rx[..n], |dg| {
                // The master reads control, address and data in one datagram from SII control on.
                let data = usize::from(registers::SII_DATA - registers::SII_CONTROL);
                let reads_sii = (dg.header.command, dg.header.adp, dg.header.ado)
                    == (Command::Fprd, station, registers::SII_CONTROL);
                if reads_sii && dg.data.len() > data {
                    dg.data[data..].iter_mut().for_each(|b| *b ^= 0xFF);
                }
            })?;
        }
        Ok(n)
    }

    fn describe(&self) -> String {
        "a line with a damaged EEPROM".into()
    }
}

#[test]
fn a_terminal_whose_eeprom_is_damaged_is_named_in_one_line_and_nothing_goes_on() {
    let line: SimLine = "ek1100,el2004,akd".parse().unwrap();
    let bus = VirtualBus::of_line(&line, Timing::of(Pace::Immediate, MissedFrames::Lost)).unwrap();
    let bus = Arc::new(Mutex::new(bus));
    let link = DamagedEeprom { inner: Shared::new(bus.clone()), station: 0x1002 };
    let mut m = Master::new(Box::new(link), Duration::from_millis(100));
    let refused = m.scan().unwrap_err().to_string();
    assert!(refused.contains("slave 1 (station 0x1002)") && refused.contains("checksum"), "{refused}");
    assert!(!refused.contains('\n'), "{refused}");
    assert!(m.slaves().is_empty(), "no slave taken from a scan that failed");
    for position in 0..3 {
        assert_eq!(bus.lock().unwrap().at(position).registers()[0x0130] & 0x0F, 1, "slave {position} left in Init");
    }
}

/// A link whose thread stalls once, for longer than the master waits for an SII read, right
/// after a read found the EEPROM interface busy, as this shared host stalls a thread now and then.
struct StallAfterBusySii {
    inner: Shared,
    stalled: bool,
}

impl Link for StallAfterBusySii {
    fn send(&mut self, tx: &[u8]) -> akd_native::error::Result<()> {
        self.inner.send(tx)
    }

    fn receive(&mut self, rx: &mut [u8], deadline: Instant) -> akd_native::error::Result<Option<usize>> {
        let n = self.inner.receive(rx, deadline)?;
        let mut busy = false;
        if let Some(n) = n {
            frame::for_each_datagram_mut(&mut rx[..n], |dg| {
                let reads_sii = (dg.header.command, dg.header.ado) == (Command::Fprd, registers::SII_CONTROL);
                busy |= reads_sii && dg.data.len() >= 2 && dg.data[1] & 0x80 != 0;
            })?;
        }
        if busy && !self.stalled {
            self.stalled = true;
            std::thread::sleep(Duration::from_millis(150));
        }
        Ok(n)
    }

    fn describe(&self) -> String {
        "a line on a host that stalls".into()
    }
}

#[test]
fn a_stall_after_a_busy_eeprom_read_is_no_time_out() {
    let line: SimLine = "ek1100,el1004,akd".parse().unwrap();
    let bus = VirtualBus::of_line(&line, Timing::of(Pace::Immediate, MissedFrames::Lost)).unwrap();
    let link = StallAfterBusySii { inner: Shared::new(Arc::new(Mutex::new(bus))), stalled: false };
    let mut m = Master::new(Box::new(link), Duration::from_millis(100));
    assert_eq!(m.scan().unwrap(), 3);
}
