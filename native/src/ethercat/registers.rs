//! ESC register addresses (ETG.1000.4 §6, AKD manual §5.1) used by the master and served by
//! the virtual AKD. All registers are little-endian. The error counters (0x0300–0x0313) are
//! [`crate::ethercat::line_health::registers`]'.

/// ESC type (1 byte), then revision (1) and build (2).
pub const TYPE: u16 = 0x0000;
/// Port descriptor (1 byte).
pub const PORT_DESCRIPTOR: u16 = 0x0007;
/// ESC features supported (2 bytes).
pub const FEATURES: u16 = 0x0008;
/// Feature bit of a distributed clock.
pub const FEATURE_DC: u16 = 0x0004;
/// Configured station address (2 bytes).
pub const STATION_ADDRESS: u16 = 0x0010;
/// Configured station alias (2 bytes, loaded from SII word 4).
pub const STATION_ALIAS: u16 = 0x0012;
/// DL control (4 bytes): forwarding and loop control.
pub const DL_CONTROL: u16 = 0x0100;
/// DL status (2 bytes): link and loop state of the ports.
pub const DL_STATUS: u16 = 0x0110;
/// AL control (2 bytes): requested state and error acknowledge (bit 4).
pub const AL_CONTROL: u16 = 0x0120;
/// AL status (2 bytes): current state and error flag (bit 4).
pub const AL_STATUS: u16 = 0x0130;
/// AL status code (2 bytes): why the last state change failed.
pub const AL_STATUS_CODE: u16 = 0x0134;
/// PDI control (1 byte).
pub const PDI_CONTROL: u16 = 0x0140;
/// ECAT event mask (2 bytes).
pub const ECAT_EVENT_MASK: u16 = 0x0200;
/// ECAT event request (2 bytes).
pub const ECAT_EVENT_REQUEST: u16 = 0x0210;
/// Watchdog divider (2 bytes), in 40 ns ticks.
pub const WATCHDOG_DIVIDER: u16 = 0x0400;
/// Process-data (SM) watchdog time (2 bytes), in watchdog-divider units.
pub const WATCHDOG_TIME_PROCESS_DATA: u16 = 0x0420;
/// Watchdog status process data (2 bytes): bit 0 = 1 while not expired.
pub const WATCHDOG_STATUS: u16 = 0x0440;
/// SII EEPROM configuration (1 byte): bit 0 = PDI owns the EEPROM.
pub const SII_CONFIG: u16 = 0x0500;
/// SII EEPROM control/status (2 bytes).
pub const SII_CONTROL: u16 = 0x0502;
/// SII EEPROM word address (4 bytes).
pub const SII_ADDRESS: u16 = 0x0504;
/// SII EEPROM data (4 or 8 bytes).
pub const SII_DATA: u16 = 0x0508;
/// First FMMU (16 bytes each).
pub const FMMU0: u16 = 0x0600;
/// Size of one FMMU's registers.
pub const FMMU_LEN: u16 = 16;
/// First sync manager (8 bytes each).
pub const SM0: u16 = 0x0800;
/// Size of one sync manager's registers.
pub const SM_LEN: u16 = 8;
/// DC receive time of port 0 (4 bytes); a write latches all ports' receive times.
pub const DC_RECEIVE_TIME_PORT0: u16 = 0x0900;
/// DC system time (8 bytes); an ARMW/FRMW write feeds the drift control loop.
pub const DC_SYSTEM_TIME: u16 = 0x0910;
/// DC local receive time of the processing unit (8 bytes).
pub const DC_RECEIVE_TIME_ECAT: u16 = 0x0918;
/// DC system time offset (8 bytes).
pub const DC_SYSTEM_TIME_OFFSET: u16 = 0x0920;
/// DC system time delay (4 bytes): propagation delay from the reference clock.
pub const DC_SYSTEM_TIME_DELAY: u16 = 0x0928;
/// DC system time difference (4 bytes): bit 31 sign, magnitude in ns.
pub const DC_SYSTEM_TIME_DIFFERENCE: u16 = 0x092C;
/// DC activation (1 byte): bit 0 cyclic operation, bit 1 SYNC0, bit 2 SYNC1.
pub const DC_ACTIVATION: u16 = 0x0981;
/// DC SYNC0 start time (8 bytes, system time).
pub const DC_SYNC0_START_TIME: u16 = 0x0990;
/// DC SYNC0 cycle time (4 bytes, ns).
pub const DC_SYNC0_CYCLE_TIME: u16 = 0x09A0;

/// Address of sync manager `n`'s registers.
pub const fn sm(n: u8) -> u16 {
    SM0 + SM_LEN * n as u16
}

/// Address of FMMU `n`'s registers.
pub const fn fmmu(n: u8) -> u16 {
    FMMU0 + FMMU_LEN * n as u16
}

/// Sync manager register layout (8 bytes at 0x0800 + 8·n).
pub mod sm_reg {
    /// Physical start address (2 bytes).
    pub const START: usize = 0;
    /// Length (2 bytes).
    pub const LENGTH: usize = 2;
    /// Control (1 byte): bits 0–1 mode (0 buffered, 2 mailbox), bits 2–3 direction
    /// (0 master reads, 1 master writes), bit 5 interrupt to PDI, bit 6 watchdog trigger.
    pub const CONTROL: usize = 4;
    /// Status (1 byte): bit 3 mailbox full, bits 4–5 buffered state.
    pub const STATUS: usize = 5;
    /// Activate (1 byte): bit 0 enable, bit 1 repeat request.
    pub const ACTIVATE: usize = 6;
    /// PDI control (1 byte): bit 0 deactivate, bit 1 repeat acknowledge.
    pub const PDI_CONTROL: usize = 7;
    /// Status bit: mailbox full / buffer written.
    pub const STATUS_MAILBOX_FULL: u8 = 0x08;
    /// Control: mailbox mode.
    pub const MODE_MAILBOX: u8 = 0x02;
    /// Control: master writes (ECAT write, PDI read).
    pub const DIRECTION_WRITE: u8 = 0x04;
    /// Activate bit 1: mailbox repeat request, toggled by the master.
    pub const ACTIVATE_REPEAT: u8 = 0x02;
    /// PDI control bit 1: repeat acknowledge, the slave's copy of the repeat request.
    pub const PDI_REPEAT_ACK: u8 = 0x02;
}

/// FMMU register layout (16 bytes at 0x0600 + 16·n).
pub mod fmmu_reg {
    /// Logical start address (4 bytes).
    pub const LOGICAL_START: usize = 0;
    /// Length in bytes (2).
    pub const LENGTH: usize = 4;
    /// Logical start bit (1).
    pub const LOGICAL_START_BIT: usize = 6;
    /// Logical end bit (1).
    pub const LOGICAL_END_BIT: usize = 7;
    /// Physical start address (2).
    pub const PHYSICAL_START: usize = 8;
    /// Physical start bit (1).
    pub const PHYSICAL_START_BIT: usize = 10;
    /// Type (1): bit 0 read (slave to master), bit 1 write (master to slave).
    pub const TYPE: usize = 11;
    /// Activate (1): bit 0.
    pub const ACTIVATE: usize = 12;
    /// Type bit: the master reads through this FMMU.
    pub const TYPE_READ: u8 = 0x01;
    /// Type bit: the master writes through this FMMU.
    pub const TYPE_WRITE: u8 = 0x02;
}

/// SII control/status register (0x0502) bits.
pub mod sii_reg {
    /// Write access enable.
    pub const WRITE_ENABLE: u16 = 0x0001;
    /// EEPROM emulation by the PDI (the AKD reports 1).
    pub const EMULATION: u16 = 0x0020;
    /// 8 bytes are read at once instead of 4 (the AKD reports 0: 4 bytes).
    pub const READ_8_BYTES: u16 = 0x0040;
    /// Command: read.
    pub const CMD_READ: u16 = 0x0100;
    /// Command: write.
    pub const CMD_WRITE: u16 = 0x0200;
    /// Command: reload.
    pub const CMD_RELOAD: u16 = 0x0400;
    /// Missing acknowledge or invalid command.
    pub const ERROR_ACK: u16 = 0x2000;
    /// Interface busy.
    pub const BUSY: u16 = 0x8000;
}
