//! The virtual AKD's Ethernet over EtherCAT: its answer to Set IP Parameter and the IP stack
//! behind it (smoltcp), which answers ARP and ICMP echo at the address a master gave it.
//!
//! As a real AKD did under TwinCAT (issue 15): the Set IP Parameter response (result 0) comes
//! [`Timing::eoe_set_ip_ns`](crate::sim::Timing) after the request, and
//! [`Timing::eoe_announce_ns`](crate::sim::Timing) after that the drive announces itself with a
//! broadcast ARP request from its MAC for its own address. Every frame the stack sends goes in
//! fragments that fit the mailbox, its frame number counting up by one per frame. A fragment
//! that does not continue the frame being put together drops that frame, as a lost frame on an
//! Ethernet would be; it is counted, and nothing else changes.

use std::collections::VecDeque;
use std::net::Ipv4Addr;

use smoltcp::iface::{Config, Interface, SocketSet};
use smoltcp::phy::{Device, DeviceCapabilities, Medium};
use smoltcp::time::Instant;
use smoltcp::wire::{
    ArpOperation, ArpPacket, ArpRepr, EthernetAddress, EthernetFrame, EthernetProtocol, EthernetRepr, HardwareAddress,
    IpCidr,
};

use crate::ethercat::eoe::{
    write_fragment, write_response, EoeFrameType, EoeMessage, EoeResult, Fragmenter, IpParameters, Reassembler,
    MAX_FRAME_LEN,
};

/// Frames from the master the stack holds before it drops the next.
const MAX_RECEIVED: usize = 32;

/// The MAC a drive uses before a master gives it one (locally administered).
const DEFAULT_MAC: [u8; 6] = [0x02, 0x00, 0x00, 0x00, 0x00, 0x00];

/// The stack's side of the mailbox: frames the master sent, frames the stack sends.
#[derive(Default)]
struct Queues {
    received: VecDeque<Vec<u8>>,
    sent: VecDeque<Vec<u8>>,
}

struct Rx(Vec<u8>);
struct Tx<'a>(&'a mut VecDeque<Vec<u8>>);

impl smoltcp::phy::RxToken for Rx {
    fn consume<R, F: FnOnce(&[u8]) -> R>(self, f: F) -> R {
        f(&self.0)
    }
}

impl smoltcp::phy::TxToken for Tx<'_> {
    fn consume<R, F: FnOnce(&mut [u8]) -> R>(self, len: usize, f: F) -> R {
        let mut frame = vec![0u8; len];
        let result = f(&mut frame);
        self.0.push_back(frame);
        result
    }
}

impl Device for Queues {
    type RxToken<'a> = Rx;
    type TxToken<'a> = Tx<'a>;

    fn receive(&mut self, _: Instant) -> Option<(Rx, Tx<'_>)> {
        let frame = self.received.pop_front()?;
        Some((Rx(frame), Tx(&mut self.sent)))
    }

    fn transmit(&mut self, _: Instant) -> Option<Tx<'_>> {
        Some(Tx(&mut self.sent))
    }

    fn capabilities(&self) -> DeviceCapabilities {
        let mut caps = DeviceCapabilities::default();
        caps.medium = Medium::Ethernet;
        caps.max_transmission_unit = MAX_FRAME_LEN - 4;
        caps
    }
}

/// A reply to release at a time of the drive's firmware.
enum Due {
    /// The Set IP Parameter response, with the request's counter.
    SetIpResponse { at_ns: u64, counter: u8 },
    /// The broadcast ARP request announcing the drive's address.
    Announce { at_ns: u64 },
}

/// The EoE side of one virtual AKD.
pub struct EoeServer {
    parameters: IpParameters,
    interface: Option<Interface>,
    queues: Queues,
    sockets: SocketSet<'static>,
    reassembler: Reassembler,
    due: VecDeque<Due>,
    frame_number: u8,
    /// Fragments dropped because they did not continue a frame, and frames the stack had no
    /// room for.
    pub dropped_fragments: u64,
}

impl Default for EoeServer {
    fn default() -> Self {
        EoeServer {
            parameters: IpParameters::default(),
            interface: None,
            queues: Queues::default(),
            sockets: SocketSet::new(Vec::new()),
            reassembler: Reassembler::default(),
            due: VecDeque::new(),
            frame_number: 0,
            dropped_fragments: 0,
        }
    }
}

/// smoltcp's clock from the bus time.
fn instant(now_ns: u64) -> Instant {
    Instant::from_micros((now_ns / 1000) as i64)
}

impl EoeServer {
    /// The drive's MAC address.
    fn mac(&self) -> [u8; 6] {
        self.parameters.mac.unwrap_or(DEFAULT_MAC)
    }

    /// Handles one EoE message body from the master at bus time `now_ns`; a reply to send at
    /// once (an EoE response or nothing) goes into `reply` and its length is returned.
    pub fn handle(
        &mut self,
        body: &[u8],
        counter: u8,
        now_ns: u64,
        delays: (u64, u64),
        reply: &mut [u8],
    ) -> Result<usize, crate::error::EoeError> {
        match EoeMessage::decode(body)? {
            EoeMessage::Fragment { header, data, .. } => {
                match self.reassembler.push(&header, data) {
                    // A stack that cannot keep up drops what it cannot queue, as a NIC does.
                    Ok(Some(_)) if self.queues.received.len() >= MAX_RECEIVED => self.dropped_fragments += 1,
                    Ok(Some(frame)) => self.queues.received.push_back(frame.to_vec()),
                    Ok(None) => {}
                    Err(_) => self.dropped_fragments += 1,
                }
                Ok(0)
            }
            EoeMessage::SetIpRequest(request) => {
                self.set_parameters(request, now_ns);
                let (set_ip_ns, announce_ns) = delays;
                self.due.push_back(Due::SetIpResponse { at_ns: now_ns + set_ip_ns, counter });
                self.due.push_back(Due::Announce { at_ns: now_ns + set_ip_ns + announce_ns });
                Ok(0)
            }
            // A response from the master means nothing to the drive.
            EoeMessage::SetIpResponse(_) => Ok(0),
            EoeMessage::Other { frame_type, .. } => {
                let answer = match frame_type {
                    EoeFrameType::SetAddressFilterRequest => {
                        (EoeFrameType::SetAddressFilterResponse, EoeResult::NO_FILTER_SUPPORT)
                    }
                    EoeFrameType::GetIpRequest => (EoeFrameType::GetIpResponse, EoeResult::UNSUPPORTED_FRAME_TYPE),
                    EoeFrameType::GetAddressFilterRequest => {
                        (EoeFrameType::GetAddressFilterResponse, EoeResult::NO_FILTER_SUPPORT)
                    }
                    // Responses and time stamps are the slave's to send, not to answer.
                    _ => return Ok(0),
                };
                Ok(write_response(reply, counter, answer.0, answer.1))
            }
        }
    }

    /// Takes the fields a request carries; the stack follows a new MAC or address.
    fn set_parameters(&mut self, request: IpParameters, now_ns: u64) {
        let p = &mut self.parameters;
        p.mac = request.mac.or(p.mac);
        p.ip = request.ip.or(p.ip);
        p.subnet_mask = request.subnet_mask.or(p.subnet_mask);
        p.gateway = request.gateway.or(p.gateway);
        p.dns_server = request.dns_server.or(p.dns_server);
        p.dns_name = request.dns_name.or(p.dns_name.take());
        let mac = HardwareAddress::Ethernet(EthernetAddress(self.mac()));
        let interface =
            self.interface.get_or_insert_with(|| Interface::new(Config::new(mac), &mut self.queues, instant(now_ns)));
        interface.set_hardware_addr(mac);
        let prefix = self.parameters.subnet_mask.map_or(32, |m| u32::from(m).leading_ones() as u8);
        let ip = self.parameters.ip;
        interface.update_ip_addrs(|addresses| {
            addresses.clear();
            if let Some(ip) = ip {
                // At most one address, which always fits.
                let _ = addresses.push(IpCidr::new(ip.into(), prefix));
            }
        });
        if let Some(gateway) = self.parameters.gateway.filter(|g| !g.is_unspecified()) {
            let _ = interface.routes_mut().add_default_ipv4_route(gateway);
        }
    }

    /// The drive's work at bus time `now_ns`: releases what is due and runs the IP stack; each
    /// message to send (a whole mailbox message, fragments fitting `mailbox_size`) goes to
    /// `send`, given the drive's next counter by `counter`.
    pub fn poll(
        &mut self,
        now_ns: u64,
        mailbox_size: usize,
        mut counter: impl FnMut() -> u8,
        mut send: impl FnMut(Vec<u8>),
    ) {
        while let Some(due) = self.due.front() {
            match *due {
                Due::SetIpResponse { at_ns, counter: request_counter } if at_ns <= now_ns => {
                    let mut out = vec![0u8; mailbox_size];
                    let len =
                        write_response(&mut out, request_counter, EoeFrameType::SetIpResponse, EoeResult::SUCCESS);
                    out.truncate(len);
                    send(out);
                }
                Due::Announce { at_ns } if at_ns <= now_ns => {
                    if let Some(ip) = self.parameters.ip {
                        let frame = arp_request(self.mac(), ip, ip);
                        self.queues.sent.push_back(frame);
                    }
                }
                _ => break,
            }
            self.due.pop_front();
        }
        if let Some(interface) = self.interface.as_mut() {
            interface.poll(instant(now_ns), &mut self.queues, &mut self.sockets);
        }
        while let Some(frame) = self.queues.sent.pop_front() {
            let Ok(fragments) = Fragmenter::new(&frame, self.frame_number, mailbox_size) else { continue };
            for (header, data) in fragments {
                let mut out = vec![0u8; mailbox_size];
                let len = write_fragment(&mut out, counter(), &header, data);
                out.truncate(len);
                send(out);
            }
            self.frame_number = (self.frame_number + 1) & 0x0F;
        }
    }
}

/// A broadcast ARP request from `mac` at `sender` for `target`; for its own address
/// (`sender == target`) a gratuitous ARP, with which the drive announces itself.
pub fn arp_request(mac: [u8; 6], sender: Ipv4Addr, target: Ipv4Addr) -> Vec<u8> {
    let arp = ArpRepr::EthernetIpv4 {
        operation: ArpOperation::Request,
        source_hardware_addr: EthernetAddress(mac),
        source_protocol_addr: sender,
        target_hardware_addr: EthernetAddress([0; 6]),
        target_protocol_addr: target,
    };
    let ethernet = EthernetRepr {
        src_addr: EthernetAddress(mac),
        dst_addr: EthernetAddress::BROADCAST,
        ethertype: EthernetProtocol::Arp,
    };
    let mut frame = vec![0u8; ethernet.buffer_len() + arp.buffer_len()];
    let mut e = EthernetFrame::new_unchecked(&mut frame[..]);
    ethernet.emit(&mut e);
    arp.emit(&mut ArpPacket::new_unchecked(e.payload_mut()));
    frame
}

#[cfg(test)]
mod tests {
    use smoltcp::phy::ChecksumCapabilities;
    use smoltcp::wire::{Icmpv4Packet, Icmpv4Repr, IpProtocol, Ipv4Packet, Ipv4Repr};

    use super::*;
    use crate::ethercat::al::AlState;
    use crate::ethercat::eoe::{write_set_ip_request, FragmentHeader};
    use crate::ethercat::mailbox::{MailboxHeader, MailboxType};
    use crate::sim::mailbox_server::MailboxServer;
    use crate::sim::od::ObjectDictionary;

    const MAC: [u8; 6] = [0x02, 0x01, 0x05, 0x30, 0x03, 0xE9];
    const HOST_MAC: [u8; 6] = [0x02, 0xAA, 0, 0, 0, 1];
    const IP: Ipv4Addr = Ipv4Addr::new(192, 168, 0, 2);
    const HOST: Ipv4Addr = Ipv4Addr::new(192, 168, 0, 1);
    const MS: u64 = 1_000_000;

    struct EoeDrive {
        server: MailboxServer,
        od: ObjectDictionary,
        counter: u8,
        size: usize,
    }

    impl EoeDrive {
        fn new(size: usize) -> Self {
            let server = MailboxServer::with_eoe_delays(25 * MS, 18 * MS);
            EoeDrive { server, od: ObjectDictionary::akd(), counter: 0, size }
        }

        fn send(&mut self, message: &[u8], now_ns: u64) {
            self.counter = crate::ethercat::mailbox::next_counter(self.counter);
            let mut m = message.to_vec();
            m[5] = (m[5] & 0x0F) | (self.counter << 4);
            self.server.handle(&m, &mut self.od, AlState::Op, self.size, self.size, now_ns);
        }

        /// Every message the drive has for the master at `now_ns`.
        fn replies(&mut self, now_ns: u64) -> Vec<Vec<u8>> {
            self.server.poll(now_ns, self.size);
            std::iter::from_fn(|| self.server.next_reply().map(<[u8]>::to_vec)).collect()
        }

        fn set_ip(&mut self, now_ns: u64) {
            let parameters = IpParameters {
                mac: Some(MAC),
                ip: Some(IP),
                subnet_mask: Some(Ipv4Addr::new(255, 255, 255, 0)),
                ..IpParameters::default()
            };
            let mut out = [0u8; 128];
            let len = write_set_ip_request(&mut out, 0, &parameters).unwrap();
            self.send(&out[..len], now_ns);
        }

        /// Sends `frame` in fragments, as a master does.
        fn send_frame(&mut self, frame: &[u8], number: u8, now_ns: u64) {
            for (header, data) in Fragmenter::new(frame, number, self.size).unwrap() {
                let mut out = vec![0u8; self.size];
                let len = write_fragment(&mut out, 0, &header, data);
                self.send(&out[..len], now_ns);
            }
        }
    }

    /// The fragments among `messages`, decoded.
    fn fragments(messages: &[Vec<u8>]) -> Vec<(FragmentHeader, Vec<u8>)> {
        messages
            .iter()
            .filter_map(|m| {
                let h = MailboxHeader::decode(m).unwrap();
                assert_eq!(h.protocol(), Some(MailboxType::Eoe));
                match EoeMessage::decode(h.body(m)).unwrap() {
                    EoeMessage::Fragment { header, data, .. } => Some((header, data.to_vec())),
                    _ => None,
                }
            })
            .collect()
    }

    /// The frames the fragments put together.
    fn frames(messages: &[Vec<u8>]) -> Vec<Vec<u8>> {
        let mut r = Reassembler::default();
        fragments(messages).iter().filter_map(|(h, d)| r.push(h, d).unwrap().map(<[u8]>::to_vec)).collect()
    }

    fn ping(payload: usize) -> Vec<u8> {
        let data = vec![0x5A; payload];
        let icmp = Icmpv4Repr::EchoRequest { ident: 7, seq_no: 1, data: &data };
        let ip = Ipv4Repr {
            src_addr: HOST,
            dst_addr: IP,
            next_header: IpProtocol::Icmp,
            payload_len: icmp.buffer_len(),
            hop_limit: 64,
        };
        let ethernet = EthernetRepr {
            src_addr: EthernetAddress(HOST_MAC),
            dst_addr: EthernetAddress(MAC),
            ethertype: EthernetProtocol::Ipv4,
        };
        let mut frame = vec![0u8; ethernet.buffer_len() + ip.buffer_len() + icmp.buffer_len()];
        let mut e = EthernetFrame::new_unchecked(&mut frame[..]);
        ethernet.emit(&mut e);
        let mut p = Ipv4Packet::new_unchecked(e.payload_mut());
        ip.emit(&mut p, &ChecksumCapabilities::default());
        icmp.emit(&mut Icmpv4Packet::new_unchecked(p.payload_mut()), &ChecksumCapabilities::default());
        frame
    }

    #[test]
    fn set_ip_is_answered_then_the_drive_announces_itself() {
        let mut drive = EoeDrive::new(1024);
        drive.set_ip(0);
        assert!(drive.replies(24 * MS).is_empty(), "the response takes 25 ms");
        let replies = drive.replies(25 * MS);
        assert_eq!(replies.len(), 1);
        let h = MailboxHeader::decode(&replies[0]).unwrap();
        assert_eq!(h.counter, 1, "the response has the request's counter");
        assert_eq!(EoeMessage::decode(h.body(&replies[0])).unwrap(), EoeMessage::SetIpResponse(EoeResult::SUCCESS));
        assert!(drive.replies(42 * MS).is_empty(), "the announcement 18 ms after the response");
        let replies = drive.replies(43 * MS);
        let f = fragments(&replies);
        assert_eq!(f.len(), 1);
        assert!(f[0].0.last_fragment && f[0].0.fragment_number == 0);
        let e = EthernetFrame::new_checked(&f[0].1[..]).unwrap();
        assert_eq!((e.dst_addr(), e.src_addr()), (EthernetAddress::BROADCAST, EthernetAddress(MAC)));
        let arp = ArpRepr::parse(&ArpPacket::new_checked(e.payload()).unwrap()).unwrap();
        let ArpRepr::EthernetIpv4 { operation, source_protocol_addr, target_protocol_addr, .. } = arp else { panic!() };
        assert_eq!((operation, source_protocol_addr, target_protocol_addr), (ArpOperation::Request, IP, IP));
        // The same exchange each time the master runs its start-up; the frame numbers go on.
        drive.set_ip(50 * MS);
        let replies = drive.replies(100 * MS);
        assert_eq!(fragments(&replies)[0].0.frame_number, f[0].0.frame_number + 1);
    }

    #[test]
    fn answers_arp_and_ping_and_fragments_large_replies() {
        let mut drive = EoeDrive::new(1024);
        drive.set_ip(0);
        drive.replies(50 * MS);
        // Who has 192.168.0.2?
        let frame = arp_request(HOST_MAC, HOST, IP);
        drive.send_frame(&frame, 0, 51 * MS);
        let answer = frames(&drive.replies(52 * MS));
        assert_eq!(answer.len(), 1);
        let e = EthernetFrame::new_checked(&answer[0][..]).unwrap();
        let ArpRepr::EthernetIpv4 { operation, source_hardware_addr, .. } =
            ArpRepr::parse(&ArpPacket::new_checked(e.payload()).unwrap()).unwrap()
        else {
            panic!()
        };
        assert_eq!((operation, source_hardware_addr), (ArpOperation::Reply, EthernetAddress(MAC)));
        for (number, payload) in [(1, 56), (2, 1400)] {
            drive.send_frame(&ping(payload), number, 53 * MS);
            let replies = drive.replies(54 * MS);
            assert_eq!(fragments(&replies).len(), if payload > 1000 { 2 } else { 1 }, "{payload}-byte ping");
            let answer = frames(&replies);
            let e = EthernetFrame::new_checked(&answer[0][..]).unwrap();
            let ip = Ipv4Packet::new_checked(e.payload()).unwrap();
            assert_eq!((ip.src_addr(), ip.dst_addr()), (IP, HOST));
            let icmp = Icmpv4Packet::new_checked(ip.payload()).unwrap();
            let reply = Icmpv4Repr::parse(&icmp, &ChecksumCapabilities::default()).unwrap();
            assert_eq!(reply, Icmpv4Repr::EchoReply { ident: 7, seq_no: 1, data: &vec![0x5A; payload] });
        }
    }

    #[test]
    fn a_broken_frame_is_dropped_and_counted() {
        let mut drive = EoeDrive::new(64);
        drive.set_ip(0);
        drive.replies(50 * MS);
        let frame = ping(100);
        let parts: Vec<_> = Fragmenter::new(&frame, 3, 64).unwrap().collect();
        // Fragment 1 lost on the way: the others do not make a frame, and nothing answers.
        for (i, (header, data)) in parts.iter().enumerate().filter(|(i, _)| *i != 1) {
            let mut out = vec![0u8; 64];
            let len = write_fragment(&mut out, 0, header, data);
            drive.send(&out[..len], 51 * MS + i as u64);
        }
        assert!(drive.replies(52 * MS).is_empty());
        // Each fragment after the lost one is dropped: 142 bytes in 32, 32, 32 and 46.
        assert_eq!(parts.len(), 4);
        assert_eq!(drive.server.eoe().dropped_fragments, 2);
        // The next frame goes through.
        drive.send_frame(&ping(100), 4, 53 * MS);
        assert_eq!(frames(&drive.replies(54 * MS)).len(), 1);
    }

    #[test]
    fn malformed_headers_get_the_standards_answers() {
        let mut drive = EoeDrive::new(128);
        let answer = |drive: &mut EoeDrive, message: &[u8]| {
            drive.send(message, 0);
            drive.replies(0)
        };
        // EoE header cut short: mailbox error "data too short" (6).
        let r = answer(&mut drive, &[0x02, 0, 0, 0, 0, 0x02, 0x00, 0x00]);
        assert_eq!(r[0][5] & 0x0F, MailboxType::Error as u8);
        assert_eq!(&r[0][6..], &[0x01, 0x00, 0x06, 0x00]);
        // Frame type 12: "service not supported" (4).
        let r = answer(&mut drive, &[0x04, 0, 0, 0, 0, 0x02, 0x0C, 0x00, 0x00, 0x00]);
        assert_eq!(&r[0][6..], &[0x01, 0x00, 0x04, 0x00]);
        // Get Address Filter: its response with "no filter support".
        let r = answer(&mut drive, &[0x04, 0, 0, 0, 0, 0x02, 0x08, 0x00, 0x00, 0x00]);
        assert_eq!(&r[0][6..], &[0x09, 0x00, 0x01, 0x04]);
    }
}
