//! The EtherCAT layer: everything a master of any slave needs, and nothing of an AKD.
//!
//! Its modules point one way, each using only those listed before it:
//!
//! 1. Pure codecs, no I/O and no allocation in their hot paths, so each is tested alone and the
//!    master and the virtual AKD share them without sharing any state: [`frame`] (datagrams
//!    and working counters), [`registers`] (ESC register map), [`sii`] (SII EEPROM content),
//!    [`al`] (AL states and status codes), [`mailbox`] and [`coe`] (mailbox header, CoE SDO,
//!    SDO information, emergency), [`eoe`] (Ethernet over EtherCAT: fragments, Set IP
//!    Parameter), [`foe`] (file access over EtherCAT), [`dc`] (distributed-clock arithmetic),
//!    [`pdo`] (process-data entries, and the description of a slave's process data the master
//!    sets it up from), [`device`] (a slave's process data by name: its channels, their
//!    values to the bit), [`link_spec`] (the text that names a bus) and [`line_health`] (the ESCs'
//!    error counters and links, the line's topology and the place of a fault). Each raises its own error, declared
//!    beside it and named in the standard's words (AL status code names, SDO abort code
//!    names).
//! 2. [`link`]: the [`link::Link`] trait that moves frames, and the links to a real line (UDP,
//!    raw interface) with the pcapng capture.
//! 3. [`master`]: one [`master::Master`] drives one bus (scan, AL states of every slave, the
//!    cyclic exchange, distributed clocks) and hands out a [`master::SlaveRef`] per slave for
//!    what concerns that slave alone (SDO, mailbox, process data).
//!
//! The links and the master return the crate's umbrella [`crate::error::Error`].

pub mod al;
pub mod coe;
pub mod dc;
pub mod device;
pub mod eoe;
pub mod foe;
pub mod frame;
pub mod line_health;
pub mod link;
pub mod link_spec;
pub mod mailbox;
pub mod master;
pub mod pdo;
pub mod registers;
pub mod sii;
