"""What the akd_node benchmarks share: the six-joint parameter file they run the node with, the node and akd-sim
started and ended, the CPU time of a process and of its cycle thread from /proc over a window of holding, the faults
the node logged, and quantiles in ms. Imported by the scripts in bench/ once tests/ is on sys.path (support.ros)."""

from __future__ import annotations

import argparse
import os
import re
import statistics
import time
from collections.abc import Callable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from pathlib import Path

import yaml
from scheduling import real_time

from support.netns import free_udp_port
from support.ros import NodeProcess, Sim, stop

ROOT = Path(__file__).resolve().parents[1]
COUNT = 6
JOINTS = [f"joint_{i}" for i in range(1, COUNT + 1)]
CONFIG = ROOT / "config" / "akd_sim_6axis.yaml"
FAULT_LINE = re.compile(r"fault of (\w+): ([^;]+);")
"""akd_node's log line of a joint's fault: the joint and what the fault is (its source and text, e.g. "emergency:
F125 Synchronization lost", "lost_frames: 1 cycles in a row")."""
TICK = os.sysconf("SC_CLK_TCK")


def params(port: int, cycle_time: float, rate: float, priority: int, changes: dict | None = None) -> str:
    """config/akd_sim_6axis.yaml's parameters on udp://127.0.0.1:`port` at `cycle_time`, /joint_states at `rate`,
    the cycle thread at rt.priority `priority` unless it is 0, and `changes` on top."""
    document = yaml.safe_load(CONFIG.read_text())
    values = document["akd_node"]["ros__parameters"]
    values |= {"link": f"udp://127.0.0.1:{port}", "cycle_time": cycle_time, "joint_states_rate": rate}
    if priority:
        values["rt.priority"] = priority
    values |= changes or {}
    return yaml.safe_dump(document)


def cpu_ticks(stat: Path) -> int:
    """utime + stime in a /proc stat file (of a process: its threads together; of a task: that thread), in clock
    ticks."""
    # The command name in parentheses may hold spaces: the fields are counted after its closing one.
    fields = stat.read_text().rsplit(")", 1)[1].split()
    return int(fields[11]) + int(fields[12])


def cpu_of(pid: int) -> tuple[int, int]:
    """(the whole process's, its akd-cycle thread's) CPU time so far, clock ticks; the thread's 0 if it has none."""
    cycle = [t for t in Path(f"/proc/{pid}/task").iterdir() if (t / "comm").read_text().strip() == "akd-cycle"]
    return cpu_ticks(Path(f"/proc/{pid}/stat")), sum(cpu_ticks(t / "stat") for t in cycle)


def node_arguments(parser: argparse.ArgumentParser) -> None:
    """The options of the node's run every node benchmark has: /joint_states rate, the measuring window, the cycle
    thread's and akd-sim's priorities."""
    parser.add_argument("--joint-states-rate", type=float, default=250.0, help="/joint_states rate, Hz")
    parser.add_argument("--window", type=float, default=10.0, help="s over which CPU and /joint_states are counted")
    parser.add_argument("--priority", type=int, default=80, help="the node's rt.priority (0: the config's, none)")
    parser.add_argument("--sim-priority", type=int, default=70, help="akd-sim's SCHED_FIFO priority (0: none)")


@contextmanager
def node_on_sim(
    folder: Path, start_node: Callable[[Path], NodeProcess], cycle_time: float, args, changes: dict | None = None
) -> Iterator[tuple[Sim, NodeProcess]]:
    """`akd-sim --count COUNT` (its threads at SCHED_FIFO args.sim_priority unless 0) and akd_node on it, started by
    start_node(the parameter file in `folder`: params() at `cycle_time`, args.joint_states_rate, args.priority and
    `changes`); yields (sim, node) and ends both afterwards, printing the node's output if the block failed."""
    sim = Sim(free_udp_port(), count=COUNT)
    if args.sim_priority:
        real_time(sim.process.pid, args.sim_priority)
    path = folder / "akd_node.yaml"
    path.write_text(params(sim.port, cycle_time, args.joint_states_rate, args.priority, changes))
    node = start_node(path)
    try:
        yield sim, node
    except Exception:
        print(f"akd_node output:\n{node.output()}")
        raise
    finally:
        stop(node.process)
        sim.stop()


def hold(
    node_pid: int,
    sim_pid: int,
    wait: Callable[[float], None],
    count: Callable[[], int],
    seconds: float,
    others: Mapping[str, int] | None = None,
) -> dict:
    """Over `seconds` of every joint holding, the client waiting with wait(seconds) while count() tells how many
    /joint_states messages it has received: the CPU share (% of one core) of the node, of its cycle thread, of
    akd-sim and of each of `others` (name: pid, as "<name>_cpu"), the messages received per second, and the slice of
    the client's messages that arrived in the window ("window")."""
    others = dict(others or {})
    wait(1.0)  # past the enable's transients

    def now() -> tuple:
        other_ticks = (cpu_ticks(Path(f"/proc/{pid}/stat")) for pid in others.values())
        return (*cpu_of(node_pid), *cpu_of(sim_pid), *other_ticks, count(), time.monotonic())

    before = now()
    wait(seconds)
    after = now()
    node_ticks, cycle_ticks, sim_ticks, _, *other_ticks, messages, elapsed = (
        b - a for a, b in zip(before, after, strict=True)
    )
    return {
        "cpu": 100 * node_ticks / TICK / elapsed,
        "cycle_cpu": 100 * cycle_ticks / TICK / elapsed,
        "sim_cpu": 100 * sim_ticks / TICK / elapsed,
        **{f"{name}_cpu": 100 * ticks / TICK / elapsed for name, ticks in zip(others, other_ticks, strict=True)},
        "joint_states": messages / elapsed,
        "window": slice(before[-2], after[-2]),
    }


def faults(output: str) -> dict[str, list[str]]:
    """The joints each fault was logged for in akd_node's `output`, by what the fault is."""
    found: dict[str, list[str]] = {}
    for joint, what in FAULT_LINE.findall(output):
        if joint not in found.setdefault(what, []):
            found[what].append(joint)
    return found


def quantile(values_ns: Sequence[int], fraction: float) -> float:
    """The `fraction` quantile of `values_ns` (at least two), 1.0 giving the largest."""
    if fraction == 1.0:
        return max(values_ns)
    return statistics.quantiles(values_ns, n=100)[round(fraction * 100) - 1]


def ms(values_ns: Sequence[int], fraction: float) -> str:
    """The `fraction` quantile (1.0: the largest) of `values_ns` in ms, or n/a for fewer than two."""
    if len(values_ns) < 2:
        return "n/a"
    return f"{quantile(values_ns, fraction) / 1e6:.2f}ms"
