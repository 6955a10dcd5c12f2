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
from akd_ros.node import ros_parameters
from akd_ros.node.lifecycle import AkdNode
from akd_ros.node.node_state import NODE_NAME
from support.params_files import BAD_FILES, params_file

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
    assert "configured: slave 0 on sim?missed=warn in Op" in output and "closed: drive disabled, bus in Init" in output


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


def test_cyclic_synchronous_position_with_fixed_mappings_and_whole_numbers_for_reals_pipelined(tmp_path):
    path = params_file(
        tmp_path,
        "mode: cyclic_synchronous_position\nmapping: 0x1724/0x1B26\ngear_ratio: 2\nenable_on_start: true\n"
        "rt.pipelined: true",
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
    assert (settings.realtime.priority, settings.realtime.cpu, joint.limits.max_velocity) == (80, 1, 50.0)
    assert settings.realtime.cpu_latency_us == 0
    assert settings.realtime.pipelined is False
    assert params.settings({**values, "rt.pipelined": True}).realtime.pipelined is True
    assert params.settings({**values, "rt.cpu_latency_us": -1}).realtime.cpu_latency_us is None
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


def test_the_names_of_inputs_and_outputs_are_declared_and_another_nodes_are_not(tmp_path):
    path = tmp_path / "akd_node.yaml"
    path.write_text(
        "akd_node:\n  ros__parameters:\n    mapping: io\n    mode: cyclic_synchronous_position\n"
        "    io:\n      inputs: {part_present: 3}\n      outputs: {lamp: 2}\n"
        "other_node:\n  ros__parameters:\n    io.inputs.ghost: 5\n"
    )
    context = rclpy.Context()
    rclpy.init(context=context, domain_id=int(os.environ["ROS_DOMAIN_ID"]) + IN_PROCESS_DOMAIN_OFFSET)
    try:
        node = AkdNode(args=[], context=context, cli_args=["--ros-args", "--params-file", str(path)])
        inputs, outputs = node.describe_parameters(["io.inputs.part_present", "io.outputs.lamp"])
        assert "part_present" in inputs.description and inputs.read_only, inputs
        assert (inputs.integer_range[0].to_value, outputs.integer_range[0].to_value) == (7, 2)
        assert not node.has_parameter("io.inputs.ghost")
        (joint,) = node.settings.joints
        assert (joint.io_inputs, joint.io_outputs) == ({"part_present": 3}, {"lamp": 2})
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


RCL_ORDER_FILES = {
    "own.yaml": "akd_node:\n  ros__parameters:\n    cycle_time: 0.002\n    mode: homing\n    limits:\n"
    "      max_velocity: 2.0\n",
    "wildcard.yaml": "/**:\n  ros__parameters:\n    cycle_time: 0.004\n    status_rate: 5.0\n/ns:\n  akd_node:\n"
    "    ros__parameters:\n      dc: 'off'\n/*:\n  ros__parameters:\n    limits.max_velocity: 3.0\n",
    "both.yaml": "/**/akd_node:\n  ros__parameters:\n    status_rate: 20.0\nakd_node:\n  ros__parameters:\n"
    "    joint_name: elbow\n/**:\n  ros__parameters:\n    mode: profile_torque\n",
}


@pytest.mark.parametrize(
    "arguments",
    [
        ["own.yaml"],
        ["own.yaml", "wildcard.yaml"],
        ["wildcard.yaml", "own.yaml"],
        ["both.yaml", "own.yaml", "wildcard.yaml"],
        ["-p", "mode:=profile_velocity", "own.yaml"],
        ["own.yaml", "-p", "mode:=profile_velocity", "-p", "dc:=on", "-p", "latch.arm:=[1/rising]"],
    ],
    ids=" ".join,
)
def test_read_arguments_gives_what_rcl_gives_the_node(arguments, tmp_path):
    """akd_ros.params reads the files and -p as rcl does: the same values for the node, the same one winning."""
    from rclpy.node import Node

    for name, text in RCL_ORDER_FILES.items():
        (tmp_path / name).write_text(text)
    ros_args = ["--ros-args"]
    for argument in arguments:
        ros_args += ["--params-file", str(tmp_path / argument)] if argument.endswith(".yaml") else [argument]
    context = rclpy.Context()
    rclpy.init(args=ros_args, context=context, domain_id=int(os.environ["ROS_DOMAIN_ID"]) + IN_PROCESS_DOMAIN_OFFSET)
    try:
        node = Node(NODE_NAME, context=context, automatically_declare_parameters_from_overrides=True)
        names = [
            n for n in node.list_parameters([], 0).names if n not in ("use_sim_time", "start_type_description_service")
        ]
        given = {parameter.name: parameter.value for parameter in node.get_parameters(names)}
        node.destroy_node()
    finally:
        rclpy.shutdown(context=context)
    assert given and params.read_arguments(ros_args, NODE_NAME) == given
