//! EoE client: a slave's IP parameters (Set IP Parameter) and Ethernet frames to and from its
//! IP stack, cut into fragments that fit its mailbox and put back together from the slave's.
//!
//! Fragments arrive between the slave's other replies, so the mailbox client hands each one
//! to the slave's [`EoePort`] as it reads it; whole frames wait there until taken.

use std::collections::VecDeque;
use std::time::{Duration, Instant};

use crate::error::{EoeError, Error, Result};
use crate::ethercat::eoe::{self, EoeMessage, EoeResult, Fragmenter, IpParameters, Reassembler};
use crate::ethercat::mailbox::MailboxType;
use crate::ethercat::master::Master;

/// Frames received from a slave and not yet taken, at most; older ones are dropped (counted).
pub const MAX_WAITING_FRAMES: usize = 64;

/// One slave's end of EoE: the frame being put together, whole frames waiting, the number of
/// the next frame sent.
#[derive(Clone, Debug, Default)]
pub struct EoePort {
    reassembler: Reassembler,
    frames: VecDeque<Vec<u8>>,
    frame_number: u8,
    /// Fragments that did not continue a frame, and frames dropped unread.
    pub dropped: u64,
}

impl EoePort {
    /// Takes one EoE message body the slave sent; `false` when it is no fragment (a response
    /// for whoever awaits it).
    pub(super) fn take(&mut self, body: &[u8]) -> bool {
        let (header, data) = match EoeMessage::decode(body) {
            Ok(EoeMessage::Fragment { header, data, .. }) => (header, data),
            Ok(_) => return false,
            // Nobody asked for it: dropped as a broken fragment would be.
            Err(_) => {
                self.dropped += 1;
                return true;
            }
        };
        match self.reassembler.push(&header, data) {
            Ok(Some(frame)) => {
                if self.frames.len() == MAX_WAITING_FRAMES {
                    self.frames.pop_front();
                    self.dropped += 1;
                }
                self.frames.push_back(frame.to_vec());
            }
            Ok(None) => {}
            Err(_) => self.dropped += 1,
        }
        true
    }
}

/// The MAC TwinCAT gave a real AKD at station address 0x03E9 (issue 15): 02:01:05:30 then
/// the station address, locally administered. A master that gives none uses the same rule.
pub fn default_mac(station_address: u16) -> [u8; 6] {
    let [high, low] = station_address.to_be_bytes();
    [0x02, 0x01, 0x05, 0x30, high, low]
}

impl Master {
    fn check_eoe(&self, position: u16) -> Result<usize> {
        match &self.slave(position)?.mailbox {
            Some(mb) if mb.protocols & MailboxType::Eoe.sii_protocol_bit() != 0 => Ok(mb.out_len as usize),
            _ => Err(EoeError::NotSupported { slave: position }.into()),
        }
    }

    /// Gives the slave at `position` its IP parameters and waits for its response.
    pub(super) fn eoe_set_ip(&mut self, position: u16, parameters: &IpParameters) -> Result<()> {
        let mut message = vec![0u8; self.check_eoe(position)?.max(eoe::BODY_OFFSET + eoe::SET_IP_LEN)];
        let len = eoe::write_set_ip_request(&mut message, 0, parameters)?;
        self.mailbox_send(position, &mut message[..len], self.mailbox_timeout)?;
        // The real drive answers after about 25 ms; CoE replies still in SM1 are not this.
        let deadline = Instant::now() + self.mailbox_timeout;
        loop {
            let left = deadline.saturating_duration_since(Instant::now());
            let reply = self.mailbox_receive(position, left)?;
            let Some(body) = eoe_body(&reply) else { continue };
            if let Ok(EoeMessage::SetIpResponse(result)) = EoeMessage::decode(body) {
                if result == EoeResult::SUCCESS {
                    return Ok(());
                }
                return Err(EoeError::Refused { slave: position, result: result.0, result_name: result.name() }.into());
            }
        }
    }

    /// Sends one Ethernet frame to the slave at `position`'s IP stack.
    pub(super) fn eoe_send(&mut self, position: u16, frame: &[u8]) -> Result<()> {
        let out_len = self.check_eoe(position)?;
        let port = &mut self.slave_entry_mut(position)?.eoe;
        let number = port.frame_number;
        port.frame_number = (number + 1) & 0x0F;
        let mut message = vec![0u8; out_len];
        for (header, data) in Fragmenter::new(frame, number, out_len)? {
            let len = eoe::write_fragment(&mut message, 0, &header, data);
            self.mailbox_send(position, &mut message[..len], self.mailbox_timeout)?;
        }
        Ok(())
    }

    /// The next Ethernet frame the slave at `position` sent, waiting up to `timeout` for one.
    pub(super) fn eoe_receive(&mut self, position: u16, timeout: Duration) -> Result<Option<Vec<u8>>> {
        self.check_eoe(position)?;
        let deadline = Instant::now() + timeout;
        loop {
            if let Some(frame) = self.slave_entry_mut(position)?.eoe.frames.pop_front() {
                return Ok(Some(frame));
            }
            // A reply that is no fragment has nobody waiting for it here.
            match self.mailbox_receive(position, Duration::ZERO) {
                Ok(_) | Err(Error::Timeout { .. }) => {}
                Err(e) => return Err(e),
            }
            if Instant::now() >= deadline {
                return Ok(None);
            }
            std::thread::sleep(Duration::from_micros(200));
        }
    }
}

/// The EoE body of a whole mailbox message, `None` for another protocol's.
fn eoe_body(message: &[u8]) -> Option<&[u8]> {
    let header = crate::ethercat::mailbox::MailboxHeader::decode(message).ok()?;
    (header.protocol() == Some(MailboxType::Eoe)).then(|| header.body(message))
}
