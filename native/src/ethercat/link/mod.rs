//! Links: how EtherCAT frames reach the slaves and come back.
//!
//! Every link carries the EtherCAT payload (frame header plus datagrams) and hides what wraps it:
//! nothing for the in-process virtual bus (which the simulator provides), a UDP datagram for EtherCAT-over-UDP, an Ethernet II
//! header for a raw interface. [`CapturingLink`](pcap::CapturingLink) wraps any link and writes what it
//! sends and receives to a pcapng file.

use std::time::{Duration, Instant};

use crate::error::{Error, Result};

pub use returns::Returns;

pub mod pcap;
pub mod privilege;
pub mod raw;
pub mod returns;
pub mod socket;
pub mod udp;

/// A path to a chain of slaves. Frames go out with [`send`](Link::send) and come back, in the
/// order they were sent, through [`receive`](Link::receive); which frame a return belongs to is
/// the caller's to tell ([`is_reply_to`]), so that a master may send a frame and take its return
/// later, after other frames have come and gone ([`exchange_keeping_others`]).
pub trait Link: Send {
    /// Sends the EtherCAT payload `tx` (frame header and datagrams).
    fn send(&mut self, tx: &[u8]) -> Result<()>;

    /// Waits until `deadline` for the next frame to come back and writes its EtherCAT payload
    /// to `rx`; its length, or `None` when none came by then. What is no return at all (another
    /// master's frame, one no slave forwarded) is skipped; an earlier frame's late return is
    /// given like any other.
    fn receive(&mut self, rx: &mut [u8], deadline: Instant) -> Result<Option<usize>>;

    /// Human-readable description, e.g. `udp://127.0.0.1:34980` or `eth0`.
    fn describe(&self) -> String;

    /// What a frame that did not come back was awaited as, in the time-out's text: a fixed
    /// text, as the cycle thread meets it and must not allocate.
    fn awaited(&self) -> &'static str {
        "a frame to come back"
    }

    /// Sends `tx` and waits up to `timeout` for its return, written to `rx`; its length. The
    /// returns of other frames (an earlier frame's late return) are dropped. A frame that does
    /// not come back gives [`Error::Timeout`]. Built on `send` and `receive` for every link.
    fn exchange(&mut self, tx: &[u8], rx: &mut [u8], timeout: Duration) -> Result<usize> {
        exchange_keeping_others(self, tx, rx, timeout, |_| {})
    }
}

impl<L: Link + ?Sized> Link for Box<L> {
    fn send(&mut self, tx: &[u8]) -> Result<()> {
        (**self).send(tx)
    }

    fn receive(&mut self, rx: &mut [u8], deadline: Instant) -> Result<Option<usize>> {
        (**self).receive(rx, deadline)
    }

    fn describe(&self) -> String {
        (**self).describe()
    }

    fn awaited(&self) -> &'static str {
        (**self).awaited()
    }
}

/// [`Link::exchange`], handing the returns of other frames to `others` instead of dropping
/// them: a master waiting for a mailbox frame while its cyclic frame is on its way back keeps
/// the cyclic frame's return there.
pub fn exchange_keeping_others<L: Link + ?Sized>(
    link: &mut L,
    tx: &[u8],
    rx: &mut [u8],
    timeout: Duration,
    others: impl FnMut(&[u8]),
) -> Result<usize> {
    link.send(tx)?;
    receive_reply(link, tx, rx, Instant::now() + timeout, others)?
        .ok_or_else(|| Error::Timeout { what: link.awaited().into() })
}

/// Waits until `deadline` for the return of the frame `tx` sent on `link`, written to `rx`; its
/// length, or `None` when it did not come by then. The returns of other frames met on the way
/// (an earlier frame's late return) are handed to `others`.
pub fn receive_reply<L: Link + ?Sized>(
    link: &mut L,
    tx: &[u8],
    rx: &mut [u8],
    deadline: Instant,
    mut others: impl FnMut(&[u8]),
) -> Result<Option<usize>> {
    loop {
        match link.receive(rx, deadline)? {
            Some(n) if is_reply_to(tx, &rx[..n]) => return Ok(Some(n)),
            Some(n) => others(&rx[..n]),
            None => return Ok(None),
        }
    }
}

/// Whether the slaves count a datagram's ADP up as it passes (auto-increment and broadcast).
fn counts_adp(command: crate::ethercat::frame::Command) -> bool {
    use crate::ethercat::frame::Addressing;
    matches!(command.addressing(), Addressing::AutoIncrement | Addressing::Broadcast)
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
/// the same command, index, length and address (ADP where the slaves do not count it up, as
/// they do in auto-increment and broadcast datagrams). Slaves change those ADPs, data, IRQ
/// and working counters, never the rest, so a stale reply of an earlier frame (another index)
/// or foreign traffic is told apart from the awaited one — and so is the return of a frame
/// 256 frames older (the index wrapped) that a stalled line brings back late, such as another
/// slave's mailbox read.
pub fn is_reply_to(tx: &[u8], rx: &[u8]) -> bool {
    let (Ok(sent), Ok(back)) = (crate::ethercat::frame::parse(tx), crate::ethercat::frame::parse(rx)) else {
        return false;
    };
    let mut back = back;
    for request in sent {
        match (request, back.next()) {
            (Ok(a), Some(Ok(b)))
                if a.header.command == b.header.command
                    && a.header.index == b.header.index
                    && a.header.len == b.header.len
                    && a.header.ado == b.header.ado
                    && (a.header.adp == b.header.adp || counts_adp(a.header.command)) => {}
            _ => return false,
        }
    }
    back.next().is_none()
}

#[cfg(test)]
mod tests {
    use super::is_reply_to;
    use crate::ethercat::frame::{Command, FrameBuilder};

    fn frame(command: Command, index: u8, adp: u16, ado: u16) -> Vec<u8> {
        let mut buf = [0u8; 64];
        let mut b = FrameBuilder::new(&mut buf);
        b.push(command, index, adp, ado, &[0, 0]).unwrap();
        let n = b.finish();
        buf[..n].to_vec()
    }

    #[test]
    fn a_return_with_the_same_index_from_another_address_is_not_the_reply() {
        // 256 frames later the index is the same again: a read of another slave's mailbox, or of
        // another register, that a stalled line brings back that late is not this read's return.
        let read = frame(Command::Fprd, 9, 0x1008, 0x1C00);
        assert!(is_reply_to(&read, &frame(Command::Fprd, 9, 0x1008, 0x1C00)));
        assert!(!is_reply_to(&read, &frame(Command::Fprd, 9, 0x1010, 0x1C00)));
        assert!(!is_reply_to(&read, &frame(Command::Fprd, 9, 0x1008, 0x080D)));
        // Auto-increment and broadcast ADPs are counted up by each slave on the way.
        assert!(is_reply_to(&frame(Command::Aprd, 9, 0, 0x0010), &frame(Command::Aprd, 9, 3, 0x0010)));
        assert!(is_reply_to(&frame(Command::Brd, 9, 0, 0x0130), &frame(Command::Brd, 9, 64, 0x0130)));
    }
}
