//! One record per cycle and sequenced drive — what the drive reported and what it was sent —
//! through a [`Ring`], for recording every cycle from a thread that cannot keep up with the
//! cycle one by one but can take them in batches.

use crate::cycle::ring::Ring;

/// Records the ring holds per drive: at 4 kHz, two seconds.
pub const CAPACITY: usize = 8192;
const WORDS: usize = 8;

/// One drive in one cycle, in drive units (counts, counts/s, 0.1 % of peak torque).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Sample {
    /// The cycle (from 1).
    pub cycle: u64,
    /// Its wake-up time (ns, monotonic).
    pub time_ns: u64,
    /// The slave's position on the bus.
    pub slave: u16,
    /// Time since the previous wake-up (ns; 0 for the first cycle).
    pub period_ns: u32,
    /// How long the exchange took (ns).
    pub exchange_ns: u32,
    /// The cyclic working counter (0 when the frame was lost).
    pub wkc: u16,
    /// Whether this cycle's exchange succeeded (else the actual values are the last good ones).
    pub fresh: bool,
    /// Whether this cycle's exchange was lost: a frame of it did not come back (counted in
    /// `lost_frames`) or its return could not be read (`other_errors`). A cycle neither fresh nor
    /// lost came back with a wrong working counter (`wkc_errors`), which may be 0 too: the
    /// working counter alone does not tell a lost frame from one no slave took.
    pub lost: bool,
    /// The statusword.
    pub statusword: u16,
    /// Modes of operation display 0x6061 (0 where not mapped).
    pub mode: i8,
    /// Actual position (0x6064 or 0x6063).
    pub position: i32,
    /// Actual velocity 0x606C (0 where not mapped).
    pub velocity: i32,
    /// Actual torque 0x6077 (0 where not mapped).
    pub torque: i16,
    /// Following error 0x60F4 (0 where not mapped).
    pub following_error: i32,
    /// The position target as sent (0x607A or 0x60C1:01; 0 where not mapped).
    pub target_position: i32,
    /// The velocity target as sent (0x60FF; 0 where not mapped).
    pub target_velocity: i32,
    /// The torque target as sent (0x6071; 0 where not mapped).
    pub target_torque: i16,
}

impl Sample {
    fn encode(&self) -> [u64; WORDS] {
        let lo_hi = |lo: u32, hi: u32| lo as u64 | (hi as u64) << 32;
        [
            self.cycle,
            self.time_ns,
            lo_hi(self.period_ns, self.exchange_ns),
            self.statusword as u64
                | (self.wkc as u64) << 16
                | (self.mode as u8 as u64) << 32
                | (self.slave as u64) << 40
                | (self.fresh as u64) << 56
                | (self.lost as u64) << 57,
            lo_hi(self.position as u32, self.velocity as u32),
            lo_hi(self.torque as u16 as u32, self.following_error as u32),
            lo_hi(self.target_position as u32, self.target_velocity as u32),
            self.target_torque as u16 as u64,
        ]
    }

    fn decode(w: [u64; WORDS]) -> Sample {
        Sample {
            cycle: w[0],
            time_ns: w[1],
            period_ns: w[2] as u32,
            exchange_ns: (w[2] >> 32) as u32,
            statusword: w[3] as u16,
            wkc: (w[3] >> 16) as u16,
            mode: (w[3] >> 32) as u8 as i8,
            slave: (w[3] >> 40) as u16,
            fresh: (w[3] >> 56) & 1 == 1,
            lost: (w[3] >> 57) & 1 == 1,
            position: w[4] as u32 as i32,
            velocity: (w[4] >> 32) as u32 as i32,
            torque: w[5] as u16 as i16,
            following_error: (w[5] >> 32) as u32 as i32,
            target_position: w[6] as u32 as i32,
            target_velocity: (w[6] >> 32) as u32 as i32,
            target_torque: w[7] as u16 as i16,
        }
    }
}

/// The records nobody has taken yet.
pub struct Samples {
    ring: Ring<WORDS>,
}

impl Samples {
    /// A ring of [`CAPACITY`] records for each of `drives` drives (at least one), so a bus of many drives keeps as
    /// many seconds as a bus of one.
    pub fn for_drives(drives: usize) -> Self {
        Samples { ring: Ring::new(CAPACITY * drives.max(1)) }
    }

    /// Adds `sample` (the cycle thread only); counts it as dropped when the ring is full.
    pub fn push(&self, sample: &Sample) {
        self.ring.push(sample.encode());
    }

    /// Takes every record pushed since the last call, oldest first.
    pub fn drain(&self) -> Vec<Sample> {
        self.ring.drain(|w| Some(Sample::decode(w)))
    }

    /// Records dropped because the ring was full.
    pub fn dropped(&self) -> u64 {
        self.ring.dropped()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn samples_round_trip_every_field_and_a_full_ring_drops() {
        let sample = Sample {
            cycle: 9,
            time_ns: 1 << 40,
            slave: 3,
            period_ns: 1_000_123,
            exchange_ns: 4567,
            wkc: 3,
            fresh: true,
            lost: true,
            statusword: 0x1637,
            mode: -1,
            position: -5,
            velocity: -1_000_000,
            torque: -300,
            following_error: -12,
            target_position: i32::MIN,
            target_velocity: i32::MAX,
            target_torque: i16::MIN,
        };
        let samples = Samples::for_drives(1);
        samples.push(&sample);
        assert_eq!(samples.drain(), [sample]);
        for _ in 0..CAPACITY + 2 {
            samples.push(&sample);
        }
        assert_eq!((samples.drain().len(), samples.dropped()), (CAPACITY, 2));
    }
}
