//! akd_native: an EtherCAT master for Kollmorgen AKD drives and a virtual AKD that answers as a
//! real one does.
//!
//! The protocol modules are pure codecs with no I/O and no allocation in their hot paths, so
//! each can be tested alone and the master and the virtual AKD share them without sharing any
//! state: [`frame`] (datagrams and working counters), [`registers`] (ESC register map),
//! [`sii`] (SII EEPROM content), [`al`] (AL states and status codes), [`mailbox`] and [`coe`]
//! (mailbox header, CoE SDO, SDO information, emergency), [`pdo`] (AKD process-data mappings),
//! [`dc`] (distributed-clock arithmetic) and [`ds402`] (CiA 402 drive state machine).
//! [`link`] moves frames; [`master`] drives a bus; [`cycle`] runs the master's exchange in a
//! real-time thread; [`sim`] is the virtual AKD.

#![deny(missing_docs)]

#[macro_use]
mod wire_code;

pub mod akd_fault;
pub mod al;
pub mod coe;
pub mod cycle;
pub mod dc;
pub mod ds402;
pub mod error;
pub mod frame;
pub mod link;
pub mod mailbox;
pub mod master;
pub mod pdo;
pub mod registers;
pub mod sii;
pub mod sim;

#[cfg(feature = "python")]
mod python;
