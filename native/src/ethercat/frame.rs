//! EtherCAT frame and datagram codec (ETG.1000.4 §5).
//!
//! An EtherCAT frame, as carried after an Ethernet header (EtherType 0x88A4) or as the payload
//! of a UDP datagram to port 0x88A4, is a 2-byte frame header followed by one or more datagrams.
//! Each datagram is a 10-byte header, its data, and a 16-bit working counter (WKC).
//!
//! The codec works in caller-owned buffers: [`FrameBuilder`] writes datagrams into a byte
//! slice, [`parse`] walks a received frame, and [`for_each_datagram_mut`] lets a slave (the
//! virtual AKD) serve the datagrams in place. Nothing here allocates, so the cyclic path can
//! use it.

/// EtherType of EtherCAT frames, also the UDP port of EtherCAT-over-UDP.
pub const ETHERTYPE: u16 = 0x88A4;
/// Length of an Ethernet II header (destination, source, EtherType).
pub const ETH_HEADER_LEN: usize = 14;
/// Length of the EtherCAT frame header (11-bit length, reserved bit, 4-bit type).
pub const FRAME_HEADER_LEN: usize = 2;
/// Length of a datagram header (command, index, address, length word, IRQ).
pub const DATAGRAM_HEADER_LEN: usize = 10;
/// Length of a datagram's working counter.
pub const WKC_LEN: usize = 2;
/// Largest EtherCAT payload (frame header plus datagrams) an Ethernet frame carries.
pub const MAX_PAYLOAD_LEN: usize = 1500;
/// Largest data part of a single datagram in a maximum-size frame.
pub const MAX_DATAGRAM_DATA: usize = MAX_PAYLOAD_LEN - FRAME_HEADER_LEN - DATAGRAM_HEADER_LEN - WKC_LEN;
/// Frame header type of frames that carry EtherCAT datagrams.
pub const FRAME_TYPE_DATAGRAMS: u8 = 1;
/// Smallest Ethernet frame without FCS; shorter frames are padded on the wire.
pub const MIN_ETH_FRAME_LEN: usize = 60;

wire_codes! {
    /// An EtherCAT datagram command (ETG.1000.4 table 5).
    pub enum Command: u8, "datagram command" {
        /// No operation: slaves ignore it.
        Nop = 0 => "NOP",
        /// Auto-increment physical read.
        Aprd = 1 => "APRD",
        /// Auto-increment physical write.
        Apwr = 2 => "APWR",
        /// Auto-increment physical read-write.
        Aprw = 3 => "APRW",
        /// Configured-address physical read.
        Fprd = 4 => "FPRD",
        /// Configured-address physical write.
        Fpwr = 5 => "FPWR",
        /// Configured-address physical read-write.
        Fprw = 6 => "FPRW",
        /// Broadcast read.
        Brd = 7 => "BRD",
        /// Broadcast write.
        Bwr = 8 => "BWR",
        /// Broadcast read-write.
        Brw = 9 => "BRW",
        /// Logical read.
        Lrd = 10 => "LRD",
        /// Logical write.
        Lwr = 11 => "LWR",
        /// Logical read-write.
        Lrw = 12 => "LRW",
        /// Auto-increment physical read, multiple write (the addressed slave reads, all others write).
        Armw = 13 => "ARMW",
        /// Configured-address physical read, multiple write.
        Frmw = 14 => "FRMW",
    }
}

/// How a datagram selects the slaves that serve it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Addressing {
    /// Position on the bus: the slave that sees ADP == 0 serves it; every slave increments ADP.
    AutoIncrement,
    /// Configured station address (register 0x0010) or alias equals ADP.
    Configured,
    /// Every slave serves it; every slave increments ADP.
    Broadcast,
    /// A 32-bit logical address mapped to physical memory by each slave's FMMUs.
    Logical,
    /// Nobody serves it.
    None,
}

impl Command {
    /// Decodes a command byte.
    pub fn from_u8(code: u8) -> Result<Self, FrameError> {
        Self::ALL.get(code as usize).copied().ok_or(FrameError::UnknownCommand(code))
    }

    /// How the command addresses slaves.
    pub fn addressing(self) -> Addressing {
        match self {
            Command::Nop => Addressing::None,
            Command::Aprd | Command::Apwr | Command::Aprw | Command::Armw => Addressing::AutoIncrement,
            Command::Fprd | Command::Fpwr | Command::Fprw | Command::Frmw => Addressing::Configured,
            Command::Brd | Command::Bwr | Command::Brw => Addressing::Broadcast,
            Command::Lrd | Command::Lwr | Command::Lrw => Addressing::Logical,
        }
    }

    /// Whether a serving slave copies its memory into the datagram.
    pub fn reads(self) -> bool {
        matches!(
            self,
            Command::Aprd
                | Command::Aprw
                | Command::Fprd
                | Command::Fprw
                | Command::Brd
                | Command::Brw
                | Command::Lrd
                | Command::Lrw
                | Command::Armw
                | Command::Frmw
        )
    }

    /// Whether a serving slave copies datagram data into its memory (for ARMW and FRMW, every
    /// slave but the addressed one).
    pub fn writes(self) -> bool {
        matches!(
            self,
            Command::Apwr
                | Command::Aprw
                | Command::Fpwr
                | Command::Fprw
                | Command::Bwr
                | Command::Brw
                | Command::Lwr
                | Command::Lrw
                | Command::Armw
                | Command::Frmw
        )
    }

    /// Working-counter increment of one slave that served the datagram: a read adds 1, a write
    /// adds 1, and a read-write adds 1 for the read and 2 for the write (ETG.1000.4 §5.4.3).
    /// ARMW and FRMW count 1 for the reading slave and 1 for each writing slave.
    pub fn wkc_increment(self, did_read: bool, did_write: bool) -> u16 {
        match self {
            Command::Aprw | Command::Fprw | Command::Brw | Command::Lrw => (did_read as u16) + 2 * (did_write as u16),
            _ => (did_read || did_write) as u16,
        }
    }
}

/// Expected working counter of a datagram served by `readers` slaves that read and `writers`
/// slaves that write (for ARMW/FRMW: the addressed slave reads, the others write).
pub fn expected_wkc(command: Command, readers: u16, writers: u16) -> u16 {
    match command {
        Command::Nop => 0,
        Command::Aprw | Command::Fprw | Command::Brw | Command::Lrw => readers + 2 * writers,
        _ if command.reads() && command.writes() => readers + writers,
        _ if command.reads() => readers,
        _ => writers,
    }
}

/// The decoded header of one datagram.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct DatagramHeader {
    /// The command.
    pub command: Command,
    /// Index chosen by the master to match replies to requests.
    pub index: u8,
    /// Position (auto-increment), station address (configured) or low half of a logical address.
    pub adp: u16,
    /// Register offset, or high half of a logical address.
    pub ado: u16,
    /// Length of the data part in bytes.
    pub len: u16,
    /// The frame has circulated (set by a slave that closed a broken ring).
    pub circulating: bool,
    /// Another datagram follows this one.
    pub more: bool,
    /// External event (IRQ) word, ORed in by the slaves.
    pub irq: u16,
}

impl DatagramHeader {
    /// The 32-bit logical address of a logical-addressing datagram.
    pub fn logical_address(&self) -> u32 {
        (self.adp as u32) | ((self.ado as u32) << 16)
    }

    fn decode(bytes: &[u8]) -> Result<Self, FrameError> {
        let command = Command::from_u8(bytes[0])?;
        let len_word = u16::from_le_bytes([bytes[6], bytes[7]]);
        Ok(DatagramHeader {
            command,
            index: bytes[1],
            adp: u16::from_le_bytes([bytes[2], bytes[3]]),
            ado: u16::from_le_bytes([bytes[4], bytes[5]]),
            len: len_word & 0x07FF,
            circulating: len_word & 0x4000 != 0,
            more: len_word & 0x8000 != 0,
            irq: u16::from_le_bytes([bytes[8], bytes[9]]),
        })
    }

    fn encode(&self, out: &mut [u8]) {
        out[0] = self.command as u8;
        out[1] = self.index;
        out[2..4].copy_from_slice(&self.adp.to_le_bytes());
        out[4..6].copy_from_slice(&self.ado.to_le_bytes());
        let len_word = self.len | ((self.circulating as u16) << 14) | ((self.more as u16) << 15);
        out[6..8].copy_from_slice(&len_word.to_le_bytes());
        out[8..10].copy_from_slice(&self.irq.to_le_bytes());
    }
}

/// One datagram of a received frame.
#[derive(Clone, Copy, Debug)]
pub struct Datagram<'a> {
    /// Its header.
    pub header: DatagramHeader,
    /// Its data part.
    pub data: &'a [u8],
    /// Its working counter.
    pub wkc: u16,
    /// Offset of the data part from the start of the frame (the frame header's first byte).
    pub data_offset: usize,
}

/// Reads the EtherCAT frame header: returns the length of the datagram area.
pub fn frame_header(payload: &[u8]) -> Result<usize, FrameError> {
    if payload.len() < FRAME_HEADER_LEN {
        return Err(FrameError::Truncated { what: "frame header", needed: FRAME_HEADER_LEN, got: payload.len() });
    }
    let word = u16::from_le_bytes([payload[0], payload[1]]);
    let frame_type = (word >> 12) as u8;
    if frame_type != FRAME_TYPE_DATAGRAMS {
        return Err(FrameError::NotDatagrams(frame_type));
    }
    let len = (word & 0x07FF) as usize;
    if FRAME_HEADER_LEN + len > payload.len() {
        return Err(FrameError::Truncated {
            what: "datagrams announced by the frame header",
            needed: FRAME_HEADER_LEN + len,
            got: payload.len(),
        });
    }
    Ok(len)
}

/// Iterator over the datagrams of a frame; yields an error once and stops on malformed input.
pub struct Datagrams<'a> {
    payload: &'a [u8],
    pos: usize,
    end: usize,
    done: bool,
}

impl<'a> Iterator for Datagrams<'a> {
    type Item = Result<Datagram<'a>, FrameError>;

    fn next(&mut self) -> Option<Self::Item> {
        if self.done {
            return None;
        }
        match locate_datagram(self.payload, self.pos, self.end) {
            Ok((header, data_offset, next)) => {
                let len = header.len as usize;
                let wkc = u16::from_le_bytes([self.payload[data_offset + len], self.payload[data_offset + len + 1]]);
                self.pos = next;
                self.done = !header.more;
                Some(Ok(Datagram { header, data: &self.payload[data_offset..data_offset + len], wkc, data_offset }))
            }
            Err(e) => {
                self.done = true;
                Some(Err(e))
            }
        }
    }
}

/// Decodes the header of the datagram at `pos` and checks it fits before `end`; returns it, the
/// offset of its data and the offset of the next datagram.
fn locate_datagram(payload: &[u8], pos: usize, end: usize) -> Result<(DatagramHeader, usize, usize), FrameError> {
    if pos + DATAGRAM_HEADER_LEN > end {
        return Err(FrameError::Truncated { what: "datagram header", needed: pos + DATAGRAM_HEADER_LEN, got: end });
    }
    let header = DatagramHeader::decode(&payload[pos..pos + DATAGRAM_HEADER_LEN])?;
    let data_offset = pos + DATAGRAM_HEADER_LEN;
    let next = data_offset + header.len as usize + WKC_LEN;
    if next > end {
        return Err(FrameError::Truncated { what: "datagram data and working counter", needed: next, got: end });
    }
    Ok((header, data_offset, next))
}

/// Walks the datagrams of an EtherCAT payload (starting at the frame header).
pub fn parse(payload: &[u8]) -> Result<Datagrams<'_>, FrameError> {
    let len = frame_header(payload)?;
    Ok(Datagrams { payload, pos: FRAME_HEADER_LEN, end: FRAME_HEADER_LEN + len, done: len == 0 })
}

/// Checks a whole frame: header, every datagram, and that the last one ends the frame.
/// Returns the number of datagrams.
pub fn validate(payload: &[u8]) -> Result<usize, FrameError> {
    let len = frame_header(payload)?;
    if len == 0 {
        return Err(FrameError::Empty);
    }
    let mut count = 0;
    let mut last_end = FRAME_HEADER_LEN;
    for datagram in parse(payload)? {
        let datagram = datagram?;
        count += 1;
        last_end = datagram.data_offset + datagram.header.len as usize + WKC_LEN;
    }
    if last_end != FRAME_HEADER_LEN + len {
        return Err(FrameError::LengthMismatch { header: len, datagrams: last_end - FRAME_HEADER_LEN });
    }
    Ok(count)
}

/// A datagram a slave serves in place: the header is decoded, data and WKC are writable.
pub struct DatagramMut<'a> {
    /// Its header; a slave may change `adp` (auto-increment) and `irq`.
    pub header: DatagramHeader,
    /// Its data part.
    pub data: &'a mut [u8],
    /// Its working counter.
    pub wkc: u16,
}

/// Lets a slave serve every datagram of a frame in place, in order. Changes the callback makes
/// to `adp`, `irq`, the data and the WKC are written back. The frame is validated first, so a
/// malformed frame is left untouched.
pub fn for_each_datagram_mut(
    payload: &mut [u8],
    mut serve: impl FnMut(&mut DatagramMut<'_>),
) -> Result<usize, FrameError> {
    let count = validate(payload)?;
    let len = frame_header(payload)?;
    let end = FRAME_HEADER_LEN + len;
    let mut pos = FRAME_HEADER_LEN;
    for _ in 0..count {
        let (header, data_offset, next) = locate_datagram(payload, pos, end)?;
        let data_end = data_offset + header.len as usize;
        let wkc = u16::from_le_bytes([payload[data_end], payload[data_end + 1]]);
        let (head, rest) = payload.split_at_mut(data_offset);
        let (data, tail) = rest.split_at_mut(header.len as usize);
        let mut datagram = DatagramMut { header, data, wkc };
        serve(&mut datagram);
        datagram.header.encode(&mut head[pos..pos + DATAGRAM_HEADER_LEN]);
        tail[..WKC_LEN].copy_from_slice(&datagram.wkc.to_le_bytes());
        pos = next;
    }
    Ok(count)
}

/// Where a datagram pushed into a [`FrameBuilder`] landed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Slot {
    /// Offset of the data part from the frame header's first byte.
    pub data_offset: usize,
    /// Length of the data part.
    pub len: usize,
    /// The datagram index.
    pub index: u8,
}

impl Slot {
    /// Offset of the working counter from the frame header's first byte.
    pub fn wkc_offset(&self) -> usize {
        self.data_offset + self.len
    }

    /// Reads the working counter of this slot from a reply frame.
    pub fn wkc(&self, reply: &[u8]) -> Result<u16, FrameError> {
        let at = self.wkc_offset();
        reply.get(at..at + WKC_LEN).map(|b| u16::from_le_bytes([b[0], b[1]])).ok_or(FrameError::Truncated {
            what: "reply working counter",
            needed: at + WKC_LEN,
            got: reply.len(),
        })
    }

    /// The data part of this slot in a reply frame.
    pub fn data<'r>(&self, reply: &'r [u8]) -> Result<&'r [u8], FrameError> {
        reply.get(self.data_offset..self.data_offset + self.len).ok_or(FrameError::Truncated {
            what: "reply datagram data",
            needed: self.data_offset + self.len,
            got: reply.len(),
        })
    }
}

/// Builds a frame of one or more datagrams in a caller-owned buffer.
pub struct FrameBuilder<'a> {
    buf: &'a mut [u8],
    len: usize,
    last_header: Option<usize>,
}

impl<'a> FrameBuilder<'a> {
    /// Starts an empty frame at the start of `buf`.
    pub fn new(buf: &'a mut [u8]) -> Self {
        FrameBuilder { buf, len: FRAME_HEADER_LEN, last_header: None }
    }

    /// Bytes still free for datagram data after headers and WKC.
    pub fn remaining_data(&self) -> usize {
        self.buf.len().min(MAX_PAYLOAD_LEN).saturating_sub(self.len + DATAGRAM_HEADER_LEN + WKC_LEN)
    }

    /// Appends a datagram whose data is `data` (for reads, zeros of the wanted length).
    pub fn push(&mut self, command: Command, index: u8, adp: u16, ado: u16, data: &[u8]) -> Result<Slot, FrameError> {
        let slot = self.push_zeroed(command, index, adp, ado, data.len())?;
        self.buf[slot.data_offset..slot.data_offset + data.len()].copy_from_slice(data);
        Ok(slot)
    }

    /// Appends a datagram with `len` zero bytes of data, for the caller to fill through the slot.
    pub fn push_zeroed(
        &mut self,
        command: Command,
        index: u8,
        adp: u16,
        ado: u16,
        len: usize,
    ) -> Result<Slot, FrameError> {
        if len > MAX_DATAGRAM_DATA || len > self.remaining_data() {
            return Err(FrameError::TooLarge { len, room: self.remaining_data() });
        }
        if let Some(previous) = self.last_header {
            self.buf[previous + 7] |= 0x80;
        }
        let at = self.len;
        DatagramHeader { command, index, adp, ado, len: len as u16, circulating: false, more: false, irq: 0 }
            .encode(&mut self.buf[at..at + DATAGRAM_HEADER_LEN]);
        let data_offset = at + DATAGRAM_HEADER_LEN;
        self.buf[data_offset..data_offset + len + WKC_LEN].fill(0);
        self.len = data_offset + len + WKC_LEN;
        self.last_header = Some(at);
        Ok(Slot { data_offset, len, index })
    }

    /// Mutable access to the frame bytes written so far (to fill a slot).
    pub fn bytes_mut(&mut self) -> &mut [u8] {
        &mut self.buf[..self.len]
    }

    /// Number of datagrams pushed so far is not tracked; this says whether any was.
    pub fn is_empty(&self) -> bool {
        self.last_header.is_none()
    }

    /// Writes the frame header and returns the frame's length.
    pub fn finish(self) -> usize {
        let word = ((self.len - FRAME_HEADER_LEN) as u16 & 0x07FF) | ((FRAME_TYPE_DATAGRAMS as u16) << 12);
        self.buf[..FRAME_HEADER_LEN].copy_from_slice(&word.to_le_bytes());
        self.len
    }
}

/// Writes an Ethernet II header for an EtherCAT frame: broadcast destination, `source` MAC.
pub fn write_ethernet_header(out: &mut [u8], source: [u8; 6]) {
    out[0..6].fill(0xFF);
    out[6..12].copy_from_slice(&source);
    out[12..14].copy_from_slice(&ETHERTYPE.to_be_bytes());
}

/// A malformed or unexpected EtherCAT frame.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum FrameError {
    /// Fewer bytes than the structure named by `what` needs.
    #[error("truncated frame: the {what} needs {needed} bytes, the frame has {got}")]
    Truncated {
        /// The structure being decoded.
        what: &'static str,
        /// Bytes it needs.
        needed: usize,
        /// Bytes there were.
        got: usize,
    },
    /// The frame header's type is not 1 (EtherCAT datagrams).
    #[error("frame header type {0} is not 1 (EtherCAT datagrams)")]
    NotDatagrams(u8),
    /// A datagram command byte above 14.
    #[error("unknown datagram command {0} (allowed 0..=14, NOP..FRMW)")]
    UnknownCommand(u8),
    /// A frame header announcing no datagrams.
    #[error("frame header announces no datagrams")]
    Empty,
    /// The frame header's length differs from the datagrams' total.
    #[error("frame header announces {header} bytes of datagrams but the datagrams take {datagrams}")]
    LengthMismatch {
        /// Length in the frame header.
        header: usize,
        /// Length the datagrams take.
        datagrams: usize,
    },
    /// A datagram that does not fit the frame.
    #[error("datagram of {len} data bytes does not fit the frame ({room} bytes left)")]
    TooLarge {
        /// Data length asked for.
        len: usize,
        /// Room left.
        room: usize,
    },
    /// Not an EtherCAT Ethernet frame (EtherType other than 0x88A4).
    #[error("EtherType 0x{0:04X} is not EtherCAT (0x88A4)")]
    NotEtherCat(u16),
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn builds_and_parses_several_datagrams() {
        let mut buf = [0u8; 256];
        let mut b = FrameBuilder::new(&mut buf);
        let a = b.push(Command::Brd, 1, 0, 0x0130, &[0, 0]).unwrap();
        let c = b.push(Command::Lrw, 2, 0, 0x0001, &[1, 2, 3, 4]).unwrap();
        let len = b.finish();
        assert_eq!(len, 2 + (10 + 2 + 2) + (10 + 4 + 2));
        let datagrams: Vec<_> = parse(&buf[..len]).unwrap().map(|d| d.unwrap()).collect();
        assert_eq!(datagrams.len(), 2);
        assert!(datagrams[0].header.more);
        assert!(!datagrams[1].header.more);
        assert_eq!(datagrams[1].header.command, Command::Lrw);
        assert_eq!(datagrams[1].header.logical_address(), 0x0001_0000);
        assert_eq!(datagrams[1].data, &[1, 2, 3, 4]);
        assert_eq!(a.data_offset, 12);
        assert_eq!(c.data_offset, datagrams[1].data_offset);
        assert_eq!(validate(&buf[..len]).unwrap(), 2);
    }

    #[test]
    fn decodes_a_frame_from_the_real_capture() {
        // Frame 1 of soem-sdinfo-akd.pcapng after its Ethernet header: BWR 0x0103, one byte.
        let payload = [0x0d, 0x10, 0x08, 0x01, 0x00, 0x00, 0x03, 0x01, 0x01, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00];
        let d = parse(&payload).unwrap().next().unwrap().unwrap();
        assert_eq!(d.header.command, Command::Bwr);
        assert_eq!(d.header.ado, 0x0103);
        assert_eq!(d.data, &[0]);
    }

    #[test]
    fn working_counter_rules() {
        assert_eq!(Command::Lrw.wkc_increment(true, true), 3);
        assert_eq!(Command::Lrw.wkc_increment(true, false), 1);
        assert_eq!(Command::Lrw.wkc_increment(false, true), 2);
        assert_eq!(Command::Brd.wkc_increment(true, false), 1);
        assert_eq!(Command::Armw.wkc_increment(false, true), 1);
        assert_eq!(expected_wkc(Command::Lrw, 2, 2), 6);
        assert_eq!(expected_wkc(Command::Bwr, 0, 3), 3);
        assert_eq!(expected_wkc(Command::Nop, 4, 4), 0);
        // DC drift datagram on three clocks: the reference reads, the two others write.
        assert_eq!(expected_wkc(Command::Frmw, 1, 2), 3);
    }

    #[test]
    fn rejects_bad_frames() {
        assert!(matches!(parse(&[0x0d]), Err(FrameError::Truncated { .. })));
        assert!(matches!(parse(&[0x00, 0x50, 0, 0]), Err(FrameError::NotDatagrams(5))));
        assert!(matches!(validate(&[0x20, 0x10, 0, 0]), Err(FrameError::Truncated { .. })));
        let bad_command = [0x0c, 0x10, 0x0f, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0];
        assert!(matches!(validate(&bad_command), Err(FrameError::UnknownCommand(15))));
        assert!(matches!(validate(&[0x00, 0x10]), Err(FrameError::Empty)));
    }

    #[test]
    fn refuses_datagrams_that_do_not_fit() {
        let mut buf = [0u8; 40];
        let mut b = FrameBuilder::new(&mut buf);
        assert!(matches!(b.push_zeroed(Command::Fprd, 0, 0, 0, 100), Err(FrameError::TooLarge { .. })));
    }

    proptest! {
        #[test]
        fn parsing_arbitrary_bytes_never_panics(bytes in proptest::collection::vec(any::<u8>(), 0..300)) {
            let _ = validate(&bytes);
            if let Ok(it) = parse(&bytes) { for d in it { let _ = d; } }
            let mut copy = bytes.clone();
            let before = copy.clone();
            if for_each_datagram_mut(&mut copy, |d| d.wkc += 1).is_err() {
                prop_assert_eq!(copy, before);
            }
        }

        #[test]
        fn built_frames_round_trip(sizes in proptest::collection::vec(0usize..64, 1..8), cmd in 0u8..15) {
            let mut buf = [0u8; 1514];
            let mut b = FrameBuilder::new(&mut buf);
            let command = Command::from_u8(cmd).unwrap();
            for (i, s) in sizes.iter().enumerate() {
                let data: Vec<u8> = (0..*s).map(|x| x as u8 ^ i as u8).collect();
                b.push(command, i as u8, i as u16, 0x1000 + i as u16, &data).unwrap();
            }
            let len = b.finish();
            prop_assert_eq!(validate(&buf[..len]).unwrap(), sizes.len());
            for (i, d) in parse(&buf[..len]).unwrap().enumerate() {
                let d = d.unwrap();
                prop_assert_eq!(d.header.index, i as u8);
                prop_assert_eq!(d.data.len(), sizes[i]);
                prop_assert_eq!(d.header.more, i + 1 < sizes.len());
            }
        }
    }
}
