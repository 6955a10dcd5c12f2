//! Events the cycle thread reports — latch captures, faults, command time-outs, what became
//! of trajectories, changes of a drive's digital inputs and of a device's — as four words each through a
//! [`Ring`], so that the thread never waits for whoever reads them; a full ring drops and
//! counts, so what was missed is known.

use crate::cycle::ring::Ring;
use crate::ethercat::master::state::AlStatus;

/// Events the ring holds before new ones are dropped.
pub const CAPACITY: usize = 256;

named_variants! {
    /// A latch edge.
    pub enum Edge {
        /// The input went high.
        Rising => "rising",
        /// The input went low.
        Falling => "falling",
    }
    /// The edge's name as the Python API and the messages spell it.
    fn name;
}

wire_codes! {
    /// What a fault event is about.
    pub enum FaultSource: u8, "fault source" {
        /// The statusword shows Fault (or Fault reaction active); the code is 0x603F's.
        DriveFault = 1 => "drive_fault",
        /// The drive sent a CoE emergency message; the code is the message's.
        Emergency = 2 => "emergency",
        /// Frames were lost while a drive was enabled; the code is how many in a row.
        LostFrames = 3 => "lost_frames",
        /// The cyclic working counter was wrong while a drive was enabled; the code is how many
        /// cycles in a row.
        WorkingCounter = 4 => "working_counter",
        /// The slave left Op; the AL status says where it went and why.
        AlState = 5 => "al_state",
        /// The slave stopped answering (power, cable, line); the code is how many cycles in a
        /// row. It is being brought back ([`recovery`](crate::cycle::recovery)).
        Unreachable = 6 => "unreachable",
        /// The slave is back in Op after it was lost or left Op, its power stage off; the code is
        /// how long it was gone (ms, saturating).
        Recovered = 7 => "recovered",
    }
}

named_variants! {
    /// What the cycle thread did about a fault.
    #[repr(u8)]
    pub enum Action {
        /// Reported only: the drive's own reaction (or another event's action) covers it.
        Reported = 1 => "reported; the drive reacts by itself (power stage off in Fault)",
        /// The drive was asked for Switch on disabled and its target held at the actual position.
        Disabled = 2 => "drive disabled (Switch on disabled requested) with its target held at the actual position; \
            nothing moves until it is reset, enabled and commanded again",
        /// Counted: the drive held its last set-point through a short gap and went on.
        Counted = 3 => "counted; the drive held its last set-point through the gap and no more than that",
        /// Restored: the slave is back in Op (with its address, mapping, mode and clock set again
        /// where it had lost them), its power stage off and its target held at the actual position.
        Restored = 4 => "back in Op (readdressed and reconfigured where it had lost its configuration), its power \
            stage off and its target held at the actual position; nothing moves until it is enabled and commanded \
            again",
        /// A device beside the drives (a terminal) was lost or left Op: its outputs were
        /// switched off in the process image, where they stay until set again.
        OutputsOff = 5 => "its outputs switched off; they stay off until set again",
        /// A device is back in Op, its outputs off.
        RestoredOutputsOff = 6 => "back in Op (readdressed and reconfigured where it had lost its configuration), its \
            outputs off until set again",
    }
    /// One sentence for the fault message and the log.
    fn describe;
}

wire_codes! {
    /// What the command time-out does when a velocity or torque stream stops.
    pub enum CommandTimeoutAction: u8, "command time-out action" {
        /// Halt (controlword bit 8) until the next target write.
        Halt = 1 => "hold",
        /// Quick stop: the drive brakes and holds in Quick stop active until enabled again.
        QuickStop = 2 => "quick_stop",
    }
}

impl CommandTimeoutAction {
    /// What was done, for the log.
    pub fn describe(self) -> &'static str {
        match self {
            CommandTimeoutAction::Halt => "halted, holding until the next command",
            CommandTimeoutAction::QuickStop => "quick stop",
        }
    }
}

wire_codes! {
    /// The target a command stream writes.
    pub enum CommandedTarget: u8, "commanded target" {
        /// Target velocity 0x60FF (profile velocity), counts/s.
        Velocity = 1 => "velocity",
        /// Target torque 0x6071 (profile torque), 0.1 % of peak torque.
        Torque = 2 => "torque",
    }
}

/// Where a trajectory handed to the cycle thread stands.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TrajectoryState {
    /// Handed over, waiting for its start.
    Pending,
    /// Being followed.
    Running,
    /// Past its last point: its drives hold the last point's positions.
    Done,
    /// A newer trajectory took over.
    Replaced {
        /// The newer trajectory's id.
        by: u32,
    },
    /// A drive left Operation enabled (fault, disable, quick stop, hardware enable low): the
    /// trajectory stopped, its other drives holding where they were.
    Aborted {
        /// The drive's position on the bus.
        slave: u16,
        /// Its statusword then.
        statusword: u16,
    },
    /// Stopped on request (a cancel): its drives decelerated to a standstill.
    Stopped,
    /// A drive strayed past the path tolerance while it ran: its drives decelerated to a
    /// standstill.
    PathToleranceViolated(Violation),
    /// A drive was not within the goal tolerance by the end plus the goal time tolerance.
    GoalToleranceViolated(Violation),
    /// Refused when it was to take over, nothing moved: from the set-point then in force, a
    /// drive's segment to the first point would go past its limits, or a drive of the
    /// trajectory in force that this one does not drive was still moving. The trajectory in
    /// force goes on.
    Refused(Refusal),
}

/// Why a trajectory was refused when it was to take over, and of which drive.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Refusal {
    /// The drive's position on the bus.
    pub slave: u16,
    /// Why.
    pub why: RefusalReason,
    /// The value that went past the limit (counts, counts/s or counts/s²; the velocity step, or
    /// the velocity of the drive left moving).
    pub value: f32,
}

wire_codes! {
    /// What a refusal at the take-over judged.
    pub enum RefusalReason: u8, "trajectory refusal" {
        /// Its segment to the first point went past the drive's position limits.
        Position = 0 => "position",
        /// ... past its max velocity.
        Velocity = 1 => "max_velocity",
        /// ... past its max acceleration.
        Acceleration = 2 => "max_acceleration",
        /// Its set-point's velocity would step where its acceleration is limited.
        VelocityStep = 3 => "velocity_step",
        /// It is a drive of the trajectory in force, not of this one, and it was still moving.
        LeftMoving = 4 => "left_moving",
    }
}

// A refusal's value is what a finite trajectory reached, never NaN: equal to itself.
impl Eq for Refusal {}

impl Refusal {
    /// In 56 bits: `code` plus the reason, the drive, the value as an f32.
    fn pack(self, code: u64) -> u64 {
        (code + self.why as u64) | (self.slave as u64) << 8 | (self.value.to_bits() as u64) << 24
    }

    fn unpack(v: u64, code: u8) -> Option<Refusal> {
        Some(Refusal {
            why: RefusalReason::try_from((v as u8).checked_sub(code)?).ok()?,
            slave: (v >> 8) as u16,
            value: f32::from_bits((v >> 24) as u32),
        })
    }
}

/// Which drive strayed from a trajectory and by how much.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Violation {
    /// The drive's position on the bus.
    pub slave: u16,
    /// Whether its velocity strayed (else its position).
    pub velocity: bool,
    /// The error, set-point minus actual: counts, or counts/s for a velocity.
    pub error: i32,
}

impl Violation {
    /// In 56 bits (an event keeps a state in 56): `code` for a position, the next for a
    /// velocity, the drive, the error.
    fn pack(self, code: u64) -> u64 {
        (code + self.velocity as u64) | (self.slave as u64) << 8 | (self.error as u32 as u64) << 24
    }

    fn unpack(v: u64, code: u8) -> Violation {
        Violation { slave: (v >> 8) as u16, velocity: v as u8 != code, error: (v >> 24) as u32 as i32 }
    }
}

impl TrajectoryState {
    /// The state's name as the Python API spells it.
    pub fn name(self) -> &'static str {
        match self {
            TrajectoryState::Pending => "pending",
            TrajectoryState::Running => "running",
            TrajectoryState::Done => "done",
            TrajectoryState::Replaced { .. } => "replaced",
            TrajectoryState::Aborted { .. } => "aborted",
            TrajectoryState::Stopped => "stopped",
            TrajectoryState::PathToleranceViolated(_) => "path_tolerance_violated",
            TrajectoryState::GoalToleranceViolated(_) => "goal_tolerance_violated",
            TrajectoryState::Refused(_) => "refused",
        }
    }

    /// Whether the trajectory is over.
    pub fn ended(self) -> bool {
        !matches!(self, TrajectoryState::Pending | TrajectoryState::Running)
    }

    /// The state in 64 bits: a code, then the replacing id, the drive and its statusword, or
    /// the violation.
    pub fn pack(self) -> u64 {
        match self {
            TrajectoryState::Pending => 1,
            TrajectoryState::Running => 2,
            TrajectoryState::Done => 3,
            TrajectoryState::Replaced { by } => 4 | (by as u64) << 8,
            TrajectoryState::Aborted { slave, statusword } => 5 | (slave as u64) << 8 | (statusword as u64) << 24,
            TrajectoryState::Stopped => 6,
            TrajectoryState::PathToleranceViolated(v) => v.pack(7),
            TrajectoryState::GoalToleranceViolated(v) => v.pack(9),
            TrajectoryState::Refused(r) => r.pack(11),
        }
    }

    /// The state [`pack`](Self::pack) gave.
    pub fn unpack(v: u64) -> Option<TrajectoryState> {
        match v as u8 {
            1 => Some(TrajectoryState::Pending),
            2 => Some(TrajectoryState::Running),
            3 => Some(TrajectoryState::Done),
            4 => Some(TrajectoryState::Replaced { by: (v >> 8) as u32 }),
            5 => Some(TrajectoryState::Aborted { slave: (v >> 8) as u16, statusword: (v >> 24) as u16 }),
            6 => Some(TrajectoryState::Stopped),
            7 | 8 => Some(TrajectoryState::PathToleranceViolated(Violation::unpack(v, 7))),
            9 | 10 => Some(TrajectoryState::GoalToleranceViolated(Violation::unpack(v, 9))),
            11..=15 => Some(TrajectoryState::Refused(Refusal::unpack(v, 11)?)),
            _ => None,
        }
    }
}

/// One event.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Event {
    /// A position captured by a latch (or touch probe).
    Latch {
        /// The cycle that saw it.
        cycle: u64,
        /// That cycle's wake-up time (ns, monotonic).
        time_ns: u64,
        /// The slave's position on the bus.
        slave: u16,
        /// Latch 1 or 2.
        channel: u8,
        /// Which edge.
        edge: Edge,
        /// The captured position (counts).
        position: i32,
    },
    /// A fault.
    Fault {
        /// The cycle that saw it.
        cycle: u64,
        /// That cycle's wake-up time (ns, monotonic).
        time_ns: u64,
        /// The slave's position on the bus.
        slave: u16,
        /// What it is about.
        source: FaultSource,
        /// The error code (see [`FaultSource`]), 0 when none.
        code: u16,
        /// The statusword of that cycle.
        statusword: u16,
        /// AL status 0x0130 of that cycle (0 when not read).
        al_status: u16,
        /// AL status code 0x0134 of that cycle.
        al_status_code: u16,
        /// What was done about it.
        action: Action,
    },
    /// A velocity or torque stream stopped for longer than the command time-out while the
    /// drive was in Operation enabled.
    CommandTimeout {
        /// The cycle that saw it.
        cycle: u64,
        /// That cycle's wake-up time (ns, monotonic).
        time_ns: u64,
        /// The slave's position on the bus.
        slave: u16,
        /// Which target the stream wrote.
        target: CommandedTarget,
        /// Its last value (drive units).
        value: i32,
        /// The time-out (µs, saturating).
        timeout_us: u32,
        /// The statusword of that cycle.
        statusword: u16,
        /// What was done.
        action: CommandTimeoutAction,
    },
    /// A drive's digital inputs 0x60FD, or its hardware enable as its statusword shows it,
    /// changed in this cycle's inputs ([`crate::drive::io::InputWatch`]).
    Inputs {
        /// The cycle whose inputs showed it.
        cycle: u64,
        /// That cycle's wake-up time (ns, monotonic).
        time_ns: u64,
        /// The slave's position on the bus.
        slave: u16,
        /// 0x60FD (0 where the mapping lacks it).
        digital_inputs: u32,
        /// The statusword of that cycle.
        statusword: u16,
    },
    /// A device's inputs of one bit (an EL1004's) changed in this cycle's inputs
    /// ([`crate::cycle::devices`]).
    DeviceInputs {
        /// The cycle whose inputs showed it.
        cycle: u64,
        /// That cycle's wake-up time (ns, monotonic).
        time_ns: u64,
        /// The slave's position on the bus.
        slave: u16,
        /// Their levels, the device's first input channel of one bit in bit 0 (up to 64).
        levels: u64,
    },
    /// A trajectory started ([`TrajectoryState::Running`]) or ended.
    Trajectory {
        /// The cycle that saw it.
        cycle: u64,
        /// That cycle's wake-up time (ns, monotonic).
        time_ns: u64,
        /// The trajectory's id.
        id: u32,
        /// Where it stands now.
        state: TrajectoryState,
    },
}

impl Event {
    /// A fault of the slave at `slave` seen in the cycle `at` (its number and wake-up time),
    /// with the statusword and AL status of that cycle (0 where not known).
    pub fn fault(
        at: (u64, u64),
        slave: u16,
        statusword: u16,
        al: Option<AlStatus>,
        (source, code, action): (FaultSource, u16, Action),
    ) -> Event {
        let (al_status, al_status_code) = al.map_or((0, 0), |a| (a.status, a.code));
        Event::Fault { cycle: at.0, time_ns: at.1, slave, source, code, statusword, al_status, al_status_code, action }
    }

    fn encode(&self) -> [u64; 4] {
        match *self {
            Event::Latch { cycle, time_ns, slave, channel, edge, position } => [
                cycle,
                time_ns,
                1 | (slave as u64) << 8 | (channel as u64) << 24 | ((edge == Edge::Falling) as u64) << 32,
                position as u32 as u64,
            ],
            Event::Fault { cycle, time_ns, slave, source, code, statusword, al_status, al_status_code, action } => [
                cycle,
                time_ns,
                2 | (slave as u64) << 8 | (source as u64) << 24 | (action as u64) << 32,
                code as u64 | (statusword as u64) << 16 | (al_status as u64) << 32 | (al_status_code as u64) << 48,
            ],
            Event::CommandTimeout { cycle, time_ns, slave, target, value, timeout_us, statusword, action } => [
                cycle,
                time_ns,
                3 | (slave as u64) << 8 | (action as u64) << 24 | (target as u64) << 32 | (statusword as u64) << 40,
                value as u32 as u64 | (timeout_us as u64) << 32,
            ],
            Event::Trajectory { cycle, time_ns, id, state } => [cycle, time_ns, 4 | state.pack() << 8, id as u64],
            Event::Inputs { cycle, time_ns, slave, digital_inputs, statusword } => {
                [cycle, time_ns, 5 | (slave as u64) << 8 | (statusword as u64) << 24, digital_inputs as u64]
            }
            Event::DeviceInputs { cycle, time_ns, slave, levels } => [cycle, time_ns, 6 | (slave as u64) << 8, levels],
        }
    }

    fn decode(w: [u64; 4]) -> Option<Event> {
        let [cycle, time_ns, what, data] = w;
        let slave = (what >> 8) as u16;
        match what as u8 {
            1 => Some(Event::Latch {
                cycle,
                time_ns,
                slave,
                channel: (what >> 24) as u8,
                edge: if (what >> 32) & 1 == 1 { Edge::Falling } else { Edge::Rising },
                position: data as u32 as i32,
            }),
            2 => Some(Event::Fault {
                cycle,
                time_ns,
                slave,
                source: FaultSource::try_from((what >> 24) as u8).ok()?,
                code: data as u16,
                statusword: (data >> 16) as u16,
                al_status: (data >> 32) as u16,
                al_status_code: (data >> 48) as u16,
                action: *Action::ALL.iter().find(|a| **a as u8 == (what >> 32) as u8)?,
            }),
            3 => Some(Event::CommandTimeout {
                cycle,
                time_ns,
                slave,
                target: CommandedTarget::try_from((what >> 32) as u8).ok()?,
                value: data as u32 as i32,
                timeout_us: (data >> 32) as u32,
                statusword: (what >> 40) as u16,
                action: *CommandTimeoutAction::ALL.iter().find(|a| **a as u8 == (what >> 24) as u8)?,
            }),
            4 => {
                Some(Event::Trajectory { cycle, time_ns, id: data as u32, state: TrajectoryState::unpack(what >> 8)? })
            }
            5 => Some(Event::Inputs {
                cycle,
                time_ns,
                slave,
                digital_inputs: data as u32,
                statusword: (what >> 24) as u16,
            }),
            6 => Some(Event::DeviceInputs { cycle, time_ns, slave, levels: data }),
            _ => None,
        }
    }
}

/// The events the cycle thread has reported and nobody has taken yet.
pub struct Events {
    ring: Ring<4>,
}

impl Default for Events {
    fn default() -> Self {
        Events { ring: Ring::new(CAPACITY) }
    }
}

impl Events {
    /// Adds `event` (the cycle thread only); counts it as dropped when the ring is full.
    pub fn push(&self, event: Event) {
        self.ring.push(event.encode());
    }

    /// Takes every event pushed since the last call, oldest first.
    pub fn drain(&self) -> Vec<Event> {
        self.ring.drain(Event::decode)
    }

    /// Whether an event waits to be taken.
    pub fn pending(&self) -> bool {
        self.ring.pending()
    }

    /// Events pushed so far (dropped ones not counted).
    pub fn pushed(&self) -> u64 {
        self.ring.pushed()
    }

    /// Events dropped because the ring was full.
    pub fn dropped(&self) -> u64 {
        self.ring.dropped()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn events_round_trip_and_a_full_ring_drops_and_counts() {
        let events = Events::default();
        let latch = Event::Latch { cycle: 7, time_ns: 9, slave: 2, channel: 1, edge: Edge::Falling, position: -5 };
        let fault = Event::Fault {
            cycle: 8,
            time_ns: 10,
            slave: 0,
            source: FaultSource::AlState,
            code: 0x8611,
            statusword: 0x0218,
            al_status: 0x0014,
            al_status_code: 0x001B,
            action: Action::Disabled,
        };
        let timeout = Event::CommandTimeout {
            cycle: 9,
            time_ns: 11,
            slave: 3,
            target: CommandedTarget::Torque,
            value: -300,
            timeout_us: 500_000,
            statusword: 0x1637,
            action: CommandTimeoutAction::QuickStop,
        };
        let inputs =
            Event::Inputs { cycle: 12, time_ns: 13, slave: 0xFFFE, digital_inputs: 0x8001_0002, statusword: 0xC0DE };
        events.push(latch);
        events.push(fault);
        events.push(timeout);
        events.push(inputs);
        let device = Event::DeviceInputs { cycle: 14, time_ns: 15, slave: 3, levels: u64::MAX - 2 };
        events.push(device);
        let trajectories = [
            TrajectoryState::Running,
            TrajectoryState::Done,
            TrajectoryState::Replaced { by: u32::MAX },
            TrajectoryState::Aborted { slave: 0xFFFE, statusword: 0x0218 },
        ]
        .map(|state| Event::Trajectory { cycle: 10, time_ns: 12, id: 7, state });
        trajectories.iter().for_each(|t| events.push(*t));
        assert_eq!(events.drain(), [[latch, fault, timeout, inputs, device].as_slice(), &trajectories].concat());
        assert_eq!(TrajectoryState::unpack(TrajectoryState::Pending.pack()), Some(TrajectoryState::Pending));
        assert!(events.drain().is_empty());
        for _ in 0..CAPACITY + 3 {
            events.push(latch);
        }
        assert_eq!(events.dropped(), 3);
        assert_eq!(events.drain().len(), CAPACITY);
    }
}
