//! Recording a link's traffic to a pcapng file that Wireshark and tshark decode.
//!
//! [`Recorder`] wraps any [`Link`]. Links carry bare EtherCAT payloads, so each frame is written
//! as the Ethernet frame it is (or would be) on the wire: broadcast, from
//! [`MASTER_MAC`](super::raw::MASTER_MAC) for requests and from the same address with
//! [`RETURNED_MAC_BIT`](super::raw::RETURNED_MAC_BIT) set for replies, as a real ESC marks the
//! frames it returns, EtherType 0x88A4, padded to the Ethernet minimum. Timestamps are wall-clock
//! nanoseconds (pcapng `if_tsresol` 9) taken just before the request leaves and just after the
//! reply is back; the file is written after the exchange, through a large buffer, so recording
//! adds no system call to most exchanges.
//!
//! A failing write never breaks the link: it is counted ([`Recorder::write_errors`]) and the
//! first one is returned by [`Recorder::finish`]. A recorder dropped without `finish` still
//! flushes its buffer (the buffered writer does on drop), only without reporting a failure.

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::time::{Duration, SystemTime, UNIX_EPOCH};

use super::raw::{MASTER_MAC, RETURNED_MAC_BIT};
use super::Link;
use crate::error::{Error, Result};
use crate::frame::{write_ethernet_header, ETH_HEADER_LEN, MAX_PAYLOAD_LEN, MIN_ETH_FRAME_LEN};

/// pcapng block types and option codes (pcapng specification, IETF draft).
mod block {
    pub const SECTION_HEADER: u32 = 0x0A0D_0D0A;
    pub const INTERFACE_DESCRIPTION: u32 = 0x0000_0001;
    pub const ENHANCED_PACKET: u32 = 0x0000_0006;
    pub const BYTE_ORDER_MAGIC: u32 = 0x1A2B_3C4D;
    pub const LINKTYPE_ETHERNET: u16 = 1;
    pub const OPT_END: u16 = 0;
    pub const OPT_IF_NAME: u16 = 2;
    pub const OPT_IF_TSRESOL: u16 = 9;
    pub const OPT_SHB_USERAPPL: u16 = 4;
}

/// Buffer between the recorder and the file: about 8000 minimum-size frames.
const WRITE_BUFFER: usize = 1 << 20;

/// A link whose every frame sent and received is written to a pcapng file.
pub struct Recorder<L: Link> {
    inner: L,
    path: PathBuf,
    out: BufWriter<File>,
    /// The block being assembled, reused so recording does not allocate per frame.
    block: Vec<u8>,
    write_errors: u64,
    first_error: Option<std::io::Error>,
}

/// Nanoseconds since the Unix epoch (0 if the clock is before it).
fn now_ns() -> u64 {
    SystemTime::now().duration_since(UNIX_EPOCH).map_or(0, |d| d.as_nanos() as u64)
}

/// Appends a pcapng option, padded to 4 bytes.
fn push_option(block: &mut Vec<u8>, code: u16, value: &[u8]) {
    block.extend_from_slice(&code.to_le_bytes());
    block.extend_from_slice(&(value.len() as u16).to_le_bytes());
    block.extend_from_slice(value);
    block.resize(block.len().next_multiple_of(4), 0);
}

/// Starts a block of `kind` in `block` (cleared); [`end_block`] fills in its length.
fn begin_block(block: &mut Vec<u8>, kind: u32) {
    block.clear();
    block.extend_from_slice(&kind.to_le_bytes());
    block.extend_from_slice(&[0; 4]);
}

/// Pads the block, appends the trailing length and writes both length fields.
fn end_block(block: &mut Vec<u8>) {
    block.resize(block.len().next_multiple_of(4), 0);
    let total = (block.len() + 4) as u32;
    block.extend_from_slice(&total.to_le_bytes());
    block[4..8].copy_from_slice(&total.to_le_bytes());
}

impl<L: Link> Recorder<L> {
    /// Wraps `inner`, creating (or truncating) the pcapng file at `path` and writing its
    /// section header and interface description (named after `inner`).
    pub fn new(inner: L, path: impl AsRef<Path>) -> Result<Self> {
        let path = path.as_ref().to_path_buf();
        let file =
            File::create(&path).map_err(|e| Error::io(format!("creating capture file {}", path.display()), e))?;
        let mut recorder = Recorder {
            inner,
            path,
            out: BufWriter::with_capacity(WRITE_BUFFER, file),
            block: Vec::with_capacity(ETH_HEADER_LEN + MAX_PAYLOAD_LEN + 64),
            write_errors: 0,
            first_error: None,
        };
        let b = &mut recorder.block;
        begin_block(b, block::SECTION_HEADER);
        b.extend_from_slice(&block::BYTE_ORDER_MAGIC.to_le_bytes());
        b.extend_from_slice(&1u16.to_le_bytes());
        b.extend_from_slice(&0u16.to_le_bytes());
        // Section length unknown.
        b.extend_from_slice(&(-1i64).to_le_bytes());
        push_option(b, block::OPT_SHB_USERAPPL, b"akd_ros");
        push_option(b, block::OPT_END, &[]);
        end_block(b);
        recorder.write_block()?;

        let name = recorder.inner.describe();
        let b = &mut recorder.block;
        begin_block(b, block::INTERFACE_DESCRIPTION);
        b.extend_from_slice(&block::LINKTYPE_ETHERNET.to_le_bytes());
        b.extend_from_slice(&0u16.to_le_bytes());
        // No snapshot limit.
        b.extend_from_slice(&0u32.to_le_bytes());
        push_option(b, block::OPT_IF_NAME, name.as_bytes());
        // Timestamps in units of 10^-9 s.
        push_option(b, block::OPT_IF_TSRESOL, &[9]);
        push_option(b, block::OPT_END, &[]);
        end_block(b);
        recorder.write_block()?;
        Ok(recorder)
    }

    /// Writes the assembled block, an error naming the file.
    fn write_block(&mut self) -> Result<()> {
        self.out
            .write_all(&self.block)
            .map_err(|e| Error::io(format!("writing capture file {}", self.path.display()), e))
    }

    /// Records one EtherCAT payload as an Ethernet frame at `time_ns`; a reply's source address
    /// has [`RETURNED_MAC_BIT`] set.
    fn record(&mut self, payload: &[u8], time_ns: u64, reply: bool) {
        let b = &mut self.block;
        begin_block(b, block::ENHANCED_PACKET);
        // Interface 0, timestamp high then low 32 bits.
        b.extend_from_slice(&0u32.to_le_bytes());
        b.extend_from_slice(&((time_ns >> 32) as u32).to_le_bytes());
        b.extend_from_slice(&(time_ns as u32).to_le_bytes());
        let frame_len = (ETH_HEADER_LEN + payload.len()).max(MIN_ETH_FRAME_LEN) as u32;
        b.extend_from_slice(&frame_len.to_le_bytes());
        b.extend_from_slice(&frame_len.to_le_bytes());
        let frame_start = b.len();
        let mut source = MASTER_MAC;
        if reply {
            source[0] |= RETURNED_MAC_BIT;
        }
        b.resize(frame_start + ETH_HEADER_LEN, 0);
        write_ethernet_header(&mut b[frame_start..], source);
        b.extend_from_slice(payload);
        b.resize(frame_start + frame_len as usize, 0);
        end_block(b);
        if let Err(e) = self.out.write_all(&self.block) {
            self.count_error(e);
        }
    }

    fn count_error(&mut self, e: std::io::Error) {
        self.write_errors += 1;
        self.first_error.get_or_insert(e);
    }

    /// Frames that could not be written to the file.
    pub fn write_errors(&self) -> u64 {
        self.write_errors
    }

    /// Flushes the file and returns the wrapped link, or the first write error.
    pub fn finish(mut self) -> Result<L> {
        if let Err(e) = self.out.flush() {
            self.count_error(e);
        }
        match self.first_error.take() {
            Some(e) => Err(Error::io(
                format!("writing capture file {} ({} frames lost)", self.path.display(), self.write_errors),
                e,
            )),
            None => Ok(self.inner),
        }
    }
}

impl<L: Link> Link for Recorder<L> {
    fn exchange(&mut self, tx: &[u8], rx: &mut [u8], timeout: Duration) -> Result<usize> {
        let sent_ns = now_ns();
        let result = self.inner.exchange(tx, rx, timeout);
        let received_ns = now_ns();
        self.record(tx, sent_ns, false);
        if let Ok(n) = result {
            self.record(&rx[..n], received_ns, true);
        }
        result
    }

    fn describe(&self) -> String {
        format!("{} recorded to {}", self.inner.describe(), self.path.display())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::frame::{Command, FrameBuilder};

    /// A link where every datagram is answered with its working counter incremented, and the
    /// third exchange times out.
    struct Loop {
        exchanges: u32,
    }

    impl Link for Loop {
        fn exchange(&mut self, tx: &[u8], rx: &mut [u8], _timeout: Duration) -> Result<usize> {
            self.exchanges += 1;
            if self.exchanges == 3 {
                return Err(Error::Timeout { what: "the test frame".into() });
            }
            rx[..tx.len()].copy_from_slice(tx);
            rx[tx.len() - 2] += 1;
            Ok(tx.len())
        }

        fn describe(&self) -> String {
            "loop".into()
        }
    }

    /// The blocks of a pcapng file as (type, body without the type and length fields).
    fn blocks(file: &[u8]) -> Vec<(u32, &[u8])> {
        let mut out = Vec::new();
        let mut at = 0;
        while at < file.len() {
            let kind = u32::from_le_bytes(file[at..at + 4].try_into().unwrap());
            let len = u32::from_le_bytes(file[at + 4..at + 8].try_into().unwrap()) as usize;
            assert_eq!(len % 4, 0, "block at {at} has unaligned length {len}");
            let trailer = u32::from_le_bytes(file[at + len - 4..at + len].try_into().unwrap()) as usize;
            assert_eq!(trailer, len, "block at {at}: trailing length differs");
            out.push((kind, &file[at + 8..at + len - 4]));
            at += len;
        }
        out
    }

    #[test]
    fn records_requests_and_replies_as_ethernet_frames() {
        let path = std::env::temp_dir().join(format!("akd_pcap_test_{}.pcapng", std::process::id()));
        let mut recorder = Recorder::new(Loop { exchanges: 0 }, &path).unwrap();
        let mut tx = [0u8; 64];
        let mut builder = FrameBuilder::new(&mut tx);
        builder.push_zeroed(Command::Brd, 0, 0, 0x0130, 2).unwrap();
        let n = builder.finish();
        let mut rx = [0u8; 64];
        for _ in 0..3 {
            let _ = recorder.exchange(&tx[..n], &mut rx, Duration::from_millis(1));
        }
        assert_eq!(recorder.write_errors(), 0);
        recorder.finish().unwrap();
        let file = std::fs::read(&path).unwrap();
        std::fs::remove_file(&path).unwrap();

        let blocks = blocks(&file);
        let kinds: Vec<u32> = blocks.iter().map(|b| b.0).collect();
        // Two exchanges with a reply, one without: five packets.
        assert_eq!(kinds, [0x0A0D_0D0A, 1, 6, 6, 6, 6, 6]);
        assert_eq!(&blocks[0].1[..4], &block::BYTE_ORDER_MAGIC.to_le_bytes());
        let idb = blocks[1].1;
        assert_eq!(u16::from_le_bytes([idb[0], idb[1]]), 1, "linktype Ethernet");
        // Options after linktype, reserved, snaplen: if_name "loop", then if_tsresol 9.
        assert_eq!(&idb[8..16], &[2, 0, 4, 0, b'l', b'o', b'o', b'p']);
        assert_eq!(&idb[16..21], &[9, 0, 1, 0, 9]);

        let mut last_time = 0;
        for (i, (_, epb)) in blocks[2..].iter().enumerate() {
            let time = (u64::from(u32::from_le_bytes(epb[4..8].try_into().unwrap())) << 32)
                | u64::from(u32::from_le_bytes(epb[8..12].try_into().unwrap()));
            assert!(time >= last_time, "packet {i} goes back in time");
            last_time = time;
            let captured = u32::from_le_bytes(epb[12..16].try_into().unwrap()) as usize;
            assert_eq!(captured, MIN_ETH_FRAME_LEN);
            let frame = &epb[20..20 + captured];
            let reply = i == 1 || i == 3;
            assert_eq!(frame[6], if reply { 0x03 } else { 0x01 }, "packet {i} source address");
            assert_eq!(&frame[12..14], &[0x88, 0xA4]);
            assert_eq!(&frame[14..14 + n - 2], &tx[..n - 2]);
            let wkc = u16::from_le_bytes([frame[14 + n - 2], frame[14 + n - 1]]);
            assert_eq!(wkc, u16::from(reply));
        }
    }

    #[test]
    fn an_unwritable_path_is_a_named_error() {
        let e = Recorder::new(Loop { exchanges: 0 }, "/nonexistent-dir/x.pcapng").err().unwrap().to_string();
        assert!(e.contains("creating capture file /nonexistent-dir/x.pcapng"), "{e}");
    }
}
