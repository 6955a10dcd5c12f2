"""FollowJointTrajectory from ROS: akd_node's ~/follow_joint_trajectory (control_msgs/action/FollowJointTrajectory) on
six virtual AKDs (one `akd-sim --udp --count 6` process), driven by an rclpy ActionClient in this process, the node in
another, as MoveIt's simple controller manager drives it.

A lagging drive is made as a real AKD lags: its max torque 0x6072 (per mille of peak) written low over SDO, so it cannot
accelerate as the trajectory asks. Positions and velocities are judged with tolerances, never timings; every wait is
bounded; the processes are always ended.
"""

from __future__ import annotations

import itertools
import math
import re

import pytest
from action_msgs.msg import GoalStatus
from builtin_interfaces.msg import Duration
from rclpy.action import ActionClient
from trajectory_msgs.msg import JointTrajectoryPoint

from akd_ros.srv import SdoWrite
from control_msgs.action import FollowJointTrajectory
from control_msgs.msg import JointTolerance
from support.ros import Participant, Sim, node_on_sim, ros_environment

DOMAINS = range(211, 221)
NODE = "/akd_node/"
JOINTS = [f"joint_{i}" for i in range(1, 7)]
COUNTS_PER_RAD = 2**20 / (2 * math.pi)
STOP_DECELERATION = 4.0
GOAL_TOLERANCE = 0.005
Result = FollowJointTrajectory.Result

PARAMS = """\
akd_node:
  ros__parameters:
    link: udp://127.0.0.1:{port}
    cycle_time: 0.002
    doors: [observe, operate, configure]
    mode: cyclic_synchronous_position
    follow_joint_trajectory.feedback_rate: 50.0
    trajectory.stop_deceleration: {deceleration}
    constraints.goal: {goal}
    constraints.goal_time: 1.0
    joints: [{joints}]
"""


def duration(seconds: float) -> Duration:
    return Duration(sec=int(seconds), nanosec=round((seconds - int(seconds)) * 1e9))


class Mover(Participant):
    """The client: ~/follow_joint_trajectory, as MoveIt reaches it."""

    def __init__(self, domain: int):
        super().__init__(domain, "akd_node_follow_test")
        self.client = ActionClient(self.node, FollowJointTrajectory, NODE + "follow_joint_trajectory")
        self.feedback: list = []

    def send(self, goal: FollowJointTrajectory.Goal):
        """Sends `goal`; its accepted goal handle."""
        self.spin_until(lambda: self.client.server_is_ready(), "~/follow_joint_trajectory action server")
        return self.send_goal(self.client, goal, lambda f: self.feedback.append(f.feedback))

    def result(self, handle, timeout: float = 20.0):
        """(goal status, result) of `handle` once it ends."""
        return self.goal_result(handle, timeout)


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    params = PARAMS.format(port="{port}", deceleration=STOP_DECELERATION, goal=GOAL_TOLERANCE, joints=", ".join(JOINTS))
    folder = tmp_path_factory.mktemp("follow")
    with ros_environment(DOMAINS) as domain:
        ready = lambda client: client.client.server_is_ready()  # noqa: E731
        with node_on_sim(params, folder, domain, count=len(JOINTS), client_of=Mover, ready=ready) as (
            sim,
            node,
            client,
        ):
            client.trigger("enable")
            client.spin_until(lambda: all(s["state"] == "Operation enabled" for s in states(sim)), "enabled")
            yield sim, node, client


@pytest.fixture(autouse=True)
def enabled(run):
    """Each test starts with every drive enabled: a fault test, or an F706 after a host stall of over 100 ms on a
    loaded machine, does not carry over to the next."""
    sim, _, client = run
    if not all(s["state"] == "Operation enabled" for s in states(sim)):
        client.trigger("reset_fault")
        client.trigger("enable")
        client.spin_until(lambda: all(s["state"] == "Operation enabled" for s in states(sim)), "enabled again")


def states(sim: Sim) -> list[dict]:
    return [sim.state(i) for i in range(len(JOINTS))]


def positions(sim: Sim) -> list[float]:
    """Each joint's position, rad."""
    return [s["position"] / COUNTS_PER_RAD for s in states(sim)]


def goal_to(targets: list[float], seconds: float, velocities: bool = False, **fields) -> FollowJointTrajectory.Goal:
    """A goal through one point: `targets` at `seconds` (at rest where `velocities`)."""
    point = JointTrajectoryPoint(positions=targets, time_from_start=duration(seconds))
    if velocities:
        point.velocities = [0.0] * len(targets)
    goal = FollowJointTrajectory.Goal(**fields)
    goal.trajectory.joint_names = JOINTS
    goal.trajectory.points = [point]
    return goal


def test_a_six_joint_trajectory_ends_succeeded_within_the_goal_tolerance(run):
    sim, _, client = run
    start = positions(sim)
    targets = [p + 0.2 * (i + 1) for i, p in enumerate(start)]
    client.feedback.clear()
    status, result = client.result(client.send(goal_to(targets, 1.0)))
    assert status == GoalStatus.STATUS_SUCCEEDED and result.error_code == Result.SUCCESSFUL, result.error_string
    errors = [abs(a - b) for a, b in zip(positions(sim), targets, strict=True)]
    assert max(errors) <= GOAL_TOLERANCE, errors
    assert client.feedback and list(client.feedback[-1].joint_names) == JOINTS
    last = client.feedback[-1]
    assert all(len(p.positions) == 6 for p in (last.desired, last.actual, last.error))


def test_a_bad_goal_is_refused_with_control_msgs_codes_and_nothing_moves(run):
    sim, _, client = run
    before = positions(sim)
    unknown = goal_to(before, 1.0)
    unknown.trajectory.joint_names = [*JOINTS[:5], "elbow"]
    status, result = client.result(client.send(unknown))
    assert status == GoalStatus.STATUS_ABORTED and result.error_code == Result.INVALID_JOINTS, result
    assert "unknown joint elbow" in result.error_string, result.error_string
    nan = goal_to([*before[:5], math.nan], 1.0)
    status, result = client.result(client.send(nan))
    assert result.error_code == Result.INVALID_GOAL and "joint_6" in result.error_string, result.error_string
    old = goal_to(before, 0.5)
    old.trajectory.header.stamp.sec = 1
    status, result = client.result(client.send(old))
    assert result.error_code == Result.OLD_HEADER_TIMESTAMP, result.error_string
    assert all(abs(a - b) < 1e-3 for a, b in zip(positions(sim), before, strict=True))


def write_max_torque(client: Mover, joint: str, per_mille: int) -> None:
    request = SdoWrite.Request(index=0x6072, subindex=0, data=list(per_mille.to_bytes(2, "little")))
    response = client.call(SdoWrite, f"{joint}/sdo_write", request)
    assert response.success, response.message


def test_a_lagging_drive_ends_path_or_goal_tolerance_violated_naming_it(run):
    sim, _, client = run
    # 1 % of the peak torque: just above the dry friction, so joint_2 accelerates slowly.
    write_max_torque(client, "joint_2", 10)
    try:
        start = positions(sim)
        tolerance = [JointTolerance(name="joint_2", position=0.01)]
        goal = goal_to([p + 1.0 for p in start], 0.5, path_tolerance=tolerance, goal_tolerance=tolerance)
        status, result = client.result(client.send(goal))
        assert status == GoalStatus.STATUS_ABORTED, result
        assert result.error_code in (Result.PATH_TOLERANCE_VIOLATED, Result.GOAL_TOLERANCE_VIOLATED), result
        assert "joint_2" in result.error_string, result.error_string
    finally:
        write_max_torque(client, "joint_2", 1000)
    client.spin_for(0.5)


def test_a_cancel_brings_the_joints_to_a_standstill_within_their_deceleration(run):
    sim, _, client = run
    start = positions(sim)
    speed = 0.5
    client.feedback.clear()
    handle = client.send(goal_to([p + 1.5 for p in start], 1.5 / speed))
    moved = lambda: client.feedback and client.feedback[-1].desired.positions[0] > start[0] + 0.3  # noqa: E731
    client.spin_until(moved, "motion")
    canceling = handle.cancel_goal_async()
    client.spin_until(canceling.done, "cancel response")
    status, result = client.result(handle)
    assert status == GoalStatus.STATUS_CANCELED, result
    client.spin_for(0.3)
    now = states(sim)
    assert all(abs(s["velocity"]) < COUNTS_PER_RAD * 0.01 for s in now), [s["velocity"] for s in now]
    # Stopped short of the goal, within the braking distance of where the set-points were when canceled.
    braking = speed**2 / (2 * STOP_DECELERATION)
    for i, p in enumerate(positions(sim)):
        assert start[i] + 0.1 < p < start[i] + 1.5 - 0.1, (i, p, start[i])
    desired = [f.desired for f in client.feedback]
    assert all(abs(v) <= speed * 1.01 for d in desired for v in d.velocities), "never faster than the trajectory"
    steps = [abs(b.positions[0] - a.positions[0]) for a, b in itertools.pairwise(desired)]
    assert max(steps) < speed * 0.2 + braking, steps


def test_a_new_goal_preempts_from_the_set_point_in_force_without_a_step(run):
    sim, _, client = run
    start = positions(sim)
    client.feedback.clear()
    first = client.send(goal_to([p + 1.0 for p in start], 2.0))
    client.spin_until(lambda: len(client.feedback) > 10, "motion of the first goal")
    second = client.send(goal_to([p - 0.3 for p in start], 1.5, velocities=True))
    status, result = client.result(first)
    assert status == GoalStatus.STATUS_ABORTED and "preempted" in result.error_string, result
    status, result = client.result(second)
    assert status == GoalStatus.STATUS_SUCCEEDED, result.error_string
    # The set-points fed back across the handover move no more than the motion does between two feedbacks.
    desired = [f.desired.positions[0] for f in client.feedback]
    steps = [abs(b - a) for a, b in itertools.pairwise(desired)]
    assert max(steps) < 0.1, max(steps)
    errors = [abs(a - (b - 0.3)) for a, b in zip(positions(sim), start, strict=True)]
    assert max(errors) <= GOAL_TOLERANCE, errors


def test_the_node_answers_requests_while_a_goal_runs(run):
    """A goal's execution waits for its trajectory for as long as it moves; it does so off the executor's thread, which
    takes the commands, so a request is answered while the goal still runs."""
    sim, _, client = run
    start = positions(sim)
    client.feedback.clear()
    handle = client.send(goal_to([p + 0.4 for p in start], 3.0))
    client.spin_until(lambda: len(client.feedback) > 2, "motion")
    result = handle.get_result_async()
    write_max_torque(client, "joint_2", 1000)
    assert not result.done(), "the request was answered only once the goal had ended"
    status, answer = client.result(handle)
    assert status == GoalStatus.STATUS_SUCCEEDED, answer.error_string


def test_a_fault_mid_way_aborts_the_goal_naming_the_joint(run):
    sim, _, client = run
    start = positions(sim)
    client.feedback.clear()
    handle = client.send(goal_to([p + 0.8 for p in start], 2.0))
    client.spin_until(lambda: len(client.feedback) > 5, "motion")
    sim.command("fault 3 F439")
    status, result = client.result(handle)
    assert status == GoalStatus.STATUS_ABORTED, result
    assert "joint_4" in result.error_string and "left Operation enabled" in result.error_string, result.error_string
    # A goal now (joint_4 in Fault, the others quick-stopped) is refused naming a joint as the goal does, by its name.
    handle = client.send(goal_to(start, 1.0))
    status, result = client.result(handle)
    assert status == GoalStatus.STATUS_ABORTED and result.error_code == Result.INVALID_GOAL, result
    assert re.search(r"nothing moved: joint_\d \(drive \d\): it is in ", result.error_string), result.error_string
