//! Links: how EtherCAT frames reach the slaves and come back.
//!
//! Every link carries the EtherCAT payload (frame header plus datagrams) and hides what wraps it:
//! nothing for the in-process virtual bus (which the simulator provides), a UDP datagram for EtherCAT-over-UDP, an Ethernet II
//! header for a raw interface. [`Recorder`](pcap::Recorder) wraps any link and writes what it
//! sends and receives to a pcapng file.

use std::time::Duration;

use crate::error::Result;

pub use spec::LinkSpec;

pub mod pcap;
pub mod privilege;
pub mod raw;
pub mod spec;
pub mod udp;

/// A path to a chain of slaves.
pub trait Link: Send {
    /// Sends the EtherCAT payload `tx` and waits up to `timeout` for the frame to come back.
    /// The returned frame is written to `rx` and its length returned. Stale or foreign frames
    /// (an earlier frame's late return, another master's traffic) are dropped, not returned.
    /// A frame that does not come back gives [`Error::Timeout`](crate::error::Error::Timeout).
    fn exchange(&mut self, tx: &[u8], rx: &mut [u8], timeout: Duration) -> Result<usize>;

    /// Human-readable description, e.g. `udp://127.0.0.1:34980` or `eth0`.
    fn describe(&self) -> String;
}

impl<L: Link + ?Sized> Link for Box<L> {
    fn exchange(&mut self, tx: &[u8], rx: &mut [u8], timeout: Duration) -> Result<usize> {
        (**self).exchange(tx, rx, timeout)
    }

    fn describe(&self) -> String {
        (**self).describe()
    }
}

/// Copies a returned frame into the caller's buffer and gives its length; a buffer too small
/// for it is an error, not a truncated frame.
pub fn copy_reply(reply: &[u8], rx: &mut [u8]) -> Result<usize> {
    let room = rx.len();
    rx.get_mut(..reply.len())
        .ok_or(crate::error::FrameError::TooLarge { len: reply.len(), room })?
        .copy_from_slice(reply);
    Ok(reply.len())
}

/// Whether `rx` is the return of the frame `tx`: same frame header and, datagram by datagram,
/// the same command, index and length. Slaves change addresses (auto-increment), data, IRQ
/// and working counters, never these, so a stale reply of an earlier frame (another index)
/// or foreign traffic is told apart from the awaited one.
pub fn is_reply_to(tx: &[u8], rx: &[u8]) -> bool {
    let (Ok(sent), Ok(back)) = (crate::frame::parse(tx), crate::frame::parse(rx)) else {
        return false;
    };
    let mut back = back;
    for request in sent {
        match (request, back.next()) {
            (Ok(a), Some(Ok(b)))
                if a.header.command == b.header.command
                    && a.header.index == b.header.index
                    && a.header.len == b.header.len => {}
            _ => return false,
        }
    }
    back.next().is_none()
}
