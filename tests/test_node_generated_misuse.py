"""Generated misuse, checked by invariants: Hypothesis drives the six-axis virtual robot (`config/akd_sim_6axis.yaml`
on one `akd-sim --udp --count 6`, the node in another process, this one the client over real rclpy) with goals of
both actions, ~/joint_trajectory, ~/joint_commands and position commands, homing requests, output writes, cancels and
bursts of service calls, in random order and timing, and after every step checks:

- no crash and no traceback: the node runs and has printed none;
- the node still answers (its lifecycle state, at once);
- nothing moves on a refusal: a goal refused while the robot stood still leaves every joint where it was;
- no joint past its limits: every position set-point the drives received while enabled in cyclic synchronous position
  (the simulator's set-point trace) is within the joint's position limits (or, for a joint that coasted past one,
  no further out than it was) and moved from the one before at most at max_velocity;
- every accepted goal ends with a result: within its own duration and bound, and all of them when the example's goals
  are canceled at its end;
- every service call of a burst is answered.

The budget is small here (`AKD_MISUSE_EXAMPLES` examples of `AKD_MISUSE_STEPS` steps, 40 of 10 unless set);
`bench/misuse_soak.py` runs the same machine for hours and says how many cases it tried.
"""

from __future__ import annotations

import collections
import json
import math
import os
import time
from pathlib import Path

import pytest
from action_msgs.msg import GoalStatus
from hypothesis import HealthCheck, settings
from hypothesis import strategies as st
from hypothesis.stateful import RuleBasedStateMachine, invariant, rule, run_state_machine_as_test
from lifecycle_msgs.srv import GetState
from rclpy.qos import QoSProfile, ReliabilityPolicy
from std_msgs.msg import Float64
from std_srvs.srv import Trigger

from akd_ros.action import Home
from akd_ros.srv import SetOutputs
from control_msgs.msg import JointTolerance
from support.netns import free_udp_port
from support.ros import NodeProcess, Sim, ros_environment, stop
from test_node_misuse import JOINTS, NODE, SIX_AXES, Careless, duration, goal, point, six_axis_params, trajectory

DOMAINS = range(*(int(n) for n in os.environ.get("AKD_MISUSE_DOMAINS", "78 84").split()))
"""The ROS domains this module picks from; the soak takes ones no test module uses, so it can run beside the suite (a
run sharing a domain with the suite's saw the other node's /joint_states)."""
EXAMPLES = int(os.environ.get("AKD_MISUSE_EXAMPLES", "40"))
STEPS = int(os.environ.get("AKD_MISUSE_STEPS", "10"))
CASES_FILE = os.environ.get("AKD_MISUSE_CASES")
"""Where bench/misuse_soak.py has the steps tried counted."""

PERIOD_S = 0.001
WINDOW_S = 0.01
"""How far back a set-point's speed is judged: ten periods."""
"""config/akd_sim_6axis.yaml's cycle_time."""
GEARS = [100.0, 100.0, 80.0, 50.0, 50.0, 50.0]
LIMIT = [3.2, 2.0, 3.2, 3.2, 3.2, 3.2]
MAX_VELOCITY = 6.0
COUNTS_PER_RAD = [2**20 * gear / (2 * math.pi) for gear in GEARS]
STILL = 1e-3
QUIET_S = 1.5
"""How long after a command published on a topic the robot counts as still again, if it is: the command may still be
on its way to the node."""
GOAL_BOUND_S = 15.0
"""How long past its end (plus its goal time tolerance and its stamp) an accepted goal may take to answer."""
SERVICES = ["enable", "disable", "reset_fault", "quick_stop"]
BURST = 20
"""The most calls of one service a burst makes at once."""


class Robot:
    """The node and its simulator, with the set-point trace, for every example of the module."""

    def __init__(self, folder: Path, domain: int):
        self.trace = folder / "setpoints.jsonl"
        self.sim = Sim(free_udp_port(), count=len(JOINTS), setpoint_trace=self.trace)
        path = folder / "akd_node.yaml"
        path.write_text(six_axis_params(self.sim.port))
        self.node = NodeProcess(path, domain)
        self.client = Careless(domain)
        self.client.spin_until(lambda: self.client.ready() or self.node.process.poll() is not None, "the node")
        assert self.node.process.poll() is None, f"akd_node exited:\n{self.node.output()}"
        self.read_at = 0
        self.last: dict[int, dict] = {}
        self.windows: dict[int, collections.deque] = collections.defaultdict(collections.deque)
        """Each drive's recent set-points since it was last held, over which its speed is judged."""
        self._callers: dict[str, list] = {}
        self.last_published = 0.0
        """When a command was last published on a topic (monotonic s)."""
        self.tried: collections.Counter = collections.Counter()
        """Steps tried, by rule."""

    def callers(self, name: str) -> list:
        """BURST clients of Trigger service ~/`name`, made once and each answered once: a client just discovered may
        miss its first answer (DDS matches the answer's way later than the request's), no fault of the node's. Each
        keeps room for every answer of a burst: Fast DDS hands each answer of a service to every client of it (each
        picks its own out), and a client's default queue of 10 overflowed when twenty came at once, dropping its own
        now and then, no fault of the node's either."""
        if name not in self._callers:
            qos = QoSProfile(depth=10 * BURST, reliability=ReliabilityPolicy.RELIABLE)
            callers = [self.client.node.create_client(Trigger, NODE + name, qos_profile=qos) for _ in range(BURST)]
            for caller in callers:
                self.client.spin_until(caller.service_is_ready, name)
                first = caller.call_async(Trigger.Request())
                self.client.spin_until(first.done, f"an answer of {name}")
            self._callers[name] = callers
        return self._callers[name]

    def close(self) -> None:
        self.client.close()
        stop(self.node.process)
        self.sim.stop()
        print(f"akd_node output:\n{self.node.output()}")

    def new_setpoints(self) -> list[dict]:
        """The set-point trace's lines since the last call (those the writer has written)."""
        with self.trace.open() as trace:
            trace.seek(self.read_at)
            text = trace.read()
        complete = text[: text.rfind("\n") + 1]
        self.read_at += len(complete.encode())
        return [json.loads(line) for line in complete.splitlines() if line.startswith('{"drive"')]


def enabled_in_csp(line: dict) -> bool:
    """Whether the drive was commanded in Operation enabled (controlword 0x0F, no fault reset) in cyclic synchronous
    position."""
    return line.get("controlword", 0) & 0x8F == 0x0F and line.get("modes_of_operation") == 8


def past(position: float, limit: float) -> float:
    """How far `position` is past ±`limit`, rad (0 within)."""
    return max(0.0, abs(position) - limit)


def check_setpoints(robot: Robot) -> None:
    """No position set-point a drive received while enabled went past its joint's limits or moved faster than
    max_velocity. The speed is judged from the newest set-point at least WINDOW_S older, not frame by frame: a cycle the
    master ran late (the VM stalls its thread now and then) advances the set-point by all the time it missed, in one
    frame that can come a period after the late one, whose own receipt carries the stall (a soak saw 0.017 rad in one
    frame 1.1 ms after the one before, the drive nearly still, in a run whose cycle stalled up to 42 ms); a window
    reaching back past the late frame spans the stall, which the allowance (1.2 times, plus a period) covers, while a
    joint driven faster than max_velocity for longer than a window is still caught. A target set where the drive stands
    (the sequencer holding it at the actual position, as after an enable), if it jumps, moves nothing, whatever the
    target before and wherever it stands: a window starts there. A target following the drive closely in motion is no
    hold: it stays in the window."""
    for line in robot.new_setpoints():
        drive, target = line["drive"], line.get("target_position")
        before, robot.last[drive] = robot.last.get(drive), line
        window = robot.windows[drive]
        if target is None or before is None or not (enabled_in_csp(line) and enabled_in_csp(before)):
            window.clear()
            continue
        rad, previous = target / COUNTS_PER_RAD[drive], before["target_position"] / COUNTS_PER_RAD[drive]
        # Where the drive stands: held, or followed closely; past a limit too where a homing search (which knows no
        # limits yet) left it.
        stands = abs(rad - line["position"] / COUNTS_PER_RAD[drive]) <= MAX_VELOCITY * PERIOD_S
        joint = JOINTS[drive]
        assert stands or past(rad, LIMIT[drive]) <= past(previous, LIMIT[drive]) + 1e-6, (
            f"{joint}'s set-point {rad} rad is past its limit ±{LIMIT[drive]} (before: {previous}): {line}"
        )
        if line["frame"] - before["frame"] != 1:
            # The frames between carried before's target (only changes are traced): it stood until the last one.
            window.clear()
            window.append({**before, "monotonic_ns": line["monotonic_ns"] - round(PERIOD_S * 1e9)})
        # From the newest set-point at least WINDOW_S before this one: a window that spans a stall.
        while len(window) > 1 and line["monotonic_ns"] - window[1]["monotonic_ns"] >= WINDOW_S * 1e9:
            window.popleft()
        first = window[0] if window else before
        seconds = (line["monotonic_ns"] - first["monotonic_ns"]) * 1e-9 + PERIOD_S
        moved = rad - first["target_position"] / COUNTS_PER_RAD[drive]
        allowed = MAX_VELOCITY * seconds * 1.2 + 2 / COUNTS_PER_RAD[drive]
        if abs(moved) > allowed and stands:
            # A hold: the target jumped to where the drive stands, which moves nothing; a window starts there.
            window.clear()
            window.append(line)
            continue
        assert abs(moved) <= allowed, (
            f"{joint}'s set-point moved {moved} rad in {seconds - PERIOD_S} s, past max_velocity: {first} -> {line}"
        )
        window.append(line)


# --- what the machine generates -------------------------------------------------------------------------------------

FLAWS = [
    None,
    "unknown_joint",
    "joint_twice",
    "no_joints",
    "no_points",
    "nan",
    "inf",
    "past_limit",
    "too_fast",
    "negative_time",
    "zero_time",
    "times_not_increasing",
    "nan_tolerance",
    "negative_tolerance",
    "no_tolerance",
    "negative_goal_time",
    "stamp_past",
    "stamp_soon",
    "stamp_in_an_hour",
]
"""What is wrong with a generated trajectory, if anything; its first, the simplest draw, is a trajectory to follow."""

motions = st.tuples(
    st.lists(st.sampled_from(JOINTS), min_size=1, max_size=6, unique=True),
    st.lists(
        st.tuples(st.lists(st.floats(-0.5, 0.5), min_size=6, max_size=6), st.floats(0.1, 2.0)), min_size=1, max_size=3
    ),
    st.booleans(),
    st.sampled_from(FLAWS),
)
"""(joints, points of (offsets from where each joint stands, gap to the point before), cubic, flaw)."""


def made(motion, here: dict[str, float]):
    """`motion` as (joints, points of (positions, time from start), cubic, stamp offset s, tolerances, goal time s)."""
    joints, points, cubic, flaw = motion
    joints = list(joints)
    elapsed, made_points = 0.0, []
    for values, gap in points:
        elapsed += gap * (0.02 if flaw == "too_fast" else 1.0)
        made_points.append(([here[j] + v for j, v in zip(joints, values, strict=False)], elapsed))
    tolerance, goal_time, stamp = 0.0, 0.0, 0.0
    if flaw == "unknown_joint":
        joints[-1] = "joint_7"
    elif flaw == "joint_twice":
        joints.append(joints[0])
        made_points = [([*p, p[0]], t) for p, t in made_points]
    elif flaw == "no_joints":
        joints, made_points = [], [([], t) for _, t in made_points]
    elif flaw == "no_points":
        made_points = []
    elif flaw in ("nan", "inf", "past_limit"):
        value = {"nan": math.nan, "inf": math.inf, "past_limit": 4.0}[flaw]
        made_points[-1][0][0] = value
    elif flaw in ("negative_time", "zero_time"):
        made_points[0] = (made_points[0][0], -1.0 if flaw == "negative_time" else 0.0)
    elif flaw == "times_not_increasing":
        made_points.append((made_points[-1][0], made_points[-1][1]))
    elif flaw in ("nan_tolerance", "negative_tolerance", "no_tolerance"):
        tolerance = {"nan_tolerance": math.nan, "negative_tolerance": -2.0, "no_tolerance": -1.0}[flaw]
    elif flaw == "negative_goal_time":
        goal_time = -1.0
    elif flaw is not None and flaw.startswith("stamp"):
        stamp = {"stamp_past": -100.0, "stamp_soon": 1.0, "stamp_in_an_hour": 3600.0}[flaw]
    return joints, made_points, cubic, stamp, tolerance, goal_time


outputs = st.lists(
    st.one_of(
        st.sampled_from(["1", "2", "3", "0", "gripper_open", "\u0663", "\uff11", "-1", "+1", " 1", "9" * 30]),
        st.integers(0, 2**70).map(str),
        st.text(max_size=4),
    ),
    max_size=3,
)


class Misuse(RuleBasedStateMachine):
    """One example: a random sequence of what a careless client does. `robot` is the module's."""

    robot: Robot

    def __init__(self):
        super().__init__()
        self.goals: list[tuple[object, float, str]] = []
        """Each accepted goal's handle, the monotonic time by which it must have answered, and what it was."""
        self.answers: list = []
        self.still_stamp = None
        """The stamp of the /joint_states message the robot was last judged still by."""

    @property
    def client(self) -> Careless:
        return self.robot.client

    def step(self, rule: str) -> None:
        self.robot.tried[rule] += 1

    def still(self) -> dict[str, float] | None:
        """Every joint's position when the robot stands still with no goal of this example pending and no trajectory
        running, else None: a refusal then must leave them so."""
        if any(not self.ended(handle) for handle, _, _ in self.goals):
            return None
        # A command on a topic reaches the node some time after it was published, unanswered: not quiet yet.
        if time.monotonic() - self.robot.last_published < QUIET_S:
            return None
        message = self.client.latest("/joint_states")
        if any(abs(v) > 1e-3 for v in message.velocity):
            return None
        self.still_stamp = message.header.stamp
        statuses = self.client.received[NODE + "trajectory_status"]
        running = {m.id for m in statuses if m.state == "running"} - {m.id for m in statuses if m.state != "running"}
        if running or any(m.state == "pending" for m in statuses[-3:]):
            return None
        return dict(zip(message.name, message.position, strict=True))

    def ended(self, handle) -> bool:
        return handle.status in (GoalStatus.STATUS_SUCCEEDED, GoalStatus.STATUS_ABORTED, GoalStatus.STATUS_CANCELED)

    def accepted(self, client, goal_message, bound_s: float, what: str):
        handle = self.client.send_goal(client, goal_message)
        result = handle.get_result_async()
        self.answers.append(result)
        self.goals.append((handle, time.monotonic() + bound_s, what))
        return handle, result

    # --- rules ---------------------------------------------------------------------------------------------------

    @rule(motion=motions)
    def follow(self, motion):
        self.step("follow")
        before = self.still()
        joints, points, cubic, stamp, tolerance, goal_time = made(motion, self.client.positions())
        rest = [0.0] * len(joints) if cubic else None
        header = None if stamp == 0.0 else stamp_in(self.client, stamp)
        tolerances = [JointTolerance(name=j, position=tolerance, velocity=tolerance) for j in joints[:1]]
        message = goal(
            joints,
            [point(positions, t, rest) for positions, t in points],
            header,
            path_tolerance=tolerances,
            goal_tolerance=tolerances,
            goal_time_tolerance=duration(goal_time),
        )
        elapsed = max((t for _, t in points), default=0.0)
        bound = max(stamp, 0.0) + max(elapsed, 0.0) + 1.0 + GOAL_BOUND_S
        handle, result = self.accepted(self.client.follow, message, bound, f"follow {motion}")
        if before is not None:
            judged_ns = time.monotonic_ns()
            # A refused goal is answered at once, before anything moved.
            self.client.spin_until(lambda: result.done() or handle.status == GoalStatus.STATUS_EXECUTING, "an answer")
            self.client.spin_for(0.05)
            if result.done() and result.result().result.error_string.startswith("goal refused"):
                self.client.spin_for(0.2)
                after = dict(zip(JOINTS, (self.client.positions()[j] for j in JOINTS), strict=True))
                moved = {j: after[j] - before[j] for j in JOINTS if abs(after[j] - before[j]) > STILL}
                assert not moved, self.why_moved(result.result().result.error_string, moved, judged_ns)

    def why_moved(self, refusal: str, moved: dict[str, float], judged_ns: int) -> str:
        """What the soak needs to tell who moved a joint a refused goal did not name: what each moved joint's drive
        received from half a second before the robot was judged still (akd-sim stamps it with this host's monotonic
        clock; its writer may lag, so it is given a second to catch up), the moved joints' last /joint_states, the
        trajectories' last statuses, this example's goals and the node's log."""
        time.sleep(1.0)
        since = judged_ns - 500_000_000
        with self.robot.trace.open() as trace:
            lines = [json.loads(line) for line in trace if line.startswith('{"drive"')]
        lines = [line for line in lines if line["monotonic_ns"] >= since]
        received = [
            f"every drive's traced frames since: {dict(collections.Counter(JOINTS[x['drive']] for x in lines))}"
        ]
        keys = ("monotonic_ns", "controlword", "modes_of_operation", "target_position", "position")
        for joint in moved:
            mine = [{k: line.get(k) for k in keys} for line in lines if line["drive"] == JOINTS.index(joint)]
            received.append(f"{joint} (judged at {judged_ns}): {len(mine)} frames: {mine[:6]} ... {mine[-6:]}")
        states = self.client.received["/joint_states"][-40:]
        for joint in moved:
            at = states[-1].name.index(joint)
            seen = [
                (m.header.stamp.sec % 1000 + m.header.stamp.nanosec * 1e-9, m.position[at], m.velocity[at])
                for m in states
            ]
            received.append(f"{joint} on /joint_states (stamp, position, velocity): {seen}")
        statuses = [
            (m.id, m.state, list(m.joints), m.message) for m in self.client.received[NODE + "trajectory_status"][-8:]
        ]
        goals = [(what, handle.status) for handle, _, what in self.goals]
        log = self.robot.node.output().splitlines()[-30:]
        judged_by = self.still_stamp.sec % 1000 + self.still_stamp.nanosec * 1e-9
        return "\n".join(
            [
                f"{refusal}; moved: {moved}; judged still by /joint_states stamped {judged_by:.3f}",
                *received,
                f"last statuses: {statuses}",
                f"goals: {goals}",
                *log,
            ]
        )

    @rule(motion=motions)
    def joint_trajectory(self, motion):
        self.step("joint_trajectory")
        joints, points, cubic, stamp, _, _ = made(motion, self.client.positions())
        rest = [0.0] * len(joints) if cubic else None
        header = None if stamp == 0.0 else stamp_in(self.client, stamp)
        message = trajectory(joints, [point(positions, t, rest) for positions, t in points], header)
        self.client.publish(self.client.joint_trajectory, message)
        self.robot.last_published = time.monotonic()

    @rule(joint=st.sampled_from(JOINTS), step=st.sampled_from([0.0, 1e-4, 3e-3, 0.05, 1.0, math.nan]))
    def position_command(self, joint, step):
        self.step("position_command")
        publisher = self.client.node.create_publisher(Float64, f"{NODE}{joint}/position_command", 10)
        self.client.publish(publisher, Float64(data=self.client.positions()[joint] + step))
        self.robot.last_published = time.monotonic()
        self.client.node.destroy_publisher(publisher)

    @rule(
        joints=st.one_of(
            st.lists(st.sampled_from(JOINTS), max_size=6, unique=True),
            st.lists(st.sampled_from([*JOINTS, "joint_7", ""]), max_size=4),
        ),
        cancel_after=st.sampled_from([None, 0.0, 0.2]),
    )
    def home(self, joints, cancel_after):
        self.step("home")
        handle, _ = self.accepted(self.client.homing, Home.Goal(joints=joints), 60.0, f"home {joints}")
        if cancel_after is not None:
            self.client.spin_for(cancel_after)
            self.client.cancel(handle)

    @rule(joint=st.sampled_from([*JOINTS, "", "joint_9"]), names=outputs, analog=st.booleans())
    def set_outputs(self, joint, names, analog):
        self.step("set_outputs")
        request = SetOutputs.Request(joint=joint, outputs=names, values=[True] * len(names))
        request.set_analog_output, request.analog_output = analog, 1.0
        response = self.client.call(SetOutputs, "set_outputs", request)
        assert response.success or response.message.startswith("outputs not set"), response.message

    @rule(
        # Enable as often as the others together: a robot left disabled refuses every motion after.
        service=st.sampled_from(["enable", "enable", "enable", *SERVICES[1:]]),
        joint=st.sampled_from([None, *JOINTS]),
        count=st.integers(1, BURST),
    )
    def burst(self, service, joint, count):
        self.step("burst")
        callers = self.robot.callers(service if joint is None else f"{joint}/{service}")[:count]
        futures = [caller.call_async(Trigger.Request()) for caller in callers]
        # Answered one after the other, each within the wait a request may take (5 s) past its own time-out.
        self.client.spin_until(
            lambda: all(f.done() for f in futures), f"{count} answers of {callers[0].srv_name}", timeout=10 + 6 * count
        )

    @rule(index=st.integers(0, 100))
    def cancel(self, index):
        self.step("cancel")
        if self.goals:
            handle, _, _ = self.goals[index % len(self.goals)]
            self.client.cancel(handle)

    @rule(seconds=st.sampled_from([0.0, 0.05, 0.3, 1.0]))
    def wait(self, seconds):
        self.step("wait")
        self.client.spin_for(seconds)

    # --- invariants ------------------------------------------------------------------------------------------------

    @invariant()
    def alive_and_answering(self):
        node = self.robot.node
        assert node.process.poll() is None, f"akd_node exited:\n{node.output()}"
        assert "Traceback" not in node.output(), node.output()
        state = self.client.call(GetState, "get_state")
        assert state.current_state.label == "active", state

    @invariant()
    def within_limits(self):
        check_setpoints(self.robot)

    @invariant()
    def goals_answer_in_time(self):
        now = time.monotonic()
        late = [what for handle, by, what in self.goals if now > by and not self.ended(handle)]
        assert not late, late

    def teardown(self):
        """Every goal of the example ends with a result once canceled; the robot is left enabled, in its limits."""
        for handle, _, _ in self.goals:
            if not self.ended(handle):
                self.client.cancel(handle)
        self.client.spin_until(lambda: all(a.done() for a in self.answers), "every goal's result", timeout=60.0)
        self.robot.client.call(Trigger, "reset_fault")
        self.robot.client.call(Trigger, "enable")
        check_setpoints(self.robot)


def stamp_in(client: Careless, seconds: float):
    from rclpy.duration import Duration as RosDuration

    return (client.node.get_clock().now() + RosDuration(nanoseconds=round(seconds * 1e9))).to_msg()


@pytest.fixture(scope="module")
def robot(tmp_path_factory):
    with ros_environment(DOMAINS) as domain:
        run = Robot(tmp_path_factory.mktemp("generated_misuse"), domain)
        yield run
        run.close()


def test_generated_misuse_keeps_every_invariant(robot):
    assert SIX_AXES.exists()
    Misuse.robot = robot
    robot.client.trigger("enable")
    started = time.monotonic()
    try:
        run_state_machine_as_test(
            Misuse,
            settings=settings(
                max_examples=EXAMPLES,
                stateful_step_count=STEPS,
                deadline=None,
                database=None,
                suppress_health_check=list(HealthCheck),
            ),
        )
    finally:
        took, steps = time.monotonic() - started, sum(robot.tried.values())
        print(f"generated misuse: {steps} steps over {EXAMPLES} examples in {took:.0f} s: {dict(robot.tried)}")
        if CASES_FILE:
            tried = {"steps": steps, "examples": EXAMPLES, "seconds": round(took), "by_rule": dict(robot.tried)}
            Path(CASES_FILE).write_text(json.dumps(tried))
