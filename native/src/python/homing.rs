//! Homing from Python: `Cycle.start_homing`, `Cycle.cancel_homing` and `Cycle.homing_status`,
//! converted here; the procedure is the crate's ([`crate::cycle::homing`]).

use pyo3::prelude::*;

use crate::cycle::homing::{HomingStatus, Phase};

/// What `Cycle.homing_status` gives.
#[derive(IntoPyObject)]
pub(super) struct HomingView {
    request: u32,
    phase: &'static str,
    outcome: Option<&'static str>,
    reason: Option<&'static str>,
    statusword: u16,
    homing_state: &'static str,
    homed: bool,
}

impl From<HomingStatus> for HomingView {
    fn from(s: HomingStatus) -> Self {
        let (phase, outcome) = match s.phase {
            Phase::Idle => ("idle", None),
            Phase::Entering | Phase::Homing => ("homing", None),
            Phase::Stopping(o) | Phase::Leaving(o) => ("ending", Some(o)),
            Phase::Done(o) => ("done", Some(o)),
        };
        HomingView {
            request: s.request,
            phase,
            outcome: outcome.map(|o| o.name()),
            reason: outcome.and_then(|o| o.describe()),
            statusword: s.statusword,
            homing_state: s.homing_state(),
            homed: s.homed,
        }
    }
}
