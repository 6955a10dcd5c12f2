"""akd_node's parameters: every bad parameters file stops the node with its message, good ones start it.

Each case is a real run of `.venv/bin/akd_node --ros-args --params-file FILE` (link "sim", the built-in virtual AKD,
unless the case is about the link): its exit status and what it printed are checked. The declared descriptors
(types, ranges, allowed values) are read back from a node in this process.
"""

from __future__ import annotations

import math
import os
import random
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
import rclpy
import yaml
from rcl_interfaces.msg import ParameterType

from akd_ros import params
from akd_ros.node import AkdNode, ros_parameters

BIN = Path(sys.executable).parent
REPO = Path(__file__).resolve().parents[1]
# A bound on each run, not a timing expectation: a bad file ends the node within a second or two.
RUN_TIMEOUT_S = 60.0
IN_PROCESS_DOMAIN_OFFSET = 5


@pytest.fixture(scope="module", autouse=True)
def ros_domain():
    """A ROS_DOMAIN_ID of this module's own, discovery on localhost, for the nodes it starts."""
    with pytest.MonkeyPatch.context() as patch:
        patch.setenv("ROS_DOMAIN_ID", str(random.randint(221, 225)))
        patch.setenv("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
        patch.setenv("RMW_IMPLEMENTATION", "rmw_fastrtps_cpp")
        patch.delenv("ROS_LOCALHOST_ONLY", raising=False)
        yield


def params_file(directory: Path, body: str) -> Path:
    """A parameters file for akd_node whose ros__parameters are `body` (YAML lines)."""
    path = directory / "params.yaml"
    lines = "".join(f"    {line}\n" for line in body.strip().splitlines())
    path.write_text(f"akd_node:\n  ros__parameters:\n{lines}")
    return path


def run_node(path: Path) -> subprocess.CompletedProcess:
    """akd_node with `path`, to its end."""
    return subprocess.run(
        [str(BIN / "akd_node"), "--ros-args", "--params-file", str(path)],
        capture_output=True,
        text=True,
        timeout=RUN_TIMEOUT_S,
        env=dict(os.environ),
        check=False,
    )


BAD_FILES = {
    "wrong type": ("cycle_time: fast", ["parameter cycle_time must be a number in [0.00025, 0.01]", "'fast'"]),
    "real for an integer": ("slave: 1.5", ["parameter slave must be an integer in [0, 65535]"]),
    "cycle below 250 us": ("cycle_time: 0.0001", ["parameter cycle_time", "[0.00025, 0.01]", "0.0001"]),
    "cycle above 10 ms": ("cycle_time: 0.02", ["parameter cycle_time", "[0.00025, 0.01]"]),
    "unknown mode": (
        "mode: cyclic_synchronous_velocity",
        [
            "parameter mode must be one of profile_position",
            "cyclic_synchronous_position",
            "'cyclic_synchronous_velocity'",
        ],
    ),
    "unknown fixed mapping": (
        "mapping: 0x1799/0x1B01",
        ["parameter mapping", "0x1799 is not a fixed RxPDO", "0x1701", "0x1725"],
    ),
    "unknown fixed tx mapping": ("mapping: 0x1724/0x1B99", ["parameter mapping", "0x1B99", "0x1B26"]),
    "mapping no mapping": ("mapping: csp", ["parameter mapping 'csp' is not a mapping", "'default'", "'flexible'"]),
    "flexible entry unmappable": (
        'mapping: flexible\nmapping.rx: ["0x6040:00/16 0x1234:56/32"]\nmapping.tx: ["0x6041:00/16 0x6064:00/32"]',
        ["parameter mapping", "0x1234:56"],
    ),
    "flexible entry malformed": (
        'mapping: flexible\nmapping.rx: ["6040-16"]\nmapping.tx: ["0x6041:00/16"]',
        ["parameter mapping.rx", "'6040-16'", "INDEX:SUB/BITS"],
    ),
    "flexible lists without flexible": ('mapping.rx: ["0x6040:00/16"]', ["mapping.rx", "'flexible' only"]),
    "mode the mapping cannot carry": (
        "mode: cyclic_synchronous_position\nmapping: 0x1701/0x1B01",
        ["parameters mode/mapping", "0x607A", "lacks"],
    ),
    "missing interface": (
        "link: akd_missing0",
        ["parameter link", "'akd_missing0' does not exist", "'sim'", "udp://HOST:PORT", "lo"],
    ),
    "udp without port": ("link: udp://127.0.0.1", ["parameter link", "udp://HOST:PORT", "1..65535"]),
    "more virtual AKDs than a bus holds": (
        "link: sim:100",
        ["parameter link", "sim:100", "the number of virtual AKDs must be 1..=64"],
    ),
    "unknown parameter": ("cycle_tme: 0.001", ["unknown parameter cycle_tme", "cycle_time"]),
    "direction": ("direction: 0", ["parameter direction must be one of 1, -1"]),
    "linear without lead": ("axis: linear", ["axis/lead", "lead", "linear"]),
    "lead on a rotary axis": ("lead: 0.005", ["parameter lead", "rotary", "0"]),
    "limits crossed": (
        "limits.min_position: 2.0\nlimits.max_position: 1.0",
        ["limits", "min_position", "max_position"],
    ),
    "limit policy": ("limits.policy: wrap", ["parameter limits.policy must be one of refuse, clamp"]),
    "latch": ('latch.arm: ["3/rising"]', ["parameter latch.arm", "'3/rising'", "1/rising", "2/falling"]),
    "fault reset policy": ("fault_reset: always", ["parameter fault_reset must be one of manual, auto_once"]),
    "command timeout policy": (
        "command_timeout_policy: coast",
        ["parameter command_timeout_policy must be one of hold, quick_stop"],
    ),
    "rate": ("joint_states_rate: 0.0", ["parameter joint_states_rate", "[1.0, 1000.0]"]),
    "bool": ("autostart: 1", ["parameter autostart must be a bool"]),
    "dc": ("dc: sometimes", ["parameter dc must be one of auto, on, off", "'sometimes'"]),
    "dc as a number": ("dc: 1", ["parameter dc must be one of auto, on, off", "got 1"]),
    "dc shift of a cycle": (
        "cycle_time: 0.001\ndc_shift: 0.001",
        ["parameter dc_shift must be less than one cycle_time (0.001 s) either way", "0.001"],
    ),
    "dc shift out of range": ("dc_shift: 0.5", ["parameter dc_shift must be a number in [-0.01, 0.01]", "0.5"]),
    "fault reaction": ("fault_reaction: some", ["parameter fault_reaction must be one of all, joint", "'some'"]),
    "joint name not a name token": ("joints: [arm/1]", ["parameter joints: 'arm/1' is not a joint name", "joint_1"]),
    "joint named twice": ("link: sim:2\njoints: [a, a]", ["parameter joints names a more than once"]),
    "joint_name beside joints": (
        "link: sim:2\njoints: [a, b]\njoint_name: c",
        ["parameter joint_name applies to a file without joints", "joints.<name>.slave"],
    ),
    "a block of a joint not in joints": (
        "link: sim:2\njoints: [a, b]\njoints.c.mode: homing",
        ["unknown parameter joints.c.mode", "joints.<name>.<one of slave, alias, mode"],
    ),
    "a parameter no joint block has": (
        "link: sim:2\njoints: [a, b]\njoints.a.cycle_time: 0.002",
        ["unknown parameter joints.a.cycle_time"],
    ),
    "a bad value in a joint block": (
        "link: sim:2\njoints: [a, b]\njoints.b.mode: fast",
        ["parameter joints.b.mode must be one of profile_position", "'fast'"],
    ),
    "a bad mapping in a joint block": (
        "link: sim:2\njoints: [a, b]\njoints.b.mapping: 0x1799/0x1B01",
        ["parameter joints.b.mapping", "0x1799 is not a fixed RxPDO"],
    ),
    "a bad latch in a joint block": (
        'link: sim:2\njoints: [a, b]\njoints.a.latch.arm: ["1/up"]',
        ["parameter joints.a.latch.arm: '1/up' is not CHANNEL/EDGE"],
    ),
    "two joints on one drive": (
        "link: sim:2\njoints: [a, b]\njoints.b.slave: 0",
        ["parameters joints.<name>.slave/alias", "slave 0 given to several drives"],
    ),
    "a joint past the last drive": (
        "link: sim:2\njoints: [a, b, c]",
        ["the drives (a (slave 0), b (slave 1), c (slave 2))", "slave 2 is not on the bus (slaves 0..1)"],
    ),
}


@pytest.mark.parametrize("case", sorted(BAD_FILES))
def test_a_bad_parameters_file_stops_the_node_with_its_message(case, tmp_path):
    body, expected = BAD_FILES[case]
    result = run_node(params_file(tmp_path, body))
    assert result.returncode == 1, f"exit {result.returncode}\n{result.stdout}\n{result.stderr}"
    assert "akd_node: error: " in result.stderr, result.stderr
    for text in expected:
        assert text in result.stderr, f"{text!r} not in:\n{result.stderr}"


def start_node(path: Path) -> subprocess.Popen:
    """akd_node on `path`, its output (stderr too) on a text pipe."""
    return subprocess.Popen(
        [str(BIN / "akd_node"), "--ros-args", "--params-file", str(path)],
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
        env=dict(os.environ),
    )


def run_until_configured(path: Path, stop: int = signal.SIGINT) -> tuple[int, str]:
    """Starts akd_node with `path`, waits until it is active (or fails), sends `stop`; its exit status and
    output."""
    process = start_node(path)
    try:
        output = []
        for line in process.stdout:
            output.append(line)
            if "active:" in line or "error" in line:
                break
        process.send_signal(stop)
        rest, _ = process.communicate(timeout=RUN_TIMEOUT_S)
        return process.returncode, "".join(output) + rest
    finally:
        if process.poll() is None:
            process.kill()
            process.wait()


def test_the_simulator_config_runs_and_sigint_ends_it_cleanly():
    status, output = run_until_configured(REPO / "config" / "akd_sim.yaml")
    assert status == 0, output
    assert "configured: slave 0 on sim in Op" in output and "closed: drive disabled, bus in Init" in output


def test_the_six_axis_simulator_config_runs_six_joints_with_their_own_blocks(tmp_path):
    status, output = run_until_configured(REPO / "config" / "akd_sim_6axis.yaml")
    assert status == 0, output
    assert "configured: joint_1 (slave 0), joint_2 (slave 1)" in output and "joint_6 (slave 5) on sim:6" in output
    assert "closed: drives disabled, bus in Init" in output


def test_a_joint_block_overrides_the_top_level_defaults():
    values = {spec.name: spec.default for spec in params.SCHEMA}
    values |= {
        "link": "sim:3",
        "joints": ["shoulder", "elbow", "wrist"],
        "mode": "cyclic_synchronous_position",
        "limits.max_velocity": 4.0,
        "joints.elbow.mode": "profile_velocity",
        "joints.elbow.gear_ratio": 50.0,
        "joints.wrist.alias": 7,
        "joints.wrist.latch.arm": ["2/falling"],
    }
    settings = params.settings(values)
    assert settings.joint_namespaces and [j.name for j in settings.joints] == ["shoulder", "elbow", "wrist"]
    shoulder, elbow, wrist = settings.joints
    assert (shoulder.slave, shoulder.mode, shoulder.limits.max_velocity) == (0, "cyclic_synchronous_position", 4.0)
    assert (elbow.slave, elbow.mode, elbow.units.gear_ratio, elbow.limits.max_velocity) == (
        1,
        "profile_velocity",
        50.0,
        4.0,
    )
    assert (wrist.slave, wrist.alias, wrist.latch_arm) == (None, 7, ((2, "falling"),))


def test_the_real_six_axis_template_names_only_joint_parameters_in_its_blocks():
    template = yaml.safe_load((REPO / "config" / "akd_6axis.yaml").read_text())["akd_node"]["ros__parameters"]
    values = {spec.name: spec.default for spec in params.SCHEMA}
    for name, value in template.items():
        if name.startswith("joints."):
            for key, v in value.items():
                values[f"{name}.{key}"] = v
        else:
            assert name in params.SPECS, name
            values[name] = value
    per_joint = {spec.name for spec in params.SCHEMA if spec.per_joint}
    blocks = {key for name, block in template.items() if name.startswith("joints.") for key in block}
    assert blocks <= per_joint, blocks - per_joint
    values["link"] = "sim:6"  # its link names an interface of the target machine
    settings = params.settings(values)
    assert [j.name for j in settings.joints] == [f"joint_{i}" for i in range(1, 7)]
    assert settings.joints[2].units.direction == -1 and settings.joints[5].latch_arm == ((1, "rising"),)


def test_cyclic_synchronous_position_with_fixed_mappings_and_whole_numbers_for_reals(tmp_path):
    path = params_file(
        tmp_path, "mode: cyclic_synchronous_position\nmapping: 0x1724/0x1B26\ngear_ratio: 2\nenable_on_start: true"
    )
    status, output = run_until_configured(path, signal.SIGTERM)
    assert status == 0, output
    assert "mode cyclic_synchronous_position" in output and "enable_on_start: Operation enabled" in output


def test_the_real_drive_template_names_only_known_parameters_with_good_values():
    template = yaml.safe_load((REPO / "config" / "akd.yaml").read_text())["akd_node"]["ros__parameters"]
    assert set(template) == set(params.SPECS), set(template) ^ set(params.SPECS)
    values = {name: [] if value == [] else value for name, value in template.items()}
    # Its link names an interface of the target machine, which this one need not have.
    values["link"] = "sim"
    settings = params.settings(values)
    (joint,) = settings.joints
    assert (settings.rt_priority, settings.rt_cpu, joint.limits.max_velocity) == (80, 1, 50.0)
    assert math.isinf(template["limits.max_position"]) and joint.limits.max_position is None


@pytest.fixture
def node_in_process():
    """An AkdNode in this process (its own context and domain, so no client of another test sees it), with the
    built-in defaults."""
    context = rclpy.Context()
    rclpy.init(context=context, domain_id=int(os.environ["ROS_DOMAIN_ID"]) + IN_PROCESS_DOMAIN_OFFSET)
    node = AkdNode(context=context)
    yield node
    node.destroy_node()
    rclpy.shutdown(context=context)


def test_every_parameter_is_declared_with_type_description_and_range(node_in_process):
    names = [spec.name for spec in params.SCHEMA]
    descriptors = dict(zip(names, node_in_process.describe_parameters(names), strict=True))
    for spec in params.SCHEMA:
        descriptor = descriptors[spec.name]
        assert descriptor.description and descriptor.read_only, spec.name
        assert descriptor.type == ros_parameters.parameter_type(spec).value, spec.name
    cycle = descriptors["cycle_time"]
    assert cycle.type == ParameterType.PARAMETER_DOUBLE
    assert (cycle.floating_point_range[0].from_value, cycle.floating_point_range[0].to_value) == (0.00025, 0.01)
    assert descriptors["slave"].integer_range[0].to_value == 65535
    assert "cyclic_synchronous_position" in descriptors["mode"].additional_constraints
    assert descriptors["dc"].additional_constraints == "one of auto, on, off"
    assert "'udp://'" in descriptors["dc"].description and node_in_process.settings.dc is None
    direction = descriptors["direction"].integer_range[0]
    assert (direction.from_value, direction.to_value, direction.step) == (-1, 1, 2)
    assert node_in_process.get_parameter("mode").value == "interpolated_position"
    (joint,) = node_in_process.settings.joints
    assert joint.latch_arm == () and joint.mapping is None and joint.name == "akd_axis"


def test_every_joint_block_parameter_is_declared_with_its_description_and_range():
    from rclpy.parameter import Parameter

    context = rclpy.Context()
    rclpy.init(context=context, domain_id=int(os.environ["ROS_DOMAIN_ID"]) + IN_PROCESS_DOMAIN_OFFSET)
    overrides = [
        Parameter("link", value="sim:2"),
        Parameter("joints", value=["a", "b"]),
        Parameter("joints.b.slave", value=0),
        Parameter("joints.a.slave", value=1),
    ]
    try:
        node = AkdNode(context=context, parameter_overrides=overrides)
        names = [f"joints.{j}.{spec.name}" for j in ("a", "b") for spec in params.SCHEMA if spec.per_joint]
        for name, descriptor in zip(names, node.describe_parameters(names), strict=True):
            assert descriptor.description.startswith(f"Joint {name.split('.')[1]}: ") and descriptor.read_only, name
        assert (
            node.get_parameter("joints.a.slave").value == 1
            and node.get_parameter("joints.b.mode").value == "interpolated_position"
        )
        mode = node.describe_parameters(["joints.b.mode"])[0]
        assert "cyclic_synchronous_position" in mode.additional_constraints
        assert [(j.name, j.slave) for j in node.settings.joints] == [("a", 1), ("b", 0)]
        node.destroy_node()
    finally:
        rclpy.shutdown(context=context)


def test_without_autostart_the_lifecycle_services_walk_the_node(tmp_path):
    from lifecycle_msgs.msg import State, Transition
    from lifecycle_msgs.srv import ChangeState, GetState
    from rclpy.executors import SingleThreadedExecutor
    from sensor_msgs.msg import JointState

    path = params_file(tmp_path, "autostart: false\njoint_states_rate: 50.0")
    process = start_node(path)
    context = rclpy.Context()
    rclpy.init(context=context, domain_id=int(os.environ["ROS_DOMAIN_ID"]))
    client = rclpy.create_node("akd_lifecycle_test", context=context)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(client)
    joint_states: list = []
    client.create_subscription(JointState, "/joint_states", joint_states.append, 10)

    def spin_until(done, what: str) -> None:
        deadline = time.monotonic() + RUN_TIMEOUT_S
        while not done():
            assert time.monotonic() < deadline and process.poll() is None, f"no {what}"
            executor.spin_once(timeout_sec=0.02)

    def call(kind, name, request):
        service = client.create_client(kind, f"/akd_node/{name}")
        spin_until(service.service_is_ready, f"service {name}")
        future = service.call_async(request)
        spin_until(future.done, f"answer of {name}")
        return future.result()

    def state() -> int:
        return call(GetState, "get_state", GetState.Request()).current_state.id

    def change(transition: int) -> None:
        assert call(ChangeState, "change_state", ChangeState.Request(transition=Transition(id=transition))).success

    try:
        assert state() == State.PRIMARY_STATE_UNCONFIGURED
        change(Transition.TRANSITION_CONFIGURE)
        assert state() == State.PRIMARY_STATE_INACTIVE
        executor.spin_once(timeout_sec=0.5)
        assert not joint_states, "an inactive node published"
        change(Transition.TRANSITION_ACTIVATE)
        spin_until(lambda: len(joint_states) >= 5, "joint_states once active")
        change(Transition.TRANSITION_DEACTIVATE)
        count = len(joint_states)
        deadline = time.monotonic() + 0.5
        while time.monotonic() < deadline:
            executor.spin_once(timeout_sec=0.02)
        # One already on its way may still arrive; publishing has stopped.
        assert len(joint_states) <= count + 1
        change(Transition.TRANSITION_CLEANUP)
        assert state() == State.PRIMARY_STATE_UNCONFIGURED
        process.send_signal(signal.SIGINT)
        output, _ = process.communicate(timeout=RUN_TIMEOUT_S)
        assert process.returncode == 0, output
        assert "closed: drive disabled, bus in Init" in output
    finally:
        if process.poll() is None:
            process.kill()
            process.wait()
        executor.shutdown()
        client.destroy_node()
        rclpy.shutdown(context=context)
