"""akd_node running a robot: six joints on one bus of six virtual AKDs, seen from another process through real rclpy.

The drives are one `akd-sim --udp --count 6` process, the node `akd_node --ros-args --params-file FILE` with the
joints `joint_1`..`joint_6` on udp://127.0.0.1:PORT, and this process the ROS client (Fast DDS, a ROS_DOMAIN_ID of the
module's own). Positions are compared in counts (the default units: 2^20 counts per revolution, gear 1). Every wait
is bounded; the processes are always ended.

`recorded_run` plays trajectories on a node that records every cycle of every joint, then stops it and reads the bag
back with rosbags: the set-points each cycle sent are what the continuity checks look at, and the per-cycle records
are what /joint_states is compared with.
"""

from __future__ import annotations

import itertools
import math
import time
from dataclasses import dataclass, field
from pathlib import Path

import pytest
from builtin_interfaces.msg import Duration
from diagnostic_msgs.msg import DiagnosticArray
from rclpy.qos import QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import JointState
from std_srvs.srv import Trigger
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from akd_ros.msg import DriveFault, TrajectoryStatus
from akd_ros.srv import SetMode
from support.ros import (
    COUNTS_PER_RAD,
    NodeProcess,
    Participant,
    Sim,
    ros_environment,
    stop,
)

DOMAINS = range(20, 30)
"""ROS_DOMAIN_IDs of this module (others: 60-90, 100-230; Fast DDS takes none above 232); its second and third runs
take the next two."""
NODE = "/akd_node/"
JOINTS = [f"joint_{i}" for i in range(1, 7)]
CYCLE_TIME = 0.002
LIMIT = 100.0
"""Position limit of every joint, rad, except joint_3's upper one."""
JOINT_3_MAX = 50.0
HANDOVER_MARGIN = 0.05
"""rad: how far a joint's set-point may be from the /joint_states sample taken as its start (half a rad/s for up to
0.1 s)."""
SETTLED_COUNTS = 20
"""Where an axis must be, counts, once a trajectory is done."""

PARAMS = """\
akd_node:
  ros__parameters:
    link: udp://127.0.0.1:{port}
    cycle_time: {cycle_time}
    # As an integrator runs it: the cycle thread under SCHED_FIFO where permitted (else a warning).
    rt.priority: 30
    rt.pipelined: {pipelined}
    dc: '{dc}'
    fault_reaction: {fault_reaction}
    mode: cyclic_synchronous_position
    limits.min_position: -{limit}
    limits.max_position: {limit}
    limits.max_velocity: 20.0
    joint_states_rate: 50.0
    status_rate: 10.0
    diagnostics_rate: 5.0
    command_timeout: 1.0
    record.enabled: {record}
    record.folder: {folder}
    record.black_box_seconds: 0.0
    joints: [{joints}]
    joints.joint_3.limits.max_position: {joint_3_max}
"""


def params(
    port: int, folder: Path, *, fault_reaction: str = "all", dc: str = "off", record: bool = False, pipelined=False
) -> str:
    return PARAMS.format(
        port=port,
        pipelined=str(pipelined).lower(),
        cycle_time=CYCLE_TIME,
        dc=dc,
        fault_reaction=fault_reaction,
        limit=LIMIT,
        record=str(record).lower(),
        folder=folder,
        joints=", ".join(JOINTS),
        joint_3_max=JOINT_3_MAX,
    )


class Arm(Participant):
    """The client of a node of joints: /joint_states, /diagnostics, ~/trajectory_status and each joint's fault
    collected in `received`; ~/joint_commands and ~/joint_trajectory published; the services called."""

    def __init__(self, domain: int):
        super().__init__(domain, "akd_node_joints_test")
        qos = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE)
        topics = {
            "/joint_states": JointState,
            "/diagnostics": DiagnosticArray,
            NODE + "trajectory_status": TrajectoryStatus,
        }
        topics |= {f"{NODE}{joint}/fault": DriveFault for joint in JOINTS}
        for topic, kind in topics.items():
            self.received[topic] = []
            self.node.create_subscription(kind, topic, self.received[topic].append, qos)
        self.joint_commands = self.node.create_publisher(JointState, NODE + "joint_commands", qos)
        self.joint_trajectory = self.node.create_publisher(JointTrajectory, NODE + "joint_trajectory", qos)

    def positions(self) -> dict[str, float]:
        message = self.latest("/joint_states")
        return dict(zip(message.name, message.position, strict=True))

    def publish(self, publisher, message) -> None:
        self.spin_until(lambda: publisher.get_subscription_count() > 0, f"subscriber of {publisher.topic_name}")
        publisher.publish(message)

    def trajectory(self, points: list[tuple[float, list[float]]], joints=JOINTS) -> None:
        """Publishes a trajectory of (time from start in s, positions) points, stamped zero (now)."""
        message = JointTrajectory(joint_names=list(joints))
        for t, positions in points:
            message.points.append(
                JointTrajectoryPoint(
                    positions=[float(p) for p in positions],
                    time_from_start=Duration(sec=int(t), nanosec=round((t % 1) * 1e9)),
                )
            )
        self.publish(self.joint_trajectory, message)

    def status_of_next(self, state: str, since: int) -> TrajectoryStatus:
        """The first TrajectoryStatus in `state` after the first `since` received."""
        topic = NODE + "trajectory_status"
        self.spin_until(lambda: any(m.state == state for m in self.received[topic][since:]), f"trajectory {state}")
        return next(m for m in self.received[topic][since:] if m.state == state)


@dataclass
class Run:
    """A node of joints on its simulator and the client."""

    sim: Sim
    node: NodeProcess
    arm: Arm
    log: dict = field(default_factory=dict)

    def drive_counts(self) -> list[float]:
        return [self.sim.state(i)["position"] for i in range(len(JOINTS))]

    def enable_all(self, mode: str = "cyclic_synchronous_position") -> None:
        for i, joint in enumerate(JOINTS):
            if self.sim.state(i)["fault"] is not None:
                self.arm.trigger(f"{joint}/reset_fault")
        self.arm.trigger("disable")
        for joint in JOINTS:
            response = self.arm.call(SetMode, f"{joint}/set_mode", SetMode.Request(mode=mode))
            assert response.success, response.message
        self.arm.trigger("enable")


def start(tmp_path: Path, domain: int, **kwargs) -> Run:
    from support.netns import free_udp_port

    sim = Sim(free_udp_port(), count=len(JOINTS))
    path = tmp_path / "akd_node.yaml"
    path.write_text(params(sim.port, tmp_path / "bags", **kwargs))
    node = NodeProcess(path, domain)
    arm = Arm(domain)
    arm.spin_until(lambda: arm.received["/joint_states"] or node.process.poll() is not None, "joint_states")
    assert node.process.poll() is None, f"akd_node exited:\n{node.output()}"
    return Run(sim, node, arm)


def end(run: Run) -> None:
    run.arm.close()
    stop(run.node.process)
    run.sim.stop()
    print(f"akd_node output:\n{run.node.output()}")


@pytest.fixture(scope="module")
def ros_domain():
    with ros_environment(DOMAINS) as domain:
        yield domain


@pytest.fixture(scope="module")
def robot(ros_domain, tmp_path_factory):
    """A node of six joints with fault_reaction all, distributed clocks on and a pipelined cycle (the other nodes
    here wait for each frame)."""
    run = start(tmp_path_factory.mktemp("robot"), ros_domain, dc="on", pipelined=True)
    yield run
    end(run)


def test_joint_states_name_all_six_joints_with_the_drives_values(robot):
    message = robot.arm.latest("/joint_states")
    assert list(message.name) == JOINTS
    assert len(message.position) == len(message.velocity) == len(message.effort) == 6
    counts = robot.drive_counts()
    for position, drive in zip(message.position, counts, strict=True):
        assert abs(position * COUNTS_PER_RAD - drive) <= 1.0, (message.position, counts)


def test_with_dc_on_every_virtual_drive_runs_sync0_at_the_cycle_time_and_diagnostics_tell(robot):
    for i in range(len(JOINTS)):
        dc = robot.sim.state(i)["dc"]
        assert (dc["sync0_active"], dc["sync0_cycle_ns"], dc["fbus_param02"]) == (True, 2_000_000, 1), (i, dc)
    statuses = {s.name: s for s in robot.arm.latest("/diagnostics").status}
    # Each joint's and the bus's status; the line's (its links and error counters) once they were first read.
    joints_and_bus = {f"akd_node: {j}" for j in JOINTS} | {"akd_node: bus"}
    assert joints_and_bus <= set(statuses), statuses
    assert all(name.startswith("akd_node: line") for name in set(statuses) - joints_and_bus), statuses
    serials = set()
    for position, joint in enumerate(JOINTS):
        status = statuses[f"akd_node: {joint}"]
        values = {v.key: v.value for v in status.values}
        assert f"AKD slave {position} serial {values['serial_number']}" in status.hardware_id
        assert values["dc"] == "on (SYNC0)" and values["system_time_difference_ns"] != "", values
        serials.add(values["serial_number"])
    assert len(serials) == len(JOINTS), f"the virtual AKDs share serial numbers: {serials}"
    bus = {v.key: v.value for v in statuses["akd_node: bus"].values}
    assert bus["dc"] == "on (SYNC0)" and bus["joints"] == ", ".join(JOINTS) and int(bus["cycles"]) > 0, bus
    assert bus["frames"] == "pipelined, each taken at the next wake-up", bus


def test_each_joint_in_its_own_mode_takes_its_command_from_one_joint_commands_message(robot):
    modes = ["interpolated_position", "cyclic_synchronous_position", "profile_velocity", "profile_torque"]
    robot.enable_all()
    robot.arm.trigger("disable")
    for joint, mode in zip(JOINTS, modes, strict=False):
        response = robot.arm.call(SetMode, f"{joint}/set_mode", SetMode.Request(mode=mode))
        assert response.success, response.message
    robot.arm.trigger("enable")
    here = robot.arm.positions()
    names = JOINTS[:4]
    message = JointState(
        name=names,
        position=[here["joint_1"] + 0.002, here["joint_2"] - 0.002, 0.0, 0.0],
        velocity=[0.0, 0.0, 1.5, 0.0],
        effort=[0.0, 0.0, 0.0, 0.03],
    )
    deadline = time.monotonic() + 0.6
    while time.monotonic() < deadline:
        robot.arm.publish(robot.arm.joint_commands, message)
        robot.arm.spin_for(0.02)
    drives = [robot.sim.state(i) for i in range(4)]
    assert drives[0]["position"] == pytest.approx((here["joint_1"] + 0.002) * COUNTS_PER_RAD, abs=20)
    assert drives[1]["position"] == pytest.approx((here["joint_2"] - 0.002) * COUNTS_PER_RAD, abs=20)
    assert drives[2]["velocity"] == pytest.approx(1.5 * COUNTS_PER_RAD, rel=0.05)
    # The virtual motor's torque in N·m: 1 % of the peak 3 N·m, ten of the drive's 0.1 % units.
    assert drives[3]["torque"] == pytest.approx(0.03, abs=0.003), drives[3]
    # joint_4 spins up under its torque: profile velocity brakes it (and joint_3) to a standstill for what follows.
    robot.arm.trigger("joint_4/disable")
    response = robot.arm.call(SetMode, "joint_4/set_mode", SetMode.Request(mode="profile_velocity"))
    assert response.success, response.message
    robot.arm.trigger("joint_4/enable")
    stop = JointState(name=["joint_3", "joint_4"], velocity=[0.0, 0.0])
    robot.arm.publish(robot.arm.joint_commands, stop)
    robot.arm.spin_until(
        lambda: all(abs(robot.sim.state(i)["velocity"]) < 1.0 for i in (2, 3)), "joint_3 and joint_4 standing still"
    )
    robot.enable_all()


def test_joint_commands_move_exactly_the_named_joints(robot):
    robot.enable_all()
    before = robot.drive_counts()
    here = robot.arm.positions()
    targets = {"joint_2": here["joint_2"] + 0.01, "joint_5": here["joint_5"] - 0.01}
    for i in range(50):
        step = (i + 1) / 50
        message = JointState(name=list(targets), position=[here[j] + (t - here[j]) * step for j, t in targets.items()])
        robot.arm.publish(robot.arm.joint_commands, message)
        robot.arm.spin_for(0.01)
    moved = {JOINTS.index(j): t * COUNTS_PER_RAD for j, t in targets.items()}
    robot.arm.spin_until(
        lambda: all(abs(robot.sim.state(i)["position"] - c) <= 20 for i, c in moved.items()), "the named joints there"
    )
    after = robot.drive_counts()
    for i, joint in enumerate(JOINTS):
        if joint in targets:
            assert after[i] == pytest.approx(targets[joint] * COUNTS_PER_RAD, abs=20), (joint, after[i])
        else:
            assert abs(after[i] - before[i]) <= 1, (joint, before[i], after[i])


@pytest.mark.parametrize(
    ("message", "why"),
    [
        (
            lambda here: JointState(name=["joint_1", "elbow"], position=[here["joint_1"] + 0.1, 0.1]),
            "unknown joint elbow",
        ),
        (
            lambda here: JointState(name=["joint_1", "joint_2"], position=[here["joint_1"] + 0.1, math.nan]),
            "joint joint_2: position command refused",
        ),
        (
            lambda here: JointState(name=["joint_1", "joint_3"], position=[here["joint_1"] + 0.1, JOINT_3_MAX + 1]),
            "beyond the limit max_position",
        ),
        (
            lambda here: JointState(name=["joint_1", "joint_2"], position=[here["joint_1"] + 0.1]),
            "has 1 values for 2 names",
        ),
    ],
    ids=["unknown_name", "nan", "past_a_limit", "short"],
)
def test_a_bad_joint_commands_message_is_refused_whole_and_nothing_moves(robot, message, why):
    """Each message moves joint_1 by 0.1 rad were it sent, and has one thing wrong."""
    robot.enable_all()
    before = robot.drive_counts()
    robot.arm.publish(robot.arm.joint_commands, message(robot.arm.positions()))
    robot.arm.spin_until(lambda: why in robot.node.output(), f"the refusal naming {why!r}")
    robot.arm.spin_for(0.3)
    after = robot.drive_counts()
    assert all(abs(a - b) <= 1 for a, b in zip(after, before, strict=True)), (before, after)
    assert "~/joint_commands refused, nothing sent" in robot.node.output()


def test_a_refused_trajectory_leaves_every_axis_still(robot):
    robot.enable_all()
    before = robot.drive_counts()
    here = robot.arm.positions()
    since = len(robot.arm.received[NODE + "trajectory_status"])
    # joint_3's second point is past its limit; the others' points would move them.
    points = [
        (0.5, [here[j] + 0.5 for j in JOINTS]),
        (1.0, [here[j] + (JOINT_3_MAX + 5 if j == "joint_3" else 1.0) for j in JOINTS]),
    ]
    robot.arm.trajectory(points)
    refused = robot.arm.status_of_next("refused", since)
    assert "joint_3" in refused.message and "max_position" in refused.message, refused.message
    robot.arm.spin_for(0.5)
    after = robot.drive_counts()
    assert all(abs(a - b) <= 1 for a, b in zip(after, before, strict=True)), (before, after)


@pytest.mark.parametrize(
    ("points", "why"),
    [
        ([(0.5, [0.0] * 6), (0.5, [0.1] * 6)], "increas"),
        ([(0.5, [math.nan] * 6)], "finite"),
    ],
    ids=["non_increasing_times", "nan"],
)
def test_a_trajectory_with_bad_times_or_nan_is_refused(robot, points, why):
    robot.enable_all()
    here = robot.arm.positions()
    points = [(t, [here[j] + p for j, p in zip(JOINTS, ps, strict=True)]) for t, ps in points]
    since = len(robot.arm.received[NODE + "trajectory_status"])
    robot.arm.trajectory(points)
    refused = robot.arm.status_of_next("refused", since)
    assert why in refused.message, refused.message


@pytest.mark.parametrize("kind", ["cubic", "quintic"])
def test_a_trajectory_with_velocities_or_accelerations_ends_on_its_last_point(robot, kind):
    robot.enable_all()
    here = robot.arm.positions()
    message = JointTrajectory(joint_names=JOINTS)
    for t, offset, velocity in ((0.4, 0.2, 0.5), (0.8, 0.3, 0.0)):
        message.points.append(
            JointTrajectoryPoint(
                positions=[here[j] + offset for j in JOINTS],
                velocities=[velocity] * 6,
                accelerations=[0.0] * 6 if kind == "quintic" else [],
                time_from_start=Duration(sec=0, nanosec=round(t * 1e9)),
            )
        )
    since = len(robot.arm.received[NODE + "trajectory_status"])
    robot.arm.publish(robot.arm.joint_trajectory, message)
    robot.arm.status_of_next("done", since)
    robot.arm.spin_for(0.2)
    for i, j in enumerate(JOINTS):
        assert abs(robot.sim.state(i)["position"] - (here[j] + 0.3) * COUNTS_PER_RAD) <= SETTLED_COUNTS, j


def test_accelerations_without_velocities_refuse_the_trajectory(robot):
    robot.enable_all()
    here = robot.arm.positions()
    point = JointTrajectoryPoint(
        positions=[here[j] + 0.1 for j in JOINTS], accelerations=[0.0] * 6, time_from_start=Duration(sec=1)
    )
    since = len(robot.arm.received[NODE + "trajectory_status"])
    robot.arm.publish(robot.arm.joint_trajectory, JointTrajectory(joint_names=JOINTS, points=[point]))
    refused = robot.arm.status_of_next("refused", since)
    assert "accelerations without velocities" in refused.message, refused.message


def test_bus_wide_enable_with_one_hardware_enable_low_names_that_joint(robot):
    robot.enable_all()
    robot.arm.trigger("disable")
    robot.sim.command("hardware_enable 3 low")
    try:
        response = robot.arm.call(Trigger, "enable")
        assert not response.success
        assert "joint_4" in response.message and "joint_1" not in response.message.split("done:")[0], response.message
    finally:
        robot.sim.command("hardware_enable 3 high")
    robot.enable_all()


def test_a_fault_on_joint_3_quick_stops_the_other_five_under_fault_reaction_all(robot):
    robot.enable_all()
    faults_before = {j: len(robot.arm.received[f"{NODE}{j}/fault"]) for j in JOINTS}
    robot.sim.command("fault 2 F439")
    robot.arm.spin_until(
        lambda: len(robot.arm.received[f"{NODE}joint_3/fault"]) > faults_before["joint_3"], "fault of joint_3"
    )
    robot.arm.spin_for(0.3)
    states = [robot.sim.state(i)["state"] for i in range(len(JOINTS))]
    assert states[2] in ("Fault", "Fault reaction active"), states
    assert all(s in ("Quick stop active", "Switch on disabled") for i, s in enumerate(states) if i != 2), states
    # Reported by the joint that faulted alone, once as its drive's fault (and once as the emergency message the
    # drive sent with it); the others' quick stops are no faults of theirs.
    new = {j: robot.arm.received[f"{NODE}{j}/fault"][faults_before[j] :] for j in JOINTS}
    assert all(not new[j] for j in JOINTS if j != "joint_3"), new
    assert sorted(f.source for f in new["joint_3"]) == ["drive_fault", "emergency"], new["joint_3"]
    assert robot.arm.received[f"{NODE}joint_3/fault"][-1].joint == "joint_3"
    robot.arm.trigger("reset_fault")
    robot.enable_all()


def test_under_fault_reaction_joint_only_the_faulted_joint_stops(ros_domain, tmp_path):
    run = start(tmp_path, ros_domain + 1, fault_reaction="joint")
    try:
        run.enable_all()
        run.sim.command("fault 2 F439")
        run.arm.spin_until(lambda: run.arm.received[f"{NODE}joint_3/fault"], "fault of joint_3")
        run.arm.spin_for(0.3)
        states = [run.sim.state(i)["state"] for i in range(len(JOINTS))]
        assert states[2] in ("Fault", "Fault reaction active"), states
        assert all(s == "Operation enabled" for i, s in enumerate(states) if i != 2), states
    finally:
        end(run)


# --- trajectories, read back from the bag of every cycle -----------------------------------------------------------


@dataclass
class Recorded:
    """What `recorded_run` did and got: the trajectories' points (joint: [(time, position rad)] from the start of
    each), the statuses, the JointStates received, and the bag's per-cycle records by joint."""

    bag: Path
    statuses: list
    joint_states: list
    cycles: dict[str, list]
    ends: dict[str, float]
    replaced: list
    slopes: dict[str, float]
    """The largest |velocity| each joint's trajectories ask for, rad/s."""


@pytest.fixture(scope="module")
def recorded_run(ros_domain, tmp_path_factory):
    """Six joints recorded every cycle: a three-point trajectory over 2 s, done; then one replaced half-way by
    another, which is done; the node stopped and its bag read."""
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    folder = tmp_path_factory.mktemp("recorded")
    run = start(folder, ros_domain + 2, record=True)
    try:
        run.enable_all()
        arm = run.arm
        here = arm.positions()
        starts = [dict(here)]
        first = [
            (0.7, [here[j] + 0.3 * (k + 1) for k, j in enumerate(JOINTS)]),
            (1.4, [here[j] - 0.2 * (k + 1) for k, j in enumerate(JOINTS)]),
            (2.0, [here[j] + 0.1 for j in JOINTS]),
        ]
        since = len(arm.received[NODE + "trajectory_status"])
        arm.trajectory(first)
        done = arm.status_of_next("done", since)
        assert (done.point, done.points, list(done.joints)) == (3, 3, JOINTS), done
        arm.spin_for(0.2)
        ends = dict(zip(JOINTS, run.drive_counts(), strict=True))
        expected_ends = {j: (here[j] + 0.1) * COUNTS_PER_RAD for j in JOINTS}
        for j in JOINTS:
            assert abs(ends[j] - expected_ends[j]) <= SETTLED_COUNTS, (j, ends[j], expected_ends[j])
        # The second, replaced after 1 s by the third.
        here = arm.positions()
        starts.append(dict(here))
        second = [(1.0, [here[j] + 0.5 for j in JOINTS]), (2.0, [here[j] + 1.0 for j in JOINTS])]
        third = [(0.5, [here[j] - 0.2 for j in JOINTS]), (1.0, [here[j] for j in JOINTS])]
        since = len(arm.received[NODE + "trajectory_status"])
        arm.trajectory(second)
        arm.status_of_next("running", since)
        arm.spin_for(1.0)
        starts.append(arm.positions())
        arm.trajectory(third)
        replaced = arm.status_of_next("replaced", since)
        arm.status_of_next("done", since)
        arm.spin_for(0.2)
        statuses = list(arm.received[NODE + "trajectory_status"])
        joint_states = list(arm.received["/joint_states"])
    finally:
        end(run)
    # The velocities the points ask for: each segment's slope, the first from where the joint was when it was sent
    # (a /joint_states sample, up to HANDOVER_MARGIN behind the set-point the trajectory really took over from).
    slopes = dict.fromkeys(JOINTS, 0.0)
    for origin, points in zip(starts, (first, second, third), strict=True):
        for k, j in enumerate(JOINTS):
            previous_t, previous_p = 0.0, origin[j]
            for t, positions in points:
                margin = HANDOVER_MARGIN if previous_t == 0.0 else 0.0
                slopes[j] = max(slopes[j], (abs(positions[k] - previous_p) + margin) / (t - previous_t))
                previous_t, previous_p = t, positions[k]
    store = get_typestore(Stores.ROS2_JAZZY)
    for path in sorted((Path(__file__).resolve().parents[1] / "msg").glob("*.msg")):
        store.register(get_types_from_msg(path.read_text(), f"akd_ros/msg/{path.stem}"))
    (bag,) = (folder / "bags").iterdir()
    cycles: dict[str, list] = {j: [] for j in JOINTS}
    with AnyReader([bag], default_typestore=store) as reader:
        connections = [c for c in reader.connections if c.topic == NODE + "cycle"]
        for connection, _, raw in reader.messages(connections=connections):
            sample = reader.deserialize(raw, connection.msgtype)
            cycles[sample.joint].append(sample)
    return Recorded(bag, statuses, joint_states, cycles, ends, [replaced], slopes)


def test_every_joint_states_message_holds_the_values_of_one_cycle(recorded_run):
    by_cycle: dict[int, dict[str, float]] = {}
    for joint, samples in recorded_run.cycles.items():
        for s in samples:
            by_cycle.setdefault(s.cycle, {})[joint] = s.position
    positions_of_cycles = {tuple(v[j] for j in JOINTS) for v in by_cycle.values() if len(v) == len(JOINTS)}
    moving = [m for m in recorded_run.joint_states if len(set(m.position)) > 1]
    # At 50 Hz over 3.5 s of motion; enough to tell one cycle from several, however slowly a loaded host publishes.
    assert len(moving) > 20, len(moving)
    for message in moving:
        assert tuple(message.position) in positions_of_cycles, f"no cycle had the positions {message.position}"


def test_the_set_points_stay_continuous_through_trajectories_and_a_replacement(recorded_run):
    for joint, samples in recorded_run.cycles.items():
        assert len(samples) > 2000, (joint, len(samples))
        cycles = [s.cycle for s in samples]
        assert cycles == list(range(cycles[0], cycles[0] + len(cycles))), f"{joint}: a cycle is missing"
        # The cycle thread interpolates by time: a cycle that came late steps as far as its period allows.
        velocity = recorded_run.slopes[joint] * COUNTS_PER_RAD
        excess = [
            (abs(b.command - a.command) * COUNTS_PER_RAD - (velocity * b.period_ns * 1e-9 + 1), b.cycle)
            for a, b in itertools.pairwise(samples)
        ]
        worst, cycle = max(excess)
        assert worst <= 0, f"{joint}: a step of {worst:.1f} counts beyond the bound at cycle {cycle}"


def test_the_trajectory_status_tells_the_story(recorded_run):
    states = [(m.id, m.state) for m in recorded_run.statuses]
    ids = []
    for identifier, _ in states:
        if identifier not in ids:
            ids.append(identifier)
    first, second, third = ids
    outcome = {i: [s for j, s in states if j == i] for i in ids}
    assert outcome[first][0] == "running" and outcome[first][-1] == "done", outcome
    assert outcome[second][-1] == "replaced" and outcome[third][-1] == "done", outcome
    (replaced,) = recorded_run.replaced
    assert replaced.replaced_by == third and "replaced by trajectory" in replaced.message


def test_akd_plot_draws_one_joint_of_the_bag_and_names_the_joints_it_has(recorded_run, tmp_path):
    from support.ros import akd_plot

    picture = tmp_path / "joint_3.png"
    done = akd_plot(str(recorded_run.bag), "--joint", "joint_3", "-o", str(picture))
    assert done.returncode == 0, done.stderr
    assert picture.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    done = akd_plot(str(recorded_run.bag), "--joint", "elbow", "-o", str(picture))
    assert done.returncode == 1 and "no cycle samples of joint 'elbow'" in done.stderr, done.stderr
    assert "joint_1, joint_2, joint_3, joint_4, joint_5, joint_6" in done.stderr and "Traceback" not in done.stderr
