"""The virtual AKD failing as the field does, seen through a real `_native.Master`: a drive
power-cycled, a cable pulled and replugged, frames lost or corrupted, wrong working counters;
in process (`Master("sim:3").simulator`, while a Cycle holds the master) and through akd-sim's
stdin commands with a master on UDP.

The waits have deadlines only so that a failure does not hang; nothing here asserts how fast
anything happens. Recovery is not the subject: each test shows what the master sees.
"""

from __future__ import annotations

import contextlib
import subprocess
import time

import pytest
from akd_ros._native import Ds402State

from akd_ros import _native
from support.netns import console_script, udp_port_bound
from test_sim_control import Lines, wait_for

DRIVES = 3
INPUT_ENTRIES = [[0x60640020, 0x60410010]]


@contextlib.contextmanager
def in_op(link: str):
    """A Master(`link`) with every drive in Op, its Simulator, and a Cycle at 1 kHz."""
    with _native.Master(link) as master:
        drives = len(master.scan())
        master.request_state("preop")
        for position in range(drives):
            master.configure_pdo(position, 0x1724, INPUT_ENTRIES)
        master.request_state("op")
        with _native.Cycle(master, 0.001) as cycle:
            yield master.simulator, cycle


@pytest.fixture
def op_rig():
    """A Master("sim:3") with every drive in Op, its Simulator, and a Cycle at 1 kHz."""
    with in_op(f"sim:{DRIVES}") as rig:
        yield rig


def counts(cycle) -> tuple[int, int, int]:
    """(lost_frames, wkc_errors, other_errors) of `cycle` so far, its cyclic frames' and the frames it sends beside
    them (the line's counters read four times a second, mailbox traffic): a burst hits whichever frames come."""
    stats = cycle.stats()
    return (
        stats["lost_frames"] + stats["acyclic_lost_frames"],
        stats["wkc_errors"] + stats["acyclic_wkc_errors"],
        stats["other_errors"],
    )


def after_burst(cycle, simulator_call, frames: int) -> tuple[int, int, int]:
    """Starts a burst with `simulator_call(frames)` and gives how the counts grew once the
    cycle ran well past it."""
    base = counts(cycle)
    simulator_call(frames)
    cycles = cycle.stats()["cycles"]
    wait_for("the cycle to run past the burst", lambda: cycle.stats()["cycles"] > cycles + 4 * frames + 50)
    return tuple(now - before for now, before in zip(counts(cycle), base, strict=True))


def test_dropped_frames_are_lost_to_the_cycle_exactly_as_many_as_asked(op_rig):
    simulator, cycle = op_rig
    assert after_burst(cycle, simulator.drop_frames, 3) == (3, 0, 0)


def test_wrong_working_counters_are_counted_by_the_cycle(op_rig):
    simulator, cycle = op_rig
    assert after_burst(cycle, simulator.wrong_wkc, 4) == (0, 4, 0)


def test_corrupted_replies_are_refused_by_the_masters_codec(op_rig):
    simulator, cycle = op_rig
    # The link drops a reply that is not the frame it sent, as a line's link does: lost.
    assert after_burst(cycle, simulator.corrupt_frames, 2) == (2, 0, 0)


def test_the_line_counts_what_it_did_to_the_frames_as_the_master_counts_them(op_rig):
    simulator, cycle = op_rig
    before = simulator.line_counts()
    cycles = cycle.stats()["cycles"]
    assert after_burst(cycle, simulator.drop_frames, 3) == (3, 0, 0)
    assert after_burst(cycle, simulator.corrupt_frames, 2) == (2, 0, 0)
    assert after_burst(cycle, simulator.wrong_wkc, 4) == (0, 4, 0)
    cycles = cycle.stats()["cycles"] - cycles
    after = simulator.line_counts()
    assert {key: after[key] - before[key] for key in ("lost", "corrupted", "wrong_wkc")} == {
        "lost": 3,
        "corrupted": 2,
        "wrong_wkc": 4,
    }
    # Every cycle between the two answers sent its frame down the line, and the line counted it.
    assert after["frames"] - before["frames"] >= cycles > 0


@pytest.fixture
def preop_master():
    """A Master("sim:3") with every drive in PreOp."""
    with _native.Master(f"sim:{DRIVES}") as master:
        master.scan()
        master.request_state("preop")
        yield master


def silent(master, positions) -> bool:
    """Whether none of the drives at `positions` answers at its station address."""
    for position in positions:
        with pytest.raises(_native.WorkingCounterError):
            master.al_status(position)
    return True


@pytest.mark.parametrize("missed", ["late", "lost"])
def test_an_enabled_drive_behind_a_pulled_cable_misses_its_frames_and_faults(missed):
    # late: its firmware runs on without frames, and after more than seven missed, by time, F125; lost: every frame the
    # line carries is one it misses, and the eighth raises F125.
    with in_op(f"sim:{DRIVES}?missed={missed}") as (simulator, cycle):
        cycle.enable(2)
        cycle.wait_state(2, Ds402State.OPERATION_ENABLED)
        simulator.pull_cable(1)
        wait_for("F125 behind the cable", lambda: simulator.drive_state(2)["fault_number"] == 125)
        assert simulator.drive_state(0)["fault"] is None
        simulator.replug_cable(1)


@pytest.mark.parametrize("burst", [7, 8])
def test_a_drive_judging_by_frames_lost_faults_after_more_than_seven_lost_on_the_line(burst):
    # `?missed=lost`: a frame the line lost counts, however late the next one comes; eight in a row raise F125.
    with in_op("sim:1?missed=lost") as (simulator, cycle):
        cycle.enable(0)
        cycle.wait_state(0, Ds402State.OPERATION_ENABLED)
        assert after_burst(cycle, simulator.drop_frames, burst) == (burst, 0, 0)
        assert simulator.drive_state(0)["fault"] == (None if burst == 7 else "sync_lost")


def test_a_pulled_cable_silences_the_drives_behind_it_until_replugged(preop_master):
    master = preop_master
    master.simulator.pull_cable(1)
    assert master.al_status(0)[0] == "PreOp" and silent(master, (1, 2))
    assert len(master.scan()) == 1
    master.simulator.replug_cable(1)
    # Behind the cable the drives kept their power and their state.
    assert [s["found_al_state"] for s in master.scan()] == ["Init", "PreOp", "PreOp"]


def test_a_power_cycled_drive_is_back_in_init_without_its_station_address(preop_master):
    master = preop_master
    master.simulator.power_cycle(1)
    # Its station address is gone: nothing answers at it any more.
    assert master.al_status(0)[0] == "PreOp" and silent(master, (1,))
    assert [s["found_al_state"] for s in master.scan()] == ["PreOp", "Init", "PreOp"]


def test_bad_failures_are_refused_naming_the_allowed_values():
    with _native.Master(f"sim:{DRIVES}") as master:
        simulator = master.simulator
        for call in (simulator.power_cycle, simulator.pull_cable, simulator.replug_cable):
            with pytest.raises(_native.ConfigError, match="no slave at position 3: the bus has 3 slave"):
                call(3)
        for call in (simulator.drop_frames, simulator.corrupt_frames, simulator.wrong_wkc):
            with pytest.raises(_native.ConfigError, match=r"-1 frames: allowed are 0 \(ends the burst\) or more"):
                call(-1)


def test_akd_sim_fails_on_command_while_a_master_talks_to_it(udp_port):
    argv = [*console_script("akd-sim"), "--udp", f"127.0.0.1:{udp_port}", "--count", str(DRIVES)]
    sim = subprocess.Popen(argv, stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        lines = Lines(sim.stdout)
        assert lines.next().startswith("akd-sim: starting 3 virtual AKDs")
        wait_for("akd-sim bound", lambda: udp_port_bound(udp_port) or sim.poll() is not None)

        def command(line: str) -> str:
            sim.stdin.write(line + "\n")
            sim.stdin.flush()
            return lines.next()

        with _native.Master(f"udp://127.0.0.1:{udp_port}", timeout=0.05) as master:
            master.scan()
            master.request_state("preop")
            assert command("drop 2") == "ok drop 2"
            # The server takes a command at its next frame or wake-up; the master retries.
            time.sleep(0.3)
            before = master.stats()["lost_frames"]
            assert master.al_status(0)[0] == "PreOp"
            assert master.stats()["lost_frames"] - before == 2
            assert command("corrupt 1") == "ok corrupt 1"
            time.sleep(0.3)
            # Over UDP a reply the codec refuses is not the awaited one: it is lost too.
            before = master.stats()["lost_frames"]
            assert master.al_status(0)[0] == "PreOp"
            assert master.stats()["lost_frames"] - before == 1
            assert command("wrong_wkc 1") == "ok wrong_wkc 1"
            time.sleep(0.3)
            with pytest.raises(_native.WorkingCounterError):
                master.al_status(0)
            assert master.al_status(0)[0] == "PreOp"
            assert command("cable 1 pulled") == "ok cable 1 pulled"
            time.sleep(0.3)
            with pytest.raises(_native.WorkingCounterError):
                master.al_status(2)
            assert len(master.scan()) == 1
            assert command("cable 1 plugged") == "ok cable 1 plugged"
            assert command("power_cycle 2") == "ok power_cycle 2"
            time.sleep(0.3)
            assert [s["found_al_state"] for s in master.scan()] == ["Init", "PreOp", "Init"]
        for bad, named in (
            ("power_cycle 3", "no slave at position 3: the bus has 3 slave"),
            ("cable 0 loose", "cable takes pulled or plugged"),
            ("cable 0", "usage: cable POSITION pulled|plugged"),
            ("drop -1", "FRAMES must be a whole number 0 or more"),
            ("corrupt x", "FRAMES must be a whole number 0 or more"),
            ("wrong_wkc", "usage: wrong_wkc FRAMES"),
        ):
            reply = command(bad)
            assert reply.startswith("error: ") and named in reply, (bad, reply)
        assert (
            "power_cycle POSITION | homing POSITION ok|error|no_reference | cable POSITION pulled|plugged"
            in command("help")
        )
    finally:
        if sim.poll() is None:
            sim.kill()
            sim.wait()
