//! Joint trajectories as joint_trajectory_controller takes them: points at times from the
//! start, each with every joint's position and, where given, its velocity and acceleration,
//! interpolated per joint and segment — quintic where both ends give accelerations, cubic
//! (Hermite) where both give velocities, linear otherwise.
//!
//! Pure arithmetic, no I/O: [`Trajectory::new`] validates a whole trajectory and computes its
//! segments (allocating, in the caller's thread); [`Trajectory::lead_in`] and
//! [`Trajectory::at`] then evaluate it without allocating, so the cycle thread can. The segment
//! to the first point starts from the set-point the drive has when the trajectory takes over
//! (its position, velocity and acceleration), so a new trajectory never makes a step; that
//! segment takes the first point's kind.
//!
//! Units are the drive's: positions in counts, velocities in counts/s, accelerations in
//! counts/s², times in ns.

use std::fmt;

/// One joint's value at one point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Knot {
    /// Position, counts.
    pub position: f64,
    /// Velocity, counts/s, where given.
    pub velocity: Option<f64>,
    /// Acceleration, counts/s², where given (only with a velocity).
    pub acceleration: Option<f64>,
}

impl Knot {
    /// A knot of a position alone.
    pub fn position(position: f64) -> Knot {
        Knot { position, velocity: None, acceleration: None }
    }
}

/// A set-point with its derivatives.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Setpoint {
    /// Position, counts.
    pub position: f64,
    /// Velocity, counts/s.
    pub velocity: f64,
    /// Acceleration, counts/s².
    pub acceleration: f64,
}

/// A joint's allowed positions, counts.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Limits {
    /// The lowest position.
    pub min: f64,
    /// The highest position.
    pub max: f64,
}

impl Limits {
    /// What an INT32 position target can carry.
    pub const TARGET: Limits = Limits { min: i32::MIN as f64, max: i32::MAX as f64 };
}

/// How a segment interpolates.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Interpolation {
    /// Positions only: constant velocity.
    Linear,
    /// Positions and velocities at both ends (Hermite).
    Cubic,
    /// Positions, velocities and accelerations at both ends.
    Quintic,
}

impl Interpolation {
    /// The interpolation a segment ending at `to` takes from an end that gives everything.
    fn toward(to: &Knot) -> Interpolation {
        match (to.velocity, to.acceleration) {
            (Some(_), Some(_)) => Interpolation::Quintic,
            (Some(_), None) => Interpolation::Cubic,
            _ => Interpolation::Linear,
        }
    }

    /// The interpolation between two points: what both ends give.
    fn between(from: &Knot, to: &Knot) -> Interpolation {
        match (Interpolation::toward(from), Interpolation::toward(to)) {
            (Interpolation::Quintic, Interpolation::Quintic) => Interpolation::Quintic,
            (Interpolation::Linear, _) | (_, Interpolation::Linear) => Interpolation::Linear,
            _ => Interpolation::Cubic,
        }
    }
}

/// One joint's polynomial over one segment: position = Σ cᵢ·sⁱ, s in seconds from the
/// segment's start.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Segment {
    c: [f64; 6],
}

impl Segment {
    /// The segment of `duration_s` from `from` to `to` by `kind`; `to`'s derivatives that
    /// `kind` needs are taken as given, the others are not used.
    fn new(kind: Interpolation, from: Setpoint, to: Setpoint, duration_s: f64) -> Segment {
        let (p0, v0, a0) = (from.position, from.velocity, from.acceleration);
        let (p1, v1, a1) = (to.position, to.velocity, to.acceleration);
        let t = duration_s;
        let h = p1 - p0;
        let c = match kind {
            Interpolation::Linear => [p0, h / t, 0.0, 0.0, 0.0, 0.0],
            Interpolation::Cubic => {
                [p0, v0, (3.0 * h / t - 2.0 * v0 - v1) / t, (-2.0 * h / t + v0 + v1) / (t * t), 0.0, 0.0]
            }
            Interpolation::Quintic => {
                let (t2, t3) = (t * t, t * t * t);
                [
                    p0,
                    v0,
                    a0 / 2.0,
                    (20.0 * h - (8.0 * v1 + 12.0 * v0) * t - (3.0 * a0 - a1) * t2) / (2.0 * t3),
                    (-30.0 * h + (14.0 * v1 + 16.0 * v0) * t + (3.0 * a0 - 2.0 * a1) * t2) / (2.0 * t3 * t),
                    (12.0 * h - 6.0 * (v1 + v0) * t + (a1 - a0) * t2) / (2.0 * t3 * t2),
                ]
            }
        };
        Segment { c }
    }

    /// The set-point `s` seconds into the segment.
    pub fn at(&self, s: f64) -> Setpoint {
        let c = &self.c;
        let position = c[0] + s * (c[1] + s * (c[2] + s * (c[3] + s * (c[4] + s * c[5]))));
        let velocity = c[1] + s * (2.0 * c[2] + s * (3.0 * c[3] + s * (4.0 * c[4] + s * 5.0 * c[5])));
        let acceleration = 2.0 * c[2] + s * (6.0 * c[3] + s * (12.0 * c[4] + s * 20.0 * c[5]));
        Setpoint { position, velocity, acceleration }
    }
}

/// A validated trajectory of one or more joints.
#[derive(Clone, Debug, PartialEq)]
pub struct Trajectory {
    joints: usize,
    /// Each point's time from the start, strictly increasing from above 0.
    times_ns: Vec<u64>,
    /// Point-major: the knot of joint j at point k is `knots[k * joints + j]`.
    knots: Vec<Knot>,
    /// Between points k-1 and k (k from 1): `segments[(k - 1) * joints + j]`.
    segments: Vec<Segment>,
}

fn seconds(ns: u64) -> f64 {
    ns as f64 * 1e-9
}

/// What a knot gives as a set-point: its derivatives where given, else 0.
fn setpoint(knot: &Knot) -> Setpoint {
    Setpoint {
        position: knot.position,
        velocity: knot.velocity.unwrap_or(0.0),
        acceleration: knot.acceleration.unwrap_or(0.0),
    }
}

impl Trajectory {
    /// Validates `points` (one list of the `joints` joints' knots per point) at `times_ns` (each
    /// point's time from the start) against `limits` (one per joint; an INT32 target's range
    /// when `None`) and computes the segments between the points. Refuses the whole
    /// trajectory, naming the point, the joint and what is allowed, when a value is NaN or
    /// infinite, a position is outside its joint's limits, a time does not increase strictly
    /// from above 0, an acceleration comes without a velocity, or the counts do not match.
    pub fn new(
        joints: usize,
        times_ns: &[u64],
        points: &[Vec<Knot>],
        limits: Option<&[Limits]>,
    ) -> Result<Trajectory, TrajectoryError> {
        if joints == 0 {
            return Err(TrajectoryError::NoJoints);
        }
        if points.is_empty() {
            return Err(TrajectoryError::NoPoints);
        }
        if times_ns.len() != points.len() {
            return Err(TrajectoryError::TimesCount { points: points.len(), times: times_ns.len() });
        }
        let limits = match limits {
            Some(l) if l.len() != joints => return Err(TrajectoryError::LimitsCount { given: l.len(), joints }),
            Some(l) => l,
            None => &vec![Limits::TARGET; joints][..],
        };
        for (joint, l) in limits.iter().enumerate() {
            if !(l.min.is_finite() && l.max.is_finite() && l.min <= l.max) {
                return Err(TrajectoryError::BadLimits { joint, min: l.min, max: l.max });
            }
        }
        let mut after_ns = 0;
        for (point, (&time_ns, knots)) in times_ns.iter().zip(points).enumerate() {
            if time_ns <= after_ns || (point == 0 && time_ns == 0) {
                return Err(TrajectoryError::TimeNotIncreasing { point, time_ns, after_ns });
            }
            after_ns = time_ns;
            if knots.len() != joints {
                return Err(TrajectoryError::JointCount { point, given: knots.len(), joints });
            }
            for (joint, (knot, l)) in knots.iter().zip(limits).enumerate() {
                check_knot(point, joint, knot, l)?;
            }
        }
        let knots: Vec<Knot> = points.iter().flatten().copied().collect();
        let segments = (1..points.len())
            .flat_map(|k| {
                let duration_s = seconds(times_ns[k] - times_ns[k - 1]);
                let (from, to) = (&knots[(k - 1) * joints..k * joints], &knots[k * joints..(k + 1) * joints]);
                from.iter()
                    .zip(to)
                    .map(move |(a, b)| Segment::new(Interpolation::between(a, b), setpoint(a), setpoint(b), duration_s))
            })
            .collect();
        Ok(Trajectory { joints, times_ns: times_ns.to_vec(), knots, segments })
    }

    /// Joints.
    pub fn joints(&self) -> usize {
        self.joints
    }

    /// Points.
    pub fn points(&self) -> usize {
        self.times_ns.len()
    }

    /// The last point's time from the start, ns.
    pub fn duration_ns(&self) -> u64 {
        self.times_ns[self.times_ns.len() - 1]
    }

    /// Joint `joint`'s knot at point `point`.
    pub fn knot(&self, point: usize, joint: usize) -> Knot {
        self.knots[point * self.joints + joint]
    }

    /// The interpolation of joint `joint` toward point `point` (from the set-point at the
    /// start for point 0).
    pub fn interpolation(&self, point: usize, joint: usize) -> Interpolation {
        let to = &self.knots[point * self.joints + joint];
        match point {
            0 => Interpolation::toward(to),
            _ => Interpolation::between(&self.knots[(point - 1) * self.joints + joint], to),
        }
    }

    /// Joint `joint`'s segment from `from`, the set-point it has at the start, to the first
    /// point. No allocation.
    pub fn lead_in(&self, joint: usize, from: Setpoint) -> Segment {
        let to = &self.knots[joint];
        Segment::new(Interpolation::toward(to), from, setpoint(to), seconds(self.times_ns[0]))
    }

    /// The point the trajectory approaches `t_ns` after its start; [`points`](Self::points)
    /// once it is past the last.
    pub fn segment(&self, t_ns: u64) -> usize {
        self.times_ns.partition_point(|&t| t <= t_ns)
    }

    /// Joint `joint`'s set-point `t_ns` after the start, with `lead_in` its segment to the
    /// first point. From the last point's time on, that point's position, at rest. A point's
    /// time gives that point exactly. No allocation.
    pub fn at(&self, lead_in: &Segment, t_ns: u64, joint: usize) -> Setpoint {
        match self.segment(t_ns) {
            0 => lead_in.at(seconds(t_ns)),
            k if k == self.points() => Setpoint { position: self.knot(k - 1, joint).position, ..Setpoint::default() },
            k => self.segments[(k - 1) * self.joints + joint].at(seconds(t_ns - self.times_ns[k - 1])),
        }
    }
}

fn check_knot(point: usize, joint: usize, knot: &Knot, limits: &Limits) -> Result<(), TrajectoryError> {
    let values = [("position", Some(knot.position)), ("velocity", knot.velocity), ("acceleration", knot.acceleration)];
    for (what, value) in values {
        if let Some(value) = value.filter(|v| !v.is_finite()) {
            return Err(TrajectoryError::NotFinite { point, joint, what, value });
        }
    }
    if knot.acceleration.is_some() && knot.velocity.is_none() {
        return Err(TrajectoryError::AccelerationWithoutVelocity { point, joint });
    }
    if !(limits.min..=limits.max).contains(&knot.position) {
        return Err(TrajectoryError::OutOfLimits {
            point,
            joint,
            position: knot.position,
            min: limits.min,
            max: limits.max,
        });
    }
    Ok(())
}

/// Why a trajectory is refused before anything moves. Points and joints count from 0, in the
/// order given; positions are counts, velocities counts/s, accelerations counts/s².
#[derive(Clone, Debug, PartialEq)]
pub enum TrajectoryError {
    /// A trajectory for no joint.
    NoJoints,
    /// A trajectory of no point.
    NoPoints,
    /// Points and their times of different numbers.
    TimesCount {
        /// Points given.
        points: usize,
        /// Times given.
        times: usize,
    },
    /// A point with another number of values than the trajectory has joints.
    JointCount {
        /// The point.
        point: usize,
        /// Values it gives.
        given: usize,
        /// Joints of the trajectory.
        joints: usize,
    },
    /// Limits for another number of joints than the trajectory has.
    LimitsCount {
        /// Limits given.
        given: usize,
        /// Joints of the trajectory.
        joints: usize,
    },
    /// Tolerances for another number of joints than the trajectory has.
    TolerancesCount {
        /// Tolerances given.
        given: usize,
        /// Joints of the trajectory.
        joints: usize,
    },
    /// A joint's limits that are not finite or whose minimum is above the maximum.
    BadLimits {
        /// The joint.
        joint: usize,
        /// The minimum given.
        min: f64,
        /// The maximum given.
        max: f64,
    },
    /// A point's time from the start that is not after the previous point's (or, for the first
    /// point, after the start).
    TimeNotIncreasing {
        /// The point.
        point: usize,
        /// Its time from the start, ns.
        time_ns: u64,
        /// The time it must be after, ns (0: the start).
        after_ns: u64,
    },
    /// A position, velocity or acceleration that is NaN or infinite.
    NotFinite {
        /// The point.
        point: usize,
        /// The joint.
        joint: usize,
        /// "position", "velocity" or "acceleration".
        what: &'static str,
        /// The value given.
        value: f64,
    },
    /// A position outside the joint's limits.
    OutOfLimits {
        /// The point.
        point: usize,
        /// The joint.
        joint: usize,
        /// The position given.
        position: f64,
        /// The joint's minimum.
        min: f64,
        /// The joint's maximum.
        max: f64,
    },
    /// An acceleration given without a velocity (a quintic segment needs both).
    AccelerationWithoutVelocity {
        /// The point.
        point: usize,
        /// The joint.
        joint: usize,
    },
    /// A drive named for two joints.
    DriveTwice {
        /// The drive's position on the bus.
        slave: u16,
        /// The first joint it was named for.
        first: usize,
        /// The second.
        second: usize,
    },
    /// A drive that cannot follow a trajectory now: not on the bus, not sequenced, not in
    /// Operation enabled, not in a cyclic position mode, or without its position target mapped.
    DriveNotReady {
        /// The joint.
        joint: usize,
        /// The drive's position on the bus.
        slave: u16,
        /// Why, with what it would need.
        why: String,
    },
}

impl TrajectoryError {
    /// This error with each joint called as `names` calls it (its name), where it names one.
    pub fn naming<'a>(&'a self, names: &'a [String]) -> impl fmt::Display + 'a {
        Named { error: self, names }
    }

    /// Writes this error, each joint it names called `joint(index)`.
    fn write(&self, f: &mut fmt::Formatter<'_>, joint: &dyn Fn(usize) -> String) -> fmt::Result {
        write!(f, "trajectory refused, nothing moved: ")?;
        match self {
            TrajectoryError::NoJoints => write!(f, "it names no joint; at least one is needed"),
            TrajectoryError::NoPoints => write!(f, "it has no point; at least one is needed"),
            TrajectoryError::TimesCount { points, times } => {
                write!(f, "{points} point(s) but {times} time(s) from the start; one time per point is needed")
            }
            TrajectoryError::JointCount { point, given, joints } => {
                write!(f, "point {point} gives {given} joint value(s); the trajectory has {joints} joint(s)")
            }
            TrajectoryError::LimitsCount { given, joints } => {
                write!(f, "{given} joint limit(s) given; the trajectory has {joints} joint(s)")
            }
            TrajectoryError::TolerancesCount { given, joints } => {
                write!(f, "{given} joint tolerance(s) given; the trajectory has {joints} joint(s)")
            }
            TrajectoryError::BadLimits { joint: j, min, max } => {
                write!(f, "{}: limits {min} ..= {max} counts; they must be finite with min <= max", joint(*j))
            }
            TrajectoryError::TimeNotIncreasing { point, time_ns, after_ns: 0 } => write!(
                f,
                "point {point}: time from the start {time_ns} ns; the first point's must be after the start (> 0 ns)"
            ),
            TrajectoryError::TimeNotIncreasing { point, time_ns, after_ns } => write!(
                f,
                "point {point}: time from the start {time_ns} ns is not after the previous point's {after_ns} ns; \
                 times must increase strictly"
            ),
            TrajectoryError::NotFinite { point, joint: j, what, value } => {
                write!(f, "point {point}, {}: {what} {value}; it must be a finite number", joint(*j))
            }
            TrajectoryError::OutOfLimits { point, joint: j, position, min, max } => write!(
                f,
                "point {point}, {}: position {position} counts is outside the joint's limits {min} ..= {max} counts",
                joint(*j)
            ),
            TrajectoryError::AccelerationWithoutVelocity { point, joint: j } => write!(
                f,
                "point {point}, {}: an acceleration without a velocity; give both (quintic), the velocity alone \
                 (cubic) or neither (linear)",
                joint(*j)
            ),
            TrajectoryError::DriveTwice { slave, first, second } => {
                write!(
                    f,
                    "drive {slave} is named for {} and {}; each drive may be one joint",
                    joint(*first),
                    joint(*second)
                )
            }
            TrajectoryError::DriveNotReady { joint: j, slave, why } => {
                write!(f, "{} (drive {slave}): {why}", joint(*j))
            }
        }
    }
}

impl fmt::Display for TrajectoryError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        self.write(f, &|j| format!("joint {j}"))
    }
}

/// A [`TrajectoryError`] naming its joints (see [`TrajectoryError::naming`]).
struct Named<'a> {
    error: &'a TrajectoryError,
    names: &'a [String],
}

impl fmt::Display for Named<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        self.error.write(f, &|j| self.names.get(j).cloned().unwrap_or_else(|| format!("joint {j}")))
    }
}

impl std::error::Error for TrajectoryError {}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    const S: u64 = 1_000_000_000;

    fn close(a: f64, b: f64, tolerance: f64) -> bool {
        (a - b).abs() <= tolerance * (1.0 + a.abs().max(b.abs()))
    }

    fn one_joint(times_ns: &[u64], knots: &[Knot]) -> Trajectory {
        let points: Vec<Vec<Knot>> = knots.iter().map(|k| vec![*k]).collect();
        Trajectory::new(1, times_ns, &points, None).unwrap()
    }

    #[test]
    fn linear_goes_at_constant_velocity_from_the_set_point_at_the_start() {
        let t = one_joint(&[S, 3 * S], &[Knot::position(1000.0), Knot::position(-1000.0)]);
        let lead_in = t.lead_in(0, Setpoint { position: 500.0, ..Setpoint::default() });
        assert_eq!(t.at(&lead_in, 0, 0).position, 500.0);
        assert_eq!(t.at(&lead_in, S / 2, 0), Setpoint { position: 750.0, velocity: 500.0, acceleration: 0.0 });
        assert_eq!(t.at(&lead_in, S, 0).position, 1000.0);
        assert_eq!(t.at(&lead_in, 2 * S, 0), Setpoint { position: 0.0, velocity: -1000.0, acceleration: 0.0 });
        assert_eq!(t.at(&lead_in, 3 * S, 0), Setpoint { position: -1000.0, velocity: 0.0, acceleration: 0.0 });
        assert_eq!(t.at(&lead_in, 10 * S, 0).position, -1000.0);
        assert_eq!((t.segment(0), t.segment(S - 1), t.segment(S), t.segment(3 * S)), (0, 0, 1, 2));
        assert_eq!(t.interpolation(1, 0), Interpolation::Linear);
    }

    #[test]
    fn velocities_make_cubic_segments_and_accelerations_quintic_ones() {
        let cubic = |p, v| Knot { position: p, velocity: Some(v), acceleration: None };
        let quintic = |p, v, a| Knot { position: p, velocity: Some(v), acceleration: Some(a) };
        let points = vec![
            vec![cubic(100.0, 10.0), quintic(0.0, 1.0, 2.0)],
            vec![cubic(200.0, 0.0), quintic(5.0, 0.0, -1.0)],
            vec![Knot::position(0.0), quintic(9.0, 0.0, 0.0)],
        ];
        let t = Trajectory::new(2, &[S, 2 * S, 3 * S], &points, None).unwrap();
        let kinds: Vec<_> = (0..3).map(|k| (t.interpolation(k, 0), t.interpolation(k, 1))).collect();
        assert_eq!(
            kinds,
            [
                (Interpolation::Cubic, Interpolation::Quintic),
                (Interpolation::Cubic, Interpolation::Quintic),
                (Interpolation::Linear, Interpolation::Quintic)
            ]
        );
    }

    #[test]
    fn refuses_with_the_point_the_joint_and_what_is_allowed() {
        let limits = [Limits { min: -10.0, max: 10.0 }, Limits { min: 0.0, max: 100.0 }];
        let refused = |times: &[u64], points: Vec<Vec<Knot>>| {
            Trajectory::new(2, times, &points, Some(&limits)).unwrap_err().to_string()
        };
        let p = |a: f64, b: f64| vec![Knot::position(a), Knot::position(b)];
        let e = refused(&[S, 2 * S], vec![p(0.0, 0.0), p(0.0, 101.0)]);
        assert!(
            e.contains("point 1, joint 1: position 101 counts is outside the joint's limits 0 ..= 100 counts"),
            "{e}"
        );
        assert!(e.starts_with("trajectory refused, nothing moved: "), "{e}");
        let e = refused(&[S, S], vec![p(0.0, 0.0), p(0.0, 1.0)]);
        assert!(e.contains("point 1: time from the start 1000000000 ns is not after the previous point's"), "{e}");
        let e = refused(&[0], vec![p(0.0, 0.0)]);
        assert!(e.contains("the first point's must be after the start (> 0 ns)"), "{e}");
        let e = refused(&[S], vec![p(0.0, f64::NAN)]);
        assert!(e.contains("point 0, joint 1: position NaN; it must be a finite number"), "{e}");
        let nan_velocity = Knot { velocity: Some(f64::INFINITY), ..Knot::position(0.0) };
        let e = refused(&[S], vec![vec![nan_velocity, Knot::position(0.0)]]);
        assert!(e.contains("point 0, joint 0: velocity inf"), "{e}");
        let e = refused(&[S], vec![vec![Knot::position(0.0)]]);
        assert!(e.contains("point 0 gives 1 joint value(s); the trajectory has 2 joint(s)"), "{e}");
        let e = refused(&[S, 2 * S], vec![p(0.0, 0.0), vec![Knot::position(0.0)]]);
        assert!(e.contains("point 1 gives 1 joint value(s)"), "{e}");
        let e = refused(&[S], vec![vec![Knot { acceleration: Some(1.0), ..Knot::position(0.0) }, Knot::position(0.0)]]);
        assert!(e.contains("point 0, joint 0: an acceleration without a velocity"), "{e}");
        let e = refused(&[S, 2 * S], vec![p(0.0, 0.0)]);
        assert!(e.contains("1 point(s) but 2 time(s)"), "{e}");
        let e = Trajectory::new(2, &[S], &[p(0.0, 0.0)], Some(&limits[..1])).unwrap_err().to_string();
        assert!(e.contains("1 joint limit(s) given; the trajectory has 2 joint(s)"), "{e}");
        let bad = [Limits { min: 1.0, max: 0.0 }, limits[1]];
        let e = Trajectory::new(2, &[S], &[p(0.0, 0.0)], Some(&bad)).unwrap_err().to_string();
        assert!(e.contains("joint 0: limits 1 ..= 0 counts"), "{e}");
        assert_eq!(Trajectory::new(1, &[], &[], None), Err(TrajectoryError::NoPoints));
        assert_eq!(Trajectory::new(0, &[S], &[vec![]], None), Err(TrajectoryError::NoJoints));
        // Without limits, what a 32-bit target carries.
        let e = Trajectory::new(1, &[S], &[vec![Knot::position(3e9)]], None).unwrap_err().to_string();
        assert!(e.contains("outside the joint's limits -2147483648 ..= 2147483647 counts"), "{e}");
    }

    fn knot_strategy() -> impl Strategy<Value = Knot> {
        (-1e6..1e6f64, -1e5..1e5f64, -1e5..1e5f64, 0..3u8).prop_map(|(p, v, a, kind)| Knot {
            position: p,
            velocity: (kind >= 1).then_some(v),
            acceleration: (kind == 2).then_some(a),
        })
    }

    /// A trajectory of 1..5 points of one kind for one joint, with its times.
    fn trajectory_strategy() -> impl Strategy<Value = (Vec<u64>, Vec<Knot>, Setpoint)> {
        (1usize..5, 0..3u8)
            .prop_flat_map(|(n, kind)| {
                let knots = prop::collection::vec(knot_strategy(), n).prop_map(move |ks| {
                    ks.into_iter()
                        .map(|k| Knot {
                            velocity: (kind >= 1).then(|| k.velocity.unwrap_or(0.0)),
                            acceleration: (kind == 2).then(|| k.acceleration.unwrap_or(0.0)),
                            ..k
                        })
                        .collect::<Vec<_>>()
                });
                let gaps = prop::collection::vec(1_000_000u64..2 * S, n);
                let from = (-1e6..1e6f64, -1e5..1e5f64, -1e5..1e5f64)
                    .prop_map(|(position, velocity, acceleration)| Setpoint { position, velocity, acceleration });
                (gaps, knots, from)
            })
            .prop_map(|(gaps, knots, from)| {
                let times = gaps.iter().scan(0, |t, g| {
                    *t += g;
                    Some(*t)
                });
                (times.collect(), knots, from)
            })
    }

    proptest! {
        #[test]
        fn endpoints_are_hit_exactly_and_the_derivatives_given_are_followed(
            (times, knots, from) in trajectory_strategy()
        ) {
            let t = one_joint(&times, &knots);
            let lead_in = t.lead_in(0, from);
            // The set-point at the start, with its derivatives where the first point's kind
            // carries them.
            let start = t.at(&lead_in, 0, 0);
            prop_assert_eq!(start.position, from.position);
            match t.interpolation(0, 0) {
                Interpolation::Linear => {}
                Interpolation::Cubic => prop_assert_eq!(start.velocity, from.velocity),
                Interpolation::Quintic => {
                    prop_assert_eq!(start.velocity, from.velocity);
                    prop_assert!(close(start.acceleration, from.acceleration, 1e-9));
                }
            }
            for (k, knot) in knots.iter().enumerate() {
                // At a point's time the next segment begins with the point itself.
                let at = t.at(&lead_in, times[k], 0);
                prop_assert_eq!(at.position, knot.position);
                // Approached from before, the segment ends there and with its derivatives, to
                // the rounding of its coefficients: relative to what it spans per second^n.
                let (previous, span_ns) = if k == 0 { (from, times[0]) } else {
                    (setpoint(&knots[k - 1]), times[k] - times[k - 1])
                };
                let before = if k == 0 { lead_in.at(seconds(span_ns)) } else {
                    t.segments[k - 1].at(seconds(span_ns))
                };
                let span = seconds(span_ns);
                let size = 1.0 + previous.position.abs() + knot.position.abs()
                    + (previous.velocity.abs() + knot.velocity.unwrap_or(0.0).abs()) * span
                    + (previous.acceleration.abs() + knot.acceleration.unwrap_or(0.0).abs()) * span * span;
                let tolerance = |n: i32| 1e-9 * size / span.powi(n);
                prop_assert!((before.position - knot.position).abs() <= tolerance(0), "{:?} at point {}", before, k);
                let kind = t.interpolation(k, 0);
                if kind != Interpolation::Linear {
                    let v = knot.velocity.unwrap();
                    prop_assert!((before.velocity - v).abs() <= tolerance(1), "{:?} {:?}", before, knot);
                }
                if kind == Interpolation::Quintic {
                    let a = knot.acceleration.unwrap();
                    prop_assert!((before.acceleration - a).abs() <= tolerance(2), "{:?} {:?}", before, knot);
                }
                let next_kind = (k + 1 < knots.len()).then(|| t.interpolation(k + 1, 0));
                if next_kind.is_some_and(|n| n != Interpolation::Linear) {
                    prop_assert_eq!(at.velocity, knot.velocity.unwrap());
                }
                if next_kind == Some(Interpolation::Quintic) {
                    prop_assert!(close(at.acceleration, knot.acceleration.unwrap(), 1e-9));
                }
            }
            let end = t.at(&lead_in, t.duration_ns() + 1, 0);
            prop_assert_eq!(end, Setpoint { position: knots[knots.len() - 1].position, ..Setpoint::default() });
        }

        #[test]
        fn the_position_is_continuous_between_the_points(
            (times, knots, from) in trajectory_strategy(), probe in 0.0..1.0f64
        ) {
            let t = one_joint(&times, &knots);
            let lead_in = t.lead_in(0, from);
            // Around any time, the set-point moves no more than its velocity says.
            let at_ns = (probe * t.duration_ns() as f64) as u64;
            let dt_ns = 1000;
            let (a, b) = (t.at(&lead_in, at_ns, 0), t.at(&lead_in, at_ns + dt_ns, 0));
            // Velocity times the time plus what the acceleration adds; a linear segment's
            // velocity steps at its points, its position does not.
            let bound = a.velocity.abs().max(b.velocity.abs()) * seconds(dt_ns)
                + a.acceleration.abs().max(b.acceleration.abs()) * seconds(dt_ns).powi(2);
            prop_assert!((b.position - a.position).abs() <= bound * 1.01 + 1e-6 * (1.0 + a.position.abs()) + 1e-2,
                "{:?} -> {:?} in {} ns", a, b, dt_ns);
        }
    }
}
