//! akd_native: an EtherCAT master for Kollmorgen AKD drives and a virtual AKD that answers as a
//! real one does.
//!
//! The crate is its products, one folder each, and they point one way:
//!
//! - [`ethercat`]: the EtherCAT layer, which knows no AKD: pure codecs (frames, registers, SII,
//!   AL states, mailbox, CoE, EoE, FoE, distributed clocks, process-data entries, the text that
//!   names a bus), the links that move frames, and the master.
//! - [`drive`]: the drive profile above it, pure: CiA 402, the AKD's objects, mappings, scaling,
//!   faults and I/O, and joint trajectories.
//! - [`sim`]: the virtual AKDs beside the master, sharing its codecs and never its state; they
//!   serve frames through the same [`ethercat::link::Link`] trait.
//! - [`cycle`]: the real-time thread that owns a master in Op and sequences each drive.
//! - [`ros`]: the ROS side: the messages the crate serialises, the bag's files and their writer
//!   thread, and what the node publishes and records of a running cycle.
//! - The Python bindings (feature `python`) on top of all of them, the only place that opens a
//!   link spec, since only they may see both the links and the simulator.
//!
//! Beside them, four things every product uses: [`error`] (the umbrella [`error::Error`] the
//! layers above the codecs return, a `From` for each codec's error, and the errors only those
//! layers raise), [`setting`] (a configuration value out of range) and the `wire_codes!` macro
//! (closed sets of wire codes as enums, e.g. [`ethercat::coe::CoeService`]; open ones as
//! newtypes with a `name()`, e.g. [`ethercat::coe::SdoAbortCode`]) and [`spelling`] (how a
//! name is spelled as one word, [`spelling::snake_case`]).

#![deny(missing_docs)]

#[macro_use]
mod wire_code;

pub mod cycle;
pub mod drive;
pub mod error;
pub mod ethercat;
pub mod ros;
pub mod setting;
pub mod sim;
pub mod spelling;

#[cfg(feature = "python")]
mod python;
