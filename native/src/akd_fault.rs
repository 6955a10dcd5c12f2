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

/// How a virtual AKD judges that it missed frames (F125, "Synchronization lost", after more
/// than seven): the link spec names it (`sim:N?missed=warn`), akd-sim takes it (`--missed`),
/// and the virtual AKD applies it. A real AKD always judges [`Late`](MissedFrames::Late).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum MissedFrames {
    /// By time, as the real AKD does: a frame is missed once half a cycle passed after it was
    /// due, so a master thread the host runs late faults the drive.
    #[default]
    Late,
    /// By the frames the line lost before they reached the drive (a lost burst, a pulled
    /// cable): a late frame is not a missed one. It cannot see a master that stopped sending.
    Lost,
    /// By time, as the real AKD does, but where the real drive would raise F125 the virtual
    /// one counts it as a would-be F125 (and akd-sim warns) and goes on: for a robot developed
    /// on a host that stalls the master thread now and then. Frames lost on the line still
    /// count as [`Lost`](MissedFrames::Lost) counts them, so a pulled cable still faults.
    Warn,
}

impl MissedFrames {
    /// The option's values as the link spec writes them.
    pub const NAMES: [(&'static str, MissedFrames); 3] =
        [("late", MissedFrames::Late), ("lost", MissedFrames::Lost), ("warn", MissedFrames::Warn)];

    /// "late", "lost" or "warn".
    pub fn name(self) -> &'static str {
        Self::NAMES.iter().find(|(_, m)| *m == self).map_or("late", |(name, _)| name)
    }

    /// The judgement named `name` ("late", "lost" or "warn").
    pub fn parse(name: &str) -> Option<Self> {
        Self::NAMES.iter().find(|(n, _)| *n == name).map(|(_, m)| *m)
    }
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
