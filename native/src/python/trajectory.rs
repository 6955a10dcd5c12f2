//! Joint trajectories for Python: `Cycle.play_trajectory`, `Cycle.trajectory_status` and the
//! "trajectory" events, converted here; the validation, the handoff and the interpolation are
//! the crate's ([`crate::drive::trajectory`], [`crate::cycle::trajectory_player`]).

use pyo3::prelude::*;

use super::{ConfigError, IntoPyResult, Merged};
use crate::cycle::events::TrajectoryState;
use crate::cycle::trajectory_player::{Tolerance, Tolerances, TrajectoryStatus};
use crate::cycle::CycleThread;
use crate::drive::ds402::State;
use crate::drive::trajectory::{Knot, Limits};
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

/// Validates and hands over a trajectory, the GIL released while the cycle thread takes it.
#[allow(clippy::too_many_arguments)]
/// A trajectory as `Cycle.play_trajectory` takes it (see there).
pub(super) struct Played {
    pub positions: Vec<u16>,
    pub times_ns: Vec<u64>,
    pub points: Vec<Vec<PyKnot>>,
    pub start_ns: Option<u64>,
    pub limits: Option<Vec<(f64, f64)>>,
    pub tolerances: Option<Tolerances>,
}

/// Plays `played`; a refusal names the joints as `names` does, where given.
pub(super) fn play(py: Python<'_>, cycle: &CycleThread, played: Played, names: Option<&[String]>) -> PyResult<u32> {
    let Played { positions, times_ns, points, start_ns, limits, tolerances } = played;
    let points: Vec<Vec<Knot>> = points.iter().map(|p| p.iter().map(Knot::from).collect()).collect();
    let limits: Option<Vec<Limits>> = limits.map(|l| l.into_iter().map(|(min, max)| Limits { min, max }).collect());
    let played = py.allow_threads(|| {
        cycle.follow_trajectory(&positions, &times_ns, &points, limits.as_deref(), start_ns, tolerances)
    });
    match (played, names) {
        (Err(Error::Trajectory(e)), Some(names)) => Err(ConfigError::new_err(e.naming(names).to_string())),
        (played, _) => played.py(),
    }
}

/// Adds what `state` says to `d`: "state", and "replaced_by", "slave", "statusword",
/// "ds402_state" (None where they do not apply).
/// How a trajectory stands, as Python sees it in its status and its events: "state",
/// "replaced_by" (the newer id), and for an abort the drive, its statusword and its CiA 402
/// state.
/// A tolerance violation adds "velocity" (whether the velocity strayed, else the position)
/// and "error" (counts or counts/s), "slave" naming the drive.
#[derive(IntoPyObject)]
pub(super) struct StateView {
    state: &'static str,
    replaced_by: Option<u32>,
    slave: Option<u16>,
    statusword: Option<u16>,
    ds402_state: Option<&'static str>,
    velocity: Option<bool>,
    error: Option<i32>,
}

impl From<TrajectoryState> for StateView {
    fn from(state: TrajectoryState) -> Self {
        let (replaced_by, aborted) = match state {
            TrajectoryState::Replaced { by } => (Some(by), None),
            TrajectoryState::Aborted { slave, statusword } => (None, Some((slave, statusword))),
            _ => (None, None),
        };
        let violation = match state {
            TrajectoryState::PathToleranceViolated(v) | TrajectoryState::GoalToleranceViolated(v) => Some(v),
            _ => None,
        };
        StateView {
            state: state.name(),
            replaced_by,
            slave: aborted.map(|a| a.0).or(violation.map(|v| v.slave)),
            statusword: aborted.map(|a| a.1),
            ds402_state: aborted.and_then(|a| State::from_statusword(a.1)).map(State::name),
            velocity: violation.map(|v| v.velocity),
            error: violation.map(|v| v.error),
        }
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

pub(super) fn status_view(s: TrajectoryStatus) -> StatusView {
    let progress = ProgressView {
        id: s.id,
        point: s.point,
        points: s.points,
        started_ns: (s.started_ns != 0).then_some(s.started_ns),
        elapsed_ns: s.elapsed_ns,
        duration_ns: s.duration_ns,
    };
    Merged(progress, s.state.into())
}
