//! A virtual Beckhoff terminal: an ESC serving the terminal's SII image ([`super::terminal_sii`]),
//! and behind it what the real one has there.
//!
//! - The EK1100 and the digital terminals have no processor: their EEPROM sets device emulation
//!   (the ESC copies AL control to AL status at once, whatever the request, as the capture shows
//!   the real ones do) and, for the EL1xxx and EL2xxx, the ESC's digital I/O PDI. An EL1xxx's
//!   inputs go into process RAM at 0x1000, where its sync manager 0 lets the master read them,
//!   after the terminal's input filter (3 ms for the EL1004 and EL1008, as their names say). An
//!   EL2xxx's outputs are the ESC's digital output register 0x0F00, which its sync manager 0
//!   guards: the pins follow what the master writes there while the terminal is in Op, and drop
//!   to off when the sync-manager watchdog runs out (100 ms of no output write at the ESC's
//!   default registers) until the master writes again. No AL state changes on its own.
//! - The EL3102 has a processor: the AL machine and the mailbox ([`super::firmware`], the same
//!   as the AKD's), an object dictionary of its own (identity, its two TxPDOs and their
//!   assignment 0x1C13, the inputs 0x3101 and 0x3102), and its inputs copied into sync manager 3
//!   from SafeOp on. It answers at once (before the next frame): no capture shows its pace.
//!
//! A terminal's SII image is read when the terminal is made: an image that cannot be read is
//! refused there, naming the terminal and what is wrong.

use crate::error::{Result, SettingError};
use crate::ethercat::al::AlState;
use crate::ethercat::coe::{access, data_type, ObjectCode};
use crate::ethercat::frame::DatagramMut;
use crate::ethercat::link_spec::SimProduct;
use crate::ethercat::pdo::PdoEntry;
use crate::ethercat::registers as reg;
use crate::ethercat::sii::Sii;
use crate::sim::al_machine::AlMachine;
use crate::sim::esc::{Arrival, Esc, Events};
use crate::sim::esc_hardware::{EscHardware, ET1100, ET1200};
use crate::sim::mailbox_server::MailboxServer;
use crate::sim::od::{self, ObjectDictionary};
use crate::sim::process_data::{self, Image};
use crate::sim::sync_manager::{self, SyncManager};
use crate::sim::terminal_sii::{self as images, Kind, TerminalSii};
use crate::sim::{firmware, watchdog};

/// How long a digital input terminal's input filter holds a change back (the EL1004's and the
/// EL1008's 3 ms).
pub const INPUT_FILTER_NS: u64 = 3_000_000;
/// The EL3102's input range, ±10 V, and the value it gives at its end.
pub const ANALOG_RANGE_V: f64 = 10.0;
const ANALOG_FULL_SCALE: f64 = 32767.0;

/// The image description of each terminal product; `None` for the AKD.
pub fn description(product: SimProduct) -> Option<TerminalSii> {
    Some(match product {
        SimProduct::Akd => return None,
        SimProduct::Ek1100 => images::EK1100,
        SimProduct::El1004 => images::EL1004,
        SimProduct::El1008 => images::EL1008,
        SimProduct::El2004 => images::EL2004,
        SimProduct::El2008 => images::EL2008,
        SimProduct::El3102 => images::EL3102,
    })
}

/// A terminal's I/O as a query reports it; bit n of a mask is channel n + 1.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TerminalState {
    /// The product.
    pub product: SimProduct,
    /// AL status (state bits and the error flag).
    pub al_status: u16,
    /// Digital inputs as the master reads them (after the filter).
    pub inputs: u16,
    /// How many digital inputs it has.
    pub input_count: u8,
    /// Digital outputs as the pins drive them.
    pub outputs: u16,
    /// How many digital outputs it has.
    pub output_count: u8,
    /// Analog inputs, V.
    pub analog_inputs: [f64; 2],
    /// How many analog inputs it has.
    pub analog_count: u8,
    /// Whether the sync-manager watchdog ran out and holds the outputs off.
    pub watchdog_expired: bool,
}

/// A digital input terminal's inputs and their filter.
#[derive(Clone, Copy, Debug, Default)]
struct Filter {
    /// The levels at the terminal's connector.
    wanted: u16,
    /// The levels past the filter, as the master reads them.
    shown: u16,
    /// Since when the levels at the connector differ from those shown.
    since_ns: Option<u64>,
}

/// The processor of a terminal that has one (the EL3102).
struct Processor {
    al: AlMachine,
    mailbox: MailboxServer,
    od: ObjectDictionary,
    tx_image: Image,
    pending_control: Option<u16>,
    pending_mailbox: bool,
    volts: [f64; 2],
}

/// What is behind the ESC.
enum Io {
    None,
    DigitalInputs(Filter),
    DigitalOutputs { pins: u16, watchdog_expired: bool },
    Processor(Box<Processor>),
}

/// The ESC a terminal `description` describes is built on: a coupler's ET1100, the others'
/// ET1200.
pub fn hardware(description: &TerminalSii) -> EscHardware {
    if description.kind == Kind::Coupler {
        ET1100
    } else {
        ET1200
    }
}

/// One virtual terminal.
pub struct VirtualTerminal {
    product: SimProduct,
    description: TerminalSii,
    esc: Esc,
    has_successor: bool,
    watchdog: watchdog::Watchdog,
    io: Io,
}

impl VirtualTerminal {
    /// Terminal `product`, which `description` describes ([`description`]), at power-up with
    /// the SII image it is made from; `has_successor` tells whether another slave follows on
    /// port 1.
    pub fn new(product: SimProduct, description: TerminalSii, has_successor: bool) -> Result<Self> {
        let image =
            description.image().map_err(|error| SettingError::TerminalImage { product: product.name(), error })?;
        Self::with_sii(product, description, image, has_successor)
    }

    /// [`new`](Self::new) serving the EEPROM `sii` (its own, or one a test corrupted): refused
    /// when the image cannot be read.
    pub fn with_sii(product: SimProduct, description: TerminalSii, sii: Vec<u8>, has_successor: bool) -> Result<Self> {
        let parsed =
            Sii::parse(&sii).map_err(|error| SettingError::TerminalImage { product: product.name(), error })?;
        let mut esc = Esc::with_hardware(hardware(&description), sii, has_successor);
        let io = match description.kind {
            Kind::Coupler => Io::None,
            Kind::DigitalInputs { .. } => Io::DigitalInputs(Filter::default()),
            Kind::DigitalOutputs { .. } => Io::DigitalOutputs { pins: 0, watchdog_expired: false },
            Kind::AnalogInputs { .. } => {
                firmware::deactivate_sync_managers(&mut esc);
                Io::Processor(Box::new(Processor {
                    al: AlMachine::power_up(),
                    mailbox: MailboxServer::of_protocols(parsed.header.mailbox_protocols),
                    od: analog_dictionary(&description),
                    tx_image: Image::new(),
                    pending_control: None,
                    pending_mailbox: false,
                    volts: [0.0; 2],
                }))
            }
        };
        Ok(VirtualTerminal { product, description, esc, has_successor, watchdog: watchdog::Watchdog::default(), io })
    }

    /// The product.
    pub fn product(&self) -> SimProduct {
        self.product
    }

    /// The ESC's register and RAM space.
    pub fn registers(&self) -> &[u8] {
        self.esc.memory()
    }

    /// The terminal loses its power and comes back as at power-up, with the same EEPROM; the
    /// levels at its input connector stay what they were.
    pub fn power_cycle(&mut self) {
        let sii = self.esc.sii().to_vec();
        let (wanted, volts) = match &self.io {
            Io::DigitalInputs(filter) => (filter.wanted, [0.0; 2]),
            Io::Processor(p) => (0, p.volts),
            _ => (0, [0.0; 2]),
        };
        if let Ok(fresh) = Self::with_sii(self.product, self.description, sii, self.has_successor) {
            *self = fresh;
        }
        match &mut self.io {
            Io::DigitalInputs(filter) => filter.wanted = wanted,
            Io::Processor(p) => p.volts = volts,
            _ => {}
        }
    }

    /// Its ESC.
    pub fn esc(&self) -> &Esc {
        &self.esc
    }

    /// Its ESC, for the line to set its links and count what the frames meet at its ports.
    pub(super) fn esc_mut(&mut self) -> &mut Esc {
        &mut self.esc
    }

    /// The number of digital inputs, outputs and analog inputs.
    fn counts(&self) -> (u8, u8, u8) {
        match self.description.kind {
            Kind::Coupler => (0, 0, 0),
            Kind::DigitalInputs { channels } => (channels, 0, 0),
            Kind::DigitalOutputs { channels } => (0, channels, 0),
            Kind::AnalogInputs { channels } => (0, 0, channels),
        }
    }

    /// Checks that `product` (at `position`, for the error) has input `input` (from 1) of the
    /// kind asked: a digital one, or an analog one where `analog`.
    pub fn check_input(product: SimProduct, position: usize, input: usize, analog: bool) -> Result<()> {
        let kind = description(product).map(|d| d.kind);
        let count = match (kind, analog) {
            (Some(Kind::DigitalInputs { channels }), false) | (Some(Kind::AnalogInputs { channels }), true) => {
                usize::from(channels)
            }
            _ => 0,
        };
        if (1..=count).contains(&input) {
            return Ok(());
        }
        let kind = if analog { "analog" } else { "digital" };
        Err(SettingError::TerminalInput { position, product: product.name(), input, count, kind }.into())
    }

    /// Checks an analog input voltage: finite, within the EL3102's ±10 V.
    pub fn check_volts(volts: f64) -> Result<()> {
        if volts.is_finite() && volts.abs() <= ANALOG_RANGE_V {
            return Ok(());
        }
        Err(SettingError::AnalogInputVolts { volts, limit: ANALOG_RANGE_V }.into())
    }

    /// Sets digital input `input` (from 1, checked by [`check_input`](Self::check_input)) at the
    /// connector; the master sees it once the filter let it through.
    pub fn set_input(&mut self, input: usize, high: bool) {
        if let Io::DigitalInputs(filter) = &mut self.io {
            let bit = 1u16 << (input - 1);
            filter.wanted = if high { filter.wanted | bit } else { filter.wanted & !bit };
        }
    }

    /// Sets analog input `input` (from 1) to `volts` (both checked).
    pub fn set_analog_input(&mut self, input: usize, volts: f64) {
        if let Io::Processor(p) = &mut self.io {
            p.volts[input - 1] = volts;
        }
    }

    /// The terminal's I/O now.
    pub fn state(&self) -> TerminalState {
        let (input_count, output_count, analog_count) = self.counts();
        let mut state = TerminalState {
            product: self.product,
            al_status: self.esc.u16_at(reg::AL_STATUS),
            inputs: 0,
            input_count,
            outputs: 0,
            output_count,
            analog_inputs: [0.0; 2],
            analog_count,
            watchdog_expired: false,
        };
        match &self.io {
            Io::None => {}
            Io::DigitalInputs(filter) => state.inputs = filter.shown,
            Io::DigitalOutputs { pins, watchdog_expired } => {
                (state.outputs, state.watchdog_expired) = (*pins, *watchdog_expired)
            }
            Io::Processor(p) => state.analog_inputs = p.volts,
        }
        state
    }

    /// Serves one datagram passing the terminal at bus time `now_ns`.
    pub fn serve(&mut self, dg: &mut DatagramMut<'_>, now_ns: u64, arrival: Arrival) {
        self.esc.serve(dg, arrival);
        let events = self.esc.take_events();
        if events == Events::default() {
            return;
        }
        if events.watchdog_trigger {
            self.watchdog.trigger(now_ns);
        }
        if events.outputs_written && matches!(self.io, Io::DigitalOutputs { .. }) {
            // The ESC drives the pins from the register once the sync manager's buffer is
            // written, in the frame.
            self.poll(now_ns);
        }
        if let Io::Processor(p) = &mut self.io {
            if let Some(control) = events.al_control {
                p.pending_control = Some(control);
            }
            p.pending_mailbox |= events.mailbox_written;
            if events.repeat_request {
                firmware::repeat_reply(&mut self.esc, &mut p.mailbox);
            }
        }
    }

    /// What the terminal does between frames, up to bus time `now_ns`.
    pub fn poll(&mut self, now_ns: u64) {
        let expired = self.watchdog.expired(now_ns, self.esc.memory_mut());
        let al_state = self.esc.memory()[reg::AL_STATUS as usize] & 0x0F;
        let mask = |count: u8| ((1u32 << count) - 1) as u16;
        let (inputs, outputs, _) = self.counts();
        match &mut self.io {
            Io::None => {}
            Io::DigitalInputs(filter) => {
                if filter.wanted == filter.shown {
                    filter.since_ns = None;
                } else if now_ns.saturating_sub(*filter.since_ns.get_or_insert(now_ns)) >= INPUT_FILTER_NS {
                    (filter.shown, filter.since_ns) = (filter.wanted, None);
                }
                let at = usize::from(images::DIGITAL_INPUTS);
                self.esc.memory_mut()[at] = (filter.shown & mask(inputs)) as u8;
            }
            Io::DigitalOutputs { pins, watchdog_expired } => {
                let register = u16::from(self.esc.memory()[usize::from(images::DIGITAL_OUTPUTS)]);
                let driven = al_state == AlState::Op as u8 && !expired;
                *pins = if driven { register & mask(outputs) } else { 0 };
                *watchdog_expired = expired;
            }
            Io::Processor(p) => p.run(&mut self.esc, now_ns),
        }
    }
}

impl Processor {
    fn run(&mut self, esc: &mut Esc, now_ns: u64) {
        if let Some(control) = self.pending_control.take() {
            esc.release_al_control();
            self.handle_al_control(esc, control);
        }
        if std::mem::take(&mut self.pending_mailbox) {
            firmware::take_request(esc, &mut self.mailbox, &mut self.od, self.al.state(), now_ns);
        }
        firmware::offer_reply(esc, &mut self.mailbox);
        if self.al.state() >= AlState::SafeOp && self.al.state() != AlState::Bootstrap {
            for (n, volts) in self.volts.iter().enumerate() {
                let value = (volts / ANALOG_RANGE_V * ANALOG_FULL_SCALE).round() as i16;
                self.od.set(images::analog_object(n as u8), 2, &value.to_le_bytes());
            }
            process_data::refresh_inputs_at(&self.od, esc.memory_mut(), &self.tx_image, images::EL3102_INPUTS);
        }
    }

    fn handle_al_control(&mut self, esc: &mut Esc, control: u16) {
        let (od, memory) = (&self.od, esc.memory());
        let mailbox = images::EL3102_MAILBOX;
        let transition = self.al.request(control, |from, to| match (from, to) {
            (AlState::Init, AlState::PreOp) => sync_manager::check_mailbox_at(
                memory,
                (mailbox.receive_offset, mailbox.send_offset),
                mailbox.receive_size,
            ),
            (AlState::PreOp, AlState::SafeOp) => {
                let (rx, tx) = process_data::images(od);
                let bytes = |image: &[PdoEntry]| crate::ethercat::pdo::bit_len(image).div_ceil(8);
                let sm = |n| SyncManager::read(memory, n);
                process_data::check_sync_manager(&sm(2), images::EL3102_OUTPUTS, bytes(&rx), true)?;
                process_data::check_sync_manager(&sm(3), images::EL3102_INPUTS, bytes(&tx), false)
            }
            _ => Ok(()),
        });
        if let Some(t) = transition {
            firmware::enter_state(esc, &mut self.mailbox, t.to);
            if t.from == AlState::PreOp && t.to == AlState::SafeOp {
                self.tx_image = process_data::images(&self.od).1;
            }
        }
        firmware::write_al_status(esc, &self.al);
    }
}

/// 0x1C13 takes the EL3102's own TxPDOs only.
fn tx_assignment(
    _: &ObjectDictionary,
    object: &od::Object,
    written: u8,
) -> Result<(), crate::ethercat::coe::SdoAbortCode> {
    let chosen = object.unsigned(written) as u16;
    match written {
        0 if object.unsigned(0) <= 2 => Ok(()),
        1 | 2 if matches!(chosen, 0x1A00 | 0x1A01) => Ok(()),
        _ => Err(crate::ethercat::coe::SdoAbortCode::VALUE_RANGE),
    }
}

/// The EL3102's object dictionary: identity, its two fixed TxPDOs, their assignment, and the
/// inputs (0x3101 and 0x3102: status byte and value).
fn analog_dictionary(description: &TerminalSii) -> ObjectDictionary {
    use data_type::{INTEGER16, UNSIGNED16, UNSIGNED8};
    let Kind::AnalogInputs { channels } = description.kind else { unreachable!("an analog terminal") };
    let ro_tx = od::RO | access::TX_PDO;
    let mut objects = vec![
        od::string_var(0x1008, "Device name", description.order),
        od::identity_object("Identity", "Revision", description.identity),
        od::array(0x1C00, "Sync manager type", UNSIGNED8, od::RO, od::RO, 1..=4),
        od::record(0x1C12, "RxPDO assign", ObjectCode::Array, UNSIGNED16, od::RW_PREOP, Vec::new()),
    ];
    let names = ["Inputs Ch.1", "Inputs Ch.2"];
    for n in 0..channels {
        let object = images::analog_object(n);
        let entries = [PdoEntry::new(object, 1, 8), PdoEntry::new(object, 2, 16)];
        let pdo = 0x1A00 + u16::from(n);
        let name = if n == 0 { "TxPDO-Map Channel 1" } else { "TxPDO-Map Channel 2" };
        objects.push(od::mapping_object(pdo, name, od::RO, &entries, entries.len()));
        objects.push(od::record(
            object,
            names[usize::from(n)],
            ObjectCode::Record,
            INTEGER16,
            od::RO,
            vec![od::entry(1, "Status", UNSIGNED8, 8, ro_tx, 0), od::entry(2, "Value", INTEGER16, 16, ro_tx, 0)],
        ));
    }
    let pdos = (0..channels).map(|n| 0x1A00 + u64::from(n));
    let mut tx_assign = od::array(0x1C13, "TxPDO assign", UNSIGNED16, od::RW_PREOP, od::RW_PREOP, pdos);
    tx_assign.check = Some(tx_assignment);
    objects.push(tx_assign);
    ObjectDictionary::from_objects(objects)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ethercat::frame::{Command, FrameBuilder};
    use crate::sim::tests::exchange;
    use crate::sim::{Timing, VirtualBus};

    fn line(spec: &str) -> VirtualBus {
        VirtualBus::of_line(&spec.parse().unwrap(), Timing::IMMEDIATE).unwrap()
    }

    /// Station addresses 0x1001.. as SOEM gives them.
    fn address(bus: &mut VirtualBus) {
        for i in 0..bus.len() as u16 {
            exchange(bus, 0, Command::Apwr, 0u16.wrapping_sub(i), 0x0010, &(0x1001 + i).to_le_bytes());
        }
    }

    /// An FMMU's 16 bytes: logical start and bits, length, physical start and bit, type.
    fn fmmu(logical: u32, len: u16, bits: (u8, u8), physical: u16, physical_bit: u8, kind: u8) -> [u8; 16] {
        let mut r = [0u8; 16];
        r[..4].copy_from_slice(&logical.to_le_bytes());
        r[4..6].copy_from_slice(&len.to_le_bytes());
        (r[6], r[7]) = bits;
        r[8..10].copy_from_slice(&physical.to_le_bytes());
        (r[10], r[11], r[12]) = (physical_bit, kind, 1);
        r
    }

    #[test]
    fn terminals_answer_with_their_escs_and_images() {
        let mut bus = line("ek1100,el1004,el2004");
        // ET1100 0x11 ORed with two ET1200s 0x12 revision 1, as SOEM read 0x13 0x01.
        assert_eq!(exchange(&mut bus, 0, Command::Brd, 0, 0x0000, &[0, 0]), (vec![0x13, 0x01], 3));
        address(&mut bus);
        assert_eq!(exchange(&mut bus, 0, Command::Fprd, 0x1001, 0x0140, &[0, 0]).0, [0x00, 0x0D]);
        assert_eq!(exchange(&mut bus, 0, Command::Fprd, 0x1002, 0x0140, &[0, 0]).0, [0x04, 0x01]);
        assert_eq!(exchange(&mut bus, 0, Command::Fprd, 0x1001, 0x0110, &[0, 0]).0, [0x31, 0x5A]);
        assert_eq!(exchange(&mut bus, 0, Command::Fprd, 0x1003, 0x0110, &[0, 0]).0, [0x13, 0x56]);
        // An ET1200 has no DC system time and no fourth FMMU: nothing answers there.
        assert_eq!(exchange(&mut bus, 0, Command::Fprd, 0x1002, 0x0918, &[0; 8]).1, 0);
        assert_eq!(exchange(&mut bus, 0, Command::Bwr, 0, 0x0630, &[0; 16]).1, 1);
        assert_eq!(exchange(&mut bus, 0, Command::Bwr, 0, 0x0910, &[0; 4]).1, 1);
        // The EEPROM: 8 bytes a read, busy for 0.65 ms, bit 4 set below SafeOp on the ET1200.
        exchange(&mut bus, 1_000, Command::Fpwr, 0x1002, 0x0502, &[0x00, 0x01, 0x0A, 0, 0, 0]);
        assert_eq!(exchange(&mut bus, 500_000, Command::Fprd, 0x1002, 0x0502, &[0, 0]).0, [0x50, 0x81]);
        assert_eq!(exchange(&mut bus, 700_000, Command::Fprd, 0x1002, 0x0502, &[0, 0]).0, [0x50, 0x00]);
        let (data, _) = exchange(&mut bus, 700_000, Command::Fprd, 0x1002, 0x0508, &[0; 8]);
        assert_eq!(data, images::EL1004.image().unwrap()[0x14..0x1C]);
        assert_eq!(exchange(&mut bus, 0, Command::Fprd, 0x1001, 0x0502, &[0, 0]).0, [0x40, 0x00]);
        // Device emulation: AL control is AL status at once, the error acknowledge included.
        exchange(&mut bus, 800_000, Command::Bwr, 0, 0x0120, &[0x12, 0x00]);
        assert_eq!(exchange(&mut bus, 800_000, Command::Brd, 0, 0x0130, &[0, 0]), (vec![0x12, 0x00], 3));
        exchange(&mut bus, 800_000, Command::Bwr, 0, 0x0120, &[0x08, 0x00]);
        assert_eq!(exchange(&mut bus, 800_000, Command::Fprd, 0x1002, 0x0130, &[0; 6]).0, [0x08, 0, 0, 0, 0, 0]);
        assert_eq!(exchange(&mut bus, 800_000, Command::Fprd, 0x1002, 0x0502, &[0, 0]).0, [0x40, 0x00]);
    }

    #[test]
    fn a_slave_behind_another_shows_its_link_coming_up_in_the_irq_word() {
        /// The IRQ word of one BRD of the AL status.
        fn irq(bus: &mut VirtualBus) -> u16 {
            let mut buf = [0u8; 64];
            let mut b = FrameBuilder::new(&mut buf);
            b.push(Command::Brd, 0, 0, 0x0130, &[0, 0]).unwrap();
            let len = b.finish();
            bus.process(&mut buf[..len], 0).unwrap();
            u16::from_le_bytes([buf[10], buf[11]])
        }
        let mut bus = line("ek1100,el1004");
        address(&mut bus);
        assert_eq!(irq(&mut bus), 0, "masked");
        // As SOEM: the ECAT event mask to the DL status event; the EL1004's is pending from power-up.
        exchange(&mut bus, 0, Command::Bwr, 0, 0x0200, &[0x04, 0x00]);
        assert_eq!(irq(&mut bus), 0x0004);
        // The EK1100's DL status read leaves it, the EL1004's clears it.
        exchange(&mut bus, 0, Command::Fprd, 0x1001, 0x0110, &[0, 0]);
        assert_eq!(irq(&mut bus), 0x0004);
        exchange(&mut bus, 0, Command::Fprd, 0x1002, 0x0110, &[0, 0]);
        assert_eq!(irq(&mut bus), 0);
        // A power cycle takes the EK1100's port 1 link down and up again: its DL status changed,
        // which its event says until the DL status is read. The EL1004's link comes up again; its
        // mask is at power-up's.
        bus.power_cycle(1);
        assert_eq!(irq(&mut bus), 0x0004);
        exchange(&mut bus, 0, Command::Fprd, 0x1001, 0x0110, &[0, 0]);
        assert_eq!(irq(&mut bus), 0);
        exchange(&mut bus, 0, Command::Bwr, 0, 0x0200, &[0x04, 0x00]);
        assert_eq!(irq(&mut bus), 0x0004);
    }

    #[test]
    fn digital_terminals_follow_the_process_data_as_soem_packs_it() {
        let mut bus = line("ek1100,el1004,el2004,el2004");
        address(&mut bus);
        // As SOEM sets them from the SII: the EL1004's SM0 at 0x1000 (1 byte, read), the
        // EL2004s' at 0x0F00 (1 byte, written, watchdog); the outputs' 4 bits of each EL2004 in
        // bits 0-3 and 4-7 of logical byte 0, the inputs in bits 0-3 of logical byte 1.
        exchange(&mut bus, 0, Command::Fpwr, 0x1002, 0x0800, &[0x00, 0x10, 1, 0, 0x00, 0, 1, 0]);
        exchange(&mut bus, 0, Command::Fpwr, 0x1002, 0x0600, &fmmu(1, 1, (0, 3), 0x1000, 0, 1));
        for (station, bits) in [(0x1003, (0, 3)), (0x1004, (4, 7))] {
            exchange(&mut bus, 0, Command::Fpwr, station, 0x0800, &[0x00, 0x0F, 1, 0, 0x44, 0, 9, 0]);
            exchange(&mut bus, 0, Command::Fpwr, station, 0x0600, &fmmu(0, 1, bits, 0x0F00, 0, 2));
        }
        exchange(&mut bus, 0, Command::Bwr, 0, 0x0120, &[0x08, 0x00]);
        bus.at_mut(1).terminal_mut().unwrap().set_input(2, true);
        bus.at_mut(1).terminal_mut().unwrap().set_input(4, true);
        // Outputs 1 and 3 of the first EL2004, 2 and 4 of the second; the inputs pass the
        // 3 ms filter after the change reached the terminal.
        let frame = |bus: &mut VirtualBus, now| exchange(bus, now, Command::Lrw, 0, 0, &[0x05 | 0xA0, 0]);
        // One working counter per slave read (EL1004) and two per slave written.
        assert_eq!(frame(&mut bus, 1_000_000), (vec![0xA5, 0x00], 5));
        assert_eq!(frame(&mut bus, 3_999_999), (vec![0xA5, 0x00], 5));
        assert_eq!(frame(&mut bus, 4_000_000), (vec![0xA5, 0x0A], 5));
        let state = |bus: &VirtualBus, i: usize| bus.at(i).terminal().unwrap().state();
        assert_eq!((state(&bus, 2).outputs, state(&bus, 3).outputs), (0x05, 0x0A));
        assert_eq!((state(&bus, 1).inputs, state(&bus, 1).input_count), (0x0A, 4));
        // No output written for 100 ms (the ESC's default watchdog): the pins drop to off.
        bus.advance(104_000_001);
        assert_eq!((state(&bus, 2).outputs, state(&bus, 2).watchdog_expired), (0, true));
        assert_eq!(state(&bus, 2).al_status, 0x08, "no firmware to leave Op");
        frame(&mut bus, 105_000_000);
        assert_eq!((state(&bus, 2).outputs, state(&bus, 2).watchdog_expired), (0x05, false));
        // Out of Op the pins are off whatever the process data says.
        exchange(&mut bus, 106_000_000, Command::Bwr, 0, 0x0120, &[0x04, 0x00]);
        frame(&mut bus, 106_000_000);
        assert_eq!(state(&bus, 3).outputs, 0);
    }

    #[test]
    fn the_el3102_runs_its_mailbox_and_inputs_through_the_shared_firmware() {
        let mut bus = line("ek1100,el3102");
        address(&mut bus);
        bus.at_mut(1).terminal_mut().unwrap().set_analog_input(2, -5.0);
        // Without its mailbox sync managers it refuses PreOp (0x0017), as the AKD does.
        exchange(&mut bus, 0, Command::Fpwr, 0x1002, 0x0120, &[0x02, 0x00]);
        assert_eq!(exchange(&mut bus, 1, Command::Fprd, 0x1002, 0x0130, &[0; 6]).0, [0x11, 0, 0, 0, 0x17, 0]);
        exchange(&mut bus, 2, Command::Fpwr, 0x1002, 0x0800, &[0x00, 0x10, 0x80, 0, 0x26, 0, 1, 0]);
        exchange(&mut bus, 2, Command::Fpwr, 0x1002, 0x0808, &[0x80, 0x10, 0x80, 0, 0x22, 0, 1, 0]);
        exchange(&mut bus, 2, Command::Fpwr, 0x1002, 0x0120, &[0x12, 0x00]);
        assert_eq!(exchange(&mut bus, 3, Command::Fprd, 0x1002, 0x0130, &[0; 6]).0, [0x02, 0, 0, 0, 0, 0]);
        // An SDO upload of 0x1C13:02, the second TxPDO assigned.
        let mut request = [0u8; 0x80];
        request[..16].copy_from_slice(&[0x0A, 0, 0, 0, 0, 0x13, 0x00, 0x20, 0x40, 0x13, 0x1C, 0x02, 0, 0, 0, 0]);
        exchange(&mut bus, 4, Command::Fpwr, 0x1002, 0x1000, &request);
        let (reply, wkc) = exchange(&mut bus, 5, Command::Fprd, 0x1002, 0x1080, &[0; 0x80]);
        assert_eq!(
            (&reply[..16], wkc),
            (&[0x0A, 0, 0, 0, 0, 0x13, 0x00, 0x30, 0x4B, 0x13, 0x1C, 0x02, 0x01, 0x1A, 0, 0][..], 1)
        );
        // It declares CoE only: an EoE message gets a mailbox error (service 2: unsupported protocol).
        let mut eoe = [0u8; 0x80];
        eoe[..8].copy_from_slice(&[0x02, 0, 0, 0, 0, 0x22, 0x00, 0x00]);
        exchange(&mut bus, 6, Command::Fpwr, 0x1002, 0x1000, &eoe);
        let (reply, _) = exchange(&mut bus, 7, Command::Fprd, 0x1002, 0x1080, &[0; 0x80]);
        assert_eq!((reply[5] & 0x0F, &reply[6..10]), (0x00, &[0x01, 0x00, 0x02, 0x00][..]));
        // SafeOp with SM3 of its 6 input bytes, then the inputs: status 0 and the value.
        exchange(&mut bus, 8, Command::Fpwr, 0x1002, 0x0818, &[0x80, 0x11, 6, 0, 0x20, 0, 1, 0]);
        exchange(&mut bus, 8, Command::Fpwr, 0x1002, 0x0120, &[0x04, 0x00]);
        assert_eq!(exchange(&mut bus, 9, Command::Fprd, 0x1002, 0x0130, &[0; 6]).0, [0x04, 0, 0, 0, 0, 0]);
        let (inputs, _) = exchange(&mut bus, 10, Command::Fprd, 0x1002, 0x1180, &[0; 6]);
        let half = (-16384i16).to_le_bytes();
        assert_eq!(inputs, [0, 0, 0, 0, half[0], half[1]]);
    }

    #[test]
    fn a_corrupt_image_is_refused_in_one_line_naming_the_terminal() {
        let image = images::EL1004.image().unwrap();
        let refused = |at: usize| {
            let mut corrupt = image.clone();
            corrupt[at] ^= 0xFF;
            let made = VirtualTerminal::with_sii(SimProduct::El1004, images::EL1004, corrupt, false);
            made.err().map(|e| e.to_string()).unwrap_or_default()
        };
        // The header checksum (word 7), and the general category's name (string 4, byte 0x10B).
        let checksum = refused(0x0E);
        assert!(checksum.starts_with("configuration: the virtual el1004's SII image cannot be read: "), "{checksum}");
        assert!(checksum.contains("checksum") && !checksum.contains('\n'), "{checksum}");
        let name = refused(0x10B);
        assert!(name.starts_with("configuration: the virtual el1004's SII image cannot be read: "), "{name}");
        assert!(name.contains("name") && !name.contains('\n'), "{name}");
    }

    #[test]
    fn commands_are_checked_against_the_terminal() {
        let e = |r: Result<()>| r.unwrap_err().to_string();
        assert_eq!(
            e(VirtualTerminal::check_input(SimProduct::El1004, 1, 5, false)),
            "configuration: digital input 5: the el1004 at position 1 has digital inputs 1 to 4"
        );
        assert_eq!(
            e(VirtualTerminal::check_input(SimProduct::El2004, 2, 1, false)),
            "configuration: digital input 1: the el2004 at position 2 has no digital inputs"
        );
        assert!(VirtualTerminal::check_input(SimProduct::El1008, 1, 8, false).is_ok());
        assert!(VirtualTerminal::check_input(SimProduct::El3102, 1, 2, true).is_ok());
        assert_eq!(
            e(VirtualTerminal::check_volts(10.5)),
            "configuration: analog input of 10.5 V: allowed are -10 to 10 V"
        );
        assert!(VirtualTerminal::check_volts(f64::NAN).is_err());
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig::with_cases(256))]

        /// Any datagrams, at any bus time, through a line of every kind of slave: each frame is
        /// served (or refused untouched) without a panic, whatever the FMMUs and sync managers
        /// the earlier ones set.
        #[test]
        fn any_datagrams_through_a_mixed_line_are_served(
            datagrams in proptest::collection::vec(
                (0u8..15, proptest::prelude::any::<u16>(), proptest::prelude::any::<u16>(),
                 proptest::collection::vec(proptest::prelude::any::<u8>(), 0..48), 0u64..200_000_000),
                1..40,
            )
        ) {
            let mut bus = line("ek1100,el1004,el2004,el3102,akd");
            // Some set-up a master does, so that logical datagrams meet active FMMUs, and an
            // empty logical datagram at their start.
            address(&mut bus);
            for station in 0x1002..=0x1003u16 {
                exchange(&mut bus, 0, Command::Fpwr, station, 0x0600, &fmmu(0, 2, (3, 5), 0x0F00, 2, 3));
            }
            assert_eq!(exchange(&mut bus, 0, Command::Lrw, 0, 0, &[]).1, 0);
            let mut now = 0;
            for (command, adp, ado, data, step) in datagrams {
                now += step;
                let Ok(command) = Command::try_from(command) else { continue };
                let mut buf = [0u8; 1500];
                let mut b = FrameBuilder::new(&mut buf);
                b.push(command, 0, adp, ado, &data).unwrap();
                let len = b.finish();
                bus.process(&mut buf[..len], now).unwrap();
            }
        }
    }
}
