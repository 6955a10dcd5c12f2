//! How the AKD scales the positions of its CoE objects, pure and free of I/O: which objects
//! count in which unit, and how many of those units make one motor revolution, from the DS402
//! scaling objects and FBUS.PARAM05 bit 4. Shared by the master, which reads the objects to
//! derive a joint's units, and the virtual AKD, which scales its positions by them.
//!
//! The AKD counts positions in two units (AKD EtherCAT manual 2017 §5.3.70-72; Kollmorgen's
//! notes "Position Scaling for AKD drive with EtherCAT Communication" and "AKD DS402 Position
//! Scaling Setup"):
//! - increments: 0x6063 (position actual internal value) and 0x60C1:01 (interpolated position
//!   set-point) count 0x608F:01 increments per 0x608F:02 motor revolutions, always. 0x608F:01
//!   is FB1.PSCALE's power of two (2^20 by default).
//! - position units: 0x6064 (position actual value) and 0x607A (target position). With
//!   FBUS.PARAM05 bit 4 clear (the AKD's default) they follow the drive's UNIT parameters
//!   (UNIT.PIN/UNIT.POUT, 2^20 per revolution by default), which no DS402 object tells; with
//!   bit 4 set they follow CiA 402's factor group: position units per motor revolution =
//!   feed constant (0x6092:01 feed per 0x6092:02 driving-shaft revolutions) / gear ratio
//!   (0x6091:01 motor revolutions per 0x6091:02 driving-shaft revolutions).
//!
//! Evidence is thin beyond these four objects: the notes say bit 4 also scales the profile
//! acceleration and deceleration (0x6083/0x6084) in the position modes, and say nothing of the
//! velocity objects; neither is modelled here.

/// Position encoder resolution: encoder increments (:01) per motor revolutions (:02).
pub const POSITION_ENCODER_RESOLUTION: u16 = 0x608F;
/// Gear ratio: motor revolutions (:01) per driving-shaft revolutions (:02).
pub const GEAR_RATIO: u16 = 0x6091;
/// Feed constant: feed in position units (:01) per driving-shaft revolutions (:02).
pub const FEED_CONSTANT: u16 = 0x6092;

/// FBUS.PARAM05, the AKD's fieldbus behaviour bits (manual §5.14). The manual names the
/// parameter but gives no CoE index for it; like FBUS.PARAM02 ([`crate::drive::sync::FBUS_PARAM02`],
/// which explains the choice) it is modelled as manufacturer object 0x3E05:00, UNSIGNED32, and
/// a master trusts what it reads there only where the drive's SDO information names the object
/// [`FBUS_PARAM05_NAME`].
pub const FBUS_PARAM05: u16 = 0x3E05;
/// The parameter's name as the AKD names its parameters, and as the virtual AKD's SDO
/// information names object [`FBUS_PARAM05`].
pub const FBUS_PARAM05_NAME: &str = "FBUS.PARAM05";
/// FBUS.PARAM05 bit 4: positions are scaled by the DS402 objects instead of the UNIT
/// parameters.
pub const FBUS_PARAM05_DS402_SCALING: u32 = 1 << 4;

/// The AKD's default resolution, FB1.PSCALE 20: 2^20 increments per motor revolution; also
/// UNIT.PIN's default, the position units per revolution with DS402 scaling off.
pub const DEFAULT_COUNTS_PER_REVOLUTION: u32 = 1 << 20;

/// The objects a master reads to know the drive's scaling: the three ratios, numerator and
/// denominator each.
pub const SCALING_ENTRIES: [(u16, u8); 6] = [
    (POSITION_ENCODER_RESOLUTION, 1),
    (POSITION_ENCODER_RESOLUTION, 2),
    (GEAR_RATIO, 1),
    (GEAR_RATIO, 2),
    (FEED_CONSTANT, 1),
    (FEED_CONSTANT, 2),
];

/// A ratio of two UNSIGNED32 entries of one object (sub 1 over sub 2).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Ratio {
    /// Subindex 1.
    pub numerator: u32,
    /// Subindex 2.
    pub denominator: u32,
}

impl Ratio {
    /// 1/1.
    pub const ONE: Ratio = Ratio { numerator: 1, denominator: 1 };

    /// The ratio's value; `None` for a zero denominator (a drive refuses to hold one).
    pub fn value(self) -> Option<f64> {
        (self.denominator != 0).then(|| self.numerator as f64 / self.denominator as f64)
    }
}

/// The unit an object's positions count in.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PositionUnit {
    /// Encoder increments (0x608F): 0x6063, 0x60C1:01.
    Increments,
    /// Position units (UNIT parameters, or DS402 scaling with FBUS.PARAM05 bit 4): 0x6064, 0x607A.
    PositionUnits,
}

/// The position objects whose unit the scaling sets, each with its unit.
pub const POSITION_OBJECTS: [((u16, u8), PositionUnit); 4] = [
    ((0x6063, 0), PositionUnit::Increments),
    ((0x60C1, 1), PositionUnit::Increments),
    ((0x6064, 0), PositionUnit::PositionUnits),
    ((0x607A, 0), PositionUnit::PositionUnits),
];

/// The unit the position object `index:subindex` counts in; `None` for an object that holds no
/// position.
pub fn unit_of(index: u16, subindex: u8) -> Option<PositionUnit> {
    POSITION_OBJECTS.iter().find(|(object, _)| *object == (index, subindex)).map(|(_, unit)| *unit)
}

/// One drive's position scaling as its objects give it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PositionScaling {
    /// 0x608F: increments per motor revolutions.
    pub encoder_resolution: Ratio,
    /// 0x6091: motor revolutions per driving-shaft revolutions.
    pub gear_ratio: Ratio,
    /// 0x6092: feed (position units) per driving-shaft revolutions.
    pub feed_constant: Ratio,
    /// FBUS.PARAM05 bit 4 (DS402 scaling); `None` where the drive's parameter is not known.
    pub ds402_scaling: Option<bool>,
}

impl PositionScaling {
    /// The AKD at its defaults: 2^20 increments per revolution, gear and feed 1/1, DS402
    /// scaling off.
    pub const AKD_DEFAULT: PositionScaling = PositionScaling {
        encoder_resolution: Ratio { numerator: DEFAULT_COUNTS_PER_REVOLUTION, denominator: 1 },
        gear_ratio: Ratio::ONE,
        feed_constant: Ratio::ONE,
        ds402_scaling: Some(false),
    };

    /// The scaling from the six entries of [`SCALING_ENTRIES`], in that order, and FBUS.PARAM05
    /// where known.
    pub fn from_entries(entries: [u32; 6], fbus_param05: Option<u32>) -> Self {
        let ratio = |i: usize| Ratio { numerator: entries[i], denominator: entries[i + 1] };
        PositionScaling {
            encoder_resolution: ratio(0),
            gear_ratio: ratio(2),
            feed_constant: ratio(4),
            ds402_scaling: fbus_param05.map(|p| p & FBUS_PARAM05_DS402_SCALING != 0),
        }
    }

    /// Increments per motor revolution (0x6063, 0x60C1:01); `None` for a zero denominator.
    pub fn increments_per_revolution(&self) -> Option<f64> {
        self.encoder_resolution.value()
    }

    /// Position units per motor revolution (0x6064, 0x607A) as far as the DS402 objects tell
    /// it: with DS402 scaling, feed constant over gear ratio; without it, the UNIT parameters'
    /// (`unit_parameters`, when the caller knows them, e.g. the virtual AKD's defaults);
    /// `None` where that is unknown.
    pub fn position_units_per_revolution(&self, unit_parameters: Option<f64>) -> Option<f64> {
        match self.ds402_scaling? {
            true => {
                let per_motor_revolution = self.feed_constant.value()? / self.gear_ratio.value()?;
                (per_motor_revolution.is_finite() && per_motor_revolution > 0.0).then_some(per_motor_revolution)
            }
            false => unit_parameters,
        }
    }

    /// How many of its counts object `index:subindex` counts per motor revolution; `None` for
    /// an object that holds no position or whose scale the objects do not tell.
    pub fn counts_per_revolution(&self, index: u16, subindex: u8, unit_parameters: Option<f64>) -> Option<f64> {
        match unit_of(index, subindex)? {
            PositionUnit::Increments => self.increments_per_revolution(),
            PositionUnit::PositionUnits => self.position_units_per_revolution(unit_parameters),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_defaults_count_2_pow_20_per_revolution_in_both_units() {
        let s = PositionScaling::AKD_DEFAULT;
        let unit_pin = Some(DEFAULT_COUNTS_PER_REVOLUTION as f64);
        for (index, sub) in [(0x6063, 0), (0x60C1, 1), (0x6064, 0), (0x607A, 0)] {
            assert_eq!(s.counts_per_revolution(index, sub, unit_pin), Some(1048576.0), "0x{index:04X}");
        }
        assert_eq!(s.counts_per_revolution(0x6064, 0, None), None, "UNIT.PIN is no DS402 object");
        assert_eq!(s.counts_per_revolution(0x606C, 0, unit_pin), None, "no position");
    }

    #[test]
    fn ds402_scaling_is_feed_over_gear_and_leaves_the_increments_alone() {
        // 10000 µm per driving-shaft revolution, 5 motor revolutions per shaft revolution.
        let entries = [1 << 16, 1, 5, 1, 10_000, 1];
        let s = PositionScaling::from_entries(entries, Some(0x10));
        assert_eq!(s.ds402_scaling, Some(true));
        assert_eq!(s.counts_per_revolution(0x607A, 0, Some(1048576.0)), Some(2000.0));
        assert_eq!(s.counts_per_revolution(0x6063, 0, Some(1048576.0)), Some(65536.0));
        let off = PositionScaling::from_entries(entries, Some(0x01));
        assert_eq!(off.counts_per_revolution(0x6064, 0, Some(1048576.0)), Some(1048576.0));
        let unknown = PositionScaling::from_entries(entries, None);
        assert_eq!(unknown.counts_per_revolution(0x6064, 0, Some(1048576.0)), None);
        assert_eq!(unknown.counts_per_revolution(0x60C1, 1, None), Some(65536.0));
        let zero = PositionScaling::from_entries([1 << 20, 0, 0, 1, 1, 1], Some(0x10));
        assert_eq!((zero.increments_per_revolution(), zero.position_units_per_revolution(None)), (None, None));
    }
}
