//! The virtual AKD's homing (mode 6, "AKD-internal homing", AKD manual §5.8): on the rising
//! edge of controlword bit 4 the drive moves toward its reference at its homing speed, stops
//! there, and makes that place its zero (statusword bit 12, homing attained).
//!
//! The AKD takes its homing method, speeds and offset from its own HOME.* parameters, which the
//! EtherCAT manuals here name no CoE object for (the 2013 manual lists none of 0x6098, 0x6099,
//! 0x609A, 0x607C, and the real drive's capture reads none), so the virtual AKD does not
//! answer them either: its homing is set where a real drive's is, outside the master, here
//! through akd-sim's control ([`Setup`]). The reference is a place on the machine (a home switch
//! in shaft counts), kept through a power cycle; the zero found is the drive's and is forgotten
//! by one.
//!
//! Statusword bits in homing (CiA 402): 13 homing error, 12 homing attained, 10 target reached
//! (the motion stopped); 0/0/0 in progress, 10 alone interrupted or not started.

use crate::error::UnknownName;
use crate::sim::motion::COUNTS_PER_REV;

named_variants! {
    /// How a homing run goes wrong, as akd-sim's control makes it.
    pub enum Failure {
        /// Halfway to the reference the drive stops with a homing error (bit 13), as the AKD does
        /// when a limit switch or a fault ends the search.
        Error => "error",
        /// The reference is never seen: the drive searches at its homing speed until halted or
        /// taken out of homing (the master's time-out is what ends it).
        NoReference => "no_reference",
    }
    /// Its name in akd-sim's control.
    fn name;
}

impl Failure {
    /// The failure named `name`, or `None` for "ok" (homing works).
    pub fn from_name(name: &str) -> Result<Option<Failure>, UnknownName> {
        if name == "ok" {
            return Ok(None);
        }
        Failure::ALL
            .into_iter()
            .find(|f| f.name() == name)
            .map(Some)
            .ok_or_else(|| UnknownName::HomingFailure { name: name.to_owned() })
    }
}

/// A drive's homing as set up in the drive (the AKD's HOME.* parameters).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Setup {
    /// Where the reference is, shaft counts.
    pub reference: f64,
    /// Homing speed, counts/s.
    pub speed: f64,
    /// Homing acceleration and deceleration, counts/s².
    pub acceleration: f64,
    /// How the next runs fail, if they do.
    pub failure: Option<Failure>,
}

impl Default for Setup {
    /// A reference a quarter revolution from where the shaft is at power-up, found at one
    /// revolution per second with 20 rev/s² (the simulator's choice, not the AKD's defaults).
    fn default() -> Self {
        Setup {
            reference: COUNTS_PER_REV / 4.0,
            speed: COUNTS_PER_REV,
            acceleration: 20.0 * COUNTS_PER_REV,
            failure: None,
        }
    }
}

/// One homing run under way.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Run {
    /// Where the motion stops, shaft counts (infinite while it searches for nothing).
    pub stop_at: f64,
    /// What it finds there.
    pub ends: Ending,
}

/// What a run finds where it stops.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Ending {
    /// The reference: homing attained, the zero defined there.
    Reference,
    /// A homing error.
    Error,
}

impl Run {
    /// The run `setup` makes from shaft position `from`.
    pub fn start(setup: &Setup, from: f64) -> Run {
        match setup.failure {
            None => Run { stop_at: setup.reference, ends: Ending::Reference },
            Some(Failure::Error) => Run { stop_at: (from + setup.reference) / 2.0, ends: Ending::Error },
            Some(Failure::NoReference) => {
                let toward = if setup.reference >= from { f64::INFINITY } else { f64::NEG_INFINITY };
                Run { stop_at: toward, ends: Ending::Reference }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn failures_are_named_and_a_wrong_name_lists_them() {
        assert_eq!(Failure::from_name("ok"), Ok(None));
        assert_eq!(Failure::from_name("no_reference"), Ok(Some(Failure::NoReference)));
        let e = Failure::from_name("stall").unwrap_err().to_string();
        assert!(e.contains("stall") && e.contains("ok, error, no_reference"), "{e}");
    }

    #[test]
    fn a_run_goes_to_the_reference_or_fails_as_set_up() {
        let mut setup = Setup::default();
        assert_eq!(Run::start(&setup, 0.0), Run { stop_at: setup.reference, ends: Ending::Reference });
        setup.failure = Some(Failure::Error);
        assert_eq!(Run::start(&setup, -setup.reference).stop_at, 0.0);
        setup.failure = Some(Failure::NoReference);
        assert_eq!(Run::start(&setup, 1e9).stop_at, f64::NEG_INFINITY);
    }
}
