//! Recording a link's traffic to a pcapng file that Wireshark and tshark decode.
//!
//! [`CapturingLink`] wraps any [`Link`]. Links carry bare EtherCAT payloads, so each frame is written
//! as the Ethernet frame it is (or would be) on the wire: broadcast, from
//! [`super::raw::MASTER_MAC`] for requests and from the same address with
//! [`super::raw::RETURNED_MAC_BIT`] set for replies, as a real ESC marks the
//! frames it returns, EtherType 0x88A4, padded to the Ethernet minimum. Timestamps are wall-clock
//! nanoseconds (pcapng `if_tsresol` 9) taken just before the request leaves and just after the
//! reply is back.
//!
//! The exchange itself only appends the two blocks to a memory chunk; full chunks go to a writer
//! thread and come back empty, so recording costs no system call and, once a few chunks exist,
//! no allocation in the cyclic path. If the writer falls so far behind that no chunk can be
//! handed over, the frames of that chunk are counted as lost, never waited for.
//! [`CapturingLink::finish`] (or dropping the capture) writes the rest and reports lost frames and
//! write errors.

use std::fs::File;
use std::io::Write;
use std::mem;
use std::path::{Path, PathBuf};
use std::sync::mpsc::{self, Receiver, SyncSender, TrySendError};
use std::thread::JoinHandle;
use std::time::{Instant, SystemTime, UNIX_EPOCH};

use super::raw::{MASTER_MAC, RETURNED_MAC_BIT};
use super::Link;
use crate::error::{Error, Result};
use crate::ethercat::frame::{write_ethernet_header, ETH_HEADER_LEN, MIN_ETH_FRAME_LEN};

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

/// A chunk is handed to the writer once it holds this many bytes (about 600 minimum frames).
const CHUNK: usize = 64 * 1024;
/// Chunks that may wait for the writer: 1 MiB of frames.
const QUEUED_CHUNKS: usize = 16;

/// A chunk of blocks and the number of frames in it.
type Chunk = (Vec<u8>, u64);

/// A link whose every frame sent and received is written to a pcapng file.
pub struct CapturingLink<L: Link> {
    inner: L,
    path: PathBuf,
    /// Blocks not yet handed to the writer.
    chunk: Chunk,
    /// `None` once finished.
    to_writer: Option<SyncSender<Chunk>>,
    /// Chunks the writer has written, to be filled again.
    spare: Receiver<Vec<u8>>,
    writer: Option<JoinHandle<std::io::Result<()>>>,
    lost_frames: u64,
}

/// Nanoseconds since the Unix epoch (0 if the clock is before it).
fn now_ns() -> u64 {
    SystemTime::now().duration_since(UNIX_EPOCH).map_or(0, |d| d.as_nanos() as u64)
}

/// Appends a pcapng option, padded to 4 bytes.
fn push_option(out: &mut Vec<u8>, code: u16, value: &[u8]) {
    out.extend_from_slice(&code.to_le_bytes());
    out.extend_from_slice(&(value.len() as u16).to_le_bytes());
    out.extend_from_slice(value);
    out.resize(out.len().next_multiple_of(4), 0);
}

/// Starts a block of `kind` at the end of `out` and returns where it starts, for [`end_block`].
fn begin_block(out: &mut Vec<u8>, kind: u32) -> usize {
    let start = out.len();
    out.extend_from_slice(&kind.to_le_bytes());
    out.extend_from_slice(&[0; 4]);
    start
}

/// Pads the block that starts at `start`, appends its trailing length and fills in the leading one.
fn end_block(out: &mut Vec<u8>, start: usize) {
    out.resize(out.len().next_multiple_of(4), 0);
    let total = (out.len() + 4 - start) as u32;
    out.extend_from_slice(&total.to_le_bytes());
    out[start + 4..start + 8].copy_from_slice(&total.to_le_bytes());
}

/// Appends one EtherCAT payload as an Ethernet frame at `time_ns`; a reply's source address has
/// [`RETURNED_MAC_BIT`] set.
fn push_frame(out: &mut Vec<u8>, payload: &[u8], time_ns: u64, reply: bool) {
    let start = begin_block(out, block::ENHANCED_PACKET);
    // Interface 0, timestamp high then low 32 bits.
    out.extend_from_slice(&0u32.to_le_bytes());
    out.extend_from_slice(&((time_ns >> 32) as u32).to_le_bytes());
    out.extend_from_slice(&(time_ns as u32).to_le_bytes());
    let frame_len = (ETH_HEADER_LEN + payload.len()).max(MIN_ETH_FRAME_LEN);
    out.extend_from_slice(&(frame_len as u32).to_le_bytes());
    out.extend_from_slice(&(frame_len as u32).to_le_bytes());
    let frame_start = out.len();
    let mut source = MASTER_MAC;
    if reply {
        source[0] |= RETURNED_MAC_BIT;
    }
    out.resize(frame_start + ETH_HEADER_LEN, 0);
    write_ethernet_header(&mut out[frame_start..], source);
    out.extend_from_slice(payload);
    out.resize(frame_start + frame_len, 0);
    end_block(out, start);
}

/// The section header and interface description (named `interface`) that open the file.
fn file_header(interface: &str) -> Vec<u8> {
    let mut out = Vec::new();
    let start = begin_block(&mut out, block::SECTION_HEADER);
    out.extend_from_slice(&block::BYTE_ORDER_MAGIC.to_le_bytes());
    out.extend_from_slice(&1u16.to_le_bytes());
    out.extend_from_slice(&0u16.to_le_bytes());
    // Section length unknown.
    out.extend_from_slice(&(-1i64).to_le_bytes());
    push_option(&mut out, block::OPT_SHB_USERAPPL, b"akd_ros");
    push_option(&mut out, block::OPT_END, &[]);
    end_block(&mut out, start);

    let start = begin_block(&mut out, block::INTERFACE_DESCRIPTION);
    out.extend_from_slice(&block::LINKTYPE_ETHERNET.to_le_bytes());
    out.extend_from_slice(&0u16.to_le_bytes());
    // No snapshot limit.
    out.extend_from_slice(&0u32.to_le_bytes());
    push_option(&mut out, block::OPT_IF_NAME, interface.as_bytes());
    // Timestamps in units of 10^-9 s.
    push_option(&mut out, block::OPT_IF_TSRESOL, &[9]);
    push_option(&mut out, block::OPT_END, &[]);
    end_block(&mut out, start);
    out
}

/// The writer thread: writes chunks in order and returns them empty. After a write error it
/// keeps returning chunks (so the capture never waits) and reports the first error at the end.
fn write_chunks(mut file: File, chunks: Receiver<Chunk>, spare: SyncSender<Vec<u8>>) -> std::io::Result<()> {
    let mut result = Ok(());
    for (mut chunk, _) in chunks {
        if result.is_ok() {
            result = file.write_all(&chunk);
        }
        chunk.clear();
        // The capture may be gone or have spares enough; either way the chunk is not needed.
        let _ = spare.try_send(chunk);
    }
    result.and_then(|()| file.sync_data())
}

impl<L: Link> CapturingLink<L> {
    /// Wraps `inner`, creating (or truncating) the pcapng file at `path`, writing its section
    /// header and interface description (named after `inner`) and starting the writer thread.
    pub fn new(inner: L, path: impl AsRef<Path>) -> Result<Self> {
        let path = path.as_ref().to_path_buf();
        let context = |what: &str| format!("{what} capture file {}", path.display());
        let mut file = File::create(&path).map_err(|e| Error::io(context("creating"), e))?;
        file.write_all(&file_header(&inner.describe())).map_err(|e| Error::io(context("writing"), e))?;
        let (to_writer, chunks) = mpsc::sync_channel(QUEUED_CHUNKS);
        let (spare_tx, spare) = mpsc::sync_channel(QUEUED_CHUNKS);
        let writer = std::thread::Builder::new()
            .name("pcap-writer".into())
            .spawn(move || write_chunks(file, chunks, spare_tx))
            .map_err(|e| Error::io(context("starting the writer thread of"), e))?;
        Ok(CapturingLink {
            inner,
            path,
            chunk: (Vec::with_capacity(CHUNK + 4096), 0),
            to_writer: Some(to_writer),
            spare,
            writer: Some(writer),
            lost_frames: 0,
        })
    }

    /// Hands a full chunk to the writer and continues in a spare one.
    fn hand_over(&mut self) {
        let Some(to_writer) = &self.to_writer else { return };
        let empty = self.spare.try_recv().unwrap_or_else(|_| Vec::with_capacity(CHUNK + 4096));
        let full = (mem::replace(&mut self.chunk.0, empty), mem::take(&mut self.chunk.1));
        match to_writer.try_send(full) {
            Ok(()) => {}
            Err(TrySendError::Full((mut chunk, frames)) | TrySendError::Disconnected((mut chunk, frames))) => {
                self.lost_frames += frames;
                chunk.clear();
                self.chunk.0 = chunk;
            }
        }
    }

    /// Writes what is left and stops the writer; an error names the file and says how many
    /// frames were lost. Later exchanges are no longer recorded.
    pub fn finish(&mut self) -> Result<()> {
        let (Some(to_writer), Some(writer)) = (self.to_writer.take(), self.writer.take()) else { return Ok(()) };
        let last = mem::take(&mut self.chunk);
        let handed = to_writer.send(last).is_ok();
        drop(to_writer);
        let written = writer.join().unwrap_or_else(|_| Err(std::io::Error::other("the writer thread panicked")));
        let context = format!("writing capture file {}", self.path.display());
        match (written, handed, self.lost_frames) {
            (Err(e), _, _) => Err(Error::io(context, e)),
            (Ok(()), false, _) => Err(Error::io(context, std::io::Error::other("the writer thread ended early"))),
            (Ok(()), true, 0) => Ok(()),
            (Ok(()), true, lost) => {
                Err(Error::io(context, std::io::Error::other(format!("{lost} frames lost: the writer fell behind"))))
            }
        }
    }
}

impl<L: Link> CapturingLink<L> {
    /// Adds one frame, sent or returned at `time_ns`, to the chunk under way.
    fn record(&mut self, frame: &[u8], time_ns: u64, returned: bool) {
        if self.to_writer.is_none() {
            return;
        }
        push_frame(&mut self.chunk.0, frame, time_ns, returned);
        self.chunk.1 += 1;
        if self.chunk.0.len() >= CHUNK {
            self.hand_over();
        }
    }
}

impl<L: Link> Link for CapturingLink<L> {
    fn send(&mut self, tx: &[u8]) -> Result<()> {
        let sent_ns = now_ns();
        self.inner.send(tx)?;
        self.record(tx, sent_ns, false);
        Ok(())
    }

    fn receive(&mut self, rx: &mut [u8], deadline: Instant) -> Result<Option<usize>> {
        let got = self.inner.receive(rx, deadline)?;
        if let Some(n) = got {
            self.record(&rx[..n], now_ns(), true);
        }
        Ok(got)
    }

    fn describe(&self) -> String {
        format!("{} recorded to {}", self.inner.describe(), self.path.display())
    }

    fn awaited(&self) -> &'static str {
        self.inner.awaited()
    }
}

impl<L: Link> Drop for CapturingLink<L> {
    fn drop(&mut self) {
        // Owners that hold the capture as a plain `Link` cannot call `finish`; the file is
        // completed here all the same, and a failure has no caller left to tell.
        let _ = self.finish();
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ethercat::frame::{Command, FrameBuilder};
    use std::time::Duration;

    /// A link where every datagram is answered with its working counter incremented, and the
    /// third frame is lost.
    struct Loop {
        sent: u32,
        returns: crate::ethercat::link::Returns,
    }

    impl Link for Loop {
        fn send(&mut self, tx: &[u8]) -> Result<()> {
            self.sent += 1;
            let lost = self.sent == 3;
            self.returns.serve(tx, |frame| {
                let wkc = frame.len() - 2;
                frame[wkc] += 1;
                Ok(!lost)
            })
        }

        fn receive(&mut self, rx: &mut [u8], _deadline: Instant) -> Result<Option<usize>> {
            self.returns.take(rx)
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

    /// Records `exchanges` exchanges of one datagram through a [`Loop`], ends the capture
    /// with `end` and returns the request and the file.
    fn record(
        name: &str,
        command: Command,
        data_len: usize,
        exchanges: usize,
        end: impl FnOnce(CapturingLink<Loop>),
    ) -> (Vec<u8>, Vec<u8>) {
        let path = std::env::temp_dir().join(format!("akd_pcap_{name}_{}.pcapng", std::process::id()));
        let mut capture = CapturingLink::new(Loop { sent: 0, returns: Default::default() }, &path).unwrap();
        let mut tx = [0u8; 64];
        let mut builder = FrameBuilder::new(&mut tx);
        builder.push_zeroed(command, 0, 0, 0x0130, data_len).unwrap();
        let n = builder.finish();
        let mut rx = [0u8; 64];
        for _ in 0..exchanges {
            let _ = capture.exchange(&tx[..n], &mut rx, Duration::from_millis(1));
        }
        end(capture);
        let file = std::fs::read(&path).unwrap();
        std::fs::remove_file(&path).unwrap();
        (tx[..n].to_vec(), file)
    }

    #[test]
    fn records_requests_and_replies_as_ethernet_frames() {
        // finish() refuses when a frame was lost.
        let (tx, file) = record("frames", Command::Brd, 2, 3, |mut capture| capture.finish().unwrap());
        let n = tx.len();

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
    fn frames_over_many_chunks_are_all_written_when_the_capture_is_dropped() {
        // 4000 exchanges (one times out): 7999 blocks of 96 bytes, about 12 chunks.
        let (_, file) = record("chunks", Command::Lrw, 34, 4000, drop);
        let blocks = blocks(&file);
        assert_eq!(blocks.len(), 2 + 7999);
        assert!(blocks[2..].iter().all(|b| b.0 == block::ENHANCED_PACKET));
    }

    #[test]
    fn an_unwritable_path_is_a_named_error() {
        let e = CapturingLink::new(Loop { sent: 0, returns: Default::default() }, "/nonexistent-dir/x.pcapng")
            .err()
            .unwrap()
            .to_string();
        assert!(e.contains("creating capture file /nonexistent-dir/x.pcapng"), "{e}");
    }
}
