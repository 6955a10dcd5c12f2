"""Measures what publishing the drives' own I/O costs akd_node: six joints at a 1 kHz cycle, the node's CPU with every
joint's ~/io published and without, alternating in one run.

Not a test: CPU depends on the machine and its load. Each case starts `akd-sim --count 6 --udp 127.0.0.1:PORT` and
akd_node on it (config/akd_sim_6axis.yaml over rclpy, cycle_time 0.001, the cycle thread at --priority, akd-sim at
SCHED_FIFO --sim-priority), both separate processes; this process is the client, an rclpy node (Fast DDS, a
ROS_DOMAIN_ID of its own, localhost discovery) subscribed to /joint_states and every joint's ~/<joint>/io. The cases:
- without: the joints on the default mapping, io_rate 0.1 Hz, no input changing: the node as it was before ~/io;
- with ~/io at R Hz, for each R of --io-rates: the joints on the io mapping, every joint's ~/io at R Hz, and one
  digital input of every joint flipped at --flip-rate by akd-sim's `input` command, each flip a change the node
  publishes once more.
Every joint is enabled (~/enable) and holds. Over --window seconds: the node's CPU time (utime + stime of
/proc/PID/stat) and its akd-cycle thread's, as % of one core, and the ~/io messages received per second. The cases
alternate for --rounds rounds; the table gives each run, and for each rate what the medians add to the node's CPU,
in all and per ~/io message.

    .venv/bin/python bench/node_io.py [--rounds 3] [--window 5] [--io-rates 10,100] [--flip-rate 10]
        [--priority 80] [--sim-priority 70] [--json PATH]
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import threading
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

import yaml
from figures import Figures, json_argument, real_time
from node_ros import TICK, cpu_ticks, thread_ticks
from rclpy.qos import QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import JointState
from std_srvs.srv import Trigger

from akd_ros.msg import DriveIO
from support.netns import free_udp_port
from support.ros import NodeProcess, Participant, Sim, ros_environment, stop

ROOT = Path(__file__).resolve().parents[1]
CONFIG = ROOT / "config" / "akd_sim_6axis.yaml"
NODE = "/akd_node/"
DOMAINS = range(30, 40)
"""ROS_DOMAIN_IDs of this benchmark, apart from the tests' and node_ros.py's."""
JOINTS = [f"joint_{i}" for i in range(1, 7)]
FLIPPED_INPUT = 4
"""The digital input of every drive the cases with ~/io flip."""
WITHOUT = "without ~/io"


def params(port: int, io_rate: float | None, args) -> str:
    """config/akd_sim_6axis.yaml on udp://127.0.0.1:`port` at 1 kHz, with ~/io at `io_rate` Hz, or without (None)."""
    document = yaml.safe_load(CONFIG.read_text())
    values = document["akd_node"]["ros__parameters"]
    values |= {"link": f"udp://127.0.0.1:{port}", "cycle_time": 0.001, "transport": "rclpy"}
    if args.priority:
        values["rt.priority"] = args.priority
    if io_rate is None:
        values |= {"mapping": "default", "io_rate": 0.1}
        for key in [k for k in values if ".io." in k]:
            del values[key]
    else:
        values["io_rate"] = io_rate
    return yaml.safe_dump(document)


class Client(Participant):
    """/joint_states and every joint's ~/io counted; ~/enable called."""

    def __init__(self, domain: int) -> None:
        super().__init__(domain, "akd_node_io_bench")
        qos = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE)
        self.joint_states = 0
        self.io = 0
        self.node.create_subscription(JointState, "/joint_states", self._joint_states, qos)
        for joint in JOINTS:
            self.node.create_subscription(DriveIO, f"{NODE}{joint}/io", self._io, qos)

    def _joint_states(self, _) -> None:
        self.joint_states += 1

    def _io(self, _) -> None:
        self.io += 1


def flip(sim: Sim, rate: float, stop_flipping: threading.Event) -> None:
    """Flips input FLIPPED_INPUT of every drive at `rate` Hz until told to stop."""
    high = False
    while not stop_flipping.wait(1.0 / rate):
        high = not high
        for position in range(len(JOINTS)):
            sim.command(f"input {position} {FLIPPED_INPUT} {'high' if high else 'low'}")


def case_name(io_rate: float | None) -> str:
    return WITHOUT if io_rate is None else f"~/io at {io_rate:g} Hz"


def run(io_rate: float | None, domain: int, args) -> dict:
    """One case (~/io at `io_rate` Hz, None for none): the node's and its cycle thread's CPU over the window, the ~/io
    messages per second."""
    with tempfile.TemporaryDirectory(prefix="node_io-") as temp:
        sim = Sim(free_udp_port(), count=len(JOINTS))
        if args.sim_priority:
            real_time(sim.process.pid, args.sim_priority)
        path = Path(temp) / "akd_node.yaml"
        path.write_text(params(sim.port, io_rate, args))
        node = NodeProcess(path, domain=domain)
        client = None
        stop_flipping = threading.Event()
        flipper = None
        try:
            client = Client(domain)
            client.spin_until(lambda: client.joint_states or node.process.poll() is not None, "/joint_states")
            if node.process.poll() is not None:
                raise RuntimeError(f"akd_node exited:\n{node.output()}")
            response = client.call(Trigger, "enable")
            if not response.success:
                raise RuntimeError(f"~/enable: {response.message}")
            if io_rate is not None:
                flipper = threading.Thread(target=flip, args=(sim, args.flip_rate, stop_flipping), daemon=True)
                flipper.start()
            client.spin_for(1.0)  # past the enable's transients
            pid = node.process.pid
            before = (cpu_ticks(Path(f"/proc/{pid}/stat")), thread_ticks(pid)["cycle"], client.io, time.monotonic())
            client.spin_for(args.window)
            after = (cpu_ticks(Path(f"/proc/{pid}/stat")), thread_ticks(pid)["cycle"], client.io, time.monotonic())
            node_ticks, cycle_ticks, io, elapsed = (b - a for a, b in zip(before, after, strict=True))
            return {
                "case": case_name(io_rate),
                "node CPU %": 100 * node_ticks / TICK / elapsed,
                "of it cycle %": 100 * cycle_ticks / TICK / elapsed,
                "~/io messages/s": io / elapsed,
                "faults": "fault of" in node.output(),
            }
        finally:
            stop_flipping.set()
            if flipper is not None:
                flipper.join()
            if client is not None:
                client.close()
            stop(node.process)
            sim.stop()


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=3, help="rounds of both cases, alternating")
    parser.add_argument("--window", type=float, default=5.0, help="s over which CPU and ~/io are counted")
    parser.add_argument(
        "--io-rates",
        type=lambda t: [float(r) for r in t.split(",")],
        default=[10.0, 100.0],
        help="io_rate Hz of each case with ~/io",
    )
    parser.add_argument("--flip-rate", type=float, default=10.0, help="Hz at which one input of each drive flips")
    parser.add_argument("--priority", type=int, default=80, help="rt.priority of the node's cycle thread (0: none)")
    parser.add_argument("--sim-priority", type=int, default=70, help="SCHED_FIFO of akd-sim's threads (0: none)")
    json_argument(parser)
    args = parser.parse_args()
    figures = Figures("node_io.py", "akd_node's CPU with every joint's ~/io and without, six joints at 1 kHz", args)
    rows = []
    cases = [None, *args.io_rates]
    with ros_environment(DOMAINS) as domain:
        for round_number in range(1, args.rounds + 1):
            for io_rate in cases:
                try:
                    rows.append({"round": round_number, **run(io_rate, domain, args)})
                except (RuntimeError, AssertionError) as e:
                    figures.missing(f"round {round_number}, {case_name(io_rate)}: {e}")
    figures.table("Each run: six joints holding at 1 kHz over rclpy (Fast DDS)", rows)
    medians = {}
    for io_rate in cases:
        runs = [r for r in rows if r["case"] == case_name(io_rate) and not r["faults"]]
        if runs:
            medians[io_rate] = {k: statistics.median(r[k] for r in runs) for k in ("node CPU %", "~/io messages/s")}
        else:
            figures.missing(f"the node's CPU {case_name(io_rate)}: no run without a fault")
    if None in medians:
        without = medians[None]["node CPU %"]
        figures.table(
            "Medians: what ~/io adds to the node's CPU (% of one core)",
            [
                {
                    "case": case_name(io_rate),
                    "node CPU %": m["node CPU %"],
                    f"node CPU % {WITHOUT}": without,
                    "added, % of one core": m["node CPU %"] - without,
                    "with/without": m["node CPU %"] / without if without else None,
                    "~/io messages/s": m["~/io messages/s"],
                    "added µs of CPU per message": (m["node CPU %"] - without) * 1e4 / m["~/io messages/s"]
                    if m["~/io messages/s"]
                    else None,
                }
                for io_rate, m in medians.items()
                if io_rate is not None
            ],
        )
    figures.note(
        f"{WITHOUT}: default mapping, io_rate 0.1 Hz, no input changing (the node before ~/io); ~/io at R Hz: mapping "
        f"io, every joint's ~/io at R Hz and input {FLIPPED_INPUT} of every drive flipped at {args.flip_rate:g} Hz "
        "(each flip one more message); CPU: utime + stime over the window, % of one core; runs alternate; runs in "
        "which a drive faulted are left out of the medians"
    )
    return figures.finish()


if __name__ == "__main__":
    sys.exit(main())
