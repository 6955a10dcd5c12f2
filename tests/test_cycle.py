"""The real-time cycle thread (akd_ros._native.Cycle) against the in-process virtual AKD.

The thread owns the master while it runs; Python writes set-points and reads snapshots
lock-free while it does other work. No timing is asserted here: period jitter and CPU time per
cycle are printed by bench/cycle_jitter.py.

The virtual AKDs judge missed frames by the frames the line lost (`?missed=lost`): nothing here is about this shared
host's scheduling, so a cycle it runs late must not fault them (F125) as it would a real drive.
"""

from __future__ import annotations

import itertools
import struct
import threading
import time
from pathlib import Path

import pytest

from akd_ros import _native

# The default fixed mappings: 0x1701 outputs = interpolation set-point 0x60C1:01 (i32) and
# controlword (u16); 0x1B01 inputs = internal position 0x6063 (i32) and statusword (u16).
OUTPUTS = struct.Struct("<iH")
INPUTS = struct.Struct("<iH")


@pytest.fixture
def master():
    with _native.Master("sim?missed=lost") as m:
        m.scan()
        m.request_state("op")
        yield m


def wait_for_cycle(cycle, at_least: int, timeout: float = 30.0) -> dict:
    deadline = time.monotonic() + timeout
    while (snapshot := cycle.snapshot())["cycle"] < at_least:
        assert time.monotonic() < deadline, f"the cycle stopped at {snapshot['cycle']}"
        time.sleep(0.005)
    return snapshot


def wait_for_statusword(cycle, mask: int, value: int, timeout: float = 5.0) -> int:
    """Waits until the drive's statusword in the snapshots matches `value` under `mask`."""
    deadline = time.monotonic() + timeout
    while (statusword := INPUTS.unpack(cycle.snapshot()["inputs"][0])[1]) & mask != value:
        assert time.monotonic() < deadline, f"statusword 0x{statusword:04X}, wanted 0x{value:04X}/0x{mask:04X}"
        time.sleep(0.005)
    return statusword


def busy_work(stop: threading.Event) -> int:
    """Pure-Python work holding the GIL as much as the interpreter lets it."""
    n = 0
    while not stop.is_set():
        n += sum(i * i for i in range(2000)) & 1
    return n


@pytest.mark.parametrize("pipelined", [False, True], ids=["waiting", "pipelined"])
def test_2000_cycles_with_python_busy_reach_the_drive(master, pipelined):
    expected_wkc = master.expected_wkc
    with _native.Cycle(master, 0.001, realtime=_native.RealTime(pipelined=pipelined)) as cycle:
        assert cycle.running and cycle.period == pytest.approx(0.001)
        stop = threading.Event()
        workers = [threading.Thread(target=busy_work, args=(stop,)) for _ in range(2)]
        for w in workers:
            w.start()
        snapshots = []
        setpoint = 0
        try:
            while (s := cycle.snapshot())["cycle"] < 2000:
                snapshots.append(s)
                setpoint += 1
                cycle.set_outputs(0, OUTPUTS.pack(setpoint, 0x0006))
                assert cycle.outputs(0) == OUTPUTS.pack(setpoint, 0x0006)
                time.sleep(0.002)
            # The controlword went out: the drive answers Shutdown with Ready to Switch On in
            # the statusword the inputs bring back, and a zero controlword with Switch On
            # Disabled (CiA 402).
            wait_for_statusword(cycle, 0x006F, 0x0021)
            cycle.set_outputs(0, OUTPUTS.pack(setpoint, 0x0000))
            wait_for_statusword(cycle, 0x004F, 0x0040)
            cycle.set_outputs(0, OUTPUTS.pack(setpoint, 0x0006))
            wait_for_statusword(cycle, 0x006F, 0x0021)
        finally:
            stop.set()
            for w in workers:
                w.join()
    assert not cycle.running
    # After stop, the final snapshot and statistics stay readable and agree.
    stats, last, histograms = cycle.stats(), cycle.snapshot(), cycle.histograms()
    assert last["cycle"] == stats["cycles"]
    for name in ("period", "wake_latency", "exchange"):
        assert sum(count for _, count in histograms[name]) == stats[name]["count"]
    # Each snapshot is one cycle's: good working counter, fresh inputs of the mapping's size,
    # cycle count and time moving forward together.
    for s in snapshots[1:]:
        assert (s["wkc"], s["fresh"]) == (expected_wkc, True), s
        assert len(s["inputs"]) == 1 and len(s["inputs"][0]) == INPUTS.size
    for a, b in itertools.pairwise(snapshots):
        assert b["cycle"] >= a["cycle"]
        assert (b["time_ns"] > a["time_ns"]) == (b["cycle"] > a["cycle"])
    assert last["cycle"] >= 2000
    assert stats["cycles"] >= 2000
    assert (stats["lost_frames"], stats["wkc_errors"], stats["other_errors"]) == (0, 0, 0)
    for name in ("period", "wake_latency", "exchange"):
        h = stats[name]
        assert h["count"] >= 1999, (name, h)
        assert 0 < h["min_ns"] <= h["mean_ns"] <= h["max_ns"], (name, h)
        assert h["min_ns"] <= h["p99_ns"] <= h["max_ns"], (name, h)
    # The master is back, the drive stayed in Op, and the set-points reached its objects.
    assert master.al_status(0) == ("Op", 0, "no error")
    assert master.sdo_read(0, 0x60C1, 1) == struct.pack("<i", setpoint)
    assert master.sdo_read(0, 0x6040, 0) == struct.pack("<H", 0x0006)
    # The snapshot's statusword is the drive's.
    assert last["inputs"][0][4:] == master.sdo_read(0, 0x6041, 0)
    assert master.stats()["cycles"] >= stats["cycles"]
    master.request_state("init")


def test_the_master_is_unusable_while_cycling_and_back_after_stop(master):
    cycle = _native.Cycle(master, 0.0005)
    with pytest.raises(_native.ConfigError, match="handed to a Cycle"):
        master.exchange()
    with pytest.raises(_native.ConfigError, match="handed to a Cycle"):
        _native.Cycle(master, 0.001)
    wait_for_cycle(cycle, 10)
    cycle.stop()
    cycle.stop()  # a second stop does nothing
    with pytest.raises(_native.ConfigError, match="the cycle is stopped"):
        cycle.set_outputs(0, bytes(6))
    assert master.exchange() == master.expected_wkc


def test_a_forgotten_cycle_hands_the_master_back(master):
    cycle = _native.Cycle(master, 0.001)
    wait_for_cycle(cycle, 5)
    del cycle
    assert master.exchange() == master.expected_wkc


@pytest.mark.parametrize("period", [0.0002, 0.011, -1.0, float("nan")])
def test_a_period_out_of_range_is_refused_and_the_master_kept(master, period):
    with pytest.raises(_native.ConfigError, match=r"allowed range"):
        _native.Cycle(master, period)
    assert master.exchange() == master.expected_wkc


def test_bad_settings_and_outputs_are_refused_by_name(master):
    with pytest.raises(_native.ConfigError, match=r"priority 0 is outside 1..=99"):
        _native.RealTime(priority=0)
    with pytest.raises(_native.ConfigError, match="CPU 4096 does not exist"):
        _native.RealTime(cpu=4096)
    with _native.Cycle(master, 0.001) as cycle:
        with pytest.raises(_native.ConfigError, match="6 bytes of outputs, 2 given"):
            cycle.set_outputs(0, b"\x01\x02")
        with pytest.raises(_native.ConfigError, match="slave 3 has no process data"):
            cycle.set_outputs(3, bytes(6))


def test_a_master_without_process_data_is_refused():
    with _native.Master("sim?missed=lost") as m:
        m.scan()
        with pytest.raises(_native.ConfigError, match="no process image"):
            _native.Cycle(m, 0.001)
        assert m.slave_count == 1


def test_real_time_settings_apply_or_warn_by_name(master):
    # Permitted or not depends on the machine: either way the cycle runs, and each refusal
    # is one warning naming the setting.
    with _native.Cycle(master, 0.001, realtime=_native.RealTime(priority=10, cpu=0)) as cycle:
        wait_for_cycle(cycle, 10)
        for w in cycle.warnings:
            assert w.startswith(("SCHED_FIFO priority 10 not set", "CPU affinity to CPU 0 not set")), w
        assert cycle.stats()["lost_frames"] == 0


def cpu_latency_target() -> int | None:
    """The CPUs' wake-up latency the kernel's PM QoS holds now, µs; None where it cannot be read."""
    try:
        return struct.unpack("i", Path("/dev/cpu_dma_latency").read_bytes()[:4])[0]
    except OSError:
        return None


def test_a_cpu_latency_is_held_while_the_cycle_runs_or_refused_by_name(master):
    before = cpu_latency_target()
    with _native.Cycle(master, 0.001, realtime=_native.RealTime(cpu_latency_us=7)) as cycle:
        wait_for_cycle(cycle, 10)
        if cycle.warnings:
            # Not permitted here (no write access): one warning naming the setting and the file; the cycle runs.
            (warning,) = cycle.warnings
            assert warning.startswith("CPU wake-up latency of 7 µs not held (/dev/cpu_dma_latency"), warning
        else:
            assert cpu_latency_target() == 7
        assert cycle.stats()["lost_frames"] == 0
    # Released with the cycle: the kernel's target is what it was (another holder's, or none).
    assert cpu_latency_target() == before


@pytest.mark.parametrize("us", [-1, 1_000_001])
def test_a_cpu_latency_out_of_range_is_refused_with_the_range(master, us):
    refused = rf"CPU wake-up latency {us} µs is outside the allowed range 0\.\.=1000000 µs"
    with pytest.raises(_native.ConfigError, match=refused):
        _native.RealTime(cpu_latency_us=us)
