"""Measures what the live view in Foxglove (live_view.port) costs akd_node: six joints at a 1 kHz cycle, the node's
CPU with the live view off, on without a client, and on with one client subscribed to every channel, alternating in
one run.

Not a test: CPU depends on the machine and its load. Each case starts `akd-sim --count 6 --udp 127.0.0.1:PORT` and
akd_node on it (config/akd_sim_6axis.yaml over rclpy, cycle_time 0.001, /joint_states at --joint-states-rate, the cycle
thread at --priority, akd-sim at SCHED_FIFO --sim-priority), both separate processes; this process is an rclpy node
(Fast DDS, a ROS_DOMAIN_ID of its own, localhost discovery) subscribed to /joint_states in every case, which enables
the joints (~/enable) so that they hold, and, in the case with a client, a Foxglove client (the `websockets` package,
tests/support/foxglove.py) on a thread of its own, subscribed to every channel the live view advertises and reading
every message without decoding it. Over --window seconds: the node's CPU time (utime + stime of /proc/PID/stat) as %
of one core, split into its akd-publish thread (which hands the crate's messages to the middleware and, with the
live view, to the SDK's queues), the SDK's threads (tokio-rt-worker: the WebSocket server) and the rest; and the
messages the Foxglove client received per second. The cases alternate for --rounds rounds; the table gives each run,
and the medians what the live view adds to the node's CPU, each case against the case off of its own round.

    .venv/bin/python bench/live_view.py [--rounds 5] [--window 8] [--joint-states-rate 100] [--priority 80]
        [--sim-priority 70] [--json PATH]
"""

from __future__ import annotations

import argparse
import socket
import statistics
import sys
import tempfile
import threading
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

import yaml
from figures import Figures, json_argument, real_time
from node_ros import FAULT_LINE, TICK, cpu_ticks, thread_ticks
from rclpy.qos import QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import JointState
from std_srvs.srv import Trigger
from websockets.exceptions import ConnectionClosed

from support.foxglove import FoxgloveClient
from support.netns import free_udp_port
from support.ros import NodeProcess, Participant, Sim, ros_environment, stop

ROOT = Path(__file__).resolve().parents[1]
CONFIG = ROOT / "config" / "akd_sim_6axis.yaml"
DOMAINS = range(90, 100)
"""ROS_DOMAIN_IDs of this benchmark, apart from the tests', node_ros.py's and node_io.py's."""
JOINTS = 6
OFF, ON, WATCHED = "off", "on, no client", "on, one client"
CASES = (OFF, ON, WATCHED)
THREADS = {"akd-publish": "akd-publish", "tokio-rt-worker": "SDK threads"}
"""The node's threads the table shows apart, by name; the others are REST."""
REST = "the rest"


def free_tcp_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


def params(sim_port: int, live_view_port: int, args) -> str:
    """config/akd_sim_6axis.yaml on udp://127.0.0.1:`sim_port` at 1 kHz, the live view on `live_view_port` (0: off)."""
    document = yaml.safe_load(CONFIG.read_text())
    values = document["akd_node"]["ros__parameters"]
    values |= {
        "link": f"udp://127.0.0.1:{sim_port}",
        "cycle_time": 0.001,
        "transport": "rclpy",
        "joint_states_rate": args.joint_states_rate,
        "live_view.port": live_view_port,
    }
    if args.priority:
        values["rt.priority"] = args.priority
    return yaml.safe_dump(document)


class Watcher:
    """A Foxglove client on a thread of its own, subscribed to every channel, counting the messages it reads."""

    def __init__(self, url: str) -> None:
        self.client = FoxgloveClient(url)
        for channel in self.client.topics({"/joint_states", "/diagnostics"}).values():
            self.client.subscribe(channel)
        self.messages = 0
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._read, daemon=True)
        self._thread.start()

    def _read(self) -> None:
        while not self._stop.is_set():
            try:
                frame = self.client.connection.recv(timeout=0.5)
            except TimeoutError:
                continue
            except ConnectionClosed:
                return
            if isinstance(frame, bytes):
                self.messages += 1

    def close(self) -> None:
        self._stop.set()
        self._thread.join()
        self.client.close()


def run(case: str, domain: int, args) -> dict:
    """One case: the node's CPU over the window, by thread, and the messages a Foxglove client received per second."""
    with tempfile.TemporaryDirectory(prefix="live_view-") as temp:
        sim = Sim(free_udp_port(), count=JOINTS)
        if args.sim_priority:
            real_time(sim.process.pid, args.sim_priority)
        port = 0 if case == OFF else free_tcp_port()
        path = Path(temp) / "akd_node.yaml"
        path.write_text(params(sim.port, port, args))
        node = NodeProcess(path, domain=domain)
        client = watcher = None
        try:
            client = Participant(domain, "akd_node_live_view_bench")
            received = []
            qos = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE)
            client.node.create_subscription(JointState, "/joint_states", received.append, qos)
            client.spin_until(lambda: received or node.process.poll() is not None, "/joint_states")
            if node.process.poll() is not None:
                raise RuntimeError(f"akd_node exited:\n{node.output()}")
            response = client.call(Trigger, "enable")
            if not response.success:
                raise RuntimeError(f"~/enable: {response.message}")
            if case == WATCHED:
                watcher = Watcher(f"ws://127.0.0.1:{port}")
            client.spin_for(1.0)  # past the enable's transients and the subscriptions
            pid = node.process.pid

            def taken() -> tuple:
                counted = watcher.messages if watcher else 0
                return cpu_ticks(Path(f"/proc/{pid}/stat")), thread_ticks(pid, THREADS, REST), counted, time.monotonic()

            before = taken()
            received.clear()
            client.spin_for(args.window)
            after = taken()
            elapsed = after[3] - before[3]
            threads = after[1] - before[1]
            return {
                "case": case,
                "node CPU %": 100 * (after[0] - before[0]) / TICK / elapsed,
                **{f"of it {group} %": 100 * threads[group] / TICK / elapsed for group in THREADS.values()},
                "Foxglove messages/s": (after[2] - before[2]) / elapsed,
                "/joint_states over DDS /s": len(received) / elapsed,
                "faults": ", ".join(
                    sorted({f"{what} on {joint}" for joint, what in FAULT_LINE.findall(node.output())})
                ),
            }
        finally:
            if watcher is not None:
                watcher.close()
            if client is not None:
                client.close()
            stop(node.process)
            sim.stop()


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=5, help="rounds of the three cases, alternating")
    parser.add_argument("--window", type=float, default=8.0, help="s over which CPU and messages are counted")
    parser.add_argument("--joint-states-rate", type=float, default=100.0, help="Hz of /joint_states")
    parser.add_argument("--priority", type=int, default=80, help="rt.priority of the node's cycle thread (0: none)")
    parser.add_argument("--sim-priority", type=int, default=70, help="SCHED_FIFO of akd-sim's threads (0: none)")
    json_argument(parser)
    args = parser.parse_args()
    figures = Figures(
        "live_view.py", "akd_node's CPU with the live view off, on, and on with a client, six joints at 1 kHz", args
    )
    rows = []
    with ros_environment(DOMAINS) as domain:
        for round_number in range(1, args.rounds + 1):
            for case in CASES:
                try:
                    rows.append({"round": round_number, **run(case, domain, args)})
                except (RuntimeError, AssertionError) as e:
                    figures.missing(f"round {round_number}, live view {case}: {e}")
    figures.table("Each run: six joints holding at 1 kHz over rclpy (Fast DDS)", rows)
    columns = ["node CPU %", *(f"of it {group} %" for group in THREADS.values()), "Foxglove messages/s"]
    medians = {}
    for case in CASES:
        runs = [r for r in rows if r["case"] == case and not r["faults"]]
        if runs:
            medians[case] = {k: statistics.median(r[k] for r in runs) for k in columns}
        else:
            figures.missing(f"the node's CPU with the live view {case}: no run without a fault")
    if OFF in medians:
        # What each case adds to the case off of its own round: the machine's load drifts slower than a round.
        cpu = {(r["round"], r["case"]): r["node CPU %"] for r in rows if not r["faults"]}
        added = {
            case: [
                cpu[n, case] - cpu[n, OFF] for n in range(1, args.rounds + 1) if (n, case) in cpu and (n, OFF) in cpu
            ]
            for case in medians
        }
        figures.table(
            "Medians: what the live view adds to the node's CPU (% of one core)",
            [
                {
                    "live view": case,
                    **m,
                    "added to off in its round, median %": statistics.median(added[case]) if added[case] else None,
                    "added µs of CPU per message sent": statistics.median(added[case]) * 1e4 / m["Foxglove messages/s"]
                    if m["Foxglove messages/s"] and added[case]
                    else None,
                }
                for case, m in medians.items()
            ],
        )
    figures.note(
        f"/joint_states at {args.joint_states_rate:g} Hz, each joint's status and ~/io at 10 Hz, /diagnostics at 1 Hz "
        "(config/akd_sim_6axis.yaml); CPU: utime + stime over the window, % of one core; SDK threads: the "
        "foxglove-sdk's tokio-rt-worker threads (none when off); runs alternate; runs in which a drive faulted are "
        "left out of the medians"
    )
    return figures.finish()


if __name__ == "__main__":
    sys.exit(main())
