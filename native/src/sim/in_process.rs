//! The in-process link: frames go straight through a [`VirtualBus`] of virtual AKDs, with no
//! socket in between, so tests are fast and deterministic. The bus takes commands from
//! [`SimControl`] handles at each frame (see [`crate::sim::control`]), so a test can inject
//! faults while the master, or its cycle thread, owns the link. It lives beside the simulator,
//! not among the links, so that the link layer knows only frames and the simulator serves them
//! through the same [`Link`] trait as any other line.

use std::time::Instant;

use crate::error::Result;
use crate::ethercat::link::{Link, Returns};
use crate::sim::control::{ControlledBus, SimControl};
use crate::sim::line::Delivery;
use crate::sim::VirtualBus;

/// A link to virtual AKDs in this process.
pub struct InProcess {
    bus: ControlledBus,
    start: Instant,
    returns: Returns,
}

impl InProcess {
    /// `count` virtual AKDs in a line, as at power-up.
    pub fn new(count: usize) -> Self {
        Self::with_bus(VirtualBus::new(count))
    }

    /// A link to an existing bus (for tests that prepare or inspect it).
    pub fn with_bus(bus: VirtualBus) -> Self {
        InProcess { bus: ControlledBus::from(bus), start: Instant::now(), returns: Returns::default() }
    }

    /// The bus behind the link.
    pub fn bus(&self) -> &VirtualBus {
        self.bus.bus()
    }

    /// The bus behind the link, for fault injection.
    pub fn bus_mut(&mut self) -> &mut VirtualBus {
        self.bus.bus_mut()
    }

    /// A handle that controls the bus from any thread while the link is in use.
    pub fn control(&self) -> SimControl {
        self.bus.control()
    }
}

impl Link for InProcess {
    fn send(&mut self, tx: &[u8]) -> Result<()> {
        // Monotonic time since the link opened: the bus's clocks run from there.
        let now_ns = self.start.elapsed().as_nanos() as u64;
        let bus = &mut self.bus;
        // The drives serve the frame as it passes; its return waits to be received. A frame
        // lost on the line is not waited out: nothing is there to receive, and the drives'
        // time runs on anyway.
        self.returns.serve(tx, |frame| Ok(bus.process(frame, now_ns)? == Delivery::Returned))
    }

    fn receive(&mut self, rx: &mut [u8], _deadline: Instant) -> Result<Option<usize>> {
        self.returns.take(rx)
    }

    fn describe(&self) -> String {
        format!("sim:{}", self.bus.bus().len())
    }

    fn awaited(&self) -> &'static str {
        "a frame to come back from the virtual AKDs (lost on the line)"
    }
}
