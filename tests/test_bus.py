"""`akd_ros.Bus` against three in-process virtual AKDs (``sim:3``): one master and one cycle, an Axis per drive, each
in its own mode and moving only as commanded; events filed under the drive they came from; a fault on one drive
quick-stopping the others or not, as `fault_reaction` says; bus-wide requests naming the drive that refused; bad
configurations refused before anything is set up.

The waits have deadlines only so that a failure does not hang; no test asserts how fast anything happens.

The virtual AKDs judge missed frames by the frames the line lost (`?missed=lost`): nothing here is about this shared
host's scheduling, so a cycle it runs late must not fault them (F125) as it would a real drive.
"""

from __future__ import annotations

import time

import pytest
from akd_ros._native import Ds402State

from akd_ros import Axis, Bus, BusRequestError, CommandError, DriveConfig, Limits
from support.waiting import wait_for

THREE = [
    DriveConfig(slave=0, name="ip", mode="interpolated_position"),
    DriveConfig(slave=1, name="velocity", mode="profile_velocity"),
    DriveConfig(slave=2, name="torque", mode="profile_torque"),
]


def still(axis: Axis, cycles: int = 100) -> int:
    """How far (counts) the axis moved over the next `cycles` cycles, sampled every few ms."""
    seen = []
    end = axis.state().cycle + cycles
    while (s := axis.state()).cycle < end:
        seen.append(s.position_counts)
        time.sleep(0.002)
    return max(seen) - min(seen)


def cycles_later(axis: Axis, count: int) -> bool:
    """Waits `count` cycles."""
    end = axis.state().cycle + count
    return wait_for(f"{count} cycles", lambda: axis.state().cycle >= end)


@pytest.fixture
def bus():
    with Bus("sim:3?missed=lost", THREE) as b:
        yield b


def test_three_axes_in_three_modes_move_each_as_commanded_and_only_then(bus: Bus) -> None:
    ip, velocity, torque = bus.axes
    assert bus["velocity"] is velocity and [a.slave for a in bus.axes] == [0, 1, 2]
    assert [a.mode for a in bus.axes] == ["interpolated_position", "profile_velocity", "profile_torque"]
    bus.enable()
    assert [a.state().state for a in bus.axes] == [Ds402State.OPERATION_ENABLED] * 3
    # Enabled together, nothing moves before its command.
    assert [still(a) for a in bus.axes] == [0, 0, 0]
    start = {a.name: a.state().position_counts for a in bus.axes}
    ip.command_position(ip.state().position + 1.0)
    wait_for("the position", lambda: abs(ip.state().position - ip.command) < 1e-3 and still(ip, 50) <= 1)
    ip_at = ip.state().position_counts
    # The other two stand where they were.
    assert abs(velocity.state().position_counts - start["velocity"]) <= 1
    assert abs(torque.state().position_counts - start["torque"]) <= 1
    velocity.command_velocity(-8.0)

    # The drive model overshoots a step in velocity a little: -8 rad/s is reached when it holds over 50 cycles.
    def at_speed() -> bool:
        return abs(velocity.state().velocity + 8.0) < 0.08

    wait_for("-8 rad/s", lambda: at_speed() and (cycles_later(velocity, 50) and at_speed()))
    assert abs(ip.state().position_counts - ip_at) <= 1
    assert abs(torque.state().position_counts - start["torque"]) <= 1
    torque.command_torque(0.3)
    wait_for("0.3 N·m", lambda: abs(torque.state().torque - 0.3) <= 3.0 / 1000)
    assert wait_for("the torque axis to turn", lambda: torque.state().velocity > 0.0)
    # Each axis keeps its own: the velocity axis still at -8 rad/s, the position axis still where it went.
    assert at_speed()
    assert abs(ip.state().position_counts - ip_at) <= 1
    # Every cycle recorded once per drive, from the one cycle.
    columns = bus.samples()
    assert set(columns["slave"]) == {0, 1, 2}
    cycles = [c for c, s in zip(columns["cycle"], columns["slave"], strict=True) if s == 1]
    assert cycles == list(range(cycles[0], cycles[0] + len(cycles)))
    time.sleep(0.01)
    assert set(velocity.samples()["slave"]) == {1}


def test_a_latch_and_a_fault_arrive_only_at_their_axis(bus: Bus) -> None:
    ip, velocity, torque = bus.axes
    bus.simulator.set_input_toggles(0, 1, [300_000.4])
    bus.enable()
    ip.arm_latch(1, "rising")
    ip.command_position(2.0)  # about 334,000 counts: across the toggle
    wait_for("the position axis past the toggle", lambda: ip.state().position_counts > 310_000)
    # The other axes take the cycle's events first; the capture waits for its own axis, and comes once.
    assert list(torque.latch_events()) == [] and list(velocity.fault_events()) == []
    captures = wait_for("the capture", lambda: list(ip.latch_events()))
    assert [(e.channel, e.edge) for e in captures] == [(1, "rising")]
    assert abs(captures[0].position_counts - 300_000.4) <= 1
    bus.simulator.inject_fault(1, "F439")
    faults = wait_for("the fault", lambda: [e for e in velocity.fault_events() if e.source == "drive_fault"])
    assert len(faults) == 1 and faults[0].text == "F439 Following error"
    time.sleep(0.05)
    for other in (ip, torque):
        assert list(other.latch_events()) == [] and list(other.fault_events()) == []
    assert list(velocity.latch_events()) == []


@pytest.mark.parametrize(
    ("reaction", "others"), [("all", Ds402State.QUICK_STOP_ACTIVE), ("joint", Ds402State.OPERATION_ENABLED)]
)
def test_a_fault_on_one_drive_stops_the_others_as_fault_reaction_says(reaction: str, others: str) -> None:
    with Bus("sim:3?missed=lost", THREE, fault_reaction=reaction) as bus:
        ip, velocity, torque = bus.axes
        bus.enable()
        velocity.command_velocity(2.0)
        ip.command_position(0.5)
        bus.simulator.inject_fault(1, "F439")
        wait_for("the fault", lambda: velocity.state().state in (Ds402State.FAULT, Ds402State.FAULT_REACTION_ACTIVE))
        for axis in (ip, torque):
            wait_for(f"{axis.name} in {others}", lambda a=axis: a.state().state == others)
        time.sleep(0.1)
        assert [ip.state().state, torque.state().state] == [others, others]
        # Only the faulting drive reports a fault.
        assert {e.source for e in velocity.fault_events()} >= {"drive_fault"}
        assert list(ip.fault_events()) == [] and list(torque.fault_events()) == []
        if reaction == "all":
            # Quick-stopped, not faulted: enabling again is the user's call, and it works.
            ip.enable()
            assert ip.state().state == Ds402State.OPERATION_ENABLED


def test_an_enable_a_fault_elsewhere_replaces_with_a_quick_stop_says_so() -> None:
    # Drive 2's enable cannot finish (hardware enable low) and stays under way for its 3 s request time-out; drive 0's
    # fault meanwhile quick-stops every drive being enabled, drive 2 too.
    with Bus("sim:3?missed=lost", THREE, request_timeout=3.0) as bus:
        ip, _, torque = bus.axes
        bus.simulator.set_hardware_enable(2, False)
        ip.enable()
        torque.request("enable")
        bus.simulator.inject_fault(0, "F439")
        with pytest.raises(TimeoutError, match="the enable was replaced by a quick_stop request"):
            torque.wait("enable", timeout=1.5)


def test_bus_wide_enable_names_the_drive_whose_hardware_enable_is_low(bus: Bus) -> None:
    bus.simulator.set_hardware_enable(2, False)
    with pytest.raises(BusRequestError, match=r"torque: .*hardware enable") as refused:
        bus.enable()
    assert list(refused.value.failed) == ["torque"] and refused.value.done == ["ip", "velocity"]
    bus.simulator.set_hardware_enable(2, True)
    bus.enable()
    bus.disable()
    assert {a.state().state for a in bus.axes} == {Ds402State.SWITCH_ON_DISABLED}


@pytest.mark.parametrize(
    ("drives", "settings", "message"),
    [
        (
            [DriveConfig(slave=0, mode="spin")],
            {},
            "mode 'spin' is not one of profile_position, .*, cyclic_synchronous_position",
        ),
        ([DriveConfig(slave=5)], {}, r"slave 5 is not on the bus: the line has 3 slaves \(0..2\)"),
        ([DriveConfig(slave=1), DriveConfig(slave=1)], {}, "slave 1 given to several drives"),
        ([DriveConfig(slave=0, name="a"), DriveConfig(slave=1, name="a")], {}, "name a given to several drives"),
        ([DriveConfig(alias=0)], {}, r"station alias 0 is on 3 slave\(s\), not one \(position: alias of each: 0: 0, "),
        ([DriveConfig(slave=0), DriveConfig(alias=0)], {}, r"station alias 0 is on 3 slave\(s\)"),
        ([DriveConfig(slave=0, alias=3)], {}, r"drive 0: give its slave .* or its alias, one of them \(both given\)"),
        ([DriveConfig(slave=0), DriveConfig(name="x")], {}, r"drive 1 \(x\): give its slave .* \(neither given\)"),
        ([], {}, "at least one drive"),
        (THREE, {"fault_reaction": "some"}, "fault_reaction 'some' is not one of all, joint"),
        (THREE, {"dc": True, "dc_shift": float("nan")}, "dc_shift must be finite"),
    ],
)
def test_a_bad_bus_is_refused_naming_the_problem(drives, settings, message) -> None:
    with pytest.raises(CommandError, match=message):
        Bus("sim:3?missed=lost", drives, **settings)
    # Nothing was left open: the same line opens again.
    with pytest.raises(CommandError, match=r"slave 0 is given twice \(drives 0 and 1\); each drive once"):
        Bus("sim?missed=lost", [DriveConfig(slave=0), DriveConfig(alias=0)])
    with Bus("sim:3?missed=lost", [DriveConfig(slave=0)]) as bus:
        assert bus.axes[0].name == "slave_0"


def test_an_axis_of_a_shared_bus_closes_alone_and_a_closed_bus_refuses(bus: Bus) -> None:
    ip, velocity, _ = bus.axes
    bus.enable()
    velocity.close()
    assert ip.state().state == Ds402State.OPERATION_ENABLED
    assert bus.cycle.drive_status(1).state == Ds402State.SWITCH_ON_DISABLED
    with pytest.raises(CommandError, match="the axis is closed"):
        velocity.command_velocity(1.0)
    bus.close()
    with pytest.raises(CommandError, match="the axis is closed"):
        ip.command_position(0.0)
    with pytest.raises(CommandError, match="the bus is closed"):
        bus.enable()


def test_limits_and_units_are_each_axis_own() -> None:
    drives = [DriveConfig(slave=0, limits=Limits(max_position=1.0)), DriveConfig(slave=1)]
    with Bus("sim:2?missed=lost", drives) as bus:
        bus.enable()
        with pytest.raises(CommandError, match="position"):
            bus.axes[0].command_position(2.0)
        bus.axes[1].command_position(2.0)


def test_dc_is_set_once_for_the_bus_and_every_drive_follows_the_one_sync0() -> None:
    with Bus("sim:3?missed=lost", THREE, period=0.002, dc=True, dc_shift=-0.0005) as bus:
        dc = bus.cycle.dc_status()
        assert (dc["active"], dc["cycle_ns"], dc["shift_ns"]) == (True, 2_000_000, -500_000)
        assert [(d["position"], d["fbus_param02"]) for d in dc["drives"]] == [(0, 1), (1, 1), (2, 1)]
        starts = set()
        for axis in bus.axes:
            sync = bus.simulator.drive_state(axis.slave)["dc"]
            assert sync["source"] == "sync0" and sync["pll_locked"], (axis.name, sync)
            starts.add(sync["sync0_start_ns"])
        assert len(starts) == 1 and starts.pop() % 2_000_000 == 1_500_000, "one SYNC0 for the line"
    with Bus("sim:3?missed=lost", THREE) as bus:
        assert bus.cycle.dc_status() == {"active": False}
        assert {bus.simulator.drive_state(a.slave)["dc"]["source"] for a in bus.axes} == {"sm2"}


def test_the_cycle_keeps_as_many_records_for_each_drive_as_for_one() -> None:
    # 5000 cycles of three drives: more than one drive's 8192 records in all, fewer than 8192 for each.
    with Bus("sim:3?missed=lost", THREE, period=0.00025) as bus:
        wait_for("5000 cycles", lambda: bus.stats()["cycles"] >= 5000, timeout=20.0)
        columns = bus.samples()
        stats = bus.stats()
    assert stats["samples_dropped"] == 0, stats
    per_drive = [columns["slave"].count(axis.slave) for axis in bus.axes]
    assert min(per_drive) >= 5000, per_drive
