//! The virtual AKD's motor and load, and the drive's cascaded position and velocity loops.
//!
//! Units are the drive's: position in counts (2^20 per revolution, the AKD's default
//! resolution of 0x6063/0x6064), velocity in counts/s, torque in N·m. The model is stepped at
//! the AKD's current-loop rate of 16 kHz ([`STEP_NS`]); the current loop itself is taken as
//! ideal (the torque asked is the torque given, within the peak torque).

/// Counts per motor revolution of 0x6063/0x6064 (the AKD's default 20-bit resolution).
pub const COUNTS_PER_REV: f64 = (1u64 << 20) as f64;
/// Model step, ns: 16 kHz, the AKD's fastest internal loop (62.5 µs, the FBUS.SAMPLEPERIOD unit).
pub const STEP_NS: u64 = 62_500;
/// Model step, s.
pub const STEP_S: f64 = STEP_NS as f64 * 1e-9;

/// One radian in counts.
const COUNTS_PER_RAD: f64 = COUNTS_PER_REV / std::f64::consts::TAU;

/// The mechanics of motor and load, in SI units.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Mechanics {
    /// Inertia of motor and load, kg·m².
    pub inertia: f64,
    /// Viscous friction, N·m per rad/s.
    pub viscous: f64,
    /// Coulomb (dry) friction, N·m.
    pub coulomb: f64,
    /// Peak torque the drive gives, N·m: the torque limit, and what 0x6071/0x6072/0x6077 count
    /// in 0.1 % of ("torque in % of drive peak torque", AKD manual, mode 4).
    pub peak_torque: f64,
}

impl Default for Mechanics {
    /// A small AKM-class servo motor with a light load.
    fn default() -> Self {
        Mechanics { inertia: 2.0e-4, viscous: 2.0e-4, coulomb: 0.02, peak_torque: 3.0 }
    }
}

/// The state of the motor shaft.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Shaft {
    /// Position, counts (fractional: the model's own resolution is finer than the encoder's).
    pub position: f64,
    /// Velocity, counts/s.
    pub velocity: f64,
    /// Torque the motor gives, N·m.
    pub torque: f64,
}

impl Shaft {
    /// One step with motor torque `torque` (N·m, `None` when the power stage is off and the
    /// shaft coasts). Dry friction holds a shaft at rest while the torque is below it.
    pub fn step(&mut self, torque: Option<f64>, m: &Mechanics) {
        let torque = torque.unwrap_or(0.0);
        let omega = self.velocity / COUNTS_PER_RAD;
        let driving = torque - m.viscous * omega;
        let accel = if omega == 0.0 && driving.abs() <= m.coulomb {
            0.0
        } else {
            let direction = if omega != 0.0 { omega.signum() } else { driving.signum() };
            (driving - m.coulomb * direction) / m.inertia
        };
        let mut next = omega + accel * STEP_S;
        // Friction stops the shaft; it does not turn it round.
        if omega != 0.0 && next.signum() != omega.signum() && torque.abs() <= m.coulomb {
            next = 0.0;
        }
        self.velocity = next * COUNTS_PER_RAD;
        self.position += (omega + next) * 0.5 * STEP_S * COUNTS_PER_RAD;
        self.torque = torque;
    }

    /// Whether nothing changes while the power stage stays off (the shaft is at rest).
    pub fn at_rest(&self) -> bool {
        self.velocity == 0.0
    }
}

/// Gains of the cascaded loops.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Gains {
    /// Position loop proportional gain, 1/s.
    pub position_kp: f64,
    /// Velocity loop proportional gain, N·m per rad/s.
    pub velocity_kp: f64,
    /// Velocity loop integral gain, 1/s (integrator time constant's inverse).
    pub velocity_ki: f64,
}

impl Gains {
    /// Loops tuned for `m`: a velocity loop of about 150 Hz bandwidth, an integrator at a tenth
    /// of it and a position loop of about 30 Hz.
    pub fn tuned_for(m: &Mechanics) -> Self {
        let velocity_bandwidth = std::f64::consts::TAU * 150.0;
        Gains {
            position_kp: std::f64::consts::TAU * 30.0,
            velocity_kp: m.inertia * velocity_bandwidth,
            velocity_ki: velocity_bandwidth / 10.0,
        }
    }
}

/// The drive's position and velocity loops with velocity and torque feed-forward.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Loops {
    integral: f64,
    /// Whether the last torque was limited (statusword bit 11).
    pub limited: bool,
}

impl Loops {
    /// Forgets the integrator (power stage off, mode change).
    pub fn reset(&mut self) {
        *self = Loops::default();
    }

    /// Torque for a position command (counts) with its velocity feed-forward (counts/s).
    pub fn position(&mut self, command: f64, feed_forward: f64, shaft: &Shaft, g: &Gains, m: &Mechanics) -> f64 {
        let velocity = feed_forward + g.position_kp * (command - shaft.position);
        self.velocity(velocity, 0.0, shaft, g, m)
    }

    /// Torque for a velocity command (counts/s) plus a torque feed-forward (N·m); the
    /// integrator stops while the torque is limited (anti-windup).
    pub fn velocity(&mut self, command: f64, torque_ff: f64, shaft: &Shaft, g: &Gains, m: &Mechanics) -> f64 {
        let error = (command - shaft.velocity) / COUNTS_PER_RAD;
        let wanted = torque_ff + g.velocity_kp * (error + self.integral);
        let torque = wanted.clamp(-m.peak_torque, m.peak_torque);
        self.limited = torque != wanted;
        if !self.limited {
            self.integral += error * g.velocity_ki * STEP_S;
        }
        torque
    }

    /// A torque command, within the peak torque.
    pub fn torque(&mut self, command: f64, m: &Mechanics) -> f64 {
        let torque = command.clamp(-m.peak_torque, m.peak_torque);
        self.limited = torque != command;
        torque
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn run(steps: usize, shaft: &mut Shaft, mut torque: impl FnMut(&Shaft) -> Option<f64>) {
        let m = Mechanics::default();
        for _ in 0..steps {
            let t = torque(shaft);
            shaft.step(t, &m);
        }
    }

    #[test]
    fn a_coasting_shaft_stops_by_friction_and_stays_stopped() {
        let mut shaft = Shaft { velocity: COUNTS_PER_REV * 10.0, ..Shaft::default() };
        run(16_000 * 5, &mut shaft, |_| None);
        assert_eq!(shaft.velocity, 0.0);
        assert!(shaft.position > 0.0);
        let stopped = shaft.position;
        run(100, &mut shaft, |_| None);
        assert_eq!(shaft.position, stopped);
    }

    #[test]
    fn torque_below_dry_friction_does_not_move_it() {
        let mut shaft = Shaft::default();
        run(1000, &mut shaft, |_| Some(0.019));
        assert_eq!((shaft.position, shaft.velocity), (0.0, 0.0));
        run(1000, &mut shaft, |_| Some(0.5));
        assert!(shaft.velocity > 0.0);
    }

    #[test]
    fn the_velocity_loop_reaches_its_command_and_the_torque_is_limited_on_the_way() {
        let m = Mechanics::default();
        let g = Gains::tuned_for(&m);
        let mut loops = Loops::default();
        let mut shaft = Shaft::default();
        let command = COUNTS_PER_REV * 20.0;
        let mut limited = false;
        run(16_000, &mut shaft, |s| {
            let t = loops.velocity(command, 0.0, s, &g, &m);
            limited |= loops.limited;
            Some(t)
        });
        assert!(limited, "an acceleration to 1200 rpm in one step needs more than the peak torque");
        assert!((shaft.velocity - command).abs() < command * 1e-3, "{}", shaft.velocity);
    }

    #[test]
    fn the_position_loop_holds_against_a_load_torque() {
        let m = Mechanics::default();
        let g = Gains::tuned_for(&m);
        let mut loops = Loops::default();
        let mut shaft = Shaft::default();
        run(16_000, &mut shaft, |s| Some(loops.position(1000.0, 0.0, s, &g, &m) - 0.5));
        assert!((shaft.position - 1000.0).abs() < 1.0, "{}", shaft.position);
    }
}
