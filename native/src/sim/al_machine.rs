//! The AKD's AL state machine (AKD manual §5.3, and the real drive in the SOEM capture).
//!
//! The drive polls AL control; a request is handled whole: a valid transition whose checks
//! pass changes the state, an invalid one sets the error flag with 0x0011, a failed check sets
//! it with the check's code (0x0017 for sync managers, 0x001D/0x001E for an odd process image)
//! and leaves the state where it was. While the error flag is set, requests for a higher state
//! are ignored until the master acknowledges with AL control bit 4.

use crate::ethercat::al::{AlState, AlStatusCode, AL_ERROR_ACK, AL_ERROR_FLAG};

/// The AL status of one virtual AKD.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct AlMachine {
    state: AlState,
    error: bool,
    status_code: AlStatusCode,
}

/// A state change that happened, for the caller to start or stop what the new state runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Transition {
    /// The state left.
    pub from: AlState,
    /// The state entered.
    pub to: AlState,
}

impl Default for AlMachine {
    fn default() -> Self {
        Self::power_up()
    }
}

impl AlMachine {
    /// The state after power-up: Init, no error (AL status 0x0001, code 0).
    pub const fn power_up() -> Self {
        AlMachine { state: AlState::Init, error: false, status_code: AlStatusCode::NO_ERROR }
    }

    /// The current state.
    pub fn state(&self) -> AlState {
        self.state
    }

    /// Whether the error flag is set.
    pub fn error(&self) -> bool {
        self.error
    }

    /// The AL status register value (state bits and error flag).
    pub fn status(&self) -> u16 {
        self.state as u16 | if self.error { AL_ERROR_FLAG } else { 0 }
    }

    /// The AL status code register value.
    pub fn status_code(&self) -> u16 {
        self.status_code.0
    }

    /// Handles an AL control value. `check(from, to)` runs the drive's checks of an upward
    /// transition (sync managers, process image) and returns the AL status code of a failure.
    pub fn request(
        &mut self,
        control: u16,
        check: impl FnOnce(AlState, AlState) -> Result<(), AlStatusCode>,
    ) -> Option<Transition> {
        if control & AL_ERROR_ACK != 0 {
            self.error = false;
            self.status_code = AlStatusCode::NO_ERROR;
        }
        let Some(to) = AlState::from_bits(control) else {
            self.fail(self.state, AlStatusCode::INVALID_STATE_CHANGE);
            return None;
        };
        let from = self.state;
        if to == from || (self.error && to > from) {
            return None;
        }
        let allowed = matches!(
            (from, to),
            (_, AlState::Init)
                | (AlState::Init, AlState::PreOp)
                | (AlState::Init, AlState::Bootstrap)
                | (AlState::PreOp, AlState::SafeOp)
                | (AlState::SafeOp, AlState::Op)
                | (AlState::SafeOp, AlState::PreOp)
                | (AlState::Op, AlState::SafeOp)
                | (AlState::Op, AlState::PreOp)
        );
        if !allowed {
            self.fail(from, AlStatusCode::INVALID_STATE_CHANGE);
            return None;
        }
        if to > from && to != AlState::Bootstrap {
            if let Err(status_code) = check(from, to) {
                self.fail(from, status_code);
                return None;
            }
        }
        self.state = to;
        Some(Transition { from, to })
    }

    /// Falls back to `state` with the error flag and `status_code` (a refused request, or the
    /// drive dropping out of Op on its own, e.g. the process-data watchdog).
    pub fn fail(&mut self, state: AlState, status_code: AlStatusCode) {
        self.state = state;
        self.error = true;
        self.status_code = status_code;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ok(_: AlState, _: AlState) -> Result<(), AlStatusCode> {
        Ok(())
    }

    #[test]
    fn refuses_the_transitions_the_manual_lists() {
        for (path, to) in [
            (&[][..], AlState::SafeOp),
            (&[], AlState::Op),
            (&[AlState::PreOp], AlState::Op),
            (&[AlState::PreOp], AlState::Bootstrap),
            (&[AlState::PreOp, AlState::SafeOp], AlState::Bootstrap),
            (&[AlState::PreOp, AlState::SafeOp, AlState::Op], AlState::Bootstrap),
        ] {
            let mut al = AlMachine::power_up();
            for s in path {
                assert!(al.request(*s as u16, ok).is_some());
            }
            let before = al.state();
            assert_eq!(al.request(to as u16, ok), None);
            assert_eq!((al.state(), al.status() & AL_ERROR_FLAG, al.status_code()), (before, AL_ERROR_FLAG, 0x0011));
        }
    }

    #[test]
    fn a_failed_check_keeps_the_state_until_acknowledged() {
        let mut al = AlMachine::power_up();
        al.request(0x02, ok);
        al.request(0x04, |_, _| Err(AlStatusCode::INVALID_OUTPUT_CONFIG));
        assert_eq!((al.status(), al.status_code()), (0x12, 0x001D));
        // Without acknowledge a higher state is ignored; with it the request is handled.
        assert_eq!(al.request(0x04, ok), None);
        assert_eq!(al.status(), 0x12);
        assert!(al.request(0x14, ok).is_some());
        assert_eq!((al.status(), al.status_code()), (0x04, 0));
    }

    #[test]
    fn goes_down_and_back_to_init_from_anywhere() {
        let mut al = AlMachine::power_up();
        for s in [0x02, 0x04, 0x08, 0x02, 0x04, 0x01, 0x03, 0x01] {
            assert!(al.request(s, ok).is_some(), "request 0x{s:02X}");
            assert_eq!(al.status(), s);
        }
        al.request(0x05, ok);
        assert_eq!((al.status(), al.status_code()), (0x11, 0x0011));
    }
}
