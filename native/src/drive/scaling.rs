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
//!
//! [`JointScaling`] is a joint's own scale (counts, gear, direction, offset, torque), by which
//! every SI value of the joint is converted, and [`PositionUnwrap`] reads its position across
//! the 32-bit wrap.

use crate::drive::ds402::CommandKind;
use crate::drive::trajectory::{trimmed, Scale, Unit};

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
#[cfg_attr(feature = "python", pyo3::pyclass(module = "akd_ros._native", frozen, eq, get_all))]
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

    /// How many of its counts object `index:subindex` counts per motor revolution: increments
    /// (0x6063, 0x60C1:01) by the encoder resolution; position units (0x6064, 0x607A) with DS402
    /// scaling by feed constant over gear ratio, without it by the UNIT parameters
    /// (`unit_parameters`, when the caller knows them, e.g. the virtual AKD's defaults). `None`
    /// for an object that holds no position or whose scale the objects do not tell (a zero
    /// denominator, FBUS.PARAM05 not known).
    pub fn counts_per_revolution(&self, index: u16, subindex: u8, unit_parameters: Option<f64>) -> Option<f64> {
        match unit_of(index, subindex)? {
            PositionUnit::Increments => self.encoder_resolution.value(),
            PositionUnit::PositionUnits if self.ds402_scaling? => {
                let per_motor_revolution = self.feed_constant.value()? / self.gear_ratio.value()?;
                (per_motor_revolution.is_finite() && per_motor_revolution > 0.0).then_some(per_motor_revolution)
            }
            PositionUnit::PositionUnits => unit_parameters,
        }
    }
}

/// Feedback counts per revolution, gear, direction, offset and torque of one joint: how its
/// load's SI values (rad, rad/s, N·m; m, m/s, N on a linear axis, REP 103) and its drive's
/// values relate. The one place a joint's scale is: the feed's joint states, the recorded
/// cycles, the commands and the Python `Units` all convert by it.
///
/// The drive counts positions (0x6064, 0x607A, 0x60C1:01) in `counts_per_revolution` per motor
/// revolution, velocities (0x606C, 0x60FF) in those counts per second (an assumption of the
/// virtual AKD: a real AKD's DS402 velocity unit is configurable and must be set to match), and
/// torques (0x6071, 0x6077) in 0.1 % of its peak torque (AKD manual, mode 4, unlike CiA 402's
/// per mille of rated torque). `gear_ratio` is motor revolutions per load revolution,
/// `direction` flips the load's sense against the motor's, `offset` is the load position at
/// count 0, and a linear axis moves `lead` metres per load revolution.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "python", pyo3::pyclass(name = "Units", module = "akd_ros._native", frozen, eq, get_all))]
pub struct JointScaling {
    /// Feedback counts per motor revolution; the virtual AKD uses 2**20.
    pub counts_per_revolution: u64,
    /// Motor revolutions per load revolution.
    pub gear_ratio: f64,
    /// +1 when the load turns with the motor's positive sense, -1 when against it.
    pub direction: i8,
    /// Load position at motor count 0: rad for a rotary axis, m for a linear one.
    pub offset: f64,
    /// Metres the load travels per load revolution of a linear axis; None for a rotary one.
    pub lead: Option<f64>,
    /// The drive's peak torque at the motor in N·m, which drive torque value 1000 (100 %) means.
    pub peak_torque: f64,
}

/// Drive torque units per peak torque: 0x6071/0x6077 count in 0.1 %.
pub const TORQUE_UNITS_PER_PEAK: f64 = 1000.0;

/// What a joint's scaling or a conversion by it refuses.
#[derive(Clone, Debug, PartialEq)]
pub enum ScalingError {
    /// `counts_per_revolution` is no positive integer.
    CountsPerRevolution,
    /// A value that must be finite (and, where `positive`, greater than 0) is not.
    NotFinite {
        /// Its name.
        name: &'static str,
        /// Whether it must be greater than 0.
        positive: bool,
        /// The value.
        value: f64,
    },
    /// `direction` is neither +1 nor -1.
    Direction,
    /// A lead given to a rotary axis.
    LeadOnRotary(f64),
    /// A linear axis without a lead.
    NoLead,
    /// A value whose drive value is outside the drive object's range.
    OutOfRange {
        /// "position", "velocity" or "torque".
        name: &'static str,
        /// The SI value.
        si: f64,
        /// Its drive value.
        value: i64,
        /// The drive's range.
        range: (i64, i64),
        /// The SI values of the range's ends, the lower first.
        allowed: (f64, f64),
        /// The SI unit.
        unit: &'static str,
    },
}

impl std::fmt::Display for ScalingError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            ScalingError::CountsPerRevolution => write!(f, "counts_per_revolution must be a positive integer"),
            ScalingError::NotFinite { name, positive, value } => {
                let allowed = if *positive { "a finite number greater than 0" } else { "a finite number" };
                write!(f, "{name} must be {allowed}, got {}", py_repr(*value))
            }
            ScalingError::Direction => write!(f, "direction must be +1 or -1"),
            ScalingError::LeadOnRotary(lead) => {
                write!(f, "lead applies to a linear axis only; a rotary axis needs lead None, got {}", py_repr(*lead))
            }
            ScalingError::NoLead => write!(f, "lead (m per load revolution) is required for a linear axis"),
            ScalingError::OutOfRange { name, si, value, range: (low, high), allowed: (a, b), unit } => write!(
                f,
                "{name} {} {unit} maps to drive value {value}, outside [{low}, {high}]; the allowed {name} range is \
                 [{}, {}] {unit}",
                py_repr(*si),
                trimmed(*a),
                trimmed(*b)
            ),
        }
    }
}

/// `x` as Python writes a float ("nan", "inf", "0.5"), which the refusals quote.
pub fn py_repr(x: f64) -> String {
    if x.is_nan() {
        "nan".into()
    } else {
        format!("{x:?}")
    }
}

fn finite(name: &'static str, value: f64, positive: bool) -> Result<f64, ScalingError> {
    match value.is_finite() && (!positive || value > 0.0) {
        true => Ok(value),
        false => Err(ScalingError::NotFinite { name, positive, value }),
    }
}

impl Default for JointScaling {
    /// The virtual AKD's: 2^20 counts per revolution, no gear, peak torque 3 N·m, rotary.
    fn default() -> Self {
        JointScaling {
            counts_per_revolution: DEFAULT_COUNTS_PER_REVOLUTION as u64,
            gear_ratio: 1.0,
            direction: 1,
            offset: 0.0,
            lead: None,
            peak_torque: 3.0,
        }
    }
}

impl JointScaling {
    /// The scaling of these mechanics (`linear` with its `lead`, or rotary without one), or
    /// why they are none.
    pub fn new(
        counts_per_revolution: u64,
        gear_ratio: f64,
        direction: i8,
        offset: f64,
        (linear, lead): (bool, Option<f64>),
        peak_torque: f64,
    ) -> Result<JointScaling, ScalingError> {
        if counts_per_revolution == 0 {
            return Err(ScalingError::CountsPerRevolution);
        }
        finite("gear_ratio", gear_ratio, true)?;
        if direction != 1 && direction != -1 {
            return Err(ScalingError::Direction);
        }
        finite("offset", offset, false)?;
        match (linear, lead) {
            (false, Some(lead)) => return Err(ScalingError::LeadOnRotary(lead)),
            (true, None) => return Err(ScalingError::NoLead),
            (true, Some(lead)) => _ = finite("lead", lead, true)?,
            (false, None) => {}
        }
        finite("peak_torque", peak_torque, true)?;
        Ok(JointScaling { counts_per_revolution, gear_ratio, direction, offset, lead, peak_torque })
    }

    /// The unit of its positions.
    pub fn position_unit(&self) -> Unit {
        if self.lead.is_some() {
            Unit::Metre
        } else {
            Unit::Radian
        }
    }

    /// Load travel (rad or m, signed by the direction) per count.
    pub fn si_per_count(&self) -> f64 {
        let travel = self.lead.unwrap_or(std::f64::consts::TAU);
        self.direction as f64 * travel / (self.counts_per_revolution as f64 * self.gear_ratio)
    }

    /// Load torque (N·m) or force (N), signed by the direction, per drive torque unit.
    pub fn si_per_torque_unit(&self) -> f64 {
        let load_torque = self.peak_torque * self.gear_ratio / TORQUE_UNITS_PER_PEAK;
        let per_unit = self.lead.map_or(load_torque, |lead| load_torque * std::f64::consts::TAU / lead);
        self.direction as f64 * per_unit
    }

    /// How its values read in words (the trajectory's and the cycle's refusals).
    pub fn scale(&self) -> Scale {
        Scale { per_count: self.si_per_count(), offset: self.offset, unit: self.position_unit() }
    }

    /// The load position at `counts` (raw, or unwrapped).
    pub fn position_to_si(&self, counts: f64) -> f64 {
        counts * self.si_per_count() + self.offset
    }

    /// The load velocity at `counts_per_second`; so too a distance (a following error) in counts.
    pub fn velocity_to_si(&self, counts_per_second: f64) -> f64 {
        counts_per_second * self.si_per_count()
    }

    /// The load torque (or force) at drive torque `value`.
    pub fn torque_to_si(&self, value: f64) -> f64 {
        value * self.si_per_torque_unit()
    }

    /// The int32 target position for load position `position`.
    pub fn position_to_counts(&self, position: f64) -> Result<i32, ScalingError> {
        self.to_drive(CommandKind::Position, position).map(|c| c as i32)
    }

    /// The int32 target velocity (counts/s) for load velocity `velocity`.
    pub fn velocity_to_counts(&self, velocity: f64) -> Result<i32, ScalingError> {
        self.to_drive(CommandKind::Velocity, velocity).map(|c| c as i32)
    }

    /// Counts/s² for load acceleration `acceleration`.
    pub fn acceleration_to_counts(&self, acceleration: f64) -> Result<f64, ScalingError> {
        Ok(finite("acceleration", acceleration, false)? / self.si_per_count())
    }

    /// The int16 target torque (0.1 % of peak) for load torque (or force) `torque`.
    pub fn torque_to_drive(&self, torque: f64) -> Result<i16, ScalingError> {
        self.to_drive(CommandKind::Torque, torque).map(|v| v as i16)
    }

    /// The drive value of `kind` for SI `si` (counts, counts/s, 0.1 % of peak), within the
    /// range of the drive's object (INT32 targets, INT16 torque).
    pub fn to_drive(&self, kind: CommandKind, si: f64) -> Result<i64, ScalingError> {
        let linear = self.position_unit() == Unit::Metre;
        let (name, unit, per_value, offset, (low, high)) = match kind {
            CommandKind::Position => ("position", self.position_unit().name(), self.si_per_count(), self.offset, INT32),
            CommandKind::Velocity => {
                ("velocity", if linear { "m/s" } else { "rad/s" }, self.si_per_count(), 0.0, INT32)
            }
            CommandKind::Torque => (
                "torque",
                if linear { "N" } else { "N·m" },
                self.si_per_torque_unit(),
                0.0,
                (i16::MIN.into(), i16::MAX.into()),
            ),
        };
        let value = ((finite(name, si, false)? - offset) / per_value).round();
        if (low as f64..=high as f64).contains(&value) {
            return Ok(value as i64);
        }
        let (a, b) = (low as f64 * per_value + offset, high as f64 * per_value + offset);
        let value = if value.abs() < 9.2e18 { value as i64 } else { value.signum() as i64 * i64::MAX };
        Err(ScalingError::OutOfRange { name, si, value, range: (low, high), allowed: (a.min(b), a.max(b)), unit })
    }
}

const INT32: (i64, i64) = (i32::MIN as i64, i32::MAX as i64);

/// The continuous count nearest `last` that reads as the int32 `raw` on the drive: continuous
/// while the axis moves less than 2^31 counts between readings.
pub fn unwrap_position(last: i64, raw: i32) -> i64 {
    last.wrapping_add(raw.wrapping_sub(last as i32) as i64)
}

/// A joint's position unwrapped across the drive's 32-bit wrap, reading after reading: each
/// reader of a joint's position (the feed, an `Axis`) keeps its own, the rule being
/// [`unwrap_position`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct PositionUnwrap {
    last: Option<i64>,
}

impl PositionUnwrap {
    /// The continuous count of the reading `raw`; the first reading is taken as it is.
    pub fn next(&mut self, raw: i32) -> i64 {
        let counts = self.last.map_or(raw as i64, |last| unwrap_position(last, raw));
        self.last = Some(counts);
        counts
    }
}

impl PositionScaling {
    /// Where the drive counts the position objects `mapped` carries in another scale than
    /// `counts_per_revolution`, one sentence saying which, by how much, from which of its
    /// objects, and what to change; `None` where they agree or the objects do not tell. The
    /// objects give positions only: velocity and torque units are the AKD's own parameters.
    pub fn mismatch(&self, counts_per_revolution: u64, mapped: impl Fn(u16, u8) -> bool) -> Option<String> {
        let mut differing: Vec<((u16, u8), f64)> = POSITION_OBJECTS
            .iter()
            .filter(|((index, sub), _)| mapped(*index, *sub))
            .filter_map(|&((index, sub), _)| Some(((index, sub), self.counts_per_revolution(index, sub, None)?)))
            .filter(|&(_, counts)| counts != counts_per_revolution as f64)
            .collect();
        differing.sort_by_key(|(object, _)| *object);
        if differing.is_empty() {
            return None;
        }
        let objects: Vec<String> = differing
            .iter()
            .map(|((i, s), _)| if *s == 0 { format!("0x{i:04X}") } else { format!("0x{i:04X}:{s:02X}") })
            .collect();
        let mut counts: Vec<f64> = differing.iter().map(|(_, c)| *c).collect();
        counts.sort_by(f64::total_cmp);
        counts.dedup();
        let pair = |r: Ratio| format!("{}/{}", r.numerator, r.denominator);
        let mut told = Vec::new();
        let in_unit = |unit| differing.iter().any(|((i, s), _)| unit_of(*i, *s) == Some(unit));
        if in_unit(PositionUnit::Increments) {
            told.push(format!(
                "0x608F = {} (encoder increments per motor revolutions, FB1.PSCALE)",
                pair(self.encoder_resolution)
            ));
        }
        if in_unit(PositionUnit::PositionUnits) {
            told.push(format!(
                "FBUS.PARAM05 bit 4 set: feed constant 0x6092 = {} over gear ratio 0x6091 = {}",
                pair(self.feed_constant),
                pair(self.gear_ratio)
            ));
        }
        let scales: Vec<String> = counts.iter().map(|c| trimmed(*c)).collect();
        Some(format!(
            "counts_per_revolution is {counts_per_revolution}, but the drive counts {} per motor revolution in {} \
             ({}): its positions would be read and commanded {} times off; set counts_per_revolution to the drive's \
             scale, or the drive's scaling to {counts_per_revolution} per revolution",
            scales.join(" and "),
            objects.join(", "),
            told.join("; "),
            trimmed(counts[0] / counts_per_revolution as f64)
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_defaults_count_2_pow_20_per_revolution_in_both_units() {
        // The AKD at its defaults: 2^20 increments per revolution, gear and feed 1/1, DS402 scaling off.
        let s = PositionScaling::from_entries([DEFAULT_COUNTS_PER_REVOLUTION, 1, 1, 1, 1, 1], Some(0));
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
        assert_eq!(
            (zero.counts_per_revolution(0x6063, 0, None), zero.counts_per_revolution(0x6064, 0, None)),
            (None, None)
        );
    }

    #[test]
    fn positions_stay_continuous_across_the_wrap_either_way() {
        assert_eq!(unwrap_position(i32::MAX as i64, i32::MIN), i32::MAX as i64 + 1);
        assert_eq!(unwrap_position(i32::MIN as i64, i32::MAX), i32::MIN as i64 - 1);
        assert_eq!(unwrap_position(i32::MAX as i64 + 10, i32::MIN + 20), i32::MAX as i64 + 21);
        assert_eq!(unwrap_position(5 * (1 << 32) + 7, 3), 5 * (1 << 32) + 3);
        assert_eq!(unwrap_position(-7, -7), -7);
        let mut unwrap = PositionUnwrap::default();
        assert_eq!([unwrap.next(i32::MAX - 1), unwrap.next(i32::MIN + 1)], [i32::MAX as i64 - 1, i32::MAX as i64 + 2]);
    }

    #[test]
    fn numbers_read_as_python_writes_them() {
        let cases =
            [(0.0, "0.0"), (-2.0, "-2.0"), (13000.0, "13000.0"), (f64::NAN, "nan"), (f64::NEG_INFINITY, "-inf")];
        for (x, text) in cases {
            assert_eq!(py_repr(x), text);
        }
    }

    #[test]
    fn a_command_past_the_drive_range_names_the_range_in_si() {
        let s = JointScaling::new(1 << 20, 1.0, 1, 0.0, (false, None), 1.0).unwrap();
        assert_eq!(s.torque_to_drive(32.767), Ok(i16::MAX));
        let e = s.torque_to_drive(32.768).unwrap_err().to_string();
        assert_eq!(
            e,
            "torque 32.768 N·m maps to drive value 32768, outside [-32768, 32767]; the allowed torque range is \
             [-32.768, 32.767] N·m"
        );
        assert_eq!(s.to_drive(CommandKind::Velocity, std::f64::consts::TAU), Ok(1 << 20));
        assert!(matches!(s.position_to_counts(f64::NAN), Err(ScalingError::NotFinite { name: "position", .. })));
    }

    #[test]
    fn a_mismatch_names_the_objects_and_the_scale() {
        let s = PositionScaling::from_entries([1 << 16, 1, 1, 1, 1, 1], Some(0));
        let text = s.mismatch(1 << 20, |_, _| true).unwrap();
        assert!(text.starts_with("counts_per_revolution is 1048576, but the drive counts 65536 per motor revolution in 0x6063, 0x60C1:01 (0x608F = 65536/1"), "{text}");
        assert!(text.contains("0.0625 times off"), "{text}");
        assert_eq!(s.mismatch(1 << 16, |_, _| true), None);
        assert_eq!(s.mismatch(1 << 20, |i, _| i == 0x6064), None);
    }
}
