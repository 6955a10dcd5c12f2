"""Soak of the in-process bus: the real cycle thread (`_native.Cycle`) with six virtual AKDs ("sim:6") for ten million
cycles (`--cycles`), random command streams and injected faults; resident memory stays flat after warm-up and every
cycle is accounted for. Exits 1 when RSS grew past the bound or a counter does not add up, 2 when the bus did not come
back, 3 on a hang (no cycle for `--hang` seconds: every thread's stack is printed).

How it runs: the cycle thread at its minimum period (250 µs, 4 kHz: 10M cycles take about 42 min), in real time,
as a user's program runs it; nothing is sped up. `--cycles` makes a shorter soak. The machine's other load makes
overruns (deadlines skipped, counted, not cycles) and, past seven missed frames, F125 in an enabled drive: expected,
reset and gone on.

    nice -n 10 .venv/bin/python bench/soak.py [--cycles 10000000] [--seed N] [--period 0.00025]
        [--report-every 500000] [--warmup 1000000] [--rss-bound-mib 2] [--fault-every 1.0] [--priority 80]

Drives 0 and 1 run interpolated position, 2 cyclic synchronous position (0..2 also play joint trajectories
together), 3 profile position (set-point handshake), 4 profile velocity, 5 profile torque. The command stream (one
action every 1..8 ms) asks for enable, disable, quick stop and fault reset, writes set-points within the limits below
(a position a small step from the actual one or, in profile position, anywhere within ±2 revolutions; a velocity
within ±0.5 rev/s; a torque within ±5 % of peak), plays trajectories; a thread beside it reads objects by SDO through
the cycle. About every `--fault-every` seconds one fault is injected (`Master.simulator`): frames dropped (1, 3, 7, 8
or 100), replies corrupted or with wrong working counters (1..10), a drive fault (F439, F235, F125, F706), a drive
power-cycled, or a cable pulled and replugged 5..200 ms later. A drive power-cycled or unplugged is left to the
master's own recovery (`cycle/recovery.rs`: readdressed, re-mapped, back in Op beside the running cycle); one not back
within 5 s, or any other stall of the bus (no good exchange for 0.2 s with no burst pending), is a finding and ends
the cycle's segment: the cycle is stopped, the line re-scanned, re-mapped and taken to Op, a new Cycle started.
The seed (printed) makes the sequence of commands and faults the same again; their interleaving with the cycle thread
is the machine's.

What is checked, for every segment (one Cycle's life):
- the cycle's per-cycle records (drive 0's, `Cycle.samples`, none dropped) number one per cycle, consecutive:
  records == cycles;
- every cycle is either fresh (exchanged, working counter right) or stale, and every stale cycle is counted as the
  master counts it, by what its record says (`lost`; its working counter alone does not tell, a reply no slave took
  has 0 as a lost frame has): lost cycles (a frame of the cycle did not come back, or its return could not be read)
  == lost_frames + other_errors, one count each; the others, with a wrong working counter (0 included),
  <= wkc_errors, which counts frames: beyond the stale cycles only those of a cycle's second frame (`watch_frames`,
  every slave's AL and mailbox status read apart after the broadcast reads saw a change) in which a slave did not
  answer, in a stale cycle or a fresh one: wkc_errors - stale cycles with a wrong working counter <= watch_frames;
  the mailbox frames (SDO, error code) beside the cycle are counted apart: acyclic_lost_frames + acyclic_wkc_errors
  <= the master's frames - its cyclic exchanges;
- the master's own counters (`Master.stats`, before and after) moved as the cycle's: one cyclic exchange per cycle,
  its lost frames and wrong working counters those of the cyclic frame and the frames beside it together;
and at the end, over the whole run, the virtual AKDs' own count (`Simulator.line_counts`) against the master's:
every frame the master sent reached the line, and every frame the master counted lost was one the line lost or
corrupted.
"""

from __future__ import annotations

import argparse
import ctypes
import faulthandler
import os
import random
import sys
import threading
import time
from dataclasses import dataclass, field

from akd_ros import _native

COUNT = 6
MODES = {m.name: m.code for m in _native.MODES_OF_OPERATION}
DRIVE_MODES = [
    "interpolated_position",
    "interpolated_position",
    "cyclic_synchronous_position",
    "profile_position",
    "profile_velocity",
    "profile_torque",
]
TRAJECTORY_DRIVES = [0, 1, 2]
REV = 1 << 20
"""Counts per revolution."""
POSITION_LIMIT = 2 * REV
"""Position set-points stay within ±2 revolutions."""
STEP = 500
"""Largest position step from the actual position in interpolated and cyclic synchronous position (counts)."""
VELOCITY_LIMIT = REV // 2
TORQUE_LIMIT = 50
"""0.1 % of peak torque."""
TARGETS = {
    "interpolated_position": (0x60C1, 1),
    "cyclic_synchronous_position": (0x607A, 0),
    "profile_position": (0x607A, 0),
    "profile_velocity": (0x60FF, 0),
    "profile_torque": (0x6071, 0),
}
SDO_OBJECTS = [(0x6041, 0), (0x6064, 0), (0x1018, 1), (0x6060, 0), (0x603F, 0), (0x6061, 0)]
FAULT_NAMES = ["following_error", "over_temperature", "sync_lost", "setpoints_missing"]
DRAIN_EVERY = 0.05
"""Seconds between takes of the per-cycle records: the ring holds 8192 records, 1365 cycles of six drives."""
STALL = 0.2
LOST_SEEN = 0.02
RECOVERY_WAIT = 5.0
"""How long a power-cycled or unplugged drive may take to be brought back by the master's own recovery (a restore
takes ~0.25 s at 1 kHz, one mailbox frame a cycle) before the soak counts it as not recovered and restarts the line."""
"""Seconds without a good exchange, no burst pending, after which the bus is brought up again."""
MIB = 1024 * 1024


class _Mallinfo2(ctypes.Structure):
    _fields_ = [
        (name, ctypes.c_size_t)
        for name in ("arena", "ordblks", "smblks", "hblks", "hblkhd", "usmblks", "fsmblks", "uordblks", "fordblks")
    ] + [("keepcost", ctypes.c_size_t)]


def heap_in_use() -> int | None:
    """Bytes the C allocator has handed out and not taken back (glibc's mallinfo2: uordblks + hblkhd), or None
    without it: growing with a flat count here is fragmentation, growing with it is a leak."""
    try:
        mallinfo2 = ctypes.CDLL(None).mallinfo2
    except (AttributeError, OSError):
        return None
    mallinfo2.restype = _Mallinfo2
    info = mallinfo2()
    return info.uordblks + info.hblkhd


def rss_bytes() -> int:
    """This process's resident memory, from /proc/self/status VmRSS."""
    with open("/proc/self/status") as status:
        for line in status:
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) * 1024
    raise RuntimeError("no VmRSS in /proc/self/status")


@dataclass
class Segment:
    """One Cycle's life and what was counted of it."""

    cycle: object
    master_before: dict
    records: int = 0
    fresh: int = 0
    stale_lost: int = 0
    stale_wkc: int = 0
    last_record: int = 0
    gaps: int = 0
    events: dict = field(default_factory=dict)

    def drain(self) -> None:
        columns = self.cycle.samples()
        for slave, cycle, fresh, lost in zip(
            columns["slave"], columns["cycle"], columns["fresh"], columns["lost"], strict=True
        ):
            if slave != 0:
                continue
            self.records += 1
            self.gaps += cycle != self.last_record + 1
            self.last_record = cycle
            if fresh:
                self.fresh += 1
            elif lost:
                self.stale_lost += 1
            else:
                self.stale_wkc += 1
        for event in self.cycle.events():
            fault = event.get("fault")
            key = event["kind"] if fault is None else f"fault:{fault.source}:{fault.code:#06x}"
            self.events[key] = self.events.get(key, 0) + 1

    def check(self, master_after: dict) -> list[str]:
        """What does not add up in this finished segment, one sentence each."""
        s = self.cycle.stats()
        cycles, lost, wkc, other, watch = (
            s[k] for k in ("cycles", "lost_frames", "wkc_errors", "other_errors", "watch_frames")
        )
        acyclic = (s["acyclic_lost_frames"], s["acyclic_wkc_errors"])
        before, after = self.master_before, master_after
        stale = self.stale_lost + self.stale_wkc
        acyclic_frames = (after["frames"] - before["frames"]) - (after["cycles"] - before["cycles"])
        problems = []
        if self.cycle.samples_dropped:
            problems.append(f"{self.cycle.samples_dropped} per-cycle records dropped: not every cycle was seen")
        if self.records != cycles or self.gaps:
            problems.append(f"{self.records} records of drive 0 ({self.gaps} gaps) for {cycles} cycles")
        if self.fresh + stale != self.records:
            problems.append(f"fresh {self.fresh} + stale {stale} != records {self.records}")
        if self.stale_lost != lost + other:
            problems.append(f"{self.stale_lost} cycles lost != lost_frames {lost} + other_errors {other}")
        if self.stale_wkc > wkc:
            problems.append(f"{self.stale_wkc} stale cycles with a wrong working counter > wkc_errors {wkc}")
        if wkc - self.stale_wkc > watch:
            problems.append(
                f"wkc_errors {wkc} - {self.stale_wkc} stale cycles with a wrong working counter > {watch} second "
                "frames: wrong working counters no frame of the cycle explains"
            )
        if sum(acyclic) > acyclic_frames:
            problems.append(f"{sum(acyclic)} lost or wrong frames beside the cycle > {acyclic_frames} sent")
        if after["cycles"] - before["cycles"] != cycles:
            problems.append(f"the master exchanged {after['cycles'] - before['cycles']} times in {cycles} cycles")
        if (after["lost_frames"] - before["lost_frames"], after["wkc_errors"] - before["wkc_errors"]) != (
            lost + acyclic[0],
            wkc + acyclic[1],
        ):
            problems.append("the master's lost frames or wrong working counters are not the cycle's")
        return problems


class Soak:
    def __init__(self, args) -> None:
        self.args = args
        self.rng = random.Random(args.seed)
        self.master = _native.Master(f"sim:{COUNT}")
        self.simulator = self.master.simulator
        self.segment: Segment | None = None
        self.done = {
            "cycles": 0,
            "lost_frames": 0,
            "wkc_errors": 0,
            "other_errors": 0,
            "watch_frames": 0,
            "overruns": 0,
            "f125_stalls": 0,
        }
        self.totals = {"fresh": 0, "stale_lost": 0, "stale_wkc": 0, "segments": 0}
        self.events: dict[str, int] = {}
        self.injected: dict[str, int] = {}
        self.commands: dict[str, int] = {}
        self.sdo = {"ok": 0, "failed": 0}
        self.recoveries: dict[str, int] = {}
        self.problems: list[str] = []
        self.burst_until = 0.0
        self.cable_out: tuple[int, float] | None = None
        self.power_cycled = False
        """A drive was power-cycled in this segment: the bus stays stale until it is brought up again."""
        self.cable_pulled = False
        """A cable was pulled and no good exchange was seen since it was replugged."""
        self.last_good = time.monotonic()
        self.lost_at = 0.0
        """When the last drive was power-cycled or unplugged: a fresh exchange in the first LOST_SEEN after it is of a
        cycle before the drive was found gone, not its recovery."""
        self.heartbeat = time.monotonic()

    # --- the bus ----------------------------------------------------------------------------------------------------

    def bring_up(self) -> None:
        """Scans the line, maps every drive with its mode, takes it to Op and starts a Cycle (a new segment)."""
        m = self.master
        for attempt in range(5):
            try:
                m.scan()
                m.request_state("preop")
                rx, tx = _native.DEFAULT_MAPPING
                for position, mode in enumerate(DRIVE_MODES):
                    m.configure_pdo(position, rx, tx)
                    m.set_mode(position, MODES[mode])
                m.configure_sm2_sync(round(self.args.period * 1e9))
                m.request_state("op")
                before = m.stats()
                cycle = _native.Cycle(m, self.args.period, realtime=_native.RealTime(priority=self.args.priority))
                for drive in TRAJECTORY_DRIVES:
                    cycle.set_joint_limits(drive, f"drive {drive}", (-POSITION_LIMIT, POSITION_LIMIT))
                break
            except _native.EtherCatError as e:
                print(f"soak: bring-up attempt {attempt + 1} failed: {e}", flush=True)
        else:
            raise SystemExit(self.fail(2, "the bus did not come back after five attempts"))
        self.segment = Segment(cycle, before)
        self.last_good = time.monotonic()
        self.power_cycled = False

    def end_segment(self) -> None:
        """Stops the cycle, takes its last records and checks what it counted."""
        segment, self.segment = self.segment, None
        segment.cycle.stop()
        segment.drain()
        after = self.master.stats()
        for problem in segment.check(after):
            self.problems.append(f"segment {self.totals['segments'] + 1}: {problem}")
        s = segment.cycle.stats()
        for key in self.done:
            self.done[key] += s[key]
        self.totals["fresh"] += segment.fresh
        self.totals["stale_lost"] += segment.stale_lost
        self.totals["stale_wkc"] += segment.stale_wkc
        self.totals["segments"] += 1
        for key, n in segment.events.items():
            self.events[key] = self.events.get(key, 0) + n

    def cycles(self) -> int:
        return self.done["cycles"] + (self.segment.cycle.stats()["cycles"] if self.segment else 0)

    def recover(self, why: str) -> None:
        self.recoveries[why] = self.recoveries.get(why, 0) + 1
        self.sdo_pause.set()
        self.sdo_idle.wait()
        self.end_segment()
        self.bring_up()
        self.sdo_pause.clear()

    # --- the command stream -----------------------------------------------------------------------------------------

    def count(self, table: dict, key: str) -> None:
        table[key] = table.get(key, 0) + 1

    def command(self) -> None:
        cycle, rng = self.segment.cycle, self.rng
        drive = rng.randrange(COUNT)
        roll = rng.random()
        if roll < 0.15:
            request = rng.choices(["enable", "disable", "quick_stop", "reset_fault"], weights=[6, 1, 1, 3])[0]
            getattr(cycle, request)(drive)
            self.count(self.commands, request)
        elif roll < 0.18:
            self.trajectory()
        else:
            self.set_point(drive)
        # A drive in Fault is reset now and then, so that the stream goes on.
        if cycle.drive_status(drive).state == _native.Ds402State.FAULT and rng.random() < 0.3:
            cycle.reset_fault(drive)
            self.count(self.commands, "reset_fault")

    def set_point(self, drive: int) -> None:
        cycle, rng = self.segment.cycle, self.rng
        mode = DRIVE_MODES[drive]
        index, subindex = TARGETS[mode]
        if mode in ("interpolated_position", "cyclic_synchronous_position"):
            actual = cycle.drive_inputs(drive).position_actual or 0
            value = max(-POSITION_LIMIT, min(POSITION_LIMIT, actual + rng.randint(-STEP, STEP)))
        elif mode == "profile_position":
            value = rng.randint(-POSITION_LIMIT, POSITION_LIMIT)
        elif mode == "profile_velocity":
            value = rng.randint(-VELOCITY_LIMIT, VELOCITY_LIMIT)
        else:
            value = rng.randint(-TORQUE_LIMIT, TORQUE_LIMIT)
        try:
            cycle.set_object(drive, index, subindex, _native.encode_value(index, subindex, value))
        except _native.ConfigError:
            # A drive a trajectory drives takes no set-point until the trajectory ends: refused, nothing written.
            self.count(self.commands, f"set_point_refused:{mode}")
            return
        if mode == "profile_position" and cycle.drive_status(drive).state == _native.Ds402State.OPERATION_ENABLED:
            cycle.start_setpoint(drive, 0x30)
        self.count(self.commands, f"set_point:{mode}")

    def trajectory(self) -> None:
        cycle, rng = self.segment.cycle, self.rng
        inputs = cycle.drives_inputs(TRAJECTORY_DRIVES)
        start = [i.position_actual or 0 for i in inputs]
        points = rng.randint(1, 4)
        steps = [round(rng.uniform(0.05, 0.3) * 1e9) for _ in range(points)]
        times = [sum(steps[: k + 1]) for k in range(points)]
        knots = [
            [(max(-POSITION_LIMIT, min(POSITION_LIMIT, s + rng.randint(-20_000, 20_000))), None, None) for s in start]
            for _ in range(points)
        ]
        try:
            cycle.play_trajectory(TRAJECTORY_DRIVES, times, knots)
            self.count(self.commands, "trajectory")
        except _native.ConfigError:
            # A joint not in Operation enabled, or a take-over past its limits: refused before anything moved, as it
            # should be.
            self.count(self.commands, "trajectory_refused")

    def sdo_reads(self, stop: threading.Event) -> None:
        """Reads objects by SDO beside the cycle, pausing while the bus is brought up again."""
        rng = random.Random(self.args.seed + 1)
        while not stop.is_set():
            if self.sdo_pause.is_set():
                self.sdo_idle.set()
                time.sleep(0.005)
                continue
            self.sdo_idle.clear()
            if self.sdo_pause.is_set() or self.segment is None:
                continue
            index, subindex = rng.choice(SDO_OBJECTS)
            try:
                self.segment.cycle.sdo_read(rng.randrange(COUNT), index, subindex)
                self.sdo["ok"] += 1
            except _native.EtherCatError:
                # Lost frames, a power-cycled drive without its mailbox: the transfer fails and says why.
                self.sdo["failed"] += 1
            time.sleep(rng.uniform(0.001, 0.005))
        self.sdo_idle.set()

    # --- faults -----------------------------------------------------------------------------------------------------

    def fault(self) -> None:
        sim, rng, now = self.simulator, self.rng, time.monotonic()
        kind = rng.choices(
            ["drop", "corrupt", "wrong_wkc", "drive_fault", "power_cycle", "cable"], weights=[5, 2, 2, 2, 1, 1]
        )[0]
        if kind == "drop":
            frames = rng.choice([1, 3, 7, 8, 100])
            sim.drop_frames(frames)
        elif kind == "corrupt":
            frames = rng.randint(1, 10)
            sim.corrupt_frames(frames)
        elif kind == "wrong_wkc":
            frames = rng.randint(1, 10)
            sim.wrong_wkc(frames)
        elif kind == "drive_fault":
            sim.inject_fault(rng.randrange(COUNT), rng.choice(FAULT_NAMES))
            frames = 0
        elif kind == "power_cycle":
            sim.power_cycle(rng.randrange(COUNT))
            self.power_cycled = True
            self.lost_at = now
            frames = 0
        else:
            if self.cable_out is not None:
                return
            position = rng.randrange(1, COUNT)
            sim.pull_cable(position)
            self.cable_out = (position, now + rng.uniform(0.005, 0.2))
            self.cable_pulled = True
            self.lost_at = now
            frames = 0
        # Frames go at 1 per period at least; give the burst time to pass before judging a stall.
        self.burst_until = max(self.burst_until, now + frames * self.args.period * 4 + 0.05)
        self.count(self.injected, kind if kind != "drop" else f"drop:{frames}")

    # --- the run ----------------------------------------------------------------------------------------------------

    def fail(self, status: int, why: str) -> int:
        print(f"soak: FAILED: {why}", flush=True)
        return status

    def report(self, label: str) -> int:
        cycles, rss, heap = self.cycles(), rss_bytes(), heap_in_use()
        stats = self.segment.cycle.stats() if self.segment else {}
        heap = "?" if heap is None else f"{heap / MIB:.2f}"
        print(
            f"soak: {label}: cycles {cycles}, {time.monotonic() - self.t0:.0f} s, RSS {rss / MIB:.2f} MiB "
            f"(heap in use {heap} MiB, Python blocks {sys.getallocatedblocks()}), "
            f"segments {self.totals['segments'] + (self.segment is not None)}, "
            f"lost {self.done['lost_frames'] + stats.get('lost_frames', 0)}, "
            f"wkc {self.done['wkc_errors'] + stats.get('wkc_errors', 0)}, "
            f"other {self.done['other_errors'] + stats.get('other_errors', 0)}, "
            f"overruns {self.done['overruns'] + stats.get('overruns', 0)}",
            flush=True,
        )
        return rss

    def run(self) -> int:
        args = self.args
        print(
            f"soak: seed {args.seed}, {args.cycles} cycles of sim:{COUNT} at {args.period * 1e6:.0f} µs "
            f"(real cycle thread, priority {args.priority}), a fault about every {args.fault_every} s, "
            f"warm-up {args.warmup} cycles, RSS bound +{args.rss_bound_mib} MiB after warm-up",
            flush=True,
        )
        self.t0 = time.monotonic()
        rss_start = self.report("start")
        self.sdo_pause, self.sdo_idle = threading.Event(), threading.Event()
        self.bring_up()
        stop = threading.Event()
        sdo = threading.Thread(target=self.sdo_reads, args=(stop,), name="soak-sdo", daemon=True)
        sdo.start()
        rss_warm, rss_max, next_report = None, 0, args.warmup
        last_drain = next_fault = time.monotonic()
        last_cycles, last_progress = 0, time.monotonic()
        threading.Thread(target=self.watchdog, name="soak-watchdog", daemon=True).start()
        while (cycles := self.cycles()) < args.cycles:
            now = self.heartbeat = time.monotonic()
            # Hang: the cycle count has not moved for --hang seconds.
            if cycles != last_cycles:
                last_cycles, last_progress = cycles, now
            elif now - last_progress > args.hang:
                faulthandler.dump_traceback(all_threads=True)
                return self.fail(3, f"no cycle for {args.hang} s at cycle {cycles}")
            if now - last_drain >= DRAIN_EVERY:
                self.segment.drain()
                last_drain = now
            if now >= next_fault:
                self.fault()
                next_fault = now + self.rng.expovariate(1 / args.fault_every)
            if self.cable_out is not None and now >= self.cable_out[1]:
                self.simulator.replug_cable(self.cable_out[0])
                self.cable_out = None
                self.burst_until = max(self.burst_until, now + 0.05)
            self.command()
            if self.segment.cycle.snapshot()["fresh"]:
                if (self.power_cycled or self.cable_pulled) and now - self.lost_at > LOST_SEEN:
                    why = "power cycle" if self.power_cycled else "cable pulled"
                    self.recoveries[f"{why}, by the master"] = self.recoveries.get(f"{why}, by the master", 0) + 1
                    self.power_cycled = False
                self.last_good = now
                self.cable_pulled = self.cable_pulled and self.cable_out is not None
            elif (self.power_cycled or self.cable_pulled) and now - self.last_good <= RECOVERY_WAIT:
                pass  # the master's recovery brings the drive back beside the cycle
            elif now - self.last_good > STALL and now > self.burst_until and self.cable_out is None:
                if self.power_cycled or self.cable_pulled:
                    why = "power cycle" if self.power_cycled else "cable pulled"
                    self.problems.append(f"a drive was not back {RECOVERY_WAIT} s after a {why} at cycle {cycles}")
                    self.recover(why)
                else:
                    self.problems.append(f"the bus stalled at cycle {cycles} with nothing injected to explain it")
                    self.recover("unexplained stall")
                self.cable_pulled = False
                last_drain = time.monotonic()
            if cycles >= next_report:
                rss = self.report("warm-up done" if rss_warm is None else "progress")
                if rss_warm is None:
                    rss_warm = rss
                rss_max = max(rss_max, rss)
                next_report += args.report_every
            time.sleep(self.rng.uniform(0.001, 0.008))
        stop.set()
        self.sdo_pause.set()
        sdo.join(timeout=5)
        if self.cable_out is not None:
            self.simulator.replug_cable(self.cable_out[0])
        for burst in (self.simulator.drop_frames, self.simulator.corrupt_frames, self.simulator.wrong_wkc):
            burst(0)
        self.end_segment()
        rss_end = self.report("end")
        if rss_warm is None:
            rss_warm = rss_end
        rss_max = max(rss_max, rss_end)
        self.check_line()
        self.summary(rss_start, rss_warm, rss_max, rss_end)
        self.master.close()
        growth = rss_max - rss_warm
        status = 0
        if growth > args.rss_bound_mib * MIB:
            status = self.fail(1, f"RSS grew {growth / MIB:.2f} MiB after warm-up, past +{args.rss_bound_mib} MiB")
        if self.problems:
            for problem in self.problems:
                print(f"soak: does not add up: {problem}", flush=True)
            status = status or self.fail(1, f"{len(self.problems)} counter check(s) failed")
        if status == 0:
            print("soak: OK: RSS within the bound after warm-up, every cycle and frame accounted for", flush=True)
        return status

    def watchdog(self) -> None:
        """A hang inside a call (stopping a cycle, bringing the bus up): the loop's heartbeat stops."""
        while True:
            time.sleep(1.0)
            if time.monotonic() - self.heartbeat > self.args.hang:
                faulthandler.dump_traceback(all_threads=True)
                self.fail(3, f"the soak's loop made no progress for {self.args.hang} s")
                os._exit(3)

    def check_line(self) -> None:
        """The virtual AKDs' own count against the master's, the bus quiet: one register read at a time until the
        query of the line's counts is answered after one of them (counted in by both)."""
        answer: dict = {}

        def ask() -> None:
            answer.update(self.simulator.line_counts(timeout=5.0))

        asking = threading.Thread(target=ask)
        asking.start()
        while asking.is_alive():
            self.master.al_status(0)
            asking.join(timeout=1.0)
        line, master = answer, self.master.stats()
        print(f"soak: line (virtual AKDs' count): {line}; master: {master}", flush=True)
        if line.get("frames") != master["frames"]:
            self.problems.append(f"the master sent {master['frames']} frames, the line carried {line.get('frames')}")
        if line.get("lost", 0) + line.get("corrupted", 0) != master["lost_frames"]:
            self.problems.append(
                f"the master counted {master['lost_frames']} frames lost, the line lost {line.get('lost')} and "
                f"corrupted {line.get('corrupted')}"
            )

    def summary(self, rss_start: int, rss_warm: int, rss_max: int, rss_end: int) -> None:
        t = self.totals
        print(
            f"soak: {self.done['cycles']} cycles in {time.monotonic() - self.t0:.0f} s over {t['segments']} segments: "
            f"fresh {t['fresh']}, stale lost {t['stale_lost']}, stale with a wrong working counter {t['stale_wkc']}; "
            f"cycle counters lost {self.done['lost_frames']}, wkc {self.done['wkc_errors']}, "
            f"other {self.done['other_errors']}, second frames {self.done['watch_frames']}, "
            f"overruns {self.done['overruns']}, would-be F125 {self.done['f125_stalls']}",
            flush=True,
        )
        print(
            f"soak: RSS start {rss_start / MIB:.2f} MiB, after warm-up {rss_warm / MIB:.2f}, max after warm-up "
            f"{rss_max / MIB:.2f}, end {rss_end / MIB:.2f} (growth {(rss_max - rss_warm) / 1024:.0f} KiB)",
            flush=True,
        )
        print(f"soak: injected {dict(sorted(self.injected.items()))}", flush=True)
        print(f"soak: commands {dict(sorted(self.commands.items()))}, SDO reads {self.sdo}", flush=True)
        print(f"soak: events {dict(sorted(self.events.items()))}, recoveries {self.recoveries}", flush=True)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cycles", type=int, default=10_000_000, help="cycles to run (all segments together)")
    parser.add_argument("--seed", type=int, default=None, help="seed of the commands and faults (default: random)")
    parser.add_argument("--period", type=float, default=0.00025, help="cycle period in s (0.00025..0.01)")
    parser.add_argument("--report-every", type=int, default=500_000, help="cycles between RSS reports")
    parser.add_argument("--warmup", type=int, default=1_000_000, help="cycles before RSS is taken as the base")
    parser.add_argument("--rss-bound-mib", type=float, default=2.0, help="allowed RSS growth after warm-up, MiB")
    parser.add_argument("--fault-every", type=float, default=1.0, help="mean seconds between injected faults")
    parser.add_argument("--priority", type=int, default=None, help="the cycle thread's SCHED_FIFO priority")
    parser.add_argument("--hang", type=float, default=30.0, help="seconds without a cycle that count as a hang")
    args = parser.parse_args()
    if args.seed is None:
        args.seed = int.from_bytes(os.urandom(4), "little")
    return Soak(args).run()


if __name__ == "__main__":
    sys.exit(main())
