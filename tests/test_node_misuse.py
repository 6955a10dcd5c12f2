"""A careless client against the six-axis virtual robot: each case of issue 32, run as it was found, ends in a clear
refusal or the right result, nothing past a limit, no traceback.

The node runs `config/akd_sim_6axis.yaml` as shipped but for its link (one `akd-sim --udp --count 6` process, its
drives judging missed frames by the frames the line lost), in another process; this one is the client over real
rclpy. Positions are judged from /joint_states and from the simulator's own state, never by timing; every wait is
bounded; the processes are always ended.
"""

from __future__ import annotations

import math
import re
import signal
import threading
from pathlib import Path

import pytest
from action_msgs.msg import GoalStatus
from builtin_interfaces.msg import Duration
from rclpy.action import ActionClient
from rclpy.qos import QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import JointState
from std_srvs.srv import Trigger
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from akd_ros.action import Home
from akd_ros.msg import TrajectoryStatus
from akd_ros.srv import SetOutputs
from control_msgs.action import FollowJointTrajectory
from control_msgs.msg import JointTolerance
from support.ros import NodeProcess, Participant, Sim, ros_environment, stop

DOMAINS = range(70, 76)
OWN_DOMAINS = range(76, 78)
"""The SIGINT test's node, beside the module's."""
NODE = "/akd_node/"
JOINTS = [f"joint_{i}" for i in range(1, 7)]
SIX_AXES = Path(__file__).resolve().parents[1] / "config" / "akd_sim_6axis.yaml"
MAX_POSITION = {"joint_2": 2.0}
"""Position limits of the six-axis robot, rad: ±3.2, joint_2's ±2."""
MAX_VELOCITY = 6.0
STILL = 1e-3
"""rad: how far a joint may drift while nothing is commanded (the position loop's own settling)."""
Result = FollowJointTrajectory.Result


def six_axis_params(port: int) -> str:
    """config/akd_sim_6axis.yaml with its link on akd-sim over UDP at `port`."""
    text = SIX_AXES.read_text()
    assert "link: sim:6?missed=warn" in text, "the six-axis configuration's link moved"
    return text.replace("link: sim:6?missed=warn", f"link: udp://127.0.0.1:{port}")


def duration(seconds: float) -> Duration:
    whole = math.floor(seconds)
    return Duration(sec=whole, nanosec=round((seconds - whole) * 1e9))


def point(positions, seconds: float, velocities=None) -> JointTrajectoryPoint:
    p = JointTrajectoryPoint(positions=[float(x) for x in positions], time_from_start=duration(seconds))
    if velocities is not None:
        p.velocities = [float(v) for v in velocities]
    return p


class Careless(Participant):
    """The client: both actions, the services, ~/joint_trajectory and ~/joint_commands, /joint_states and
    ~/trajectory_status collected."""

    def __init__(self, domain: int):
        super().__init__(domain, "akd_node_misuse_test")
        qos = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE)
        for topic, kind in (("/joint_states", JointState), (NODE + "trajectory_status", TrajectoryStatus)):
            self.received[topic] = []
            self.node.create_subscription(kind, topic, self.received[topic].append, qos)
        self.follow = ActionClient(self.node, FollowJointTrajectory, NODE + "follow_joint_trajectory")
        self.homing = ActionClient(self.node, Home, NODE + "home")
        self.joint_trajectory = self.node.create_publisher(JointTrajectory, NODE + "joint_trajectory", qos)
        self.joint_commands = self.node.create_publisher(JointState, NODE + "joint_commands", qos)
        self.feedback: list = []

    def ready(self) -> bool:
        return self.follow.server_is_ready() and self.homing.server_is_ready() and bool(self.received["/joint_states"])

    def positions(self) -> dict[str, float]:
        message = self.latest("/joint_states")
        return dict(zip(message.name, message.position, strict=True))

    def efforts(self) -> dict[str, float]:
        message = self.latest("/joint_states")
        return dict(zip(message.name, message.effort, strict=True))

    def send(self, client: ActionClient, goal):
        """Sends `goal`; its accepted goal handle."""
        return self.send_goal(client, goal, lambda f: self.feedback.append(f.feedback))

    def result(self, handle, timeout: float = 20.0):
        """(goal status, result) of `handle` once it ends."""
        return self.goal_result(handle, timeout)

    def cancel(self, handle) -> None:
        canceling = handle.cancel_goal_async()
        self.spin_until(canceling.done, "cancel response")

    def home(self, joints: list[str], timeout: float = 20.0):
        return self.result(self.send(self.homing, Home.Goal(joints=joints)), timeout)

    def publish(self, publisher, message) -> None:
        self.spin_until(lambda: publisher.get_subscription_count() > 0, f"subscriber of {publisher.topic_name}")
        publisher.publish(message)

    def status_of_next(self, state: str, since: int) -> TrajectoryStatus:
        topic = NODE + "trajectory_status"
        self.spin_until(lambda: any(m.state == state for m in self.received[topic][since:]), f"trajectory {state}")
        return next(m for m in self.received[topic][since:] if m.state == state)


def trajectory(joints, points, stamp=None) -> JointTrajectory:
    message = JointTrajectory(joint_names=list(joints), points=list(points))
    if stamp is not None:
        message.header.stamp = stamp
    return message


def goal(joints, points, stamp=None, **fields) -> FollowJointTrajectory.Goal:
    return FollowJointTrajectory.Goal(trajectory=trajectory(joints, points, stamp), **fields)


class Robot:
    """The node on the simulator, with the client."""

    def __init__(self, folder: Path, domain: int):
        from support.netns import free_udp_port

        self.sim = Sim(free_udp_port(), count=len(JOINTS))
        path = folder / "akd_node.yaml"
        path.write_text(six_axis_params(self.sim.port))
        self.node = NodeProcess(path, domain)
        self.client = None
        try:
            self.client = Careless(domain)
            self.client.spin_until(lambda: self.client.ready() or self.node.process.poll() is not None, "the node")
            assert self.node.process.poll() is None, f"akd_node exited:\n{self.node.output()}"
        except BaseException:
            self.close()
            raise

    def states(self) -> list[dict]:
        return [self.sim.state(i) for i in range(len(JOINTS))]

    def enabled(self) -> bool:
        return all(s["state"] == "Operation enabled" for s in self.states())

    def enable(self) -> None:
        """Every drive without a fault, enabled."""
        if not self.enabled():
            self.client.trigger("reset_fault")
            self.client.trigger("enable")
        self.client.spin_until(self.enabled, "every drive enabled")

    def alive(self) -> None:
        """The node runs, answers, and printed no traceback."""
        assert self.node.process.poll() is None, f"akd_node exited:\n{self.node.output()}"
        assert "Traceback" not in self.node.output(), self.node.output()
        self.client.spin_until(lambda: self.client.call(Trigger, "enable") is not None, "an answer")

    def close(self) -> None:
        if self.client is not None:
            self.client.close()
        stop(self.node.process)
        self.sim.stop()
        print(f"akd_node output:\n{self.node.output()}")


@pytest.fixture(scope="module")
def robot(tmp_path_factory):
    with ros_environment(DOMAINS):
        import os

        run = Robot(tmp_path_factory.mktemp("misuse"), int(os.environ["ROS_DOMAIN_ID"]))
        yield run
        run.close()


@pytest.fixture(autouse=True)
def ready(request):
    """Each test of the shared robot starts with every drive enabled and ends with the node alive."""
    if "robot" not in request.fixturenames:
        yield
        return
    robot = request.getfixturevalue("robot")
    robot.enable()
    yield
    robot.alive()


def moved(before: dict[str, float], after: dict[str, float]) -> dict[str, float]:
    """The joints that moved by more than STILL, with how far."""
    return {j: after[j] - before[j] for j in before if abs(after[j] - before[j]) > STILL}


# --- 1. the crash -------------------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "output", ["9223372036854775808", "9223372036854775807", "18446744073709551616" * 3, "\u0663", "\uff11", "3", "0"]
)
def test_1_an_output_number_no_akd_has_is_refused_and_the_node_lives(robot, output):
    response = robot.client.call(
        SetOutputs, "set_outputs", SetOutputs.Request(joint="joint_6", outputs=[output], values=[True])
    )
    assert not response.success, response.message
    text = response.message
    assert text.startswith("outputs not set") and ("1, 2" in text or "1 to 2" in text), text


# --- 2. the speed limit -------------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("joint", "move", "seconds"),
    [("joint_4", 0.8, 0.1), ("joint_3", 2.5, 0.2)],
)
def test_2_a_goal_faster_than_max_velocity_is_refused_naming_joint_segment_and_speed(robot, joint, move, seconds):
    client = robot.client
    before = client.positions()
    status, result = client.result(client.send(client.follow, goal([joint], [point([before[joint] + move], seconds)])))
    assert status == GoalStatus.STATUS_ABORTED and result.error_code == Result.INVALID_GOAL, result.error_string
    text = result.error_string
    assert (
        f"{joint}: the segment to point 0" in text and f"past the joint's max_velocity {MAX_VELOCITY:g} rad/s" in text
    )
    speed = float(re.search(r"a velocity of ([-\d.]+) rad/s", text).group(1))
    assert abs(speed - move / seconds) < 1e-3 * move / seconds, text
    client.spin_for(0.3)
    assert not moved(before, client.positions())


def test_2_every_door_judges_the_speed_a_command_implies(robot):
    client = robot.client
    before = client.positions()
    since = len(client.received[NODE + "trajectory_status"])
    # ~/joint_trajectory: the same refusal, on ~/trajectory_status.
    client.publish(client.joint_trajectory, trajectory(["joint_4"], [point([before["joint_4"] + 0.8], 0.1)]))
    refused = client.status_of_next("refused", since)
    assert "joint_4: the segment to point 0" in refused.message and "max_velocity 6 rad/s" in refused.message
    # ~/joint_commands: a step of 0.1 rad in one 1 ms cycle is 100 rad/s.
    step = JointState(name=["joint_1"], position=[before["joint_1"] + 0.1])
    client.publish(client.joint_commands, step)
    client.spin_until(lambda: "~/joint_commands refused, nothing sent" in robot.node.output(), "the refusal")
    line = [x for x in robot.node.output().splitlines() if "~/joint_commands refused" in x][-1]
    assert "max_velocity 6 rad/s" in line and "within one cycle" in line, line
    client.spin_for(0.3)
    assert not moved(before, client.positions())


def test_2_the_path_between_the_points_is_judged_not_only_the_points(robot):
    client = robot.client
    before = client.positions()
    # Both points within ±3.2 rad and 6 rad/s; leaving 3.1 rad at 2 rad/s, the cubic back to 3.1 rad overshoots to
    # 3.1 + 8/27 rad.
    here = before["joint_1"]
    points = [point([3.1], 2.0 + abs(3.1 - here), [2.0]), point([3.1], 3.0 + abs(3.1 - here), [0.0])]
    status, result = client.result(client.send(client.follow, goal(["joint_1"], points)))
    assert status == GoalStatus.STATUS_ABORTED and result.error_code == Result.INVALID_GOAL
    assert (
        "joint_1: the segment from point 0 to point 1 reaches position 3.3963 rad, past the joint's max_position "
        "3.2 rad" in result.error_string
    ), result.error_string
    assert not moved(before, client.positions())


def test_2_a_goal_within_the_limits_is_followed_and_no_joint_passes_one(robot):
    client = robot.client
    before = client.positions()
    target = {j: before[j] + 0.3 for j in JOINTS}
    points = [point([target[j] for j in JOINTS], 1.0, [0.0] * 6)]
    since = len(client.received["/joint_states"])
    status, result = client.result(client.send(client.follow, goal(JOINTS, points)))
    assert status == GoalStatus.STATUS_SUCCEEDED, result.error_string
    # The cubic from rest to rest peaks at 1.5 times the mean 0.3 rad/s; every sample within the limit.
    peak = max(abs(v) for m in client.received["/joint_states"][since:] for v in m.velocity)
    assert 0.3 < peak <= MAX_VELOCITY, peak
    after = client.positions()
    assert all(abs(after[j] - target[j]) < 0.01 for j in JOINTS), after


# --- 3. success reported for nothing done --------------------------------------------------------------------------


def test_3_homing_a_disabled_or_quick_stopped_joint_fails_whatever_it_was_before(robot):
    client = robot.client
    # As found: every joint homed, then the node's ~/disable (or joint_2's quick stop), then joint_2 homed again.
    status, result = client.home([])
    assert status == GoalStatus.STATUS_SUCCEEDED and result.success, result.message
    for request in ("disable", "joint_2/quick_stop"):
        robot.enable()
        client.trigger(request)
        status, result = client.home(["joint_2"])
        assert status == GoalStatus.STATUS_ABORTED and not result.success, (request, result)
        assert list(result.outcome) == ["refused"] and "not homed: joint_2: refused" in result.message, result
        assert "Operation enabled" in result.reason[0], result.reason


@pytest.mark.parametrize("driven", [["joint_1"], JOINTS], ids=["joint_1_alone", "every_joint"])
def test_3_homing_a_joint_a_goal_drives_is_refused_and_the_goal_reaches_its_point(robot, driven):
    client = robot.client
    before = client.positions()
    target = {j: before[j] + 0.4 for j in driven}
    handle = client.send(client.follow, goal(driven, [point([target[j] for j in driven], 2.0, [0.0] * len(driven))]))
    client.spin_until(lambda: abs(client.positions()["joint_1"] - before["joint_1"]) > 0.01, "joint_1 moving")
    status, result = client.home(["joint_1"])
    assert status == GoalStatus.STATUS_ABORTED and list(result.outcome) == ["refused"], result
    assert re.search(r"a homing refused, nothing changed: trajectory \d+ drives it", result.reason[0]), result.reason
    status, followed = client.result(handle)
    assert status == GoalStatus.STATUS_SUCCEEDED, followed.error_string
    client.spin_for(0.3)
    after = client.positions()
    assert all(abs(after[j] - target[j]) < 0.01 for j in driven), (target, after)
    assert all(s["fault"] is None for s in robot.states()), robot.states()


# --- 4. goals left without an answer -------------------------------------------------------------------------------


def stamp_in(client: Careless, seconds: float):
    return (client.node.get_clock().now() + rclpy_duration(seconds)).to_msg()


def rclpy_duration(seconds: float):
    from rclpy.duration import Duration as RosDuration

    return RosDuration(nanoseconds=round(seconds * 1e9))


def test_4_a_goal_waiting_for_its_start_ends_at_a_cancel_or_a_disable(robot):
    client = robot.client
    before = client.positions()
    for ahead, end in ((6.0, "cancel"), (3600.0, "cancel"), (3600.0, "disable")):
        robot.enable()
        stamp = stamp_in(client, ahead)
        handle = client.send(client.follow, goal(["joint_1"], [point([before["joint_1"] + 0.1], 1.0)], stamp))
        client.spin_for(0.5)
        if end == "cancel":
            client.cancel(handle)
        else:
            client.trigger("disable")
        # Bounded well short of the stamp: it ends now, not when it was due.
        status, result = client.result(handle, timeout=3.0)
        expected = GoalStatus.STATUS_CANCELED if end == "cancel" else GoalStatus.STATUS_ABORTED
        assert status == expected, (end, status, result.error_string)
        assert not moved(before, client.positions())


def test_4_twenty_enable_calls_at_once_are_all_answered(robot):
    client = robot.client
    callers = [client.node.create_client(Trigger, NODE + "enable") for _ in range(20)]
    for caller in callers:
        client.spin_until(caller.service_is_ready, "~/enable")
        # One call each first: a client just discovered may not get its first answer back (DDS matches the answer's
        # way later than the request's), which is no fault of the node's.
        warm_up = caller.call_async(Trigger.Request())
        client.spin_until(warm_up.done, "an answer")
    futures = [caller.call_async(Trigger.Request()) for caller in callers]
    client.spin_until(lambda: all(f.done() for f in futures), "20 answers")
    assert all(f.result().success for f in futures), [f.result().message for f in futures]
    for caller in callers:
        client.node.destroy_client(caller)


# --- 5. a reset that cuts power --------------------------------------------------------------------------------------


def test_5_a_reset_without_a_fault_takes_power_from_no_drive_and_the_goal_goes_on(robot):
    client = robot.client
    before = client.positions()
    target = before["joint_5"] + 0.3
    handle = client.send(client.follow, goal(["joint_5"], [point([target], 1.0, [0.0])]))
    response = client.call(Trigger, "reset_fault")
    assert response.success and "no fault to reset" in response.message, response.message
    response = client.call(Trigger, "joint_5/reset_fault")
    assert response.success and "no fault to reset" in response.message, response.message
    assert robot.enabled()
    status, result = client.result(handle)
    assert status == GoalStatus.STATUS_SUCCEEDED, result.error_string
    assert robot.enabled()


# --- 6. smaller ------------------------------------------------------------------------------------------------------


def test_6_a_joint_homed_by_one_goal_is_refused_to_another_and_a_cancel_ends_only_its_own(robot):
    client = robot.client
    robot.sim.command("homing 3 no_reference")
    client.feedback.clear()
    try:
        first = client.send(client.homing, Home.Goal(joints=["joint_4"]))
        client.spin_until(lambda: any("in_progress" in f.state for f in client.feedback if hasattr(f, "state")), "home")
        status, result = client.home(["joint_4"])
        assert status == GoalStatus.STATUS_ABORTED and "already homed by another goal" in result.message, result
        assert robot.states()[3]["state"] == "Operation enabled"
        client.cancel(first)
        status, result = client.result(first)
        assert status == GoalStatus.STATUS_CANCELED and list(result.outcome) == ["canceled"], result
    finally:
        robot.sim.command("homing 3 ok")
    client.spin_until(lambda: "~/home: canceled" in robot.node.output(), "the cancel in the log")
    line = next(x for x in robot.node.output().splitlines() if "~/home: canceled" in x)
    assert line.startswith("[INFO]"), line


def test_6_a_joint_named_twice_is_refused_before_anything_moves(robot):
    status, result = robot.client.home(["joint_4", "joint_4"])
    assert status == GoalStatus.STATUS_ABORTED and "joint_4 named twice" in result.message, result


def test_6_homing_feedback_shows_every_joint_as_it_is(robot):
    client = robot.client
    client.feedback.clear()
    status, result = client.home(["joint_1", "joint_2", "joint_3"])
    assert status == GoalStatus.STATUS_SUCCEEDED, result.message
    homing = [f for f in client.feedback if hasattr(f, "state")]
    assert homing and all("waiting" not in f.state for f in homing), [list(f.state) for f in homing]


@pytest.mark.parametrize(
    ("fields", "why"),
    [
        ({"time_from_start": -1.0}, "time_from_start is -1 s"),
        ({"goal_time_tolerance": duration(-1.0)}, "goal_time_tolerance -1 s"),
        ({"path_tolerance": [JointTolerance(name="joint_1", position=math.nan)]}, "position nan"),
        ({"goal_tolerance": [JointTolerance(name="joint_1", velocity=-2.0)]}, "velocity -2.0"),
    ],
    ids=["time_from_start", "goal_time_tolerance", "nan_tolerance", "negative_tolerance"],
)
def test_6_negative_times_and_bad_tolerances_are_refused_saying_why(robot, fields, why):
    client = robot.client
    before = client.positions()
    seconds = fields.pop("time_from_start", 2.0)
    points = [point([before["joint_1"] + 0.1], 1.0), point([before["joint_1"] + 0.2], seconds)]
    status, result = client.result(client.send(client.follow, goal(["joint_1"], points, **fields)))
    assert status == GoalStatus.STATUS_ABORTED and result.error_code == Result.INVALID_GOAL, result.error_string
    assert why in result.error_string and "unsigned" not in result.error_string, result.error_string
    assert not moved(before, client.positions())


def test_6_a_tolerance_of_minus_one_is_not_judged(robot):
    client = robot.client
    here = client.positions()["joint_1"]
    tolerance = [JointTolerance(name="joint_1", position=-1.0, velocity=-1.0)]
    status, result = client.result(
        client.send(client.follow, goal(["joint_1"], [point([here + 0.1], 0.5, [0.0])], goal_tolerance=tolerance))
    )
    assert status == GoalStatus.STATUS_SUCCEEDED, result.error_string


def test_6_a_preempted_goal_ends_aborted_with_an_error_code(robot):
    client = robot.client
    here = client.positions()["joint_1"]
    first = client.send(client.follow, goal(["joint_1"], [point([here + 0.3], 2.0, [0.0])]))
    client.spin_for(0.3)
    second = client.send(client.follow, goal(["joint_1"], [point([here + 0.1], 1.0, [0.0])]))
    status, result = client.result(first)
    assert status == GoalStatus.STATUS_ABORTED and result.error_code == Result.INVALID_GOAL, result
    assert result.error_string.startswith("preempted"), result.error_string
    assert client.result(second)[0] == GoalStatus.STATUS_SUCCEEDED


def test_6_a_trajectory_stamped_in_the_past_is_refused_by_both_doors(robot):
    client = robot.client
    before = client.positions()
    stamp = stamp_in(client, -100.0)
    since = len(client.received[NODE + "trajectory_status"])
    client.publish(client.joint_trajectory, trajectory(["joint_1"], [point([before["joint_1"] + 0.1], 1.0)], stamp))
    refused = client.status_of_next("refused", since)
    assert "before it arrived" in refused.message, refused.message
    status, result = client.result(
        client.send(client.follow, goal(["joint_1"], [point([before["joint_1"] + 0.1], 1.0)], stamp))
    )
    assert status == GoalStatus.STATUS_ABORTED and result.error_code == Result.OLD_HEADER_TIMESTAMP
    client.spin_for(0.3)
    assert not moved(before, client.positions())


def test_6_a_power_stage_that_is_off_makes_no_torque(robot):
    client = robot.client
    client.trigger("joint_2/quick_stop")
    client.trigger("joint_2/disable")
    client.spin_for(0.3)
    assert robot.states()[1]["state"] == "Switch on disabled"
    assert client.efforts()["joint_2"] == 0.0, client.efforts()


# --- 4, on a node of its own: SIGINT with goals executing ------------------------------------------------------------


def test_4_sigint_answers_every_goal_executing_before_the_bus_goes_to_init(tmp_path):
    with ros_environment(OWN_DOMAINS) as domain:
        robot = Robot(tmp_path, domain)
        try:
            client = robot.client
            robot.enable()
            here = client.positions()
            robot.sim.command("homing 1 no_reference")
            homing = client.send(client.homing, Home.Goal(joints=["joint_2"]))
            follow = client.send(client.follow, goal(["joint_1"], [point([here["joint_1"] + 1.0], 10.0, [0.0])]))
            client.spin_until(lambda: abs(client.positions()["joint_1"] - here["joint_1"]) > 0.01, "joint_1 moving")
            # As Ctrl-C: SIGINT to the node, from a thread, while this one spins for the answers.
            threading.Thread(target=robot.node.process.send_signal, args=(signal.SIGINT,)).start()
            answers = [client.result(homing), client.result(follow)]
            robot.node.process.wait(timeout=30)
        finally:
            robot.close()
    (home_status, home_result), (follow_status, follow_result) = answers
    assert home_status == GoalStatus.STATUS_ABORTED and "the node is shutting down" in home_result.message
    assert follow_status == GoalStatus.STATUS_ABORTED and "shutting down" in follow_result.error_string
    output = robot.node.output()
    assert robot.node.process.returncode == 0 and "Traceback" not in output, output
    assert output.index("~/home: the node is shutting down") < output.index("bus in Init"), output
    assert output.index("~/follow_joint_trajectory: trajectory") < output.index("bus in Init"), output
