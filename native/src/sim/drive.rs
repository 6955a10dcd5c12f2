//! The virtual AKD's drive firmware: the CiA 402 state machine (AKD manual §5.4, through
//! [`crate::drive::ds402`]), the modes of operation (§5.8), the set-point handling, the monitoring that
//! raises faults (§5.14), and the motor model ([`crate::sim::motion`]) it drives.
//!
//! The drive reads what the master sent from the object dictionary (controlword 0x6040, mode
//! 0x6060, set-points), whether process data or SDO put it there, and writes back the actual
//! values (0x6041, 0x6061, 0x6063/0x6064, 0x606C, 0x6077, 0x60F4, 0x603F, latch objects). Time
//! is the bus time the caller passes; the model runs in steps of [`STEP_NS`] up to it, so a run
//! is deterministic.
//!
//! What the drive does, in the AKD's words:
//! - Controlword commands as §4's table, fault reset on the rising edge of bit 7 only
//!   (FBUS.PARAM05 bit 0 = 1); enable operation from Ready to switch on passes Switched on.
//! - Hardware enable low (FBUS.PARAM05 bit 1 = 0): Switched on and Operation enabled fall back
//!   to Switch on disabled; the statusword shows a warning (bit 7) while it is low.
//! - Quick stop (transition 11) and halt (bit 8) ramp the speed to zero with 0x6085 (halt: 0x6084)
//!   and hold the position; quick stop then stays in Quick stop active (CiA 402 option 6) until
//!   Disable voltage (12) or Enable operation (16). A fault ramps down the same way in Fault
//!   reaction active (13) and then enters Fault (14) with the power stage off.
//! - Cyclic position modes (8: 0x607A, 7: 0x60C1:01) interpolate linearly between set-points
//!   over the cycle time 0x60C2, the slope feeding the velocity loop forward. Profile velocity
//!   (3) ramps to 0x60FF with 0x6083/0x6084. Torque (4) gives 0x6071 in 0.1 % of the peak
//!   torque. Profile position (1) moves to 0x607A (bit 6: relative) on the rising edge of bit 4
//!   with a trapezoid of 0x6081/0x6083/0x6084, each new set-point at once. Homing (6) moves to
//!   the reference on the rising edge of bit 4 and makes it the zero ([`crate::sim::homing`]).
//! - On entering Operation enabled and on every mode change the position command is the actual
//!   position: nothing moves until a set-point asks for it.
//! - An active limit switch holds motion toward it back in every mode
//!   ([`crate::sim::terminals`]).
//! - Units: position in counts of 2^20 per revolution, velocity in counts/s, acceleration in
//!   counts/s², torque in 0.1 % of the drive's peak torque.

use crate::drive::akd_fault::MISSED_FRAMES_TOLERATED;
use crate::drive::ds402::{controlword as cw, statusword as sw, transition, Mode, State};
use crate::ethercat::coe::Emergency;
use crate::ethercat::link_spec::MissedFrames;
use crate::ethercat::pdo::PdoEntry;
use crate::sim::digital_inputs::{Inputs, Latch, TouchProbe};
use crate::sim::faults::Fault;
use crate::sim::homing::{self, Ending};
use crate::sim::missed_frames::WouldBeF125;
use crate::sim::motion::{Gains, Loops, Mechanics, Shaft, COUNTS_PER_REV, STEP_NS, STEP_S};
use crate::sim::od::ObjectDictionary;
use crate::sim::terminals::{LimitStop, Terminals};

/// How long an enabled drive waits for cyclic set-points before F706 when the master set no
/// process-data watchdog (the AKD's default, FAULT706.ACTION).
pub const SETPOINT_TIMEOUT_NS: u64 = 100_000_000;
/// Position window of "target reached", counts.
const POSITION_WINDOW: f64 = 100.0;
/// Velocity window of "target reached" and of "speed is zero", counts/s (0.01 rev/s).
const VELOCITY_WINDOW: f64 = COUNTS_PER_REV / 100.0;
/// Longest stretch of bus time the model catches up with in one go; after a longer silence
/// the motor's time jumps (a stopped motor loses nothing by it).
const MAX_CATCH_UP_NS: u64 = 10_000_000_000;

fn bytes<const N: usize>(od: &ObjectDictionary, index: u16, subindex: u8) -> [u8; N] {
    let mut out = [0u8; N];
    if let Some(v) = od.get(index, subindex) {
        let n = N.min(v.len());
        out[..n].copy_from_slice(&v[..n]);
    }
    out
}

fn i32_of(od: &ObjectDictionary, index: u16, subindex: u8) -> i32 {
    i32::from_le_bytes(bytes(od, index, subindex))
}

fn u32_of(od: &ObjectDictionary, index: u16) -> u32 {
    u32::from_le_bytes(bytes(od, index, 0))
}

fn u16_of(od: &ObjectDictionary, index: u16) -> u16 {
    u16::from_le_bytes(bytes(od, index, 0))
}

/// `value` moved toward `target` by at most `step` (any step when `step` is not positive:
/// an acceleration of 0 means no ramp).
fn approach(value: f64, target: f64, step: f64) -> f64 {
    if step <= 0.0 {
        target
    } else {
        value + (target - value).clamp(-step, step)
    }
}

/// One cyclic set-point's stretch: from the previous set-point to this one over a cycle.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Segment {
    from: f64,
    to: f64,
    start_ns: u64,
    length_ns: u64,
}

impl Segment {
    /// Position command and its velocity at time `t`.
    fn at(&self, t: u64) -> (f64, f64) {
        let elapsed = t.saturating_sub(self.start_ns);
        if elapsed >= self.length_ns {
            return (self.to, 0.0);
        }
        let share = elapsed as f64 / self.length_ns as f64;
        (self.from + (self.to - self.from) * share, (self.to - self.from) / (self.length_ns as f64 * 1e-9))
    }
}

/// Process data the drive received.
#[derive(Clone, Copy, Debug)]
pub struct Received<'a> {
    /// Bus time the master wrote them.
    pub at_ns: u64,
    /// The output image they fill.
    pub image: &'a [PdoEntry],
}

/// What the ESC tells the firmware besides process data.
#[derive(Clone, Copy, Debug, Default)]
pub struct Bus<'a> {
    /// Process data from the master since the last run, if any.
    pub received: Option<Received<'a>>,
    /// Whether process data are expected (AL state SafeOp or Op): synchronisation is
    /// supervised only then.
    pub process_data_expected: bool,
    /// The process-data watchdog time the master configured, if any (F706's time-out).
    pub watchdog_ns: Option<u64>,
    /// How the firmware judges missed frames (by time, as the real drive, unless told otherwise).
    pub missed_frames: MissedFrames,
    /// Frames in a row the line lost before they reached the drive.
    pub frames_lost: u64,
}

/// The drive firmware of one virtual AKD.
#[derive(Clone, Debug)]
pub struct DriveFirmware {
    state: State,
    controlword: u16,
    mode: Option<Mode>,
    mechanics: Mechanics,
    gains: Gains,
    shaft: Shaft,
    loops: Loops,
    /// Reported position = shaft position + offset (homing moves the offset).
    offset: f64,
    /// Position command, in shaft counts.
    command: f64,
    /// Velocity command of the ramps and profiles, counts/s.
    command_velocity: f64,
    segment: Option<Segment>,
    profile_target: Option<f64>,
    setpoint_acknowledged: bool,
    homing_attained: bool,
    homing_error: bool,
    /// The homing run under way.
    homing: Option<homing::Run>,
    /// The homing as set up in the drive (its HOME.* parameters).
    homing_setup: homing::Setup,
    /// A ramp to stand-still runs (halt, quick stop, fault reaction).
    stopping: bool,
    hardware_enable: bool,
    injected: Option<Fault>,
    fault: Option<Fault>,
    last_error_code: u16,
    inputs: Inputs,
    terminals: Terminals,
    limit_stop: LimitStop,
    latch: Latch,
    touch_probe: TouchProbe,
    time_ns: Option<u64>,
    last_process_data_ns: Option<u64>,
    last_setpoint_ns: Option<u64>,
    /// Since when cyclic set-points are due: the enable, or the change into the mode.
    setpoints_due_since_ns: u64,
    would_be_f125: WouldBeF125,
}

impl Default for DriveFirmware {
    fn default() -> Self {
        DriveFirmware::new(Mechanics::default())
    }
}

impl DriveFirmware {
    /// A drive at power-up driving a motor and load of `mechanics`, loops tuned for it.
    pub fn new(mechanics: Mechanics) -> Self {
        DriveFirmware {
            state: State::NotReadyToSwitchOn,
            controlword: 0,
            mode: None,
            gains: Gains::tuned_for(&mechanics),
            mechanics,
            shaft: Shaft::default(),
            loops: Loops::default(),
            offset: 0.0,
            command: 0.0,
            command_velocity: 0.0,
            segment: None,
            profile_target: None,
            setpoint_acknowledged: false,
            homing_attained: false,
            homing_error: false,
            homing: None,
            homing_setup: homing::Setup::default(),
            stopping: false,
            hardware_enable: true,
            injected: None,
            fault: None,
            last_error_code: 0,
            inputs: Inputs::default(),
            terminals: Terminals::default(),
            limit_stop: LimitStop::default(),
            latch: Latch::default(),
            touch_probe: TouchProbe::default(),
            time_ns: None,
            last_process_data_ns: None,
            last_setpoint_ns: None,
            setpoints_due_since_ns: 0,
            would_be_f125: WouldBeF125::default(),
        }
    }

    /// The CiA 402 state.
    pub fn state(&self) -> State {
        self.state
    }

    /// The active fault, if any.
    pub fn fault(&self) -> Option<Fault> {
        self.fault
    }

    /// The actual position 0x6064 reports, counts (fractional: the model's own resolution).
    pub fn position(&self) -> f64 {
        self.reported(self.shaft.position)
    }

    /// The F125 a real AKD would have raised where this one judges missed frames by
    /// [`MissedFrames::Warn`].
    pub fn would_be_f125(&self) -> WouldBeF125 {
        self.would_be_f125
    }

    /// The shaft (position in counts before any homing offset, velocity, torque).
    pub fn shaft(&self) -> &Shaft {
        &self.shaft
    }

    /// Raises `fault` at the drive's next run, as the firmware would on detecting it.
    pub fn inject(&mut self, fault: Fault) {
        self.injected = Some(fault);
    }

    /// Sets the hardware enable input (X8), high at power-up.
    pub fn set_hardware_enable(&mut self, high: bool) {
        self.hardware_enable = high;
    }

    /// Sets the drive's homing up (where a real AKD's HOME.* parameters are set).
    pub fn set_homing(&mut self, setup: homing::Setup) {
        self.homing_setup = setup;
    }

    /// The drive's homing set-up.
    pub fn homing_setup(&self) -> homing::Setup {
        self.homing_setup
    }

    /// The simulated digital inputs, to set their levels and where they toggle.
    pub fn inputs_mut(&mut self) -> &mut Inputs {
        &mut self.inputs
    }

    /// The switches and the analog input, to set them.
    pub fn terminals_mut(&mut self) -> &mut Terminals {
        &mut self.terminals
    }

    /// The position reported in 0x6063/0x6064, counts (fractional).
    fn reported(&self, shaft_position: f64) -> f64 {
        shaft_position + self.offset
    }

    /// The shaft position of a 32-bit position `target`, counted `scale` to a shaft count
    /// ([`ObjectDictionary::position_scale`]), taken as the nearest one to shaft position
    /// `near`: positions wrap at ±2^31 as 0x6064 does, and the axis moves the short way across
    /// the wrap, not 2^32 back.
    fn shaft_target(&self, target: i32, near: f64, scale: f64) -> f64 {
        let near_counts = ((near + self.offset) * scale).round();
        (near_counts + target.wrapping_sub(near_counts as i64 as i32) as f64) / scale - self.offset
    }

    /// Runs the firmware up to bus time `now_ns`; returns the emergency of a fault raised.
    pub fn run(&mut self, od: &mut ObjectDictionary, now_ns: u64, bus: Bus<'_>) -> Option<Emergency> {
        let mut raised = None;
        if !bus.process_data_expected {
            self.last_process_data_ns = None;
        }
        // Commands first: a mode change or an enable in the same frame applies to its set-point.
        self.take_commands(od);
        if let Some(received) = bus.received {
            self.receive(od, received);
        }
        let time = *self.time_ns.get_or_insert(now_ns);
        let mut t = time;
        if now_ns.saturating_sub(t) > MAX_CATCH_UP_NS {
            t = now_ns - MAX_CATCH_UP_NS;
        }
        let cycle_ns = od.cycle_time_ns().unwrap_or(0);
        let timeout = bus.watchdog_ns.unwrap_or(SETPOINT_TIMEOUT_NS);
        let window = u32_of(od, 0x6065) as f64;
        while t + STEP_NS <= now_ns {
            t += STEP_NS;
            if let Some(fault) = self.injected.take().or_else(|| self.supervise(t, cycle_ns, timeout, &bus)) {
                raised = raised.or(self.raise(fault));
            }
            if self.shaft.at_rest() && !self.state.is_power_stage_on() {
                // It stays at rest, and a power stage that is off makes no torque.
                self.shaft.torque = 0.0;
                continue;
            }
            let before = self.reported(self.shaft.position);
            let torque = self.control(od, t);
            self.shaft.step(torque, &self.mechanics);
            let after = self.reported(self.shaft.position);
            self.latch.capture(&self.inputs, before, after);
            self.touch_probe.capture(&self.inputs, before, after);
            if self.state.is_power_stage_on() && window > 0.0 && self.following_error().abs() > window {
                raised = raised.or(self.raise(Fault::FollowingError));
            }
            if self.state == State::FaultReactionActive && self.command_velocity == 0.0 {
                self.enter(State::Fault, t);
            }
        }
        self.time_ns = Some(t);
        self.publish(od);
        raised
    }

    /// Process data arrived: note the time and take a new cyclic set-point.
    fn receive(&mut self, od: &ObjectDictionary, received: Received<'_>) {
        self.last_process_data_ns = Some(received.at_ns);
        let setpoint = match self.mode {
            Some(Mode::CyclicSynchronousPosition) => (0x607A, 0),
            Some(Mode::InterpolatedPosition) => (0x60C1, 1),
            _ => return,
        };
        if !received.image.iter().any(|e| (e.index, e.subindex) == setpoint) {
            return;
        }
        self.last_setpoint_ns = Some(received.at_ns);
        if self.state != State::OperationEnabled || self.stopping {
            return;
        }
        let from = self.segment.map_or(self.command, |s| s.to);
        let scale = od.position_scale(setpoint.0, setpoint.1);
        let to = self.shaft_target(i32_of(od, setpoint.0, setpoint.1), from, scale);
        let length_ns = od.cycle_time_ns().unwrap_or(STEP_NS).max(STEP_NS);
        self.segment = Some(Segment { from, to, start_ns: received.at_ns, length_ns });
    }

    /// The controlword, the mode, the latch control: what the master asks now.
    fn take_commands(&mut self, od: &ObjectDictionary) {
        let now = self.time_ns.unwrap_or(0);
        let controlword = u16_of(od, 0x6040);
        let previous = std::mem::replace(&mut self.controlword, controlword);
        if self.state == State::NotReadyToSwitchOn {
            // Transition 1: the firmware is up.
            self.state = State::SwitchOnDisabled;
        }
        let mut edge = controlword & cw::FAULT_RESET != 0 && previous & cw::FAULT_RESET == 0;
        for _ in 0..2 {
            match transition(self.state, controlword, edge) {
                Some((next, _)) => self.enter(next, now),
                None => break,
            }
            edge = false;
        }
        if !self.hardware_enable && matches!(self.state, State::SwitchedOn | State::OperationEnabled) {
            self.enter(State::SwitchOnDisabled, now);
        }
        let requested = Mode::from_i8(bytes::<1>(od, 0x6060, 0)[0] as i8);
        if requested.is_some() && requested != self.mode {
            self.mode = requested;
            self.setpoints_due_since_ns = now;
            self.hold_here();
            self.homing_attained = false;
            self.homing_error = false;
        }
        let enabled = self.state == State::OperationEnabled;
        let halt = enabled && controlword & cw::HALT != 0;
        if halt && !self.stopping {
            self.start_stop();
        } else if !halt && self.stopping && enabled {
            self.stopping = false;
            self.hold_here();
        }
        let new_setpoint = controlword & cw::NEW_SETPOINT != 0 && previous & cw::NEW_SETPOINT == 0;
        if controlword & cw::NEW_SETPOINT == 0 {
            self.setpoint_acknowledged = false;
        }
        if enabled && new_setpoint && !halt {
            match self.mode {
                Some(Mode::ProfilePosition) => {
                    let (target, scale) = (i32_of(od, 0x607A, 0), od.position_scale(0x607A, 0));
                    self.profile_target = Some(if controlword & cw::RELATIVE != 0 {
                        self.profile_target.unwrap_or(self.command) + target as f64 / scale
                    } else {
                        self.shaft_target(target, self.command, scale)
                    });
                    self.setpoint_acknowledged = true;
                }
                Some(Mode::Homing) => {
                    self.homing = Some(homing::Run::start(&self.homing_setup, self.command));
                    self.homing_attained = false;
                    self.homing_error = false;
                }
                _ => {}
            }
        }
        self.latch.control(u16_of(od, 0x20A4));
        self.touch_probe.function(u16_of(od, 0x60B8));
    }

    /// The command holds the actual position: nothing moves until a set-point asks for it.
    fn hold_here(&mut self) {
        self.command = self.shaft.position;
        self.command_velocity = self.shaft.velocity;
        self.segment = None;
        self.profile_target = None;
        self.homing = None;
        // A limit switch holds back from where the axis is now, not from where it once stopped.
        self.limit_stop = LimitStop::default();
    }

    fn start_stop(&mut self) {
        self.hold_here();
        self.stopping = true;
    }

    /// Enters `next`, setting up what the new state needs.
    fn enter(&mut self, next: State, now: u64) {
        let was_on = self.state.is_power_stage_on();
        self.state = next;
        match next {
            State::OperationEnabled => {
                if !was_on || self.stopping {
                    self.setpoints_due_since_ns = now;
                    self.loops.reset();
                    self.stopping = false;
                    self.hold_here();
                }
            }
            State::QuickStopActive | State::FaultReactionActive => self.start_stop(),
            State::SwitchOnDisabled if self.fault.is_some() => self.fault = None,
            _ => {
                self.stopping = false;
                self.loops.reset();
                self.segment = None;
                self.profile_target = None;
            }
        }
    }

    /// Raises `fault` unless one is active; returns its emergency.
    fn raise(&mut self, fault: Fault) -> Option<Emergency> {
        if self.fault.is_some() {
            return None;
        }
        self.fault = Some(fault);
        self.last_error_code = fault.error_code();
        let now = self.time_ns.unwrap_or(0);
        if self.state.is_power_stage_on() {
            self.enter(State::FaultReactionActive, now);
        } else {
            self.enter(State::Fault, now);
        }
        Some(fault.emergency())
    }

    /// The fault the firmware's supervision finds at time `t`, if any.
    fn supervise(&mut self, t: u64, cycle_ns: u64, timeout_ns: u64, bus: &Bus<'_>) -> Option<Fault> {
        if self.fault.is_some() || !matches!(self.state, State::OperationEnabled | State::QuickStopActive) {
            return None;
        }
        let last = self.last_process_data_ns;
        if self.would_be_f125.missed(bus.missed_frames, t, last, cycle_ns, bus.frames_lost) > MISSED_FRAMES_TOLERATED {
            return Some(Fault::SyncLost);
        }
        let cyclic = matches!(self.mode, Some(Mode::CyclicSynchronousPosition | Mode::InterpolatedPosition));
        if cyclic && self.state == State::OperationEnabled {
            let since =
                self.last_setpoint_ns.map_or(self.setpoints_due_since_ns, |s| s.max(self.setpoints_due_since_ns));
            if t.saturating_sub(since) > timeout_ns {
                return Some(Fault::SetpointsMissing);
            }
        }
        None
    }

    /// The torque for one step at time `t` (`None`: power stage off).
    fn control(&mut self, od: &ObjectDictionary, t: u64) -> Option<f64> {
        if !self.state.is_power_stage_on() {
            self.hold_here();
            return None;
        }
        let mut m = self.mechanics;
        let max_torque = u16_of(od, 0x6072) as f64 * m.peak_torque / 1000.0;
        if max_torque > 0.0 {
            m.peak_torque = m.peak_torque.min(max_torque);
        }
        let (shaft, g) = (self.shaft, self.gains);
        let (blocked, quick_stop) = (self.terminals.blocked(), u32_of(od, 0x6085) as f64);
        if self.stopping {
            let deceleration = match self.state {
                State::OperationEnabled => u32_of(od, 0x6084),
                _ => u32_of(od, 0x6085),
            } as f64;
            self.command_velocity = approach(self.command_velocity, 0.0, deceleration * STEP_S);
            self.command += self.command_velocity * STEP_S;
            return Some(self.loops.position(self.command, self.command_velocity, &shaft, &g, &m));
        }
        let torque = match self.mode {
            Some(Mode::CyclicSynchronousPosition | Mode::InterpolatedPosition) => {
                let commanded = self.segment.map_or((self.command, 0.0), |s| s.at(t));
                let (position, velocity) = self.limit_stop.position(blocked, commanded, quick_stop);
                self.command = position;
                self.loops.position(position, velocity, &shaft, &g, &m)
            }
            Some(Mode::ProfileVelocity) => {
                let target = self.limit_stop.target(blocked, i32_of(od, 0x60FF, 0) as f64);
                let speeding_up = target.abs() > self.command_velocity.abs();
                let rate = match (self.limit_stop.limited, speeding_up) {
                    (true, _) => quick_stop,
                    (false, up) => u32_of(od, if up { 0x6083 } else { 0x6084 }) as f64,
                };
                self.command_velocity = approach(self.command_velocity, target, rate * STEP_S);
                self.command = shaft.position;
                self.loops.velocity(self.command_velocity, 0.0, &shaft, &g, &m)
            }
            Some(Mode::ProfileTorque) => {
                self.command = shaft.position;
                let target = self.limit_stop.target(blocked, i16::from_le_bytes(bytes::<2>(od, 0x6071, 0)) as f64);
                self.loops.torque(target * self.mechanics.peak_torque / 1000.0, &m)
            }
            Some(Mode::ProfilePosition) => {
                if let Some(target) = self.profile_target {
                    let (v_max, acceleration, deceleration) =
                        (u32_of(od, 0x6081) as f64, u32_of(od, 0x6083) as f64, u32_of(od, 0x6084) as f64);
                    self.trapezoid_step(target, v_max, acceleration, deceleration);
                }
                (self.command, self.command_velocity) =
                    self.limit_stop.position(blocked, (self.command, self.command_velocity), quick_stop);
                self.loops.position(self.command, self.command_velocity, &shaft, &g, &m)
            }
            Some(Mode::Homing) => {
                self.homing_step();
                self.loops.position(self.command, self.command_velocity, &shaft, &g, &m)
            }
            None => self.loops.position(self.command, 0.0, &shaft, &g, &m),
        };
        Some(torque)
    }

    /// One step of the homing run: toward where it stops, then the zero or the error there.
    fn homing_step(&mut self) {
        let Some(run) = self.homing else { return };
        let s = self.homing_setup;
        if !self.trapezoid_step(run.stop_at, s.speed, s.acceleration, s.acceleration) {
            return;
        }
        self.homing = None;
        match run.ends {
            Ending::Reference => {
                self.offset = -run.stop_at;
                self.homing_attained = true;
            }
            Ending::Error => self.homing_error = true,
        }
    }

    /// One step of a trapezoid of `v_max`, `acceleration` and `deceleration` toward `target`
    /// (profile position, homing); whether the command is there.
    fn trapezoid_step(&mut self, target: f64, v_max: f64, acceleration: f64, deceleration: f64) -> bool {
        let remaining = target - self.command;
        let v = self.command_velocity;
        let direction = remaining.signum();
        let braking = deceleration > 0.0 && v * direction > 0.0 && remaining.abs() <= v * v / (2.0 * deceleration);
        let wanted = if braking { 0.0 } else { direction * v_max };
        let rate = if wanted.abs() > v.abs() && wanted * v >= 0.0 { acceleration } else { deceleration };
        let next = approach(v, wanted, rate * STEP_S);
        if (next * STEP_S).abs() >= remaining.abs() {
            self.command = target;
            self.command_velocity = 0.0;
            true
        } else {
            self.command += next * STEP_S;
            self.command_velocity = next;
            false
        }
    }

    /// The statusword: the state's bits, remote, warning, and the mode-specific bits.
    fn statusword(&self, od: &ObjectDictionary, following_error: f64, window: f64) -> u16 {
        let mut word = self.state.statusword_bits() | sw::REMOTE;
        if !self.hardware_enable {
            word |= sw::WARNING;
        }
        if self.state != State::OperationEnabled {
            return word;
        }
        if self.loops.limited || self.limit_stop.limited {
            word |= sw::INTERNAL_LIMIT;
        }
        let lagging = window > 0.0 && following_error.abs() > window;
        let still = self.shaft.velocity.abs() <= VELOCITY_WINDOW;
        let (reached, bit12, bit13) = if self.stopping {
            (still, false, false)
        } else {
            match self.mode {
                Some(Mode::ProfilePosition) => {
                    let done = self
                        .profile_target
                        .is_none_or(|t| t == self.command && (self.shaft.position - t).abs() <= POSITION_WINDOW);
                    (done, self.setpoint_acknowledged, lagging)
                }
                Some(Mode::ProfileVelocity) => {
                    let target = i32_of(od, 0x60FF, 0) as f64;
                    ((self.shaft.velocity - target).abs() <= VELOCITY_WINDOW, still, false)
                }
                Some(Mode::CyclicSynchronousPosition | Mode::InterpolatedPosition) => {
                    (following_error.abs() <= POSITION_WINDOW, true, lagging)
                }
                Some(Mode::Homing) => (self.homing.is_none() && still, self.homing_attained, self.homing_error),
                Some(Mode::ProfileTorque) | None => (!self.loops.limited, false, false),
            }
        };
        for (on, bit) in [(reached, sw::TARGET_REACHED), (bit12, sw::MODE_SPECIFIC_12), (bit13, sw::MODE_SPECIFIC_13)] {
            if on {
                word |= bit;
            }
        }
        word
    }

    /// Position command minus actual position, counts; 0 with the power stage off and in the
    /// modes without a position command (profile velocity and torque, unless a stop ramp runs).
    fn following_error(&self) -> f64 {
        if !self.state.is_power_stage_on() {
            return 0.0;
        }
        match self.mode {
            Some(Mode::ProfileVelocity | Mode::ProfileTorque) if !self.stopping => 0.0,
            _ => self.command - self.shaft.position,
        }
    }

    /// Writes the actual values into the object dictionary.
    fn publish(&self, od: &mut ObjectDictionary) {
        let position = self.reported(self.shaft.position);
        let in_units_of = |index| (position * od.position_scale(index, 0)).round() as i64 as i32;
        let (internal, actual) = (in_units_of(0x6063), in_units_of(0x6064));
        let following_error = self.following_error();
        let window = u32_of(od, 0x6065) as f64;
        od.set(0x6041, 0, &self.statusword(od, following_error, window).to_le_bytes());
        od.set(0x6061, 0, &[self.mode.map_or(0, |m| m as i8) as u8]);
        od.set(0x6063, 0, &internal.to_le_bytes());
        od.set(0x6064, 0, &actual.to_le_bytes());
        od.set(0x606C, 0, &(self.shaft.velocity.round() as i64 as i32).to_le_bytes());
        let torque = (self.shaft.torque / self.mechanics.peak_torque * 1000.0).round() as i16;
        od.set(0x6077, 0, &torque.to_le_bytes());
        od.set(0x60F4, 0, &(following_error.round() as i64 as i32).to_le_bytes());
        od.set(0x603F, 0, &self.last_error_code.to_le_bytes());
        od.set(0x1001, 0, &[self.fault.map_or(0, |f| f.error_register())]);
        let levels = self.inputs.levels(position);
        self.latch.publish(od, levels);
        self.terminals.publish(od, levels);
        self.touch_probe.publish(od);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const MS: u64 = 1_000_000;

    /// A drive and its dictionary, run at bus time `now` with SDO-like writes between runs.
    struct Bench {
        drive: DriveFirmware,
        od: ObjectDictionary,
        now: u64,
        emergencies: Vec<u16>,
    }

    impl Bench {
        fn new() -> Bench {
            let mut b =
                Bench { drive: DriveFirmware::default(), od: ObjectDictionary::akd(), now: 0, emergencies: Vec::new() };
            b.run_for(0);
            b
        }

        fn write(&mut self, index: u16, subindex: u8, value: &[u8]) {
            self.od.set(index, subindex, value);
        }

        fn controlword(&mut self, controlword: u16) {
            self.write(0x6040, 0, &controlword.to_le_bytes());
            self.run_for(MS);
        }

        fn run_with(&mut self, duration: u64, bus: Bus<'_>) {
            self.now += duration;
            if let Some(e) = self.drive.run(&mut self.od, self.now, bus) {
                self.emergencies.push(e.error_code);
            }
        }

        fn run_for(&mut self, duration: u64) {
            self.run_with(duration, Bus::default());
        }

        fn enable(&mut self, mode: i8) {
            self.write(0x6060, 0, &[mode as u8]);
            for controlword in [cw::SHUTDOWN, cw::SWITCH_ON_COMMAND, cw::ENABLE_OPERATION_COMMAND] {
                self.controlword(controlword);
            }
            assert_eq!(self.drive.state(), State::OperationEnabled);
        }

        /// Operation enabled in profile velocity at `revs_per_s` after `duration`.
        fn spin(&mut self, revs_per_s: i32, duration: u64) {
            self.enable(3);
            self.write(0x60FF, 0, &(revs_per_s << 20).to_le_bytes());
            self.run_for(duration);
        }

        fn i32(&self, index: u16) -> i32 {
            i32_of(&self.od, index, 0)
        }
    }

    #[test]
    fn quick_stop_ramps_with_0x6085_and_holds_in_quick_stop_active() {
        let mut b = Bench::new();
        b.spin(10, 300 * MS);
        assert!((b.drive.shaft().velocity - COUNTS_PER_REV * 10.0).abs() < COUNTS_PER_REV * 0.05);
        b.controlword(cw::QUICK_STOP_COMMAND);
        assert_eq!(b.drive.state(), State::QuickStopActive);
        assert_eq!(b.od.get(0x6041, 0).unwrap()[0] & 0x6F, 0x07, "quick stop bit 5 low");
        // 10 rev/s at 100 rev/s² stops in 0.1 s; it has not stopped half-way.
        b.run_for(50 * MS);
        assert!(b.drive.shaft().velocity > COUNTS_PER_REV * 3.0, "{}", b.drive.shaft().velocity);
        b.run_for(100 * MS);
        assert!(b.drive.shaft().velocity.abs() < COUNTS_PER_REV * 0.01, "{}", b.drive.shaft().velocity);
        // The command stands still; the shaft settles on it (dry friction and the integrator
        // leave a few counts of stick-slip) and stays.
        let command = b.drive.command;
        for _ in 0..10 {
            b.run_for(100 * MS);
            assert!((b.drive.shaft().position - command).abs() < 20.0, "held at {command}: {:?}", b.drive.shaft());
        }
        assert_eq!(b.drive.state(), State::QuickStopActive);
    }

    #[test]
    fn a_drive_disabled_while_its_shaft_is_held_by_friction_reports_no_torque() {
        // 5 thousandths of the 3 N·m peak, 0.015 N·m, is less than the shaft's dry friction: it stays at rest.
        let mut b = Bench::new();
        b.enable(4);
        b.write(0x6071, 0, &5i16.to_le_bytes());
        b.run_for(100 * MS);
        assert_eq!((b.drive.shaft().velocity, b.od.get(0x6077, 0).unwrap()[..2].to_vec()), (0.0, vec![5, 0]));
        b.controlword(cw::DISABLE_VOLTAGE);
        b.run_for(100 * MS);
        assert_eq!(b.drive.state(), State::SwitchOnDisabled);
        assert_eq!(b.od.get(0x6077, 0).unwrap()[..2], [0, 0], "a power stage that is off makes no torque");
    }

    #[test]
    fn with_the_power_stage_off_the_motor_coasts_to_a_stop() {
        let mut b = Bench::new();
        b.spin(5, 200 * MS);
        b.controlword(cw::DISABLE_VOLTAGE);
        assert_eq!(b.drive.state(), State::SwitchOnDisabled);
        let at_disable = b.drive.position();
        b.run_for(3000 * MS);
        assert_eq!(b.drive.shaft().velocity, 0.0, "friction stopped it");
        assert!(b.drive.position() > at_disable + COUNTS_PER_REV * 0.1, "it coasted on");
        assert_eq!(b.i32(0x6064), b.drive.position().round() as i32);
        assert_eq!(b.i32(0x60F4), 0, "no command while disabled");
    }

    #[test]
    fn f125_counts_missed_frames_from_the_last_process_data() {
        // The eighth frame after the last one at T is due at T + 16 ms and missed half a
        // cycle later, at T + 17 ms.
        for (silence, faults) in [(17 * MS - STEP_NS, false), (17 * MS, true)] {
            let mut b = Bench::new();
            let image = [PdoEntry::new(0x6040, 0, 16), PdoEntry::new(0x607A, 0, 32)];
            let expected = |received| Bus { received, process_data_expected: true, ..Bus::default() };
            b.write(0x60C2, 2, &[(-3i8) as u8]);
            b.enable(8);
            for _ in 0..5 {
                b.run_with(2 * MS, expected(Some(Received { at_ns: b.now, image: &image })));
            }
            let last = b.now - 2 * MS;
            b.run_with(last + silence - b.now, expected(None));
            assert_eq!(b.drive.fault() == Some(Fault::SyncLost), faults, "{silence} ns of silence");
            assert_eq!(b.emergencies, if faults { vec![0x8700] } else { vec![] });
        }
    }

    #[test]
    fn f125_judged_by_frames_lost_ignores_a_late_frame_and_counts_lost_ones() {
        for (lost, faults) in [(0, false), (7, false), (8, true)] {
            let mut b = Bench::new();
            let image = [PdoEntry::new(0x6040, 0, 16), PdoEntry::new(0x607A, 0, 32)];
            let bus = |received, frames_lost| Bus {
                received,
                process_data_expected: true,
                missed_frames: MissedFrames::Lost,
                frames_lost,
                ..Bus::default()
            };
            b.write(0x60C2, 2, &[(-3i8) as u8]);
            b.enable(8);
            for _ in 0..5 {
                b.run_with(2 * MS, bus(Some(Received { at_ns: b.now, image: &image }), 0));
            }
            // 25 cycles' silence (F125 by time), `lost` frames of them lost on the line.
            b.run_with(50 * MS, bus(None, lost));
            assert_eq!(b.drive.fault() == Some(Fault::SyncLost), faults, "{lost} frames lost");
        }
    }

    #[test]
    fn f706_when_no_set_point_follows_the_enable() {
        let mut b = Bench::new();
        b.enable(7);
        b.run_for(SETPOINT_TIMEOUT_NS - 2 * MS);
        assert_eq!(b.drive.fault(), None);
        b.run_for(2 * MS);
        assert_eq!(b.drive.fault(), Some(Fault::SetpointsMissing));
        assert_eq!(b.drive.state(), State::Fault);
        assert_eq!(u16_of(&b.od, 0x603F), 0x8250);
        assert_eq!(b.od.get(0x1001, 0).unwrap(), [0x11]);
    }

    #[test]
    fn profile_position_relative_moves() {
        let mut b = Bench::new();
        b.enable(1);
        b.write(0x607A, 0, &(1i32 << 20).to_le_bytes());
        for _ in 0..2 {
            b.controlword(cw::ENABLE_OPERATION_COMMAND | cw::NEW_SETPOINT | cw::RELATIVE);
            b.controlword(cw::ENABLE_OPERATION_COMMAND | cw::RELATIVE);
            b.run_for(1000 * MS);
        }
        assert!((b.drive.position() - 2.0 * COUNTS_PER_REV).abs() <= POSITION_WINDOW, "{}", b.drive.position());
        assert_ne!(u16_of(&b.od, 0x6041) & sw::TARGET_REACHED, 0);
    }

    const HOMING_BITS: u16 = sw::MODE_SPECIFIC_13 | sw::MODE_SPECIFIC_12 | sw::TARGET_REACHED;

    /// Starts homing on an enabled drive: mode 6, then bit 4's rising edge.
    fn start_homing(b: &mut Bench) {
        b.write(0x6060, 0, &[6]);
        b.controlword(cw::ENABLE_OPERATION_COMMAND);
        assert_eq!(u16_of(&b.od, 0x6041) & HOMING_BITS, sw::TARGET_REACHED, "not started");
        b.controlword(cw::ENABLE_OPERATION_COMMAND | cw::NEW_SETPOINT);
    }

    #[test]
    fn homing_moves_to_the_reference_at_its_speed_and_makes_it_the_zero() {
        let mut b = Bench::new();
        b.drive.shaft.position = -COUNTS_PER_REV;
        b.enable(8);
        let setup = b.drive.homing_setup();
        start_homing(&mut b);
        assert_eq!(u16_of(&b.od, 0x6041) & HOMING_BITS, 0, "in progress");
        b.run_for(300 * MS);
        // At the homing speed, toward the reference, before it is reached.
        let v = b.drive.shaft().velocity;
        assert!((v - setup.speed).abs() < 0.05 * setup.speed, "{v}");
        assert_eq!(u16_of(&b.od, 0x6041) & HOMING_BITS, 0);
        b.run_for(1200 * MS);
        assert_eq!(u16_of(&b.od, 0x6041) & HOMING_BITS, sw::MODE_SPECIFIC_12 | sw::TARGET_REACHED, "attained");
        assert!(b.i32(0x6064).abs() <= 20, "{}", b.i32(0x6064));
        assert!((b.drive.shaft().position - setup.reference).abs() <= 20.0);
        // Attained goes with the mode: back in a cyclic mode (whose set-points are due from the
        // change, not from the enable), then homing again, it starts over.
        b.write(0x6060, 0, &[8]);
        b.run_for(MS);
        assert_eq!(b.drive.fault(), None);
        start_homing(&mut b);
    }

    #[test]
    fn homing_fails_as_set_up_and_a_halt_interrupts_it() {
        let mut b = Bench::new();
        b.enable(8);
        let mut setup = b.drive.homing_setup();
        setup.failure = Some(homing::Failure::Error);
        b.drive.set_homing(setup);
        start_homing(&mut b);
        b.run_for(1000 * MS);
        let error = sw::MODE_SPECIFIC_13 | sw::TARGET_REACHED;
        assert_eq!(u16_of(&b.od, 0x6041) & HOMING_BITS, error);
        assert!((b.drive.shaft().position - setup.reference / 2.0).abs() <= 20.0, "stopped halfway");
        setup.failure = Some(homing::Failure::NoReference);
        b.drive.set_homing(setup);
        b.controlword(cw::ENABLE_OPERATION_COMMAND);
        b.controlword(cw::ENABLE_OPERATION_COMMAND | cw::NEW_SETPOINT);
        b.run_for(1000 * MS);
        assert!(b.drive.shaft().position > 1.5 * setup.reference, "searched past it");
        assert_eq!(u16_of(&b.od, 0x6041) & HOMING_BITS, 0, "still in progress");
        b.controlword(cw::ENABLE_OPERATION_COMMAND | cw::NEW_SETPOINT | cw::HALT);
        b.run_for(200 * MS);
        assert_eq!(u16_of(&b.od, 0x6041) & HOMING_BITS, sw::TARGET_REACHED, "interrupted");
        assert_eq!(b.drive.state(), State::OperationEnabled);
    }

    #[test]
    fn cyclic_positions_cross_the_32_bit_wrap_the_short_way() {
        let mut b = Bench::new();
        let image = [PdoEntry::new(0x607A, 0, 32)];
        b.drive.shaft.position = i32::MAX as f64 - 5000.0;
        b.enable(8);
        let mut target = b.i32(0x6064);
        for _ in 0..100 {
            target = target.wrapping_add(100);
            b.write(0x607A, 0, &target.to_le_bytes());
            let bus = Bus { received: Some(Received { at_ns: b.now, image: &image }), ..Bus::default() };
            b.run_with(MS, bus);
        }
        b.run_for(20 * MS);
        assert_eq!(b.drive.fault(), None);
        // Settled within the few counts of stick-slip, past the wrap: not 2^32 counts back.
        assert!(b.i32(0x6064) < 0 && b.i32(0x6064).wrapping_sub(target).abs() <= 20, "{}", b.i32(0x6064));
    }

    #[test]
    fn a_limit_switch_stops_a_move_toward_it_and_lets_one_away_from_it_go() {
        let mut b = Bench::new();
        b.spin(2, 200 * MS);
        b.drive.terminals_mut().set_switch("positive_limit", true).unwrap();
        // 2 rev/s braked at 0x6085 (100 rev/s²) stop within 20 ms.
        b.run_for(100 * MS);
        assert!(b.drive.shaft().velocity.abs() < VELOCITY_WINDOW, "{:?}", b.drive.shaft());
        assert_ne!(u16_of(&b.od, 0x6041) & sw::INTERNAL_LIMIT, 0, "bit 11 while it holds the command back");
        assert_eq!((b.drive.state(), b.drive.fault()), (State::OperationEnabled, None));
        assert_eq!(u32_of(&b.od, 0x60FD) & 0x3, 0x2, "0x60FD bit 1: positive limit switch");
        b.write(0x60FF, 0, &(-(1i32 << 20)).to_le_bytes());
        b.run_for(300 * MS);
        assert!(b.drive.shaft().velocity < -0.9 * COUNTS_PER_REV, "{:?}", b.drive.shaft());
        assert_eq!(u16_of(&b.od, 0x6041) & sw::INTERNAL_LIMIT, 0);
    }

    #[test]
    fn max_torque_0x6072_limits_the_torque_and_sets_internal_limit() {
        let mut b = Bench::new();
        b.enable(4);
        b.write(0x6072, 0, &200u16.to_le_bytes());
        b.write(0x6071, 0, &500i16.to_le_bytes());
        b.run_for(10 * MS);
        assert_eq!(bytes::<2>(&b.od, 0x6077, 0), 200i16.to_le_bytes());
        assert_ne!(u16_of(&b.od, 0x6041) & sw::INTERNAL_LIMIT, 0);
    }
}
