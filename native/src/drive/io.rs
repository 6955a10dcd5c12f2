//! The AKD's own I/O in its process data — digital inputs 0x60FD, digital outputs 0x60FE:01,
//! the analog input 0x3470:04 and the analog output set-point 0x3470:03 (AKD manual §5.5–5.7) — which mappings carry them, what their
//! bits mean, and what one drive's process image says of them.
//!
//! What the manuals give, and what they leave out:
//! - the objects, their data types, and the mappings that carry them: the fixed 0x1720, 0x1722
//!   and 0x1723 the digital outputs, 0x1B20–0x1B25 the digital and analog inputs (the real
//!   drive's SII adds 0x1725 with both outputs and 0x1B26 with both inputs), and any flexible
//!   mapping within the AKD's rules;
//! - no bit layout of 0x60FD or 0x60FE. CiA 402 gives one [std]: 0x60FD bit 0 negative limit
//!   switch, 1 positive limit switch, 2 home switch, 3 interlock, bits 16–31 the manufacturer's;
//!   0x60FE:01 bits 16–31 the manufacturer's, and 0x60FE:02 a bit mask of the outputs the master
//!   may drive, whose use on the AKD the manuals do not describe (nothing here writes it). The AKD's digital inputs 1..7 are taken at
//!   bits 16..22 and its digital outputs 1..2 at bits 16..17 of the manufacturer's bits, in the
//!   AKD's own numbering: a choice the manuals neither confirm nor refute;
//! - no scaling of the analog values: [`ANALOG_VOLTS_PER_COUNT`] assumes ±10 V over the INT16
//!   range, an assumption the node lets an integrator correct (`io.analog_scale`);
//! - no object that carries the hardware enable input. What the drive shows of it is its
//!   reaction (with FBUS.PARAM05 bit 1 = 0, §5.14: Switched on and Operation enabled fall back
//!   to Switch on disabled while it is low) and the statusword's warning (bit 7), which the AKD
//!   raises for several reasons: [`hardware_enable`] reads the input from those two.

use crate::drive::ds402::{statusword, Mode, State};
use crate::drive::objects;
use crate::drive::pdo;
use crate::ethercat::pdo::{find, Direction, PdoEntry};
use crate::setting::SettingError;

/// Digital inputs 0x60FD (index, subindex).
pub const DIGITAL_INPUTS: (u16, u8) = (0x60FD, 0);
/// Digital outputs 0x60FE:01.
pub const DIGITAL_OUTPUTS: (u16, u8) = (0x60FE, 1);
/// The analog input as the fixed mappings carry it, 0x3470:04 ("AIN.VALUE" in the drive's SII).
pub const ANALOG_INPUT: (u16, u8) = (0x3470, 4);
/// The analog output set-point 0x3470:03 ("AOUT.VALUE write").
pub const ANALOG_OUTPUT: (u16, u8) = (0x3470, 3);

/// The AKD's digital inputs, DIN1..DIN7.
pub const INPUT_COUNT: u8 = 7;
/// The AKD's digital outputs, DOUT1 and DOUT2.
pub const OUTPUT_COUNT: u8 = 2;
/// The bit of 0x60FD that carries digital input 1, and of 0x60FE:01 that drives output 1.
const FIRST_MANUFACTURER_BIT: u8 = 16;
/// Volts per count of the analog input and output: ±10 V over the INT16 range (assumed: the
/// manuals give no scaling).
pub const ANALOG_VOLTS_PER_COUNT: f64 = 10.0 / 32767.0;

wire_codes! {
    /// A switch CiA 402 gives a bit of 0x60FD [std].
    pub enum Switch: u8, "switch" {
        /// Bit 0: the negative limit switch, which stops moves in the negative direction.
        NegativeLimit = 0 => "negative_limit",
        /// Bit 1: the positive limit switch, which stops moves in the positive direction.
        PositiveLimit = 1 => "positive_limit",
        /// Bit 2: the home switch.
        Home = 2 => "home_switch",
        /// Bit 3: the interlock.
        Interlock = 3 => "interlock",
    }
}

impl Switch {
    /// The switch named `name`, or an error naming the switches.
    pub fn from_name(name: &str) -> Result<Switch, SettingError> {
        let allowed = || Self::ALL.iter().map(|s| s.name()).collect();
        Self::ALL
            .iter()
            .copied()
            .find(|s| s.name() == name)
            .ok_or_else(|| SettingError::Switch { name: name.to_owned(), allowed: allowed() })
    }

    /// Its bit in 0x60FD.
    pub const fn mask(self) -> u32 {
        1 << self as u32
    }

    /// Whether `digital_inputs` (0x60FD) shows it active.
    pub fn active(self, digital_inputs: u32) -> bool {
        digital_inputs & self.mask() != 0
    }

    /// The direction of motion it stops (+1 or -1), for a limit switch.
    pub fn guards(self) -> Option<f64> {
        match self {
            Switch::NegativeLimit => Some(-1.0),
            Switch::PositiveLimit => Some(1.0),
            Switch::Home | Switch::Interlock => None,
        }
    }
}

/// The bit of 0x60FD of digital input `input` (1..=[`INPUT_COUNT`]), or of 0x60FE:01 of digital
/// output `input` (1..=[`OUTPUT_COUNT`]).
pub const fn bit(input: u8) -> u32 {
    1 << (FIRST_MANUFACTURER_BIT + input - 1)
}

/// Digital inputs 1..=7 of `digital_inputs` (0x60FD), input 1 in bit 0.
pub fn inputs(digital_inputs: u32) -> u8 {
    (digital_inputs >> FIRST_MANUFACTURER_BIT) as u8 & ((1 << INPUT_COUNT) - 1)
}

/// Digital outputs 1..=2 of `digital_outputs` (0x60FE:01), output 1 in bit 0.
pub fn outputs(digital_outputs: u32) -> u8 {
    (digital_outputs >> FIRST_MANUFACTURER_BIT) as u8 & ((1 << OUTPUT_COUNT) - 1)
}

/// 0x60FE:01 with the AKD's outputs at `levels` (output 1 in bit 0), the other bits as `word` has them.
pub fn with_outputs(word: u32, levels: u8) -> u32 {
    let mask = u32::from((1u8 << OUTPUT_COUNT) - 1) << FIRST_MANUFACTURER_BIT;
    (word & !mask) | (u32::from(levels) << FIRST_MANUFACTURER_BIT & mask)
}

/// 0x60FE:01 `word` with the digital outputs of `levels` (each an output number and its
/// level) set, its other bits as they are; `Err` with the first number the AKD has no output
/// of.
pub fn with_output_levels(word: u32, levels: &[(i64, bool)]) -> Result<u32, i64> {
    let mut now = outputs(word);
    for &(number, high) in levels {
        if !(1..=i64::from(OUTPUT_COUNT)).contains(&number) {
            return Err(number);
        }
        let bit = 1u8 << (number - 1);
        now = if high { now | bit } else { now & !bit };
    }
    Ok(with_outputs(word, now))
}

named_variants! {
    /// The hardware enable input as the drive shows it, numbered as akd_ros/DriveIO's
    /// HARDWARE_ENABLE_* constants.
    pub enum HardwareEnable {
        /// High: the drive is switched on (which it leaves while the input is low), or shows no
        /// warning.
        High = 1 => "high",
        /// Low: the drive is not switched on and shows a warning (statusword bit 7), which the AKD
        /// raises while the input is low, among other reasons.
        Low = 2 => "low",
        /// The statusword shows no valid state.
        Unknown = 0 => "unknown",
    }
    /// "high", "low" or "unknown".
    fn name;
}

/// The hardware enable input as `statusword` shows it (see the module's words on the evidence).
pub fn hardware_enable(statusword: u16) -> HardwareEnable {
    match State::from_statusword(statusword) {
        None => HardwareEnable::Unknown,
        Some(State::SwitchedOn | State::OperationEnabled | State::QuickStopActive) => HardwareEnable::High,
        Some(_) if statusword & statusword::WARNING != 0 => HardwareEnable::Low,
        Some(_) => HardwareEnable::High,
    }
}

/// Which of the drive's I/O a mapping carries.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "python", derive(pyo3::IntoPyObject))]
pub struct Carried {
    /// Digital inputs 0x60FD (with the limit and home switches).
    pub digital_inputs: bool,
    /// The analog input 0x3470:04.
    pub analog_input: bool,
    /// Digital outputs 0x60FE:01.
    pub digital_outputs: bool,
    /// The analog output set-point 0x3470:03.
    pub analog_output: bool,
}

impl Carried {
    /// What the mapping of outputs `rx` and inputs `tx` carries.
    pub fn of(rx: &[PdoEntry], tx: &[PdoEntry]) -> Carried {
        let has = |entries: &[PdoEntry], (index, subindex): (u16, u8)| find(entries, index, subindex).is_some();
        Carried {
            digital_inputs: has(tx, DIGITAL_INPUTS),
            analog_input: has(tx, ANALOG_INPUT),
            digital_outputs: has(rx, DIGITAL_OUTPUTS),
            analog_output: has(rx, ANALOG_OUTPUT),
        }
    }

    /// Whether it carries all four.
    pub fn all(self) -> bool {
        self.digital_inputs && self.analog_input && self.digital_outputs && self.analog_output
    }
}

/// A mapping as the node's `mapping` parameter names it, with what it carries of the I/O.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct IoMapping {
    /// The parameter's value: a named flexible mapping ("io") or fixed ones ("0x1725/0x1B20").
    pub name: String,
    /// What it carries.
    pub carried: Carried,
}

/// The mappings that carry the command of `mode` and what `wanted` asks of the I/O, the best
/// first: akd_ros's own flexible mappings, then each fixed RxPDO that does with the first fixed
/// TxPDO carrying every input of the I/O (0x1B20).
pub fn mappings_for(mode: Mode, wanted: impl Fn(Carried) -> bool) -> Vec<IoMapping> {
    let commands = |rx: &[PdoEntry]| mode.command_objects().iter().all(|&(i, s)| find(rx, i, s).is_some());
    let fixed = |direction| pdo::FIXED.iter().filter(move |p| p.direction == direction);
    let inputs = fixed(Direction::Tx).find(|tx| {
        let carried = Carried::of(&[], tx.entries);
        carried.digital_inputs && carried.analog_input
    });
    let named = pdo::NAMED.iter().map(|(name, rx, tx)| ((*name).to_owned(), rx.concat(), tx.concat()));
    let fixed_pairs = fixed(Direction::Rx).filter_map(|rx| {
        let tx = inputs?;
        Some((format!("0x{:04X}/0x{:04X}", rx.index, tx.index), rx.entries.to_vec(), tx.entries.to_vec()))
    });
    let mut found: Vec<IoMapping> = named
        .chain(fixed_pairs)
        .filter(|(_, rx, _)| commands(rx))
        .map(|(name, rx, tx)| IoMapping { name, carried: Carried::of(&rx, &tx) })
        .filter(|m| wanted(m.carried))
        .collect();
    // Those carrying all of the I/O first, each group in the order above.
    found.sort_by_key(|m| !m.carried.all());
    found
}

/// The mappings [`mappings_for`] finds, in words for a refusal: their names, or where none has
/// it, a flexible mapping.
pub fn mappings_in_words(mode: Mode, wanted: impl Fn(Carried) -> bool) -> String {
    let found: Vec<String> = mappings_for(mode, wanted).into_iter().map(|m| m.name).collect();
    if found.is_empty() {
        "a flexible mapping (mapping.rx, mapping.tx) with it".into()
    } else {
        found.join(", ")
    }
}

/// One drive's I/O in one cycle, read by its mapping: each value `None` where the mapping lacks
/// its object (`Cycle.drives_io` in Python). Raw values in the drive's units (counts of the
/// analog objects, ±10 V over their range as `ANALOG_VOLTS_PER_COUNT` assumes).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "python", pyo3::pyclass(module = "akd_ros._native", frozen, get_all))]
pub struct DriveIo {
    /// The cycle they are from (from 1; 0 where not read from a cycle's snapshot).
    pub cycle: u64,
    /// That cycle's wake-up time on the monotonic clock (ns).
    pub time_ns: u64,
    /// Whether that cycle's exchange succeeded (else the inputs are the last good ones).
    pub fresh: bool,
    /// Statusword 0x6041 (for the hardware enable).
    pub statusword: Option<u16>,
    /// Digital inputs 0x60FD.
    pub digital_inputs: Option<u32>,
    /// Analog input 0x3470:04, counts.
    pub analog_input: Option<i16>,
    /// Digital outputs 0x60FE:01 as sent.
    pub digital_outputs: Option<u32>,
    /// Analog output set-point 0x3470:03 as sent, counts.
    pub analog_output: Option<i16>,
}

impl DriveIo {
    /// Reads a drive's I/O from its `outputs` laid out by `rx` and its `inputs` laid out by `tx`.
    pub fn read(rx: &[PdoEntry], tx: &[PdoEntry], outputs: &[u8], inputs: &[u8]) -> DriveIo {
        let input = |(index, subindex): (u16, u8)| objects::read(tx, inputs, index, subindex);
        let output = |(index, subindex): (u16, u8)| objects::read(rx, outputs, index, subindex);
        DriveIo {
            statusword: input((0x6041, 0)).map(|v| v as u16),
            digital_inputs: input(DIGITAL_INPUTS).map(|v| v as u32),
            analog_input: input(ANALOG_INPUT).map(|v| v as i16),
            digital_outputs: output(DIGITAL_OUTPUTS).map(|v| v as u32),
            analog_output: output(ANALOG_OUTPUT).map(|v| v as i16),
            ..DriveIo::default()
        }
    }

    /// These I/O with the digital inputs and statusword of another cycle (the cycle thread's
    /// event of an input change), where the mapping carries them.
    pub fn with_inputs(self, cycle: u64, time_ns: u64, digital_inputs: u32, statusword: u16) -> DriveIo {
        DriveIo {
            cycle,
            time_ns,
            fresh: true,
            statusword: self.statusword.map(|_| statusword),
            digital_inputs: self.digital_inputs.map(|_| digital_inputs),
            ..self
        }
    }

    /// The levels of digital inputs 1..=[`INPUT_COUNT`], input 1 first; `None` without 0x60FD.
    pub fn input_levels(&self) -> Option<Vec<bool>> {
        self.digital_inputs.map(|word| (0..INPUT_COUNT).map(|i| inputs(word) >> i & 1 == 1).collect())
    }

    /// The levels of digital outputs 1..=[`OUTPUT_COUNT`] as sent, output 1 first; `None`
    /// without 0x60FE:01.
    pub fn output_levels(&self) -> Option<Vec<bool>> {
        self.digital_outputs.map(|word| (0..OUTPUT_COUNT).map(|o| outputs(word) >> o & 1 == 1).collect())
    }

    /// The hardware enable input as the statusword shows it.
    pub fn hardware_enable(&self) -> HardwareEnable {
        self.statusword.map_or(HardwareEnable::Unknown, hardware_enable)
    }
}

/// What the cycle thread watches of one drive's I/O to report each change in the cycle it
/// happens: the digital inputs and the hardware enable as the statusword shows it. Where in
/// the drive's inputs 0x60FD sits, and what the last cycle showed.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct InputWatch {
    digital_inputs: Option<usize>,
    statusword: usize,
    last: Option<(u32, HardwareEnable)>,
}

impl InputWatch {
    /// Watches the digital inputs at `digital_inputs` (offset in the whole input image, where
    /// mapped) and the statusword at `statusword`.
    pub fn new(digital_inputs: Option<usize>, statusword: usize) -> Self {
        InputWatch { digital_inputs, statusword, last: None }
    }

    /// This cycle's `inputs` (the whole image): the digital inputs and statusword when they
    /// differ from the last cycle's in what they say, else `None` (also on the first cycle,
    /// which sets what the next ones are compared with).
    pub fn observe(&mut self, inputs: &[u8]) -> Option<(u32, u16)> {
        let word = |at: usize, len: usize| {
            inputs.get(at..at + len).map(|b| b.iter().rev().fold(0u32, |v, x| v << 8 | *x as u32))
        };
        let digital = self.digital_inputs.and_then(|at| word(at, 4)).unwrap_or(0);
        let statusword = word(self.statusword, 2)? as u16;
        let now = (digital, hardware_enable(statusword));
        let last = self.last.replace(now);
        (last.is_some() && last != Some(now)).then_some((digital, statusword))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_bits_of_the_switches_inputs_and_outputs() {
        let word = Switch::PositiveLimit.mask() | Switch::Home.mask() | bit(1) | bit(7);
        assert!(Switch::PositiveLimit.active(word) && !Switch::NegativeLimit.active(word));
        assert_eq!(inputs(word), 0b100_0001);
        assert_eq!(Switch::from_name("negative_limit"), Ok(Switch::NegativeLimit));
        assert_eq!(with_outputs(0x0000_0001, 0b10), 0x0002_0001, "bit 0 (set brake) kept");
        assert_eq!(outputs(with_outputs(0, 0b11)), 0b11);
    }

    #[test]
    fn the_hardware_enable_as_the_drive_shows_it() {
        let disabled = State::SwitchOnDisabled.statusword_bits();
        assert_eq!(hardware_enable(disabled | statusword::WARNING), HardwareEnable::Low);
        assert_eq!(hardware_enable(disabled), HardwareEnable::High);
        let enabled = State::OperationEnabled.statusword_bits() | statusword::WARNING;
        assert_eq!(hardware_enable(enabled), HardwareEnable::High, "a drive it would have dropped");
        assert_eq!(hardware_enable(0x0002), HardwareEnable::Unknown, "no valid state");
    }

    #[test]
    fn which_mappings_carry_the_io_with_a_modes_command() {
        let outputs = |mode| mappings_for(mode, |c| c.digital_outputs).into_iter().map(|m| m.name).collect::<Vec<_>>();
        assert_eq!(outputs(Mode::CyclicSynchronousPosition), ["io", "0x1725/0x1B20"]);
        assert_eq!(outputs(Mode::InterpolatedPosition), ["0x1720/0x1B20", "0x1722/0x1B20", "0x1723/0x1B20"]);
        assert_eq!(outputs(Mode::ProfileVelocity), ["io"]);
        let io = &mappings_for(Mode::ProfileTorque, Carried::all)[0];
        assert_eq!((io.name.as_str(), io.carried.all()), ("io", true));
        let default = Carried::of(&pdo::DEFAULT_RX.concat(), &pdo::DEFAULT_TX.concat());
        assert_eq!(default, Carried { digital_inputs: true, ..Carried::default() });
    }

    #[test]
    fn a_drives_io_is_read_by_its_mapping_and_changes_are_watched() {
        let (rx, tx) = (pdo::IO_RX.concat(), pdo::IO_TX.concat());
        let mut outputs = vec![0u8; 22];
        let mut image = vec![0u8; 30];
        let (out_at, _) = find(&rx, 0x60FE, 1).unwrap();
        outputs[out_at..out_at + 4].copy_from_slice(&bit(2).to_le_bytes());
        let (aout_at, _) = find(&rx, 0x3470, 3).unwrap();
        outputs[aout_at..aout_at + 2].copy_from_slice(&(-1000i16).to_le_bytes());
        let (din_at, _) = find(&tx, 0x60FD, 0).unwrap();
        image[din_at..din_at + 4].copy_from_slice(&(bit(3) | Switch::NegativeLimit.mask()).to_le_bytes());
        let io = DriveIo::read(&rx, &tx, &outputs, &image);
        assert_eq!(io.digital_outputs, Some(bit(2)));
        assert_eq!(io.analog_output, Some(-1000));
        assert_eq!(io.digital_inputs.map(inputs), Some(0b100));
        assert_eq!(io.analog_input, Some(0));
        assert_eq!(io.hardware_enable(), HardwareEnable::High, "Not ready to switch on, no warning");
        let missing = DriveIo::read(&pdo::DEFAULT_RX.concat(), &[], &outputs, &image);
        assert_eq!((missing.digital_outputs, missing.digital_inputs), (None, None));

        let mut watch = InputWatch::new(Some(din_at), 0);
        image[..2].copy_from_slice(&State::SwitchOnDisabled.statusword_bits().to_le_bytes());
        assert_eq!(watch.observe(&image), None, "the first cycle sets the reference");
        assert_eq!(watch.observe(&image), None);
        image[din_at + 2] |= 1; // input 1
        let changed = watch.observe(&image).unwrap();
        assert_eq!(inputs(changed.0), 0b101);
        image[0] |= statusword::WARNING as u8;
        assert_eq!(watch.observe(&image).map(|c| hardware_enable(c.1)), Some(HardwareEnable::Low));
        image[1] |= 0x02; // remote: says nothing of the I/O
        assert_eq!(watch.observe(&image), None);
    }
}
