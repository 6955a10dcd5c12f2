//! Serving a [`VirtualBus`](crate::sim::VirtualBus) to a master in another process: EtherCAT over UDP (the payload is
//! the UDP datagram) or raw Ethernet on a network interface (e.g. one end of a veth pair).
//!
//! Each request is processed at the monotonic time since the server started and sent back at
//! once, before the drives' IP stacks (EoE) do their work, as the ESC answers in hardware; a
//! malformed request is counted and dropped, as a real line drops a corrupt frame, and a frame
//! lost on the simulated line is counted and not answered. The
//! loops wake at least every 100 ms to see `stop`. The bus takes commands from its
//! [`SimControl`](crate::sim::control::SimControl) handles at each frame and, with no frame,
//! at each wake-up, so a query is answered within 100 ms whether a master runs or not.
//!
//! Given a [`TraceSender`], a server stamps each frame as it is received and, once the reply is
//! out, traces the set-points it changed (see [`crate::sim::setpoint_trace`]).

use std::net::{SocketAddr, UdpSocket};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use crate::error::{Error, Result, SettingError};
use crate::ethercat::frame::{ETHERTYPE, ETH_HEADER_LEN, MAX_PAYLOAD_LEN};
use crate::ethercat::link::raw::{RawSocket, MAX_ETH_FRAME_LEN, RETURNED_MAC_BIT};
use crate::sim::control::ControlledBus;
use crate::sim::line::Delivery;
use crate::sim::setpoint_trace::{clock_ns, Stamps, TraceSender};

/// How often a server looks at its stop flag and its commands, and lets its drives' firmware
/// run when no frame comes: a real AKD's firmware runs by itself, so a master that is gone
/// ends in F125 within a few ms of its last frame, not at the next master's first frame.
pub const POLL_INTERVAL: Duration = Duration::from_millis(2);

/// What a server did, for its caller to report.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct ServerStats {
    /// Frames served and sent back.
    pub served: u64,
    /// Frames dropped because they were not valid EtherCAT frames.
    pub malformed: u64,
    /// Frames lost on the simulated line (see [`crate::sim::line`]): never answered.
    pub lost: u64,
    /// Replies the interface could not send because the line went down under them (the
    /// master's end of a veth pair taken down, a cable pulled): lost, as on a real line.
    pub unsent: u64,
    /// How late replies went back because the server was not run, where the interface stamps
    /// each frame's arrival (`None` over UDP, or where the kernel refuses).
    pub late: Option<LateReplies>,
    /// How long the server's own serving of a frame took (the ESCs and the drives' firmware
    /// answering it, from its taking it up to the reply handed to the interface), by the same
    /// bounds: a master counts a reply later than its time-out as lost whether the server took
    /// the frame up late or took long to answer it, and `late` leaves this part out.
    pub serving: LateReplies,
    /// F125 the drives would have raised as real AKDs and did not, judging missed frames by
    /// [`MissedFrames::Warn`](crate::ethercat::link_spec::MissedFrames::Warn): each warned of on stderr.
    pub would_be_f125: u64,
    /// Each drive's count of them when last warned of.
    warned: Vec<u64>,
}

/// The bounds of [`LateReplies::over`], in µs.
pub const LATE_AFTER_US: [u64; 5] = [250, 500, 1000, 2000, 4000];

/// Replies that went back late because the server was not run: the time from the frame's
/// arrival on the interface to the server's taking it up, less the server's own work meanwhile
/// (serving, the drives' IP stacks, their firmware). An ESC answers as the frame passes; a
/// simulator on a loaded host, or on a virtual CPU its host holds, answers milliseconds later,
/// and a master counts a reply later than its time-out as a lost frame. This tells those losses
/// from ones the master or the line cause. Every frame counts, the cyclic ones and the mailbox
/// ones alike: the server cannot tell which a master waits for how long.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LateReplies {
    /// Replies later than each bound of [`LATE_AFTER_US`].
    pub over: [u64; LATE_AFTER_US.len()],
    /// How late the latest reply was, in µs.
    pub longest_us: u64,
}

impl LateReplies {
    /// Counts a reply whose frame was taken up `late_ns` late.
    fn count(&mut self, late_ns: u64) {
        let late_us = late_ns / 1000;
        for (over, bound) in self.over.iter_mut().zip(LATE_AFTER_US) {
            *over += (late_us > bound) as u64;
        }
        self.longest_us = self.longest_us.max(late_us);
    }
}

/// CLOCK_REALTIME in ns, the clock of the kernel's arrival stamps.
fn realtime_ns() -> u64 {
    clock_ns(libc::CLOCK_REALTIME)
}

impl ServerStats {
    /// Serves `payload` through `bus` at `now_ns` as the ESCs answer it (the drives' IP stacks
    /// run once it has gone back); whether it goes back. What does not is counted, malformed or
    /// lost.
    fn serve(&mut self, bus: &mut ControlledBus, payload: &mut [u8], now_ns: u64) -> bool {
        let returned = match bus.answer(payload, now_ns) {
            Ok(Delivery::Returned) => true,
            Ok(Delivery::Lost) => {
                self.lost += 1;
                false
            }
            Err(_) => {
                self.malformed += 1;
                false
            }
        };
        self.warn_of_f125(bus);
        returned
    }

    /// Says on stderr, once each, where a drive judging missed frames by
    /// [`MissedFrames::Warn`](crate::ethercat::link_spec::MissedFrames::Warn) went on where a real AKD
    /// would have raised F125. Rare (a stall of the master), so a line of I/O is no burden.
    fn warn_of_f125(&mut self, bus: &ControlledBus) {
        let bus = bus.bus();
        self.warned.resize(bus.len(), 0);
        for (position, warned) in self.warned.iter_mut().enumerate() {
            let Some(akd) = bus.at(position).akd() else { continue };
            let w = akd.would_be_f125();
            if w.count == *warned {
                continue;
            }
            self.would_be_f125 += w.count - *warned;
            *warned = w.count;
            eprintln!(
                "akd-sim: drive {position}: a real AKD would raise F125 here (no process data for {:.1} ms while \
                 enabled, more than seven frames missed); this one goes on (--missed warn), {} so far",
                w.latest_ns as f64 / 1e6,
                w.count
            );
        }
    }
}

fn elapsed_ns(start: Instant) -> u64 {
    start.elapsed().as_nanos() as u64
}

/// The stamps of a frame just received, when a trace wants them.
fn stamp(trace: &Option<TraceSender>) -> Option<Stamps> {
    trace.as_ref().map(|_| Stamps::now())
}

/// Traces the set-points `payload`, served and answered, left in the drives.
fn trace_frame(trace: &mut Option<TraceSender>, bus: &ControlledBus, payload: &[u8], received: Option<Stamps>) {
    if let (Some(recorder), Some(received)) = (trace, received) {
        recorder.record_bus(bus.bus(), payload, received);
    }
}

/// A UDP socket bound to `bind` for [`serve_udp_on`]: a caller that says it serves once its
/// socket is bound binds it first.
pub fn bind_udp(bind: SocketAddr) -> Result<UdpSocket> {
    let socket = UdpSocket::bind(bind).map_err(|e| Error::io(format!("binding UDP {bind}"), e))?;
    socket.set_read_timeout(Some(POLL_INTERVAL)).map_err(|e| Error::io("setting the UDP read timeout", e))?;
    Ok(socket)
}

/// Serves `bus` (a [`VirtualBus`](crate::sim::VirtualBus), or a [`ControlledBus`] whose
/// handles the caller kept) on the UDP socket [`bind_udp`] bound until `stop` is set: each
/// datagram is an EtherCAT payload, answered to its sender. `trace`, if given, records the
/// set-points the drives receive.
pub fn serve_udp_on(
    socket: UdpSocket,
    bus: impl Into<ControlledBus>,
    stop: &AtomicBool,
    mut trace: Option<TraceSender>,
) -> Result<ServerStats> {
    let mut bus = bus.into();
    let bind = socket.local_addr().map_err(|e| Error::io("reading the UDP socket's address", e))?;
    let start = Instant::now();
    let mut stats = ServerStats::default();
    let mut buf = [0u8; MAX_PAYLOAD_LEN];
    while !stop.load(Ordering::Relaxed) {
        let (len, peer) = match socket.recv_from(&mut buf) {
            Ok(r) => r,
            Err(e)
                if matches!(
                    e.kind(),
                    std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut | std::io::ErrorKind::Interrupted
                ) =>
            {
                bus.idle(elapsed_ns(start));
                continue;
            }
            Err(e) => return Err(Error::io(format!("receiving on UDP {bind}"), e)),
        };
        let received = stamp(&trace);
        let (now_ns, answered_ns) = (elapsed_ns(start), realtime_ns());
        if stats.serve(&mut bus, &mut buf[..len], now_ns) {
            socket.send_to(&buf[..len], peer).map_err(|e| Error::io(format!("replying to {peer}"), e))?;
            stats.served += 1;
            stats.serving.count(realtime_ns().saturating_sub(answered_ns));
            trace_frame(&mut trace, &bus, &buf[..len], received);
        }
        bus.run_ip_stacks(now_ns);
    }
    Ok(stats)
}

/// A raw socket on `iface` for [`serve_iface_on`]; refuses `busy_poll` under a real-time
/// scheduler (see [`serve_iface_on`]).
pub fn open_iface(iface: &str, busy_poll: bool) -> Result<RawSocket> {
    // SAFETY: sched_getscheduler(0) asks about the calling thread and touches no memory.
    if busy_poll && matches!(unsafe { libc::sched_getscheduler(0) }, libc::SCHED_FIFO | libc::SCHED_RR) {
        return Err(SettingError::BusyPollRealTime.into());
    }
    let socket = RawSocket::open(iface)?;
    socket.set_read_timeout(POLL_INTERVAL)?;
    Ok(socket)
}

/// Serves `bus` (as [`serve_udp_on`] takes it) on the raw socket [`open_iface`] opened until
/// `stop` is set: each EtherCAT frame received is processed and sent back with the first byte
/// of its source MAC ORed with 0x02, as the real ESC marks a frame it returns
/// (01:01:01:01:01:01 → 03:01:01:01:01:01). `trace` as for [`serve_udp_on`].
///
/// With `busy_poll` the server never sleeps: it asks the socket for the next frame again and
/// again, and lets the firmware run every [`POLL_INTERVAL`]. A real ESC answers in hardware as
/// the frame passes; a server woken by each frame's arrival adds the scheduler's wake-up (tens
/// of µs on a virtual machine) to every round trip, the same for every master, which hides
/// their differences in a benchmark. It takes a CPU of its own, under the normal scheduler.
pub fn serve_iface_on(
    socket: RawSocket,
    bus: impl Into<ControlledBus>,
    stop: &AtomicBool,
    mut trace: Option<TraceSender>,
    busy_poll: bool,
) -> Result<ServerStats> {
    let mut bus = bus.into();
    let start = Instant::now();
    let mut stats = ServerStats { late: socket.stamp_arrivals().then(LateReplies::default), ..Default::default() };
    let mut buf = [0u8; MAX_ETH_FRAME_LEN];
    // When the firmware last ran, by a frame or by itself: busy-polling, it runs by itself once
    // no frame came for POLL_INTERVAL, as the blocking receive's time-out makes it.
    let mut ran_ns = 0;
    // The server's own work last done between receives, from and to (CLOCK_REALTIME).
    let mut work_ns = (0, 0);
    while !stop.load(Ordering::Relaxed) {
        let Some((len, arrived_ns)) = socket.recv_stamped(&mut buf, !busy_poll)? else {
            let now_ns = elapsed_ns(start);
            if !busy_poll || now_ns - ran_ns >= POLL_INTERVAL.as_nanos() as u64 {
                let from_ns = realtime_ns();
                bus.idle(now_ns);
                ran_ns = now_ns;
                work_ns = (from_ns, realtime_ns());
            }
            continue;
        };
        let received = stamp(&trace);
        let is_ecat = len > ETH_HEADER_LEN && u16::from_be_bytes([buf[12], buf[13]]) == ETHERTYPE;
        // Masters differ in their source MAC (SOEM 01:.., KickCAT 02:..), so the returned bit
        // cannot tell requests from replies; the socket already skips what this server sent.
        if !is_ecat {
            // Other traffic on the wire must not hold commands back until it pauses.
            let from_ns = realtime_ns();
            bus.serve_commands();
            work_ns = (from_ns, realtime_ns());
            continue;
        }
        let now_ns = elapsed_ns(start);
        ran_ns = now_ns;
        let answered_ns = realtime_ns();
        if stats.serve(&mut bus, &mut buf[ETH_HEADER_LEN..len], now_ns) {
            buf[6] |= RETURNED_MAC_BIT;
            match socket.send(&buf[..len]) {
                Ok(()) => stats.served += 1,
                Err(Error::Io { source, .. }) if line_down(&source) => stats.unsent += 1,
                Err(e) => return Err(e),
            }
            stats.serving.count(realtime_ns().saturating_sub(answered_ns));
            if let (Some(late), Some(arrived_ns)) = (&mut stats.late, arrived_ns) {
                late.count(lateness_ns(arrived_ns, answered_ns, work_ns));
            }
            trace_frame(&mut trace, &bus, &buf[ETH_HEADER_LEN..len], received);
        }
        bus.run_ip_stacks(now_ns);
        work_ns = (answered_ns, realtime_ns());
    }
    Ok(stats)
}

/// How late a frame that arrived at `arrived_ns` was taken up, at `answered_ns`, less the
/// server's own work `work_ns` (from, to) done meanwhile.
fn lateness_ns(arrived_ns: u64, answered_ns: u64, (from_ns, to_ns): (u64, u64)) -> u64 {
    let own_ns = to_ns.saturating_sub(from_ns.max(arrived_ns));
    answered_ns.saturating_sub(arrived_ns).saturating_sub(own_ns)
}

/// Whether a send failed because the line is down: the interface's peer or carrier gone
/// (ENOBUFS from a socket that bypasses the queue, ENETDOWN), or the interface itself (ENXIO).
fn line_down(error: &std::io::Error) -> bool {
    matches!(error.raw_os_error(), Some(libc::ENOBUFS | libc::ENETDOWN | libc::ENXIO))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ethercat::frame::{Command, FrameBuilder};
    use crate::sim::control::Change;
    use crate::sim::VirtualBus;
    use std::sync::Arc;

    #[test]
    fn serves_udp_until_stopped() {
        let socket = bind_udp("127.0.0.1:0".parse().unwrap()).unwrap();
        let address = socket.local_addr().unwrap();
        let stop = Arc::new(AtomicBool::new(false));
        let flag = stop.clone();
        let server = std::thread::spawn(move || serve_udp_on(socket, VirtualBus::new(2), &flag, None));
        let client = UdpSocket::bind("127.0.0.1:0").unwrap();
        client.set_read_timeout(Some(Duration::from_millis(200))).unwrap();
        let mut buf = [0u8; 64];
        let mut b = FrameBuilder::new(&mut buf);
        let slot = b.push(Command::Brd, 7, 0, 0x0000, &[0, 0]).unwrap();
        let len = b.finish();
        let mut reply = [0u8; 64];
        let got = (0..20).find_map(|_| {
            client.send_to(&buf[..len], address).ok()?;
            client.recv(&mut reply).ok()
        });
        assert_eq!(got, Some(len));
        assert_eq!(slot.wkc(&reply[..len]).unwrap(), 2);
        assert_eq!(slot.data(&reply[..len]).unwrap(), &[0x04, 0x02]);
        client.send_to(&[0xFF, 0xFF, 0xFF], address).unwrap();
        stop.store(true, Ordering::Relaxed);
        let stats = server.join().unwrap().unwrap();
        assert!(stats.served >= 1);
    }

    #[test]
    fn takes_commands_with_and_without_frames() {
        let socket = bind_udp("127.0.0.1:0".parse().unwrap()).unwrap();
        let address = socket.local_addr().unwrap();
        let bus = ControlledBus::from(VirtualBus::new(1));
        let control = bus.control();
        let stop = Arc::new(AtomicBool::new(false));
        let flag = stop.clone();
        let server = std::thread::spawn(move || serve_udp_on(socket, bus, &flag, None));
        // No master: the server answers at its next wake-up.
        let idle = control.drive_state(0, Duration::from_secs(5)).unwrap();
        assert_eq!(idle.fault, None);
        control.change(Change::inject_fault(control.products(), 0, "F125")).unwrap();
        // The drive raises the fault when its firmware next runs, at a frame.
        let client = UdpSocket::bind("127.0.0.1:0").unwrap();
        let mut buf = [0u8; 64];
        let mut b = FrameBuilder::new(&mut buf);
        b.push(Command::Brd, 0, 0, 0x0130, &[0, 0]).unwrap();
        let len = b.finish();
        let deadline = Instant::now() + Duration::from_secs(5);
        while control.drive_state(0, Duration::from_secs(5)).unwrap().fault.is_none() {
            assert!(Instant::now() < deadline, "F125 not raised");
            client.send_to(&buf[..len], address).unwrap();
            std::thread::sleep(Duration::from_millis(1));
        }
        stop.store(true, Ordering::Relaxed);
        server.join().unwrap().unwrap();
        assert!(control
            .change(Change::hardware_enable(control.products(), 0, false))
            .unwrap_err()
            .to_string()
            .contains("gone"));
    }

    #[test]
    fn lateness_leaves_out_the_servers_own_work_after_the_arrival() {
        const MS: u64 = 1_000_000;
        // Waiting in its receive since before the frame came: all of it late.
        assert_eq!(lateness_ns(10 * MS, 15 * MS, (2 * MS, 3 * MS)), 5 * MS);
        // Busy with its own work when the frame came: only the rest.
        assert_eq!(lateness_ns(10 * MS, 15 * MS, (9 * MS, 12 * MS)), 3 * MS);
        // Its receive returned without the frame (a signal, the time-out) and it worked: the wait before is late.
        assert_eq!(lateness_ns(10 * MS, 15 * MS, (13 * MS, 14 * MS)), 4 * MS);
        let mut late = LateReplies::default();
        for us in [100, 250, 251, 4001, 3000] {
            late.count(us * 1000);
        }
        assert_eq!(late, LateReplies { over: [3, 2, 2, 2, 1], longest_us: 4001 });
    }

    #[test]
    fn names_a_missing_interface() {
        let err = open_iface("akd-no-such-if", false).unwrap_err();
        assert!(err.to_string().contains("akd-no-such-if"), "{err}");
    }
}
