//! The line's other slaves in the cycle thread: the devices beside the drives, configured from
//! what they say of themselves (an EK1100 coupler, an EL1004's inputs, an EL2004's outputs).
//! Each change of a device's inputs of one bit is an event of the cycle whose inputs show it
//! ([`Event::DeviceInputs`](crate::cycle::events::Event::DeviceInputs)), so that an edge is
//! published at once, not a period later, and none is lost between two publications; its
//! outputs are switched off in the process image where the loop decides it (a device lost or
//! back, the fault reaction that quick-stops the drives) and stay off until they are set again;
//! and its presence is judged as a drive's is, its recovery asked for the same way.
//!
//! The loop never waits for another thread: it clears a device's outputs in the image it sends
//! at once, and in the set-points (which the other threads write) as soon as it finds them free.

use std::sync::atomic::{AtomicBool, Ordering};

use super::recovery::Presence;
use super::seqlock::SeqBytes;
use crate::ethercat::device::Channel;
use crate::ethercat::master::cyclic::ImageSlot;
use crate::ethercat::pdo::{clear_bits, Direction};

/// The most input channels of one bit whose edges a device reports (one event word).
pub const WATCHED_INPUTS: usize = 64;

/// What the loop and the other threads share of one device.
#[derive(Debug, Default)]
pub struct DeviceShared {
    /// Asked of the loop: switch its outputs off.
    off: AtomicBool,
}

impl DeviceShared {
    /// Asks the loop to switch the device's outputs off (in the next cycle's image, and in the
    /// set-points so that they stay off until set again).
    pub fn request_off(&self) {
        self.off.store(true, Ordering::Release);
    }
}

/// One device as the loop runs it.
pub(super) struct DeviceLoop {
    /// Its position on the bus.
    pub(super) position: u16,
    /// Its outputs in the output image: first bit and bits.
    outputs: Option<(usize, usize)>,
    /// Its input channels of one bit: their bits in the input image.
    input_bits: Vec<usize>,
    /// Their levels in the last good cycle.
    last: Option<u64>,
    pub(super) presence: Presence,
    /// The mailbox counter the recovery left off at, for the master to go on from.
    pub(super) mailbox_counter: Option<u8>,
}

impl DeviceLoop {
    /// The device at `position`, at `slot` in the image (none without process data), with its
    /// `channels`.
    pub(super) fn new(position: u16, slot: Option<ImageSlot>, channels: &[Channel]) -> Self {
        let outputs = slot.filter(|s| s.out_bits > 0).map(|s| (s.out_start_bit(), s.out_bits));
        let input_bits = slot.map_or_else(Vec::new, |s| {
            channels
                .iter()
                .filter(|c| c.direction == Direction::Tx && c.is_bit())
                .take(WATCHED_INPUTS)
                .map(|c| s.in_start_bit() + c.bit)
                .collect()
        });
        DeviceLoop { position, outputs, input_bits, last: None, presence: Presence::default(), mailbox_counter: None }
    }

    /// After the set-points were copied into `outputs` (the whole output image): where its
    /// outputs were asked off, clears them there, and in `setpoints` when no other thread
    /// writes them (else the next cycle tries again).
    pub(super) fn apply_off(&self, shared: &DeviceShared, setpoints: &SeqBytes, outputs: &mut [u8]) {
        if !shared.off.load(Ordering::Acquire) {
            return;
        }
        let Some((start, bits)) = self.outputs else {
            shared.off.store(false, Ordering::Release);
            return;
        };
        clear_bits(outputs, start, bits);
        if let Some(mut w) = setpoints.try_write() {
            for n in (0..bits).step_by(64) {
                let chunk = (bits - n).min(64);
                w.write_bits(start + n, &[0; 8], chunk);
            }
            shared.off.store(false, Ordering::Release);
        }
    }

    /// This cycle's `inputs` (the whole input image): the levels of its input channels of one
    /// bit when they differ from the last good cycle's, else `None` (also on the first, which
    /// sets what the next ones are compared with).
    pub(super) fn observe_inputs(&mut self, inputs: &[u8]) -> Option<u64> {
        if self.input_bits.is_empty() {
            return None;
        }
        let levels = self
            .input_bits
            .iter()
            .enumerate()
            .fold(0u64, |levels, (n, &bit)| levels | u64::from(inputs[bit / 8] >> (bit % 8) & 1) << n);
        let last = self.last.replace(levels);
        (last.is_some() && last != Some(levels)).then_some(levels)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ethercat::coe::data_type;
    use crate::ethercat::pdo::PdoEntry;

    fn bit(direction: Direction, n: usize) -> Channel {
        Channel {
            name: format!("channel_{}", n + 1),
            direction,
            entry: PdoEntry::new(0x6000 + 0x10 * n as u16, 1, 1),
            pdo: 0x1A00 + n as u16,
            data_type: data_type::BOOLEAN,
            bit: n,
        }
    }

    #[test]
    fn an_edge_of_a_bit_input_is_seen_once_and_outputs_asked_off_stay_off() {
        let slot = ImageSlot {
            in_offset: 1,
            in_len: 1,
            in_bit: 4,
            in_bits: 4,
            out_bit: 4,
            out_bits: 4,
            out_len: 1,
            ..ImageSlot::default()
        };
        let channels: Vec<Channel> =
            (0..4).map(|n| bit(Direction::Tx, n)).chain((0..4).map(|n| bit(Direction::Rx, n))).collect();
        let mut device = DeviceLoop::new(3, Some(slot), &channels);
        let mut inputs = [0u8, 0x0F];
        assert_eq!(device.observe_inputs(&inputs), None, "the first cycle sets the reference");
        assert_eq!(device.observe_inputs(&inputs), None, "another device's bits are not this one's");
        inputs[1] |= 1 << 6;
        assert_eq!(device.observe_inputs(&inputs), Some(0b0100));
        assert_eq!(device.observe_inputs(&inputs), None);

        let shared = DeviceShared::default();
        let setpoints = SeqBytes::new(1, &[0xFF]);
        let mut outputs = [0xFFu8];
        device.apply_off(&shared, &setpoints, &mut outputs);
        assert_eq!(outputs, [0xFF], "nothing asked");
        shared.request_off();
        let busy = setpoints.write();
        device.apply_off(&shared, &setpoints, &mut outputs);
        assert_eq!(outputs, [0x0F], "off in the image at once");
        drop(busy);
        let mut held = [0u8];
        setpoints.read(&mut held);
        assert_eq!(held, [0xFF], "the set-points were being written: tried again next cycle");
        device.apply_off(&shared, &setpoints, &mut outputs);
        setpoints.read(&mut held);
        assert_eq!(held, [0x0F], "and off there too, the other device's bits kept");
        let mut again = [0xFFu8];
        device.apply_off(&shared, &setpoints, &mut again);
        assert_eq!(again, [0xFF], "done: nothing more to do");
    }
}
