//! Ethernet frames between other threads and the cycle thread, which carries them to and from
//! the drives' IP stacks through EoE beside the process data: a ring each way of fixed cells
//! allocated before the cycle, filled and emptied with atomics, so the cycle thread neither
//! allocates nor waits. The other threads take turns on their side through a lock the cycle
//! thread never takes. A frame that finds its ring full is dropped and counted, as a switch
//! drops what it cannot queue.

use std::sync::atomic::{AtomicU16, AtomicU64, AtomicU8, AtomicUsize, Ordering};
use std::sync::Mutex;
use std::time::{Duration, Instant};

use crate::ethercat::eoe::MAX_FRAME_LEN;

/// Frames each ring holds.
pub const RING_LEN: usize = 16;

struct Cell {
    slave: AtomicU16,
    len: AtomicU16,
    data: Box<[AtomicU8]>,
}

/// One ring: one producer and one consumer at a time.
struct Ring {
    cells: Box<[Cell]>,
    /// Frames pushed (the producer's).
    head: AtomicUsize,
    /// Frames popped (the consumer's).
    tail: AtomicUsize,
    dropped: AtomicU64,
}

impl Default for Ring {
    fn default() -> Self {
        let cell = || Cell {
            slave: AtomicU16::new(0),
            len: AtomicU16::new(0),
            data: (0..MAX_FRAME_LEN).map(|_| AtomicU8::new(0)).collect(),
        };
        Ring {
            cells: (0..RING_LEN).map(|_| cell()).collect(),
            head: AtomicUsize::new(0),
            tail: AtomicUsize::new(0),
            dropped: AtomicU64::new(0),
        }
    }
}

impl Ring {
    /// Adds a frame; `false` (and counted) when the ring is full.
    fn push(&self, slave: u16, frame: &[u8]) -> bool {
        let head = self.head.load(Ordering::Relaxed);
        if head - self.tail.load(Ordering::Acquire) == RING_LEN {
            self.dropped.fetch_add(1, Ordering::Relaxed);
            return false;
        }
        let cell = &self.cells[head % RING_LEN];
        for (c, b) in cell.data.iter().zip(frame) {
            c.store(*b, Ordering::Relaxed);
        }
        cell.slave.store(slave, Ordering::Relaxed);
        cell.len.store(frame.len().min(MAX_FRAME_LEN) as u16, Ordering::Relaxed);
        self.head.store(head + 1, Ordering::Release);
        true
    }

    /// Takes the oldest frame into `out` (at least [`MAX_FRAME_LEN`] bytes): its slave and
    /// length.
    fn pop(&self, out: &mut [u8]) -> Option<(u16, usize)> {
        let tail = self.tail.load(Ordering::Relaxed);
        if tail == self.head.load(Ordering::Acquire) {
            return None;
        }
        let cell = &self.cells[tail % RING_LEN];
        let len = cell.len.load(Ordering::Relaxed) as usize;
        for (o, c) in out.iter_mut().zip(&cell.data[..len]) {
            *o = c.load(Ordering::Relaxed);
        }
        let slave = cell.slave.load(Ordering::Relaxed);
        self.tail.store(tail + 1, Ordering::Release);
        Some((slave, len))
    }
}

/// Both rings and the turns of the threads on the other side.
#[derive(Default)]
pub struct EoeFrames {
    to_drives: Ring,
    from_drives: Ring,
    senders: Mutex<()>,
    receivers: Mutex<()>,
}

impl EoeFrames {
    /// Queues `frame` for the drive at `slave`; `false` when the ring was full (the frame is
    /// dropped and counted).
    pub fn send(&self, slave: u16, frame: &[u8]) -> bool {
        let _turn = self.senders.lock().unwrap_or_else(|p| p.into_inner());
        self.to_drives.push(slave, frame)
    }

    /// The next frame a drive sent, waiting up to `timeout` (polling every 200 µs): its slave
    /// and the frame.
    pub fn receive(&self, timeout: Duration) -> Option<(u16, Vec<u8>)> {
        let _turn = self.receivers.lock().unwrap_or_else(|p| p.into_inner());
        let deadline = Instant::now() + timeout;
        let mut frame = vec![0u8; MAX_FRAME_LEN];
        loop {
            if let Some((slave, len)) = self.from_drives.pop(&mut frame) {
                frame.truncate(len);
                return Some((slave, frame));
            }
            if Instant::now() >= deadline {
                return None;
            }
            std::thread::sleep(Duration::from_micros(200));
        }
    }

    /// Frames dropped because a ring was full: (to the drives, from the drives).
    pub fn dropped(&self) -> (u64, u64) {
        (self.to_drives.dropped.load(Ordering::Relaxed), self.from_drives.dropped.load(Ordering::Relaxed))
    }

    /// The cycle thread's side: the next frame for a drive, into `out`.
    pub(crate) fn next_to_drive(&self, out: &mut [u8]) -> Option<(u16, usize)> {
        self.to_drives.pop(out)
    }

    /// The cycle thread's side: a frame a drive sent.
    pub(crate) fn drive_sent(&self, slave: u16, frame: &[u8]) {
        self.from_drives.push(slave, frame);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frames_go_through_in_order_and_a_full_ring_drops_and_counts() {
        let frames = EoeFrames::default();
        for n in 0..RING_LEN as u8 {
            assert!(frames.send(u16::from(n % 3), &[n; 60]));
        }
        assert!(!frames.send(0, &[0xFF; 60]));
        assert_eq!(frames.dropped(), (1, 0));
        let mut out = [0u8; MAX_FRAME_LEN];
        for n in 0..RING_LEN as u8 {
            assert_eq!(frames.next_to_drive(&mut out), Some((u16::from(n % 3), 60)));
            assert_eq!(out[..60], [n; 60]);
        }
        assert_eq!(frames.next_to_drive(&mut out), None);
        frames.drive_sent(2, &[7; MAX_FRAME_LEN]);
        assert_eq!(frames.receive(Duration::ZERO), Some((2, vec![7; MAX_FRAME_LEN])));
        assert_eq!(frames.receive(Duration::from_millis(1)), None);
    }
}
