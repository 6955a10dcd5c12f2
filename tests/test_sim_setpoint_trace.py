"""`akd-sim --setpoint-trace FILE`: every change of the set-points the virtual AKD receives, read back from the file
after a real Master and Cycle over UDP enabled the drive and moved its target.

The waits have deadlines only so that a failure does not hang; nothing here asserts how fast anything happens. The
virtual AKD judges missed frames by the frames the line lost (`--missed lost`): this shared host's scheduling must
not fault it (F125).
"""

from __future__ import annotations

import itertools
import json
import signal
import struct
import subprocess
import time

from akd_ros._native import Ds402State

from akd_ros import _native
from support.netns import console_script, udp_port_bound
from support.waiting import wait_for

TRACED = ("target_position", "target_velocity", "target_torque", "controlword", "modes_of_operation")
"""The set-points the trace carries, all of them in the default mapping."""
CSP = 8


def position_actual(cycle) -> int:
    """The actual position 0x6064 of drive 0 in the last cycle's inputs."""
    (offset,) = [at for index, _, _, at in cycle.mapping(0)["inputs"] if index == 0x6064]
    return struct.unpack_from("<i", cycle.snapshot()["inputs"][0], offset)[0]


def after_cycles(cycle, count: int) -> None:
    start = cycle.snapshot()["cycle"]
    wait_for(f"{count} cycles", lambda: cycle.snapshot()["cycle"] >= start + count, 30)


def akd_sim(udp_port: int, *options: str) -> subprocess.Popen:
    argv = [*console_script("akd-sim"), "--udp", f"127.0.0.1:{udp_port}", "--missed", "lost", *options]
    return subprocess.Popen(argv, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def test_the_trace_holds_every_change_of_the_set_points_in_the_order_the_frames_came(udp_port, tmp_path):
    trace = tmp_path / "setpoints.jsonl"
    sim = akd_sim(udp_port, "--setpoint-trace", str(trace))
    commanded: list[tuple[int, int]] = []
    """(the system clock right before set_object, the target position given) of each target."""
    try:
        wait_for("akd-sim bound", lambda: udp_port_bound(udp_port) or sim.poll() is not None, 10)
        with _native.Master(f"udp://127.0.0.1:{udp_port}") as master:
            master.scan()
            master.request_state("preop")
            master.configure_pdo(0, *_native.DEFAULT_MAPPING)
            master.sdo_write(0, 0x6060, 0, _native.encode_value(0x6060, 0, CSP))
            master.request_state("op")
            with _native.Cycle(master, 0.001) as cycle:
                cycle.set_object(0, 0x6060, 0, _native.encode_value(0x6060, 0, CSP))
                cycle.enable(0)
                cycle.wait_state(0, Ds402State.OPERATION_ENABLED)
                here = position_actual(cycle)
                for step in (1, 2, 3):
                    target = here + 1000 * step
                    commanded.append((time.time_ns(), target))
                    cycle.set_object(0, 0x607A, 0, _native.encode_value(0x607A, 0, target))
                    after_cycles(cycle, 20)
                cycle.disable(0)
                cycle.wait_state(0, Ds402State.SWITCH_ON_DISABLED)
        sim.send_signal(signal.SIGTERM)
        out, err = sim.communicate(timeout=10)
    finally:
        if sim.poll() is None:
            sim.kill()
            sim.wait()
    assert sim.returncode == 0, err
    records = [json.loads(line) for line in trace.read_text().splitlines()]
    end = records.pop()
    assert end == {"end": {"changes": len(records), "dropped": 0}}
    assert f"akd-sim: set-point trace {trace}: {len(records)} changes, 0 dropped\n" in out
    assert out.endswith("akd-sim: stopped\n")

    # Changes only: each line names what differs from the line before; the first carries every value.
    assert records[0]["changed"] == list(TRACED)
    for before, now in itertools.pairwise(records):
        assert now["changed"] == [name for name in TRACED if now[name] != before[name]], now
        assert now["changed"]
    assert all(r["drive"] == 0 for r in records)
    # Op comes with the outputs still zero; then the mode the Cycle was given.
    modes = [r["modes_of_operation"] for r in records if "modes_of_operation" in r["changed"]]
    assert modes[-1] == CSP and set(modes) <= {0, CSP}, modes
    # In the order the frames came, on clocks that do not step back.
    for key in ("frame", "monotonic_ns"):
        assert all(a[key] < b[key] for a, b in itertools.pairwise(records)), key
    assert all(0 <= r["index"] < 256 for r in records)

    # The enable went out as controlword Shutdown, Switch on, Enable operation, and disable as Disable voltage.
    controlwords = [r["controlword"] for r in records if "controlword" in r["changed"]]
    assert [c for c in controlwords if c in (0x06, 0x07, 0x0F)][-3:] == [0x06, 0x07, 0x0F]
    assert controlwords[-1] == 0x00
    # Each target in the order given, in a frame received after it was given; the drive followed.
    targets = [r for r in records if "target_position" in r["changed"]]
    given = [target for _, target in commanded]
    carrying = [next(r for r in targets if r["target_position"] == target) for target in given]
    assert [r["frame"] for r in carrying] == sorted(r["frame"] for r in carrying)
    assert all(r["realtime_ns"] > sent for r, (sent, _) in zip(carrying, commanded, strict=True))
    assert abs(records[-1]["position"] - given[-1]) < 100


def test_a_trace_that_cannot_be_created_is_named_without_a_traceback(udp_port, tmp_path):
    path = tmp_path / "no-such-folder" / "setpoints.jsonl"
    sim = akd_sim(udp_port, "--setpoint-trace", str(path))
    _, err = sim.communicate(timeout=30)
    assert sim.returncode == 1
    # Run as root, akd-sim says first that it need not be.
    (error,) = [line for line in err.splitlines() if not line.startswith("akd-sim: warning: running as root")]
    assert error.startswith(f"akd-sim: error: creating set-point trace {path}: No such file or directory"), err
