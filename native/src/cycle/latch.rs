//! The master side of the AKD's position latch, run by the cycle thread for each drive whose
//! mapping carries it: arming through latch control 0x20A4, captures seen in the valid bits of
//! latch status 0x20A5, positions read from 0x20A0–0x20A3 where mapped or else through the
//! multiplexed 0x20A6/0x20A7 (select in 0x20A4 bits 8–12, acknowledged in 0x20A5 bits 8–11).
//! The CiA 402 touch probe (function 0x60B8, status 0x60B9, positions 0x60BA–0x60BD) is used
//! the same way where the mapping carries it instead.
//!
//! Every capture becomes one event, after which the edge is re-armed (its bit low for a cycle,
//! then high, which clears the valid bit), so an armed edge keeps reporting. An edge that
//! comes again before the drive saw the re-arming is not captured: the drive holds one value
//! per edge.
//!
//! Edges are numbered as the AKD numbers its arming bits: 0 latch 1 rising, 1 latch 1 falling,
//! 2 latch 2 rising, 3 latch 2 falling.

use std::sync::atomic::{AtomicU8, Ordering};

use crate::cycle::events::Edge;
use crate::cycle::image::{i32_at, u16_at};
use crate::ethercat::pdo::{self, PdoEntry};

/// The four edges' bits.
pub const ALL_EDGES: u8 = 0x0F;

/// The bit of `channel` (1 or 2) and `edge`.
pub fn edge_bit(channel: u8, edge: Edge) -> u8 {
    1 << ((channel - 1) * 2 + (edge == Edge::Falling) as u8)
}

/// Where a drive's latch objects are in its process data (offsets in the whole images).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LatchObjects {
    /// The AKD's own latch.
    Akd {
        /// Latch control 0x20A4 in the outputs.
        control: usize,
        /// Latch status 0x20A5 in the inputs.
        status: usize,
        /// 0x20A0..0x20A3 in the inputs, per edge, where mapped.
        direct: [Option<usize>; 4],
        /// 0x20A6 (latch 1) and 0x20A7 (latch 2) in the inputs, where mapped.
        multiplexed: [Option<usize>; 2],
    },
    /// The CiA 402 touch probe.
    TouchProbe {
        /// Function 0x60B8 in the outputs.
        function: usize,
        /// Status 0x60B9 in the inputs.
        status: usize,
        /// 0x60BA..0x60BD in the inputs, per edge, where mapped.
        positions: [Option<usize>; 4],
    },
}

impl LatchObjects {
    /// Finds the latch objects in a drive's mapping, offsets moved by `out_base`/`in_base`;
    /// `None` when it carries neither the AKD's latch nor a touch probe with a position.
    pub fn find(rx: &[PdoEntry], tx: &[PdoEntry], out_base: usize, in_base: usize) -> Option<LatchObjects> {
        let at = |entries: &[PdoEntry], base: usize, index: u16| pdo::find(entries, index, 0).map(|(o, _)| base + o);
        let input = |index| at(tx, in_base, index);
        if let (Some(control), Some(status)) = (at(rx, out_base, 0x20A4), input(0x20A5)) {
            let direct = std::array::from_fn(|b| input(0x20A0 + b as u16));
            let multiplexed = [input(0x20A6), input(0x20A7)];
            if direct.iter().chain(&multiplexed).any(Option::is_some) {
                return Some(LatchObjects::Akd { control, status, direct, multiplexed });
            }
        }
        if let (Some(function), Some(status)) = (at(rx, out_base, 0x60B8), input(0x60B9)) {
            let positions: [Option<usize>; 4] = std::array::from_fn(|b| input(0x60BA + b as u16));
            if positions.iter().any(Option::is_some) {
                return Some(LatchObjects::TouchProbe { function, status, positions });
            }
        }
        None
    }

    /// The edges whose position can be read.
    pub fn readable(&self) -> u8 {
        let bits = |have: [bool; 4]| (0..4).filter(|&b| have[b]).fold(0u8, |m, b| m | 1 << b);
        match self {
            LatchObjects::Akd { direct, multiplexed, .. } => {
                bits(std::array::from_fn(|b| direct[b].is_some() || multiplexed[b / 2].is_some()))
            }
            LatchObjects::TouchProbe { positions, .. } => bits(positions.map(|p| p.is_some())),
        }
    }
}

/// What other threads share with a drive's latch: the edges asked for.
#[derive(Default)]
pub struct LatchShared {
    armed: AtomicU8,
}

impl LatchShared {
    /// Arms (or disarms) the edges in `bits`.
    pub fn set(&self, bits: u8, arm: bool) {
        if arm {
            self.armed.fetch_or(bits & ALL_EDGES, Ordering::AcqRel);
        } else {
            self.armed.fetch_and(!bits, Ordering::AcqRel);
        }
    }

    /// The edges armed.
    pub fn armed(&self) -> u8 {
        self.armed.load(Ordering::Acquire)
    }
}

/// One drive's latch as the cycle thread runs it.
#[derive(Clone, Copy, Debug)]
pub struct Latch {
    objects: LatchObjects,
    armed: u8,
    /// Edges reported and not yet seen invalid again; their bit goes out low once.
    reported: u8,
    /// Edges whose bit goes out low this cycle.
    rearming: u8,
    /// The value selected for 0x20A6/0x20A7 (1..=4), 0 for none.
    select: u8,
}

impl Latch {
    /// A latch on `objects`, nothing armed.
    pub fn new(objects: LatchObjects) -> Self {
        Latch { objects, armed: 0, reported: 0, rearming: 0, select: 0 }
    }

    /// The valid bits, in edge order, from the inputs.
    fn valid(&self, inputs: &[u8]) -> u8 {
        match self.objects {
            LatchObjects::Akd { status, .. } => u16_at(inputs, status) as u8 & ALL_EDGES,
            LatchObjects::TouchProbe { status, .. } => {
                let s = u16_at(inputs, status);
                ((s >> 1) & 0x3 | ((s >> 9) & 0x3) << 2) as u8
            }
        }
    }

    /// The position of `edge`'s capture if it can be read from these inputs now; may select
    /// it for a later cycle instead.
    fn position(&mut self, edge: usize, inputs: &[u8]) -> Option<i32> {
        match self.objects {
            LatchObjects::TouchProbe { positions, .. } => positions[edge].map(|at| i32_at(inputs, at)),
            LatchObjects::Akd { direct, multiplexed, status, .. } => {
                if let Some(at) = direct[edge] {
                    return Some(i32_at(inputs, at));
                }
                let at = multiplexed[edge / 2]?;
                let wanted = edge as u8 + 1;
                self.select = wanted;
                (((u16_at(inputs, status) >> 8) & 0x0F) as u8 == wanted).then(|| i32_at(inputs, at))
            }
        }
    }

    /// The first half of a cycle: takes the armed edges from `shared` and calls `capture` with
    /// (channel, edge, position) for each capture seen in `inputs`.
    pub fn observe(&mut self, shared: &LatchShared, inputs: &[u8], mut capture: impl FnMut(u8, Edge, i32)) {
        self.armed = shared.armed() & self.objects.readable();
        let valid = self.valid(inputs);
        // An edge reported goes out low for the next cycle only, and is not reported again
        // until the drive shows it invalid (re-armed).
        self.rearming = 0;
        self.reported &= valid;
        let new = valid & self.armed & !self.reported;
        // One multiplexed read at a time: the first new edge in order.
        for edge in 0..4 {
            if new & (1 << edge) == 0 {
                continue;
            }
            let Some(position) = self.position(edge, inputs) else { break };
            let (channel, falling) = (edge as u8 / 2 + 1, edge % 2 == 1);
            capture(channel, if falling { Edge::Falling } else { Edge::Rising }, position);
            self.reported |= 1 << edge;
            self.rearming |= 1 << edge;
        }
    }

    /// The second half: writes the latch control (or touch probe function) into `outputs`.
    pub fn apply(&self, outputs: &mut [u8]) {
        let arm = self.armed & !self.rearming;
        let (at, word) = match self.objects {
            LatchObjects::Akd { control, .. } => (control, arm as u16 | (self.select as u16) << 8),
            LatchObjects::TouchProbe { function, .. } => {
                let bit = |b: u8| (arm >> b & 1) as u16;
                let probe1 = (arm & 0x3 != 0) as u16 | bit(0) << 4 | bit(1) << 5;
                let probe2 = ((arm & 0xC != 0) as u16) << 8 | bit(2) << 12 | bit(3) << 13;
                (function, probe1 | probe2)
            }
        };
        outputs[at..at + 2].copy_from_slice(&word.to_le_bytes());
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const RX: &[PdoEntry] = &[PdoEntry::new(0x6040, 0, 16), PdoEntry::new(0x20A4, 0, 16)];

    #[test]
    fn finds_the_akd_latch_or_the_touch_probe_or_nothing() {
        let tx = [PdoEntry::new(0x6041, 0, 16), PdoEntry::new(0x20A5, 0, 16), PdoEntry::new(0x20A6, 0, 32)];
        let found = LatchObjects::find(RX, &tx, 10, 20).unwrap();
        assert_eq!(
            found,
            LatchObjects::Akd { control: 12, status: 22, direct: [None; 4], multiplexed: [Some(24), None] }
        );
        assert_eq!(found.readable(), 0b0011);
        assert_eq!(LatchObjects::find(RX, &tx[..2], 0, 0), None, "no position mapped");
        let rx = [PdoEntry::new(0x60B8, 0, 16)];
        let tx = [PdoEntry::new(0x60B9, 0, 16), PdoEntry::new(0x60BC, 0, 32)];
        let probe = LatchObjects::find(&rx, &tx, 0, 0).unwrap();
        assert_eq!(probe.readable(), 0b0100);
    }

    /// The drive's side, as the AKD does it: a rising arming bit clears valid, an armed edge
    /// captures once; 0x20A6 shows the selected value.
    struct FakeAkd {
        control: u16,
        valid: u8,
        values: [i32; 4],
    }

    impl FakeAkd {
        fn outputs(&mut self, control: u16) {
            self.valid &= !((control & !self.control) as u8 & 0x0F);
            self.control = control;
        }

        fn edge(&mut self, edge: usize, position: i32) {
            if self.control & (1 << edge) != 0 && self.valid & (1 << edge) == 0 {
                self.valid |= 1 << edge;
                self.values[edge] = position;
            }
        }

        fn inputs(&self) -> [u8; 6] {
            let select = (self.control >> 8) & 0x1F;
            let shown = if select == 2 { self.values[1] } else { self.values[0] };
            let status = self.valid as u16 | (select.min(4)) << 8;
            let mut i = [0u8; 6];
            i[0..2].copy_from_slice(&status.to_le_bytes());
            i[2..6].copy_from_slice(&shown.to_le_bytes());
            i
        }
    }

    #[test]
    fn every_capture_is_one_event_and_the_edge_rearms() {
        let objects = LatchObjects::Akd { control: 0, status: 0, direct: [None; 4], multiplexed: [Some(2), None] };
        let mut latch = Latch::new(objects);
        let shared = LatchShared::default();
        shared.set(edge_bit(1, Edge::Rising) | edge_bit(1, Edge::Falling), true);
        let mut drive = FakeAkd { control: 0, valid: 0, values: [0; 4] };
        let mut events = Vec::new();
        let mut outputs = [0u8; 2];
        let mut cycle = |drive: &mut FakeAkd, events: &mut Vec<(u8, Edge, i32)>| {
            latch.observe(&shared, &drive.inputs(), |c, e, p| events.push((c, e, p)));
            latch.apply(&mut outputs);
            drive.outputs(u16::from_le_bytes(outputs));
        };
        cycle(&mut drive, &mut events);
        assert_eq!(drive.control & 0x0F, 0x03, "both edges of latch 1 armed");
        drive.edge(0, 1000);
        drive.edge(1, 2000);
        for _ in 0..8 {
            cycle(&mut drive, &mut events);
        }
        assert_eq!(events, [(1, Edge::Rising, 1000), (1, Edge::Falling, 2000)]);
        assert_eq!(drive.valid, 0, "both re-armed");
        drive.edge(0, 3000);
        for _ in 0..8 {
            cycle(&mut drive, &mut events);
        }
        assert_eq!(events.last(), Some(&(1, Edge::Rising, 3000)));
        assert_eq!(events.len(), 3);
        shared.set(ALL_EDGES, false);
        cycle(&mut drive, &mut events);
        assert_eq!(drive.control & 0x0F, 0, "disarmed");
    }
}
