//! One slave of a virtual line: a virtual AKD or a virtual terminal, served alike as frames
//! pass them.

use crate::error::Result;
use crate::ethercat::frame::DatagramMut;
use crate::ethercat::link_spec::SimProduct;
use crate::sim::esc::{Arrival, Esc};
use crate::sim::esc_hardware::{self, EscHardware};
use crate::sim::terminal::{self, VirtualTerminal};
use crate::sim::{sii_image, Timing, VirtualAkd};

/// One slave of a [`VirtualBus`](super::VirtualBus).
// A line holds few slaves, in a Vec: the AKD's size costs nothing there, a box a pointer chase
// per slave and frame.
#[allow(clippy::large_enum_variant)]
pub enum VirtualSlave {
    /// A virtual AKD.
    Akd(VirtualAkd),
    /// A virtual Beckhoff terminal.
    Terminal(VirtualTerminal),
}

impl VirtualSlave {
    /// `product` at power-up; an AKD reports the identity of the `akd`-th AKD of its line
    /// ([`sii_image::identity`]) and reacts with `timing`. `has_successor` tells whether another
    /// slave follows on port 1.
    pub fn of(product: SimProduct, akd: usize, has_successor: bool, timing: Timing) -> Result<Self> {
        Ok(match terminal::description(product) {
            None => VirtualSlave::Akd(VirtualAkd::new(sii_image::identity(akd), has_successor, timing)),
            Some(description) => VirtualSlave::Terminal(VirtualTerminal::new(product, description, has_successor)?),
        })
    }

    /// The product it is.
    pub fn product(&self) -> SimProduct {
        match self {
            VirtualSlave::Akd(_) => SimProduct::Akd,
            VirtualSlave::Terminal(t) => t.product(),
        }
    }

    /// The AKD, if it is one.
    pub fn akd(&self) -> Option<&VirtualAkd> {
        match self {
            VirtualSlave::Akd(akd) => Some(akd),
            VirtualSlave::Terminal(_) => None,
        }
    }

    /// The AKD, if it is one, to change it.
    pub fn akd_mut(&mut self) -> Option<&mut VirtualAkd> {
        match self {
            VirtualSlave::Akd(akd) => Some(akd),
            VirtualSlave::Terminal(_) => None,
        }
    }

    /// The terminal, if it is one.
    pub fn terminal(&self) -> Option<&VirtualTerminal> {
        match self {
            VirtualSlave::Akd(_) => None,
            VirtualSlave::Terminal(t) => Some(t),
        }
    }

    /// The terminal, if it is one, to change it.
    pub fn terminal_mut(&mut self) -> Option<&mut VirtualTerminal> {
        match self {
            VirtualSlave::Akd(_) => None,
            VirtualSlave::Terminal(t) => Some(t),
        }
    }

    /// The ESC's register and RAM space.
    pub fn registers(&self) -> &[u8] {
        match self {
            VirtualSlave::Akd(akd) => akd.registers(),
            VirtualSlave::Terminal(t) => t.registers(),
        }
    }

    /// The slave loses its power and comes back as at power-up.
    pub fn power_cycle(&mut self) {
        match self {
            VirtualSlave::Akd(akd) => akd.power_cycle(),
            VirtualSlave::Terminal(t) => t.power_cycle(),
        }
    }

    /// Serves one datagram passing the slave at bus time `now_ns`.
    pub(super) fn serve(&mut self, dg: &mut DatagramMut<'_>, now_ns: u64, arrival: Arrival) {
        match self {
            VirtualSlave::Akd(akd) => akd.serve(dg, now_ns, arrival),
            VirtualSlave::Terminal(t) => t.serve(dg, now_ns, arrival),
        }
    }

    /// The slave's work between frames, up to bus time `now_ns`.
    pub(super) fn poll(&mut self, now_ns: u64) {
        match self {
            VirtualSlave::Akd(akd) => akd.poll(now_ns),
            VirtualSlave::Terminal(t) => t.poll(now_ns),
        }
    }

    /// A frame the line carried did not reach the slave.
    pub(super) fn miss_frame(&mut self) {
        if let VirtualSlave::Akd(akd) = self {
            akd.miss_frame();
        }
    }

    /// The slave's IP stack at bus time `now_ns` (an AKD's EoE; a terminal has none).
    pub(super) fn run_ip_stack(&mut self, now_ns: u64) {
        if let VirtualSlave::Akd(akd) = self {
            akd.run_ip_stack(now_ns);
        }
    }

    /// Its ESC: registers, links, error counters.
    pub fn esc(&self) -> &Esc {
        match self {
            VirtualSlave::Akd(akd) => &akd.esc,
            VirtualSlave::Terminal(t) => t.esc(),
        }
    }

    /// Its ESC, for the line to set its links and count what frames meet at its ports.
    pub(super) fn esc_mut(&mut self) -> &mut Esc {
        match self {
            VirtualSlave::Akd(akd) => &mut akd.esc,
            VirtualSlave::Terminal(t) => t.esc_mut(),
        }
    }
}

/// The ESC `product` is built on.
pub fn hardware_of(product: SimProduct) -> EscHardware {
    terminal::description(product).map_or(esc_hardware::AKD, |d| terminal::hardware(&d))
}
