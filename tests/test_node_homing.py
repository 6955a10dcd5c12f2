"""Homing from ROS: akd_node's ~/home action on six virtual AKDs (one `akd-sim --udp --count 6` process), driven by an
rclpy ActionClient in this process, the node in another.

The virtual AKDs home as akd-sim sets them up: toward a reference a quarter revolution from where the shaft was at
power-up, at one revolution per second, that place becoming the zero; `homing POSITION error|no_reference` makes a
drive's homing fail. joint_6 is an absolute axis (homing.method none). Every wait is bounded; the processes are always
ended.
"""

from __future__ import annotations

import math

import pytest
from action_msgs.msg import GoalStatus
from rclpy.action import ActionClient
from rclpy.qos import QoSProfile, ReliabilityPolicy
from std_msgs.msg import Float64

from akd_ros.action import Home
from akd_ros.msg import DriveStatus
from support.ros import Participant, Sim, node_on_sim, ros_environment

DOMAINS = range(221, 231)
NODE = "/akd_node/"
JOINTS = [f"joint_{i}" for i in range(1, 7)]
COUNTS_PER_REV = 2**20
REFERENCE_COUNTS = COUNTS_PER_REV / 4
"""Where akd-sim's reference is, shaft counts from the power-up position."""
AT_ZERO_COUNTS = 50
HOMING_TIMEOUT = 2.5

PARAMS = """\
akd_node:
  ros__parameters:
    link: udp://127.0.0.1:{port}
    cycle_time: 0.002
    mode: cyclic_synchronous_position
    status_rate: 20.0
    homing.required: true
    homing.timeout: {timeout}
    joints: [{joints}]
    joints.joint_6.homing.method: none
"""


class Homer(Participant):
    """The client: the ~/home action, each joint's ~/status and position_command."""

    def __init__(self, domain: int):
        super().__init__(domain, "akd_node_homing_test")
        self.home_client = ActionClient(self.node, Home, NODE + "home")
        qos = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE)
        for joint in JOINTS:
            topic = f"{NODE}{joint}/status"
            self.received[topic] = []
            self.node.create_subscription(DriveStatus, topic, self.received[topic].append, qos)
        self.position_command = self.node.create_publisher(Float64, NODE + "joint_1/position_command", qos)
        self.feedback: list = []

    def home(self, joints: list[str], cancel_after: float | None = None):
        """Sends a Home goal and gives (its final status, its result)."""
        self.spin_until(lambda: self.home_client.server_is_ready(), "~/home action server")
        sent = self.home_client.send_goal_async(Home.Goal(joints=joints), feedback_callback=self.feedback.append)
        self.spin_until(sent.done, "goal response")
        handle = sent.result()
        assert handle.accepted
        if cancel_after is not None:
            self.spin_for(cancel_after)
            canceling = handle.cancel_goal_async()
            self.spin_until(canceling.done, "cancel response")
        result = handle.get_result_async()
        self.spin_until(result.done, "homing result", timeout=HOMING_TIMEOUT + 20)
        return result.result().status, result.result().result

    def homed(self, joint: str) -> bool:
        return self.latest(f"{NODE}{joint}/status").homed


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    params = PARAMS.format(port="{port}", timeout=HOMING_TIMEOUT, joints=", ".join(JOINTS))
    folder = tmp_path_factory.mktemp("homing")
    with ros_environment(DOMAINS) as domain:
        ready = f"{NODE}joint_1/status"
        with node_on_sim(params, folder, domain, count=len(JOINTS), client_of=Homer, ready=ready) as (
            sim,
            node,
            client,
        ):
            client.trigger("enable")
            yield sim, node, client


def counts(sim: Sim) -> list[float]:
    return [sim.state(i)["position"] for i in range(len(JOINTS))]


def test_a_position_command_to_an_unhomed_joint_is_refused_naming_it_and_nothing_moves(run):
    sim, node, client = run
    assert not client.homed("joint_1") and client.homed("joint_6"), "joint_6 is absolute (homing.method none)"
    before = counts(sim)
    client.spin_until(lambda: client.position_command.get_subscription_count() > 0, "position_command subscriber")
    client.position_command.publish(Float64(data=1.0))
    client.spin_until(lambda: "joint_1 is not homed" in node.output(), "the refusal in the log")
    client.spin_for(0.3)
    assert all(abs(a - b) < 20 for a, b in zip(counts(sim), before, strict=True)), (before, counts(sim))
    line = next(line for line in node.output().splitlines() if "joint_1 is not homed" in line)
    assert "position command refused, nothing sent" in line and "home it first with the ~/home action" in line, line


def test_homing_all_six_ends_with_each_attained_at_the_new_zero(run):
    sim, _, client = run
    status, result = client.home([])
    assert result.success and status == GoalStatus.STATUS_SUCCEEDED, result.message
    assert list(result.joints) == JOINTS and list(result.outcome) == ["attained"] * 6, result
    assert all(result.homed)
    # The drives moved to their references: the five homed by their drives stand at their new zero.
    positions = counts(sim)
    assert all(abs(p) <= AT_ZERO_COUNTS for p in positions[:5]), positions
    assert any(s == "in_progress" for f in client.feedback for s in f.feedback.state), "feedback while homing"
    assert all(client.homed(j) for j in JOINTS)
    # Homed, joint_1 takes position commands again.
    client.position_command.publish(Float64(data=0.2))
    target = 0.2 / (2 * math.pi) * COUNTS_PER_REV
    client.spin_until(lambda: abs(sim.state(0)["position"] - target) < 200, "joint_1 at its command")


def home_failing(run, position: int, failure: str, cancel_after: float | None = None):
    """Homes joint `position` + 1 with its drive's homing failing as `failure`; (goal status, result)."""
    sim, _, client = run
    sim.command(f"homing {position} {failure}")
    try:
        return client.home([JOINTS[position]], cancel_after)
    finally:
        sim.command(f"homing {position} ok")


def assert_enabled_and_still(sim: Sim, position: int) -> None:
    state = sim.state(position)
    assert state["state"] == "Operation enabled" and abs(state["velocity"]) < COUNTS_PER_REV / 100, state


def test_a_homing_error_reports_the_joint_and_why(run):
    sim, _, client = run
    status, result = home_failing(run, 2, "error")
    assert status == GoalStatus.STATUS_ABORTED and list(result.outcome) == ["homing_error"], result
    assert "joint_3" in result.message and "homing error (statusword bit 13)" in result.message, result.message
    assert result.statusword[0] & 0x2000, hex(result.statusword[0])
    assert not client.homed("joint_3")
    assert sim.state(2)["state"] == "Operation enabled"


def test_a_reference_never_found_times_out_halted_and_still_enabled(run):
    status, result = home_failing(run, 3, "no_reference")
    assert status == GoalStatus.STATUS_ABORTED and list(result.outcome) == ["timed_out"], result
    assert "joint_4" in result.message and "within the time-out" in result.message, result.message
    assert_enabled_and_still(run[0], 3)


def test_a_cancel_halts_the_homing_and_leaves_the_drive_enabled_and_still(run):
    status, result = home_failing(run, 4, "no_reference", cancel_after=0.5)
    assert status == GoalStatus.STATUS_CANCELED and list(result.outcome) == ["canceled"], result
    run[2].spin_for(0.3)
    assert_enabled_and_still(run[0], 4)


def test_a_power_cycle_forgets_the_reference(run):
    sim, _, client = run
    _, result = client.home(["joint_2"])
    assert result.success, result.message
    sim.command("power_cycle 1")
    client.spin_until(lambda: not client.homed("joint_2"), "joint_2 no longer homed", timeout=15)
