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

/// A joint's limits in the drive's units: the positions it may take, and where set the speed
/// and acceleration it may move at. Every point of a trajectory and every instant of the path
/// interpolated between them is judged by them.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Limits {
    /// The lowest position, counts.
    pub min: f64,
    /// The highest position, counts.
    pub max: f64,
    /// The largest velocity magnitude, counts/s (infinite: none).
    pub max_velocity: f64,
    /// The largest acceleration magnitude, counts/s² (infinite: none). Where set, the set-point's
    /// velocity may not step either: a step is an acceleration without bound.
    pub max_acceleration: f64,
}

impl Limits {
    /// What an INT32 position target can carry, at any speed.
    pub const TARGET: Limits = Limits {
        min: i32::MIN as f64,
        max: i32::MAX as f64,
        max_velocity: f64::INFINITY,
        max_acceleration: f64::INFINITY,
    };

    /// Whether these are limits at all: finite positions with min <= max, speeds above 0 (or
    /// infinite).
    fn valid(&self) -> bool {
        self.min.is_finite()
            && self.max.is_finite()
            && self.min <= self.max
            && self.max_velocity > 0.0
            && self.max_acceleration > 0.0
    }

    /// The first of these limits that `segment`, over `duration_s`, goes past (positions by
    /// more than the half count a target is rounded by, speeds by more than their rounding),
    /// with the furthest it goes. No allocation.
    pub fn excess(&self, segment: &Segment, duration_s: f64) -> Option<Excess> {
        let position = segment.c;
        let highest = peak(position, 5, duration_s);
        if highest > self.max + 0.5 {
            return Some(Excess { limit: Limit::Position, value: highest, allowed: self.max });
        }
        let lowest = -peak(position.map(|c| -c), 5, duration_s);
        if lowest < self.min - 0.5 {
            return Some(Excess { limit: Limit::Position, value: lowest, allowed: self.min });
        }
        let speeds = [
            (Limit::Velocity, derivative(position), 4, self.max_velocity),
            (Limit::Acceleration, derivative(derivative(position)), 3, self.max_acceleration),
        ];
        for (limit, c, degree, allowed) in speeds {
            if allowed.is_infinite() {
                continue;
            }
            let (up, down) = (peak(c, degree, duration_s), peak(c.map(|c| -c), degree, duration_s));
            let value = if up >= down { up } else { -down };
            if value.abs() > allowed * (1.0 + SPEED_ROUNDING) {
                return Some(Excess { limit, value, allowed });
            }
        }
        None
    }

    /// Whether a step of the set-point's velocity from `from` to `to` counts/s goes past the
    /// acceleration limit: where one is set, any step beyond rounding does.
    pub fn steps(&self, from: f64, to: f64) -> bool {
        self.max_acceleration.is_finite() && (to - from).abs() > SPEED_ROUNDING * (1.0 + from.abs().max(to.abs()))
    }
}

/// A joint as the crate judges every motion of it: its name, its limits, and how its values
/// read in words. Handed down once per drive (`CycleThread::set_joint_limits`).
#[derive(Clone, Debug, PartialEq)]
pub struct JointLimits {
    /// The joint's name.
    pub name: String,
    /// Its limits, in counts.
    pub limits: Limits,
    /// How its values read.
    pub scale: Scale,
}

impl JointLimits {
    /// Why these are no limits (see [`TrajectoryError::BadLimits`]), or `None`.
    pub fn check(&self) -> Option<TrajectoryError> {
        let limits = self.limits;
        let scale_ok = self.scale.per_count.is_finite() && self.scale.per_count != 0.0 && self.scale.offset.is_finite();
        (!(limits.valid() && scale_ok)).then_some(TrajectoryError::BadLimits { joint: 0, limits })
    }
}

/// How far past a speed limit rounding may take a value without it counting, relative.
const SPEED_ROUNDING: f64 = 1e-9;

named_variants! {
    /// Which of a joint's limits.
    pub enum Limit {
        /// Its positions.
        Position => "position",
        /// Its velocity.
        Velocity => "max_velocity",
        /// Its acceleration.
        Acceleration => "max_acceleration",
    }
    /// The limit's parameter name, as the node's limits.* parameters spell it.
    fn name;
}

/// A limit gone past: the furthest value reached (signed; counts, counts/s or counts/s²) and
/// the limit it went past (for a position the end it went past, else the magnitude allowed).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Excess {
    /// Which limit.
    pub limit: Limit,
    /// The furthest value reached.
    pub value: f64,
    /// What was allowed.
    pub allowed: f64,
}

/// How the segment to a trajectory's first point goes past its joint's limits.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Breach {
    /// A limit gone past.
    Past(Excess),
    /// Where an acceleration limit is set: the set-point's velocity steps from `from` to `to`
    /// (counts/s) at the start (`point` None) or at point `point`.
    Step {
        /// Where: `None` at the start, else the point.
        point: Option<usize>,
        /// The velocity before, counts/s.
        from: f64,
        /// The velocity after, counts/s.
        to: f64,
        /// The acceleration allowed, counts/s².
        max_acceleration: f64,
    },
}

/// How a joint's values read in words: a count is `per_count` of `unit`, and position 0 counts
/// is `offset` (signed, so that a joint turning against its motor reads right).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Scale {
    /// Units per count.
    pub per_count: f64,
    /// The position at 0 counts.
    pub offset: f64,
    /// The unit of a position.
    pub unit: Unit,
}

named_variants! {
    /// The unit a joint's positions are given in.
    pub enum Unit {
        /// The drive's counts.
        Counts => "counts",
        /// Radians (a rotary joint).
        Radian => "rad",
        /// Metres (a linear joint).
        Metre => "m",
    }
    /// Its symbol.
    fn name;
}

impl Scale {
    /// The drive's own: counts.
    pub const COUNTS: Scale = Scale { per_count: 1.0, offset: 0.0, unit: Unit::Counts };

    /// `value` of `limit`'s kind (a position when `Limit::Position`) in words, e.g. "13.4 rad/s".
    pub fn words(&self, limit: Limit, value: f64) -> String {
        let unit = self.unit.name();
        match limit {
            Limit::Position => format!("{} {unit}", trimmed(value * self.per_count + self.offset)),
            Limit::Velocity => format!("{} {unit}/s", trimmed(value * self.per_count)),
            Limit::Acceleration => format!("{} {unit}/s²", trimmed(value * self.per_count)),
        }
    }

    /// A magnitude of `limit`'s kind in words (a position's offset not added: a distance).
    pub fn magnitude(&self, limit: Limit, value: f64) -> String {
        match limit {
            Limit::Position => format!("{} {}", trimmed((value * self.per_count).abs()), self.unit.name()),
            _ => self.words(limit, value.abs() * self.per_count.signum()),
        }
    }

    /// Which of a joint's position limits `position` went past, `end` being that limit (both
    /// counts): "max_position" where it is the higher in the joint's units.
    pub fn end_name(&self, position: f64, end: f64) -> &'static str {
        let (value, limit) = (position * self.per_count, end * self.per_count);
        if value > limit {
            "max_position"
        } else {
            "min_position"
        }
    }

    /// Positions `min ..= max` counts in words, the lower end first.
    pub fn range(&self, min: f64, max: f64) -> String {
        let (a, b) = (min * self.per_count + self.offset, max * self.per_count + self.offset);
        format!("{} ..= {} {}", trimmed(a.min(b)), trimmed(a.max(b)), self.unit.name())
    }
}

/// `x` to six significant digits (all of its integer digits), without trailing zeros: how the
/// drive profile writes a joint's values in words.
pub fn trimmed(x: f64) -> String {
    let magnitude = if x == 0.0 { 0 } else { x.abs().log10().floor() as i32 };
    let decimals = (5 - magnitude).clamp(0, 12) as usize;
    let text = format!("{x:.decimals$}");
    let text = if text.contains('.') { text.trim_end_matches('0').trim_end_matches('.') } else { &text };
    if text == "-0" {
        "0".into()
    } else {
        text.into()
    }
}

/// The coefficients of the derivative of the polynomial Σ cᵢ·sⁱ.
fn derivative(c: [f64; 6]) -> [f64; 6] {
    [c[1], 2.0 * c[2], 3.0 * c[3], 4.0 * c[4], 5.0 * c[5], 0.0]
}

/// How deep [`peak`] halves an interval before it takes the bound there as the peak.
const PEAK_DEPTH: u32 = 48;

/// The largest value of the polynomial Σ cᵢ·sⁱ of `degree` (at most 5) over s in
/// `[0, duration_s]`, to a relative 1e-9: its Bernstein coefficients bound it (the polynomial
/// lies in their convex hull and meets the end ones), and halving the interval where the bound
/// is above the best value found narrows it. Arithmetic on the stack, no allocation, so that
/// the cycle thread may judge a segment too.
fn peak(c: [f64; 6], degree: usize, duration_s: f64) -> f64 {
    // On u in [0, 1]: aᵢ = cᵢ·Tⁱ; then bₖ = Σᵢ₌₀..ₖ C(k,i)/C(n,i)·aᵢ.
    let a: [f64; 6] = std::array::from_fn(|i| c[i] * duration_s.powi(i as i32));
    let b: [f64; 6] =
        std::array::from_fn(|k| (0..=k.min(degree)).map(|i| binomial(k, i) / binomial(degree, i) * a[i]).sum());
    let mut best = b[0].max(b[degree]);
    descend(&b, degree, 0, &mut best);
    best
}

fn binomial(n: usize, k: usize) -> f64 {
    (0..k).fold(1.0, |r, i| r * (n - i) as f64 / (i + 1) as f64)
}

/// Raises `best` to the peak of the polynomial of Bernstein coefficients `b` where it is above.
fn descend(b: &[f64; 6], degree: usize, depth: u32, best: &mut f64) {
    *best = best.max(b[0]).max(b[degree]);
    let bound = b[..=degree].iter().copied().fold(f64::NEG_INFINITY, f64::max);
    if bound <= *best + 1e-9 * (1.0 + best.abs()) {
        return;
    }
    if depth == PEAK_DEPTH {
        *best = bound;
        return;
    }
    // de Casteljau at u = 1/2: the left half's coefficients run down the first column, the
    // right half's up the last.
    let (mut left, mut right, mut row) = ([0.0; 6], [0.0; 6], *b);
    for k in 0..=degree {
        left[k] = row[0];
        right[degree - k] = row[degree - k];
        for i in 0..degree - k {
            row[i] = (row[i] + row[i + 1]) / 2.0;
        }
    }
    descend(&left, degree, depth + 1, best);
    descend(&right, degree, depth + 1, best);
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
    /// Per joint: the limits it was validated against, which the segment to the first point
    /// is judged by once the set-point it starts from is known.
    limits: Vec<Limits>,
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
    /// point's time from the start) against `limits` (one per joint; an INT32 target's range,
    /// at any speed, when `None`) and computes the segments between the points. Refuses the
    /// whole trajectory, naming the point, the joint and what is allowed, when a value is NaN or
    /// infinite, a point or the path interpolated between two points goes past its joint's
    /// limits (position, velocity, acceleration; where an acceleration limit is set, a step of
    /// the velocity at a point too), a time does not increase strictly from above 0, an
    /// acceleration comes without a velocity, or the counts do not match. The segment to the
    /// first point is judged once the set-point it starts from is known
    /// ([`lead_in_breach`](Self::lead_in_breach)).
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
            Some(l) if l.len() != joints => {
                return Err(TrajectoryError::PerJointCount { what: "limit", given: l.len(), joints })
            }
            Some(l) => l.to_vec(),
            None => vec![Limits::TARGET; joints],
        };
        if let Some((joint, l)) = limits.iter().enumerate().find(|(_, l)| !l.valid()) {
            return Err(TrajectoryError::BadLimits { joint, limits: *l });
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
            for (joint, (knot, l)) in knots.iter().zip(&limits).enumerate() {
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
        let trajectory = Trajectory { joints, times_ns: times_ns.to_vec(), knots, segments, limits };
        for joint in 0..joints {
            trajectory.check_path(joint)?;
        }
        Ok(trajectory)
    }

    /// Judges joint `joint`'s path from the first point on: each segment's positions and
    /// speeds, and where an acceleration limit is set, that the velocity does not step at a
    /// point (nor after the last, where the joint comes to rest).
    fn check_path(&self, joint: usize) -> Result<(), TrajectoryError> {
        let limits = &self.limits[joint];
        for point in 1..self.points() {
            let segment = &self.segments[(point - 1) * self.joints + joint];
            let duration_s = seconds(self.times_ns[point] - self.times_ns[point - 1]);
            if let Some(excess) = limits.excess(segment, duration_s) {
                return Err(TrajectoryError::SegmentPastLimit { point, joint, excess });
            }
            let (from, to) = (segment.at(duration_s).velocity, self.leaving(point, joint));
            if limits.steps(from, to) {
                let max_acceleration = limits.max_acceleration;
                return Err(TrajectoryError::VelocityStep { point: Some(point), joint, from, to, max_acceleration });
            }
        }
        Ok(())
    }

    /// Joint `joint`'s velocity as it leaves point `point`: the next segment's at its start, 0
    /// after the last point.
    fn leaving(&self, point: usize, joint: usize) -> f64 {
        match point + 1 < self.points() {
            true => self.segments[point * self.joints + joint].at(0.0).velocity,
            false => 0.0,
        }
    }

    /// How joint `joint`'s segment to the first point, from `from` (the set-point it has when
    /// the trajectory takes over), goes past its limits, if it does: past a position (further
    /// than `from` is, where it stands past one) or a speed, or, where an acceleration limit is
    /// set, with a step of the velocity at its start or at the first point. No allocation.
    pub fn lead_in_breach(&self, joint: usize, from: Setpoint) -> Option<Breach> {
        // A joint that stands past a position limit (it coasted there) may move back; it may not go further out.
        let given = &self.limits[joint];
        let limits = &Limits { min: given.min.min(from.position), max: given.max.max(from.position), ..*given };
        let lead_in = self.lead_in(joint, from);
        let duration_s = seconds(self.times_ns[0]);
        if let Some(excess) = limits.excess(&lead_in, duration_s) {
            return Some(Breach::Past(excess));
        }
        let steps = [
            (None, from.velocity, lead_in.at(0.0).velocity),
            (Some(0), lead_in.at(duration_s).velocity, self.leaving(0, joint)),
        ];
        let max_acceleration = limits.max_acceleration;
        let (point, from, to) = steps.into_iter().find(|(_, a, b)| limits.steps(*a, *b))?;
        Some(Breach::Step { point, from, to, max_acceleration })
    }

    /// The refusal of `breach` on joint `joint`'s segment to the first point.
    pub fn lead_in_error(joint: usize, breach: Breach) -> TrajectoryError {
        match breach {
            Breach::Past(excess) => TrajectoryError::SegmentPastLimit { point: 0, joint, excess },
            Breach::Step { point, from, to, max_acceleration } => {
                TrajectoryError::VelocityStep { point, joint, from, to, max_acceleration }
            }
        }
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
    let (position, min, max) = (knot.position, limits.min, limits.max);
    if !(min..=max).contains(&position) {
        return Err(TrajectoryError::OutOfLimits { point, joint, position, min, max });
    }
    let speeds = [
        (Limit::Velocity, knot.velocity, limits.max_velocity),
        (Limit::Acceleration, knot.acceleration, limits.max_acceleration),
    ];
    for (limit, value, allowed) in speeds {
        if let Some(value) = value.filter(|v| v.abs() > allowed) {
            return Err(TrajectoryError::KnotPastLimit { point, joint, excess: Excess { limit, value, allowed } });
        }
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
    /// Limits or tolerances for another number of joints than the trajectory has.
    PerJointCount {
        /// "limit" or "tolerance".
        what: &'static str,
        /// How many were given.
        given: usize,
        /// Joints of the trajectory.
        joints: usize,
    },
    /// A joint's limits whose positions are not finite or whose minimum is above the maximum,
    /// or whose speeds are not above 0.
    BadLimits {
        /// The joint.
        joint: usize,
        /// The limits given.
        limits: Limits,
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
    /// A point's velocity or acceleration past its joint's limit.
    KnotPastLimit {
        /// The point.
        point: usize,
        /// The joint.
        joint: usize,
        /// The limit and the value.
        excess: Excess,
    },
    /// The path interpolated toward a point goes past its joint's limits.
    SegmentPastLimit {
        /// The point the segment goes to (0: from the set-point in force at the start).
        point: usize,
        /// The joint.
        joint: usize,
        /// The limit and the furthest value reached.
        excess: Excess,
    },
    /// Where the joint's acceleration is limited, its set-point's velocity steps.
    VelocityStep {
        /// Where: `None` at the start (from the set-point in force), else at this point (after
        /// the last, where the joint comes to rest).
        point: Option<usize>,
        /// The joint.
        joint: usize,
        /// The velocity before, counts/s.
        from: f64,
        /// The velocity after, counts/s.
        to: f64,
        /// The acceleration allowed, counts/s².
        max_acceleration: f64,
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
    /// A drive of the trajectory in force that the new one does not drive is moving: taking
    /// over would stop it dead.
    LeavesMoving {
        /// The drive's position on the bus.
        slave: u16,
        /// Its joint's name, where known.
        name: Option<String>,
        /// Its set-point's velocity, in words.
        velocity: String,
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
    /// This error with each joint called as `names` calls it (its name), where it names one,
    /// and its values in the joint's units as `scales` gives them (counts where not given).
    pub fn naming<'a>(&'a self, names: &'a [String], scales: &'a [Scale]) -> impl fmt::Display + 'a {
        Named { error: self, names, scales }
    }

    /// Writes this error, each joint it names called `joint(index)` and its values worded by
    /// `scale(index)`.
    fn write(
        &self,
        f: &mut fmt::Formatter<'_>,
        joint: &dyn Fn(usize) -> String,
        scale: &dyn Fn(usize) -> Scale,
    ) -> fmt::Result {
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
            TrajectoryError::PerJointCount { what, given, joints } => {
                write!(f, "{given} joint {what}(s) given; the trajectory has {joints} joint(s)")
            }
            TrajectoryError::BadLimits { joint: j, limits: l } => write!(
                f,
                "{}: limits {} ..= {} counts, max velocity {} counts/s, max acceleration {} counts/s²; positions \
                 must be finite with min <= max, speeds above 0",
                joint(*j),
                l.min,
                l.max,
                l.max_velocity,
                l.max_acceleration
            ),
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
            TrajectoryError::OutOfLimits { point, joint: j, position, min, max } => {
                let s = scale(*j);
                let end = if position > max { *max } else { *min };
                write!(
                    f,
                    "point {point}, {}: position {} is past the joint's {} {} (its limits: {})",
                    joint(*j),
                    s.words(Limit::Position, *position),
                    s.end_name(*position, end),
                    s.words(Limit::Position, end),
                    s.range(*min, *max)
                )
            }
            TrajectoryError::KnotPastLimit { point, joint: j, excess } => {
                let (s, kind) = (scale(*j), if excess.limit == Limit::Velocity { "velocity" } else { "acceleration" });
                write!(
                    f,
                    "point {point}, {}: {kind} {} is past the joint's {} {}",
                    joint(*j),
                    s.words(excess.limit, excess.value),
                    excess.limit.name(),
                    s.magnitude(excess.limit, excess.allowed)
                )
            }
            TrajectoryError::SegmentPastLimit { point, joint: j, excess } => {
                let s = scale(*j);
                let segment = match point {
                    0 => "the segment to point 0, from the set-point in force,".to_string(),
                    _ => format!("the segment from point {} to point {point}", point - 1),
                };
                match excess.limit {
                    Limit::Position => write!(
                        f,
                        "{}: {segment} reaches position {}, past the joint's {} {}",
                        joint(*j),
                        s.words(Limit::Position, excess.value),
                        s.end_name(excess.value, excess.allowed),
                        s.words(Limit::Position, excess.allowed)
                    ),
                    limit => write!(
                        f,
                        "{}: {segment} reaches {} {}, past the joint's {} {}; give it more time",
                        joint(*j),
                        if limit == Limit::Velocity { "a velocity of" } else { "an acceleration of" },
                        s.words(limit, excess.value),
                        limit.name(),
                        s.magnitude(limit, excess.allowed)
                    ),
                }
            }
            TrajectoryError::VelocityStep { point, joint: j, from, to, max_acceleration } => {
                let s = scale(*j);
                let at = match point {
                    None => "at the start (from the set-point in force)".to_string(),
                    Some(p) => format!("at point {p}"),
                };
                write!(
                    f,
                    "{}: {at} the set-point's velocity steps from {} to {}, an acceleration without bound, past the \
                     joint's max_acceleration {}; where it is set, give every point a velocity (cubic) or a velocity \
                     and an acceleration (quintic), and end at rest",
                    joint(*j),
                    s.words(Limit::Velocity, *from),
                    s.words(Limit::Velocity, *to),
                    s.magnitude(Limit::Acceleration, *max_acceleration)
                )
            }
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
            TrajectoryError::LeavesMoving { slave, name, velocity } => write!(
                f,
                "{} (drive {slave}) moves at {velocity} in the trajectory in force, which this one would replace \
                 without driving it: it would stop dead; include it, or send this one once it is still",
                name.as_deref().unwrap_or("its joint")
            ),
        }
    }
}

impl fmt::Display for TrajectoryError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        self.write(f, &|j| format!("joint {j}"), &|_| Scale::COUNTS)
    }
}

/// A [`TrajectoryError`] naming its joints (see [`TrajectoryError::naming`]).
struct Named<'a> {
    error: &'a TrajectoryError,
    names: &'a [String],
    scales: &'a [Scale],
}

impl fmt::Display for Named<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        self.error.write(f, &|j| self.names.get(j).cloned().unwrap_or_else(|| format!("joint {j}")), &|j| {
            self.scales.get(j).copied().unwrap_or(Scale::COUNTS)
        })
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
        let limits =
            [Limits { min: -10.0, max: 10.0, ..Limits::TARGET }, Limits { min: 0.0, max: 100.0, ..Limits::TARGET }];
        let refused = |times: &[u64], points: Vec<Vec<Knot>>| {
            Trajectory::new(2, times, &points, Some(&limits)).unwrap_err().to_string()
        };
        let p = |a: f64, b: f64| vec![Knot::position(a), Knot::position(b)];
        let e = refused(&[S, 2 * S], vec![p(0.0, 0.0), p(0.0, 101.0)]);
        assert!(
            e.contains(
                "point 1, joint 1: position 101 counts is past the joint's max_position 100 counts (its limits: \
                 0 ..= 100 counts)"
            ),
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
        let bad = [Limits { min: 1.0, max: 0.0, ..Limits::TARGET }, limits[1]];
        let e = Trajectory::new(2, &[S], &[p(0.0, 0.0)], Some(&bad)).unwrap_err().to_string();
        assert!(e.contains("joint 0: limits 1 ..= 0 counts"), "{e}");
        assert_eq!(Trajectory::new(1, &[], &[], None), Err(TrajectoryError::NoPoints));
        assert_eq!(Trajectory::new(0, &[S], &[vec![]], None), Err(TrajectoryError::NoJoints));
        // Without limits, what a 32-bit target carries.
        let e = Trajectory::new(1, &[S], &[vec![Knot::position(3e9)]], None).unwrap_err().to_string();
        assert!(
            e.contains("past the joint's max_position 2147483647 counts (its limits: -2147483648 ..= 2147483647"),
            "{e}"
        );
    }

    /// The joint_4: 2^20 counts per motor revolution, gear 50; limits ±3.2 rad and
    /// 6 rad/s, in counts.
    const PER_RAD: f64 = 1_048_576.0 * 50.0 / std::f64::consts::TAU;

    fn joint_4() -> Limits {
        Limits { min: -3.2 * PER_RAD, max: 3.2 * PER_RAD, max_velocity: 6.0 * PER_RAD, ..Limits::TARGET }
    }

    fn rad() -> Scale {
        Scale { per_count: 1.0 / PER_RAD, offset: 0.0, unit: Unit::Radian }
    }

    #[test]
    fn the_segment_to_the_first_point_is_judged_from_the_set_point_in_force() {
        // +0.8 rad in 0.1 s from rest: 8 rad/s on a linear segment, 12 rad/s at the peak of a
        // cubic one that starts and ends at rest; 0.8 rad in 0.2 s linear is 4 rad/s.
        let at_rest = Setpoint::default();
        let linear = Trajectory::new(1, &[S / 10], &[vec![Knot::position(0.8 * PER_RAD)]], Some(&[joint_4()])).unwrap();
        let Some(Breach::Past(excess)) = linear.lead_in_breach(0, at_rest) else { panic!("not refused") };
        assert_eq!(excess.limit, Limit::Velocity);
        assert!(close(excess.value / PER_RAD, 8.0, 1e-9), "{excess:?}");
        let e = Trajectory::lead_in_error(0, Breach::Past(excess));
        let named = e.naming(&["joint_4".into()], &[rad()]).to_string();
        assert!(
            named.contains(
                "joint_4: the segment to point 0, from the set-point in force, reaches a velocity of 8 rad/s, past the \
                 joint's max_velocity 6 rad/s"
            ),
            "{named}"
        );
        let rest = Knot { position: 0.8 * PER_RAD, velocity: Some(0.0), acceleration: None };
        let cubic = Trajectory::new(1, &[S / 10], &[vec![rest]], Some(&[joint_4()])).unwrap();
        let Some(Breach::Past(excess)) = cubic.lead_in_breach(0, at_rest) else { panic!("not refused") };
        assert!(close(excess.value / PER_RAD, 12.0, 1e-6), "{excess:?}");
        let slow = Trajectory::new(1, &[S / 5], &[vec![Knot::position(0.8 * PER_RAD)]], Some(&[joint_4()])).unwrap();
        assert_eq!(slow.lead_in_breach(0, at_rest), None);
        // A joint that coasted past 3.2 rad may come back, not go further out.
        let out = Setpoint { position: 3.5 * PER_RAD, ..at_rest };
        let back = Trajectory::new(1, &[S], &[vec![Knot::position(3.0 * PER_RAD)]], Some(&[joint_4()])).unwrap();
        assert_eq!(back.lead_in_breach(0, out), None);
        // Still moving outward at 1 rad/s, a cubic back first goes further out.
        let further = Setpoint { velocity: 1.0 * PER_RAD, ..out };
        let rest = Knot { velocity: Some(0.0), ..Knot::position(3.0 * PER_RAD) };
        let cubic_back = Trajectory::new(1, &[S], &[vec![rest]], Some(&[joint_4()])).unwrap();
        let Some(Breach::Past(excess)) = cubic_back.lead_in_breach(0, further) else { panic!("not refused") };
        assert_eq!((excess.limit, excess.allowed), (Limit::Position, 3.5 * PER_RAD));
        // The same segment, from a set-point already moving the other way fast, goes too fast.
        let moving = Setpoint { velocity: -5.9 * PER_RAD, ..at_rest };
        let from_moving = Trajectory::new(1, &[S / 5], &[vec![rest]], Some(&[joint_4()])).unwrap();
        assert!(matches!(from_moving.lead_in_breach(0, moving), Some(Breach::Past(e)) if e.limit == Limit::Velocity));
    }

    #[test]
    fn the_path_between_points_is_judged_not_only_the_points() {
        let limits = [joint_4()];
        let cubic = |p: f64, v: f64| Knot { position: p * PER_RAD, velocity: Some(v * PER_RAD), acceleration: None };
        // Both points within ±3.2 rad and 6 rad/s; leaving 3.1 rad at 2 rad/s the cubic
        // overshoots past 3.2 rad on its way back to 3.1 rad.
        let points = [vec![cubic(3.1, 2.0)], vec![cubic(3.1, 0.0)]];
        let e = Trajectory::new(1, &[S, 2 * S], &points, Some(&limits)).unwrap_err();
        let TrajectoryError::SegmentPastLimit { point: 1, joint: 0, excess } = e else { panic!("{e:?}") };
        assert_eq!((excess.limit, excess.allowed), (Limit::Position, 3.2 * PER_RAD));
        // The peak of 3.1 + 2·s·(1 - s)² rad, at s = 1/3: 3.1 + 8/27.
        assert!(close(excess.value / PER_RAD, 3.1 + 8.0 / 27.0, 1e-9), "{excess:?}");
        let named = e.naming(&["joint_4".into()], &[rad()]).to_string();
        assert!(
            named.contains(
                "joint_4: the segment from point 0 to point 1 reaches position 3.3963 rad, past the \
                 joint's max_position 3.2 rad"
            ),
            "{named}"
        );
        // Quintic from rest to rest over 1 rad in 0.2 s peaks at 15/8 · 5 = 9.375 rad/s.
        let quintic = |p: f64| Knot { position: p * PER_RAD, velocity: Some(0.0), acceleration: Some(0.0) };
        let e = Trajectory::new(1, &[S, S + S / 5], &[vec![quintic(0.0)], vec![quintic(1.0)]], Some(&limits));
        let TrajectoryError::SegmentPastLimit { excess, .. } = e.unwrap_err() else { panic!() };
        assert!(close(excess.value / PER_RAD, 9.375, 1e-6), "{excess:?}");
        // A point's own velocity past the limit is named at the point.
        let e = Trajectory::new(1, &[S], &[vec![cubic(0.0, -7.0)]], Some(&limits)).unwrap_err();
        let named = e.naming(&["joint_4".into()], &[rad()]).to_string();
        assert!(
            named.contains("point 0, joint_4: velocity -7 rad/s is past the joint's max_velocity 6 rad/s"),
            "{named}"
        );
    }

    #[test]
    fn where_the_acceleration_is_limited_the_velocity_may_not_step() {
        let limits = [Limits { max_acceleration: 100.0 * PER_RAD, ..joint_4() }];
        // Linear segments step at every point; cubic ones from and to rest do not, but must
        // keep their acceleration: 1 rad in 1 s from rest to rest peaks at 6 rad/s².
        let e =
            Trajectory::new(1, &[S, 2 * S], &[vec![Knot::position(0.0)], vec![Knot::position(PER_RAD)]], Some(&limits));
        assert!(matches!(e, Err(TrajectoryError::VelocityStep { point: Some(1), .. })), "{e:?}");
        let rest = |p: f64| Knot { position: p * PER_RAD, velocity: Some(0.0), acceleration: None };
        let cubic = Trajectory::new(1, &[S, 2 * S], &[vec![rest(0.0)], vec![rest(1.0)]], Some(&limits)).unwrap();
        assert_eq!(cubic.lead_in_breach(0, Setpoint::default()), None);
        let tight = [Limits { max_acceleration: 5.0 * PER_RAD, ..joint_4() }];
        let e = Trajectory::new(1, &[S, 2 * S], &[vec![rest(0.0)], vec![rest(1.0)]], Some(&tight)).unwrap_err();
        assert!(matches!(
            e,
            TrajectoryError::SegmentPastLimit { excess: Excess { limit: Limit::Acceleration, .. }, .. }
        ));
        // A trajectory that ends moving would stop dead.
        let moving = Knot { velocity: Some(0.5 * PER_RAD), ..rest(1.0) };
        let e = Trajectory::new(1, &[S, 2 * S], &[vec![rest(0.0)], vec![moving]], Some(&limits)).unwrap_err();
        let named = e.naming(&["joint_4".into()], &[rad()]).to_string();
        assert!(
            named.contains("joint_4: at point 1 the set-point's velocity steps from 0.5 rad/s to 0 rad/s"),
            "{named}"
        );
    }

    proptest! {
        #[test]
        fn a_peak_is_the_largest_value_of_the_polynomial_over_its_segment(
            c in prop::array::uniform6(-1e3..1e3f64), duration in 1e-3..10.0f64
        ) {
            let at = |s: f64| c.iter().rev().fold(0.0, |r, c| r * s + c);
            let sampled = (0..=2000).map(|i| at(duration * i as f64 / 2000.0)).fold(f64::NEG_INFINITY, f64::max);
            let found = peak(c, 5, duration);
            let size = c.iter().enumerate().map(|(i, c)| c.abs() * duration.powi(i as i32)).sum::<f64>();
            // Never below what sampling finds, and above it by no more than sampling can miss.
            prop_assert!(found >= sampled - 1e-9 * (1.0 + size), "{} < {}", found, sampled);
            prop_assert!(found <= sampled + 1e-4 * (1.0 + size), "{} > {}", found, sampled);
        }
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
