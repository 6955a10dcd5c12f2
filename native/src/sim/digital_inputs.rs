//! The virtual AKD's digital inputs and position latch (AKD manual §5.12).
//!
//! Inputs are simulated: each one is set high or low (as a switch or a sensor wired to it would
//! set it), and from there changes level wherever the shaft crosses one of its toggle positions,
//! whichever way it moves, so its level is a function of the position and its set level. Latch 1
//! captures on digital input 1 and latch 2 on input 2 (the AKD's fast inputs). A capture is the
//! position where the input toggled, found within the model step (so within one count, not
//! within the distance travelled in a step), as the AKD's hardware capture does.
//!
//! Latch control 0x20A4: bits 0–3 arm latch 1 rising, 1 falling, 2 rising, 2 falling; an edge
//! captures once while its bit is set, and setting the bit again (0 then 1) re-arms it and
//! clears its valid bit. Bits 8–12 select the value 0x20A6/0x20A7 show (1 latch 1 rising, 2
//! latch 1 falling, 3 latch 2 rising, 4 latch 2 falling), acknowledged in 0x20A5 bits 8–11.
//! Latch status 0x20A5: bits 0–3 valid, bits 12–15 the levels of inputs 4, 3, 2, 1.
//!
//! The CiA 402 touch probes ([`TouchProbe`], 0x60B8–0x60BD) are the same capture seen through
//! the standard objects: probe 1 on input 1, probe 2 on input 2, single-shot (bit 1/9 = 0).

use crate::error::SettingError;
use crate::sim::od::ObjectDictionary;

/// Digital inputs of the AKD (DIN1..DIN7).
pub const INPUT_COUNT: usize = crate::drive::io::INPUT_COUNT as usize;

/// Simulated digital inputs: per input its set level and toggle positions.
#[derive(Clone, Debug, Default)]
pub struct Inputs {
    toggles: [Vec<f64>; INPUT_COUNT],
    set: [bool; INPUT_COUNT],
}

/// Refuses an input number outside 1..=7.
fn check_input(input: usize) -> Result<(), SettingError> {
    if (1..=INPUT_COUNT).contains(&input) {
        Ok(())
    } else {
        Err(SettingError::DigitalInput { input, count: INPUT_COUNT })
    }
}

impl Inputs {
    /// Input `input` (1..=7) toggles at `positions` (counts); it is low below all of them.
    /// Refuses an input number out of range or a position that is not finite.
    pub fn set_toggles(&mut self, input: usize, positions: &[f64]) -> Result<(), SettingError> {
        check_input(input)?;
        if let Some(&position) = positions.iter().find(|p| !p.is_finite()) {
            return Err(SettingError::TogglePosition { input, position });
        }
        let mut sorted = positions.to_vec();
        sorted.sort_by(f64::total_cmp);
        self.toggles[input - 1] = sorted;
        self.set[input - 1] = false;
        Ok(())
    }

    /// Input `input` (1..=7) is `high` or low wherever the shaft is (its toggles forgotten).
    pub fn set_level(&mut self, input: usize, high: bool) -> Result<(), SettingError> {
        check_input(input)?;
        self.toggles[input - 1].clear();
        self.set[input - 1] = high;
        Ok(())
    }

    /// Level of input `index` (0-based) with the shaft at `position`: its set level, flipped
    /// by an odd number of toggle positions at or below it.
    fn level(&self, index: usize, position: f64) -> bool {
        self.set[index] ^ (self.toggles[index].partition_point(|t| *t <= position) % 2 == 1)
    }

    /// The input levels at `position`, input 1 in bit 0.
    pub fn levels(&self, position: f64) -> u8 {
        (0..INPUT_COUNT).fold(0, |bits, i| bits | (u8::from(self.level(i, position)) << i))
    }

    /// Calls `edge(position, rising)` for every toggle of input `index` that the shaft crossed
    /// moving from `from` to `to`, in the order it crossed them.
    fn crossings(&self, index: usize, from: f64, to: f64, mut edge: impl FnMut(f64, bool)) {
        let toggles = &self.toggles[index];
        let (low, high) = if from <= to { (from, to) } else { (to, from) };
        let range = toggles.partition_point(|t| *t <= low)..toggles.partition_point(|t| *t <= high);
        let mut level = self.level(index, from);
        let mut visit = |t: f64| {
            level = !level;
            edge(t, level);
        };
        if from <= to {
            toggles[range].iter().for_each(|t| visit(*t));
        } else {
            toggles[range].iter().rev().for_each(|t| visit(*t));
        }
    }
}

/// The latch unit.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Latch {
    control: u16,
    valid: u8,
    positions: [i32; 4],
}

impl Latch {
    /// Takes the latch control word 0x20A4: an arming bit that rises clears its valid bit.
    pub fn control(&mut self, control: u16) {
        let rising = (control & !self.control) as u8 & 0x0F;
        self.valid &= !rising;
        self.control = control;
    }

    /// Captures the edges of inputs 1 and 2 the shaft crossed from `from` to `to`.
    pub fn capture(&mut self, inputs: &Inputs, from: f64, to: f64) {
        for latch in 0..2 {
            inputs.crossings(latch, from, to, |position, rising| {
                let bit = latch * 2 + usize::from(!rising);
                let mask = 1u8 << bit;
                if self.control as u8 & mask != 0 && self.valid & mask == 0 {
                    self.valid |= mask;
                    self.positions[bit] = position.floor() as i64 as i32;
                }
            });
        }
    }

    /// The value selected by 0x20A4 bits 8–12 (1..=4), or 0.
    fn selected(&self) -> u16 {
        match (self.control >> 8) & 0x1F {
            s @ 1..=4 => s,
            _ => 0,
        }
    }

    /// The latch status word 0x20A5 with inputs 1–4 at `levels` (input 1 in bit 0).
    pub fn status(&self, levels: u8) -> u16 {
        let inputs = (0..4).fold(0u16, |bits, i| bits | (u16::from(levels >> i & 1) << (15 - i)));
        self.valid as u16 | self.selected() << 8 | inputs
    }

    /// Writes the latch objects.
    pub fn publish(&self, od: &mut ObjectDictionary, levels: u8) {
        for (i, p) in self.positions.iter().enumerate() {
            od.set(0x20A0 + i as u16, 0, &p.to_le_bytes());
        }
        let one = if self.selected() == 2 { self.positions[1] } else { self.positions[0] };
        let two = if self.selected() == 4 { self.positions[3] } else { self.positions[2] };
        od.set(0x20A6, 0, &one.to_le_bytes());
        od.set(0x20A7, 0, &two.to_le_bytes());
        od.set(0x20A5, 0, &self.status(levels).to_le_bytes());
    }
}

/// The CiA 402 touch probes: function 0x60B8, status 0x60B9, edge positions 0x60BA–0x60BD.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct TouchProbe {
    latch: Latch,
    function: u16,
}

impl TouchProbe {
    /// Takes the touch probe function 0x60B8: bit 0 enables probe 1, bits 4/5 its rising and
    /// falling edge; bits 8, 12, 13 the same for probe 2. An edge bit that rises re-arms it.
    pub fn function(&mut self, function: u16) {
        let edge = |enable: u16, edge: u16| u16::from(function & enable != 0 && function & edge != 0);
        let control =
            edge(1 << 0, 1 << 4) | edge(1 << 0, 1 << 5) << 1 | edge(1 << 8, 1 << 12) << 2 | edge(1 << 8, 1 << 13) << 3;
        self.latch.control(control);
        self.function = function;
    }

    /// Captures the edges of inputs 1 and 2 the shaft crossed from `from` to `to`.
    pub fn capture(&mut self, inputs: &Inputs, from: f64, to: f64) {
        self.latch.capture(inputs, from, to);
    }

    /// Writes the touch probe status 0x60B9 and the edge positions 0x60BA–0x60BD.
    pub fn publish(&self, od: &mut ObjectDictionary) {
        let valid = self.latch.valid as u16;
        let status = (self.function & 0x0101) | (valid & 0x3) << 1 | (valid >> 2 & 0x3) << 9;
        od.set(0x60B9, 0, &status.to_le_bytes());
        for (i, p) in self.latch.positions.iter().enumerate() {
            od.set(0x60BA + i as u16, 0, &p.to_le_bytes());
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn inputs_follow_the_position_whichever_way_it_moves() {
        let mut inputs = Inputs::default();
        inputs.set_toggles(1, &[300.0, 100.0]).unwrap();
        assert_eq!(inputs.levels(99.0), 0);
        assert_eq!(inputs.levels(100.0), 1);
        assert_eq!(inputs.levels(299.5), 1);
        assert_eq!(inputs.levels(300.0), 0);
        assert!(inputs.set_toggles(8, &[]).unwrap_err().to_string().contains("inputs 1 to 7"));
        assert!(inputs.set_toggles(2, &[f64::NAN]).unwrap_err().to_string().contains("not a finite"));
        inputs.set_level(1, true).unwrap();
        assert_eq!(inputs.levels(99.0) | inputs.levels(1e9), 1, "set high wherever the shaft is");
        inputs.set_toggles(3, &[0.0]).unwrap();
        assert_eq!(inputs.levels(1.0), 0b101);
        assert!(inputs.set_level(0, true).unwrap_err().to_string().contains("inputs 1 to 7"));
    }

    #[test]
    fn a_latch_captures_once_per_arming_where_the_input_toggled() {
        let mut inputs = Inputs::default();
        inputs.set_toggles(1, &[100.25, 200.75]).unwrap();
        inputs.set_toggles(2, &[-50.5]).unwrap();
        let mut latch = Latch::default();
        latch.control(0x0001 | 0x0002 | 0x0004 | 0x0008 | 0x0100);
        latch.capture(&inputs, 0.0, 150.0);
        assert_eq!(latch.status(inputs.levels(150.0)), 0x8000 | 0x4000 | 0x0100 | 0x0001);
        latch.capture(&inputs, 150.0, 250.0);
        // Going back down: input 1 rises again at 200.75 but latch 1 rising is already valid.
        latch.capture(&inputs, 250.0, -60.0);
        let mut od = ObjectDictionary::akd();
        latch.publish(&mut od, inputs.levels(-60.0));
        assert_eq!(od.get(0x20A0, 0).unwrap(), 100i32.to_le_bytes());
        assert_eq!(od.get(0x20A1, 0).unwrap(), 200i32.to_le_bytes());
        // Input 2 is high above -50.5: it fell there on the way down (latch 2 falling).
        assert_eq!(latch.status(inputs.levels(-60.0)) & 0x000F, 0x000B);
        assert_eq!(od.get(0x20A3, 0).unwrap(), (-51i32).to_le_bytes());
        assert_eq!(od.get(0x20A6, 0).unwrap(), 100i32.to_le_bytes());
        // Re-arming latch 1 rising clears its valid bit, and it captures the next rising edge.
        latch.control(0x010E);
        latch.control(0x020F);
        assert_eq!(latch.status(0) & 0x0001, 0);
        latch.capture(&inputs, -60.0, 300.0);
        latch.publish(&mut od, 0);
        assert_eq!(od.get(0x20A0, 0).unwrap(), 100i32.to_le_bytes());
        assert_eq!(od.get(0x20A6, 0).unwrap(), 200i32.to_le_bytes(), "selection 2: latch 1 falling");
        assert_eq!(od.get(0x20A5, 0).unwrap()[1] & 0x0F, 2);
    }

    #[test]
    fn touch_probes_are_the_same_capture_through_the_cia_402_objects() {
        let mut inputs = Inputs::default();
        inputs.set_toggles(2, &[500.5]).unwrap();
        inputs.set_toggles(1, &[-20.0, 20.0]).unwrap();
        let mut probe = TouchProbe::default();
        probe.function(0x3001); // probe 1 enabled without an edge, probe 2 on both edges but off
        probe.capture(&inputs, -100.0, 1000.0);
        let mut od = ObjectDictionary::akd();
        probe.publish(&mut od);
        assert_eq!(od.get(0x60B9, 0).unwrap(), 0x0001u16.to_le_bytes(), "nothing armed");
        // Probe 1 rising, probe 2 rising.
        probe.function(0x1111);
        // Input 1 is high between -20 and 20: coming down it rises at 20.
        probe.capture(&inputs, 1000.0, -100.0);
        probe.capture(&inputs, -100.0, 1000.0);
        probe.publish(&mut od);
        assert_eq!(od.get(0x60B9, 0).unwrap(), 0x0303u16.to_le_bytes());
        assert_eq!(od.get(0x60BA, 0).unwrap(), 20i32.to_le_bytes());
        assert_eq!(od.get(0x60BC, 0).unwrap(), 500i32.to_le_bytes());
    }
}
