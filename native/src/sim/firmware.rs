//! What a slave's processor does at its ESC's PDI side, the same in every virtual slave that
//! has one (the AKD, the EL3102): AL status written from its AL machine, the sync managers it
//! opens and closes with the AL state, the master's mailbox message taken out of SM0, replies
//! put into SM1 when the master emptied it, and a reply repeated on the master's request.

use crate::ethercat::al::AlState;
use crate::ethercat::mailbox::HEADER_LEN;
use crate::ethercat::registers::{self as reg, sm_reg};
use crate::sim::al_machine::AlMachine;
use crate::sim::esc::Esc;
use crate::sim::mailbox_server::MailboxServer;
use crate::sim::od::ObjectDictionary;
use crate::sim::sync_manager::{self, SyncManager, MIN_MAILBOX_SIZE, SM_COUNT};

/// Writes the AL machine's status and status code into the ESC's registers.
pub fn write_al_status(esc: &mut Esc, al: &AlMachine) {
    let (status, status_code) = (al.status(), al.status_code());
    let memory = esc.memory_mut();
    memory[reg::AL_STATUS as usize..reg::AL_STATUS as usize + 2].copy_from_slice(&status.to_le_bytes());
    memory[reg::AL_STATUS_CODE as usize..reg::AL_STATUS_CODE as usize + 2].copy_from_slice(&status_code.to_le_bytes());
}

/// Deactivates every sync manager from the PDI side, as the firmware holds them at power-up.
pub fn deactivate_sync_managers(esc: &mut Esc) {
    for n in 0..SM_COUNT {
        sync_manager::set_pdi_deactivated(esc.memory_mut(), n, true);
    }
}

/// Opens the sync managers state `to` runs (the mailbox from PreOp, process data from SafeOp)
/// and closes the others; leaving the mailbox states clears the mailbox's status and `mailbox`.
pub fn enter_state(esc: &mut Esc, mailbox: &mut MailboxServer, to: AlState) {
    let memory = esc.memory_mut();
    let mailbox_on = to != AlState::Init && to != AlState::Bootstrap;
    let process_data_on = to >= AlState::SafeOp && to != AlState::Bootstrap;
    for n in 0..2 {
        sync_manager::set_pdi_deactivated(memory, n, !mailbox_on);
    }
    for n in 2..4 {
        sync_manager::set_pdi_deactivated(memory, n, !process_data_on);
    }
    if !mailbox_on {
        mailbox.reset();
        for n in 0..2 {
            memory[sync_manager::status_address(n)] = 0;
        }
    }
}

/// The size replies are made for: SM1 as the master set it, but never less than the smallest
/// mailbox a slave accepts at Init→PreOp (a master may shrink SM1 afterwards, even below a
/// reply's headers, and then reads what fits of each reply).
pub fn reply_size(esc: &Esc) -> usize {
    usize::from(SyncManager::read(esc.memory(), 1).length.max(MIN_MAILBOX_SIZE))
}

/// Takes the master's message out of the mailbox-out buffer and hands it to `mailbox`, which
/// answers it from `od` as a slave in `state` at bus time `now_ns`.
pub fn take_request(
    esc: &mut Esc,
    mailbox: &mut MailboxServer,
    od: &mut ObjectDictionary,
    state: AlState,
    now_ns: u64,
) {
    let out = SyncManager::read(esc.memory(), 0);
    let size = reply_size(esc);
    let memory = esc.memory();
    let buffer = &memory[out.range_within(memory.len())];
    let announced = buffer.get(..2).map_or(0, |b| u16::from_le_bytes([b[0], b[1]]) as usize);
    let message = buffer[..(HEADER_LEN + announced).min(buffer.len())].to_vec();
    sync_manager::mark_read(esc.memory_mut(), 0);
    mailbox.handle(&message, od, state, size, usize::from(out.length), now_ns);
}

/// Puts the next queued reply into the mailbox-in buffer when the master emptied it.
pub fn offer_reply(esc: &mut Esc, mailbox: &mut MailboxServer) {
    let sm = SyncManager::read(esc.memory(), 1);
    if !sm.active() || sm.full() {
        return;
    }
    if let Some(reply) = mailbox.next_reply() {
        let memory = esc.memory_mut();
        let buffer = sm.range_within(memory.len());
        let n = reply.len().min(buffer.len());
        memory[buffer.start..buffer.start + n].copy_from_slice(&reply[..n]);
        sync_manager::mark_written(memory, 1);
    }
}

/// The master toggled the repeat request: the reply it read last goes into the buffer again
/// (one put in since, unread, is queued after it) and the repeat acknowledge follows the request
/// bit.
pub fn repeat_reply(esc: &mut Esc, mailbox: &mut MailboxServer) {
    let sm = SyncManager::read(esc.memory(), 1);
    let memory = esc.memory_mut();
    if let Some(reply) = mailbox.repeat(sm.full()) {
        let buffer = sm.range_within(memory.len());
        let n = reply.len().min(buffer.len());
        memory[buffer.start..buffer.start + n].copy_from_slice(&reply[..n]);
        sync_manager::mark_written(memory, 1);
    }
    let ack = memory[reg::sm(1) as usize + sm_reg::ACTIVATE] & sm_reg::ACTIVATE_REPEAT;
    let pdi = &mut memory[sync_manager::pdi_control_address(1)];
    *pdi = (*pdi & !sm_reg::PDI_REPEAT_ACK) | ack;
}
