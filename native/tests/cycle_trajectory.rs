//! Joint trajectories followed by the cycle thread, against three virtual AKDs: drive 0 in
//! interpolated position and drive 1 in cyclic synchronous position with akd_ros's default
//! mapping (both targets, mode display), drive 2 in cyclic synchronous position with the fixed
//! 0x1724/0x1B24 (0x607A only, no mode display). The per-cycle records show what went out. The
//! interpolation itself is the pure module's and tested there; here the bounds on each cycle's
//! step come from evaluating the same trajectory, the set-point at its start read from the
//! records. The waits have deadlines only so that a failure does not hang.
//!
//! A host loaded beyond its cores can stall a cycle thread for more than seven cycles; the
//! virtual AKDs then fault with F125 (synchronization lost) as real ones would, for a reason
//! that is not the one under test. A run that fails so is repeated, up to three times; a
//! failure without it fails the test at once.

use std::panic::{catch_unwind, resume_unwind, AssertUnwindSafe};
use std::time::{Duration, Instant};

use akd_native::cycle::events::{Event, TrajectoryState};
use akd_native::cycle::samples::Sample;
use akd_native::cycle::sequencer::Request;
use akd_native::cycle::trajectory_player::TrajectoryStatus;
use akd_native::cycle::{Config, CycleThread};
use akd_native::drive::akd::AkdSlave;
use akd_native::drive::ds402::{statusword, Mode, State};
use akd_native::drive::pdo;
use akd_native::drive::pdo::Mapping;
use akd_native::drive::trajectory::{JointLimits, Knot, Limits, Scale, Setpoint, Trajectory};
use akd_native::ethercat::al::AlState;
use akd_native::ethercat::master::Master;
use akd_native::sim::control::{Change, SimControl};
use akd_native::sim::faults::Fault;
use akd_native::sim::in_process::InProcess;

const STEP: Duration = Duration::from_secs(5);
const DRIVES: [u16; 3] = [0, 1, 2];
const S: u64 = 1_000_000_000;

/// The three drives enabled, cycled at 1 kHz, and the handle that controls them.
fn rig() -> (CycleThread, SimControl) {
    let link = InProcess::new(3);
    let control = link.control();
    let mut m = Master::new(Box::new(link), Duration::from_millis(100));
    m.scan().unwrap();
    m.request_state(AlState::PreOp, STEP).unwrap();
    let default = || {
        let pdos =
            |p: &[&[akd_native::ethercat::pdo::PdoEntry]]| Mapping::Flexible(p.iter().map(|e| e.to_vec()).collect());
        (pdos(&pdo::DEFAULT_RX), pdos(&pdo::DEFAULT_TX))
    };
    let setups = [
        (default(), Mode::InterpolatedPosition),
        (default(), Mode::CyclicSynchronousPosition),
        ((Mapping::Fixed(0x1724), Mapping::Fixed(0x1B24)), Mode::CyclicSynchronousPosition),
    ];
    for (slave, ((rx, tx), mode)) in setups.into_iter().enumerate() {
        m.slave_mut(slave as u16).unwrap().configure_pdo(rx, tx).unwrap();
        m.slave_mut(slave as u16).unwrap().sdo_write(0x6060, 0, &[mode as u8]).unwrap();
    }
    m.request_state(AlState::Op, STEP).unwrap();
    let cycle = CycleThread::start(m, Config::new(Duration::from_millis(1))).map_err(|e| e.0).unwrap();
    for slave in DRIVES {
        cycle.request(slave, Request::Enable).unwrap();
    }
    wait_until("every drive enabled", || {
        DRIVES.iter().all(|&s| cycle.drive_status(s).unwrap().state() == Some(State::OperationEnabled)).then_some(())
    });
    (cycle, control)
}

/// Runs `scenario` on a fresh rig until it passes, or fails for another reason than a drive
/// losing synchronization (F125).
fn on_a_steady_host(scenario: impl Fn(&CycleThread, &SimControl)) {
    for _ in 0..3 {
        let (cycle, control) = rig();
        let run = catch_unwind(AssertUnwindSafe(|| scenario(&cycle, &control)));
        let stalled = DRIVES
            .iter()
            .any(|&d| control.drive_state(d as usize, STEP).is_ok_and(|s| s.fault == Some(Fault::SyncLost)));
        match run {
            Ok(()) => return,
            Err(failure) if !stalled => resume_unwind(failure),
            Err(_) => eprintln!("the host stalled the cycle thread into F125; once more"),
        }
    }
    panic!("the host stalled the cycle thread into F125 (synchronization lost) in each of 3 runs");
}

fn wait_until<T>(what: &str, mut done: impl FnMut() -> Option<T>) -> T {
    let deadline = Instant::now() + Duration::from_secs(20);
    loop {
        if let Some(value) = done() {
            return value;
        }
        assert!(Instant::now() < deadline, "timed out waiting for {what}");
        std::thread::sleep(Duration::from_millis(2));
    }
}

/// The records of the next `count` cycles or more, drained as they come.
fn records(cycle: &CycleThread, count: usize) -> Vec<Sample> {
    let mut all = Vec::new();
    wait_until("records", || {
        all.extend(cycle.samples());
        (all.len() >= count * DRIVES.len()).then_some(())
    });
    all
}

/// Records until trajectory `id` ends; its status then.
fn follow(cycle: &CycleThread, id: u32, all: &mut Vec<Sample>) -> TrajectoryStatus {
    wait_until("the trajectory's end", || {
        all.extend(cycle.samples());
        let status = cycle.trajectory_status(id).unwrap();
        status.state.ended().then_some(status)
    })
}

/// Drive `slave`'s records, oldest first.
fn of(all: &[Sample], slave: u16) -> Vec<Sample> {
    all.iter().filter(|s| s.slave == slave).copied().collect()
}

/// The largest |velocity| of joint `joint` of `trajectory` started from `from`, sampled every
/// 100 µs, counts/s.
fn peak_velocity(trajectory: &Trajectory, joint: usize, from: Setpoint) -> f64 {
    let lead_in = trajectory.lead_in(joint, from);
    (0..=trajectory.duration_ns() / 100_000)
        .map(|n| trajectory.at(&lead_in, n * 100_000, joint).velocity.abs())
        .fold(0.0, f64::max)
}

/// Every step between two cycles' targets is at most `velocity` times the time between them
/// plus one count.
fn assert_continuous(records: &[Sample], velocity: f64) {
    for pair in records.windows(2) {
        let step = (pair[1].target_position as i64 - pair[0].target_position as i64).abs() as f64;
        let allowed = velocity * (pair[1].time_ns - pair[0].time_ns) as f64 * 1e-9 + 1.0;
        assert!(
            step <= allowed,
            "drive {}: a step of {step} counts > {allowed} at cycle {}",
            pair[1].slave,
            pair[1].cycle
        );
    }
}

fn cubic(position: f64, velocity: f64) -> Knot {
    Knot { position, velocity: Some(velocity), acceleration: None }
}

/// Three points over 2 s from `base` (one per drive): out, on at a velocity, back past the start.
fn three_points(base: [i32; 3]) -> (Vec<u64>, Vec<Vec<Knot>>) {
    let point = |offset: f64, velocity: f64| base.iter().map(|&b| cubic(b as f64 + offset, velocity)).collect();
    (vec![S / 2, 6 * S / 5, 2 * S], vec![point(100_000.0, 150_000.0), point(150_000.0, 0.0), point(-50_000.0, 0.0)])
}

fn last_targets(all: &[Sample]) -> [i32; 3] {
    DRIVES.map(|d| of(all, d).last().unwrap().target_position)
}

/// A trajectory played: the records before it, the drives' targets then, its times, points
/// and id.
struct Played {
    before: Vec<Sample>,
    base: [i32; 3],
    times: Vec<u64>,
    points: Vec<Vec<Knot>>,
    id: u32,
}

/// Plays `three_points` from where the drives are.
fn play_three_points(cycle: &CycleThread) -> Played {
    let before = records(cycle, 20);
    let base = last_targets(&before);
    let (times, points) = three_points(base);
    let id = cycle.follow_trajectory(&DRIVES, &times, &points, None, None).unwrap();
    Played { before, base, times, points, id }
}

#[test]
fn a_three_point_trajectory_is_followed_continuously_and_ends_on_its_last_point() {
    on_a_steady_host(|cycle, _control| {
        let Played { before: mut all, base, times, points, id } = play_three_points(cycle);
        let status = follow(cycle, id, &mut all);
        assert_eq!((status.state, status.point, status.points), (TrajectoryState::Done, 3, 3));
        all.extend(records(cycle, 200));
        let trajectory = Trajectory::new(3, &times, &points, None).unwrap();
        for (joint, drive) in DRIVES.into_iter().enumerate() {
            let records = of(&all, drive);
            let from = Setpoint { position: base[joint] as f64, ..Setpoint::default() };
            assert_continuous(&records, peak_velocity(&trajectory, joint, from));
            // The middle point was passed on the way, the target ends on the last exactly and the
            // axis within 20 counts of it once settled.
            let last = points[2][joint].position;
            assert!(records.iter().any(|r| r.target_position as f64 >= points[1][joint].position - 1.0));
            let end = records.last().unwrap();
            assert_eq!(end.target_position as f64, last, "drive {drive}");
            assert!(
                (end.position as f64 - last).abs() <= 20.0,
                "drive {drive} settled at {}, not {last}",
                end.position
            );
        }
        let events: Vec<_> = cycle.events().into_iter().filter(|e| matches!(e, Event::Trajectory { .. })).collect();
        let states: Vec<_> = events
            .iter()
            .map(|e| if let Event::Trajectory { id, state, .. } = e { (*id, *state) } else { unreachable!() })
            .collect();
        assert_eq!(states, [(id, TrajectoryState::Running), (id, TrajectoryState::Done)]);
    });
}

#[test]
fn a_trajectory_replaced_half_way_continues_without_a_step() {
    on_a_steady_host(|cycle, _control| {
        let Played { before: mut all, base, times, points, id: first } = play_three_points(cycle);
        all.extend(records(cycle, 1000));
        // Back to the start in 1 s, from wherever the first one is then.
        let back: Vec<Vec<Knot>> = vec![base.iter().map(|&b| cubic(b as f64, 0.0)).collect()];
        let second = cycle.follow_trajectory(&DRIVES, &[S], &back, None, None).unwrap();
        assert_eq!(second, first + 1);
        let status = follow(cycle, second, &mut all);
        assert_eq!(status.state, TrajectoryState::Done);
        let replaced = cycle.trajectory_status(first).unwrap();
        assert_eq!(replaced.state, TrajectoryState::Replaced { by: second });
        assert!(replaced.elapsed_ns >= S - S / 10 && replaced.elapsed_ns < times[2], "{replaced:?}");
        all.extend(records(cycle, 50));
        // The second starts from the first's set-point at its start: its steps are bounded by the
        // first's peak velocity and what the second adds to it within a second.
        let first_trajectory = Trajectory::new(3, &times, &points, None).unwrap();
        for (joint, drive) in DRIVES.into_iter().enumerate() {
            let from = Setpoint { position: base[joint] as f64, ..Setpoint::default() };
            let lead_in = first_trajectory.lead_in(joint, from);
            let at_takeover = first_trajectory.at(&lead_in, status.started_ns - replaced.started_ns, joint);
            let second_trajectory = Trajectory::new(1, &[S], &[vec![back[0][joint]]], None).unwrap();
            let peak =
                peak_velocity(&first_trajectory, joint, from).max(peak_velocity(&second_trajectory, 0, at_takeover));
            let records = of(&all, drive);
            assert_continuous(&records, peak);
            assert_eq!(records.last().unwrap().target_position, base[joint], "drive {drive}");
        }
    });
}

#[test]
fn a_refused_trajectory_moves_nothing() {
    on_a_steady_host(|cycle, _control| {
        let base = last_targets(&records(cycle, 20));
        let (times, points) = three_points(base);
        let joint = |limits| JointLimits { name: "joint 0".into(), limits, scale: Scale::COUNTS };
        cycle
            .set_joint_limits(DRIVES[0], joint(Limits { min: -1e9, max: base[0] as f64 + 120_000.0, ..Limits::TARGET }))
            .unwrap();
        let past_a_limit = cycle.follow_trajectory(&DRIVES, &times, &points, None, None);
        cycle.set_joint_limits(DRIVES[0], joint(Limits::TARGET)).unwrap();
        let refusals = [
            (past_a_limit, "point 1, joint 0: position"),
            (
                cycle.follow_trajectory(&DRIVES, &[S, S, 2 * S], &points, None, None),
                "point 1: time from the start 1000000000 ns is not after the previous point's 1000000000 ns",
            ),
            (
                {
                    let mut nan = points.clone();
                    nan[2][1].velocity = Some(f64::NAN);
                    cycle.follow_trajectory(&DRIVES, &times, &nan, None, None)
                },
                "point 2, joint 1: velocity NaN",
            ),
            (cycle.follow_trajectory(&DRIVES[..2], &times, &points, None, None), "point 0 gives 3 joint value(s)"),
            (
                cycle.follow_trajectory(&[0, 1, 1], &times, &points, None, None),
                "drive 1 is named for joint 1 and joint 2",
            ),
            (cycle.follow_trajectory(&[0, 1, 7], &times, &points, None, None), "joint 2 (drive 7)"),
        ];
        for (refused, why) in refusals {
            let e = refused.unwrap_err().to_string();
            assert!(e.starts_with("trajectory refused, nothing moved: ") && e.contains(why), "{e}");
        }
        // Every target stays where it was, and every axis still.
        let after = records(cycle, 300);
        for (joint, drive) in DRIVES.into_iter().enumerate() {
            for r in of(&after, drive) {
                assert_eq!(r.target_position, base[joint], "drive {drive} at cycle {}", r.cycle);
                assert!((r.position - base[joint]).abs() <= 20, "drive {drive} moved to {}", r.position);
            }
        }
        assert!(cycle.events().iter().all(|e| !matches!(e, Event::Trajectory { .. })));
        let e = cycle.trajectory_status(1).unwrap_err().to_string();
        assert!(e.contains("no trajectory 1: none was played"), "{e}");
    });
}

#[test]
fn a_drive_faulted_mid_trajectory_aborts_it_and_the_others_hold() {
    on_a_steady_host(|cycle, control| {
        let Played { before: mut all, base, times, id, .. } = play_three_points(cycle);
        all.extend(records(cycle, 700));
        control.change(Change::inject_fault(control.products(), 1, "F235")).unwrap();
        let status = follow(cycle, id, &mut all);
        let TrajectoryState::Aborted { slave: 1, statusword: seen } = status.state else { panic!("{status:?}") };
        assert_ne!(seen & statusword::FAULT, 0, "0x{seen:04X}");
        assert!(status.elapsed_ns < times[2], "{status:?}");
        all.extend(records(cycle, 200));
        let aborted_at = cycle
            .events()
            .into_iter()
            .find_map(|e| match e {
                Event::Trajectory { id: i, cycle, state: TrajectoryState::Aborted { slave: 1, .. }, .. } if i == id => {
                    Some(cycle)
                }
                _ => None,
            })
            .expect("an aborted event");
        // From then on the others hold their last target, where the trajectory had taken them; the
        // faulted one is the sequencer's, at its actual position.
        for drive in [0, 2] {
            let held: Vec<i32> =
                of(&all, drive).iter().filter(|r| r.cycle >= aborted_at).map(|r| r.target_position).collect();
            assert!(held.len() >= 200 && held.iter().all(|&t| t == held[0]), "drive {drive} moved on");
            assert_ne!(held[0], base[drive as usize]);
        }
        assert_eq!(cycle.drive_status(1).unwrap().state(), Some(State::Fault));
        // A disabled drive cannot take a trajectory.
        let e = cycle.follow_trajectory(&[1], &[S], &[vec![Knot::position(0.0)]], None, None).unwrap_err().to_string();
        assert!(e.contains("joint 0 (drive 1): it is in Fault, not Operation enabled; enable it first"), "{e}");
    });
}
