//! EoE and FoE between the master and the in-process virtual AKD: the IP parameters set as
//! TwinCAT set a real drive's, the drive's announcement, ARP and ping through its IP stack
//! (large ones fragmented both ways, also through the smallest mailbox), and files written,
//! read back and refused by name.

use std::net::{Ipv4Addr, UdpSocket};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use akd_native::cycle::{Config, CycleThread};
use akd_native::error::{Error, FoeError};
use akd_native::ethercat::al::AlState;
use akd_native::ethercat::eoe::IpParameters;
use akd_native::ethercat::frame::{Command, FrameBuilder};
use akd_native::ethercat::link::udp::Udp;
use akd_native::ethercat::link_spec::MissedFrames;
use akd_native::ethercat::master::eoe::default_mac;
use akd_native::ethercat::master::Master;
use akd_native::sim::in_process::InProcess;
use akd_native::sim::{server, Timing, VirtualBus};
use smoltcp::wire::{ArpOperation, ArpPacket, ArpRepr, EthernetAddress, EthernetFrame, EthernetProtocol};

#[path = "support/ethernet.rs"]
mod ethernet;
use ethernet::{check_echo_reply, ping, who_has, HOST};

const STEP: Duration = Duration::from_secs(5);
fn master(bus: VirtualBus) -> Master {
    let count = bus.len();
    let mut m = Master::new(Box::new(InProcess::with_bus(bus)), Duration::from_millis(100));
    assert_eq!(m.scan().unwrap(), count);
    m.request_state(AlState::PreOp, STEP).unwrap();
    m
}

fn drive_ip(position: u16) -> Ipv4Addr {
    Ipv4Addr::new(192, 168, 0, 10 + position as u8)
}

/// Sets the drive's parameters as TwinCAT did, all six fields, or without the DNS name (a
/// 64-byte mailbox does not hold it).
fn set_ip(m: &mut Master, position: u16, with_name: bool) -> [u8; 6] {
    let mac = default_mac(m.slave(position).unwrap().station_address);
    let parameters = IpParameters {
        mac: Some(mac),
        ip: Some(drive_ip(position)),
        subnet_mask: Some(Ipv4Addr::new(255, 255, 255, 0)),
        gateway: Some(HOST),
        dns_server: Some(Ipv4Addr::UNSPECIFIED),
        dns_name: with_name.then(|| format!("Drive_{}__AKD_", position + 1)),
    };
    m.slave_mut(position).unwrap().eoe_set_ip(&parameters).unwrap();
    mac
}

fn receive(m: &mut Master, position: u16) -> Vec<u8> {
    m.slave_mut(position).unwrap().eoe_receive(STEP).unwrap().expect("a frame from the drive")
}

fn arp_of(frame: &[u8]) -> ArpRepr {
    let e = EthernetFrame::new_checked(frame).unwrap();
    assert_eq!(e.ethertype(), EthernetProtocol::Arp);
    ArpRepr::parse(&ArpPacket::new_checked(e.payload()).unwrap()).unwrap()
}

#[test]
fn each_drive_takes_its_address_announces_it_and_answers_arp_and_ping() {
    let mut m = master(VirtualBus::new(2));
    for position in 0..2 {
        let mac = set_ip(&mut m, position, true);
        let ip = drive_ip(position);
        let ArpRepr::EthernetIpv4 {
            operation, source_hardware_addr, source_protocol_addr, target_protocol_addr, ..
        } = arp_of(&receive(&mut m, position))
        else {
            panic!()
        };
        assert_eq!(operation, ArpOperation::Request, "the drive's gratuitous ARP");
        assert_eq!((source_hardware_addr, source_protocol_addr, target_protocol_addr), (EthernetAddress(mac), ip, ip));
        m.slave_mut(position).unwrap().eoe_send(&who_has(ip)).unwrap();
        let ArpRepr::EthernetIpv4 { operation, source_hardware_addr, .. } = arp_of(&receive(&mut m, position)) else {
            panic!()
        };
        assert_eq!((operation, source_hardware_addr), (ArpOperation::Reply, EthernetAddress(mac)));
        // 56 bytes as ping sends by default, then 1400: 1442 bytes each way, two fragments.
        for (seq_no, len) in [(1, 56), (2, 1400), (3, 1472)] {
            let data: Vec<u8> = (0..len).map(|i| (i * 3 + position as usize) as u8).collect();
            m.slave_mut(position).unwrap().eoe_send(&ping(ip, mac, &data, seq_no)).unwrap();
            check_echo_reply(&receive(&mut m, position), ip, &data, seq_no);
        }
    }
    // A ping for another address gets no answer.
    let mac = default_mac(m.slave(0).unwrap().station_address);
    m.slave_mut(0).unwrap().eoe_send(&ping(drive_ip(1), mac, &[1, 2, 3], 9)).unwrap();
    assert_eq!(m.slave_mut(0).unwrap().eoe_receive(Duration::from_millis(100)).unwrap(), None);
    assert_eq!(m.slave(0).unwrap().eoe.dropped, 0);
}

#[test]
fn the_smallest_mailbox_carries_a_large_ping_in_many_fragments() {
    let mut m = master(VirtualBus::with_mailbox_size(1, Timing::IMMEDIATE, 64).unwrap());
    let mac = set_ip(&mut m, 0, false);
    arp_of(&receive(&mut m, 0));
    m.slave_mut(0).unwrap().eoe_send(&who_has(drive_ip(0))).unwrap();
    arp_of(&receive(&mut m, 0));
    let data = vec![0xA5; 1400];
    m.slave_mut(0).unwrap().eoe_send(&ping(drive_ip(0), mac, &data, 1)).unwrap();
    check_echo_reply(&receive(&mut m, 0), drive_ip(0), &data, 1);
}

#[test]
fn a_file_written_reads_back_and_a_missing_one_is_refused_by_name() {
    let mut m = master(VirtualBus::new(1));
    // 1012 bytes a packet in the AKD's 1 KiB mailbox: a file of whole packets ends with an
    // empty one, the other with a short one.
    for (name, len) in [("fw.bin", 3 * 1012), ("params.txt", 5000), ("empty", 0)] {
        let file: Vec<u8> = (0..len).map(|i| (i % 251) as u8).collect();
        let mut reported = Vec::new();
        m.slave_mut(0).unwrap().foe_write(name, 0, &file, &mut |sent, total| reported.push((sent, total))).unwrap();
        assert_eq!(reported.last(), Some(&(len, len)));
        let mut received = 0;
        let read = m.slave_mut(0).unwrap().foe_read(name, 0, &mut |n| received = n).unwrap();
        assert_eq!(read, file, "{name}");
        assert_eq!(received, len);
    }
    // The drive keeps its files across Init (its mailbox restarts).
    m.request_state(AlState::Init, STEP).unwrap();
    m.request_state(AlState::PreOp, STEP).unwrap();
    assert_eq!(m.slave_mut(0).unwrap().foe_read("params.txt", 0, &mut |_| {}).unwrap().len(), 5000);
    let err = m.slave_mut(0).unwrap().foe_read("missing.bin", 0, &mut |_| {}).unwrap_err();
    let Error::Foe(FoeError::Refused { name, code, code_name, .. }) = &err else { panic!("{err}") };
    assert_eq!((name.as_str(), *code, *code_name), ("missing.bin", 0x8001, "not found"));
    assert_eq!(err.to_string(), "FoE: slave 0 refused file \"missing.bin\": FoE error 0x8001 (not found)");
    // SDO still works between transfers.
    assert_eq!(m.slave_mut(0).unwrap().sdo_read(0x6060, 0).unwrap().len(), 1);
}

#[test]
fn pings_go_beside_the_running_cycle_without_losing_one() {
    let mut m = master(VirtualBus::new(2));
    let macs = [set_ip(&mut m, 0, true), set_ip(&mut m, 1, true)];
    for position in 0..2 {
        arp_of(&receive(&mut m, position));
        m.slave_mut(position).unwrap().eoe_send(&who_has(drive_ip(position))).unwrap();
        arp_of(&receive(&mut m, position));
    }
    m.request_state(AlState::Op, STEP).unwrap();
    let cycle = CycleThread::start(m, Config::new(Duration::from_millis(1))).map_err(|e| e.0).unwrap();
    for seq_no in 0..40u16 {
        let position = seq_no % 2;
        let data: Vec<u8> = vec![seq_no as u8; if seq_no % 4 < 2 { 56 } else { 1400 }];
        let ip = drive_ip(position);
        assert!(cycle.eoe_send(position, &ping(ip, macs[position as usize], &data, seq_no)).unwrap());
        let (from, reply) = cycle.eoe_receive(STEP).expect("an echo reply");
        assert_eq!(from, position);
        check_echo_reply(&reply, ip, &data, seq_no);
    }
    // An SDO transfer shares the mailbox with the pings.
    assert_eq!(cycle.sdo_read(1, 0x6060, 0).unwrap().len(), 1);
    let stats = cycle.stats();
    let (lost, wkc) = (stats.lost_frames.load(Ordering::Relaxed), stats.wkc_errors.load(Ordering::Relaxed));
    assert_eq!((lost, wkc, cycle.eoe_dropped()), (0, 0, (0, 0)));
    assert!(cycle.stats().cycles.load(Ordering::Relaxed) > 40);
    cycle.stop().unwrap();
}

#[test]
fn a_busy_drive_gets_the_same_packet_again_until_it_takes_it() {
    let mut bus = VirtualBus::new(1);
    bus.slave_mut(0).mailbox_mut().foe_mut().inject_busy(3);
    let mut m = master(bus);
    let file: Vec<u8> = (0..2500u32).map(|i| (i * 7) as u8).collect();
    let started = std::time::Instant::now();
    m.slave_mut(0).unwrap().foe_write("busy.bin", 0, &file, &mut |_, _| {}).unwrap();
    // Three busy answers, each followed by the master's pause before it sends the packet again.
    assert!(started.elapsed() >= Duration::from_millis(30), "{:?}", started.elapsed());
    assert_eq!(m.slave_mut(0).unwrap().foe_read("busy.bin", 0, &mut |_| {}).unwrap(), file);
}

#[test]
fn malformed_eoe_headers_are_answered_by_the_standard_and_change_nothing_else() {
    let mut m = master(VirtualBus::new(1));
    let mac = set_ip(&mut m, 0, true);
    arp_of(&receive(&mut m, 0));
    // An EoE header cut short (2 of 4 bytes), then frame type 12, which the standard does not define.
    for (message, detail) in
        [(&[0x02, 0, 0, 0, 0, 0x02, 0x00, 0x00][..], 0x0006), (&[0x04, 0, 0, 0, 0, 0x02, 0x0C, 0, 0, 0], 0x0004)]
    {
        let mut message = message.to_vec();
        m.slave_mut(0).unwrap().mailbox_send(&mut message, STEP).unwrap();
        let err = m.slave_mut(0).unwrap().mailbox_receive(STEP).unwrap_err();
        let Error::Mailbox(akd_native::error::MailboxError::ErrorReply { detail: got, .. }) = err else {
            panic!("{err}")
        };
        assert_eq!(got, detail);
    }
    // The drive's IP stack and its CoE go on as before.
    m.slave_mut(0).unwrap().eoe_send(&who_has(drive_ip(0))).unwrap();
    arp_of(&receive(&mut m, 0));
    m.slave_mut(0).unwrap().eoe_send(&ping(drive_ip(0), mac, &[1, 2, 3], 5)).unwrap();
    check_echo_reply(&receive(&mut m, 0), drive_ip(0), &[1, 2, 3], 5);
    assert_eq!(m.slave_mut(0).unwrap().sdo_read(0x6060, 0).unwrap().len(), 1);
}

/// Writes `message` whole into SM0 of the drive at `station` from a socket of its own, as a
/// second frame on the wire beside the cycle's: again while SM0 still holds the cycle's last
/// message (working counter 0), up to `STEP`. The number of frames it took.
fn write_sm0_beside(injector: &UdpSocket, station: u16, sm0: (u16, u16), message: &[u8]) -> usize {
    let mut mailbox = vec![0u8; sm0.1 as usize];
    mailbox[..message.len()].copy_from_slice(message);
    let deadline = Instant::now() + STEP;
    for sent in 1.. {
        assert!(Instant::now() < deadline, "SM0 of station {station:#06x} never took the message");
        let mut frame = [0u8; 1500];
        let mut builder = FrameBuilder::new(&mut frame);
        let slot = builder.push(Command::Fpwr, 0x7F, station, sm0.0, &mailbox).unwrap();
        let len = builder.finish();
        injector.send(&frame[..len]).unwrap();
        let mut reply = [0u8; 1500];
        let got = injector.recv(&mut reply).expect("the virtual bus answers the injected frame");
        if slot.wkc(&reply[..got]).unwrap() == 1 {
            return sent;
        }
        std::thread::sleep(Duration::from_micros(200));
    }
    unreachable!()
}

#[test]
fn malformed_eoe_headers_beside_the_running_cycle_disturb_neither_it_nor_the_ip_stack() {
    // Over UDP, so that a second sender's frames reach the same virtual drives as the cycle's.
    let late_is_not_missed = Timing { missed_frames: MissedFrames::Lost, ..Timing::IMMEDIATE };
    let socket = server::bind_udp("127.0.0.1:0".parse().unwrap()).unwrap();
    let address = socket.local_addr().unwrap();
    let stop = Arc::new(AtomicBool::new(false));
    let serving = {
        let stop = stop.clone();
        std::thread::spawn(move || {
            server::serve_udp_on(socket, VirtualBus::with_timing(2, late_is_not_missed), &stop, None)
        })
    };
    let mut m = Master::new(Box::new(Udp::connect(&address.to_string()).unwrap()), Duration::from_millis(500));
    let deadline = Instant::now() + STEP;
    while m.scan().is_err() {
        assert!(Instant::now() < deadline, "no virtual bus on {address}");
    }
    m.request_state(AlState::PreOp, STEP).unwrap();
    let mac = set_ip(&mut m, 0, true);
    arp_of(&receive(&mut m, 0));
    let station = m.slave(0).unwrap().station_address;
    let sm0 = m.slave(0).unwrap().mailbox.as_ref().map(|mb| (mb.out_start, mb.out_len)).unwrap();
    m.request_state(AlState::Op, STEP).unwrap();
    let cycle = CycleThread::start(m, Config::new(Duration::from_millis(1))).map_err(|e| e.0).unwrap();
    let injector = UdpSocket::bind("127.0.0.1:0").unwrap();
    injector.connect(address).unwrap();
    injector.set_read_timeout(Some(Duration::from_secs(1))).unwrap();
    // The drive learns the host's MAC from its ARP request, so its echo replies need no ARP of theirs.
    assert!(cycle.eoe_send(0, &who_has(drive_ip(0))).unwrap());
    arp_of(&cycle.eoe_receive(STEP).expect("an ARP reply").1);
    // An EoE header cut short (2 of 4 bytes), an undefined frame type (12), and a last
    // fragment numbered 5 of no frame under way; each followed by a ping through the cycle. The
    // echo reply shows that the drive took the message out of SM0 (the cycle's fragment got in
    // after it) and that the cycle read past the drive's mailbox error answer in SM1.
    let malformed: [&[u8]; 3] = [
        &[0x02, 0, 0, 0, 0, 0x02, 0x00, 0x00],
        &[0x04, 0, 0, 0, 0, 0x02, 0x0C, 0, 0, 0],
        &[0x08, 0, 0, 0, 0, 0x02, 0x00, 0x01, 0x05, 0x00, 0xDE, 0xAD, 0xBE, 0xEF],
    ];
    let mut frames = 0;
    for (seq_no, message) in malformed.iter().enumerate() {
        frames += write_sm0_beside(&injector, station, sm0, message);
        // One fragment, so that the next message cannot fall between two of the cycle's.
        let data = vec![seq_no as u8; 56];
        assert!(cycle.eoe_send(0, &ping(drive_ip(0), mac, &data, seq_no as u16)).unwrap());
        let (from, reply) = cycle.eoe_receive(STEP).expect("an echo reply");
        assert_eq!(from, 0);
        check_echo_reply(&reply, drive_ip(0), &data, seq_no as u16);
    }
    // The drive goes on: a ping fragmented both ways, and CoE through the cycle.
    assert!(cycle.eoe_send(0, &ping(drive_ip(0), mac, &[7; 1400], 9)).unwrap());
    check_echo_reply(&cycle.eoe_receive(STEP).expect("an echo reply").1, drive_ip(0), &[7; 1400], 9);
    assert_eq!(cycle.sdo_read(0, 0x6060, 0).unwrap().len(), 1);
    let stats = cycle.stats();
    let (lost, wkc) = (stats.lost_frames.load(Ordering::Relaxed), stats.wkc_errors.load(Ordering::Relaxed));
    println!("{frames} injected frames for 3 messages; lost {lost}, WKC errors {wkc}");
    assert_eq!((lost, wkc, cycle.eoe_dropped()), (0, 0, (0, 0)));
    cycle.stop().unwrap();
    stop.store(true, Ordering::Relaxed);
    serving.join().unwrap().unwrap();
}
