//! One slave of the bus as a handle: [`SlaveRef`] carries every operation that talks to one
//! slave (AL state, registers, SDO and SDO information, mailbox, process data, its
//! slice of the process image, its emergencies), so a caller with several drives on one bus
//! picks the drive once and then talks to it, while [`Master`] keeps what concerns the whole
//! bus (scan, every slave's AL state, the cyclic exchange, distributed clocks, counters).

use std::time::Duration;

use crate::error::{Error, Result};
use crate::ethercat::al::AlState;
use crate::ethercat::coe::{Emergency, OdListType};
use crate::ethercat::master::sdo_info::{EntryInfo, ObjectInfo};
use crate::ethercat::master::state::AlStatus;
use crate::ethercat::master::{Master, Slave};
use crate::ethercat::pdo::ProcessData;

/// The slave at one position of a [`Master`]'s bus, from [`Master::slave_mut`] or
/// [`Master::slave_by_alias`]. It borrows the master, so nothing else uses the bus meanwhile.
pub struct SlaveRef<'m> {
    master: &'m mut Master,
    position: u16,
}

impl Master {
    /// The slave at `position` (from 0, in the order of the line), or an error naming how many
    /// slaves the bus has.
    pub fn slave_mut(&mut self, position: u16) -> Result<SlaveRef<'_>> {
        self.slave(position)?;
        Ok(SlaveRef { master: self, position })
    }

    /// The one slave whose station alias (register 0x0012, from SII word 4) is `alias`: a drive
    /// keeps its alias when cables are re-plugged, where its position would change. An alias on
    /// no slave or on several is an error saying on how many.
    pub fn slave_by_alias(&mut self, alias: u16) -> Result<SlaveRef<'_>> {
        let mut matching = self.slaves().iter().filter(|s| s.alias == alias);
        match (matching.next().map(|s| s.position), matching.count()) {
            (Some(position), 0) => Ok(SlaveRef { master: self, position }),
            (first, more) => Err(Error::AliasNotUnique { alias, count: first.map_or(0, |_| 1 + more) }),
        }
    }
}

impl SlaveRef<'_> {
    /// Position on the bus, from 0.
    pub fn position(&self) -> u16 {
        self.position
    }

    /// What the scan found of this slave (identity, SII, mailbox, process data).
    pub fn info(&self) -> &Slave {
        &self.master.slaves[self.position as usize]
    }

    /// AL status and AL status code (registers 0x0130, 0x0134).
    pub fn al_status(&mut self) -> Result<AlStatus> {
        self.master.al_status(self.position)
    }

    /// Takes this slave alone to `target`, stepping through the states in between, each step
    /// within `timeout`; a refusal is an [`Error::AlState`] with the AL status code and its name.
    pub fn request_state(&mut self, target: AlState, timeout: Duration) -> Result<()> {
        self.master.request_state_of(target, Some(self.position), timeout)
    }

    /// Reads `len` bytes of ESC registers from `register` (for tools and tests).
    pub fn read_register(&mut self, register: u16, len: usize) -> Result<Vec<u8>> {
        self.master.read_register_at(self.position, register, len)
    }

    /// Writes ESC registers from `register` (for tools and tests).
    pub fn write_register(&mut self, register: u16, data: &[u8]) -> Result<()> {
        self.master.write_register_at(self.position, register, data)
    }

    /// Reads object `index:subindex` by SDO upload.
    pub fn sdo_read(&mut self, index: u16, subindex: u8) -> Result<Vec<u8>> {
        self.master.sdo_read(self.position, index, subindex)
    }

    /// Writes object `index:subindex` by SDO download.
    pub fn sdo_write(&mut self, index: u16, subindex: u8, data: &[u8]) -> Result<()> {
        self.master.sdo_write(self.position, index, subindex, data)
    }

    /// The indices of the objects in one of the object lists (SDO information).
    pub fn sdo_object_list(&mut self, list_type: OdListType) -> Result<Vec<u16>> {
        self.master.sdo_object_list(self.position, list_type)
    }

    /// The description of object `index` (SDO information).
    pub fn sdo_object_description(&mut self, index: u16) -> Result<ObjectInfo> {
        self.master.sdo_object_description(self.position, index)
    }

    /// The description of entry `index:subindex` (SDO information).
    pub fn sdo_entry_description(&mut self, index: u16, subindex: u8) -> Result<EntryInfo> {
        self.master.sdo_entry_description(self.position, index, subindex)
    }

    /// Sends one mailbox message (header included), waiting up to `timeout` for SM0 to be free;
    /// the message gets the next counter value.
    pub fn mailbox_send(&mut self, message: &mut [u8], timeout: Duration) -> Result<()> {
        self.master.mailbox_send(self.position, message, timeout)
    }

    /// Waits up to `timeout` for the next mailbox message that is not an emergency.
    pub fn mailbox_receive(&mut self, timeout: Duration) -> Result<Vec<u8>> {
        self.master.mailbox_receive(self.position, timeout)
    }

    /// Takes the counter for the next mailbox message (1..=7), for a caller that writes SM0
    /// itself with [`mailbox_try_send`](Self::mailbox_try_send).
    pub fn mailbox_take_counter(&mut self) -> Result<u8> {
        self.master.mailbox_take_counter(self.position)
    }

    /// One attempt to write `buffer` (exactly SM0's length) into SM0, for a cycle thread that
    /// must not wait: `true` when the slave took it.
    pub fn mailbox_try_send(&mut self, buffer: &mut [u8]) -> Result<bool> {
        self.master.mailbox_try_send(self.position, buffer)
    }

    /// One read of SM1 into `buffer` (exactly SM1's length), for a cycle thread that saw SM1
    /// full: `true` when a message was read.
    pub fn mailbox_try_read(&mut self, buffer: &mut [u8]) -> Result<bool> {
        self.master.mailbox_try_read(self.position, buffer)
    }

    /// One frame towards the repeat request a lost read of SM1 left to make: `true` when a
    /// frame was spent on it, `false` when none is left to make.
    pub fn mailbox_try_repeat(&mut self) -> Result<bool> {
        self.master.mailbox_try_repeat(self.position)
    }

    /// Gives this slave its IP parameters (EoE Set IP Parameter) and waits for its response.
    pub fn eoe_set_ip(&mut self, parameters: &crate::ethercat::eoe::IpParameters) -> Result<()> {
        self.master.eoe_set_ip(self.position, parameters)
    }

    /// Sends one Ethernet frame to this slave's IP stack through EoE.
    pub fn eoe_send(&mut self, frame: &[u8]) -> Result<()> {
        self.master.eoe_send(self.position, frame)
    }

    /// The next Ethernet frame this slave's IP stack sent, waiting up to `timeout`.
    pub fn eoe_receive(&mut self, timeout: Duration) -> Result<Option<Vec<u8>>> {
        self.master.eoe_receive(self.position, timeout)
    }

    /// Writes `data` as the file `name` (FoE); `progress(sent, total)` after each packet.
    pub fn foe_write(
        &mut self,
        name: &str,
        password: u32,
        data: &[u8],
        progress: &mut dyn FnMut(usize, usize),
    ) -> Result<()> {
        self.master.foe_write(self.position, name, password, data, progress)
    }

    /// Reads the file `name` (FoE); `progress(received)` after each packet.
    pub fn foe_read(&mut self, name: &str, password: u32, progress: &mut dyn FnMut(usize)) -> Result<Vec<u8>> {
        self.master.foe_read(self.position, name, password, progress)
    }

    /// Takes the emergency messages received from this slave.
    pub fn take_emergencies(&mut self) -> Result<Vec<Emergency>> {
        self.master.take_emergencies(self.position)
    }

    /// Gives this slave (in PreOp) `process_data`, written over CoE where it says so; the
    /// slave's profile checks it against the slave's rules first.
    pub fn configure_process_data(&mut self, process_data: ProcessData) -> Result<()> {
        self.master.configure_process_data(self.position, process_data)
    }

    /// This slave's outputs as they go out in the next cycle, from bit 0 of the first byte (a
    /// slave of a few bits shares its byte in the image with others).
    pub fn outputs(&self) -> Result<Vec<u8>> {
        self.master.outputs(self.position)
    }

    /// Sets this slave's outputs; `data` must have their exact length, from bit 0 of the first
    /// byte.
    pub fn set_outputs(&mut self, data: &[u8]) -> Result<()> {
        self.master.set_outputs(self.position, data)
    }

    /// This slave's inputs from the last good cycle, from bit 0 of the first byte.
    pub fn inputs(&self) -> Result<Vec<u8>> {
        self.master.inputs(self.position)
    }
}
