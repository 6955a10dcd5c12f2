//! The AL state machine from the master's side: request a state, wait for it, and when the
//! slave refuses, read why from AL status code 0x0134, name it and acknowledge the error.
//!
//! Upward requests step through every state in between (Init → PreOp → SafeOp → Op), since
//! the AKD refuses skipping one (0x0011), and each step does the set-up the next state needs:
//! mailbox sync managers before PreOp, the process-data mapping, sync managers and FMMUs before
//! SafeOp, and cyclic exchange while waiting for Op, as the drive wants valid outputs first.

use std::time::{Duration, Instant};

use crate::al::{self, AlState, AL_ERROR_ACK, AL_ERROR_FLAG};
use crate::error::{Error, Result};
use crate::master::Master;
use crate::registers::{AL_CONTROL, AL_STATUS};

/// Pause between polls of AL status, short against a drive that polls its AL control itself.
const POLL_INTERVAL: Duration = Duration::from_micros(200);

/// What AL status (0x0130) and AL status code (0x0134) say about one slave.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct AlStatus {
    /// AL status register value: state bits and error flag.
    pub status: u16,
    /// AL status code: why the last state change failed.
    pub code: u16,
}

impl AlStatus {
    /// The state, if the state bits hold a valid one.
    pub fn state(&self) -> Option<AlState> {
        AlState::from_bits(self.status)
    }

    /// The state's name.
    pub fn state_name(&self) -> &'static str {
        al::state_name(self.status)
    }

    /// Whether the error flag (bit 4) is set.
    pub fn error(&self) -> bool {
        self.status & AL_ERROR_FLAG != 0
    }

    /// The name of the AL status code.
    pub fn code_name(&self) -> &'static str {
        al::status_code_name(self.code)
    }
}

/// Order of the states on the way up, for stepping; Bootstrap sits beside Init.
fn rank(state: AlState) -> u8 {
    match state {
        AlState::Init | AlState::Bootstrap => 0,
        AlState::PreOp => 1,
        AlState::SafeOp => 2,
        AlState::Op => 3,
    }
}

fn next_up(state: AlState) -> AlState {
    match state {
        AlState::Init | AlState::Bootstrap => AlState::PreOp,
        AlState::PreOp => AlState::SafeOp,
        AlState::SafeOp | AlState::Op => AlState::Op,
    }
}

impl Master {
    /// Reads AL status and AL status code of the slave at `station` in one datagram.
    fn read_al_status(&mut self, station: u16) -> Result<AlStatus> {
        let mut b = [0u8; 6];
        self.read_registers(station, AL_STATUS, &mut b)?;
        Ok(AlStatus { status: u16::from_le_bytes([b[0], b[1]]), code: u16::from_le_bytes([b[4], b[5]]) })
    }

    /// AL status and AL status code of the slave at `position`.
    pub fn al_status(&mut self, position: u16) -> Result<AlStatus> {
        let station = self.station(position)?;
        self.read_al_status(station)
    }

    /// Takes the slave at `position` (or every slave) to `target`, stepping through the states
    /// in between, each step within `timeout`. A refusal raises [`Error::AlState`] with the AL
    /// status code and its name, after the error has been acknowledged.
    pub fn request_state(&mut self, target: AlState, position: Option<u16>, timeout: Duration) -> Result<()> {
        let positions = self.positions(position)?;
        loop {
            let mut lowest = None::<AlState>;
            for &p in &positions {
                let station = self.station(p)?;
                let status = self.read_al_status(station)?;
                if status.error() {
                    self.acknowledge(station, status)?;
                }
                let state = status.state().unwrap_or(AlState::Init);
                if lowest.is_none_or(|l| rank(state) < rank(l)) {
                    lowest = Some(state);
                }
            }
            let Some(lowest) = lowest else { return Ok(()) };
            // Down, Bootstrap, or the last step up: ask for the target itself.
            let step = if rank(target) <= rank(lowest) || target == AlState::Bootstrap { target } else { next_up(lowest) };
            self.prepare(step, &positions)?;
            for &p in &positions {
                let station = self.station(p)?;
                let status = self.read_al_status(station)?;
                if status.state() != Some(step) {
                    self.write_u16(station, AL_CONTROL, step as u16)?;
                }
            }
            for &p in &positions {
                let station = self.station(p)?;
                self.wait_state(p, station, step, timeout)?;
            }
            if step == target {
                return Ok(());
            }
        }
    }

    /// Set-up before the slaves at `positions` are asked for `step`.
    fn prepare(&mut self, step: AlState, positions: &[u16]) -> Result<()> {
        match step {
            AlState::PreOp => positions.iter().try_for_each(|&p| self.setup_mailbox(p)),
            AlState::SafeOp => self.setup_process_data(positions),
            _ => Ok(()),
        }
    }

    /// Acknowledges an AL error: AL control = current state with the acknowledge bit.
    fn acknowledge(&mut self, station: u16, status: AlStatus) -> Result<()> {
        let state = status.status & al::AL_STATE_MASK;
        self.write_u16(station, AL_CONTROL, state | AL_ERROR_ACK)
    }

    /// Polls the slave until it is in `target`, refuses with the error flag, or `timeout` passes.
    /// While waiting for Op the process data keeps flowing, as the drive needs outputs first.
    pub(crate) fn wait_state(&mut self, position: u16, station: u16, target: AlState, timeout: Duration) -> Result<()> {
        let deadline = Instant::now() + timeout;
        loop {
            if target == AlState::Op && self.process.is_some() {
                // The WKC changes while the slaves move to Op; the result is the state, not it.
                let _ = self.exchange();
            }
            let status = self.read_al_status(station)?;
            if status.state() == Some(target) && !status.error() {
                return Ok(());
            }
            if status.error() {
                self.acknowledge(station, status)?;
                return Err(Error::AlState {
                    slave: position,
                    requested: target.name(),
                    actual: status.state_name(),
                    code: status.code,
                    code_name: status.code_name(),
                });
            }
            if Instant::now() >= deadline {
                return Err(Error::Timeout {
                    what: format!(
                        "slave {position} to reach {} (it is in {}, AL status code 0x{:04X}: {})",
                        target.name(),
                        status.state_name(),
                        status.code,
                        status.code_name()
                    ),
                });
            }
            std::thread::sleep(POLL_INTERVAL);
        }
    }
}
