//! EtherCAT over UDP: the EtherCAT payload (frame header plus datagrams) is the UDP payload,
//! sent to a simulator in another process, by default on port 0x88A4.

use std::io;
use std::net::{SocketAddr, ToSocketAddrs, UdpSocket};
use std::os::fd::AsFd;
use std::time::Instant;

use crate::error::{Error, Result, SettingError};
use crate::ethercat::frame::{self, ETHERTYPE};
use crate::ethercat::link::{copy_reply, socket, Link};

/// The UDP port of EtherCAT over UDP (0x88A4 = 34980).
pub const DEFAULT_PORT: u16 = ETHERTYPE;

/// A link to a simulator listening on a UDP address.
#[derive(Debug)]
pub struct Udp {
    socket: UdpSocket,
    peer: SocketAddr,
    rx: [u8; frame::MAX_PAYLOAD_LEN],
}

impl Udp {
    /// Connects to `address`, `HOST:PORT` or `HOST` (then port 0x88A4).
    pub fn connect(address: &str) -> Result<Self> {
        let with_port = if address.rsplit_once(':').is_some_and(|(_, p)| p.parse::<u16>().is_ok()) {
            address.to_owned()
        } else {
            format!("{address}:{DEFAULT_PORT}")
        };
        let peer = with_port
            .to_socket_addrs()
            .map_err(|e| Error::io(format!("resolving the UDP address {address:?}"), e))?
            .next()
            .ok_or_else(|| SettingError::UnresolvedHost { host: address.to_owned(), role: "connect" })?;
        let local: SocketAddr = if peer.is_ipv4() { "0.0.0.0:0" } else { "[::]:0" }.parse().expect("literal");
        let socket = UdpSocket::bind(local).map_err(|e| Error::io("binding a UDP socket", e))?;
        // Connecting filters out datagrams from anyone but the simulator.
        socket.connect(peer).map_err(|e| Error::io(format!("connecting to udp://{peer}"), e))?;
        Ok(Udp { socket, peer, rx: [0; frame::MAX_PAYLOAD_LEN] })
    }
}

impl Link for Udp {
    fn send(&mut self, tx: &[u8]) -> Result<()> {
        self.socket.send(tx).map_err(|e| Error::io(format!("sending to udp://{}", self.peer), e))?;
        Ok(())
    }

    /// Waits with a read time-out, as a link to a simulator may: it counts in scheduler ticks, so
    /// a reply the loaded host delays past `deadline` is still waited for, up to a tick (4 ms),
    /// rather than lost. A deadline already past takes what is there without waiting (a pipelined
    /// cycle asks for its frame a period after it sent it).
    fn receive(&mut self, rx: &mut [u8], deadline: Instant) -> Result<Option<usize>> {
        loop {
            let left = deadline.saturating_duration_since(Instant::now());
            let got = if left.is_zero() {
                socket::recv_now(self.socket.as_fd(), &mut self.rx)
            } else {
                self.socket.set_read_timeout(Some(left)).map_err(|e| Error::io("setting the UDP read time-out", e))?;
                match self.socket.recv(&mut self.rx) {
                    Err(e) if matches!(e.kind(), io::ErrorKind::WouldBlock | io::ErrorKind::TimedOut) => continue,
                    got => got.map(Some),
                }
            };
            return match got {
                Ok(got) => got.map(|got| copy_reply(&self.rx[..got], rx)).transpose(),
                // A simulator not (yet) listening answers with ICMP port unreachable.
                Err(e) if e.kind() == io::ErrorKind::ConnectionRefused => {
                    Err(Error::io(format!("udp://{}: no simulator listening", self.peer), e))
                }
                Err(e) => Err(Error::io(format!("receiving from udp://{}", self.peer), e)),
            };
        }
    }

    fn describe(&self) -> String {
        format!("udp://{}", self.peer)
    }

    fn awaited(&self) -> &'static str {
        "a frame to come back over UDP"
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ethercat::frame::{Command, FrameBuilder};
    use std::time::Duration;

    fn request(index: u8) -> Vec<u8> {
        let mut buf = [0u8; 64];
        let mut b = FrameBuilder::new(&mut buf);
        b.push(Command::Brd, index, 0, 0x0000, &[0, 0]).unwrap();
        let n = b.finish();
        buf[..n].to_vec()
    }

    #[test]
    fn returns_the_matching_reply_and_drops_stale_ones() {
        let server = UdpSocket::bind("127.0.0.1:0").unwrap();
        let mut link = Udp::connect(&server.local_addr().unwrap().to_string()).unwrap();
        let echo = std::thread::spawn(move || {
            let mut buf = [0u8; 1500];
            let (n, from) = server.recv_from(&mut buf).unwrap();
            // A stale reply of an earlier frame first, then the real one with WKC 1.
            server.send_to(&request(buf[3].wrapping_sub(1)), from).unwrap();
            buf[n - 2] = 1;
            server.send_to(&buf[..n], from).unwrap();
        });
        let tx = request(42);
        let mut rx = [0u8; 1500];
        let n = link.exchange(&tx, &mut rx, Duration::from_secs(2)).unwrap();
        assert_eq!(rx[3], 42);
        assert_eq!(rx[n - 2], 1);
        echo.join().unwrap();
    }

    #[test]
    fn times_out_without_reply() {
        let server = UdpSocket::bind("127.0.0.1:0").unwrap();
        let mut link = Udp::connect(&server.local_addr().unwrap().to_string()).unwrap();
        let mut rx = [0u8; 1500];
        let err = link.exchange(&request(1), &mut rx, Duration::from_millis(20)).unwrap_err();
        assert!(matches!(err, Error::Timeout { .. }), "{err}");
    }

    #[test]
    fn a_return_already_there_is_taken_though_its_deadline_passed() {
        // As a pipelined cycle asks for its frame a period after sending it.
        let server = UdpSocket::bind("127.0.0.1:0").unwrap();
        let mut link = Udp::connect(&server.local_addr().unwrap().to_string()).unwrap();
        link.send(&request(9)).unwrap();
        let mut buf = [0u8; 1500];
        let (n, from) = server.recv_from(&mut buf).unwrap();
        server.send_to(&buf[..n], from).unwrap();
        std::thread::sleep(Duration::from_millis(50));
        let mut rx = [0u8; 1500];
        let past = Instant::now() - Duration::from_millis(10);
        assert_eq!(link.receive(&mut rx, past).unwrap(), Some(n));
        assert_eq!(rx[3], 9);
        assert_eq!(link.receive(&mut rx, past).unwrap(), None);
    }

    #[test]
    fn default_port_is_the_ethertype() {
        let link = Udp::connect("127.0.0.1").unwrap();
        assert_eq!(link.describe(), "udp://127.0.0.1:34980");
    }
}
