//! akd_native: an EtherCAT master for Kollmorgen AKD drives and a virtual AKD that answers as a
//! real one does.
//!
//! The layers point one way, each using only those listed before it:
//!
//! 1. Pure codecs, no I/O and no allocation in their hot paths, so each is tested alone and the
//!    master and the virtual AKD share them without sharing any state: [`frame`] (datagrams
//!    and working counters), [`registers`] (ESC register map), [`sii`] (SII EEPROM content),
//!    [`al`] (AL states and status codes), [`mailbox`] and [`coe`] (mailbox header, CoE SDO,
//!    SDO information, emergency), [`eoe`] (Ethernet over EtherCAT: fragments, Set IP
//!    Parameter) and [`foe`] (file access over EtherCAT), [`pdo`] (the AKD's process-data mappings and their rules),
//!    [`io`] (the drive's own digital and analog I/O in its process data),
//!    [`dc`] (distributed-clock arithmetic), [`ds402`] (CiA 402 drive state machine), [`scaling`]
//!    (how the drive scales its positions, from its DS402 scaling objects) and
//!    [`akd_fault`] (the AKD's fault numbers), and [`trajectory`] (joint trajectories, validated
//!    and interpolated), [`link_spec`] (the text that names a bus) and [`setting`] (a
//!    configuration value out of range). Closed sets of wire codes are enums (e.g.
//!    [`coe::CoeService`]); open ones are newtypes with a `name()` (e.g. [`coe::SdoAbortCode`]).
//!    Each raises its own error, declared beside it and named in the standard's and the drive's
//!    words (AL status code names, SDO abort code names, the AKD's mapping rules).
//! 2. [`error`]: the umbrella [`error::Error`] the layers above return, a `From` for each
//!    codec's error, and the errors only those layers raise.
//! 3. [`link`]: the [`link::Link`] trait that moves frames, and the links to a real line (UDP,
//!    raw interface) with the pcapng recorder.
//! 4. [`master`]: one [`master::Master`] drives one bus (scan, AL states of every slave, the
//!    cyclic exchange, distributed clocks) and hands out a [`master::SlaveRef`] per drive for
//!    what concerns that drive alone (SDO, mailbox, mapping, its process data).
//! 5. [`cycle`]: the real-time thread that owns a master in Op, exchanges its process image
//!    every period and sequences each drive's CiA 402 state machine, without allocating,
//!    locking or waiting on another thread.
//!
//! [`sim`], the virtual AKD, stands beside the master: it uses the codecs and serves frames
//! through the same [`link::Link`] trait ([`sim::in_process`]) or over UDP and raw Ethernet
//! ([`sim::server`]), so the master cannot tell it from a real line. The Python bindings (feature
//! `python`) sit on top of all of them and are the only place that opens a link spec, since
//! only they may see both the links and the simulator.
//!
//! [`ros_msgs`] is a codec too: the ROS messages the crate serialises itself (CDR by
//! `cdr-encoding`). [`bag_file`] and [`bag_writer`] stand apart from the EtherCAT layers: one
//! MCAP file of a rosbag2 bag, and the thread that writes a bag's files (topics, messages,
//! per-cycle records, the black box). [`node`] sits on the cycle and the bag writer: what the
//! ROS node publishes and records of a running cycle, made off the Python path ([`node::feed`],
//! [`node::cycle_records`]), with the per-cycle records [`cycle::record`] serialises.

#![deny(missing_docs)]

#[macro_use]
mod wire_code;

pub mod akd_fault;
pub mod al;
pub mod bag_file;
pub mod bag_writer;
pub mod coe;
pub mod cycle;
pub mod dc;
pub mod ds402;
pub mod eoe;
pub mod error;
pub mod foe;
pub mod frame;
pub mod io;
pub mod link;
pub mod link_spec;
pub mod mailbox;
pub mod master;
pub mod node;
pub mod objects;
pub mod pdo;
pub mod registers;
pub mod ros_msgs;
pub mod scaling;
pub mod setting;
pub mod sii;
pub mod sim;
pub mod trajectory;

#[cfg(feature = "python")]
mod python;
