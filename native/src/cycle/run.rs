//! The loop the cycle thread runs ([`run`]), and what it runs for each drive it sequences
//! ([`DriveLoop`]). Nothing in it allocates, takes a lock another thread can hold or waits on
//! another thread; it reads and writes [`CycleShared`] only through seqlocks and atomics.

use std::sync::atomic::Ordering;

use super::acyclic::MailboxService;
use super::devices::DeviceLoop;
use super::events::{Event, FaultSource};
use super::samples::Sample;
use super::stats::CycleStats;
use super::supervision::{Exchange, Gaps};
use super::{
    command_timeout, events, handshake, homing, image, latch, line_health, recovery, sequencer, supervision, timing,
    trajectory_player, CycleShared, HEADER_LEN,
};
use crate::error::{Error, Result};
use crate::ethercat::al::AlState;
use crate::ethercat::master::Master;

/// What the cycle thread runs for one drive it sequences.
#[derive(Default)]
pub(super) struct DriveLoop {
    pub(super) position: u16,
    pub(super) drive: sequencer::SequencedDrive,
    pub(super) latch: Option<latch::Latch>,
    /// Its digital inputs and hardware enable, each change an event.
    pub(super) inputs: crate::drive::io::InputWatch,
    pub(super) watch: supervision::DriveWatch,
    pub(super) handshake: handshake::Handshake,
    pub(super) command_timeout: command_timeout::CommandTimeout,
    pub(super) homing: homing::Homing,
    pub(super) presence: recovery::Presence,
    /// The mailbox counter the recovery left off at, for the master to go on from.
    pub(super) mailbox_counter: Option<u8>,
    /// The command time-out's target writes counted before this cycle's copy of the
    /// set-points; `None` when the copy did not succeed.
    pub(super) target_writes: Option<u64>,
}

/// What the loop works on: the master, what it shares with the other threads, the drives it
/// sequences, the devices beside them and the gaps in their frames.
pub(super) struct Loop<'a> {
    pub(super) master: &'a mut Master,
    pub(super) shared: &'a CycleShared,
    pub(super) drives: &'a mut [DriveLoop],
    pub(super) devices: &'a mut [DeviceLoop],
    pub(super) gaps: Gaps,
}

/// A cycle whose frame went out: its (cycle, wake-up time), the period that led to it, and the
/// time its exchange calls took so far (ns).
#[derive(Clone, Copy)]
struct Sent {
    now: (u64, u64),
    period_ns: u64,
    exchange_ns: u64,
}

/// The loop. Everything it touches was allocated before it starts.
///
/// Each cycle wakes at its deadline, lets the trajectory, the sequencer and the latches write
/// the outputs from the last inputs, sends the frame and judges its return (supervises the
/// drives, records the cycle, publishes the snapshot): right after sending it, or `pipelined`
/// at the next wake-up, before anything else; then one mailbox or recovery frame may go beside
/// it.
pub(super) fn run(
    l: &mut Loop<'_>,
    (mailbox, relay_buffers, line_reader): (
        &mut MailboxService,
        &mut recovery::RelayBuffers,
        &mut line_health::LineHealthReader,
    ),
    player: &mut trajectory_player::Player,
    (period_ns, pipelined): (u64, bool),
) {
    let stats = &l.shared.stats;
    let base = l.master.stats();
    let mut schedule = timing::Schedule::new(timing::now_ns() + period_ns, period_ns);
    let mut last_wake = None;
    let mut in_flight: Option<Sent> = None;
    while !l.shared.stop.load(Ordering::Acquire) {
        timing::sleep_until(schedule.next_ns());
        let wake = timing::now_ns();
        stats.wake_latency.record(wake.saturating_sub(schedule.next_ns()));
        let period = last_wake.map_or(0, |last| wake - last);
        if last_wake.is_some() {
            stats.period.record(period);
            let enabled = l.drives.iter().any(|d| d.drive.enabled());
            CycleStats::add(&stats.f125_stalls, supervision::stall_raises_f125(period, period_ns, enabled) as u64);
        }
        last_wake = Some(wake);
        if let Some(sent) = in_flight.take() {
            let before = (timing::now_ns(), l.master.stats());
            let result = l.master.receive_process_data();
            l.judge(result, before, sent, mailbox);
        }
        let now = (stats.cycles.load(Ordering::Relaxed) + 1, wake);
        l.write_outputs(player, now);
        let before = (timing::now_ns(), l.master.stats());
        let sent = Sent { now, period_ns: period, exchange_ns: 0 };
        if pipelined {
            match l.master.send_process_data() {
                Ok(()) => in_flight = Some(Sent { exchange_ns: timing::now_ns() - before.0, ..sent }),
                Err(e) => l.judge(Err(e), before, sent, mailbox),
            }
        } else {
            let result = l.master.exchange();
            l.judge(result, before, sent, mailbox);
        }
        let (shared, master) = (l.shared, &mut *l.master);
        let frames_before = master.stats().frames;
        let recovering = |slave: u16| shared.recovery.get(slave as usize).is_some_and(recovery::busy);
        mailbox.run(master, (&shared.sdo, &shared.eoe), &shared.events, now, recovering, |slave| {
            let status = shared.drives.get(slave as usize).map(|d| d.status());
            status.map_or(0, |s| s.statusword)
        });
        shared.relay.serve(master, relay_buffers);
        let frame_free = master.stats().frames == frames_before;
        line_reader.run(master, &shared.line_health, timing::now_ns(), frame_free);
        let now_stats = master.stats();
        let cyclic = (stats.lost_frames.load(Ordering::Relaxed), stats.wkc_errors.load(Ordering::Relaxed));
        let acyclic_lost = now_stats.lost_frames - base.lost_frames - cyclic.0;
        stats.acyclic_lost_frames.store(acyclic_lost, Ordering::Relaxed);
        stats.acyclic_wkc_errors.store(now_stats.wkc_errors - base.wkc_errors - cyclic.1, Ordering::Relaxed);
        stats.late_returns.store(now_stats.late_returns - base.late_returns, Ordering::Relaxed);
        CycleStats::add(&stats.overruns, schedule.advance(timing::now_ns()));
    }
    if in_flight.is_some() {
        // The last frame's return, so that the master is handed back with none on its way.
        let _ = l.master.receive_process_data();
    }
}

impl Loop<'_> {
    /// The trajectory, the sequencer and the latches read the inputs of the last return and
    /// write over the set-points copied into the outputs; the trajectory's targets are
    /// set-point writes.
    fn write_outputs(&mut self, player: &mut trajectory_player::Player, now: (u64, u64)) {
        let (shared, master) = (self.shared, &mut *self.master);
        let stats = &shared.stats;
        for d in self.drives.iter_mut() {
            d.target_writes = Some(shared.command_timeouts[d.position as usize].writes());
            d.drive.before_copy(&shared.drives[d.position as usize]);
        }
        if let Ok(sent) = master.output_image() {
            player.before_copy(&shared.trajectories, &shared.events, sent, now);
        }
        if let Ok(outputs) = master.output_image_mut() {
            if shared.setpoints.try_read(outputs).is_none() {
                CycleStats::add(&stats.setpoints_busy, 1);
                self.drives.iter_mut().for_each(|d| d.target_writes = None);
            } else {
                self.drives.iter_mut().for_each(|d| d.drive.copied());
            }
            for device in self.devices.iter() {
                device.apply_off(&shared.devices[device.position as usize], &shared.setpoints, outputs);
            }
        }
        if let Ok(inputs) = master.input_image() {
            player.observe(&shared.trajectories, &shared.events, inputs, now);
            for d in self.drives.iter_mut().filter(|d| player.wrote(d.position)) {
                d.drive.written_in_loop(&shared.drives[d.position as usize]);
            }
            let timeout_ns = shared.request_timeout_ns.load(Ordering::Relaxed);
            for d in self.drives.iter_mut() {
                d.drive.observe(&shared.drives[d.position as usize], inputs, now.1, timeout_ns);
                if let Some(latch) = d.latch.as_mut() {
                    let slave = d.position;
                    let (cycle, time_ns) = now;
                    latch.observe(&shared.latches[slave as usize], inputs, |channel, edge, position| {
                        shared.events.push(Event::Latch { cycle, time_ns, slave, channel, edge, position })
                    });
                }
            }
        }
        if let (Ok(inputs), Ok(outputs)) = (master.input_image(), master.output_image()) {
            for d in self.drives.iter_mut() {
                observe_set_points(shared, d, inputs, outputs, now);
            }
        }
        if let Ok(outputs) = master.output_image_mut() {
            player.apply(&shared.trajectories, &shared.setpoints, outputs);
            for d in self.drives.iter() {
                d.drive.apply(outputs);
                d.handshake.apply(outputs, d.drive.offsets.controlword);
                if let Some(objects) = homing_objects(&d.drive.offsets) {
                    d.homing.apply(&objects, outputs);
                }
                d.command_timeout.apply(outputs, d.drive.offsets.controlword);
                if let Some(latch) = d.latch.as_ref() {
                    latch.apply(outputs);
                }
            }
        }
    }

    /// Judges the return of the frame of cycle `sent` (its working counter, or why there is
    /// none), counted from the time and the master's counters before the exchange call that
    /// gave it: supervises the drives, records the cycle and publishes the snapshot.
    fn judge(
        &mut self,
        result: Result<u16>,
        (started_ns, before): (u64, crate::ethercat::master::Stats),
        sent: Sent,
        mailbox: &mut MailboxService,
    ) {
        let (shared, master) = (self.shared, &mut *self.master);
        let stats = &shared.stats;
        let exchange_ns = sent.exchange_ns + (timing::now_ns() - started_ns);
        stats.exchange.record(exchange_ns);
        // Lost frames and wrong working counters are the master's own counts, the cyclic
        // frame's kept apart from the mailbox's; other failures are counted here. None of them
        // stops the cycle: supervise() judges them.
        let after = master.stats();
        CycleStats::add(&stats.lost_frames, after.lost_frames - before.lost_frames);
        CycleStats::add(&stats.wkc_errors, after.wkc_errors - before.wkc_errors);
        CycleStats::add(&stats.watch_frames, after.watch_frames - before.watch_frames);
        let (wkc, exchange) = match &result {
            Ok(wkc) => (*wkc, Exchange::Good),
            Err(Error::WorkingCounter { got, .. }) => (*got, Exchange::WrongWkc),
            Err(Error::Timeout { .. }) => (0, Exchange::Lost),
            Err(_) => {
                CycleStats::add(&stats.other_errors, 1);
                (0, Exchange::Lost)
            }
        };
        let now = sent.now;
        shared.dc.publish(master.clock());
        supervise(master, shared, (self.drives, self.devices), mailbox, &mut self.gaps, exchange, now);
        if let (Exchange::Good, Ok(inputs)) = (exchange, master.input_image()) {
            for d in self.drives.iter_mut().filter(|d| !d.presence.lost()) {
                if let Some((digital_inputs, statusword)) = d.inputs.observe(inputs) {
                    let (cycle, time_ns, slave) = (now.0, now.1, d.position);
                    shared.events.push(Event::Inputs { cycle, time_ns, slave, digital_inputs, statusword });
                }
            }
            for d in self.devices.iter_mut().filter(|d| !d.presence.lost()) {
                if let Some(levels) = d.observe_inputs(inputs) {
                    let (cycle, time_ns, slave) = (now.0, now.1, d.position);
                    shared.events.push(Event::DeviceInputs { cycle, time_ns, slave, levels });
                }
            }
        }
        let counters = self.drives.iter_mut().map(|d| (d.position, &mut d.mailbox_counter));
        for (position, counter) in counters.chain(self.devices.iter_mut().map(|d| (d.position, &mut d.mailbox_counter)))
        {
            if let Some(counter) = counter.take() {
                master.set_mailbox_counter(position, counter);
            }
        }
        if let (Ok(inputs), Ok(outputs)) = (master.input_image(), master.output_image()) {
            let timing = (sent.period_ns.min(u32::MAX as u64) as u32, exchange_ns.min(u32::MAX as u64) as u32);
            for d in self.drives.iter() {
                shared.samples.push(&sample(d, inputs, outputs, now, timing, (wkc, exchange)));
            }
        }
        CycleStats::add(&stats.cycles, 1);
        let mut w = shared.snapshot.write();
        w.write(0, &stats.cycles.load(Ordering::Relaxed).to_le_bytes());
        w.write(8, &now.1.to_le_bytes());
        w.write(16, &wkc.to_le_bytes());
        w.write(18, &[result.is_ok() as u8]);
        if let (Ok(inputs), Ok(outputs)) = (master.input_image(), master.output_image()) {
            w.write(HEADER_LEN, inputs);
            w.write(HEADER_LEN + inputs.len(), outputs);
        }
    }
}

/// Moves drive `d`'s set-point handshake and command time-out on, from this cycle's inputs and
/// the set-points just copied into `outputs`.
fn observe_set_points(shared: &CycleShared, d: &mut DriveLoop, inputs: &[u8], outputs: &[u8], now: (u64, u64)) {
    let o = d.drive.offsets;
    let slave = d.position as usize;
    let statusword = image::u16_at(inputs, o.statusword);
    let mode_display = o.mode_display.map(|at| inputs[at] as i8);
    d.handshake.observe(&shared.handshakes[slave], statusword, mode_display, now.1);
    let seen = command_timeout::Seen { now, slave: d.position, writes: d.target_writes, outputs, inputs, statusword };
    d.command_timeout.observe(&shared.command_timeouts[slave], &o, &shared.drives[slave], &shared.events, seen);
    if let Some(objects) = homing_objects(&o) {
        let stop_ns = shared.request_timeout_ns.load(Ordering::Relaxed);
        if d.homing.observe(&shared.homings[slave], &objects, (inputs, outputs), now.1, stop_ns) {
            shared.drives[slave].hold();
        }
    }
}

/// Where homing finds its objects: it needs the mode and its display mapped.
pub(super) fn homing_objects(o: &sequencer::Offsets) -> Option<homing::Objects> {
    Some(homing::Objects {
        controlword: o.controlword,
        mode: o.mode?,
        statusword: o.statusword,
        mode_display: o.mode_display?,
    })
}

/// The record of drive `d` in this cycle.
fn sample(
    d: &DriveLoop,
    inputs: &[u8],
    outputs: &[u8],
    (cycle, time_ns): (u64, u64),
    (period_ns, exchange_ns): (u32, u32),
    (wkc, exchange): (u16, Exchange),
) -> Sample {
    let o = d.drive.offsets;
    let mode = o.mode_display.map_or(0, |a| inputs[a] as i8);
    // The position target of the mode in force: interpolated position (7) takes 0x60C1:01.
    let [target_position, ip_setpoint] = o.targets;
    let position_target = if mode == 7 { ip_setpoint.or(target_position) } else { target_position.or(ip_setpoint) };
    let i32_in = |at: Option<usize>| at.map_or(0, |a| image::i32_at(inputs, a));
    Sample {
        cycle,
        time_ns,
        slave: d.position,
        period_ns,
        exchange_ns,
        wkc,
        fresh: exchange == Exchange::Good,
        lost: exchange == Exchange::Lost,
        statusword: image::u16_at(inputs, o.statusword),
        mode,
        position: i32_in(o.actual),
        velocity: i32_in(o.velocity_actual),
        torque: o.torque_actual.map_or(0, |a| image::i16_at(inputs, a)),
        following_error: i32_in(o.following_error),
        target_position: position_target.map_or(0, |a| image::i32_at(outputs, a)),
        target_velocity: o.velocity_target.map_or(0, |a| image::i32_at(outputs, a)),
        target_torque: o.torque_target.map_or(0, |a| image::i16_at(outputs, a)),
    }
}

/// Judges the cycle's exchange, every drive's state and every device's presence; reports faults
/// and brings drives to a safe state, and devices' outputs off, where the fault calls for it.
fn supervise(
    master: &Master,
    shared: &CycleShared,
    (drives, devices): (&mut [DriveLoop], &mut [DeviceLoop]),
    mailbox: &mut MailboxService,
    gaps: &mut Gaps,
    exchange: Exchange,
    now: (u64, u64),
) {
    let enabled = drives.iter().any(|d| d.drive.enabled());
    let gap = gaps.observe(exchange, enabled, now);
    let (Ok(inputs), watch) = (master.input_image(), master.watch().ok()) else { return };
    let mut faulted = false;
    let answered = |slave: u16| {
        exchange != Exchange::Lost && watch.and_then(|w| w.get(slave as usize)).is_some_and(|w| w.answered)
    };
    // Every slave of the line, devices too: a terminal that did not answer spares the drives
    // that did a wrong working counter.
    let slaves = 0..master.slaves().len() as u16;
    let all_answered = slaves.clone().all(answered);
    // A frame in which nobody answered is the line's fault, as a lost frame is, not one drive's.
    let none_answered = !slaves.clone().any(answered);
    for d in drives.iter_mut() {
        let slave = d.position;
        let o = d.drive.offsets;
        let statusword = (exchange == Exchange::Good).then(|| image::u16_at(inputs, o.statusword));
        let al_status = watch.and_then(|w| w.get(slave as usize)).filter(|w| w.answered).map(|w| w.al_status);
        // The watch keeps the last frame's reads when a frame is lost: only this cycle's count.
        let in_op = answered(slave) && al_status.is_some_and(|a| a.state() == Some(AlState::Op) && !a.error());
        let seen = d.watch.observe(slave, statusword, al_status, d.drive.sequenced(), now);
        faulted |= seen.fault.is_some() || seen.left_op.is_some();
        if let Some(event) = seen.fault {
            mailbox.read_error_code(master, slave, event, &shared.events);
        }
        if let Some(event) = seen.left_op {
            // A slave lost before answers again out of Op while it is being restored.
            if !d.presence.lost() {
                shared.events.push(event);
            }
            shared.drives[slave as usize].request(sequencer::Request::Disable);
        }
        // A wrong working counter while some drive did not answer is that drive's: the others,
        // which did, exchanged their process data and go on.
        let spared = gap.is_some_and(|g| g.source == FaultSource::WorkingCounter) && !all_answered && answered(slave);
        // A drive that did not answer in a frame that came back is reported as unreachable.
        let own = exchange == Exchange::Lost || none_answered || answered(slave) || !shared.supervised;
        let gap_reported = gap.filter(|_| d.drive.enabled() && own && !spared && !d.presence.lost());
        if let Some(report) = gap_reported {
            let fault = (report.source, report.length.min(u16::MAX as u32) as u16, report.action);
            shared.events.push(Event::fault(report.began, slave, statusword.unwrap_or(0), al_status, fault));
            if report.action == events::Action::Disabled {
                shared.drives[slave as usize].request(sequencer::Request::Disable);
            }
        }
        let reported = gap_reported.is_some_and(|r| r.action == events::Action::Disabled);
        if shared.supervised {
            faulted |= presence(master, shared, d, (answered(slave), in_op, reported), (statusword, al_status), now);
        }
    }
    if shared.supervised {
        for d in devices.iter_mut() {
            device_presence(master, shared, d, answered(d.position), now);
        }
    }
    if faulted && shared.quick_stop_on_fault.load(Ordering::Relaxed) {
        quick_stop_the_others(shared, drives, inputs);
        // The line's fault reaction: the devices' outputs (a gripper's valve) go off too.
        devices.iter().for_each(|d| shared.devices[d.position as usize].request_off());
    }
}

/// Moves device `d`'s presence on, as a drive's: when it is lost (unanswered for as long as a
/// drive, or out of Op), reports it, switches its outputs off and asks for its recovery; when
/// it is back in Op, reports it with its outputs off, where they stay until set again.
fn device_presence(master: &Master, shared: &CycleShared, d: &mut DeviceLoop, answered: bool, now: (u64, u64)) {
    let slave = d.position;
    let al_status = master.watch().ok().and_then(|w| w.get(slave as usize)).filter(|w| w.answered).map(|w| w.al_status);
    let in_op = answered && al_status.is_some_and(|a| a.state() == Some(AlState::Op) && !a.error());
    let recovery = &shared.recovery[slave as usize];
    let fault = |source, code, action| Event::fault(now, slave, 0, al_status, (source, code, action));
    match d.presence.observe(answered, in_op && !recovery::restoring(recovery), now) {
        None => {}
        Some(recovery::PresenceChange::Lost { report, missing }) => {
            let source = if report { FaultSource::Unreachable } else { FaultSource::AlState };
            let code = if report { missing.min(u16::MAX as u32) as u16 } else { 0 };
            shared.events.push(fault(source, code, events::Action::OutputsOff));
            shared.devices[slave as usize].request_off();
            recovery::want(recovery, master.mailbox_counter(slave).unwrap_or(0));
        }
        Some(recovery::PresenceChange::Back { since }) => {
            d.mailbox_counter = Some(recovery::done(recovery));
            shared.devices[slave as usize].request_off();
            let gone_ms = (now.1.saturating_sub(since.1) / 1_000_000).min(u16::MAX as u64) as u16;
            shared.events.push(fault(FaultSource::Recovered, gone_ms, events::Action::RestoredOutputsOff));
        }
    }
}

/// Moves drive `d`'s presence on (whether it answered, whether in Op); when it is lost,
/// disables it, reports it unless its leaving Op or the gap was reported (`reported`), and asks
/// for its recovery; when it is back, reports it and holds its target at the actual position.
/// Returns whether it was lost this cycle.
fn presence(
    master: &Master,
    shared: &CycleShared,
    d: &mut DriveLoop,
    (answered, in_op, reported): (bool, bool, bool),
    (statusword, al_status): (Option<u16>, Option<crate::ethercat::master::state::AlStatus>),
    now: (u64, u64),
) -> bool {
    let slave = d.position;
    let fault =
        |source, code, action| Event::fault(now, slave, statusword.unwrap_or(0), al_status, (source, code, action));
    let recovery = &shared.recovery[slave as usize];
    match d.presence.observe(answered, in_op && !recovery::restoring(recovery), now) {
        None => false,
        Some(recovery::PresenceChange::Lost { report, missing }) => {
            shared.drives[slave as usize].request(sequencer::Request::Disable);
            shared.homings[slave as usize].forget();
            if report && !reported {
                let action = if d.drive.enabled() { events::Action::Disabled } else { events::Action::Reported };
                shared.events.push(fault(FaultSource::Unreachable, missing.min(u16::MAX as u32) as u16, action));
            }
            recovery::want(recovery, master.mailbox_counter(slave).unwrap_or(0));
            true
        }
        Some(recovery::PresenceChange::Back { since }) => {
            d.mailbox_counter = Some(recovery::done(recovery));
            shared.drives[slave as usize].hold();
            let gone_ms = (now.1.saturating_sub(since.1) / 1_000_000).min(u16::MAX as u64) as u16;
            shared.events.push(fault(FaultSource::Recovered, gone_ms, events::Action::Restored));
            false
        }
    }
}

/// Asks every drive being enabled or enabled, and not in Fault, for a quick stop: the drive
/// that faulted is in Fault, and one that left Op was asked for Switch on disabled.
fn quick_stop_the_others(shared: &CycleShared, drives: &[DriveLoop], inputs: &[u8]) {
    for d in drives {
        let in_fault = image::u16_at(inputs, d.drive.offsets.statusword) & crate::drive::ds402::statusword::FAULT != 0;
        let position = d.position as usize;
        if !in_fault && shared.drives[position].status().request == Some(sequencer::Request::Enable) {
            shared.drives[position].request(sequencer::Request::QuickStop);
            shared.command_timeouts[position].release();
        }
    }
}
