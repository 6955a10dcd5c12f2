//! CiA 402 (DS402) drive state machine codec (AKD manual §5.4, CiA 402-2 §8).
//!
//! Pure functions over the controlword 0x6040 and statusword 0x6041: decode the state a
//! statusword shows, the transition a controlword causes in a state (what the drive does), and
//! the controlword that moves a drive one step toward a wanted state (what the master sends).
//! The virtual AKD and the master's sequencer both use it, so they cannot disagree.

named_variants! {
    /// A state of the drive, as the statusword shows it; in Python `Ds402State`, its members
    /// `Ds402State.OPERATION_ENABLED` and so on.
    #[cfg_attr(feature = "python", pyo3::pyclass(name = "Ds402State", module = "akd_ros._native", frozen, eq, eq_int, hash, rename_all = "SCREAMING_SNAKE_CASE"))]
    pub enum State {
        /// Initialising; the drive leaves it by itself.
        NotReadyToSwitchOn => "Not ready to switch on",
        /// Power stage off, waiting for Shutdown.
        SwitchOnDisabled => "Switch on disabled",
        /// Ready; Switch on closes the main contactor.
        ReadyToSwitchOn => "Ready to switch on",
        /// High voltage applied, power stage off.
        SwitchedOn => "Switched on",
        /// Power stage on, following set-points.
        OperationEnabled => "Operation enabled",
        /// Braking with the quick-stop ramp.
        QuickStopActive => "Quick stop active",
        /// Reacting to a fault before entering Fault.
        FaultReactionActive => "Fault reaction active",
        /// Faulted; needs a fault reset.
        Fault => "Fault",
    }
    /// The state's name as CiA 402 writes it.
    fn name;
}

/// Statusword bits.
pub mod statusword {
    /// Ready to switch on.
    pub const READY_TO_SWITCH_ON: u16 = 1 << 0;
    /// Switched on.
    pub const SWITCHED_ON: u16 = 1 << 1;
    /// Operation enabled.
    pub const OPERATION_ENABLED: u16 = 1 << 2;
    /// Fault.
    pub const FAULT: u16 = 1 << 3;
    /// Voltage enabled.
    pub const VOLTAGE_ENABLED: u16 = 1 << 4;
    /// Quick stop (active low: 0 while a quick stop runs).
    pub const QUICK_STOP: u16 = 1 << 5;
    /// Switch on disabled.
    pub const SWITCH_ON_DISABLED: u16 = 1 << 6;
    /// Warning.
    pub const WARNING: u16 = 1 << 7;
    /// Remote (always 1 on the AKD).
    pub const REMOTE: u16 = 1 << 9;
    /// Target reached.
    pub const TARGET_REACHED: u16 = 1 << 10;
    /// Internal limit active.
    pub const INTERNAL_LIMIT: u16 = 1 << 11;
    /// Mode specific bit 12 (CSP: target position ignored = 0; homing: homing attained).
    pub const MODE_SPECIFIC_12: u16 = 1 << 12;
    /// Mode specific bit 13 (following error; homing error).
    pub const MODE_SPECIFIC_13: u16 = 1 << 13;
    /// Bits that encode the state: 6, 5, 3, 2, 1, 0.
    pub const STATE_MASK: u16 = 0x006F;
}

/// Controlword bits.
pub mod controlword {
    /// Switch on.
    pub const SWITCH_ON: u16 = 1 << 0;
    /// Enable voltage.
    pub const ENABLE_VOLTAGE: u16 = 1 << 1;
    /// Quick stop (active low).
    pub const QUICK_STOP: u16 = 1 << 2;
    /// Enable operation.
    pub const ENABLE_OPERATION: u16 = 1 << 3;
    /// Profile position: new set-point; homing: start homing.
    pub const NEW_SETPOINT: u16 = 1 << 4;
    /// Profile position: change set immediately.
    pub const CHANGE_IMMEDIATELY: u16 = 1 << 5;
    /// Profile position: target is relative.
    pub const RELATIVE: u16 = 1 << 6;
    /// Fault reset, on its rising edge.
    pub const FAULT_RESET: u16 = 1 << 7;
    /// Halt, in every mode.
    pub const HALT: u16 = 1 << 8;
    /// Shutdown command (transitions 2, 6, 8).
    pub const SHUTDOWN: u16 = ENABLE_VOLTAGE | QUICK_STOP;
    /// Switch on command (transition 3); also Disable operation (transition 5).
    pub const SWITCH_ON_COMMAND: u16 = SHUTDOWN | SWITCH_ON;
    /// Enable operation command (transitions 4, 16).
    pub const ENABLE_OPERATION_COMMAND: u16 = SWITCH_ON_COMMAND | ENABLE_OPERATION;
    /// Disable voltage command (transitions 7, 9, 10, 12).
    pub const DISABLE_VOLTAGE: u16 = 0;
    /// Quick stop command (transitions 7, 10, 11).
    pub const QUICK_STOP_COMMAND: u16 = ENABLE_VOLTAGE;
    /// The bits the device-control commands use (7, 3, 2, 1, 0).
    pub const COMMAND_MASK: u16 = 0x008F;
}

impl State {
    /// Decodes the statusword per the AKD manual's table (bits 6, 5, 3, 2, 1, 0).
    pub fn from_statusword(sw: u16) -> Option<State> {
        let bits = sw & statusword::STATE_MASK;
        // Bit 5 (quick stop) is "don't care" for all states but Operation enabled/Quick stop
        // active, and Switched on/Ready where it is 1; test the specific patterns first.
        match bits & 0x004F {
            0x0000 => Some(State::NotReadyToSwitchOn),
            0x0040 => Some(State::SwitchOnDisabled),
            0x0008 => Some(State::Fault),
            0x000F => Some(State::FaultReactionActive),
            0x0001 if bits & 0x0020 != 0 => Some(State::ReadyToSwitchOn),
            0x0003 if bits & 0x0020 != 0 => Some(State::SwitchedOn),
            0x0007 if bits & 0x0020 != 0 => Some(State::OperationEnabled),
            0x0007 => Some(State::QuickStopActive),
            _ => None,
        }
    }

    /// The statusword bits 0–6 the drive shows in this state (bit 4 voltage enabled is set
    /// while the power stage has voltage, i.e. from Ready to switch on upwards).
    pub fn statusword_bits(self) -> u16 {
        use statusword::*;
        match self {
            State::NotReadyToSwitchOn => 0,
            State::SwitchOnDisabled => SWITCH_ON_DISABLED,
            State::ReadyToSwitchOn => QUICK_STOP | READY_TO_SWITCH_ON,
            State::SwitchedOn => QUICK_STOP | VOLTAGE_ENABLED | SWITCHED_ON | READY_TO_SWITCH_ON,
            State::OperationEnabled => {
                QUICK_STOP | VOLTAGE_ENABLED | OPERATION_ENABLED | SWITCHED_ON | READY_TO_SWITCH_ON
            }
            State::QuickStopActive => VOLTAGE_ENABLED | OPERATION_ENABLED | SWITCHED_ON | READY_TO_SWITCH_ON,
            State::FaultReactionActive => FAULT | OPERATION_ENABLED | SWITCHED_ON | READY_TO_SWITCH_ON,
            State::Fault => FAULT,
        }
    }

    /// The state's name as one word, as the messages spell it: "operation_enabled".
    pub fn snake_name(self) -> String {
        crate::spelling::snake_case(self.name())
    }

    /// What a message says for the state a statusword shows: its [`snake_name`](State::snake_name),
    /// "unknown" for a statusword that shows none.
    pub fn message_name(state: Option<State>) -> String {
        state.map_or_else(|| "unknown".to_owned(), State::snake_name)
    }

    /// Whether the drive shows a fault: Fault, or Fault reaction active on its way there.
    pub fn is_fault(self) -> bool {
        matches!(self, State::Fault | State::FaultReactionActive)
    }

    /// Whether the power stage drives the motor in this state.
    pub fn is_power_stage_on(self) -> bool {
        matches!(self, State::OperationEnabled | State::QuickStopActive | State::FaultReactionActive)
    }
}

/// The transition a controlword causes in `state`, as the drive evaluates it: the new state
/// and the CiA 402 transition number, or `None` when the controlword asks for nothing here.
/// `fault_reset_edge` is true when bit 7 rose since the previous controlword. The drive-side
/// transitions 0, 1, 13 and 14 (internal events) are not caused by a controlword.
pub fn transition(state: State, cw: u16, fault_reset_edge: bool) -> Option<(State, u8)> {
    use controlword::*;
    let command = cw & COMMAND_MASK & !FAULT_RESET;
    let shutdown = command & (ENABLE_VOLTAGE | QUICK_STOP | SWITCH_ON) == SHUTDOWN;
    let switch_on = command & (ENABLE_VOLTAGE | QUICK_STOP | SWITCH_ON | ENABLE_OPERATION) == SWITCH_ON_COMMAND;
    let enable = command == ENABLE_OPERATION_COMMAND;
    let disable_voltage = cw & ENABLE_VOLTAGE == 0;
    let quick_stop = cw & (ENABLE_VOLTAGE | QUICK_STOP) == ENABLE_VOLTAGE;
    match state {
        State::Fault if fault_reset_edge => Some((State::SwitchOnDisabled, 15)),
        State::Fault | State::FaultReactionActive | State::NotReadyToSwitchOn => None,
        State::SwitchOnDisabled if shutdown => Some((State::ReadyToSwitchOn, 2)),
        State::SwitchOnDisabled => None,
        State::ReadyToSwitchOn if disable_voltage || quick_stop => Some((State::SwitchOnDisabled, 7)),
        State::ReadyToSwitchOn if switch_on => Some((State::SwitchedOn, 3)),
        // Enable operation from Ready to switch on passes Switched on (3, then 4).
        State::ReadyToSwitchOn if enable => Some((State::SwitchedOn, 3)),
        State::ReadyToSwitchOn => None,
        State::SwitchedOn if disable_voltage || quick_stop => Some((State::SwitchOnDisabled, 10)),
        State::SwitchedOn if shutdown => Some((State::ReadyToSwitchOn, 6)),
        State::SwitchedOn if enable => Some((State::OperationEnabled, 4)),
        State::SwitchedOn => None,
        State::OperationEnabled if disable_voltage => Some((State::SwitchOnDisabled, 9)),
        State::OperationEnabled if quick_stop => Some((State::QuickStopActive, 11)),
        State::OperationEnabled if shutdown => Some((State::ReadyToSwitchOn, 8)),
        State::OperationEnabled if switch_on => Some((State::SwitchedOn, 5)),
        State::OperationEnabled => None,
        State::QuickStopActive if disable_voltage => Some((State::SwitchOnDisabled, 12)),
        State::QuickStopActive if enable => Some((State::OperationEnabled, 16)),
        State::QuickStopActive => None,
    }
}

/// The controlword that moves a drive in `state` one step toward `target` (one of Switch on
/// disabled, Ready to switch on, Switched on, Operation enabled), as the master sequences it.
/// In Fault the step is a fault reset: the caller must send it with bit 7 low first and then
/// high, since the drive reacts to the rising edge only.
pub fn step_toward(state: State, target: State) -> u16 {
    use controlword::*;
    let rank = |s: State| match s {
        State::SwitchOnDisabled => 0,
        State::ReadyToSwitchOn => 1,
        State::SwitchedOn => 2,
        State::OperationEnabled => 3,
        _ => 0,
    };
    match state {
        State::Fault | State::FaultReactionActive => FAULT_RESET,
        State::NotReadyToSwitchOn => DISABLE_VOLTAGE,
        State::QuickStopActive if target == State::OperationEnabled => ENABLE_OPERATION_COMMAND,
        State::QuickStopActive => DISABLE_VOLTAGE,
        _ => match (rank(state), rank(target)) {
            (_, 0) => DISABLE_VOLTAGE,
            (0, _) | (_, 1) => SHUTDOWN,
            (1, _) | (_, 2) => SWITCH_ON_COMMAND,
            _ => ENABLE_OPERATION_COMMAND,
        },
    }
}

wire_codes! {
    /// Modes of operation (0x6060 / 0x6061) the AKD supports (§5.8); in Python
    /// `ModeOfOperation`, every one in `MODES_OF_OPERATION`.
    #[cfg_attr(feature = "python", pyo3::pyclass(name = "ModeOfOperation", module = "akd_ros._native", frozen, eq, hash))]
    pub enum Mode: i8, "mode of operation" {
        /// Profile position (motion task 0).
        ProfilePosition = 1 => "profile position",
        /// Profile velocity.
        ProfileVelocity = 3 => "profile velocity",
        /// Profile torque, in 0.1 % of the drive's peak torque.
        ProfileTorque = 4 => "profile torque",
        /// Homing (drive internal).
        Homing = 6 => "homing",
        /// Interpolated position, set-points in 0x60C1:01.
        InterpolatedPosition = 7 => "interpolated position",
        /// Cyclic synchronous position, set-points in 0x607A.
        CyclicSynchronousPosition = 8 => "cyclic synchronous position",
    }
}

/// Error code 0x603F:00 (UNSIGNED16): the CiA 402 code of the drive's last fault, which the
/// AKD also sends in its emergency message.
pub const ERROR_CODE: (u16, u8) = (0x603F, 0);

/// The fault code in the drive's reply to a read of [`ERROR_CODE`]; a reply shorter than its two
/// bytes is refused, never read as 0 ("no fault code").
pub fn error_code(reply: &[u8]) -> Result<u16, crate::ethercat::mailbox::MailboxError> {
    match reply {
        [low, high, ..] => Ok(u16::from_le_bytes([*low, *high])),
        _ => Err(crate::ethercat::mailbox::MailboxError::Truncated {
            what: "error code 0x603F:00",
            len: reply.len(),
            needed: 2,
        }),
    }
}

/// CiA 402's cyclic synchronous velocity (9) and torque (10), which the AKD does not offer: by
/// their 0x6060 value and one-word name, with why (docs/virtual_akd.md has the evidence). The
/// virtual AKD refuses them as it refuses any other value (SDO abort 0x06090030), and the master
/// and the node refuse them with the reason.
pub const NOT_OFFERED: [(i8, &str, &str); 2] = [
    (
        9,
        "cyclic_synchronous_velocity",
        "the AKD offers no mode 9: no AKD EtherCAT manual (2009 to 2017, firmware up to 1.17) lists it, and the AKD's \
         0x6502 (0xE5) has no csv bit; its cyclic velocity mode is profile_velocity (3), which takes 0x60FF every \
         cycle (DRV.OPMODE 1, DRV.CMDSOURCE 1)",
    ),
    (
        10,
        "cyclic_synchronous_torque",
        "the AKD offers no mode 10: no AKD EtherCAT manual (2009 to 2017, firmware up to 1.17) lists it, and the \
         AKD's 0x6502 (0xE5) has no cst bit; its cyclic torque mode is profile_torque (4), which takes 0x6071 every \
         cycle (DRV.OPMODE 0, DRV.CMDSOURCE 1)",
    ),
];

impl Mode {
    /// Decodes 0x6060/0x6061; `None` for a mode the AKD does not support.
    pub fn from_i8(value: i8) -> Option<Mode> {
        Mode::try_from(value).ok()
    }
}

named_variants! {
    /// What the command of a mode of operation sets.
    pub enum CommandKind {
        /// A position, in counts.
        Position => "position",
        /// A velocity, in counts per second.
        Velocity => "velocity",
        /// A torque, in 0.1 % of the drive's peak torque.
        Torque => "torque",
    }
    /// The command's name as the Python API spells it: "position", "velocity", "torque".
    fn name;
}

impl Mode {
    /// The mode's name as one word, as the Python API and the node's parameters spell it:
    /// "profile_position".
    pub fn snake_name(self) -> String {
        crate::spelling::snake_case(self.name())
    }

    /// The mode whose [`snake_name`](Mode::snake_name) is `name`.
    pub fn from_snake_name(name: &str) -> Option<Mode> {
        Self::ALL.into_iter().find(|m| m.snake_name() == name)
    }

    /// What the mode's command sets; `None` for homing, which the drive runs by itself.
    pub fn command(self) -> Option<CommandKind> {
        match self {
            Mode::ProfilePosition | Mode::InterpolatedPosition | Mode::CyclicSynchronousPosition => {
                Some(CommandKind::Position)
            }
            Mode::ProfileVelocity => Some(CommandKind::Velocity),
            Mode::ProfileTorque => Some(CommandKind::Torque),
            Mode::Homing => None,
        }
    }

    /// The objects (index, subindex) the mode's command is written to, in the order tried: the
    /// first the output mapping carries; a mode started by a handshake
    /// ([`handshake_controlword`](Mode::handshake_controlword)) writes the first by SDO where
    /// none is mapped, the others need one mapped. Empty for homing.
    pub fn command_objects(self) -> &'static [(u16, u8)] {
        match self {
            Mode::ProfilePosition | Mode::CyclicSynchronousPosition => &[(0x607A, 0)],
            Mode::ProfileVelocity => &[(0x60FF, 0)],
            Mode::ProfileTorque => &[(0x6071, 0)],
            Mode::Homing => &[],
            Mode::InterpolatedPosition => &[(0x60C1, 1)],
        }
    }

    /// Whether `index:subindex` is the command object of some mode: a motion set-point, whose
    /// write releases a held target (the drive's I/O and other outputs do not).
    pub fn is_command_object(index: u16, subindex: u8) -> bool {
        Self::ALL.iter().any(|m| m.command_objects().contains(&(index, subindex)))
    }

    /// The controlword bits whose rising edge starts what the mode was commanded: profile
    /// position takes a new set-point at once (bits 4 and 5), homing starts (bit 4). The drive
    /// acknowledges in statusword bit 12; the bits then go low again, so that the next command
    /// makes a new edge (the cycle thread's set-point handshake). `None` for the modes that
    /// follow their command every cycle.
    pub fn handshake_controlword(self) -> Option<u16> {
        match self {
            Mode::ProfilePosition => Some(controlword::NEW_SETPOINT | controlword::CHANGE_IMMEDIATELY),
            Mode::Homing => Some(controlword::NEW_SETPOINT),
            _ => None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use controlword::*;

    #[test]
    fn the_error_code_reply_needs_its_two_bytes() {
        assert_eq!(error_code(&[0x10, 0x23]), Ok(0x2310));
        let e = error_code(&[0x10]).unwrap_err().to_string();
        assert_eq!(e, "error code 0x603F:00 of 1 bytes is shorter than the 2 bytes it needs");
        assert!(error_code(&[]).is_err());
    }

    #[test]
    fn statusword_round_trips_every_state() {
        for s in State::ALL {
            assert_eq!(State::from_statusword(s.statusword_bits() | statusword::REMOTE), Some(s), "{}", s.name());
        }
    }

    #[test]
    fn decodes_the_manuals_table_with_dont_care_bits() {
        assert_eq!(State::from_statusword(0x0250), Some(State::SwitchOnDisabled));
        assert_eq!(State::from_statusword(0x0270), Some(State::SwitchOnDisabled));
        assert_eq!(State::from_statusword(0x0237), Some(State::OperationEnabled));
        assert_eq!(State::from_statusword(0x0217), Some(State::QuickStopActive));
        assert_eq!(State::from_statusword(0x0228), Some(State::Fault));
        assert_eq!(State::from_statusword(0x0005), None);
    }

    #[test]
    fn every_numbered_transition() {
        let cases = [
            (State::SwitchOnDisabled, SHUTDOWN, State::ReadyToSwitchOn, 2),
            (State::ReadyToSwitchOn, SWITCH_ON_COMMAND, State::SwitchedOn, 3),
            (State::SwitchedOn, ENABLE_OPERATION_COMMAND, State::OperationEnabled, 4),
            (State::OperationEnabled, SWITCH_ON_COMMAND, State::SwitchedOn, 5),
            (State::SwitchedOn, SHUTDOWN, State::ReadyToSwitchOn, 6),
            (State::ReadyToSwitchOn, DISABLE_VOLTAGE, State::SwitchOnDisabled, 7),
            (State::ReadyToSwitchOn, QUICK_STOP_COMMAND, State::SwitchOnDisabled, 7),
            (State::OperationEnabled, SHUTDOWN, State::ReadyToSwitchOn, 8),
            (State::OperationEnabled, DISABLE_VOLTAGE, State::SwitchOnDisabled, 9),
            (State::SwitchedOn, DISABLE_VOLTAGE, State::SwitchOnDisabled, 10),
            (State::SwitchedOn, QUICK_STOP_COMMAND, State::SwitchOnDisabled, 10),
            (State::OperationEnabled, QUICK_STOP_COMMAND, State::QuickStopActive, 11),
            (State::QuickStopActive, DISABLE_VOLTAGE, State::SwitchOnDisabled, 12),
            (State::QuickStopActive, ENABLE_OPERATION_COMMAND, State::OperationEnabled, 16),
        ];
        for (from, cw, to, number) in cases {
            assert_eq!(transition(from, cw, false), Some((to, number)), "{} with 0x{cw:04X}", from.name());
        }
    }

    #[test]
    fn fault_reset_needs_the_rising_edge() {
        assert_eq!(transition(State::Fault, FAULT_RESET, false), None);
        assert_eq!(transition(State::Fault, FAULT_RESET, true), Some((State::SwitchOnDisabled, 15)));
        assert_eq!(transition(State::FaultReactionActive, FAULT_RESET, true), None);
    }

    #[test]
    fn sequencing_reaches_every_target_from_every_state() {
        for target in [State::SwitchOnDisabled, State::ReadyToSwitchOn, State::SwitchedOn, State::OperationEnabled] {
            for start in State::ALL {
                let mut state = start;
                let mut previous_cw = 0u16;
                for _ in 0..10 {
                    if state == target {
                        break;
                    }
                    let mut cw = step_toward(state, target);
                    if cw & FAULT_RESET != 0 && previous_cw & FAULT_RESET != 0 {
                        cw = 0;
                    }
                    let edge = cw & FAULT_RESET != 0 && previous_cw & FAULT_RESET == 0;
                    if let Some((next, _)) = transition(state, cw, edge) {
                        state = next;
                    } else if state == State::NotReadyToSwitchOn || state == State::FaultReactionActive {
                        // The drive leaves these by itself (transitions 1 and 14).
                        state = if state == State::NotReadyToSwitchOn { State::SwitchOnDisabled } else { State::Fault };
                    }
                    previous_cw = cw;
                }
                assert_eq!(state, target, "from {} toward {}", start.name(), target.name());
            }
        }
    }

    #[test]
    fn modes() {
        assert_eq!(Mode::from_i8(8), Some(Mode::CyclicSynchronousPosition));
        assert_eq!(Mode::from_i8(2), None);
    }

    #[test]
    fn the_virtual_akd_takes_exactly_the_modes_of_the_table() {
        use crate::ethercat::coe::access::WRITE_OP;
        let mut od = crate::sim::od::ObjectDictionary::default();
        for code in i8::MIN..=i8::MAX {
            let taken = od.write(0x6060, 0, &[code as u8], WRITE_OP).is_ok();
            assert_eq!(taken, Mode::from_i8(code).is_some(), "0x6060 = {code}");
        }
        for mode in Mode::ALL {
            assert_eq!(Mode::from_snake_name(&mode.snake_name()), Some(mode));
            assert!(!mode.snake_name().contains(' '));
        }
        assert_eq!(Mode::from_snake_name("profile position"), None);
    }

    #[test]
    fn each_command_goes_to_mappable_objects_of_its_own_type() {
        use crate::ethercat::coe::data_type::{self, ValueKind};
        for mode in Mode::ALL {
            assert_eq!(mode.command().is_none(), mode.command_objects().is_empty(), "{}", mode.name());
            for &(index, subindex) in mode.command_objects() {
                let this = |e: crate::ethercat::pdo::PdoEntry| (e.index, e.subindex) == (index, subindex);
                assert!(crate::drive::pdo::mappable(crate::ethercat::pdo::Direction::Rx).any(this));
                let (object, code) = crate::drive::objects::mappable_object(index, subindex).expect("a typed object");
                assert_eq!(data_type::kind(code), ValueKind::SignedInteger, "{}", object.name);
                // Torque counts in 0.1 % of peak (16 bits); positions and velocities in counts (32).
                let bits = if mode.command() == Some(CommandKind::Torque) { 16 } else { 32 };
                assert_eq!(data_type::bit_len(code), Some(bits), "{}", object.name);
            }
        }
    }

    #[test]
    fn handshakes_raise_bit_4_and_leave_the_device_control_bits_alone() {
        for mode in Mode::ALL {
            let handshake = mode.handshake_controlword();
            assert_eq!(handshake.is_some(), matches!(mode, Mode::ProfilePosition | Mode::Homing), "{}", mode.name());
            if let Some(bits) = handshake {
                assert_ne!(bits & NEW_SETPOINT, 0);
                assert_eq!(bits & COMMAND_MASK, 0, "the handshake leaves the device-control bits alone");
            }
        }
    }
}
