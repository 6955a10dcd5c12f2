"""Measures akd_node's /joint_states over Zenoh beside DDS in one run: latency, delivery rate and the node's CPU.

Not a test: timing depends on the machine and its load; it prints, it never asserts. akd_node with six joints
(config/akd_sim_6axis.yaml with link, cycle_time, joint_states_rate and transport changed, as bench/node_six_axes.py
runs it) on `akd-sim --count 6 --udp 127.0.0.1:PORT`, both separate processes, alternately (A/B/A/B, --rounds of
each, so a change of the machine's load over the run falls on both):

- transport rclpy: akd_node from .venv over rmw_fastrtps_cpp on a ROS_DOMAIN_ID of its own, discovery on
  localhost; the client is an rclpy subscription (reliable, depth 100) in this process;
- transport zenoh: akd_node from .venv-noros (no ROS wheel; .venv where it is missing) with tests/support/no_ros on
  its path, connected to a Zenoh router (eclipse-zenoh in router mode, its own process, on a loopback port); the
  client is a Zenoh session of this process subscribed to joint_states by rmw_zenoh's exact key expression, each
  sample decoded with rosbags (akd_ros.zenoh.types).

Every joint is enabled (~/enable, over the run's transport: a Trigger call, a Zenoh query with rmw_zenoh's
attachment) and holds. Over --window seconds: the node process's CPU time (utime + stime of /proc/PID/stat) as % of
one core, and every /joint_states message's latency, its receive time (time.time_ns() once the client holds the
decoded message: at the rclpy callback, after rosbags' decoding in the Zenoh callback) minus its header.stamp (the
node's stamp, the system clock too), and the messages received per second.

    .venv/bin/python bench/zenoh_vs_dds.py [--rounds 2] [--window 10] [--cycle-time 0.001]
        [--joint-states-rate 250] [--priority 80] [--sim-priority 70]

The node's cycle thread gets rt.priority 80 and akd-sim's threads SCHED_FIFO 70, as in bench/node_six_axes.py.
"""

from __future__ import annotations

import argparse
import functools
import os
import statistics
import sys
import tempfile
import time
from collections.abc import Mapping
from pathlib import Path
from types import MappingProxyType

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from node_bench import CONFIG, COUNT, ROOT, faults, hold, ms, node_arguments, node_on_sim, quantile
from node_six_axes import NODE, Client

from akd_ros.zenoh.types import Types
from akd_ros.zenoh.wire import Attachment, data_key_expr, dds_type_name
from support.ros import WAIT_S, NodeProcess, ros_environment
from support.waiting import wait_for
from support.zenoh import zenoh_router, zenoh_session

DOMAINS = range(50, 60)
"""ROS_DOMAIN_IDs of this benchmark (DDS, and the domain in the Zenoh keys), apart from the tests' and
node_six_axes.py's."""
JOINT_STATE = "sensor_msgs/msg/JointState"
TRIGGER = "std_srvs/srv/Trigger"
TRANSPORTS = ("rclpy", "zenoh")
S = 1_000_000_000
BENCH_GID = bytes(range(16))
"""The GID of this process's Zenoh service client in the enable request's attachment."""


class DdsClient(Client):
    """This process's rclpy side (bench/node_six_axes.py's client) with the same methods as ZenohClient."""

    others: Mapping[str, int] = MappingProxyType({})
    """Processes of the transport besides the node whose CPU is measured: none, DDS has no broker."""

    def wait(self, seconds: float) -> None:
        self.spin_for(seconds)

    def wait_until(self, done, what: str) -> None:
        self.spin_until(done, what)

    def taken(self, window: slice) -> list[tuple[int, int]]:
        """(receive time ns, stamp ns) of the messages in `window`."""
        taken = zip(self.arrivals_ns[window], self.joint_states[window], strict=True)
        return [(t, m.header.stamp.sec * S + m.header.stamp.nanosec) for t, m in taken]


class ZenohClient:
    """This process's Zenoh side: joint_states on rmw_zenoh's key, each as (receive time ns, stamp ns) once decoded;
    the node's Trigger services called as queries with rmw_zenoh's attachment."""

    def __init__(self, session, types: Types, domain: int, router_pid: int) -> None:
        self.session, self.types, self.domain = session, types, domain
        self.others = {"router": router_pid}
        self.received: list[tuple[int, int]] = []
        key = data_key_expr(domain, "/joint_states", dds_type_name(JOINT_STATE), types.rihs01(JOINT_STATE))
        self.subscriber = session.declare_subscriber(key, self._take)
        self.calls = 0

    def _take(self, sample) -> None:
        message = self.types.from_cdr(sample.payload.to_bytes(), JOINT_STATE)
        self.received.append((time.time_ns(), message.header.stamp.sec * S + message.header.stamp.nanosec))

    def count(self) -> int:
        return len(self.received)

    def wait(self, seconds: float) -> None:
        time.sleep(seconds)

    def wait_until(self, done, what: str) -> None:
        wait_for(what, done, WAIT_S)

    def taken(self, window: slice) -> list[tuple[int, int]]:
        return self.received[window]

    def trigger(self, name: str) -> str:
        key = data_key_expr(self.domain, NODE + name, dds_type_name(TRIGGER), self.types.rihs01(TRIGGER))
        request = self.types.to_cdr(self.types.message(f"{TRIGGER}_Request"), f"{TRIGGER}_Request")
        self.calls += 1
        attachment = Attachment(self.calls, time.time_ns(), BENCH_GID).encode()
        replies = [r.ok for r in self.session.get(key, payload=request, attachment=attachment, timeout=WAIT_S)]
        if len(replies) != 1 or replies[0] is None:
            raise RuntimeError(f"{NODE}{name} over Zenoh: replies {replies}")
        response = self.types.from_cdr(replies[0].payload.to_bytes(), f"{TRIGGER}_Response")
        if not response.success:
            raise RuntimeError(f"{name}: {response.message}")
        return response.message

    def close(self) -> None:
        self.subscriber.undeclare()


def children() -> list[int]:
    """The pids of this process's running children."""
    found = []
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                stat = (entry / "stat").read_text()
            except OSError:
                continue
            if int(stat.rsplit(")", 1)[1].split()[1]) == os.getpid():
                found.append(int(entry.name))
    return found


def run(transport: str, domain: int, endpoint: str, router_pid: int, session, types: Types, args) -> dict:
    with tempfile.TemporaryDirectory(prefix="zenoh_vs_dds-") as temp:
        changes = {"transport": transport}
        if transport == "zenoh":
            changes["zenoh.connect"] = [endpoint]
        start = functools.partial(NodeProcess, domain=domain, without_ros=transport == "zenoh")
        with node_on_sim(Path(temp), start, args.cycle_time, args, changes) as (sim, node):
            client = DdsClient(domain) if transport == "rclpy" else ZenohClient(session, types, domain, router_pid)
            try:
                client.wait_until(lambda: client.count() or node.process.poll() is not None, "/joint_states")
                if node.process.poll() is not None:
                    raise RuntimeError(f"akd_node exited:\n{node.output()}")
                client.trigger("enable")
                result = hold(node.process.pid, sim.process.pid, client.wait, client.count, args.window, client.others)
                taken = client.taken(result["window"])
            finally:
                client.close()
        return result | {
            "transport": transport,
            "program": os.path.relpath(node.process.args[0], ROOT),
            "latencies": [received_ns - stamp_ns for received_ns, stamp_ns in taken],
            "load": os.getloadavg(),
            "faults": faults(node.output()),
        }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=2, help="runs of each transport, alternating")
    parser.add_argument("--cycle-time", type=float, default=0.001, help="the node's cycle time, s")
    node_arguments(parser)
    args = parser.parse_args()
    types = Types()
    results = []
    with ros_environment(DOMAINS) as domain, zenoh_router() as endpoint, zenoh_session(endpoint) as session:
        (router_pid,) = children()
        print(
            f"zenoh_vs_dds: akd_node with {COUNT} joints ({CONFIG.relative_to(ROOT)}) on akd-sim --count {COUNT} "
            f"over UDP, cycle {args.cycle_time * 1e3:g} ms, /joint_states at {args.joint_states_rate:g} Hz, "
            f"rt.priority {args.priority or None}, akd-sim priority {args.sim_priority or None}, {args.window:g} s "
            f"windows, {args.rounds} rounds of {'/'.join(TRANSPORTS)}; ROS_DOMAIN_ID {domain} (rmw_fastrtps_cpp, "
            f"localhost discovery); Zenoh router {endpoint} (pid {router_pid}); {os.cpu_count()} CPUs, load "
            f"{'/'.join(f'{x:.2f}' for x in os.getloadavg())} at start"
        )
        for round_ in range(1, args.rounds + 1):
            for transport in TRANSPORTS:
                result = run(transport, domain, endpoint, router_pid, session, types, args)
                results.append(result | {"round": round_})
    print(
        f"{'round':>5s} {'transport':9s} {'node from':24s} {'load 1/5/15 min':>15s} {'node cpu':>8s} "
        f"{'of it cycle':>11s} {'akd-sim':>7s} {'router':>7s} {'joint_states':>12s} {'delivered':>9s} "
        f"{'latency p50':>11s} {'p99':>9s} {'max':>9s} {'faulted':>7s}"
    )
    for r in results:
        print(row(f"{r['round']:5d} {r['transport']:9s}", r, args))
    summary = {t: [r for r in results if r["transport"] == t] for t in TRANSPORTS}
    pooled = {t: pool(summary[t]) for t in TRANSPORTS}
    for t in TRANSPORTS:
        print(row(f"{'all':>5s} {t:9s}", pooled[t], args))
    dds, zenoh = pooled["rclpy"], pooled["zenoh"]
    ratios = {
        "node cpu": zenoh["cpu"] / dds["cpu"],
        "delivered": zenoh["joint_states"] / dds["joint_states"],
        "latency p50": quantile(zenoh["latencies"], 0.5) / quantile(dds["latencies"], 0.5),
        "latency p99": quantile(zenoh["latencies"], 0.99) / quantile(dds["latencies"], 0.99),
    }
    print("zenoh/dds: " + ", ".join(f"{name} {value:.2f}" for name, value in ratios.items()))
    for r in results:
        if r["faults"]:
            text = "; ".join(f"{what} on {', '.join(joints)}" for what, joints in r["faults"].items())
            print(f"faults in round {r['round']} over {r['transport']}: {text}")
    notes = [
        "node cpu, akd-sim, router: utime + stime of the process over the window, % of one core; of it cycle: the"
        " node's akd-cycle thread; router: the Zenoh router process (the DDS runs have none)",
        f"joint_states: messages/s this process received; delivered: of the configured {args.joint_states_rate:g}/s",
        "latency: receive time (time.time_ns(), the decoded message in hand) minus header.stamp, both the system clock",
        "all: the rounds' windows pooled (cpu and rate averaged, latencies together); ratios from those",
        f"waits bounded by {WAIT_S:g} s",
    ]
    print("; ".join(notes))


def row(head: str, r: dict, args) -> str:
    load = "/".join(f"{x:.1f}" for x in r["load"]) if "load" in r else ""
    faulted = len({joint for joints in r["faults"].values() for joint in joints}) if "faults" in r else ""
    router = f"{r['router_cpu']:6.1f}%" if "router_cpu" in r else "-"
    return (
        f"{head} {r.get('program', ''):24s} {load:>15s} {r['cpu']:7.1f}% {r['cycle_cpu']:10.1f}% "
        f"{r['sim_cpu']:6.1f}% {router:>7s} {r['joint_states']:10.1f}/s "
        f"{100 * r['joint_states'] / args.joint_states_rate:8.1f}% {ms(r['latencies'], 0.5):>11s} "
        f"{ms(r['latencies'], 0.99):>9s} {ms(r['latencies'], 1.0):>9s} {faulted:>7}"
    )


def pool(runs: list[dict]) -> dict:
    """The runs of one transport together: CPU shares and rates averaged, latencies in one list."""
    pooled = {key: statistics.fmean(r[key] for r in runs) for key in ("cpu", "cycle_cpu", "sim_cpu", "joint_states")}
    if all("router_cpu" in r for r in runs):
        pooled["router_cpu"] = statistics.fmean(r["router_cpu"] for r in runs)
    return pooled | {"latencies": [x for r in runs for x in r["latencies"]]}


if __name__ == "__main__":
    main()
