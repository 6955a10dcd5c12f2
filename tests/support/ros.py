"""ROS side of the tests: a domain of their own, `akd-sim` and `akd_node` processes, a client node.

Every wait is bounded by WAIT_S and every process is ended by its owner's teardown (`stop`). The client is real rclpy
over rmw_fastrtps_cpp in an rclpy.Context of its own, so several can live in one test process on different domains.
"""

from __future__ import annotations

import json
import math
import os
import queue
import random
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import pytest
import rclpy
from diagnostic_msgs.msg import DiagnosticArray
from rclpy.executors import SingleThreadedExecutor
from rclpy.qos import QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64
from std_srvs.srv import Trigger

from akd_ros.msg import DriveFault, DriveIO, DriveStatus, LatchEvent, TrajectoryStatus
from akd_ros.srv import ArmLatch, SetMode, SetOutputs
from support.netns import SIM_PRIORITY, free_udp_port, realtime

BIN = Path(sys.executable).parent
RMW = "rmw_fastrtps_cpp"
NODE = "/akd_node/"
# A bound on every wait, not a timing expectation: discovery and start-up on a loaded 2-core machine take seconds.
WAIT_S = 30.0
COMMAND_KINDS = ("position", "velocity", "torque")
# What the client subscribes to: every topic akd_node publishes (the recorded ~/cycle and ~/black_box are not).
NODE_TOPICS = {
    "/joint_states": JointState,
    "/diagnostics": DiagnosticArray,
    NODE + "status": DriveStatus,
    NODE + "latch": LatchEvent,
    NODE + "fault": DriveFault,
    NODE + "trajectory_status": TrajectoryStatus,
    NODE + "io": DriveIO,
}


@contextmanager
def ros_environment(domains: range) -> Iterator[int]:
    """Sets, for the block, a ROS_DOMAIN_ID picked from `domains`, discovery on localhost and Fast DDS; gives the
    domain. Test modules take ranges apart, so modules run at once on one machine do not see each other's nodes."""
    domain = random.choice(domains)
    settings = {"ROS_DOMAIN_ID": str(domain), "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST", "RMW_IMPLEMENTATION": RMW}
    with pytest.MonkeyPatch.context() as patch:
        for key, value in settings.items():
            patch.setenv(key, value)
        patch.delenv("ROS_LOCALHOST_ONLY", raising=False)
        yield domain


def module_domain(domains: range):
    """A module-scoped fixture `ros_domain`: a ROS_DOMAIN_ID from `domains` (see `ros_environment`), set for the
    module."""
    import pytest

    @pytest.fixture(scope="module")
    def ros_domain():
        with ros_environment(domains) as domain:
            yield domain

    return ros_domain


def lines_of(stream, into: queue.Queue, log: list[str]) -> None:
    """Copies a process's output lines into a queue and a log, until its end."""
    for line in stream:
        log.append(line)
        into.put(line)


def stop(process: subprocess.Popen) -> None:
    """SIGTERM, then SIGKILL if it does not end in time."""
    if process.poll() is None:
        process.terminate()
        try:
            process.wait(timeout=WAIT_S)
        except subprocess.TimeoutExpired:
            process.kill()
            process.wait()


def akd_plot(*args: str) -> subprocess.CompletedProcess:
    """`akd-plot ARGS` run to its end, its output captured."""
    return subprocess.run([str(BIN / "akd-plot"), *args], capture_output=True, text=True, timeout=120, check=False)


class Sim:
    """An akd-sim --udp process of `count` virtual AKDs on 127.0.0.1:`port` and its command line on stdin; under
    SCHED_FIFO (SIM_PRIORITY) where permitted.

    Its drives judge missed frames as `missed` says: by default "lost", only frames lost on the line, because the
    node's tests are not about this shared host's scheduling and a node cycle it runs late must not fault them
    (F125); a test of the drive's own reaction to a master that stops asks for "late", as the real drive judges.
    With `setpoint_trace` it traces the set-points its drives receive to that file (akd-sim --setpoint-trace), complete
    once it stopped. With `line` it serves that line (akd-sim --line: terminals and AKDs) instead of `count` AKDs."""

    def __init__(
        self,
        port: int,
        count: int = 1,
        missed: str = "lost",
        setpoint_trace: Path | None = None,
        line: str | None = None,
    ):
        self.port = port
        self.log: list[str] = []
        self.lines: queue.Queue = queue.Queue()
        trace = ["--setpoint-trace", str(setpoint_trace)] if setpoint_trace else []
        self.process = subprocess.Popen(
            [
                str(BIN / "akd-sim"),
                "--udp",
                f"127.0.0.1:{port}",
                *(["--line", line] if line is not None else ["--count", str(count)]),
                "--missed",
                missed,
                *trace,
            ],
            preexec_fn=lambda: realtime(SIM_PRIORITY),
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
            text=True,
            bufsize=1,
        )
        threading.Thread(target=lines_of, args=(self.process.stdout, self.lines, self.log), daemon=True).start()
        self.reply("akd-sim: starting")

    def reply(self, prefix: str) -> str:
        """The next output line starting with `prefix`."""
        deadline = time.monotonic() + WAIT_S
        while True:
            try:
                line = self.lines.get(timeout=max(0.0, deadline - time.monotonic()))
            except queue.Empty:
                raise AssertionError(
                    f"akd-sim gave no line starting {prefix!r}; output:\n{''.join(self.log)}"
                ) from None
            if line.startswith((prefix, "error")):
                assert not line.startswith("error"), line
                return line

    def command(self, line: str) -> str:
        """Sends one command line and gives its answer, which must be 'ok ...'."""
        self.process.stdin.write(line + "\n")
        self.process.stdin.flush()
        return self.reply("ok")

    def state(self, position: int = 0) -> dict:
        """The firmware state of the virtual drive at `position` (state, fault, position in counts, velocity, torque,
        dc)."""
        return json.loads(self.command(f"state {position}")[3:])

    def stop(self) -> None:
        """Ends the simulator."""
        stop(self.process)


NO_ROS = Path(__file__).resolve().parent / "no_ros"
"""The folder whose sitecustomize makes a Python refuse every ROS import (PYTHONPATH)."""
NO_ROS_NODE = Path(__file__).resolve().parents[2] / ".venv-noros" / "bin" / "akd_node"
"""akd_node of the environment scripts/setup.sh makes without any ROS wheel."""


def node_command(params: Path, domain: int | None = None, *, without_ros: bool = False) -> tuple[list[str], dict]:
    """The command line and environment of `akd_node --ros-args --params-file FILE`: `domain` overrides the
    environment's ROS_DOMAIN_ID; `without_ros` runs it as on a controller without ROS, from `.venv-noros` where it
    exists (else from .venv), every ROS import refused (NO_ROS)."""
    env = dict(os.environ)
    if domain is not None:
        env["ROS_DOMAIN_ID"] = str(domain)
    program = BIN / "akd_node"
    if without_ros:
        # NO_ROS first, so that it refuses every ROS import; then what the environment adds.
        env["PYTHONPATH"] = os.pathsep.join([str(NO_ROS), *filter(None, [os.environ.get("PYTHONPATH")])])
        program = NO_ROS_NODE if NO_ROS_NODE.exists() else program
    return [str(program), "--ros-args", "--params-file", str(params)], env


class NodeProcess:
    """akd_node running as `node_command` gives it, its output collected."""

    def __init__(self, params: Path, domain: int | None = None, *, without_ros: bool = False):
        self.log: list[str] = []
        argv, env = node_command(params, domain, without_ros=without_ros)
        self.program = Path(argv[0])
        """The akd_node it runs."""
        self.process = subprocess.Popen(
            argv,
            env=env,
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
            text=True,
            bufsize=1,
        )
        threading.Thread(target=lines_of, args=(self.process.stdout, queue.Queue(), self.log), daemon=True).start()

    def output(self) -> str:
        """What the node printed so far."""
        return "".join(self.log)


class Participant:
    """A node of this process in a context of its own on `domain`, with the executor that spins it; it calls the
    node's services and keeps what it receives by topic in `received`."""

    def __init__(self, domain: int, name: str):
        self.received: dict[str, list] = {}
        self.context = rclpy.Context()
        rclpy.init(context=self.context, domain_id=domain)
        self.node = rclpy.create_node(name, context=self.context)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)

    def spin_until(self, done, what: str, timeout: float = WAIT_S) -> None:
        """Spins until done() is true; fails naming what did not happen."""
        deadline = time.monotonic() + timeout
        while not done():
            assert time.monotonic() < deadline, f"no {what} within {timeout} s"
            self.executor.spin_once(timeout_sec=0.02)

    def spin_for(self, seconds: float) -> None:
        """Spins for `seconds`, collecting what arrives."""
        deadline = time.monotonic() + seconds
        while time.monotonic() < deadline:
            self.executor.spin_once(timeout_sec=0.02)

    def call(self, kind, name: str, request=None):
        """Calls service ~/name of the node and gives its response."""
        client = self.node.create_client(kind, NODE + name)
        self.spin_until(client.service_is_ready, f"service {NODE}{name}")
        future = client.call_async(request or kind.Request())
        self.spin_until(future.done, f"answer of {NODE}{name}")
        self.node.destroy_client(client)
        return future.result()

    def send_goal(self, action_client, goal, feedback=None):
        """Sends `goal` through `action_client` (feedback to `feedback` where given); its accepted goal handle."""
        sent = action_client.send_goal_async(goal, feedback_callback=feedback)
        self.spin_until(sent.done, "goal response")
        handle = sent.result()
        assert handle.accepted
        return handle

    def goal_result(self, handle, timeout: float = 20.0):
        """(goal status, result) of `handle` once it ends."""
        result = handle.get_result_async()
        self.spin_until(result.done, "goal result", timeout=timeout)
        return result.result().status, result.result().result

    def trigger(self, name: str) -> str:
        """Calls a Trigger service that must succeed; gives its message."""
        response = self.call(Trigger, name)
        assert response.success, f"{name}: {response.message}"
        return response.message

    def status(self, name: str, done, what: str):
        """The first /diagnostics status named `name` from now on for which `done(status)` (the participant collects
        /diagnostics in `received`)."""
        seen = len(self.received["/diagnostics"])

        def found():
            for array in self.received["/diagnostics"][seen:]:
                for status in array.status:
                    if status.name == name and done(status):
                        return status
            return None

        self.spin_until(found, what)
        return found()

    def set_outputs(self, joint: str, outputs=(), values=(), analog: float | None = None) -> SetOutputs.Response:
        """Calls ~/set_outputs for `joint` (a joint or a device) and gives its response."""
        request = SetOutputs.Request(
            joint=joint,
            outputs=list(outputs),
            values=list(values),
            set_analog_output=analog is not None,
            analog_output=0.0 if analog is None else analog,
        )
        return self.call(SetOutputs, "set_outputs", request)

    def latest(self, topic: str):
        """The last message of `topic`, stamped at or after this call. The executor hands over one message a spin, so
        a client with many entities spins slower than /joint_states comes and falls behind: the first message to
        arrive after the call was measured 100 ms old with 560 service clients, and a robot judged still by such a
        message had moved since."""
        since_ns = time.time_ns()

        def fresh() -> bool:
            stamp = self.received[topic][-1].header.stamp if self.received[topic] else None
            return stamp is not None and stamp.sec * 1_000_000_000 + stamp.nanosec >= since_ns

        self.spin_until(fresh, f"message on {topic} stamped after {since_ns} ns")
        return self.received[topic][-1]

    def close(self) -> None:
        """Destroys the node and shuts the context down."""
        self.executor.shutdown()
        self.node.destroy_node()
        rclpy.shutdown(context=self.context)


class Client(Participant):
    """The ROS side of akd_node's tests: every topic of the node collected in `received`, its services called, and
    the commands published, each counted in `sent`."""

    def __init__(self, domain: int):
        super().__init__(domain, "akd_node_test")
        qos = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE)
        for topic, kind in NODE_TOPICS.items():
            self.received[topic] = []
            self.node.create_subscription(kind, topic, self.received[topic].append, qos)
        self.commands = {
            kind: self.node.create_publisher(Float64, f"{NODE}{kind}_command", qos) for kind in COMMAND_KINDS
        }
        self.sent = dict.fromkeys(COMMAND_KINDS, 0)

    def position(self) -> float:
        """The joint's position from a fresh joint_states message."""
        return self.latest("/joint_states").position[0]

    def stream(self, kind: str, values, period: float = 0.02) -> None:
        """Publishes each of `values` as a `kind` command, one every `period` seconds, spinning between (once the
        node's subscription is matched, so none is lost)."""
        publisher = self.commands[kind]
        self.spin_until(lambda: publisher.get_subscription_count() > 0, f"subscriber of {kind} commands")
        for value in values:
            publisher.publish(Float64(data=float(value)))
            self.sent[kind] += 1
            self.spin_for(period)


def ready(ros: Client, sim: Sim, mode: str) -> None:
    """The drive without a fault, in `mode`, enabled."""
    if sim.state()["fault"] is not None:
        ros.trigger("reset_fault")
    ros.trigger("disable")
    response = ros.call(SetMode, "set_mode", SetMode.Request(mode=mode))
    assert response.success, response.message
    ros.trigger("enable")


COUNTS_PER_RAD = 2**20 / (2 * math.pi)
"""The virtual AKD's counts per radian with the node's default units."""


def latch_across(ros: Client, sim: Sim, offset: float) -> int:
    """Arms latch 1 on the rising edge, puts the simulator's input 1 edge `offset` rad ahead of the axis and moves 1 rad
    across it; gives the edge in counts once the LatchEvent arrived."""
    response = ros.call(ArmLatch, "arm_latch", ArmLatch.Request(channel=1, edge=LatchEvent.EDGE_RISING, arm=True))
    assert response.success, response.message
    here = ros.position()
    edge_counts = round((here + offset) * COUNTS_PER_RAD)
    sim.command(f"toggles 0 1 {edge_counts}")
    move_to(ros, here + 1.0)
    ros.spin_until(lambda: ros.received[NODE + "latch"], "LatchEvent")
    return edge_counts


def move_to(ros: Client, target: float, seconds: float = 1.0) -> None:
    """Streams position commands in a ramp from where the axis is to `target`, then waits for it to arrive."""
    start = ros.position()
    steps = max(1, int(seconds / 0.02))
    ros.stream("position", [start + (target - start) * (i + 1) / steps for i in range(steps)])
    ros.spin_until(lambda: abs(ros.position() - target) < 1e-3, f"axis at {target} rad")


@contextmanager
def node_on_sim(
    params: str,
    folder: Path,
    domain: int,
    *,
    count: int = 1,
    client_of=None,
    ready="/joint_states",
    line: str | None = None,
) -> Iterator[tuple[Sim, NodeProcess, Participant]]:
    """A fresh simulator of `count` drives (or of `line`), akd_node on it with `params` (a template whose {port} is the
    simulator's) on `domain`, and a client there (`client_of(domain)`, a `Client` by default) once topic `ready`
    arrives (or, a callable, once `ready(client)` is true); all ended afterwards, the node's output printed."""
    sim = Sim(free_udp_port(), count=count, line=line)
    path = folder / "akd_node.yaml"
    path.write_text(params.format(port=sim.port))
    node = NodeProcess(path, domain)
    client = None
    try:
        client = (client_of or Client)(domain)
        arrived = ready if callable(ready) else lambda c: c.received[ready]
        client.spin_until(lambda: arrived(client) or node.process.poll() is not None, str(ready))
        assert node.process.poll() is None, f"akd_node exited:\n{node.output()}"
        yield sim, node, client
    finally:
        if client is not None:
            client.close()
        stop(node.process)
        sim.stop()
        print(f"akd_node output:\n{node.output()}")
