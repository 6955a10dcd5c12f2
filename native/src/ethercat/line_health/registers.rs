//! The registers in which an ESC counts what went wrong at its ports, and those that tell its
//! ports' links: the error counters (0x0300–0x0313, one block of 20 bytes), the DL status
//! (0x0110) and the port descriptor (0x0007).
//!
//! Every counter is one byte that stops at 0xFF (Section I, "Error counters"; Section II, each
//! counter's register). A write from the master clears counters, the value written being
//! ignored (Section II, the notes under each counter): a write to any of 0x0300–0x030B clears
//! all of the RX error and forwarded RX error counters, one to 0x030C the processing unit's
//! alone, one to 0x030D the PDI error counter and its error code 0x030E–0x030F, one to any of
//! 0x0310–0x0313 all of the lost link counters ([`cleared_by_write`]). Errors are counted only
//! at an open port.

use std::ops::Range;

/// Ports an ESC may have.
pub const PORTS: usize = 4;
/// The first error counter: port 0's invalid frame counter.
pub const ERROR_COUNTERS: u16 = 0x0300;
/// Bytes from [`ERROR_COUNTERS`] through the last lost link counter (0x0313).
pub const ERROR_COUNTERS_LEN: usize = 0x14;
/// Port 0's invalid frame counter; port `n`'s is 2·`n` on, its RX error counter one after it.
pub const RX_ERROR_COUNTERS: u16 = 0x0300;
/// Port 0's forwarded RX error counter; port `n`'s is `n` on.
pub const FORWARDED_RX_ERROR_COUNTERS: u16 = 0x0308;
/// The EtherCAT processing unit's error counter.
pub const PROCESSING_UNIT_ERROR_COUNTER: u16 = 0x030C;
/// The PDI error counter.
pub const PDI_ERROR_COUNTER: u16 = 0x030D;
/// Port 0's lost link counter; port `n`'s is `n` on.
pub const LOST_LINK_COUNTERS: u16 = 0x0310;
/// Where a counter stops.
pub const SATURATED: u8 = 0xFF;

/// What a write to the registers in the first range clears: the second range.
const CLEARS: [(Range<usize>, Range<usize>); 4] = [
    (0x0300..0x030C, 0x0300..0x030C),
    (0x030C..0x030D, 0x030C..0x030D),
    (0x030D..0x030E, 0x030D..0x0310),
    (0x0310..0x0314, 0x0310..0x0314),
];

/// The counters a write of `len` bytes at `at` clears (see the module's documentation).
pub fn cleared_by_write(at: usize, len: usize) -> impl Iterator<Item = Range<usize>> {
    CLEARS.into_iter().filter(move |(written, _)| written.start < at + len && at < written.end).map(|(_, c)| c)
}

/// One counter of an ESC.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Counter {
    /// Frames that entered `port` invalid, this ESC the first to see it: CRC error, too long,
    /// a physical-layer error inside (0x0300 + 2·port).
    InvalidFrames(usize),
    /// Physical-layer receive errors at `port`, inside frames or between them (0x0301 + 2·port).
    RxErrors(usize),
    /// Frames that entered `port` invalid and marked so by an ESC before (0x0308 + port).
    ForwardedErrors(usize),
    /// Times `port` lost its link (0x0310 + port).
    LostLinks(usize),
    /// Invalid frames passing the processing unit (0x030C): those that entered port 0.
    ProcessingUnit,
    /// Errors of the process data interface, the ESC's side towards its application (0x030D).
    Pdi,
}

impl Counter {
    /// Its register.
    pub fn register(self) -> u16 {
        match self {
            Counter::InvalidFrames(port) => RX_ERROR_COUNTERS + 2 * port as u16,
            Counter::RxErrors(port) => RX_ERROR_COUNTERS + 2 * port as u16 + 1,
            Counter::ForwardedErrors(port) => FORWARDED_RX_ERROR_COUNTERS + port as u16,
            Counter::LostLinks(port) => LOST_LINK_COUNTERS + port as u16,
            Counter::ProcessingUnit => PROCESSING_UNIT_ERROR_COUNTER,
            Counter::Pdi => PDI_ERROR_COUNTER,
        }
    }
}

/// The counters of one port.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "python", derive(pyo3::IntoPyObject))]
pub struct PortCounts<T> {
    /// Invalid frames first seen at this port ([`Counter::InvalidFrames`]).
    pub invalid_frames: T,
    /// Physical-layer receive errors ([`Counter::RxErrors`]).
    pub rx_errors: T,
    /// Invalid frames an ESC before marked ([`Counter::ForwardedErrors`]).
    pub forwarded_errors: T,
    /// Links lost ([`Counter::LostLinks`]).
    pub lost_links: T,
}

/// Counts in each field: [`PortCounts::values`] and [`ErrorCounts::values`] give them in this order.
const PORT_FIELDS: usize = 4;
/// Fields of an [`ErrorCounts`].
pub const COUNTERS: usize = PORTS * PORT_FIELDS + 2;

impl<T: Copy> PortCounts<T> {
    /// The counts in field order.
    pub fn values(&self) -> [T; PORT_FIELDS] {
        [self.invalid_frames, self.rx_errors, self.forwarded_errors, self.lost_links]
    }

    fn from_values([invalid_frames, rx_errors, forwarded_errors, lost_links]: [T; PORT_FIELDS]) -> Self {
        PortCounts { invalid_frames, rx_errors, forwarded_errors, lost_links }
    }

    /// Errors first seen at this port: invalid frames and physical-layer errors (a
    /// physical-layer error inside a frame counts in both; this counts it once at least).
    pub fn original(&self) -> T
    where
        T: Ord,
    {
        self.invalid_frames.max(self.rx_errors)
    }
}

/// Every counter of one ESC, each as a `T`: the registers as read (`u8`), totals (`u64`), ...
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ErrorCounts<T> {
    /// Each port's counters, by port number.
    pub ports: [PortCounts<T>; PORTS],
    /// The processing unit's ([`Counter::ProcessingUnit`]).
    pub processing_unit: T,
    /// The process data interface's ([`Counter::Pdi`]).
    pub pdi: T,
}

impl<T: Copy + Default> ErrorCounts<T> {
    /// The counts in a fixed order: each port's in [`PortCounts::values`]' order, port by port,
    /// then the processing unit's and the PDI's.
    pub fn values(&self) -> [T; COUNTERS] {
        let mut values = [T::default(); COUNTERS];
        for (port, counts) in self.ports.iter().enumerate() {
            values[port * PORT_FIELDS..(port + 1) * PORT_FIELDS].copy_from_slice(&counts.values());
        }
        values[COUNTERS - 2] = self.processing_unit;
        values[COUNTERS - 1] = self.pdi;
        values
    }

    /// The counts [`values`](Self::values) gave.
    pub fn from_values(values: [T; COUNTERS]) -> Self {
        let port = |p: usize| {
            let mut fields = [T::default(); PORT_FIELDS];
            fields.copy_from_slice(&values[p * PORT_FIELDS..(p + 1) * PORT_FIELDS]);
            PortCounts::from_values(fields)
        };
        ErrorCounts {
            ports: std::array::from_fn(port),
            processing_unit: values[COUNTERS - 2],
            pdi: values[COUNTERS - 1],
        }
    }

    /// The count of `counter`, to change it.
    pub fn get_mut(&mut self, counter: Counter) -> &mut T {
        match counter {
            Counter::InvalidFrames(p) => &mut self.ports[p].invalid_frames,
            Counter::RxErrors(p) => &mut self.ports[p].rx_errors,
            Counter::ForwardedErrors(p) => &mut self.ports[p].forwarded_errors,
            Counter::LostLinks(p) => &mut self.ports[p].lost_links,
            Counter::ProcessingUnit => &mut self.processing_unit,
            Counter::Pdi => &mut self.pdi,
        }
    }
}

impl ErrorCounts<u8> {
    /// The counters as the block of [`ERROR_COUNTERS_LEN`] bytes from 0x0300 holds them.
    pub fn decode(block: &[u8; ERROR_COUNTERS_LEN]) -> Self {
        let at = |register: u16| block[usize::from(register - ERROR_COUNTERS)];
        let port = |p: usize| PortCounts {
            invalid_frames: at(Counter::InvalidFrames(p).register()),
            rx_errors: at(Counter::RxErrors(p).register()),
            forwarded_errors: at(Counter::ForwardedErrors(p).register()),
            lost_links: at(Counter::LostLinks(p).register()),
        };
        ErrorCounts {
            ports: std::array::from_fn(port),
            processing_unit: at(PROCESSING_UNIT_ERROR_COUNTER),
            pdi: at(PDI_ERROR_COUNTER),
        }
    }

    /// Whether any counter stopped at [`SATURATED`].
    pub fn saturated(&self) -> bool {
        self.values().contains(&SATURATED)
    }

    /// The highest count.
    pub fn highest(&self) -> u8 {
        self.values().into_iter().max().unwrap_or(0)
    }
}

/// DL status (0x0110): each port's link, loop and communication, and the PDI's state.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct DlStatus(pub u16);

impl DlStatus {
    /// Whether a physical link is detected at `port` (bit 4 + port).
    pub fn link(self, port: usize) -> bool {
        self.0 >> (4 + port) & 1 == 1
    }

    /// Whether `port`'s loop is closed (bit 8 + 2·port): frames do not leave through it.
    pub fn loop_closed(self, port: usize) -> bool {
        self.0 >> (8 + 2 * port) & 1 == 1
    }

    /// Whether communication is established at `port` (bit 9 + 2·port).
    pub fn communication(self, port: usize) -> bool {
        self.0 >> (9 + 2 * port) & 1 == 1
    }

    /// Whether frames go out and come back through `port`: its loop open with communication.
    pub fn open(self, port: usize) -> bool {
        !self.loop_closed(port) && self.communication(port)
    }

    /// The DL status of an ESC whose `pdi` bits (0–1: PDI operational, watchdog not expired)
    /// are as given and whose ports have a link where `links` says, each loop on auto: a port
    /// with a link is open with communication, one without closed (Section II, "Decoding port
    /// state in ESC DL status register 0x0111").
    pub fn with_links(pdi: u16, links: [bool; PORTS]) -> Self {
        let ports = links.iter().enumerate().fold(0u16, |bits, (port, &link)| {
            bits | if link { 1 << (4 + port) | 1 << (9 + 2 * port) } else { 1 << (8 + 2 * port) }
        });
        DlStatus(pdi & 0x0003 | ports)
    }
}

wire_codes! {
    /// What a port is, as the port descriptor (0x0007) tells it, two bits a port.
    pub enum PortKind: u8, "port kind" {
        /// No such port.
        NotImplemented = 0 => "not implemented",
        /// A port the EEPROM configures.
        NotConfigured = 1 => "not configured",
        /// E-bus (LVDS), within a terminal block.
        Ebus = 2 => "E-bus",
        /// MII or RMII to a PHY: an Ethernet cable.
        Mii = 3 => "MII",
    }
}

/// The port descriptor (0x0007).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct PortDescriptor(pub u8);

impl PortDescriptor {
    /// What `port` is.
    pub fn kind(self, port: usize) -> PortKind {
        PortKind::ALL[usize::from(self.0 >> (2 * port) & 0x03)]
    }

    /// Whether the ESC has `port`.
    pub fn has(self, port: usize) -> bool {
        self.kind(port) != PortKind::NotImplemented
    }

    /// The ports the ESC has.
    pub fn ports(self) -> impl Iterator<Item = usize> {
        (0..PORTS).filter(move |&p| self.has(p))
    }
}

/// The order in which a frame that entered at port 0 passes the ports: out through the next
/// open port after the one it came in by, back in there, and on (Section I, "Frame processing
/// order"): 0 → 3 → 1 → 2 → 0.
pub const PROCESSING_ORDER: [usize; PORTS] = [0, 3, 1, 2];

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_block_decodes_each_counter_at_its_register() {
        let mut block = [0u8; ERROR_COUNTERS_LEN];
        for (i, b) in block.iter_mut().enumerate() {
            *b = i as u8 + 1;
        }
        let counts = ErrorCounts::decode(&block);
        assert_eq!(
            counts.ports[0],
            PortCounts { invalid_frames: 1, rx_errors: 2, forwarded_errors: 9, lost_links: 17 }
        );
        assert_eq!(
            counts.ports[3],
            PortCounts { invalid_frames: 7, rx_errors: 8, forwarded_errors: 12, lost_links: 20 }
        );
        assert_eq!((counts.processing_unit, counts.pdi), (13, 14));
        assert_eq!(ErrorCounts::from_values(counts.values()), counts);
        assert_eq!(counts.ports[2].lost_links, 19);
    }

    #[test]
    fn a_write_clears_the_counters_its_note_names() {
        let cleared = |at, len| cleared_by_write(at, len).map(|r| (r.start, r.end)).collect::<Vec<_>>();
        assert_eq!(cleared(0x0305, 1), [(0x0300, 0x030C)]);
        assert_eq!(cleared(0x030C, 1), [(0x030C, 0x030D)]);
        assert_eq!(cleared(0x030D, 1), [(0x030D, 0x0310)]);
        assert_eq!(cleared(0x0312, 1), [(0x0310, 0x0314)]);
        assert_eq!(cleared(0x030E, 2), Vec::<(usize, usize)>::new(), "the PDI error code is read-only");
        assert_eq!(cleared(0x0300, ERROR_COUNTERS_LEN).len(), 4);
        assert!(cleared(0x0110, 2).is_empty());
    }

    #[test]
    fn dl_status_of_links_is_what_the_real_escs_showed() {
        // The AKD alone and with a drive behind it (SOEM capture, TwinCAT), the EK1100 alone and
        // with a terminal behind it (SOEM captures).
        assert_eq!(DlStatus::with_links(0x0003, [true, false, false, false]), DlStatus(0x5613));
        assert_eq!(DlStatus::with_links(0x0003, [true, true, false, false]), DlStatus(0x5A33));
        assert_eq!(DlStatus::with_links(0x0001, [true, false, false, false]), DlStatus(0x5611));
        assert_eq!(DlStatus::with_links(0x0001, [true, true, false, false]), DlStatus(0x5A31));
        let status = DlStatus(0x5A33);
        assert!(status.link(1) && status.open(1) && !status.loop_closed(1));
        assert!(!status.link(2) && status.loop_closed(2) && !status.open(2));
    }

    #[test]
    fn port_descriptors_of_the_real_escs() {
        // The AKD's: two MII ports; the EK1100's ET1100: MII in, E-bus to the terminals, MII out;
        // the ET1200 of the EL terminals: two E-bus ports and a port 3 the EEPROM configures.
        assert_eq!(PortDescriptor(0x0F).ports().collect::<Vec<_>>(), [0, 1]);
        assert_eq!(
            PortDescriptor(0x3B).ports().map(|p| PortDescriptor(0x3B).kind(p)).collect::<Vec<_>>(),
            [PortKind::Mii, PortKind::Ebus, PortKind::Mii]
        );
        assert_eq!(PortDescriptor(0x4A).ports().collect::<Vec<_>>(), [0, 1, 3]);
        assert_eq!(PortDescriptor(0x4A).kind(3).name(), "not configured");
    }
}
