//! Ethernet frames a host on the drives' network sends (smoltcp's wire codecs), and the check
//! of the echo replies the drives send back.

use std::net::Ipv4Addr;

use smoltcp::phy::ChecksumCapabilities;
use smoltcp::wire::{
    EthernetAddress, EthernetFrame, EthernetProtocol, EthernetRepr, Icmpv4Packet, Icmpv4Repr, IpProtocol, Ipv4Packet,
    Ipv4Repr,
};

pub const HOST_MAC: [u8; 6] = [0x02, 0xAA, 0, 0, 0, 1];
pub const HOST: Ipv4Addr = Ipv4Addr::new(192, 168, 0, 1);

pub fn frame(ethertype: EthernetProtocol, dst: [u8; 6], payload_len: usize, fill: impl FnOnce(&mut [u8])) -> Vec<u8> {
    let ethernet = EthernetRepr { src_addr: EthernetAddress(HOST_MAC), dst_addr: EthernetAddress(dst), ethertype };
    let mut frame = vec![0u8; ethernet.buffer_len() + payload_len];
    let mut e = EthernetFrame::new_unchecked(&mut frame[..]);
    ethernet.emit(&mut e);
    fill(e.payload_mut());
    frame
}

pub fn ping(to: Ipv4Addr, mac: [u8; 6], data: &[u8], seq_no: u16) -> Vec<u8> {
    let icmp = Icmpv4Repr::EchoRequest { ident: 0x42, seq_no, data };
    let ip = Ipv4Repr {
        src_addr: HOST,
        dst_addr: to,
        next_header: IpProtocol::Icmp,
        payload_len: icmp.buffer_len(),
        hop_limit: 64,
    };
    frame(EthernetProtocol::Ipv4, mac, ip.buffer_len() + icmp.buffer_len(), |payload| {
        let mut p = Ipv4Packet::new_unchecked(payload);
        ip.emit(&mut p, &ChecksumCapabilities::default());
        icmp.emit(&mut Icmpv4Packet::new_unchecked(p.payload_mut()), &ChecksumCapabilities::default());
    })
}

/// The host's ARP request for `ip`, from which the drive also learns the host's MAC.
pub fn who_has(ip: Ipv4Addr) -> Vec<u8> {
    akd_native::sim::eoe_server::arp_request(HOST_MAC, HOST, ip)
}

/// The sequence number and data of `frame` when it is an echo reply from `from` to the host;
/// `None` for any other frame.
pub fn echo_reply(frame: &[u8], from: Ipv4Addr) -> Option<(u16, Vec<u8>)> {
    let e = EthernetFrame::new_checked(frame).ok()?;
    let ip = Ipv4Packet::new_checked(e.payload()).ok()?;
    let icmp = Icmpv4Packet::new_checked(ip.payload()).ok()?;
    match Icmpv4Repr::parse(&icmp, &ChecksumCapabilities::default()).ok()? {
        Icmpv4Repr::EchoReply { ident: 0x42, seq_no, data } if (ip.src_addr(), ip.dst_addr()) == (from, HOST) => {
            Some((seq_no, data.to_vec()))
        }
        _ => None,
    }
}

pub fn check_echo_reply(frame: &[u8], from: Ipv4Addr, data: &[u8], seq_no: u16) {
    assert_eq!(echo_reply(frame, from), Some((seq_no, data.to_vec())), "the echo reply of ping {seq_no}");
}
