//! The AKD's faults as the master meets them: the drive's fault number (F125…), its text, and
//! the CiA error code it puts in 0x603F and in its emergency message. Shared by the master,
//! which names a fault from its code, and the virtual AKD, which raises them.

/// One fault of the AKD.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct AkdFault {
    /// The fault number, as in "F439".
    pub number: u16,
    /// CiA error code (0x603F, emergency).
    pub error_code: u16,
    /// The drive's text.
    pub text: &'static str,
}

/// Frames the AKD tolerates missing while enabled (FBUS.PARAM04 = 1, manual §5.14): one more
/// raises F125 "Synchronization lost".
pub const MISSED_FRAMES_TOLERATED: u64 = 7;

/// How many frames an AKD running a cycle of `cycle_ns` counts as missed after `silence_ns`
/// without process data: a frame is missed once half a cycle passed after it was due. The
/// drive raises F125 once this exceeds [`MISSED_FRAMES_TOLERATED`] while it is enabled, so
/// after a silence of 8.5 cycles; a master judges its own stalls by the same rule
/// ([`raises_f125`]).
pub fn frames_missed(silence_ns: u64, cycle_ns: u64) -> u64 {
    if cycle_ns == 0 {
        return 0;
    }
    silence_ns.saturating_sub(cycle_ns / 2) / cycle_ns
}

/// Whether an enabled AKD running a cycle of `cycle_ns` raises F125 after `silence_ns` without
/// process data.
pub fn raises_f125(silence_ns: u64, cycle_ns: u64) -> bool {
    frames_missed(silence_ns, cycle_ns) > MISSED_FRAMES_TOLERATED
}

/// Faults this package knows by code.
pub const KNOWN: &[AkdFault] = &[
    AkdFault { number: 439, error_code: 0x8611, text: "Following error" },
    AkdFault { number: 235, error_code: 0x4310, text: "Excessive temperature, drive (heat sink)" },
    AkdFault { number: 125, error_code: 0x8700, text: "Synchronization lost" },
    AkdFault { number: 706, error_code: 0x8250, text: "Cyclic set-points missing" },
];

/// The fault whose CiA error code is `code`, if known.
pub fn by_code(code: u16) -> Option<&'static AkdFault> {
    KNOWN.iter().find(|f| f.error_code == code)
}

/// The fault numbered `number`, if known.
pub fn by_number(number: u16) -> Option<&'static AkdFault> {
    KNOWN.iter().find(|f| f.number == number)
}
