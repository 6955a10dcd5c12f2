//! Lock-free exchange of fixed-size byte images between the cycle thread and other threads: a
//! sequence lock over atomic bytes.
//!
//! A writer makes the sequence number odd, writes, and makes it even again; a reader copies
//! the bytes and keeps the copy only if the sequence number was the same even value before and
//! after. The bytes are atomics (relaxed loads and stores compile to plain moves), so a copy
//! torn by a concurrent write is detected, never undefined behaviour. Writers exclude each
//! other by taking the odd sequence number with a compare-and-swap; the cycle thread never
//! waits on one: it reads with [`SeqBytes::try_read`], which gives up after a few attempts, and
//! it is the only writer of the buffers it writes. Nothing here allocates after construction.

use std::sync::atomic::{fence, AtomicU64, AtomicU8, Ordering};

/// How often [`SeqBytes::try_read`] tries before giving up on a buffer being written.
const TRY_READ_ATTEMPTS: u32 = 4;

/// A fixed-size byte image shared between threads under a sequence lock.
pub struct SeqBytes {
    sequence: AtomicU64,
    bytes: Box<[AtomicU8]>,
}

/// Write access to a [`SeqBytes`], holding its sequence number odd until dropped.
pub struct Writer<'a> {
    buffer: &'a SeqBytes,
    sequence: u64,
}

impl Writer<'_> {
    /// Writes `data` at `offset`. Panics when out of bounds: callers check ranges first.
    pub fn write(&mut self, offset: usize, data: &[u8]) {
        for (cell, &b) in self.buffer.bytes[offset..offset + data.len()].iter().zip(data) {
            cell.store(b, Ordering::Relaxed);
        }
    }
}

impl Writer<'_> {
    /// Writes `bits` bits of `data` (from its bit 0) from bit `at` of the buffer on, leaving
    /// the buffer's other bits: a slave packed in a byte beside others. Panics when out of
    /// bounds: callers check ranges first.
    pub fn write_bits(&mut self, at: usize, data: &[u8], bits: usize) {
        for n in 0..bits {
            let (cell, bit) = (&self.buffer.bytes[(at + n) / 8], (at + n) % 8);
            let value = data[n / 8] >> (n % 8) & 1;
            cell.store(cell.load(Ordering::Relaxed) & !(1 << bit) | value << bit, Ordering::Relaxed);
        }
    }
}

impl Drop for Writer<'_> {
    fn drop(&mut self) {
        self.buffer.sequence.store(self.sequence + 2, Ordering::Release);
    }
}

impl SeqBytes {
    /// A buffer of `len` bytes holding `initial` (zero-padded or cut to `len`).
    pub fn new(len: usize, initial: &[u8]) -> Self {
        let bytes = (0..len).map(|i| AtomicU8::new(initial.get(i).copied().unwrap_or(0))).collect();
        SeqBytes { sequence: AtomicU64::new(0), bytes }
    }

    /// The buffer's length in bytes.
    pub fn len(&self) -> usize {
        self.bytes.len()
    }

    /// Whether the buffer holds no bytes (clippy's pair to `len`).
    pub fn is_empty(&self) -> bool {
        self.bytes.is_empty()
    }

    /// Starts a write, waiting (spinning) for another writer to finish its own. Writers other
    /// than the cycle thread take microseconds, so the wait is as short.
    pub fn write(&self) -> Writer<'_> {
        loop {
            let sequence = self.sequence.load(Ordering::Relaxed);
            if sequence.is_multiple_of(2)
                && self
                    .sequence
                    .compare_exchange_weak(sequence, sequence + 1, Ordering::Acquire, Ordering::Relaxed)
                    .is_ok()
            {
                // The odd number is seen before any byte written after it.
                fence(Ordering::Release);
                return Writer { buffer: self, sequence };
            }
            std::hint::spin_loop();
        }
    }

    /// Starts a write unless another writer is under way (`None` then). For the cycle thread,
    /// which must not wait.
    pub fn try_write(&self) -> Option<Writer<'_>> {
        let sequence = self.sequence.load(Ordering::Relaxed);
        let taken = sequence.is_multiple_of(2)
            && self.sequence.compare_exchange(sequence, sequence + 1, Ordering::Acquire, Ordering::Relaxed).is_ok();
        taken.then(|| {
            fence(Ordering::Release);
            Writer { buffer: self, sequence }
        })
    }

    /// One attempt at a consistent copy into `out` (the buffer's length): the write count
    /// when it succeeded, `None` when a write was under way.
    fn read_once(&self, out: &mut [u8]) -> Option<u64> {
        let before = self.sequence.load(Ordering::Acquire);
        if !before.is_multiple_of(2) {
            return None;
        }
        for (o, cell) in out.iter_mut().zip(self.bytes.iter()) {
            *o = cell.load(Ordering::Relaxed);
        }
        // The byte loads are done before the sequence number is read again.
        fence(Ordering::Acquire);
        (self.sequence.load(Ordering::Relaxed) == before).then_some(before / 2)
    }

    /// A consistent copy into `out`, trying a few times; `None` when writers kept it busy (the
    /// caller keeps what it had). For the cycle thread, which must not wait.
    pub fn try_read(&self, out: &mut [u8]) -> Option<u64> {
        (0..TRY_READ_ATTEMPTS).find_map(|_| self.read_once(out))
    }

    /// A consistent copy into `out`, retrying until one succeeds; returns the write count.
    /// For readers other than the cycle thread: the only writer they can meet is quick.
    pub fn read(&self, out: &mut [u8]) -> u64 {
        loop {
            if let Some(writes) = self.read_once(out) {
                return writes;
            }
            std::hint::spin_loop();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::atomic::AtomicBool;
    use std::sync::Arc;

    #[test]
    fn write_then_read() {
        let b = SeqBytes::new(6, &[1, 2, 3]);
        let mut out = [0xFF; 6];
        assert_eq!(b.read(&mut out), 0);
        assert_eq!(out, [1, 2, 3, 0, 0, 0]);
        b.write().write(2, &[7, 8]);
        assert_eq!(b.try_read(&mut out), Some(1));
        assert_eq!(out, [1, 2, 7, 8, 0, 0]);
        b.write().write_bits(28, &[0b1010], 4);
        b.read(&mut out);
        assert_eq!(out, [1, 2, 7, 0b1010_1000, 0, 0], "bits 28-31 written, the others kept");
    }

    #[test]
    fn a_write_tried_during_another_is_refused() {
        let b = SeqBytes::new(2, &[]);
        let w = b.write();
        assert!(b.try_write().is_none());
        drop(w);
        b.try_write().unwrap().write(0, &[5, 6]);
        let mut out = [0; 2];
        assert_eq!(b.read(&mut out), 2);
        assert_eq!(out, [5, 6]);
    }

    #[test]
    fn a_read_during_a_write_is_refused() {
        let b = SeqBytes::new(4, &[]);
        let mut out = [0; 4];
        let mut w = b.write();
        w.write(0, &[9, 9, 9, 9]);
        assert_eq!(b.try_read(&mut out), None);
        drop(w);
        assert_eq!(b.try_read(&mut out), Some(1));
        assert_eq!(out, [9; 4]);
    }

    /// Writers fill the whole buffer with one value per write (each writer its own values); a
    /// reader racing them must only ever see a buffer of one value.
    #[test]
    fn concurrent_writers_and_a_reader_never_see_a_torn_image() {
        const LEN: usize = 1024;
        const WRITES: u64 = 20_000;
        let b = Arc::new(SeqBytes::new(LEN, &[]));
        let done = Arc::new(AtomicBool::new(false));
        let writers: Vec<_> = (0..2u8)
            .map(|id| {
                let b = b.clone();
                std::thread::spawn(move || {
                    let mut image = [0u8; LEN];
                    for n in 0..WRITES {
                        // The value names the writer and its write count (mod 127), so a torn
                        // copy mixes two values.
                        image.fill(((n % 127) as u8) * 2 + id);
                        b.write().write(0, &image);
                    }
                })
            })
            .collect();
        let reader = {
            let (b, done) = (b.clone(), done.clone());
            std::thread::spawn(move || {
                let mut out = [0u8; LEN];
                let mut consistent = 0u64;
                // Until the writers are done, and then until one copy is had: on a loaded host
                // the reader may not run at all while they write, which proves nothing either way.
                while !done.load(Ordering::Relaxed) || consistent == 0 {
                    if b.try_read(&mut out).is_some() {
                        assert!(out.iter().all(|&x| x == out[0]), "torn image: {:?}", &out[..16]);
                        consistent += 1;
                    }
                }
            })
        };
        for w in writers {
            w.join().unwrap();
        }
        done.store(true, Ordering::Relaxed);
        reader.join().unwrap();
        let mut out = [0u8; LEN];
        assert_eq!(b.read(&mut out), 2 * WRITES);
        assert!(out.iter().all(|&x| x == out[0]));
    }
}
