//! Joint trajectories for Python: `Cycle.play_trajectory`, `Cycle.trajectory_status` and the
//! "trajectory" events, converted here; the validation, the handoff and the interpolation are
//! the crate's ([`crate::drive::trajectory`], [`crate::cycle::trajectory_player`]).

use pyo3::prelude::*;

use super::{ConfigError, IntoPyResult, Merged};
use crate::cycle::events::TrajectoryState;
use crate::cycle::trajectory_player::{Tolerance, Tolerances, TrajectoryStatus};
use crate::cycle::CycleThread;
use crate::drive::ds402::State;
use crate::drive::trajectory::{JointLimits, Knot, Limits, Scale};
use crate::error::Error;

/// One joint at one point as Python gives it: a position, or (position, velocity or None,
/// acceleration or None).
#[derive(FromPyObject)]
pub(super) enum PyKnot {
    /// (position, velocity, acceleration).
    Full((f64, Option<f64>, Option<f64>)),
    /// A position alone.
    Position(f64),
}

impl From<&PyKnot> for Knot {
    fn from(k: &PyKnot) -> Knot {
        match *k {
            PyKnot::Full((position, velocity, acceleration)) => Knot { position, velocity, acceleration },
            PyKnot::Position(position) => Knot::position(position),
        }
    }
}

/// One joint's tolerances as Python gives them: (path position, path velocity, goal position,
/// goal velocity, stop deceleration).
pub(super) type PyTolerance = (f64, f64, f64, f64, f64);

/// The tolerances of `joints` with `goal_time_ns`.
pub(super) fn tolerances(joints: Vec<PyTolerance>, goal_time_ns: u64) -> Tolerances {
    let joints = joints
        .into_iter()
        .map(|(path_position, path_velocity, goal_position, goal_velocity, stop_deceleration)| Tolerance {
            path_position,
            path_velocity,
            goal_position,
            goal_velocity,
            stop_deceleration,
        })
        .collect();
    Tolerances { joints, goal_time_ns }
}

/// A trajectory as `Cycle.play_trajectory` takes it (see there).
pub(super) struct Played {
    pub positions: Vec<u16>,
    pub times_ns: Vec<u64>,
    pub points: Vec<Vec<PyKnot>>,
    pub start_ns: Option<u64>,
    pub tolerances: Option<Tolerances>,
}

/// Validates and hands over `played`, the GIL released while the cycle thread takes it; a
/// refusal names each joint as `names` does where given (else by the name its limits were
/// handed down with) and gives its values in the joint's units.
pub(super) fn play(py: Python<'_>, cycle: &CycleThread, played: Played, names: Option<&[String]>) -> PyResult<u32> {
    let Played { positions, times_ns, points, start_ns, tolerances } = played;
    let points: Vec<Vec<Knot>> = points.iter().map(|p| p.iter().map(Knot::from).collect()).collect();
    let played = py.allow_threads(|| cycle.follow_trajectory(&positions, &times_ns, &points, start_ns, tolerances));
    match played {
        Err(Error::Trajectory(e)) => {
            let joints: Vec<_> = positions.iter().map(|&p| cycle.limits_of(p)).collect();
            let named: Vec<String> = match names {
                Some(names) => names.to_vec(),
                None => {
                    joints.iter().enumerate().map(|(j, (_, _, n))| n.clone().unwrap_or(format!("joint {j}"))).collect()
                }
            };
            let scales: Vec<Scale> = joints.iter().map(|(_, scale, _)| *scale).collect();
            let text = e.naming(&named, &scales).to_string();
            Err(ConfigError::new_err(text))
        }
        played => played.py(),
    }
}

/// The joint on drive `position` with its name, limits (counts; None where open) and units, as
/// `Cycle.set_joint_limits` takes them.
pub(super) fn joint_limits(
    name: String,
    (min, max): (Option<f64>, Option<f64>),
    max_velocity: Option<f64>,
    max_acceleration: Option<f64>,
    scale: Scale,
) -> JointLimits {
    let open = Limits::TARGET;
    let limits = Limits {
        min: min.unwrap_or(open.min),
        max: max.unwrap_or(open.max),
        max_velocity: max_velocity.unwrap_or(open.max_velocity),
        max_acceleration: max_acceleration.unwrap_or(open.max_acceleration),
    };
    JointLimits { name, limits, scale }
}

/// How a trajectory stands, as Python sees it in its status and its events: "state",
/// "replaced_by" (the newer id), and for an abort the drive, its statusword and its CiA 402
/// state. A tolerance violation adds "velocity" (whether the velocity strayed, else the
/// position) and "error" (counts or counts/s), "slave" naming the drive; a refusal at the
/// take-over "slave" and "reason" (why, in the joint's words).
#[derive(IntoPyObject)]
pub(super) struct StateView {
    state: &'static str,
    replaced_by: Option<u32>,
    slave: Option<u16>,
    statusword: Option<u16>,
    ds402_state: Option<State>,
    velocity: Option<bool>,
    error: Option<i32>,
    reason: Option<String>,
}

/// `state` as Python sees it, a refusal worded by `cycle`.
pub(super) fn state_view(state: TrajectoryState, cycle: &CycleThread) -> StateView {
    let (replaced_by, aborted) = match state {
        TrajectoryState::Replaced { by } => (Some(by), None),
        TrajectoryState::Aborted { slave, statusword } => (None, Some((slave, statusword))),
        _ => (None, None),
    };
    let violation = match state {
        TrajectoryState::PathToleranceViolated(v) | TrajectoryState::GoalToleranceViolated(v) => Some(v),
        _ => None,
    };
    let refusal = match state {
        TrajectoryState::Refused(r) => Some(r),
        _ => None,
    };
    StateView {
        state: state.name(),
        replaced_by,
        slave: aborted.map(|a| a.0).or(violation.map(|v| v.slave)).or(refusal.map(|r| r.slave)),
        statusword: aborted.map(|a| a.1),
        ds402_state: aborted.and_then(|a| State::from_statusword(a.1)),
        velocity: violation.map(|v| v.velocity),
        error: violation.map(|v| v.error),
        reason: refusal.map(|r| cycle.refusal_text(&r)),
    }
}

/// A trajectory's progress: its id, the point approached, when it started.
#[derive(IntoPyObject)]
pub(super) struct ProgressView {
    id: u32,
    point: u32,
    points: u32,
    started_ns: Option<u64>,
    elapsed_ns: u64,
    duration_ns: u64,
}

/// `Cycle.trajectory_status`: its progress and its state.
pub(super) type StatusView = Merged<ProgressView, StateView>;

pub(super) fn status_view(s: TrajectoryStatus, cycle: &CycleThread) -> StatusView {
    let progress = ProgressView {
        id: s.id,
        point: s.point,
        points: s.points,
        started_ns: (s.started_ns != 0).then_some(s.started_ns),
        elapsed_ns: s.elapsed_ns,
        duration_ns: s.duration_ns,
    };
    Merged(progress, state_view(s.state, cycle))
}
