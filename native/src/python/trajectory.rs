//! Joint trajectories for Python: `Cycle.play_trajectory`, `Cycle.trajectory_status` and the
//! "trajectory" events, converted here; the validation, the handoff and the interpolation are
//! the crate's ([`crate::trajectory`], [`crate::cycle::trajectory_player`]).

use pyo3::prelude::*;
use pyo3::types::PyDict;

use super::IntoPyResult;
use crate::cycle::events::TrajectoryState;
use crate::cycle::trajectory_player::Status;
use crate::cycle::CycleThread;
use crate::ds402::State;
use crate::trajectory::{Knot, Limits};

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

/// Validates and hands over a trajectory, the GIL released while the cycle thread takes it.
pub(super) fn play(
    py: Python<'_>,
    cycle: &CycleThread,
    positions: Vec<u16>,
    times_ns: Vec<u64>,
    points: Vec<Vec<PyKnot>>,
    start_ns: Option<u64>,
    limits: Option<Vec<(f64, f64)>>,
) -> PyResult<u32> {
    let points: Vec<Vec<Knot>> = points.iter().map(|p| p.iter().map(Knot::from).collect()).collect();
    let limits: Option<Vec<Limits>> = limits.map(|l| l.into_iter().map(|(min, max)| Limits { min, max }).collect());
    py.allow_threads(|| cycle.play_trajectory(&positions, &times_ns, &points, limits.as_deref(), start_ns)).py()
}

/// Adds what `state` says to `d`: "state", and "replaced_by", "slave", "statusword",
/// "ds402_state" (None where they do not apply).
pub(super) fn add_state(d: &Bound<'_, PyDict>, state: TrajectoryState) -> PyResult<()> {
    d.set_item("state", state.name())?;
    let (by, aborted) = match state {
        TrajectoryState::Replaced { by } => (Some(by), None),
        TrajectoryState::Aborted { slave, statusword } => (None, Some((slave, statusword))),
        _ => (None, None),
    };
    d.set_item("replaced_by", by)?;
    d.set_item("slave", aborted.map(|a| a.0))?;
    d.set_item("statusword", aborted.map(|a| a.1))?;
    d.set_item("ds402_state", aborted.and_then(|a| State::from_statusword(a.1)).map(State::name))?;
    Ok(())
}

/// The dict `trajectory_status` gives.
pub(super) fn status_dict(py: Python<'_>, s: Status) -> PyResult<Bound<'_, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("id", s.id)?;
    add_state(&d, s.state)?;
    d.set_item("point", s.point)?;
    d.set_item("points", s.points)?;
    d.set_item("started_ns", (s.started_ns != 0).then_some(s.started_ns))?;
    d.set_item("elapsed_ns", s.elapsed_ns)?;
    d.set_item("duration_ns", s.duration_ns)?;
    Ok(d)
}
