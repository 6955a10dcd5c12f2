//! The master against the in-process virtual AKD: scan, AL states, SDO, SDO information,
//! every fixed mapping and a flexible one, cyclic exchange with its working counter, DC, and
//! the counting of lost frames and wrong working counters.

use std::sync::atomic::{AtomicBool, AtomicU32, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use akd_native::drive::akd::{AkdLine, AkdSlave};
use akd_native::drive::identity;
use akd_native::drive::pdo;
use akd_native::drive::pdo::Mapping;
use akd_native::error::{Error, Result};
use akd_native::ethercat::al::AlState;
use akd_native::ethercat::coe::{data_type, write_sdo_request, ObjectCode, OdListType, SdoAbortCode, SdoRequest};
use akd_native::ethercat::frame::{self, Command};
use akd_native::ethercat::link::Link;
use akd_native::ethercat::master::Master;
use akd_native::ethercat::pdo::{bit_len, layout, Direction, PdoEntry};
use akd_native::sim::control::{Change, SimControl};
use akd_native::sim::in_process::InProcess;
use akd_native::sim::{Timing, VirtualBus};

const STEP: Duration = Duration::from_secs(5);

fn master(count: usize) -> Master {
    let mut m = Master::new(Box::new(InProcess::new(count)), Duration::from_millis(100));
    assert_eq!(m.scan().unwrap(), count);
    m
}

/// Writes AL control behind the master's state handling. The AKD's AL control works like a
/// mailbox (its ESC refuses a write until the firmware took the last one), so retry a while.
fn raw_al_request(m: &mut Master, position: u16, state: AlState) {
    let deadline = std::time::Instant::now() + STEP;
    while let Err(e) = m.slave_mut(position).unwrap().write_register(0x0120, &(state as u16).to_le_bytes()) {
        assert!(std::time::Instant::now() < deadline, "{e}");
    }
}

/// Byte offset of `index` in a mapping's entries.
fn offset_of(entries: &[PdoEntry], index: u16) -> Option<usize> {
    layout(entries.iter().copied()).find(|(_, e)| e.index == index).map(|(at, _)| at)
}

#[test]
fn scan_finds_the_virtual_akds_with_the_real_identity() {
    for count in [1, 3] {
        let mut m = master(count);
        for position in 0..count as u16 {
            let slave = m.slave(position).unwrap().clone();
            assert_eq!(slave.station_address, 0x1001 + position);
            let id = slave.sii.identity();
            assert_eq!((id.vendor_id, id.product_code, id.revision), (0x6A, 0x0041_4B44, 2));
            assert_eq!(slave.sii.name(), Some("AKD EtherCAT Drive (CoE)"));
            assert_eq!(identity::model(&slave.sii).as_deref(), Some("AKD-P00606-NBCC-E000"));
            assert_eq!(identity::firmware(&slave.sii).as_deref(), Some("01-20-00-003"));
            let mb = slave.mailbox.as_ref().expect("the AKD has a mailbox");
            assert_eq!((mb.out_start, mb.out_len, mb.in_start, mb.in_len), (0x1800, 0x400, 0x1C00, 0x400));
            assert!(mb.has_coe());
            assert!(slave.has_dc());
            let status = m.slave_mut(position).unwrap().al_status().unwrap();
            assert_eq!((status.state(), status.code), (Some(AlState::Init), 0));
        }
    }
}

#[test]
fn esc_information_and_dl_control_read_as_the_real_drives() {
    let mut m = master(2);
    for position in 0..2 {
        let mut slave = m.slave_mut(position).unwrap();
        // Type 0x04, revision 0x02, build 0x0043, 3 FMMUs, 4 SMs, 4 KiB, ports 0x0F, features 0x0184.
        assert_eq!(
            slave.read_register(0x0000, 10).unwrap(),
            [0x04, 0x02, 0x43, 0x00, 0x03, 0x04, 0x04, 0x0F, 0x84, 0x01]
        );
        assert_eq!(slave.read_register(0x0102, 1).unwrap(), [0x07]);
    }
    // Three FMMUs are enough: the master maps outputs and inputs with two of them.
    m.request_state(AlState::Op, STEP).unwrap();
    assert_eq!(m.exchange().unwrap(), 6);
}

/// Time from the request of PreOp until the master sees it, against a drive whose firmware
/// takes `first_init_to_preop_ns` for its first since power-up.
fn init_to_preop_duration(first_init_to_preop_ns: u64) -> Duration {
    let timing = Timing { first_init_to_preop_ns, ..Timing::REAL_DRIVE };
    let link = InProcess::with_bus(VirtualBus::with_timing(1, timing));
    let mut m = Master::new(Box::new(link), Duration::from_millis(100));
    m.scan().unwrap();
    let start = std::time::Instant::now();
    m.request_state(AlState::PreOp, STEP).unwrap();
    let took = start.elapsed();
    m.request_state(AlState::Op, STEP).unwrap();
    assert_eq!(m.exchange().unwrap(), 3);
    took
}

#[test]
fn init_to_preop_takes_the_firmwares_time_and_the_master_waits_for_it() {
    // The real drive's pace under TwinCAT (the default: 17.5 ms) and that of the drive in the
    // SOEM capture (4.2-6.2 ms); the bound leaves room for a loaded machine.
    for (firmware_ns, bound) in [(Timing::REAL_DRIVE.first_init_to_preop_ns, 100), (4_500_000, 50)] {
        let took = init_to_preop_duration(firmware_ns);
        assert!(took >= Duration::from_nanos(firmware_ns), "{took:?} for {firmware_ns} ns");
        assert!(took < Duration::from_millis(bound), "{took:?} for {firmware_ns} ns");
    }
}

/// The master knows no AKD: a drive given no process data gets what its SII assigns, which
/// for the AKD is the drive profile's default fixed mapping, assigned over CoE.
#[test]
fn the_master_configures_a_drive_at_the_real_drives_pace_within_its_time_outs() {
    // The first Init→PreOp after power-up takes 17.5 ms, the first mailbox reply 30 ms, the
    // later ones 4.5 ms and 1 ms; the master's time-outs hold them all.
    let link = InProcess::with_bus(VirtualBus::with_timing(1, Timing::REAL_DRIVE));
    let mut m = Master::new(Box::new(link), Duration::from_millis(100));
    m.scan().unwrap();
    m.request_state(AlState::PreOp, STEP).unwrap();
    let start = std::time::Instant::now();
    assert_eq!(m.slave_mut(0).unwrap().sdo_read(0x1018, 1).unwrap(), 0x6Au32.to_le_bytes());
    assert!(start.elapsed() >= Duration::from_millis(30), "first reply after {:?}", start.elapsed());
    m.request_state(AlState::Op, STEP).unwrap();
    assert_eq!(m.exchange().unwrap(), 3);
    m.request_state(AlState::Init, STEP).unwrap();
    let start = std::time::Instant::now();
    m.request_state(AlState::PreOp, STEP).unwrap();
    let took = start.elapsed();
    assert!(took >= Duration::from_micros(4_500), "{took:?}");
    m.request_state(AlState::Op, STEP).unwrap();
    assert_eq!(m.exchange().unwrap(), 3);
}

#[test]
fn reaches_op_with_the_default_mapping_and_three_wkc_per_slave() {
    let mut m = master(2);
    m.request_state(AlState::Op, STEP).unwrap();
    let (rx, tx) = (Mapping::Fixed(pdo::DEFAULT_FIXED.0), Mapping::Fixed(pdo::DEFAULT_FIXED.1));
    let profiles = Mapping::process_data(&rx, &tx).unwrap();
    assert_eq!(m.slave_mut(0).unwrap().info().process_data.as_ref(), Some(&profiles));
    for position in 0..2 {
        assert_eq!(m.slave_mut(position).unwrap().al_status().unwrap().state(), Some(AlState::Op));
        assert_eq!(m.slave_mut(position).unwrap().outputs().unwrap().len(), 6);
        assert_eq!(m.slave_mut(position).unwrap().inputs().unwrap().len(), 6);
    }
    assert_eq!(m.expected_wkc().unwrap(), 6);
    for _ in 0..10 {
        assert_eq!(m.exchange().unwrap(), 6);
    }
    assert_eq!(m.stats().wkc_errors, 0);
    m.request_state(AlState::Init, STEP).unwrap();
    assert_eq!(m.slave_mut(1).unwrap().al_status().unwrap().state(), Some(AlState::Init));
}

/// Outputs written by the LRW land in the drive (its controlword object follows them) and
/// inputs come from the drive (its statusword object is what the LRW brought back).
fn check_process_data(m: &mut Master, position: u16, rx: &[PdoEntry], tx: &[PdoEntry]) {
    let controlword = offset_of(rx, 0x6040).expect("every fixed RxPDO carries the controlword");
    let mut outputs = m.slave_mut(position).unwrap().outputs().unwrap().to_vec();
    outputs[controlword..controlword + 2].copy_from_slice(&0x0006u16.to_le_bytes());
    m.slave_mut(position).unwrap().set_outputs(&outputs).unwrap();
    assert_eq!(m.exchange().unwrap(), m.expected_wkc().unwrap());
    assert_eq!(m.slave_mut(position).unwrap().sdo_read(0x6040, 0).unwrap(), 0x0006u16.to_le_bytes());
    if let Some(statusword) = offset_of(tx, 0x6041) {
        assert_eq!(m.exchange().unwrap(), m.expected_wkc().unwrap());
        let from_sdo = m.slave_mut(position).unwrap().sdo_read(0x6041, 0).unwrap();
        assert_eq!(&m.slave_mut(position).unwrap().inputs().unwrap()[statusword..statusword + 2], &from_sdo[..]);
    }
}

#[test]
fn every_fixed_mapping_exchanges_process_data() {
    let rxs = pdo::FIXED.iter().filter(|p| p.direction == Direction::Rx);
    let txs = pdo::FIXED.iter().filter(|p| p.direction == Direction::Tx);
    // Every RxPDO with the default TxPDO and every TxPDO with the default RxPDO.
    let pairs: Vec<(u16, u16)> =
        rxs.map(|r| (r.index, pdo::DEFAULT_FIXED.1)).chain(txs.map(|t| (pdo::DEFAULT_FIXED.0, t.index))).collect();
    for (rx, tx) in pairs {
        let mut m = master(1);
        m.request_state(AlState::PreOp, STEP).unwrap();
        m.slave_mut(0).unwrap().configure_pdo(Mapping::Fixed(rx), Mapping::Fixed(tx)).unwrap();
        assert_eq!(m.slave_mut(0).unwrap().sdo_read(0x1C12, 1).unwrap(), rx.to_le_bytes(), "0x1C12:01 for {rx:04X}");
        assert_eq!(m.slave_mut(0).unwrap().sdo_read(0x1C13, 1).unwrap(), tx.to_le_bytes(), "0x1C13:01 for {tx:04X}");
        m.request_state(AlState::Op, STEP).unwrap_or_else(|e| panic!("0x{rx:04X}/0x{tx:04X}: {e}"));
        let (rx_entries, tx_entries) = (pdo::fixed(rx).unwrap().entries, pdo::fixed(tx).unwrap().entries);
        assert_eq!(m.slave_mut(0).unwrap().outputs().unwrap().len(), bit_len(rx_entries) / 8);
        assert_eq!(m.slave_mut(0).unwrap().inputs().unwrap().len(), bit_len(tx_entries) / 8);
        assert_eq!(m.expected_wkc().unwrap(), 3);
        check_process_data(&mut m, 0, rx_entries, tx_entries);
    }
}

#[test]
fn flexible_mapping_is_written_in_the_akds_order_and_exchanged() {
    let mut m = master(1);
    m.request_state(AlState::PreOp, STEP).unwrap();
    let rx = vec![vec![PdoEntry::new(0x6040, 0, 16), PdoEntry::new(0x607A, 0, 32)]];
    let tx = vec![vec![PdoEntry::new(0x6041, 0, 16), PdoEntry::new(0x6064, 0, 32)], vec![PdoEntry::new(0x606C, 0, 32)]];
    m.slave_mut(0).unwrap().configure_pdo(Mapping::Flexible(rx.clone()), Mapping::Flexible(tx.clone())).unwrap();
    assert_eq!(m.slave_mut(0).unwrap().sdo_read(0x1C12, 0).unwrap(), [1]);
    assert_eq!(m.slave_mut(0).unwrap().sdo_read(0x1C12, 1).unwrap(), 0x1600u16.to_le_bytes());
    assert_eq!(m.slave_mut(0).unwrap().sdo_read(0x1C13, 0).unwrap(), [2]);
    assert_eq!(m.slave_mut(0).unwrap().sdo_read(0x1C13, 2).unwrap(), 0x1A01u16.to_le_bytes());
    assert_eq!(m.slave_mut(0).unwrap().sdo_read(0x1600, 0).unwrap(), [2]);
    assert_eq!(m.slave_mut(0).unwrap().sdo_read(0x1600, 2).unwrap(), 0x607A_0020u32.to_le_bytes());
    m.request_state(AlState::Op, STEP).unwrap();
    assert_eq!(
        (m.slave_mut(0).unwrap().outputs().unwrap().len(), m.slave_mut(0).unwrap().inputs().unwrap().len()),
        (6, 10)
    );
    let rx: Vec<PdoEntry> = rx.concat();
    let tx: Vec<PdoEntry> = tx.concat();
    check_process_data(&mut m, 0, &rx, &tx);
}

#[test]
fn a_mapping_the_akd_refuses_is_refused_before_anything_is_written() {
    let mut m = master(1);
    m.request_state(AlState::PreOp, STEP).unwrap();
    let before = m.slave_mut(0).unwrap().sdo_read(0x1C12, 0).unwrap();
    let frames = m.stats().frames;
    // The real drive's own power-up mapping: 17 bytes, odd.
    let odd = Mapping::Flexible(pdo::POWER_UP_RX.iter().map(|p| p.to_vec()).collect());
    let err = m.slave_mut(0).unwrap().configure_pdo(odd, Mapping::Fixed(0x1B01)).unwrap_err();
    assert!(matches!(&err, Error::Pdo(reason) if reason.to_string().contains("odd")), "{err}");
    let err = m.slave_mut(0).unwrap().configure_pdo(Mapping::Fixed(0x1B01), Mapping::Fixed(0x1701)).unwrap_err();
    assert!(matches!(&err, Error::Pdo(reason) if reason.to_string().contains("0x1701")), "{err}");
    assert_eq!(m.stats().frames, frames, "nothing was sent");
    assert_eq!(m.slave_mut(0).unwrap().sdo_read(0x1C12, 0).unwrap(), before);
}

#[test]
fn sdo_round_trips_of_every_size() {
    let mut m = master(2);
    m.request_state(AlState::PreOp, STEP).unwrap();
    for position in 0..2 {
        // Expedited: 1, 2 and 4 bytes.
        m.slave_mut(position).unwrap().sdo_write(0x6060, 0, &[8]).unwrap();
        assert_eq!(m.slave_mut(position).unwrap().sdo_read(0x6060, 0).unwrap(), [8]);
        m.slave_mut(position).unwrap().sdo_write(0x6040, 0, &0x000Fu16.to_le_bytes()).unwrap();
        assert_eq!(m.slave_mut(position).unwrap().sdo_read(0x6040, 0).unwrap(), 0x000Fu16.to_le_bytes());
        let target = -123_456i32 - position as i32;
        m.slave_mut(position).unwrap().sdo_write(0x607A, 0, &target.to_le_bytes()).unwrap();
        assert_eq!(m.slave_mut(position).unwrap().sdo_read(0x607A, 0).unwrap(), target.to_le_bytes());
        // Normal: strings longer than 4 bytes, which the SII also names.
        let sii = m.slave(position).unwrap().sii.clone();
        assert_eq!(
            m.slave_mut(position).unwrap().sdo_read(0x1009, 0).unwrap(),
            identity::model(&sii).unwrap().as_bytes()
        );
        assert_eq!(
            m.slave_mut(position).unwrap().sdo_read(0x100A, 0).unwrap(),
            identity::firmware(&sii).unwrap().as_bytes()
        );
        // The identity object agrees with the SII.
        assert_eq!(m.slave_mut(position).unwrap().sdo_read(0x1018, 1).unwrap(), 0x6Au32.to_le_bytes());
        assert_eq!(m.slave_mut(position).unwrap().sdo_read(0x1018, 2).unwrap(), 0x0041_4B44u32.to_le_bytes());
    }
}

#[test]
fn drives_on_one_line_report_distinct_serials_in_the_sii_and_0x1018() {
    let mut m = master(3);
    m.request_state(AlState::PreOp, STEP).unwrap();
    let mut serials = Vec::new();
    for position in 0..3 {
        let sii_serial = m.slave(position).unwrap().sii.identity().serial_number;
        let od_serial = m.slave_mut(position).unwrap().sdo_read(0x1018, 4).unwrap();
        assert_eq!(od_serial, sii_serial.to_le_bytes(), "drive {position}");
        serials.push(sii_serial);
    }
    // The first drive keeps the real drive's serial, the others count up from it.
    assert_eq!(serials, [0x9983_0093, 0x9983_0094, 0x9983_0095]);
    // The same on the next run.
    let again = master(3);
    let again: Vec<_> = (0..3).map(|p| again.slave(p).unwrap().sii.identity().serial_number).collect();
    assert_eq!(again, serials);
}

#[test]
fn sdo_aborts_come_back_by_name() {
    let mut m = master(1);
    m.request_state(AlState::PreOp, STEP).unwrap();
    match m.slave_mut(0).unwrap().sdo_read(0x1234, 0).unwrap_err() {
        Error::SdoAbort { index: 0x1234, subindex: 0, code, code_name } => {
            assert_eq!(code, SdoAbortCode::NO_SUCH_OBJECT.0);
            assert_eq!(code_name, "object does not exist in the object dictionary");
        }
        other => panic!("{other}"),
    }
    match m.slave_mut(0).unwrap().sdo_write(0x1018, 1, &[1, 2, 3, 4]).unwrap_err() {
        Error::SdoAbort { code, code_name, .. } => {
            assert_eq!(code, SdoAbortCode::READ_ONLY.0);
            assert_eq!(code_name, "attempt to write a read-only object");
        }
        other => panic!("{other}"),
    }
    // The mailbox still works after aborts.
    assert_eq!(m.slave_mut(0).unwrap().sdo_read(0x1018, 1).unwrap(), 0x6Au32.to_le_bytes());
}

#[test]
fn sdo_information_lists_and_describes_objects() {
    let mut m = master(1);
    m.request_state(AlState::PreOp, STEP).unwrap();
    let list = m.slave_mut(0).unwrap().sdo_object_list(OdListType::All).unwrap();
    for index in [0x1000, 0x1018, 0x1C12, 0x6040, 0x6041] {
        assert!(list.contains(&index), "0x{index:04X} missing from {list:04X?}");
    }
    let identity = m.slave_mut(0).unwrap().sdo_object_description(0x1018).unwrap();
    assert_eq!(identity.index, 0x1018);
    assert_eq!(identity.object_code, ObjectCode::Record);
    assert!(identity.max_subindex >= 4);
    let statusword = m.slave_mut(0).unwrap().sdo_entry_description(0x6041, 0).unwrap();
    assert_eq!((statusword.data_type, statusword.bit_length), (data_type::UNSIGNED16, 16));
    assert!(!statusword.name.is_empty());
    match m.slave_mut(0).unwrap().sdo_object_description(0x1234).unwrap_err() {
        Error::SdoAbort { code, .. } => assert_eq!(code, SdoAbortCode::NO_SUCH_OBJECT.0),
        other => panic!("{other}"),
    }
}

#[test]
fn a_refused_state_change_is_reported_by_name_and_acknowledged() {
    let mut m = master(1);
    // Init -> Op directly: the AKD refuses with 0x0011.
    raw_al_request(&mut m, 0, AlState::Op);
    let deadline = std::time::Instant::now() + STEP;
    let status = loop {
        let s = m.slave_mut(0).unwrap().al_status().unwrap();
        if s.error() || std::time::Instant::now() > deadline {
            break s;
        }
    };
    assert!(status.error(), "AL status 0x{:04X}", status.status);
    assert_eq!((status.state(), status.code), (Some(AlState::Init), 0x0011));
    assert_eq!(status.code_name(), "invalid requested state change");
    // request_state acknowledges the error and goes on.
    m.request_state(AlState::PreOp, STEP).unwrap();
    // PreOp -> Bootstrap: refused too, and request_state says so by name.
    match m.slave_mut(0).unwrap().request_state(AlState::Bootstrap, STEP).unwrap_err() {
        Error::AlState { slave: 0, requested: "Bootstrap", code: 0x0011, code_name, .. } => {
            assert_eq!(code_name, "invalid requested state change")
        }
        other => panic!("{other}"),
    }
    assert!(!m.slave_mut(0).unwrap().al_status().unwrap().error(), "the error was acknowledged");
}

#[test]
fn a_wrong_working_counter_is_counted_and_raised() {
    let mut m = master(2);
    m.request_state(AlState::Op, STEP).unwrap();
    assert_eq!(m.exchange().unwrap(), 6);
    // Slave 1 drops to Init behind the master's back: its process data stop.
    raw_al_request(&mut m, 1, AlState::Init);
    let deadline = std::time::Instant::now() + STEP;
    while m.slave_mut(1).unwrap().al_status().unwrap().state() != Some(AlState::Init) {
        assert!(std::time::Instant::now() < deadline);
    }
    match m.exchange().unwrap_err() {
        Error::WorkingCounter { expected: 6, got, .. } => assert_eq!(got, 3),
        other => panic!("{other}"),
    }
    assert_eq!(m.stats().wkc_errors, 1);
}

/// A link that loses the return of chosen frames after the slaves have served them, as a
/// broken cable on the way back would.
struct Lossy {
    inner: InProcess,
    /// Returns of LRW frames still to lose.
    lose_lrw: Arc<AtomicU32>,
    /// Returns of reads of the mailbox-in buffer (0x1C00) still to lose.
    lose_mailbox_reads: Arc<AtomicU32>,
    /// Returns of writes to the mailbox-out buffer (0x1800) still to lose.
    lose_mailbox_writes: Arc<AtomicU32>,
}

impl Link for Lossy {
    fn send(&mut self, tx: &[u8]) -> Result<()> {
        self.inner.send(tx)?;
        let first = frame::parse(tx)?.next().expect("one datagram")?.header;
        let counter = match (first.command, first.ado) {
            (Command::Lrw, _) => &self.lose_lrw,
            (Command::Fprd, 0x1C00) => &self.lose_mailbox_reads,
            (Command::Fpwr, 0x1800) => &self.lose_mailbox_writes,
            _ => return Ok(()),
        };
        if counter.fetch_update(Ordering::SeqCst, Ordering::SeqCst, |c| c.checked_sub(1)).is_ok() {
            // Served, and its return lost on the way back.
            self.inner.receive(&mut [0; frame::MAX_PAYLOAD_LEN], Instant::now())?;
        }
        Ok(())
    }

    fn receive(&mut self, rx: &mut [u8], deadline: Instant) -> Result<Option<usize>> {
        self.inner.receive(rx, deadline)
    }

    fn describe(&self) -> String {
        "lossy sim".into()
    }
}

#[test]
fn lost_frames_are_counted_and_a_lost_mailbox_reply_is_fetched_again() {
    let lose_lrw = Arc::new(AtomicU32::new(0));
    let lose_mailbox_reads = Arc::new(AtomicU32::new(0));
    let lose_mailbox_writes = Arc::new(AtomicU32::new(0));
    let link = Lossy {
        inner: InProcess::new(1),
        lose_lrw: lose_lrw.clone(),
        lose_mailbox_reads: lose_mailbox_reads.clone(),
        lose_mailbox_writes: lose_mailbox_writes.clone(),
    };
    let mut m = Master::new(Box::new(link), Duration::from_millis(100));
    m.scan().unwrap();
    m.request_state(AlState::Op, STEP).unwrap();
    let before = m.stats();
    lose_lrw.store(1, Ordering::SeqCst);
    assert!(matches!(m.exchange().unwrap_err(), Error::Timeout { .. }));
    assert_eq!(m.exchange().unwrap(), 3);
    assert_eq!(m.stats().lost_frames, before.lost_frames + 1);
    // The reply to an SDO upload is lost on its way back; the repeat request brings it again.
    lose_mailbox_reads.store(1, Ordering::SeqCst);
    assert_eq!(m.slave_mut(0).unwrap().sdo_read(0x1018, 1).unwrap(), 0x6Au32.to_le_bytes());
    assert_eq!(m.stats().mailbox_repeats, before.mailbox_repeats + 1);
    assert_eq!(m.stats().lost_frames, before.lost_frames + 2);
    // A request that reached the drive but whose frame did not come back is written again
    // with the same counter; the answer is still the one asked for, and the next SDO works.
    lose_mailbox_writes.store(1, Ordering::SeqCst);
    assert_eq!(m.slave_mut(0).unwrap().sdo_read(0x1018, 2).unwrap(), 0x0041_4B44u32.to_le_bytes());
    // The drive takes the second write for a repetition (same counter) and does not answer it
    // again: once its firmware had the time to handle it, SM1 stays empty.
    std::thread::sleep(Duration::from_millis(10));
    let sm1_status = m.slave_mut(0).unwrap().read_register(0x080D, 1).unwrap()[0];
    assert_eq!(sm1_status & 0x08, 0, "a second reply waits in SM1 (status 0x{sm1_status:02X})");
    assert_eq!(m.slave_mut(0).unwrap().sdo_read(0x1018, 3).unwrap(), 2u32.to_le_bytes());
    assert_eq!(m.stats().lost_frames, before.lost_frames + 3);
}

/// A master in PreOp on one virtual AKD behind a link that loses as many reads of SM1 as the
/// counter it gives says.
fn in_preop_losing_mailbox_reads() -> (Master, Arc<AtomicU32>) {
    let lose_mailbox_reads = Arc::new(AtomicU32::new(0));
    let link = Lossy {
        inner: InProcess::new(1),
        lose_lrw: Arc::default(),
        lose_mailbox_reads: lose_mailbox_reads.clone(),
        lose_mailbox_writes: Arc::default(),
    };
    let mut m = Master::new(Box::new(link), Duration::from_millis(100));
    m.scan().unwrap();
    m.request_state(AlState::PreOp, STEP).unwrap();
    (m, lose_mailbox_reads)
}

/// A read of SM1 whose return is lost leaves the master unsure whether it emptied SM1, so it
/// asks for the reply again (SM1's repeat request); if the read had found SM1 already empty (a
/// cycle thread reads on the mailbox status of a frame sent before its last read), the drive puts
/// back the message the master took before. That copy is not taken a second time.
#[test]
fn a_message_a_repeat_request_brings_back_after_a_lost_read_of_an_empty_mailbox_is_not_taken_twice() {
    let (mut m, lose_mailbox_reads) = in_preop_losing_mailbox_reads();
    // The mailbox as a cycle thread uses it: an SDO upload written, its reply read once.
    let mut slave = m.slave_mut(0).unwrap();
    let mut request = [0u8; 0x400];
    let counter = slave.mailbox_take_counter().unwrap();
    let upload = SdoRequest::Upload { index: 0x1018, subindex: 1, complete_access: false };
    write_sdo_request(&mut request, counter, &upload);
    let deadline = Instant::now() + STEP;
    while !slave.mailbox_try_send(&mut request).unwrap() {
        assert!(Instant::now() < deadline, "SM0 never took the request");
    }
    let mut reply = [0u8; 0x400];
    while !slave.mailbox_try_read(&mut reply).unwrap() {
        assert!(Instant::now() < deadline, "no reply");
    }
    // SM1 is empty now; a read of it whose return is lost, and the repeat request that follows.
    lose_mailbox_reads.store(1, Ordering::SeqCst);
    assert!(!slave.mailbox_try_read(&mut [0u8; 0x400]).unwrap());
    while slave.mailbox_try_repeat().unwrap() {}
    // The drive put its last reply back into SM1: the one already taken.
    let until = Instant::now() + Duration::from_millis(50);
    while Instant::now() < until {
        let mut again = [0u8; 0x400];
        assert!(!slave.mailbox_try_read(&mut again).unwrap(), "the reply taken before was taken again");
    }
    let stats = m.stats();
    assert_eq!((stats.mailbox_repeats, stats.stale_mailbox_replies), (1, 1));
}

fn sm1_full(slave: &mut akd_native::ethercat::master::SlaveRef<'_>) -> bool {
    slave.read_register(0x080D, 1).unwrap()[0] & 0x08 != 0
}

/// A read of SM1 whose return is lost after it emptied SM1, and the drive's next reply put in
/// before the repeat request comes: the repeat brings back the reply whose read was lost, and the
/// next one follows it; neither is lost.
#[test]
fn a_repeat_request_brings_back_the_reply_read_last_and_the_next_one_after_it() {
    let (mut m, lose_mailbox_reads) = in_preop_losing_mailbox_reads();
    let mut slave = m.slave_mut(0).unwrap();
    let deadline = Instant::now() + STEP;
    // Two uploads written before either reply is read: the second reply waits in the drive.
    for subindex in [1, 2] {
        let mut request = [0u8; 0x400];
        let counter = slave.mailbox_take_counter().unwrap();
        write_sdo_request(
            &mut request,
            counter,
            &SdoRequest::Upload { index: 0x1018, subindex, complete_access: false },
        );
        while !slave.mailbox_try_send(&mut request).unwrap() {
            assert!(Instant::now() < deadline, "SM0 never took the request");
        }
    }
    while !sm1_full(&mut slave) {
        assert!(Instant::now() < deadline, "no reply");
    }
    // The first reply's read empties SM1 and its return is lost; the drive puts its second in.
    lose_mailbox_reads.store(1, Ordering::SeqCst);
    assert!(!slave.mailbox_try_read(&mut [0u8; 0x400]).unwrap());
    while !sm1_full(&mut slave) {
        assert!(Instant::now() < deadline, "the second reply never came");
    }
    while slave.mailbox_try_repeat().unwrap() {}
    // The replies to subindex 1 and 2, in their order, each once.
    let mut subindices = Vec::new();
    let until = Instant::now() + Duration::from_millis(100);
    while Instant::now() < until {
        let mut reply = [0u8; 0x400];
        if slave.mailbox_try_read(&mut reply).unwrap() {
            subindices.push(reply[11]);
        }
    }
    assert_eq!(subindices, [1, 2]);
}

#[test]
fn process_data_sent_now_is_taken_later_with_mailbox_frames_between() {
    let lose_lrw = Arc::new(AtomicU32::new(0));
    let link = Lossy {
        inner: InProcess::new(2),
        lose_lrw: lose_lrw.clone(),
        lose_mailbox_reads: Arc::default(),
        lose_mailbox_writes: Arc::default(),
    };
    let mut m = Master::new(Box::new(link), Duration::from_millis(100));
    m.scan().unwrap();
    m.request_state(AlState::Op, STEP).unwrap();
    let e = m.receive_process_data().unwrap_err().to_string();
    assert!(e.contains("no cyclic frame is on its way"), "{e}");
    // Drive 1's controlword, sent with the frame.
    let at = offset_of(pdo::fixed(0x1701).unwrap().entries, 0x6040).unwrap();
    let mut outputs = m.slave_mut(1).unwrap().outputs().unwrap().to_vec();
    outputs[at..at + 2].copy_from_slice(&0x0006u16.to_le_bytes());
    m.slave_mut(1).unwrap().set_outputs(&outputs).unwrap();
    let before = m.stats();
    m.send_process_data().unwrap();
    let e = m.send_process_data().unwrap_err().to_string();
    assert!(e.contains("already on its way") && e.contains("receive_process_data"), "{e}");
    // SDO transfers while the cyclic frame is on its way back: their exchanges meet its return
    // first and keep it for receive_process_data, where it is not lost.
    assert_eq!(m.slave_mut(0).unwrap().sdo_read(0x1018, 1).unwrap(), 0x6Au32.to_le_bytes());
    assert_eq!(m.slave_mut(1).unwrap().sdo_read(0x6040, 0).unwrap(), 0x0006u16.to_le_bytes());
    assert_eq!(m.receive_process_data().unwrap(), 6);
    // The inputs are the frame's: the position of the drive at rest, as its object says.
    let position = m.slave_mut(1).unwrap().sdo_read(0x6063, 0).unwrap();
    let at = offset_of(pdo::fixed(0x1B01).unwrap().entries, 0x6063).unwrap();
    assert_eq!(&m.slave_mut(1).unwrap().inputs().unwrap()[at..at + 4], &position[..]);
    assert_eq!((m.stats().lost_frames, m.stats().cycles), (before.lost_frames, before.cycles + 1));
    // A frame whose return does not come is lost once the time-out after its sending passed,
    // however late it is asked for; the next one goes out.
    lose_lrw.store(1, Ordering::SeqCst);
    m.send_process_data().unwrap();
    assert_eq!(m.slave_mut(0).unwrap().sdo_read(0x1018, 1).unwrap(), 0x6Au32.to_le_bytes());
    assert!(matches!(m.receive_process_data().unwrap_err(), Error::Timeout { .. }));
    assert_eq!(m.stats().lost_frames, before.lost_frames + 1);
    m.send_process_data().unwrap();
    assert_eq!(m.receive_process_data().unwrap(), 6);
}

#[test]
fn a_late_reply_to_a_request_given_up_is_not_taken_for_the_next_ones() {
    // A drive whose firmware takes 50 ms per mailbox message, asked with a 1 ms time-out.
    let slow = Timing { first_mailbox_ns: 50_000_000, mailbox_ns: 50_000_000, ..Timing::IMMEDIATE };
    let link = InProcess::with_bus(VirtualBus::with_timing(1, slow));
    let mut m = Master::new(Box::new(link), Duration::from_millis(100));
    m.scan().unwrap();
    m.request_state(AlState::PreOp, STEP).unwrap();
    m.set_mailbox_timeout(Duration::from_millis(1));
    assert!(matches!(m.slave_mut(0).unwrap().sdo_read(0x1018, 1).unwrap_err(), Error::Timeout { .. }));
    // With time enough, the next request waits for SM0, then gets the answer to the first
    // request first (another counter): it is dropped and counted, the right one comes next.
    m.set_mailbox_timeout(Duration::from_secs(1));
    assert_eq!(m.slave_mut(0).unwrap().sdo_read(0x1018, 2).unwrap(), 0x0041_4B44u32.to_le_bytes());
    assert_eq!(m.stats().stale_mailbox_replies, 1);
}

#[test]
fn distributed_clocks_run_sync0_and_the_drift_datagram_rides_in_the_cycle() {
    let mut m = master(2);
    m.request_state(AlState::PreOp, STEP).unwrap();
    m.configure_dc(1_000_000, 0).unwrap();
    for position in 0..2 {
        assert_eq!(m.slave_mut(position).unwrap().read_register(0x0981, 1).unwrap(), [0x03]);
        assert_eq!(m.slave_mut(position).unwrap().read_register(0x09A0, 4).unwrap(), 1_000_000u32.to_le_bytes());
        assert_eq!(m.slave_mut(position).unwrap().sdo_read(0x60C2, 1).unwrap(), [1]);
        assert_eq!(m.slave_mut(position).unwrap().sdo_read(0x60C2, 2).unwrap(), [(-3i8) as u8]);
    }
    m.request_state(AlState::Op, STEP).unwrap();
    assert_eq!(m.exchange().unwrap(), 6);
    let first = m.clock().unwrap().system_time;
    std::thread::sleep(Duration::from_millis(2));
    assert_eq!(m.exchange().unwrap(), 6);
    let second = m.clock().unwrap().system_time;
    assert!(second > first, "the reference clock runs: {first} then {second}");
    assert_eq!(m.stats().wkc_errors, 0);
}

#[test]
fn a_station_alias_names_one_drive_or_says_on_how_many_it_is() {
    let mut m = master(2);
    let alias = m.slaves()[1].alias;
    match m.slave_by_alias(alias).map(|s| s.position()) {
        // The virtual AKDs share the real drive's SII alias, so it names no one drive.
        Err(Error::AliasNotUnique { count: 2, .. }) => {}
        other => panic!("{:?}", other.map_err(|e| e.to_string())),
    }
    let unused = alias.wrapping_add(1);
    assert!(m.slave_by_alias(unused).err().unwrap().to_string().contains("is on 0 slave(s), not one"));
    let mut one = master(1);
    let mut drive = one.slave_by_alias(alias).unwrap();
    assert_eq!((drive.position(), drive.info().alias), (0, alias));
    assert_eq!(drive.al_status().unwrap().state(), Some(AlState::Init), "the handle talks to the drive");
}

#[test]
fn an_empty_position_is_named() {
    let mut m = master(1);
    match m.slave_mut(3).and_then(|mut s| s.sdo_read(0x1000, 0)).unwrap_err() {
        Error::NoSuchSlave { position: 3, count: 1 } => {}
        other => panic!("{other}"),
    }
    assert!(m.configure_dc(100_000, 0).is_err(), "below the AKD's 250 µs");
}

#[test]
fn clocks_read_the_masters_time_and_follow_the_reference() {
    let mut m = master(3);
    m.request_state(AlState::PreOp, STEP).unwrap();
    m.configure_dc(1_000_000, 0).unwrap();
    // The reference clock was set to the master's time (ns since 2000).
    let reference = u64::from_le_bytes(m.slave_mut(0).unwrap().read_register(0x0910, 8).unwrap().try_into().unwrap());
    let now = akd_native::ethercat::dc::system_time(
        std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).unwrap(),
    );
    assert!(now.abs_diff(reference) < 100_000_000, "reference clock {reference} vs master {now}");
    for position in 1..3 {
        // Delays grow along the line; the drift datagrams left each clock next to the reference.
        let delay = |m: &mut Master, p| {
            u32::from_le_bytes(m.slave_mut(p).unwrap().read_register(0x0928, 4).unwrap().try_into().unwrap())
        };
        assert!(delay(&mut m, position) > delay(&mut m, position - 1), "delay of slave {position}");
        let raw =
            u32::from_le_bytes(m.slave_mut(position).unwrap().read_register(0x092C, 4).unwrap().try_into().unwrap());
        let difference = akd_native::ethercat::dc::time_difference(raw);
        assert!(difference.abs() < 10_000, "slave {position} is {difference} ns off the reference");
    }
}

/// A link to a bus the test keeps a handle on, to act as the drive would between frames.
struct Shared(Arc<std::sync::Mutex<InProcess>>);

impl Link for Shared {
    fn send(&mut self, tx: &[u8]) -> Result<()> {
        self.0.lock().unwrap().send(tx)
    }

    fn receive(&mut self, rx: &mut [u8], deadline: Instant) -> Result<Option<usize>> {
        self.0.lock().unwrap().receive(rx, deadline)
    }

    fn describe(&self) -> String {
        "shared sim".into()
    }
}

#[test]
fn emergencies_are_queued_while_sdo_goes_on() {
    let bus = Arc::new(std::sync::Mutex::new(InProcess::new(1)));
    let mut m = Master::new(Box::new(Shared(bus.clone())), Duration::from_millis(100));
    m.scan().unwrap();
    m.request_state(AlState::PreOp, STEP).unwrap();
    let fault =
        akd_native::ethercat::coe::Emergency { error_code: 0x7380, error_register: 0x81, data: [1, 2, 3, 4, 5] };
    bus.lock().unwrap().bus_mut().slave_mut(0).emergency(&fault);
    assert_eq!(m.slave_mut(0).unwrap().sdo_read(0x1018, 2).unwrap(), 0x0041_4B44u32.to_le_bytes());
    assert_eq!(m.slave_mut(0).unwrap().take_emergencies().unwrap(), vec![fault]);
    assert_eq!(m.stats().emergencies, 1);
    assert!(m.slave_mut(0).unwrap().take_emergencies().unwrap().is_empty());
}

#[test]
fn several_drives_share_one_cyclic_frame_each_with_its_own_data() {
    let mut m = master(3);
    m.request_state(AlState::PreOp, STEP).unwrap();
    m.slave_mut(1).unwrap().configure_pdo(Mapping::Fixed(0x1720), Mapping::Fixed(0x1B20)).unwrap();
    m.slave_mut(2).unwrap().configure_pdo(Mapping::Fixed(0x1702), Mapping::Fixed(0x1B24)).unwrap();
    m.request_state(AlState::Op, STEP).unwrap();
    assert_eq!(m.expected_wkc().unwrap(), 9);
    let frames = m.stats().frames;
    let mappings = [(0x1701, 0x1B01), (0x1720, 0x1B20), (0x1702, 0x1B24)];
    for (position, (rx, _)) in mappings.iter().enumerate() {
        let entries = pdo::fixed(*rx).unwrap().entries;
        let at = offset_of(entries, 0x6040).unwrap();
        let mut outputs = m.slave_mut(position as u16).unwrap().outputs().unwrap().to_vec();
        outputs[at..at + 2].copy_from_slice(&(0x0100 + position as u16).to_le_bytes());
        m.slave_mut(position as u16).unwrap().set_outputs(&outputs).unwrap();
    }
    assert_eq!(m.exchange().unwrap(), 9);
    assert_eq!(m.stats().frames, frames + 1, "one frame for every drive");
    for (position, (_, tx)) in mappings.iter().enumerate() {
        let p = position as u16;
        assert_eq!(m.slave_mut(p).unwrap().sdo_read(0x6040, 0).unwrap(), (0x0100 + p).to_le_bytes());
        let at = offset_of(pdo::fixed(*tx).unwrap().entries, 0x6041).unwrap();
        assert_eq!(m.exchange().unwrap(), 9);
        let statusword = m.slave_mut(p).unwrap().sdo_read(0x6041, 0).unwrap();
        assert_eq!(&m.slave_mut(p).unwrap().inputs().unwrap()[at..at + 2], &statusword[..]);
    }
}

/// A link that keeps the commands of every frame's datagrams, and loses the next frame of
/// configured reads alone when told to.
struct Recording {
    inner: InProcess,
    frames: Arc<std::sync::Mutex<Vec<Vec<Command>>>>,
    lose_reads: Arc<AtomicBool>,
}

impl Link for Recording {
    fn send(&mut self, tx: &[u8]) -> Result<()> {
        let commands: Vec<Command> = frame::parse(tx).unwrap().map(|d| d.unwrap().header.command).collect();
        let reads_alone = commands.iter().all(|&c| c == Command::Fprd);
        self.frames.lock().unwrap().push(commands);
        if reads_alone && self.lose_reads.swap(false, Ordering::SeqCst) {
            return Ok(());
        }
        self.inner.send(tx)
    }

    fn receive(&mut self, rx: &mut [u8], deadline: Instant) -> Result<Option<usize>> {
        self.inner.receive(rx, deadline)
    }

    fn describe(&self) -> String {
        "recording sim".into()
    }

    fn awaited(&self) -> &'static str {
        "a frame (lost on purpose)"
    }
}

/// What one exchange of [`recorded`] gives: its result, and the commands of every frame it sent.
type Cycled = (std::result::Result<u16, String>, Vec<Vec<Command>>);

/// A supervised master in Op on `count` virtual AKDs behind a [`Recording`] link, the control of
/// the drives, whether the next frame of reads alone is lost, and a cycle: one exchange, its
/// result and the commands of every frame it sent.
fn recorded(count: usize) -> (Master, SimControl, Arc<AtomicBool>, impl Fn(&mut Master) -> Cycled) {
    let inner = InProcess::new(count);
    let control = inner.control();
    let frames = Arc::new(std::sync::Mutex::new(Vec::new()));
    let lose_reads = Arc::new(AtomicBool::new(false));
    let link = Recording { inner, frames: frames.clone(), lose_reads: lose_reads.clone() };
    let mut m = Master::new(Box::new(link), Duration::from_millis(100));
    m.scan().unwrap();
    m.request_state(AlState::Op, STEP).unwrap();
    m.set_supervision(true).unwrap();
    let cycle = move |m: &mut Master| {
        frames.lock().unwrap().clear();
        let result = m.exchange().map_err(|e| e.to_string());
        (result, std::mem::take(&mut *frames.lock().unwrap()))
    };
    (m, control, lose_reads, cycle)
}

#[test]
fn supervision_reads_the_whole_line_by_broadcast_until_a_drive_changes_and_then_each_in_that_cycle() {
    let (mut m, control, lose_reads, cycle) = recorded(3);
    let each = [vec![Command::Lrw], [Command::Fprd; 6].to_vec()].concat();
    let whole = vec![Command::Lrw, Command::Brd, Command::Brd];
    // Nothing seen yet: every drive read on its own; from then on the line as a whole.
    assert_eq!(cycle(&mut m), (Ok(9), vec![each.clone()]));
    for _ in 0..5 {
        assert_eq!(cycle(&mut m), (Ok(9), vec![whole.clone()]));
    }
    let op = |m: &Master| m.watch().unwrap().iter().map(|w| (w.answered, w.al_status.state())).collect::<Vec<_>>();
    assert_eq!(op(&m), vec![(true, Some(AlState::Op)); 3]);

    // A fault puts an emergency in drive 1's mailbox: seen in the cycle it is there, by a
    // second frame reading each drive, and then by the cyclic frame's own reads until the
    // mail is taken. When that second frame is lost, so is the cycle, and the next one reads
    // each drive again.
    control.change(Change::inject_fault(control.products(), 1, "F439")).unwrap();
    lose_reads.store(true, Ordering::SeqCst);
    let deadline = std::time::Instant::now() + STEP;
    loop {
        assert!(std::time::Instant::now() < deadline, "the emergency was never seen");
        let (result, sent) = cycle(&mut m);
        if sent.len() == 2 {
            assert_eq!(sent, vec![whole.clone(), [Command::Fprd; 6].to_vec()]);
            assert!(result.as_ref().is_err_and(|e| e.contains("lost on purpose")), "{result:?}");
            break;
        }
        assert_eq!((result, sent), (Ok(9), vec![whole.clone()]));
        std::thread::sleep(Duration::from_millis(1));
    }
    assert_eq!(m.stats().lost_frames, 1);
    assert_eq!(cycle(&mut m), (Ok(9), vec![whole.clone(), [Command::Fprd; 6].to_vec()]));
    assert_eq!((m.stats().watch_frames, m.stats().wkc_errors), (2, 0));
    let mail: Vec<bool> = m.watch().unwrap().iter().map(|w| w.mailbox_full).collect();
    assert_eq!(mail, vec![false, true, false]);
    assert_eq!(cycle(&mut m).1, vec![each.clone()]);

    // A drive that leaves Op behind the master's back is seen in that cycle too.
    let mut m2 = master(2);
    m2.request_state(AlState::Op, STEP).unwrap();
    m2.set_supervision(true).unwrap();
    for _ in 0..3 {
        m2.exchange().unwrap();
    }
    raw_al_request(&mut m2, 0, AlState::PreOp);
    let deadline = std::time::Instant::now() + STEP;
    while m2.watch().unwrap()[0].al_status.state() == Some(AlState::Op) {
        assert!(std::time::Instant::now() < deadline, "drive 0 never left Op");
        let _ = m2.exchange();
    }
    let states: Vec<_> = m2.watch().unwrap().iter().map(|w| (w.answered, w.al_status.state())).collect();
    assert_eq!(states, vec![(true, Some(AlState::PreOp)), (true, Some(AlState::Op))]);
    assert_eq!(m2.stats().lost_frames, 0);
}

#[test]
fn a_line_too_long_for_each_drives_reads_in_the_cyclic_frame_reads_them_in_frames_of_their_own() {
    // 64 drives: every drive's own reads (31 bytes each) do not fit beside the process data, so
    // the cyclic frame keeps its broadcast reads and each drive is read in frames after it, 48
    // drives a frame, while they are not all alike (the first cycle, an emergency waiting).
    let (mut m, control, _, exchange) = recorded(64);
    let cycle = |m: &mut Master| {
        let (result, sent) = exchange(m);
        (result.is_ok(), sent)
    };
    let whole = vec![Command::Lrw, Command::Brd, Command::Brd];
    let each = vec![[Command::Fprd; 96].to_vec(), [Command::Fprd; 32].to_vec()];
    assert_eq!(cycle(&mut m), (true, [vec![whole.clone()], each.clone()].concat()));
    assert_eq!(cycle(&mut m), (true, vec![whole.clone()]));
    control.change(Change::inject_fault(control.products(), 40, "F439")).unwrap();
    let deadline = std::time::Instant::now() + STEP;
    loop {
        assert!(std::time::Instant::now() < deadline, "the emergency was never seen");
        let (ok, sent) = cycle(&mut m);
        assert!(ok);
        if sent.len() > 1 {
            assert_eq!(sent, [vec![whole.clone()], each.clone()].concat());
            break;
        }
        std::thread::sleep(Duration::from_millis(1));
    }
    let mail: Vec<usize> =
        m.watch().unwrap().iter().enumerate().filter(|(_, w)| w.mailbox_full).map(|(n, _)| n).collect();
    assert_eq!(mail, vec![40]);
    assert!(m.watch().unwrap().iter().all(|w| w.answered));
    assert_eq!(m.stats().wkc_errors, 0);
}
