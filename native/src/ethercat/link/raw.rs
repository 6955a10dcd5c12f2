//! Raw Ethernet on a named interface (AF_PACKET, EtherType 0x88A4), for real hardware and for a
//! veth pair to a simulator.
//!
//! [`RawSocket`] moves whole Ethernet frames and is shared by the master and the simulator's
//! server; [`RawLink`] is the master's [`Link`]: it adds the Ethernet header on the way out and
//! strips it on the way back, so the master sees only EtherCAT payloads.

use std::ffi::CString;
use std::io;
use std::os::fd::{AsFd, AsRawFd, FromRawFd, OwnedFd};
use std::time::{Duration, Instant};

use crate::error::{Error, FrameError, Result, SettingError};
use crate::ethercat::frame::{self, ETHERTYPE, ETH_HEADER_LEN, MIN_ETH_FRAME_LEN};
use crate::ethercat::link::{copy_reply, privilege, socket, Link};

/// Source MAC of the master's frames: the one SOEM uses, so captures of both look alike.
pub const MASTER_MAC: [u8; 6] = [0x01, 0x01, 0x01, 0x01, 0x01, 0x01];
/// Bit an EtherCAT slave sets in the first byte of the source MAC of a frame it forwards back.
pub const RETURNED_MAC_BIT: u8 = 0x02;
/// Largest Ethernet frame without FCS.
pub const MAX_ETH_FRAME_LEN: usize = ETH_HEADER_LEN + frame::MAX_PAYLOAD_LEN;

/// An AF_PACKET socket bound to EtherType 0x88A4 on one interface.
#[derive(Debug)]
pub struct RawSocket {
    fd: OwnedFd,
    iface: String,
    kept_capabilities: Option<String>,
}

impl RawSocket {
    /// Opens a raw socket on `iface`, then gives up the capabilities the process no longer needs
    /// (see [`privilege`]). Frames are broadcast, so no promiscuous mode is needed. Fails with an
    /// error naming the interface when it does not exist, and saying how to grant CAP_NET_RAW
    /// when the process lacks it.
    pub fn open(iface: &str) -> Result<Self> {
        let name = CString::new(iface).map_err(|_| SettingError::InterfaceName { name: iface.to_owned() })?;
        // SAFETY: `name` is a valid NUL-terminated string.
        let ifindex = unsafe { libc::if_nametoindex(name.as_ptr()) };
        if ifindex == 0 {
            return Err(Error::io(
                format!("network interface {iface:?}"),
                io::Error::new(io::ErrorKind::NotFound, "no such interface (see `ip link`)"),
            ));
        }
        let protocol = ETHERTYPE.to_be() as libc::c_int;
        // SAFETY: plain socket(2) call; the result is checked.
        let raw = unsafe { libc::socket(libc::AF_PACKET, libc::SOCK_RAW | libc::SOCK_CLOEXEC, protocol) };
        if raw < 0 {
            let err = io::Error::last_os_error();
            let hint = if err.kind() == io::ErrorKind::PermissionDenied { missing_net_raw() } else { String::new() };
            return Err(Error::io(format!("opening an AF_PACKET socket on {iface:?}{hint}"), err));
        }
        // SAFETY: `raw` is a fresh descriptor owned by nobody else.
        let fd = unsafe { OwnedFd::from_raw_fd(raw) };
        let address = sockaddr_ll(ifindex as i32);
        // SAFETY: `address` is a valid sockaddr_ll of the size passed.
        let rc = unsafe {
            libc::bind(
                fd.as_raw_fd(),
                &address as *const libc::sockaddr_ll as *const libc::sockaddr,
                std::mem::size_of::<libc::sockaddr_ll>() as libc::socklen_t,
            )
        };
        if rc < 0 {
            return Err(Error::last_os(format!("binding the raw socket to interface {iface:?}")));
        }
        // A socket bound to one EtherType is not handed the frames it sends (only ETH_P_ALL taps
        // are); PACKET_IGNORE_OUTGOING (Linux 4.20) makes that the kernel's promise, so no
        // received frame needs its packet type checked. PACKET_QDISC_BYPASS sends straight to
        // the driver: the frame is due now, and a queueing discipline (a NIC's fq_codel) could
        // only hold it back behind other traffic. Both are best effort: an older kernel without
        // them still delivers no frame of ours and still sends, through the queue.
        for option in [libc::PACKET_IGNORE_OUTGOING, libc::PACKET_QDISC_BYPASS] {
            switch_on(&fd, libc::SOL_PACKET, option);
        }
        let kept_capabilities = privilege::drop_after_open(iface)?;
        Ok(RawSocket { fd, iface: iface.to_owned(), kept_capabilities })
    }

    /// Which threads of the process kept their capabilities after the socket was open, when some did.
    pub fn kept_capabilities(&self) -> Option<&str> {
        self.kept_capabilities.as_deref()
    }

    /// Sends one whole Ethernet frame (headers included, no FCS).
    pub fn send(&self, ethernet_frame: &[u8]) -> Result<()> {
        // SAFETY: the pointer and length describe `ethernet_frame`.
        let sent = unsafe {
            libc::send(self.fd.as_raw_fd(), ethernet_frame.as_ptr() as *const libc::c_void, ethernet_frame.len(), 0)
        };
        if sent < 0 {
            return Err(Error::last_os(format!("sending on interface {:?}", self.iface)));
        }
        if sent as usize != ethernet_frame.len() {
            return Err(Error::io(
                format!("sending on interface {:?}", self.iface),
                io::Error::new(io::ErrorKind::WriteZero, format!("sent {sent} of {} bytes", ethernet_frame.len())),
            ));
        }
        Ok(())
    }

    /// Waits until `deadline` for an incoming Ethernet frame and writes it to `buf`; `None` when
    /// nothing came (see [`socket::recv_until`]: exact to the microsecond, so a lost frame costs a
    /// cycle thread one period and not several).
    pub fn recv_until(&self, buf: &mut [u8], deadline: Instant) -> Result<Option<usize>> {
        socket::recv_until(self.fd.as_fd(), buf, deadline).map_err(|e| self.receiving(e))
    }

    /// Takes an incoming frame that is already there and writes it to `buf`, without waiting;
    /// `None` when there is none. One recv(2).
    pub fn try_recv(&self, buf: &mut [u8]) -> Result<Option<usize>> {
        socket::recv_now(self.fd.as_fd(), buf).map_err(|e| self.receiving(e))
    }

    fn receiving(&self, err: io::Error) -> Error {
        Error::io(format!("receiving on interface {:?}", self.iface), err)
    }

    /// Sets how long [`recv_stamped`](Self::recv_stamped) waits, as
    /// [`UdpSocket::set_read_timeout`](std::net::UdpSocket::set_read_timeout) does (SO_RCVTIMEO,
    /// counted in scheduler ticks: at least one, so a short time-out may last up to 4 ms).
    pub fn set_read_timeout(&self, timeout: Duration) -> Result<()> {
        let tv = libc::timeval { tv_sec: timeout.as_secs() as libc::time_t, tv_usec: timeout.subsec_micros() as _ };
        // SAFETY: a valid descriptor and a timeval of the size passed.
        let rc = unsafe {
            libc::setsockopt(
                self.fd.as_raw_fd(),
                libc::SOL_SOCKET,
                libc::SO_RCVTIMEO,
                &tv as *const libc::timeval as *const libc::c_void,
                std::mem::size_of::<libc::timeval>() as libc::socklen_t,
            )
        };
        if rc < 0 {
            return Err(Error::last_os(format!("setting the read time-out on interface {:?}", self.iface)));
        }
        Ok(())
    }

    /// Has the kernel stamp each incoming frame with its arrival (SO_TIMESTAMPNS), for
    /// [`recv_stamped`](Self::recv_stamped); `false` where the kernel refuses. The kernel starts
    /// stamping on arrival a moment later; a frame read before then is stamped as it is read.
    pub fn stamp_arrivals(&self) -> bool {
        switch_on(&self.fd, libc::SOL_SOCKET, libc::SO_TIMESTAMPNS)
    }

    /// Takes the next incoming frame into `buf`, waiting for it up to the [read
    /// time-out](Self::set_read_timeout) when `wait`, else as [`try_recv`](Self::try_recv); with
    /// the frame's arrival on the interface as the kernel stamped it (CLOCK_REALTIME, ns) once
    /// [`stamp_arrivals`](Self::stamp_arrivals) is on. One recvmsg(2) per frame, for a server,
    /// which needs no exact time-out: half the system calls of [`recv_until`](Self::recv_until).
    pub fn recv_stamped(&self, buf: &mut [u8], wait: bool) -> Result<Option<(usize, Option<u64>)>> {
        let mut iov = libc::iovec { iov_base: buf.as_mut_ptr() as *mut libc::c_void, iov_len: buf.len() };
        // Room for one control message carrying a timespec, aligned as cmsghdr wants.
        let mut control = [0u64; 8];
        // SAFETY: zeroed msghdr is a valid value; the fields that matter are set below.
        let mut message: libc::msghdr = unsafe { std::mem::zeroed() };
        message.msg_iov = &mut iov;
        message.msg_iovlen = 1;
        message.msg_control = control.as_mut_ptr() as *mut libc::c_void;
        message.msg_controllen = std::mem::size_of_val(&control) as _;
        let flags = if wait { 0 } else { libc::MSG_DONTWAIT };
        // SAFETY: `message` describes `buf` and `control`, both valid for their lengths.
        let got = unsafe { libc::recvmsg(self.fd.as_raw_fd(), &mut message, flags) };
        let Some(len) = socket::received(got).map_err(|e| self.receiving(e))? else {
            return Ok(None);
        };
        Ok(Some((len, arrival_stamp(&message))))
    }
}

/// The SO_TIMESTAMPNS stamp among the control messages recvmsg(2) filled in, in ns.
fn arrival_stamp(message: &libc::msghdr) -> Option<u64> {
    // SAFETY: `message` was filled in by recvmsg(2); the CMSG_* walk stays within its control
    // buffer, and a SCM_TIMESTAMPNS message's data is one timespec, read unaligned.
    unsafe {
        let mut header = libc::CMSG_FIRSTHDR(message);
        while !header.is_null() {
            if (*header).cmsg_level == libc::SOL_SOCKET && (*header).cmsg_type == libc::SCM_TIMESTAMPNS {
                let stamp = std::ptr::read_unaligned(libc::CMSG_DATA(header) as *const libc::timespec);
                return Some(stamp.tv_sec as u64 * 1_000_000_000 + stamp.tv_nsec as u64);
            }
            header = libc::CMSG_NXTHDR(message, header);
        }
    }
    None
}

/// Turns the socket option `option` of `level` on (an int 1); `false` where the kernel lacks it,
/// the socket left as it was.
fn switch_on(fd: &OwnedFd, level: libc::c_int, option: libc::c_int) -> bool {
    let on: libc::c_int = 1;
    // SAFETY: a valid descriptor and a c_int of the size passed.
    let rc = unsafe {
        libc::setsockopt(
            fd.as_raw_fd(),
            level,
            option,
            &on as *const libc::c_int as *const libc::c_void,
            std::mem::size_of::<libc::c_int>() as libc::socklen_t,
        )
    };
    rc == 0
}

/// Why an AF_PACKET socket was refused and how to grant CAP_NET_RAW, on one line.
fn missing_net_raw() -> String {
    if let Some(first) = privilege::dropped_after() {
        return format!(
            " (this process gave up CAP_NET_RAW after it opened its raw socket on {first:?}: \
             open another interface from a new process)"
        );
    }
    let program = std::env::current_exe().map_or_else(|_| "the program".to_owned(), |p| p.display().to_string());
    format!(
        " (raw Ethernet needs CAP_NET_RAW, which this process lacks: grant it with \
         `setcap cap_net_raw+ep {program}` or as an ambient capability, e.g. systemd \
         AmbientCapabilities=CAP_NET_RAW or `setpriv --inh-caps=+net_raw --ambient-caps=+net_raw`)"
    )
}

fn sockaddr_ll(ifindex: i32) -> libc::sockaddr_ll {
    // SAFETY: zeroed sockaddr_ll is a valid value; the fields that matter are set below.
    let mut address: libc::sockaddr_ll = unsafe { std::mem::zeroed() };
    address.sll_family = libc::AF_PACKET as u16;
    address.sll_protocol = ETHERTYPE.to_be();
    address.sll_ifindex = ifindex;
    address
}

/// The master's link over a [`RawSocket`]: broadcast frames from [`MASTER_MAC`], replies
/// recognised by the returned-frame bit in their source MAC and by their datagrams.
///
/// With a busy poll, the link asks the socket for a returning frame without sleeping, up to
/// that long after the last frame went out, and only then sleeps until it comes: a thread woken by
/// the frame's arrival waits for the scheduler (on a virtual machine, for its halted vCPU to be
/// woken too), which costs more than the round trip of a short line. The CPU spins meanwhile,
/// so the busy poll is for a cycle thread on a core of its own; a peer process on the same CPU
/// (a simulator) cannot answer while a real-time thread spins, and its frame then comes only
/// after the busy poll.
#[derive(Debug)]
pub struct RawLink {
    socket: RawSocket,
    busy_poll: Duration,
    /// When the last frame went out: the busy poll runs from there.
    sent: Instant,
    tx: [u8; MAX_ETH_FRAME_LEN],
    rx: [u8; MAX_ETH_FRAME_LEN],
}

impl RawLink {
    /// Opens the interface `iface` (see [`RawSocket::open`]), busy-polling for each returning
    /// frame up to `busy_poll` (zero: none).
    pub fn open(iface: &str, busy_poll: Duration) -> Result<Self> {
        Ok(RawLink {
            socket: RawSocket::open(iface)?,
            busy_poll,
            sent: Instant::now(),
            tx: [0; MAX_ETH_FRAME_LEN],
            rx: [0; MAX_ETH_FRAME_LEN],
        })
    }

    /// The next incoming frame in `self.rx`, busy-polled for until `spin_end` and then waited
    /// for until `deadline`; `None` when nothing came.
    fn next_frame(&mut self, spin_end: Instant, deadline: Instant) -> Result<Option<usize>> {
        while Instant::now() < spin_end {
            if let Some(got) = self.socket.try_recv(&mut self.rx)? {
                return Ok(Some(got));
            }
            std::hint::spin_loop();
        }
        self.socket.recv_until(&mut self.rx, deadline)
    }

    /// See [`RawSocket::kept_capabilities`].
    pub fn kept_capabilities(&self) -> Option<&str> {
        self.socket.kept_capabilities()
    }
}

/// Writes the Ethernet header of a frame from the master and returns the frame length, padded
/// to the Ethernet minimum.
fn wrap(payload: &[u8], out: &mut [u8; MAX_ETH_FRAME_LEN]) -> Result<usize> {
    let len = ETH_HEADER_LEN + payload.len();
    if len > MAX_ETH_FRAME_LEN {
        return Err(FrameError::TooLarge { len: payload.len(), room: frame::MAX_PAYLOAD_LEN }.into());
    }
    out[..6].fill(0xFF);
    out[6..12].copy_from_slice(&MASTER_MAC);
    out[12..14].copy_from_slice(&ETHERTYPE.to_be_bytes());
    out[ETH_HEADER_LEN..len].copy_from_slice(payload);
    let padded = len.max(MIN_ETH_FRAME_LEN);
    out[len..padded].fill(0);
    Ok(padded)
}

/// The EtherCAT payload of a returned frame, without Ethernet padding; `None` for anything
/// else (another EtherType, a frame no slave has forwarded).
fn unwrap_returned(frame: &[u8]) -> Option<&[u8]> {
    if frame.len() < ETH_HEADER_LEN + frame::FRAME_HEADER_LEN
        || u16::from_be_bytes([frame[12], frame[13]]) != ETHERTYPE
        || frame[6] & RETURNED_MAC_BIT == 0
    {
        return None;
    }
    let payload = &frame[ETH_HEADER_LEN..];
    let len = frame::frame_header(payload).ok()?;
    Some(&payload[..frame::FRAME_HEADER_LEN + len])
}

impl Link for RawLink {
    fn send(&mut self, tx: &[u8]) -> Result<()> {
        let len = wrap(tx, &mut self.tx)?;
        self.socket.send(&self.tx[..len])?;
        self.sent = Instant::now();
        Ok(())
    }

    fn receive(&mut self, rx: &mut [u8], deadline: Instant) -> Result<Option<usize>> {
        let spin_end = (self.sent + self.busy_poll).min(deadline);
        loop {
            let Some(got) = self.next_frame(spin_end, deadline)? else {
                return Ok(None);
            };
            if let Some(payload) = unwrap_returned(&self.rx[..got]) {
                return copy_reply(payload, rx).map(Some);
            }
        }
    }

    fn describe(&self) -> String {
        self.socket.iface.clone()
    }

    fn awaited(&self) -> &'static str {
        "a frame to come back on the interface"
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ethercat::frame::{Command, FrameBuilder};
    use crate::ethercat::link::is_reply_to;

    fn payload() -> Vec<u8> {
        let mut buf = [0u8; 64];
        let mut b = FrameBuilder::new(&mut buf);
        b.push(Command::Brd, 7, 0, 0x0130, &[0, 0]).unwrap();
        let n = b.finish();
        buf[..n].to_vec()
    }

    #[test]
    fn wraps_as_soem_does_and_pads() {
        let p = payload();
        let mut out = [0u8; MAX_ETH_FRAME_LEN];
        let n = wrap(&p, &mut out).unwrap();
        assert_eq!(n, MIN_ETH_FRAME_LEN);
        assert_eq!(&out[..6], &[0xFF; 6]);
        assert_eq!(&out[6..12], &MASTER_MAC);
        assert_eq!(&out[12..14], &[0x88, 0xA4]);
        assert_eq!(&out[14..14 + p.len()], &p[..]);
        // The master's own frame is not a returned one; the slave-forwarded copy is, without padding.
        assert_eq!(unwrap_returned(&out[..n]), None);
        out[6] |= RETURNED_MAC_BIT;
        assert_eq!(unwrap_returned(&out[..n]), Some(&p[..]));
        out[13] = 0x00;
        assert_eq!(unwrap_returned(&out[..n]), None);
    }

    #[test]
    fn refuses_oversized_payload() {
        let mut out = [0u8; MAX_ETH_FRAME_LEN];
        assert!(matches!(wrap(&[0u8; 1501], &mut out), Err(Error::Frame(FrameError::TooLarge { .. }))));
    }

    #[test]
    fn names_a_missing_interface() {
        let err = RawSocket::open("nosuchif0").unwrap_err().to_string();
        assert!(err.contains("nosuchif0") && err.contains("no such interface"), "{err}");
    }

    #[test]
    #[ignore = "needs CAP_NET_RAW: scripts/test.sh runs it with --include-ignored as root"]
    fn stamps_a_frames_arrival_on_the_interface() {
        let socket = RawSocket::open("lo").unwrap();
        assert!(socket.stamp_arrivals());
        socket.set_read_timeout(Duration::from_millis(200)).unwrap();
        let mut out = [0u8; MAX_ETH_FRAME_LEN];
        let n = wrap(&payload(), &mut out).unwrap();
        // Told apart from the frames other tests send on loopback meanwhile.
        out[n - 1] = 0xA5;
        let now_ns = || std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).unwrap().as_nanos() as u64;
        let mut buf = [0u8; MAX_ETH_FRAME_LEN];
        // The kernel turns its stamping on a moment after the option is set (a deferred switch),
        // until then a frame is stamped as it is read: the first frames may be.
        let mut stamps = Vec::new();
        for _ in 0..50 {
            let before = now_ns();
            socket.send(&out[..n]).unwrap();
            std::thread::sleep(Duration::from_millis(20));
            let arrived = loop {
                let (got, arrived) = socket.recv_stamped(&mut buf, true).unwrap().expect("the frame came back");
                if buf[..got] == out[..n] {
                    break arrived.unwrap();
                }
            };
            // Stamped as it arrived, not when it was taken 20 ms later.
            if before <= arrived && arrived < before + 10_000_000 {
                return;
            }
            stamps.push(arrived - before);
        }
        panic!("no frame stamped as it arrived: stamped {stamps:?} ns after it was sent");
    }

    #[test]
    #[ignore = "needs CAP_NET_RAW: scripts/test.sh runs it with --include-ignored as root"]
    fn skips_its_own_outgoing_frames() {
        // On loopback every sent frame comes back once as an incoming one, and only once: the
        // socket is handed no copy of what it sent (PACKET_IGNORE_OUTGOING).
        let socket = RawSocket::open("lo").unwrap();
        let mut out = [0u8; MAX_ETH_FRAME_LEN];
        let n = wrap(&payload(), &mut out).unwrap();
        socket.send(&out[..n]).unwrap();
        // Other EtherCAT traffic on loopback is ignored: only copies of this frame count.
        let mut buf = [0u8; MAX_ETH_FRAME_LEN];
        let mut copies = 0;
        let deadline = Instant::now() + Duration::from_millis(200);
        while let Some(got) = socket.recv_until(&mut buf, deadline).unwrap() {
            copies += (buf[..got] == out[..n]) as usize;
        }
        assert_eq!(copies, 1);
    }

    #[test]
    #[ignore = "needs CAP_NET_RAW: scripts/test.sh runs it with --include-ignored as root"]
    fn try_recv_takes_a_frame_that_is_there_without_waiting() {
        // What a busy poll spins on: a frame sent on loopback is taken by try_recv alone, never
        // by a wait, and only once. Its datagram index is its own, so the frame of
        // skips_its_own_outgoing_frames, running beside it on loopback, is not taken for it.
        let socket = RawSocket::open("lo").unwrap();
        let mut p = payload();
        p[3] = 0x5A;
        let mut out = [0u8; MAX_ETH_FRAME_LEN];
        let n = wrap(&p, &mut out).unwrap();
        socket.send(&out[..n]).unwrap();
        let mut buf = [0u8; MAX_ETH_FRAME_LEN];
        let mut copies = 0;
        let deadline = Instant::now() + Duration::from_millis(200);
        while Instant::now() < deadline {
            if let Some(got) = socket.try_recv(&mut buf).unwrap() {
                copies += (buf[..got] == out[..n]) as usize;
            }
        }
        assert_eq!(copies, 1);
    }

    #[test]
    fn reply_matching_follows_command_index_and_length() {
        let p = payload();
        let mut back = p.clone();
        back[2 + 2] = 0x55; // ADP changed by auto-increment: still the reply
        back[p.len() - 2] = 1; // WKC
        assert!(is_reply_to(&p, &back));
        let mut other = p.clone();
        other[3] = 8; // another index: a stale frame
        assert!(!is_reply_to(&p, &other));
        assert!(!is_reply_to(&p, &p[..p.len() - 1]));
    }
}
