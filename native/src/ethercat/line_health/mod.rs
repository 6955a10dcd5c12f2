//! The line's health as its slaves' ESCs count it: each port's error counters and link, the
//! topology they make, and the place of a fault said in the cable's words. Pure: no I/O; the
//! master reads the registers ([`crate::ethercat::master::line_health`]), the cycle thread
//! tallies them beside its cycle, and the virtual slaves count into the same registers.
//!
//! - [`registers`]: the ESC's error counters (0x0300–0x0313), the DL status (0x0110) and the
//!   port descriptor (0x0007), decoded; which write clears which counters.
//! - [`tally`]: counters read now and then, turned into totals since the start and counts over
//!   a window, without allocation once made, and with nothing hidden: what saturated or was
//!   cleared by something else is counted too.
//! - [`topology`]: which port of which slave connects to which, from the DL statuses.
//! - [`place`]: where errors first appear, and the cable that names.
//!
//! Where each fact comes from: Beckhoff's EtherCAT slave controller datasheets, Section I
//! (technology, chapter "Error counters": what each counter counts, that they saturate at 0xFF,
//! that an ESC finding a frame invalid spoils its CRC and marks it so that the ESCs after it
//! count a forwarded error instead, that a physical-layer error at port 0 also counts in the
//! processing unit's counter) and Section II (register description: the layout, the clearing
//! rules, the DL status bits and the port descriptor), and their application note "Frequently
//! asked questions and troubleshooting" (error counter interpretation: an error first counted
//! at a port, with forwarded errors after it, lies on the segment in front of that port).

pub mod place;
pub mod registers;
pub mod tally;
pub mod topology;

use std::time::Duration;

/// What a reader of the line has: each slave's ports, and their links and counts as tallied.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct LineReading {
    /// Each slave's port descriptor, by position.
    pub ports: Vec<registers::PortDescriptor>,
    /// The counts.
    pub health: tally::LineHealth,
    /// How often the line is read; `None`: read once (at rest), or not at all.
    pub interval: Option<Duration>,
    /// Frames the reads took.
    pub frames: u64,
    /// Of those, the ones that did not come back.
    pub frames_lost: u64,
}

impl LineReading {
    /// The line's connections as first read (each slave's first DL status).
    pub fn topology(&self) -> topology::Topology {
        let found: Vec<_> = self.health.slaves.iter().map(|s| s.found).collect();
        topology::Topology::of(&found)
    }

    /// How its counts over the window are said: "in the last 10 s", or, for a line read once at
    /// rest, whose window is all each slave counted, "since power-up or the last clear".
    pub fn period(&self) -> String {
        match self.interval {
            Some(_) => place::window_words(self.health.window_ns),
            None => "since power-up or the last clear".to_owned(),
        }
    }

    /// What the counts show, the worst first ([`place::findings`]).
    pub fn findings(&self) -> Vec<place::Finding> {
        place::findings(&self.topology(), &self.health)
    }
}
