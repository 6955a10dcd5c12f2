//! Joint trajectories followed by the cycle thread: every cycle it evaluates the trajectory in
//! force at the cycle's wake-up time and writes each joint's position target into its drive's
//! outputs, so the set-points come at the cycle rate whatever Python's scheduling does.
//!
//! The handoff never makes the loop allocate, free or wait. A [`Plan`] (the validated
//! [`Trajectory`], its drives and where their targets are) is built and boxed in the caller's
//! thread and handed over through one atomic pointer ([`PlayerShared::give`]); the loop takes it
//! ([`Player::before_copy`]) and, once done with it (done, replaced, aborted), puts the box
//! into one of [`OUTBOX`] return slots, from which the caller's next call takes and drops it
//! ([`PlayerShared::collect`]), reading its final [`TrajectoryStatus`]. The loop takes a new plan only when
//! nothing of its own waits to be returned; from one take to the next it retires at most
//! three plans (the one waiting to start, the one running, the new one), so its own waiting
//! room of three never overflows when the caller does not collect.
//!
//! A plan waits for its start (`None`: the cycle that takes it; a start already past starts
//! then, the whole trajectory shifted, never cut short). At its start it takes over from each
//! drive's set-point: where the trajectory in force drives the same drive, from that one's
//! position, velocity and acceleration at that instant; else from the target the drive was
//! last sent, at rest. So there is no step. Each joint's target is rounded to counts and
//! written as a set-point write of the user's would be (it releases a held target), and into
//! the set-point buffer too, so the drives keep it once the trajectory ends. A drive of the
//! trajectory that leaves Operation enabled aborts it; that drive is the sequencer's from then
//! on, and the others hold where they were.
//!
//! A plan may carry [`Tolerances`] (FollowJointTrajectory's): every cycle while it runs, each
//! drive's actual position and velocity are judged against the set-point of the cycle before
//! (the one the drive has had a cycle to follow) by the path tolerance; past the last point,
//! against the last point by the goal tolerance, until the goal time tolerance runs out. A stop
//! ([`PlayerShared::stop`], a cancel) or a path violation brakes every joint from its set-point in
//! force at its stop deceleration to a standstill, then ends the plan; the set-points are
//! published each cycle ([`PlayerShared::followed`]) for feedback.

use std::collections::VecDeque;
use std::sync::atomic::{AtomicPtr, AtomicU32, Ordering};
use std::sync::Mutex;

use crate::cycle::events::{Event, Events, Refusal, RefusalReason, TrajectoryState, Violation};
use crate::cycle::image::{i32_at, u16_at};
use crate::cycle::seqlock::SeqBytes;
use crate::drive::ds402::State;
use crate::drive::trajectory::{Breach, Limit, Segment, Setpoint, Trajectory};
use crate::error::{Error, Result, TrajectoryError, Unavailable};

/// Return slots for plans the loop is done with.
pub const OUTBOX: usize = 4;

/// Statuses of ended trajectories the caller side keeps for [`Caller::status`].
pub const KEPT: usize = 64;

/// Plans retired between two takes at most: the one waiting to start, the one running and
/// the one taken.
const WAITING: usize = 3;

/// Stop requests the callers can have open at once: more than trajectories can be in force
/// (handed over and not collected: in the inbox, pending, running, waiting or returned), so a
/// stop always finds a slot.
const STOPS: usize = 16;
const _: () = assert!(STOPS > 3 + WAITING + OUTBOX);

/// One joint: its drive and where its objects are in the whole images.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Joint {
    /// The drive's position on the bus.
    pub slave: u16,
    /// The position targets written (0x607A or 0x60C1:01, or both), in the outputs; the first
    /// is read as the target last sent.
    pub targets: [Option<usize>; 2],
    /// Statusword 0x6041 in the inputs.
    pub statusword: usize,
    /// Position actual in the inputs, where mapped (judged by the tolerances).
    pub actual: Option<usize>,
    /// Velocity actual 0x606C in the inputs, where mapped (judged by the tolerances).
    pub velocity_actual: Option<usize>,
}

impl Joint {
    fn sent(&self, outputs: &[u8]) -> i32 {
        self.targets.into_iter().flatten().next().map_or(0, |at| i32_at(outputs, at))
    }
}

/// Where a trajectory stands, as the cycle thread last published it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TrajectoryStatus {
    /// The trajectory's id (from 1).
    pub id: u32,
    /// Pending, running or how it ended.
    pub state: TrajectoryState,
    /// The point approached (from 0); `points` once past the last.
    pub point: u32,
    /// Its points.
    pub points: u32,
    /// When it started on the monotonic clock (ns; 0 while pending).
    pub started_ns: u64,
    /// Time since its start (ns).
    pub elapsed_ns: u64,
    /// Its last point's time from the start (ns).
    pub duration_ns: u64,
}

/// A status in words.
const STATUS_WORDS: usize = 6;

impl TrajectoryStatus {
    fn pack(&self) -> [u64; STATUS_WORDS] {
        [
            self.state.pack(),
            self.id as u64,
            self.point as u64 | (self.points as u64) << 32,
            self.started_ns,
            self.elapsed_ns,
            self.duration_ns,
        ]
    }

    fn unpack(w: [u64; STATUS_WORDS]) -> Option<TrajectoryStatus> {
        Some(TrajectoryStatus {
            state: TrajectoryState::unpack(w[0])?,
            id: w[1] as u32,
            point: w[2] as u32,
            points: (w[2] >> 32) as u32,
            started_ns: w[3],
            elapsed_ns: w[4],
            duration_ns: w[5],
        })
    }
}

/// How closely one joint must follow, in counts and counts/s; infinite where not judged.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Tolerance {
    /// Largest position error while the trajectory runs.
    pub path_position: f64,
    /// Largest velocity error while it runs.
    pub path_velocity: f64,
    /// Largest position error from the last point at the end.
    pub goal_position: f64,
    /// Largest velocity at the end.
    pub goal_velocity: f64,
    /// Deceleration of a stop, counts/s² (above 0; infinite: stops at once where it is).
    pub stop_deceleration: f64,
}

/// A FollowJointTrajectory goal's tolerances: one per joint, and how long past the last point's
/// time the joints may take to come within their goal tolerance (0: judged at that time).
#[derive(Clone, Debug, PartialEq)]
pub struct Tolerances {
    /// Per joint.
    pub joints: Vec<Tolerance>,
    /// The goal time tolerance, ns.
    pub goal_time_ns: u64,
}

/// A stop under way: when it began, each joint's set-point then, and how the plan ends once
/// all are still.
#[derive(Debug)]
struct Braking {
    since_ns: u64,
    verdict: TrajectoryState,
}

/// A trajectory with its drives, as handed to the cycle thread.
#[derive(Debug)]
pub struct Plan {
    start_ns: Option<u64>,
    joints: Vec<Joint>,
    trajectory: Trajectory,
    /// Per joint: the segment from the set-point at the start to the first point.
    lead_in: Vec<Segment>,
    tolerances: Option<Tolerances>,
    /// Per joint: the set-point of the last cycle, which the actual values of this one follow.
    last: Vec<Setpoint>,
    braking: Option<Braking>,
    /// Per joint: its set-point when the stop began.
    brake_from: Vec<Setpoint>,
    status: TrajectoryStatus,
}

impl Plan {
    /// A plan of `trajectory` (one joint per entry of `joints`) with id `id`, starting at
    /// `start_ns` on the monotonic clock (`None`: as soon as the cycle takes it), judged by
    /// `tolerances` (one per joint) where given.
    pub fn judged(
        id: u32,
        start_ns: Option<u64>,
        joints: Vec<Joint>,
        trajectory: Trajectory,
        tolerances: Option<Tolerances>,
    ) -> Box<Plan> {
        let status = TrajectoryStatus {
            id,
            state: TrajectoryState::Pending,
            point: 0,
            points: trajectory.points() as u32,
            started_ns: 0,
            elapsed_ns: 0,
            duration_ns: trajectory.duration_ns(),
        };
        let n = joints.len();
        Box::new(Plan {
            start_ns,
            joints,
            trajectory,
            lead_in: vec![Segment::default(); n],
            tolerances,
            last: vec![Setpoint::default(); n],
            braking: None,
            brake_from: vec![Setpoint::default(); n],
            status,
        })
    }

    /// The status.
    pub fn status(&self) -> TrajectoryStatus {
        self.status
    }

    /// Joint `j`'s set-point at `now_ns` (started): the trajectory's, or the stop's.
    fn at(&self, j: usize, now_ns: u64) -> Setpoint {
        match &self.braking {
            None => self.trajectory.at(&self.lead_in[j], now_ns.saturating_sub(self.status.started_ns), j),
            Some(b) => {
                let deceleration = self.tolerances.as_ref().map_or(f64::INFINITY, |t| t.joints[j].stop_deceleration);
                braked(self.brake_from[j], deceleration, (now_ns.saturating_sub(b.since_ns)) as f64 * 1e-9)
            }
        }
    }

    /// Begins a stop from each joint's set-point at `now_ns`, to end as `verdict`.
    fn brake(&mut self, now_ns: u64, verdict: TrajectoryState) {
        for j in 0..self.joints.len() {
            self.brake_from[j] = self.at(j, now_ns);
        }
        self.braking = Some(Braking { since_ns: now_ns, verdict });
    }

    /// Whether every joint of a stop is still at `now_ns`.
    fn still(&self, now_ns: u64) -> bool {
        (0..self.joints.len()).all(|j| self.at(j, now_ns).velocity == 0.0)
    }

    /// The first joint whose actual values stray from `reference` by more than `bound` gives
    /// (position, velocity) allows, as a violation.
    fn strayed(
        &self,
        inputs: &[u8],
        reference: impl Fn(usize) -> Setpoint,
        bound: impl Fn(&Tolerance) -> (f64, f64),
    ) -> Option<Violation> {
        let tolerances = self.tolerances.as_ref()?;
        self.joints.iter().enumerate().find_map(|(j, joint)| {
            let (position, velocity) = bound(&tolerances.joints[j]);
            let want = reference(j);
            let errors = [
                (false, joint.actual.map(|at| want.position - i32_at(inputs, at) as f64), position),
                (true, joint.velocity_actual.map(|at| want.velocity - i32_at(inputs, at) as f64), velocity),
            ];
            errors.into_iter().find_map(|(is_velocity, error, allowed)| {
                let error = error?;
                (error.abs() > allowed).then(|| Violation {
                    slave: joint.slave,
                    velocity: is_velocity,
                    error: error.round().clamp(i32::MIN as f64, i32::MAX as f64) as i32,
                })
            })
        })
    }

    fn due(&self, now_ns: u64) -> bool {
        self.start_ns.is_none_or(|start| now_ns >= start)
    }
}

/// The set-point `s` seconds into a stop from `from` at `deceleration`: the velocity falls
/// linearly to 0, the position follows; an infinite deceleration stops where it was.
fn braked(from: Setpoint, deceleration: f64, s: f64) -> Setpoint {
    let v = from.velocity;
    let stop_s = if deceleration.is_finite() { v.abs() / deceleration } else { 0.0 };
    if s >= stop_s {
        let travelled = if stop_s > 0.0 { v * stop_s / 2.0 } else { 0.0 };
        return Setpoint { position: from.position + travelled, ..Setpoint::default() };
    }
    let a = -v.signum() * deceleration;
    Setpoint { position: from.position + v * s + a * s * s / 2.0, velocity: v + a * s, acceleration: a }
}

/// Words a drive's followed values take in [`PlayerShared::followed`]: the set-point's position and
/// velocity, the actual position and velocity, whether a trajectory drives it, and the
/// set-point's acceleration.
const FOLLOWED: usize = 6;

/// What the cycle thread and the callers share: the handoff and the published statuses.
pub struct PlayerShared {
    inbox: AtomicPtr<Plan>,
    outbox: [AtomicPtr<Plan>; OUTBOX],
    /// The running trajectory's status, then the pending one's (zeros where none).
    live: SeqBytes,
    /// The ids of the trajectories asked to stop, each in a slot of its own (0: free).
    stops: [AtomicU32; STOPS],
    /// Per drive: [`FOLLOWED`] f64s.
    followed: SeqBytes,
}

impl PlayerShared {
    /// The handoff for a bus of `slaves` slaves.
    pub fn new(slaves: usize) -> Self {
        PlayerShared {
            inbox: AtomicPtr::new(std::ptr::null_mut()),
            outbox: std::array::from_fn(|_| AtomicPtr::new(std::ptr::null_mut())),
            live: SeqBytes::new(2 * STATUS_WORDS * 8, &[]),
            stops: std::array::from_fn(|_| AtomicU32::new(0)),
            followed: SeqBytes::new(slaves * FOLLOWED * 8, &[]),
        }
    }

    /// Asks the cycle thread to bring trajectory `id` to a standstill at its joints' stop
    /// decelerations (it ends "stopped"). The request takes a slot of its own, free or held by
    /// a trajectory no longer `in_force`, so two stops asked within one cycle both count (one
    /// shared slot kept the last: a trajectory waiting an hour for its start, canceled with
    /// another, was never stopped and its goal never answered). Callers take turns
    /// ([`Caller::stop`] holds its lock).
    pub fn stop(&self, id: u32, in_force: impl Fn(u32) -> bool) {
        if self.stop_asked(id) {
            return;
        }
        let free = self.stops.iter().find(|slot| {
            let held = slot.load(Ordering::Acquire);
            held == 0 || !in_force(held)
        });
        if let Some(slot) = free {
            slot.store(id, Ordering::Release);
        }
    }

    fn stop_asked(&self, id: u32) -> bool {
        self.stops.iter().any(|slot| slot.load(Ordering::Acquire) == id)
    }

    /// Drive `slave`'s set-point (position, velocity) as the trajectory in force last had it
    /// and its actual (position, velocity) judged against it, counts and counts/s; `None`
    /// while no trajectory drives it.
    pub fn followed(&self, slave: u16) -> Option<[f64; 4]> {
        self.words(slave).map(|w| [w[0], w[1], w[2], w[3]])
    }

    /// Drive `slave`'s set-point (position, velocity, acceleration) as the trajectory in force
    /// last had it; `None` while none drives it.
    pub fn setpoint(&self, slave: u16) -> Option<Setpoint> {
        self.words(slave).map(|w| Setpoint { position: w[0], velocity: w[1], acceleration: w[5] })
    }

    /// Drive `slave`'s words as last published; `None` while no trajectory drives it.
    fn words(&self, slave: u16) -> Option<[f64; FOLLOWED]> {
        let mut bytes = vec![0u8; self.followed.len()];
        self.followed.read(&mut bytes);
        let at = slave as usize * FOLLOWED * 8;
        let words = bytes.get(at..at + FOLLOWED * 8)?;
        let words: [f64; FOLLOWED] =
            std::array::from_fn(|w| f64::from_le_bytes(words[w * 8..w * 8 + 8].try_into().expect("8 bytes")));
        (words[4] == 1.0).then_some(words)
    }

    /// Hands `plan` to the cycle thread; gives it back when the last one was not taken yet.
    pub fn give(&self, plan: Box<Plan>) -> std::result::Result<(), Box<Plan>> {
        let raw = Box::into_raw(plan);
        match self.inbox.compare_exchange(std::ptr::null_mut(), raw, Ordering::AcqRel, Ordering::Acquire) {
            Ok(_) => Ok(()),
            // SAFETY: `raw` came from Box::into_raw above and was not published.
            Err(_) => Err(unsafe { Box::from_raw(raw) }),
        }
    }

    /// Drops the plans the cycle thread is done with, passing each one's final status to
    /// `ended`.
    pub fn collect(&self, mut ended: impl FnMut(TrajectoryStatus)) {
        for slot in &self.outbox {
            let raw = slot.swap(std::ptr::null_mut(), Ordering::AcqRel);
            if !raw.is_null() {
                // SAFETY: only Player::flush stores into the outbox, a pointer from
                // Box::into_raw whose box it gave up; the swap made this thread its only owner.
                let plan = unsafe { Box::from_raw(raw) };
                ended(plan.status);
            }
        }
    }

    /// The running and the pending trajectory's statuses, as last published.
    pub fn live(&self) -> [Option<TrajectoryStatus>; 2] {
        let mut bytes = [0u8; 2 * STATUS_WORDS * 8];
        self.live.read(&mut bytes);
        let word = |n: usize| u64::from_le_bytes(bytes[n * 8..n * 8 + 8].try_into().expect("8 bytes"));
        [0, 1].map(|r| TrajectoryStatus::unpack(std::array::from_fn(|w| word(r * STATUS_WORDS + w))))
    }

    fn take(&self) -> Option<Box<Plan>> {
        let raw = self.inbox.swap(std::ptr::null_mut(), Ordering::AcqRel);
        // SAFETY: only `give` stores into the inbox, a pointer from Box::into_raw it gave up;
        // the swap made this thread its only owner.
        (!raw.is_null()).then(|| unsafe { Box::from_raw(raw) })
    }
}

impl Drop for PlayerShared {
    /// Plans still handed over or returned are dropped with the last owner, after the loop.
    fn drop(&mut self) {
        drop(self.take());
        self.collect(|_| {});
    }
}

/// The cycle thread's side: the trajectory in force, the one waiting for its start, and per
/// drive the target a trajectory gave it that the set-point buffer does not carry yet.
pub struct Player {
    current: Option<Box<Plan>>,
    pending: Option<Box<Plan>>,
    /// Plans retired while the outbox was full.
    waiting: [Option<Box<Plan>>; WAITING],
    /// Per slave: the target to write and where, until the set-point buffer has it.
    owned: Vec<Option<(i32, [Option<usize>; 2])>>,
    /// Per slave: whether a target was written into the outputs this cycle.
    wrote: Vec<bool>,
    /// Per joint of the pending plan: the target its drive was last sent.
    sent: Vec<i32>,
    /// Per slave: what [`PlayerShared::followed`] gives.
    followed: Vec<[f64; FOLLOWED]>,
}

impl Player {
    /// A player for a bus of `slaves` slaves; allocates here, never in the loop.
    pub fn new(slaves: usize) -> Self {
        Player {
            current: None,
            pending: None,
            waiting: std::array::from_fn(|_| None),
            owned: vec![None; slaves],
            wrote: vec![false; slaves],
            sent: vec![0; slaves],
            followed: vec![[0.0; FOLLOWED]; slaves],
        }
    }

    /// Whether a target for drive `slave` was written into this cycle's outputs.
    pub fn wrote(&self, slave: u16) -> bool {
        self.wrote.get(slave as usize).copied().unwrap_or(false)
    }

    /// Before the set-points are copied into the outputs, which still hold what the last cycle
    /// sent: returns retired plans, takes one handed over (the one waiting for its start is
    /// replaced) and, for a plan due to start, notes the targets its drives were last sent.
    pub fn before_copy(&mut self, shared: &PlayerShared, events: &Events, outputs: &[u8], now: (u64, u64)) {
        self.flush(shared);
        if self.waiting.iter().all(Option::is_none) {
            if let Some(plan) = shared.take() {
                if let Some(old) = self.pending.take() {
                    self.end(shared, events, old, TrajectoryState::Replaced { by: plan.status.id }, now);
                }
                self.pending = Some(plan);
            }
        }
        // A stop of a trajectory still waiting for its start ends it at once: nothing moved.
        if let Some(plan) = self.pending.take_if(|p| shared.stop_asked(p.status.id)) {
            self.end(shared, events, plan, TrajectoryState::Stopped, now);
        }
        if let Some(plan) = self.pending.as_ref().filter(|p| p.due(now.1)) {
            for (sent, joint) in self.sent.iter_mut().zip(&plan.joints) {
                *sent = joint.sent(outputs);
            }
        }
    }

    /// After the copy, before the sequencer: starts a plan that is due and follows the one in
    /// force from the drives' `inputs`, or aborts it; [`wrote`](Self::wrote) then tells which
    /// drives get a target from it in this cycle.
    pub fn observe(&mut self, shared: &PlayerShared, events: &Events, inputs: &[u8], now: (u64, u64)) {
        // A trajectory waiting for its start whose drive leaves Operation enabled could not
        // start: it ends aborted now, not when it was due.
        if let Some((slave, statusword)) = self.pending.as_ref().and_then(|p| left_operation(&p.joints, inputs)) {
            if let Some(plan) = self.pending.take() {
                self.end(shared, events, plan, TrajectoryState::Aborted { slave, statusword }, now);
            }
        }
        if self.pending.as_ref().is_some_and(|p| p.due(now.1)) {
            self.start(shared, events, now);
        }
        if let Some(plan) = self.current.take() {
            self.follow(shared, events, plan, inputs, now);
        }
        for (wrote, owned) in self.wrote.iter_mut().zip(&self.owned) {
            *wrote = owned.is_some();
        }
    }

    /// Writes the targets into `outputs` and, where it can without waiting, into `setpoints`
    /// (so they stay once no trajectory writes them); publishes the statuses.
    pub fn apply(&mut self, shared: &PlayerShared, setpoints: &SeqBytes, outputs: &mut [u8]) {
        for (value, targets) in self.owned.iter().flatten() {
            for at in targets.iter().flatten() {
                outputs[*at..*at + 4].copy_from_slice(&value.to_le_bytes());
            }
        }
        if self.owned.iter().any(Option::is_some) {
            if let Some(mut w) = setpoints.try_write() {
                for (value, targets) in self.owned.iter().flatten() {
                    for at in targets.iter().flatten() {
                        w.write(*at, &value.to_le_bytes());
                    }
                }
                drop(w);
                // The buffer carries them now; the running trajectory writes its own again.
                self.owned.fill(None);
            }
        }
        // The only writer of `followed` and `live`: this never waits.
        let mut followed = shared.followed.write();
        for (slave, words) in self.followed.iter().enumerate() {
            for (w, word) in words.iter().enumerate() {
                followed.write((slave * FOLLOWED + w) * 8, &word.to_le_bytes());
            }
        }
        drop(followed);
        let mut live = shared.live.write();
        for (r, plan) in [&self.current, &self.pending].into_iter().enumerate() {
            let words = plan.as_ref().map_or([0; STATUS_WORDS], |p| p.status.pack());
            for (w, word) in words.iter().enumerate() {
                live.write((r * STATUS_WORDS + w) * 8, &word.to_le_bytes());
            }
        }
    }

    /// The pending plan takes over from each drive's set-point, unless that would take a drive
    /// past its limits or leave one of the trajectory in force moving: then it is refused and
    /// the one in force goes on.
    fn start(&mut self, shared: &PlayerShared, events: &Events, now: (u64, u64)) {
        let Some(mut plan) = self.pending.take() else { return };
        for j in 0..plan.joints.len() {
            let slave = plan.joints[j].slave;
            let running = self.current.as_ref().and_then(|c| {
                let i = c.joints.iter().position(|joint| joint.slave == slave)?;
                Some(c.at(i, now.1))
            });
            let from = running.unwrap_or(Setpoint { position: self.sent[j] as f64, ..Setpoint::default() });
            if let Some(breach) = plan.trajectory.lead_in_breach(j, from) {
                let refusal = Refusal::of(slave, breach);
                return self.end(shared, events, plan, TrajectoryState::Refused(refusal), now);
            }
            plan.lead_in[j] = plan.trajectory.lead_in(j, from);
            plan.last[j] = from;
        }
        if let Some(current) = &self.current {
            let left = current.joints.iter().enumerate().find_map(|(i, joint)| {
                let velocity = current.at(i, now.1).velocity;
                (velocity != 0.0 && !plan.joints.iter().any(|j| j.slave == joint.slave))
                    .then_some((joint.slave, velocity))
            });
            if let Some((slave, velocity)) = left {
                let refusal = Refusal { slave, why: RefusalReason::LeftMoving, value: velocity as f32 };
                return self.end(shared, events, plan, TrajectoryState::Refused(refusal), now);
            }
        }
        plan.status.started_ns = now.1;
        plan.status.state = TrajectoryState::Running;
        if let Some(old) = self.current.take() {
            self.end(shared, events, old, TrajectoryState::Replaced { by: plan.status.id }, now);
        }
        events.push(Event::Trajectory { cycle: now.0, time_ns: now.1, id: plan.status.id, state: plan.status.state });
        self.current = Some(plan);
    }

    fn follow(&mut self, shared: &PlayerShared, events: &Events, mut plan: Box<Plan>, inputs: &[u8], now: (u64, u64)) {
        if let Some((slave, statusword)) = left_operation(&plan.joints, inputs) {
            // The sequencer holds that drive where it is.
            self.owned[slave as usize] = None;
            return self.end(shared, events, plan, TrajectoryState::Aborted { slave, statusword }, now);
        }
        let elapsed_ns = now.1.saturating_sub(plan.status.started_ns);
        if plan.braking.is_none() {
            if shared.stop_asked(plan.status.id) {
                plan.brake(now.1, TrajectoryState::Stopped);
            } else if elapsed_ns < plan.status.duration_ns {
                let path = |t: &Tolerance| (t.path_position, t.path_velocity);
                if let Some(violation) = plan.strayed(inputs, |j| plan.last[j], path) {
                    plan.brake(now.1, TrajectoryState::PathToleranceViolated(violation));
                }
            }
        }
        for j in 0..plan.joints.len() {
            let joint = plan.joints[j];
            let setpoint = plan.at(j, now.1);
            let position = setpoint.position.round().clamp(i32::MIN as f64, i32::MAX as f64) as i32;
            self.owned[joint.slave as usize] = Some((position, joint.targets));
            let actual = |at: Option<usize>| at.map_or(f64::NAN, |at| i32_at(inputs, at) as f64);
            let last = plan.last[j];
            self.followed[joint.slave as usize] = [
                last.position,
                last.velocity,
                actual(joint.actual),
                actual(joint.velocity_actual),
                1.0,
                last.acceleration,
            ];
            plan.last[j] = setpoint;
        }
        plan.status.elapsed_ns = elapsed_ns;
        plan.status.point = plan.trajectory.segment(elapsed_ns) as u32;
        if let Some(braking) = &plan.braking {
            if plan.still(now.1) {
                let verdict = braking.verdict;
                return self.end(shared, events, plan, verdict, now);
            }
        } else if elapsed_ns >= plan.status.duration_ns {
            let goal = |t: &Tolerance| (t.goal_position, t.goal_velocity);
            let late_ns = elapsed_ns - plan.status.duration_ns;
            let verdict = match (plan.strayed(inputs, |j| plan.at(j, now.1), goal), &plan.tolerances) {
                (None, _) => Some(TrajectoryState::Done),
                (Some(v), Some(t)) if late_ns >= t.goal_time_ns => Some(TrajectoryState::GoalToleranceViolated(v)),
                (Some(_), _) => None,
            };
            if let Some(verdict) = verdict {
                return self.end(shared, events, plan, verdict, now);
            }
        }
        self.current = Some(plan);
    }

    fn end(
        &mut self,
        shared: &PlayerShared,
        events: &Events,
        mut plan: Box<Plan>,
        state: TrajectoryState,
        now: (u64, u64),
    ) {
        plan.status.state = state;
        for joint in &plan.joints {
            self.followed[joint.slave as usize] = [0.0; FOLLOWED];
        }
        events.push(Event::Trajectory { cycle: now.0, time_ns: now.1, id: plan.status.id, state });
        match self.waiting.iter_mut().find(|w| w.is_none()) {
            Some(slot) => *slot = Some(plan),
            // Cannot happen: a plan is taken only when none waits, and at most three are
            // retired before the next take. Were it to, leaking beats freeing in the loop.
            None => std::mem::forget(plan),
        }
        self.flush(shared);
    }

    /// Moves retired plans into free return slots.
    fn flush(&mut self, shared: &PlayerShared) {
        for waiting in self.waiting.iter_mut().filter(|w| w.is_some()) {
            let Some(slot) = shared.outbox.iter().find(|s| s.load(Ordering::Acquire).is_null()) else { return };
            let Some(plan) = waiting.take() else { continue };
            // Only this thread fills return slots, so the one found empty stays empty.
            slot.store(Box::into_raw(plan), Ordering::Release);
        }
    }
}

/// The callers' side: trajectory ids, the statuses of the last [`KEPT`] trajectories, and the
/// drives of those in force.
#[derive(Default)]
pub struct Caller {
    last_id: AtomicU32,
    /// The cycle thread never takes this lock.
    known: Mutex<Known>,
}

#[derive(Default)]
struct Known {
    /// Oldest first.
    statuses: VecDeque<TrajectoryStatus>,
    /// The trajectories handed over and not known to have ended, each with its drives.
    in_force: Vec<(u32, Vec<u16>)>,
}

impl Known {
    /// Notes a trajectory handed over (pending) or ended; an end noted first (by another
    /// caller's collect) stays.
    fn note(&mut self, status: TrajectoryStatus) {
        if status.state.ended() {
            self.in_force.retain(|(id, _)| *id != status.id);
        }
        match self.statuses.iter_mut().find(|s| s.id == status.id) {
            Some(s) if s.state.ended() && !status.state.ended() => {}
            Some(s) => *s = status,
            None => {
                if self.statuses.len() == KEPT {
                    self.statuses.pop_front();
                }
                self.statuses.push_back(status);
            }
        }
    }
}

impl Caller {
    /// The next trajectory id.
    pub fn next_id(&self) -> u32 {
        self.last_id.fetch_add(1, Ordering::Relaxed) + 1
    }

    fn known(&self) -> std::sync::MutexGuard<'_, Known> {
        self.known.lock().unwrap_or_else(|poisoned| poisoned.into_inner())
    }

    /// Notes trajectory `status` (pending) handed over with its drives `slaves`; in force until
    /// its end is noted (unless that came first).
    pub fn handed(&self, status: TrajectoryStatus, slaves: Vec<u16>) {
        let mut known = self.known();
        let ended = known.statuses.iter().any(|s| s.id == status.id && s.state.ended());
        if !ended {
            known.in_force.push((status.id, slaves));
        }
        known.note(status);
    }

    /// The trajectory handed over, not known to have ended, that drives drive `slave`.
    pub fn driving(&self, shared: &PlayerShared, slave: u16) -> Option<u32> {
        shared.collect(|status| self.note(status));
        self.known().in_force.iter().find(|(_, slaves)| slaves.contains(&slave)).map(|(id, _)| *id)
    }

    /// Asks the cycle thread to stop trajectory `id` ([`PlayerShared::stop`]); nothing for a
    /// trajectory that is not in force.
    pub fn stop(&self, shared: &PlayerShared, id: u32) {
        shared.collect(|status| self.note(status));
        let known = self.known();
        let in_force = |held: u32| known.in_force.iter().any(|(i, _)| *i == held);
        if in_force(id) {
            shared.stop(id, in_force);
        }
    }

    /// Notes a trajectory handed over (pending) or ended; an end noted first (by another
    /// caller's collect) stays.
    pub fn note(&self, status: TrajectoryStatus) {
        self.known().note(status);
    }

    /// Trajectory `id` as the cycle thread last published it.
    pub fn status(&self, shared: &PlayerShared, id: u32) -> Result<TrajectoryStatus> {
        // Live first: a plan that ends meanwhile is in the outbox when collected after.
        let live = shared.live().into_iter().flatten().find(|s| s.id == id);
        shared.collect(|status| self.note(status));
        let known = self.known();
        let kept = known.statuses.iter().find(|s| s.id == id).copied();
        match (kept, live) {
            (Some(kept), _) if kept.state.ended() => Ok(kept),
            (_, Some(live)) => Ok(live),
            (Some(kept), None) => Ok(kept),
            (None, None) => {
                let statuses = &known.statuses;
                let ids = statuses.front().map(|f| (f.id, statuses.back().map_or(f.id, |b| b.id)));
                Err(Error::from(Unavailable::NoSuchTrajectory { id, kept: ids }))
            }
        }
    }
}

/// The first drive of `joints` that is not in Operation enabled in `inputs`, with its
/// statusword.
fn left_operation(joints: &[Joint], inputs: &[u8]) -> Option<(u16, u16)> {
    joints.iter().find_map(|joint| {
        let statusword = u16_at(inputs, joint.statusword);
        (State::from_statusword(statusword) != Some(State::OperationEnabled)).then_some((joint.slave, statusword))
    })
}

impl Refusal {
    /// The refusal of drive `slave` for `breach` of its segment to the first point.
    fn of(slave: u16, breach: Breach) -> Refusal {
        let (why, value) = match breach {
            Breach::Past(excess) => {
                let why = match excess.limit {
                    Limit::Position => RefusalReason::Position,
                    Limit::Velocity => RefusalReason::Velocity,
                    Limit::Acceleration => RefusalReason::Acceleration,
                };
                (why, excess.value)
            }
            Breach::Step { from, to, .. } => (RefusalReason::VelocityStep, to - from),
        };
        Refusal { slave, why, value: value as f32 }
    }
}

/// `why` as the refusal of joint `joint` on drive `slave`.
pub fn not_ready(joint: usize, slave: u16, why: impl Into<String>) -> Error {
    TrajectoryError::DriveNotReady { joint, slave, why: why.into() }.into()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::drive::trajectory::{Knot, Limits};

    const MS: u64 = 1_000_000;

    /// One drive: its target at output 0, its statusword at input 0.
    const JOINT: Joint =
        Joint { slave: 0, targets: [Some(0), None], statusword: 0, actual: None, velocity_actual: None };

    /// A player of one drive whose target last sent is `target`.
    fn rig(target: i32) -> (PlayerShared, Events, Player, [u8; 4]) {
        (PlayerShared::new(1), Events::default(), Player::new(1), target.to_le_bytes())
    }

    fn plan(id: u32, start_ns: Option<u64>, to: f64, after_ns: u64) -> Box<Plan> {
        let trajectory = Trajectory::new(1, &[after_ns], &[vec![Knot::position(to)]], None).unwrap();
        Plan::judged(id, start_ns, vec![JOINT], trajectory, None)
    }

    /// A cycle at `now` ms whose drive is in `state` at `actual` (input 2, after the statusword):
    /// the player's steps around the copy, returning the target sent.
    fn cycle(
        player: &mut Player,
        shared: &PlayerShared,
        events: &Events,
        image: &mut [u8; 4],
        now: u64,
        (state, actual): (State, i32),
    ) -> i32 {
        let mut inputs = [0u8; 6];
        inputs[..2].copy_from_slice(&state.statusword_bits().to_le_bytes());
        inputs[2..].copy_from_slice(&actual.to_le_bytes());
        let setpoints = SeqBytes::new(4, image);
        let at = (now, now * MS);
        player.before_copy(shared, events, image, at);
        player.observe(shared, events, &inputs, at);
        player.apply(shared, &setpoints, image);
        let mut kept = [0; 4];
        setpoints.read(&mut kept);
        assert_eq!(&kept, image, "the set-point buffer keeps what went out");
        i32::from_le_bytes(*image)
    }

    /// The drive enabled at `actual`.
    fn at(actual: i32) -> (State, i32) {
        (State::OperationEnabled, actual)
    }

    const ENABLED: (State, i32) = (State::OperationEnabled, 0);
    const FAULT: (State, i32) = (State::Fault, 0);

    fn trajectory_events(events: &Events) -> Vec<(u32, TrajectoryState)> {
        events
            .drain()
            .into_iter()
            .filter_map(|e| match e {
                Event::Trajectory { id, state, .. } => Some((id, state)),
                _ => None,
            })
            .collect()
    }

    #[test]
    fn a_plan_starts_from_the_target_sent_ends_on_its_point_and_comes_back() {
        let (shared, events, mut player, mut image) = rig(1000);
        shared.give(plan(1, Some(3 * MS), 2000.0, 10 * MS)).unwrap();
        // A second one cannot be handed before the first is taken.
        assert!(shared.give(plan(2, None, 0.0, MS)).is_err());
        assert_eq!(cycle(&mut player, &shared, &events, &mut image, 1, ENABLED), 1000);
        assert_eq!(shared.live()[1].map(|s| s.state), Some(TrajectoryState::Pending));
        let sent: Vec<i32> = (3..=14).map(|ms| cycle(&mut player, &shared, &events, &mut image, ms, ENABLED)).collect();
        // From where it was, at rest, 100 counts per ms, then held.
        assert_eq!(sent, [1000, 1100, 1200, 1300, 1400, 1500, 1600, 1700, 1800, 1900, 2000, 2000]);
        assert_eq!(trajectory_events(&events), [(1, TrajectoryState::Running), (1, TrajectoryState::Done)]);
        let mut ended = Vec::new();
        shared.collect(|s| ended.push((s.id, s.state, s.point, s.elapsed_ns)));
        assert_eq!(ended, [(1, TrajectoryState::Done, 1, 10 * MS)]);
        assert_eq!(shared.live(), [None, None]);
    }

    /// A judged plan of one joint whose actual position is at input 2 (after the statusword).
    fn judged(id: u32, to: f64, after_ns: u64, tolerance: Tolerance, goal_time_ns: u64) -> Box<Plan> {
        let trajectory = Trajectory::new(1, &[after_ns], &[vec![Knot::position(to)]], None).unwrap();
        let joint = Joint { actual: Some(2), ..JOINT };
        Plan::judged(id, None, vec![joint], trajectory, Some(Tolerances { joints: vec![tolerance], goal_time_ns }))
    }

    const LOOSE: Tolerance = Tolerance {
        path_position: f64::INFINITY,
        path_velocity: f64::INFINITY,
        goal_position: f64::INFINITY,
        goal_velocity: f64::INFINITY,
        stop_deceleration: f64::INFINITY,
    };

    #[test]
    fn a_drive_past_the_path_tolerance_brakes_the_plan_to_a_standstill_and_names_it() {
        let (shared, events, mut player, mut image) = rig(0);
        // 100 counts/ms, braking at 1e7 counts/s² (10 counts/ms per ms); the drive stays at 0.
        let tolerance = Tolerance { path_position: 250.0, stop_deceleration: 1e7, ..LOOSE };
        shared.give(judged(1, 1000.0, 10 * MS, tolerance, 0)).unwrap();
        let sent: Vec<i32> = (1..=16).map(|ms| cycle(&mut player, &shared, &events, &mut image, ms, at(0))).collect();
        // At 4 ms the set-point of 3 ms (200) is within; at 5 ms that of 4 ms (300) is not: it
        // brakes from 400 at 100 counts/ms over 10 ms, 500 counts more, never a step.
        assert_eq!(sent[..7], [0, 100, 200, 300, 400, 495, 580]);
        assert!(sent.windows(2).all(|w| w[1] - w[0] <= 100 && w[1] >= w[0]), "{sent:?}");
        assert_eq!(*sent.last().unwrap(), 900);
        let violation = Violation { slave: 0, velocity: false, error: 300 };
        assert_eq!(
            trajectory_events(&events),
            [(1, TrajectoryState::Running), (1, TrajectoryState::PathToleranceViolated(violation))]
        );
        assert_eq!(shared.followed(0), None, "ended: no trajectory drives it");
    }

    #[test]
    fn a_stop_brakes_and_the_goal_tolerance_waits_for_the_goal_time() {
        let (shared, events, mut player, mut image) = rig(0);
        shared.give(judged(1, 1000.0, 10 * MS, Tolerance { stop_deceleration: 1e7, ..LOOSE }, 0)).unwrap();
        for ms in 1..=3 {
            cycle(&mut player, &shared, &events, &mut image, ms, at(0));
        }
        // The set-point of 2 ms, which the drive had a cycle to follow; no velocity mapped.
        let [position, velocity, actual, actual_velocity] = shared.followed(0).unwrap();
        assert_eq!([position, velocity.round(), actual], [100.0, 100_000.0, 0.0]);
        assert!(actual_velocity.is_nan());
        shared.stop(1, |_| false);
        let sent: Vec<i32> = (4..=20).map(|ms| cycle(&mut player, &shared, &events, &mut image, ms, at(0))).collect();
        assert_eq!(sent[..3], [300, 395, 480], "from 300 at 100 counts/ms, braking");
        assert_eq!(*sent.last().unwrap(), 800);
        assert_eq!(trajectory_events(&events), [(1, TrajectoryState::Running), (1, TrajectoryState::Stopped)]);
        // A goal 50 counts short of 1000 with a tolerance of 10: done once the drive is there,
        // violated once the goal time (5 ms) is out.
        let goal = Tolerance { goal_position: 10.0, ..LOOSE };
        for (id, arrives) in [(2, true), (3, false)] {
            shared.give(judged(id, 1000.0, 2 * MS, goal, 5 * MS)).unwrap();
            let base = 100 * id as u64;
            for ms in 0..9 {
                let actual = if arrives && ms >= 5 { 995 } else { 950 };
                cycle(&mut player, &shared, &events, &mut image, base + ms, at(actual));
            }
        }
        let ended: Vec<_> = trajectory_events(&events).into_iter().filter(|e| e.1.ended()).collect();
        let violation = Violation { slave: 0, velocity: false, error: 50 };
        assert_eq!(ended, [(2, TrajectoryState::Done), (3, TrajectoryState::GoalToleranceViolated(violation))]);
    }

    #[test]
    fn two_stops_asked_within_one_cycle_both_count() {
        let (shared, events, mut player, mut image) = rig(1000);
        let caller = Caller::default();
        for (id, start) in [(1, None), (2, Some(3_600_000 * MS))] {
            let plan = plan(id, start, 2000.0, 10 * MS);
            caller.handed(plan.status(), vec![0]);
            shared.give(plan).unwrap();
            cycle(&mut player, &shared, &events, &mut image, id as u64, ENABLED);
        }
        // The one waiting an hour for its start first, then the running one, before the cycle looks.
        caller.stop(&shared, 2);
        caller.stop(&shared, 1);
        for ms in 3..=5 {
            cycle(&mut player, &shared, &events, &mut image, ms, ENABLED);
        }
        let ended: Vec<_> = trajectory_events(&events).into_iter().filter(|e| e.1.ended()).collect();
        assert_eq!(ended, [(2, TrajectoryState::Stopped), (1, TrajectoryState::Stopped)]);
    }

    #[test]
    fn a_plan_waiting_for_its_start_ends_at_once_on_a_stop_or_when_its_drive_leaves_operation() {
        let (shared, events, mut player, mut image) = rig(1000);
        // Due in an hour: stopped, it ends now, and nothing was written.
        shared.give(plan(1, Some(3_600_000 * MS), 2000.0, 10 * MS)).unwrap();
        cycle(&mut player, &shared, &events, &mut image, 1, ENABLED);
        shared.stop(1, |_| false);
        assert_eq!(cycle(&mut player, &shared, &events, &mut image, 2, ENABLED), 1000);
        assert_eq!(trajectory_events(&events), [(1, TrajectoryState::Stopped)]);
        // Due in an hour, its drive disabled: aborted now.
        shared.give(plan(2, Some(3_600_000 * MS), 2000.0, 10 * MS)).unwrap();
        cycle(&mut player, &shared, &events, &mut image, 3, ENABLED);
        assert_eq!(cycle(&mut player, &shared, &events, &mut image, 4, FAULT), 1000);
        let aborted = TrajectoryState::Aborted { slave: 0, statusword: State::Fault.statusword_bits() };
        assert_eq!(trajectory_events(&events), [(2, aborted)]);
        assert_eq!(shared.live(), [None, None]);
    }

    #[test]
    fn a_plan_whose_start_would_go_past_a_limit_is_refused_and_the_one_in_force_goes_on() {
        let (shared, events, mut player, mut image) = rig(0);
        shared.give(plan(1, None, 1000.0, 10 * MS)).unwrap();
        cycle(&mut player, &shared, &events, &mut image, 1, ENABLED);
        // 100 counts/ms allowed: from 100, where plan 1 is at 2 ms, to 5000 in 10 ms is 490.
        let limits = Limits { max_velocity: 100_000.0, ..Limits::TARGET };
        let trajectory = Trajectory::new(1, &[10 * MS], &[vec![Knot::position(5000.0)]], Some(&[limits])).unwrap();
        shared.give(Plan::judged(2, None, vec![JOINT], trajectory, None)).unwrap();
        let sent: Vec<i32> = (2..=12).map(|ms| cycle(&mut player, &shared, &events, &mut image, ms, ENABLED)).collect();
        assert_eq!(sent, [100, 200, 300, 400, 500, 600, 700, 800, 900, 1000, 1000], "plan 1 went on");
        let refusal = Refusal { slave: 0, why: RefusalReason::Velocity, value: 490_000.0 };
        assert_eq!(
            trajectory_events(&events),
            [(1, TrajectoryState::Running), (2, TrajectoryState::Refused(refusal)), (1, TrajectoryState::Done)]
        );
    }

    #[test]
    fn a_newer_plan_replaces_the_pending_one_then_the_running_one_and_a_drive_out_of_operation_aborts() {
        let (shared, events, mut player, mut image) = rig(0);
        shared.give(plan(1, None, 1000.0, 10 * MS)).unwrap();
        cycle(&mut player, &shared, &events, &mut image, 1, ENABLED);
        shared.give(plan(2, Some(100 * MS), 0.0, MS)).unwrap();
        cycle(&mut player, &shared, &events, &mut image, 2, ENABLED);
        shared.give(plan(3, Some(5 * MS), -1000.0, 10 * MS)).unwrap();
        let sent: Vec<i32> = (3..=6).map(|ms| cycle(&mut player, &shared, &events, &mut image, ms, ENABLED)).collect();
        // Plan 1 at 100 counts/ms until plan 3 takes over at 5 ms from 400, toward -1000 in 10 ms.
        assert_eq!(sent, [200, 300, 400, 260]);
        assert_eq!(cycle(&mut player, &shared, &events, &mut image, 7, FAULT), 260, "aborted: nothing written");
        assert_eq!(
            trajectory_events(&events),
            [
                (1, TrajectoryState::Running),
                (2, TrajectoryState::Replaced { by: 3 }),
                (1, TrajectoryState::Replaced { by: 3 }),
                (3, TrajectoryState::Running),
                (3, TrajectoryState::Aborted { slave: 0, statusword: State::Fault.statusword_bits() }),
            ]
        );
        let caller = Caller::default();
        let mut returned = 0;
        shared.collect(|s| {
            returned += 1;
            caller.note(s)
        });
        assert_eq!(returned, 3);
        // A pending note that comes late does not hide the end.
        caller.note(plan(3, None, 0.0, MS).status());
        assert!(matches!(caller.status(&shared, 3).unwrap().state, TrajectoryState::Aborted { .. }));
        assert_eq!(caller.status(&shared, 2).unwrap().state, TrajectoryState::Replaced { by: 3 });
        let e = caller.status(&shared, 9).unwrap_err().to_string();
        assert!(e.contains("no trajectory 9: the statuses of trajectories 2 ..= 3 are kept"), "{e}");
    }
}
