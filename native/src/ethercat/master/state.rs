//! The AL state machine from the master's side: request a state, wait for it, and when the
//! slave refuses, read why from AL status code 0x0134, name it and acknowledge the error.
//!
//! Upward requests step through every state in between (Init → PreOp → SafeOp → Op), since
//! the AKD refuses skipping one (0x0011), and each step does the set-up the next state needs:
//! mailbox sync managers before PreOp, the process-data mapping, sync managers and FMMUs before
//! SafeOp, and cyclic exchange while waiting for Op, as the drive wants valid outputs first.

use std::time::{Duration, Instant};

use crate::error::{Error, Result};
use crate::ethercat::al::{self, AlState, AL_ERROR_ACK, AL_ERROR_FLAG};
use crate::ethercat::frame::Command;
use crate::ethercat::master::Master;
use crate::ethercat::registers::{AL_CONTROL, AL_STATUS};

/// Pause between polls of AL status, short against a drive that polls its AL control itself.
const POLL_INTERVAL: Duration = Duration::from_micros(200);
/// How long the drive may take to accept an error acknowledge.
const ACK_TIMEOUT: Duration = Duration::from_secs(1);

/// What AL status (0x0130) and AL status code (0x0134) say about one slave.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct AlStatus {
    /// AL status register value: state bits and error flag.
    pub status: u16,
    /// AL status code: why the last state change failed.
    pub code: u16,
}

impl AlStatus {
    /// Decodes AL status (0x0130) and AL status code (0x0134) from the six bytes at 0x0130.
    pub fn from_registers(b: &[u8; 6]) -> Self {
        AlStatus { status: u16::from_le_bytes([b[0], b[1]]), code: u16::from_le_bytes([b[4], b[5]]) }
    }

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
        al::AlStatusCode(self.code).name()
    }

    /// The time-out of slave `position`, awaited to `goal` (e.g. "reach Op"), still as this says.
    fn timed_out(&self, position: u16, goal: &str) -> Error {
        let (state, code, code_name) = (self.state_name(), self.code, self.code_name());
        let what = format!("slave {position} to {goal} (it is in {state}, AL status code 0x{code:04X}: {code_name})");
        Error::Timeout { what: what.into() }
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
        Ok(AlStatus::from_registers(&b))
    }

    /// AL status and AL status code of the slave at `position`.
    pub(super) fn al_status(&mut self, position: u16) -> Result<AlStatus> {
        let station = self.station(position)?;
        self.read_al_status(station)
    }

    /// Takes every slave to `target`, stepping through the states in between together, each
    /// step within `timeout`. A refusal raises [`Error::AlState`] with the AL status code and its
    /// name, after the error has been acknowledged. One slave alone goes with
    /// [`SlaveRef::request_state`](crate::ethercat::master::SlaveRef::request_state).
    pub fn request_state(&mut self, target: AlState, timeout: Duration) -> Result<()> {
        self.request_state_of(target, None, timeout)
    }

    /// Takes the slave at `position` (or every slave) to `target`, as
    /// [`request_state`](Self::request_state) says.
    pub(super) fn request_state_of(&mut self, target: AlState, position: Option<u16>, timeout: Duration) -> Result<()> {
        let positions = self.positions(position)?;
        loop {
            let mut states = Vec::with_capacity(positions.len());
            for &p in &positions {
                let station = self.station(p)?;
                let status = self.read_al_status(station)?;
                if status.error() {
                    self.acknowledge(p, station, status)?;
                }
                states.push((p, station, status.state().unwrap_or(AlState::Init)));
            }
            let Some(lowest) = states.iter().map(|s| s.2).min_by_key(|&s| rank(s)) else { return Ok(()) };
            // Down, Bootstrap, or the last step up: ask for the target itself.
            let step =
                if rank(target) <= rank(lowest) || target == AlState::Bootstrap { target } else { next_up(lowest) };
            let climbing: Vec<u16> =
                states.iter().filter(|s| s.2 != step && rank(s.2) < rank(step)).map(|s| s.0).collect();
            self.prepare(step, &climbing)?;
            for &(p, station, state) in &states {
                if state != step {
                    self.write_al_control(p, station, step as u16, timeout)?;
                }
            }
            for &(p, station, _) in &states {
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

    /// Acknowledges an AL error (AL control = current state with the acknowledge bit) and
    /// waits until the drive has cleared the error flag.
    fn acknowledge(&mut self, position: u16, station: u16, status: AlStatus) -> Result<()> {
        let state = status.status & al::AL_STATE_MASK;
        self.write_al_control(position, station, state | AL_ERROR_ACK, ACK_TIMEOUT)?;
        let deadline = Instant::now() + ACK_TIMEOUT;
        loop {
            let now = self.read_al_status(station)?;
            if !now.error() {
                return Ok(());
            }
            self.clear_echoed_ack(position, station, now, state | AL_ERROR_ACK)?;
            if Instant::now() >= deadline {
                return Err(Error::Timeout { what: format!("slave {position} to clear its AL error flag").into() });
            }
            std::thread::sleep(POLL_INTERVAL);
        }
    }

    /// An ESC in device emulation (PDI control bit 8: a terminal without a processor, an
    /// EK1100 or an EL1004) copies AL control into AL status, the acknowledge bit too, so that
    /// the error flag reads set after `written` (a state with the acknowledge bit): when AL
    /// status is exactly that, with no AL status code, the state is written again without the
    /// bit, which clears it. A drive whose firmware answers the acknowledge never shows it so
    /// once the firmware took it.
    fn clear_echoed_ack(&mut self, position: u16, station: u16, status: AlStatus, written: u16) -> Result<()> {
        if status.status == written && status.code == 0 {
            self.write_al_control(position, station, written & !AL_ERROR_ACK, ACK_TIMEOUT)?;
        }
        Ok(())
    }

    /// Takes a slave found in any state, with or without its error flag set, to Init with the
    /// flag cleared. Unlike a state request, an error flag seen here is the old one still
    /// waiting for the drive's firmware to take the acknowledge, not a refusal.
    pub(crate) fn reset_to_init(&mut self, position: u16, station: u16, timeout: Duration) -> Result<()> {
        let deadline = Instant::now() + timeout;
        let written = AlState::Init as u16 | AL_ERROR_ACK;
        self.write_al_control(position, station, written, timeout)?;
        loop {
            let status = self.read_al_status(station)?;
            if status.state() == Some(AlState::Init) && !status.error() {
                return Ok(());
            }
            self.clear_echoed_ack(position, station, status, written)?;
            if Instant::now() >= deadline {
                return Err(status.timed_out(position, "return to Init"));
            }
            std::thread::sleep(POLL_INTERVAL);
        }
    }

    /// Writes AL control. Without device emulation (0x0140 bit 8, off on the AKD) AL control
    /// works like a mailbox: the ESC refuses a new write (WKC 0) until the drive's firmware has
    /// read the last one, so a refused write is repeated until `timeout`.
    fn write_al_control(&mut self, position: u16, station: u16, value: u16, timeout: Duration) -> Result<()> {
        let deadline = Instant::now() + timeout;
        loop {
            let wkc = self.datagram_retry(Command::Fpwr, station, AL_CONTROL, &mut value.to_le_bytes())?;
            if wkc == 1 {
                return Ok(());
            }
            if Instant::now() >= deadline {
                return self.expect_wkc(
                    || format!("FPWR of AL control 0x{value:04X} to slave {position} (its firmware never took the last request)"),
                    1,
                    wkc,
                );
            }
            std::thread::sleep(POLL_INTERVAL);
        }
    }

    /// Polls the slave until it is in `target`, refuses with the error flag, or `timeout` passes.
    /// While waiting for Op the process data keeps flowing, as the drive needs outputs first.
    pub(crate) fn wait_state(&mut self, position: u16, station: u16, target: AlState, timeout: Duration) -> Result<()> {
        let deadline = Instant::now() + timeout;
        loop {
            if target == AlState::Op && self.process.is_some() {
                // The WKC changes while the slaves move to Op: not an error, so not judged.
                self.cycle(false)?;
            }
            let status = self.read_al_status(station)?;
            if status.state() == Some(target) && !status.error() {
                return Ok(());
            }
            if status.error() {
                self.acknowledge(position, station, status)?;
                return Err(Error::AlState {
                    slave: position,
                    requested: target.name(),
                    actual: status.state_name(),
                    code: status.code,
                    code_name: status.code_name(),
                });
            }
            if Instant::now() >= deadline {
                return Err(status.timed_out(position, &format!("reach {}", target.name())));
            }
            std::thread::sleep(POLL_INTERVAL);
        }
    }
}
