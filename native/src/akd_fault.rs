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

/// How a virtual AKD judges that it missed frames (F125, "Synchronization lost", after more
/// than seven): the link spec names it (`sim:N?missed=lost`) and the virtual AKD applies it.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum MissedFrames {
    /// By time, as the real AKD does: a frame is missed once half a cycle passed after it was
    /// due, so a master thread the host runs late faults the drive.
    #[default]
    Late,
    /// By the frames the line lost before they reached the drive (a lost burst, a pulled
    /// cable): a late frame is not a missed one. For development and tests on a host whose
    /// master thread is not real-time; it cannot see a master that stopped sending.
    Lost,
}

impl MissedFrames {
    /// The option's values as the link spec writes them.
    pub const NAMES: [(&'static str, MissedFrames); 2] = [("late", MissedFrames::Late), ("lost", MissedFrames::Lost)];

    /// "late" or "lost".
    pub fn name(self) -> &'static str {
        Self::NAMES.iter().find(|(_, m)| *m == self).map_or("late", |(name, _)| name)
    }

    /// The judgement named `name` ("late" or "lost").
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
