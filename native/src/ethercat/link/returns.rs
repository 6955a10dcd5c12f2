//! The returns of frames a link served at once (the in-process virtual AKDs, a test's link),
//! waiting to be received in the order they were sent, as on a line.

use crate::error::Result;
use crate::ethercat::frame::MAX_PAYLOAD_LEN;
use crate::ethercat::link::copy_reply;

/// Frames that may wait at once: a cyclic frame on its way back, the mailbox frame sent beside
/// it, and room to spare. A return beyond them pushes out the oldest, as a full socket drops.
const WAITING: usize = 4;

/// Returned frames, first in first out, in buffers allocated once (the cycle never allocates).
pub struct Returns {
    frames: Box<[[u8; MAX_PAYLOAD_LEN]; WAITING]>,
    lens: [usize; WAITING],
    first: usize,
    count: usize,
}

impl Default for Returns {
    fn default() -> Self {
        Returns { frames: Box::new([[0; MAX_PAYLOAD_LEN]; WAITING]), lens: [0; WAITING], first: 0, count: 0 }
    }
}

impl Returns {
    /// Copies `tx` into the next buffer and lets `serve` turn it into its return there:
    /// `serve` gets the frame and says whether it came back (a frame lost on the line does not).
    /// A frame larger than a buffer is an error, not a truncated frame.
    pub fn serve(&mut self, tx: &[u8], serve: impl FnOnce(&mut [u8]) -> Result<bool>) -> Result<()> {
        if self.count == WAITING {
            self.first = (self.first + 1) % WAITING;
            self.count -= 1;
        }
        let at = (self.first + self.count) % WAITING;
        let len = copy_reply(tx, &mut self.frames[at])?;
        if serve(&mut self.frames[at][..len])? {
            self.lens[at] = len;
            self.count += 1;
        }
        Ok(())
    }

    /// The oldest return, copied to `rx`; `None` when none waits.
    pub fn take(&mut self, rx: &mut [u8]) -> Result<Option<usize>> {
        if self.count == 0 {
            return Ok(None);
        }
        let at = self.first;
        self.first = (self.first + 1) % WAITING;
        self.count -= 1;
        copy_reply(&self.frames[at][..self.lens[at]], rx).map(Some)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn returns_come_out_in_the_order_sent_and_lost_ones_not_at_all() {
        let mut returns = Returns::default();
        returns.serve(&[1, 2], |f| Ok(f[0] == 1)).unwrap();
        returns.serve(&[9], |_| Ok(false)).unwrap();
        returns
            .serve(&[3], |f| {
                f[0] += 1;
                Ok(true)
            })
            .unwrap();
        let mut rx = [0u8; 8];
        assert_eq!(returns.take(&mut rx).unwrap(), Some(2));
        assert_eq!(&rx[..2], &[1, 2]);
        assert_eq!(returns.take(&mut rx).unwrap(), Some(1));
        assert_eq!(rx[0], 4);
        assert_eq!(returns.take(&mut rx).unwrap(), None);
    }

    #[test]
    fn a_full_queue_drops_its_oldest_return() {
        let mut returns = Returns::default();
        for n in 0..=WAITING as u8 {
            returns.serve(&[n], |_| Ok(true)).unwrap();
        }
        let mut rx = [0u8; 1];
        let taken: Vec<u8> = std::iter::from_fn(|| returns.take(&mut rx).unwrap().map(|_| rx[0])).collect();
        assert_eq!(taken, (1..=WAITING as u8).collect::<Vec<_>>());
    }

    #[test]
    fn a_return_too_large_for_the_callers_buffer_is_an_error() {
        let mut returns = Returns::default();
        returns.serve(&[0; 16], |_| Ok(true)).unwrap();
        assert!(returns.take(&mut [0u8; 8]).is_err());
    }
}
