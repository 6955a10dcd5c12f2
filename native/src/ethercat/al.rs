//! AL (application layer) states and status codes (ETG.1000.6 §6.4, AKD manual §5.3).

wire_codes! {
    /// An EtherCAT state machine state, as written to AL control (0x0120) and read from AL status
    /// (0x0130) bits 0–3.
    #[derive(PartialOrd, Ord)]
    pub enum AlState: u8, "AL state" {
        /// Init: no mailbox, no process data.
        Init = 0x01 => "Init",
        /// Pre-Operational: mailbox running.
        PreOp = 0x02 => "PreOp",
        /// Bootstrap: firmware update only.
        Bootstrap = 0x03 => "Bootstrap",
        /// Safe-Operational: inputs exchanged, outputs held safe.
        SafeOp = 0x04 => "SafeOp",
        /// Operational: outputs applied.
        Op = 0x08 => "Op",
    }
}

/// AL status bit 4: the last state change failed; AL status code says why.
pub const AL_ERROR_FLAG: u16 = 0x0010;
/// AL control bit 4: acknowledge the error flag.
pub const AL_ERROR_ACK: u16 = 0x0010;
/// Mask of the state bits in AL control and AL status.
pub const AL_STATE_MASK: u16 = 0x000F;

impl AlState {
    /// Decodes the state bits (0–3) of AL control or AL status.
    pub fn from_bits(bits: u16) -> Option<Self> {
        AlState::try_from((bits & AL_STATE_MASK) as u8).ok()
    }

    /// Parses a state name, case-insensitively (`init`, `preop`, `safeop`, `op`, `bootstrap`).
    pub fn parse(name: &str) -> Option<Self> {
        match name.to_ascii_lowercase().replace(['-', '_'], "").as_str() {
            "init" => Some(AlState::Init),
            "preop" | "preoperational" => Some(AlState::PreOp),
            "bootstrap" | "boot" => Some(AlState::Bootstrap),
            "safeop" | "safeoperational" => Some(AlState::SafeOp),
            "op" | "operational" => Some(AlState::Op),
            _ => None,
        }
    }
}

/// Name of the state bits of an AL status word, or "unknown" for a reserved value.
pub fn state_name(status: u16) -> &'static str {
    AlState::from_bits(status).map_or("unknown", AlState::name)
}

wire_codes! {
    /// An AL status code (register 0x0134). Slaves raise vendor codes beside the standard's
    /// (ETG.1000.6 table 11), so this is the register value with the codes the AKD itself raises as
    /// constants and [`name`](AlStatusCode::name) for any code.
    pub struct AlStatusCode(u16) {
        NO_ERROR = 0x0000 => "no error",
        0x0001 => "unspecified error",
        0x0002 => "no memory",
        0x0003 => "invalid device setup",
        /// Invalid requested state change (AKD: I→S, I→O, P→O, O→B, S→B, P→B).
        INVALID_STATE_CHANGE = 0x0011 => "invalid requested state change",
        0x0012 => "unknown requested state",
        0x0013 => "bootstrap not supported",
        0x0014 => "no valid firmware",
        0x0015 => "invalid mailbox configuration (bootstrap)",
        0x0016 => "invalid mailbox configuration (PreOp)",
        /// Invalid sync manager configuration (AKD: I→P with SM0/SM1 wrong, P→S with SM2/SM3 wrong).
        INVALID_SM_CONFIG = 0x0017 => "invalid sync manager configuration",
        0x0018 => "no valid inputs available",
        0x0019 => "no valid outputs",
        0x001A => "synchronization error",
        /// Sync manager watchdog: process data stopped arriving in Op.
        SM_WATCHDOG = 0x001B => "sync manager watchdog",
        0x001C => "invalid sync manager types",
        /// Invalid output configuration: the real AKD refuses P→S with it when the RxPDO mapping
        /// has an odd length (seen in `real-akd/soem-sdinfo-akd.pcapng`).
        INVALID_OUTPUT_CONFIG = 0x001D => "invalid output configuration",
        /// Invalid input configuration: the TxPDO counterpart of 0x001D.
        INVALID_INPUT_CONFIG = 0x001E => "invalid input configuration",
        0x001F => "invalid watchdog configuration",
        0x0020 => "slave needs cold start",
        0x0021 => "slave needs Init",
        0x0022 => "slave needs PreOp",
        0x0023 => "slave needs SafeOp",
        0x0024 => "invalid input mapping",
        0x0025 => "invalid output mapping",
        0x0026 => "inconsistent settings",
        0x0027 => "free-run not supported",
        0x0028 => "synchronization not supported",
        0x0029 => "free-run needs 3-buffer mode",
        0x002A => "background watchdog",
        0x002B => "no valid inputs and outputs",
        0x002C => "fatal sync error",
        0x002D => "no sync error",
        0x0030 => "invalid DC SYNC configuration",
        0x0031 => "invalid DC latch configuration",
        0x0032 => "PLL error",
        0x0033 => "DC sync IO error",
        0x0034 => "DC sync timeout error",
        0x0035 => "DC invalid sync cycle time",
        0x0036 => "DC SYNC0 cycle time",
        0x0037 => "DC SYNC1 cycle time",
        0x0041 => "MBX_AOE",
        0x0042 => "MBX_EOE",
        0x0043 => "MBX_COE",
        0x0044 => "MBX_FOE",
        0x0045 => "MBX_SOE",
        0x004F => "MBX_VOE",
        0x0050 => "EEPROM no access",
        0x0051 => "EEPROM error",
        0x0060 => "slave restarted locally",
        0x0061 => "device identification value updated",
        0x00F0 => "application controller available",
    } else {
        0x8000..=0xFFFF => "vendor specific",
        _ => "unknown AL status code",
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn states_round_trip() {
        for s in AlState::ALL {
            assert_eq!(AlState::from_bits(s as u16), Some(s));
            assert_eq!(AlState::from_bits(s as u16 | AL_ERROR_FLAG), Some(s));
            assert_eq!(AlState::parse(s.name()), Some(s));
        }
        assert_eq!(AlState::from_bits(0x05), None);
        assert_eq!(state_name(0x12), "PreOp");
    }

    #[test]
    fn names_the_akd_codes() {
        assert_eq!(AlStatusCode::INVALID_STATE_CHANGE.name(), "invalid requested state change");
        assert_eq!(AlStatusCode::INVALID_SM_CONFIG.name(), "invalid sync manager configuration");
        assert_eq!(AlStatusCode::INVALID_OUTPUT_CONFIG.name(), "invalid output configuration");
    }
}
