//! Taking a datagram from a socket without waiting, or by an exact deadline: ppoll(2) waits to
//! the nanosecond, where a read time-out (SO_RCVTIMEO) counts in scheduler ticks, up to 4 ms, so
//! that a lost frame costs a cycle one period and not several; a deadline already past still
//! takes what is there.

use std::io;
use std::os::fd::{AsRawFd, BorrowedFd};
use std::time::{Duration, Instant};

/// Takes a datagram that is already there into `buf`, without waiting: its length, or `None`
/// when there is none (or a signal came first). One recv(2).
pub fn recv_now(fd: BorrowedFd<'_>, buf: &mut [u8]) -> io::Result<Option<usize>> {
    // SAFETY: `buf` is valid for the length passed.
    let got =
        unsafe { libc::recv(fd.as_raw_fd(), buf.as_mut_ptr() as *mut libc::c_void, buf.len(), libc::MSG_DONTWAIT) };
    received(got)
}

/// Waits until `deadline` for a datagram and takes it into `buf`; `None` when none came. One
/// ppoll(2) and one recv(2) per datagram.
pub fn recv_until(fd: BorrowedFd<'_>, buf: &mut [u8], deadline: Instant) -> io::Result<Option<usize>> {
    loop {
        if !wait_readable(fd, deadline.saturating_duration_since(Instant::now()))? {
            return Ok(None);
        }
        if let Some(got) = recv_now(fd, buf)? {
            return Ok(Some(got));
        }
    }
}

/// What a receive call's result `got` says: a datagram's length, or `None` for nothing there
/// (none waiting, a read time-out passed, a signal).
pub fn received(got: isize) -> io::Result<Option<usize>> {
    if got >= 0 {
        return Ok(Some(got as usize));
    }
    let err = io::Error::last_os_error();
    if matches!(err.kind(), io::ErrorKind::WouldBlock | io::ErrorKind::Interrupted) {
        return Ok(None);
    }
    Err(err)
}

/// Waits until a datagram can be read or `timeout` passes; `false` on time-out.
fn wait_readable(fd: BorrowedFd<'_>, timeout: Duration) -> io::Result<bool> {
    let mut poll = libc::pollfd { fd: fd.as_raw_fd(), events: libc::POLLIN, revents: 0 };
    let spec = libc::timespec { tv_sec: timeout.as_secs() as libc::time_t, tv_nsec: timeout.subsec_nanos() as _ };
    // SAFETY: one valid pollfd, a valid timespec, no signal mask.
    let rc = unsafe { libc::ppoll(&mut poll, 1, &spec, std::ptr::null()) };
    if rc < 0 {
        let err = io::Error::last_os_error();
        if err.kind() == io::ErrorKind::Interrupted {
            return Ok(true);
        }
        return Err(err);
    }
    Ok(rc > 0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::net::UdpSocket;
    use std::os::fd::AsFd;

    #[test]
    fn a_deadline_already_past_still_takes_what_is_there() {
        let a = UdpSocket::bind("127.0.0.1:0").unwrap();
        let b = UdpSocket::bind("127.0.0.1:0").unwrap();
        b.connect(a.local_addr().unwrap()).unwrap();
        let mut buf = [0u8; 8];
        assert_eq!(recv_until(a.as_fd(), &mut buf, Instant::now()).unwrap(), None);
        b.send(&[7, 8, 9]).unwrap();
        // Long enough for loopback to deliver it; then taken though its deadline has passed.
        std::thread::sleep(Duration::from_millis(50));
        let past = Instant::now() - Duration::from_millis(10);
        assert_eq!(recv_until(a.as_fd(), &mut buf, past).unwrap(), Some(3));
        assert_eq!(&buf[..3], &[7, 8, 9]);
        assert_eq!(recv_now(a.as_fd(), &mut buf).unwrap(), None);
    }
}
