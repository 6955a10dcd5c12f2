//! The drive profile: what the crate knows of a CiA 402 drive and of the AKD in particular,
//! above the EtherCAT layer, its codecs pure (no I/O): [`ds402`] (the CiA 402 state machine, its
//! modes, targets and handshakes), [`identity`] (what tells an AKD from another slave, and its
//! model and firmware in its SII), [`pdo`] (the AKD's mappable objects and mappings, and their
//! rules), [`objects`] (mapped values read and encoded by their data types), [`io`] (the
//! drive's own digital and analog I/O in its process data), [`scaling`] (how the drive scales
//! its positions), [`sync`] (how it follows the line's clock), [`akd_fault`] (the AKD's fault
//! numbers) and [`trajectory`] (joint trajectories, validated and interpolated). The cycle thread, the virtual AKD and the bindings
//! read the drive from here; [`akd`] is what the profile does to an AKD through the master (its
//! mapping, its position scaling, its clock's side, its restore), the master itself knowing no
//! AKD.

pub mod akd;
pub mod akd_fault;
pub mod ds402;
pub mod identity;
pub mod io;
pub mod objects;
pub mod pdo;
pub mod scaling;
pub mod sync;
pub mod trajectory;
