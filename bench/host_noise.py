"""The six-axis virtual robot of config/akd_sim_6axis.yaml following trajectories with every CPU loaded: how many it
completes, how many F125 a real AKD would have raised, how many the virtual ones raised, the frames missed and the
worst stall, with the shipped settings (missed=warn, rt.priority 80) and without them.

Not a test: what it measures is this machine's scheduling under load; it prints, it never asserts. Each variant
builds the Bus as akd_node builds it from the config (its joints, units, limits, cycle time and rt.* parameters, the
link and rt.priority as the variant says), enables the six joints and plays joint trajectories back to back through
the cycle thread, as ~/joint_trajectory does: each from where the joints stand to a random point within ±1 rad of 0
(inside every joint's limits) in 1.5 s, cubic, at rest at the end, the next as soon as it is done. A trajectory the
cycle thread aborted (a drive faulted) or that did not finish within 5 s counts as failed; the drives are then reset
and enabled again and the next one played. Meanwhile `stress-ng --cpu 0` loads every CPU with workers at this
process's niceness (so `nice -n 10` runs both at 10): the robot's normal-scheduler threads compete with them as
equals, its SCHED_FIFO cycle thread (rt.priority) does not.

Variants, each run for its share of --minutes in --rounds alternating rounds so that they meet the same load:
  before     link sim:6 (missed=late: F125 as the real drive judges) on the normal scheduler: the config before
  warn       sim:6?missed=warn on the normal scheduler
  priority   sim:6 with SCHED_FIFO 80 for the cycle thread
  shipped    sim:6?missed=warn with SCHED_FIFO 80: config/akd_sim_6axis.yaml as shipped

Figures per variant: trajectories played, completed, failed, the longest run of completed ones in a row;
f125_stalls (the cycle's count of frames sent 8.5 periods or more after the one before with a drive enabled: where a
real AKD raises F125), the virtual AKDs' own count of would-be F125 (missed=warn) and of F125 they raised, the
master's lost frames and overruns (deadlines skipped), and the worst stall (the longest period). Where SCHED_FIFO is
not permitted the cycle runs on the normal scheduler and the table says so (the Bus's warning).

    nice -n 10 .venv/bin/python bench/host_noise.py [--minutes 8] [--rounds 2] [--variants before,shipped]
        [--seed 28] [--no-load]
"""

from __future__ import annotations

import argparse
import math
import random
import shutil
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

from figures import Figures, json_argument

from akd_ros import Bus, BusRequestError, CommandError, EtherCatError, params

ROOT = Path(__file__).resolve().parents[1]
CONFIG = ROOT / "config" / "akd_sim_6axis.yaml"
VARIANTS = {
    "before": ("sim:6", 0),
    "warn": ("sim:6?missed=warn", 0),
    "priority": ("sim:6", 80),
    "shipped": ("sim:6?missed=warn", 80),
}
"""Each variant's link and rt.priority (0: the normal scheduler)."""
SYNC_LOST = 0x8700
"""F125's CiA error code, in a drive's fault event."""
MOVE_S = 1.5
REACH_RAD = 1.0


@dataclass
class Tally:
    """What one variant did, over all its rounds."""

    played: int = 0
    completed: int = 0
    failed: int = 0
    streak: int = 0
    longest_streak: int = 0
    f125_stalls: int = 0
    would_be_f125: int = 0
    f125_raised: int = 0
    lost_frames: int = 0
    overruns: int = 0
    cycles: int = 0
    worst_stall_ms: float = 0.0
    events_dropped: int = 0
    seconds: float = 0.0
    not_permitted: set[str] = field(default_factory=set)

    def row(self, name: str) -> dict:
        link, priority = VARIANTS[name]
        return {
            "variant": name,
            "link": link,
            "rt.priority": (
                "none"
                if not priority
                else f"{priority}" + (" (not permitted: normal scheduler)" if self.not_permitted else "")
            ),
            "minutes": round(self.seconds / 60, 1),
            "trajectories": self.played,
            "completed": self.completed,
            "failed": self.failed,
            "longest run completed": self.longest_streak,
            "would-be F125 (f125_stalls)": self.f125_stalls,
            "would-be F125 (virtual AKDs)": self.would_be_f125,
            "F125 raised": self.f125_raised,
            "events dropped": self.events_dropped,
            "lost frames": self.lost_frames,
            "overruns": self.overruns,
            "worst stall ms": round(self.worst_stall_ms, 1),
            "cycles": self.cycles,
        }

    def outcome(self, completed: bool) -> None:
        self.played += 1
        if completed:
            self.completed += 1
            self.streak += 1
            self.longest_streak = max(self.longest_streak, self.streak)
        else:
            self.failed += 1
            self.streak = 0


def bus_of(settings: params.Settings, link: str, priority: int) -> Bus:
    """The Bus akd_node would build from `settings`, on `link` with the cycle thread at `priority` (0: none)."""
    return Bus(link, [j.drive() for j in settings.joints], **(settings.bus_options() | {"priority": priority or None}))


def target_of(settings: params.Settings, rng: random.Random) -> list[float]:
    """A random point within ±REACH_RAD of 0 and inside each joint's position limits."""
    point = []
    for joint in settings.joints:
        low = max(-REACH_RAD, joint.limits.min_position if joint.limits.min_position is not None else -math.inf)
        high = min(REACH_RAD, joint.limits.max_position if joint.limits.max_position is not None else math.inf)
        point.append(rng.uniform(low, high))
    return point


def play_one(bus: Bus, settings: params.Settings, rng: random.Random) -> bool:
    """Plays one trajectory and waits for its end; whether it completed."""
    joints = bus.names
    try:
        trajectory = bus.play_trajectory(joints, [MOVE_S], [[(p, 0.0, None) for p in target_of(settings, rng)]])
    except CommandError:
        return False
    deadline = time.monotonic() + MOVE_S + 5.0
    while time.monotonic() < deadline:
        state = bus.cycle.trajectory_status(trajectory)["state"]
        if state == "done":
            return True
        if state in ("aborted", "replaced"):
            return False
        time.sleep(0.02)
    return False


def run_variant(name: str, settings: params.Settings, seconds: float, rng: random.Random, tally: Tally) -> None:
    """Runs variant `name` for `seconds`, adding what it did to `tally`."""
    link, priority = VARIANTS[name]
    bus = bus_of(settings, link, priority)
    try:
        tally.not_permitted |= {w for w in bus.warnings if "SCHED_FIFO" in w}
        bus.enable(timeout=10.0)
        started = time.monotonic()
        while time.monotonic() - started < seconds:
            completed = play_one(bus, settings, rng)
            tally.outcome(completed)
            # Taken after every trajectory: the cycle's event ring holds 256 and drops (and counts) past that.
            take_f125(bus, tally)
            if not completed:
                # A drive faulted (F125 where the virtual AKDs judge as the real ones): reset, enable, go on.
                try:
                    bus.reset_fault(timeout=5.0)
                    bus.enable(timeout=10.0)
                except (BusRequestError, EtherCatError, TimeoutError) as e:
                    print(f"  {name}: could not enable again: {e}")
                    break
        tally.seconds += time.monotonic() - started
        take_f125(bus, tally)
        stats = bus.stats()
        tally.events_dropped += stats["events_dropped"]
        tally.f125_stalls += stats["f125_stalls"]
        tally.lost_frames += stats["lost_frames"]
        tally.overruns += stats["overruns"]
        tally.cycles += stats["cycles"]
        tally.worst_stall_ms = max(tally.worst_stall_ms, stats["period"]["max_ns"] / 1e6)
        # Every drive saw the same stalls; the drive that counted most stands for the line.
        counts = [bus.simulator.drive_state(a.slave)["would_be_f125"]["count"] for a in bus.axes]
        tally.would_be_f125 += max(counts)
    finally:
        bus.close()


def take_f125(bus: Bus, tally: Tally) -> None:
    """Counts the F125 the drives raised since the last call (their fault events with 0x603F = 0x8700)."""
    for axis in bus.axes:
        for event in bus.events_of(axis.slave):
            fault = event.get("fault")
            if fault is not None and fault.source == "drive_fault":
                tally.f125_raised += fault.code == SYNC_LOST


def stress(enabled: bool) -> subprocess.Popen | None:
    """stress-ng with a CPU worker on every CPU, at this process's niceness, until stopped."""
    if not enabled:
        return None
    return subprocess.Popen(
        ["stress-ng", "--cpu", "0", "--cpu-method", "matrixprod", "--quiet"],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--minutes", type=float, default=8.0, help="minutes of trajectories per variant, all rounds")
    parser.add_argument("--rounds", type=int, default=2, help="rounds the variants alternate in")
    parser.add_argument("--variants", default=",".join(VARIANTS), help=f"of {', '.join(VARIANTS)}")
    parser.add_argument("--seed", type=int, default=28, help="seed of the trajectories' targets")
    parser.add_argument("--no-load", action="store_true", help="leave the machine as it is (no stress-ng)")
    json_argument(parser)
    args = parser.parse_args()
    variants = [v for v in args.variants.split(",") if v]
    if unknown := [v for v in variants if v not in VARIANTS]:
        parser.error(f"--variants: no variant {', '.join(unknown)}; the variants: {', '.join(VARIANTS)}")
    figures = Figures("host_noise.py", "the six-axis virtual robot with every CPU loaded", args)
    if not args.no_load and shutil.which("stress-ng") is None:
        figures.missing("every figure: stress-ng is not installed (scripts/setup.sh installs it)")
        return figures.finish()
    settings = params.settings(params.read_parameters_file(str(CONFIG)))
    rng = random.Random(args.seed)
    tallies = {name: Tally() for name in variants}
    share = args.minutes * 60 / args.rounds
    load = stress(not args.no_load)
    try:
        time.sleep(1.0 if load else 0.0)
        for round_ in range(args.rounds):
            for name in variants:
                print(f"host_noise.py: round {round_ + 1}/{args.rounds}: {name} for {share:.0f} s", flush=True)
                run_variant(name, settings, share, rng, tallies[name])
    finally:
        if load is not None:
            load.terminate()
            load.wait(timeout=10)
    title = "six-axis robot (config/akd_sim_6axis.yaml), trajectories back to back, " + (
        "no load added" if args.no_load else "every CPU loaded by stress-ng"
    )
    figures.table(title, [tallies[name].row(name) for name in variants])
    figures.note(
        "would-be F125 (f125_stalls): frames the cycle sent 8.5 periods or more after the one before with a drive "
        "enabled; a real AKD raises F125 for each. F125 raised: the drives' fault events with 0x603F = 0x8700 (each "
        "drive counts its own). A failed trajectory was aborted (a drive faulted) or did not end in time."
    )
    for name in variants:
        for warning in sorted(tallies[name].not_permitted):
            figures.note(f"{name}: {warning}")
    return figures.finish()


if __name__ == "__main__":
    sys.exit(main())
