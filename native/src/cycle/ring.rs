//! A lock-free single-producer ring of fixed-size records of `W` words, the way the cycle
//! thread hands out what it saw (events, per-cycle samples) without ever waiting.
//!
//! The producer writes a record's words into a slot before the head moves past it; a reader
//! copies the slots between its tail and the head. A full ring drops the new record and counts
//! it. Readers are serialised by their own lock, which the producer never takes.

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Mutex;

/// The ring.
pub struct Ring<const W: usize> {
    slots: Box<[[AtomicU64; W]]>,
    head: AtomicU64,
    tail: AtomicU64,
    dropped: AtomicU64,
    readers: Mutex<()>,
}

impl<const W: usize> Ring<W> {
    /// A ring of `capacity` records, allocated here and never again.
    pub fn new(capacity: usize) -> Self {
        Ring {
            slots: (0..capacity).map(|_| std::array::from_fn(|_| AtomicU64::new(0))).collect(),
            head: AtomicU64::new(0),
            tail: AtomicU64::new(0),
            dropped: AtomicU64::new(0),
            readers: Mutex::new(()),
        }
    }

    /// Adds a record (the producer only); counts it as dropped when the ring is full.
    pub fn push(&self, words: [u64; W]) {
        let head = self.head.load(Ordering::Relaxed);
        if head - self.tail.load(Ordering::Acquire) >= self.slots.len() as u64 {
            self.dropped.fetch_add(1, Ordering::Relaxed);
            return;
        }
        for (cell, word) in self.slots[head as usize % self.slots.len()].iter().zip(words) {
            cell.store(word, Ordering::Relaxed);
        }
        self.head.store(head + 1, Ordering::Release);
    }

    /// Takes every record pushed since the last call, oldest first, through `decode`.
    pub fn drain<T>(&self, decode: impl Fn([u64; W]) -> Option<T>) -> Vec<T> {
        let _reader = self.readers.lock().unwrap_or_else(|poisoned| poisoned.into_inner());
        let tail = self.tail.load(Ordering::Relaxed);
        let head = self.head.load(Ordering::Acquire);
        let records = (tail..head)
            .filter_map(|n| {
                decode(self.slots[n as usize % self.slots.len()].each_ref().map(|c| c.load(Ordering::Relaxed)))
            })
            .collect();
        self.tail.store(head, Ordering::Release);
        records
    }

    /// Records pushed so far (dropped ones not counted).
    pub fn pushed(&self) -> u64 {
        self.head.load(Ordering::Acquire)
    }

    /// Whether a record waits to be taken.
    pub fn pending(&self) -> bool {
        self.head.load(Ordering::Acquire) != self.tail.load(Ordering::Acquire)
    }

    /// Records dropped because the ring was full.
    pub fn dropped(&self) -> u64 {
        self.dropped.load(Ordering::Relaxed)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn records_come_out_in_order_once_and_a_full_ring_drops_and_counts() {
        let ring = Ring::<2>::new(4);
        ring.push([1, 2]);
        ring.push([3, 4]);
        assert_eq!(ring.drain(Some), [[1, 2], [3, 4]]);
        assert!(ring.drain(Some).is_empty());
        for n in 0..6 {
            ring.push([n, n]);
        }
        assert_eq!(ring.dropped(), 2);
        assert_eq!(ring.drain(|w| Some(w[0])), [0, 1, 2, 3]);
    }
}
