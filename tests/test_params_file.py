"""akd_ros without ROS: the package imports, and `akd_ros.params` reads and checks a node's parameters file, where
no ROS package can be imported.

The module's tests run twice: here, and once more in a Python whose ROS imports are refused (tests/support/no_ros on
PYTHONPATH), which `test_these_tests_pass_with_ros_blocked` starts. Every bad file the node on rclpy refuses
(tests/test_node_params.py) is refused here with the same message.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

from akd_ros import params
from support.params_files import BAD_FILES, params_file

REPO = Path(__file__).resolve().parents[1]
NO_ROS = REPO / "tests" / "support" / "no_ros"
ROS_BLOCKED = getattr(sys.modules.get("sitecustomize"), "BLOCKED", False)
RUN_TIMEOUT_S = 120.0
REFUSED_AT_CONFIGURE = {
    "a joint past the last drive",
    "mode the mapping cannot carry",
    "a line with no drives listening",
    "a device of another product than the line's",
    "a device's product unknown to the line",
    "a device past the end of the line",
    "a joint where the line has a terminal",
}
"""Bad files of BAD_FILES that the parameters' checks pass: the node refuses them at configure, when the Bus opens
(a slave that is not on the bus or not what the file expects, a line where nothing answers) or when it checks each
joint's mode against its drive's mapping."""
# What the package and the node's parameters need without ROS, checked where ROS cannot be imported.
IMPORTS_WITHOUT_ROS = """
import sys
import akd_ros, akd_ros.axis, akd_ros.bus, akd_ros.params, akd_ros.units
from akd_ros import params
settings = params.settings(params.read_parameters_file("config/akd_sim_6axis.yaml"))
print(",".join(j.name for j in settings.joints))
print(",".join(sorted(m for m in sys.modules if __import__("sitecustomize").is_ros(m))))
for blocked in ("rclpy", "rcl_interfaces.msg", "rosidl_runtime_py", "std_msgs.msg", "akd_ros.msg"):
    try:
        __import__(blocked)
    except ImportError:
        continue
    raise SystemExit(f"{blocked} imported: the blocker is not in place")
"""


COMPOSED = {
    "joint_name": "JointSettings.name",
    **dict.fromkeys(
        ["counts_per_revolution", "gear_ratio", "direction", "offset", "axis", "lead", "peak_torque"],
        "JointSettings.units",
    ),
    **{
        f"limits.{n}": "JointSettings.limits"
        for n in ("min_position", "max_position", "max_velocity", "max_torque", "max_acceleration")
    },
    "limits.policy": "JointSettings.limits",
    "mapping.rx": "JointSettings.mapping",
    "mapping.tx": "JointSettings.mapping",
    **{f"rt.{n}": "Settings.realtime" for n in ("priority", "cpu", "lock_memory", "cpu_latency_us", "pipelined")},
    **{f"record.{n}": "Settings.record" for n in ("enabled", "folder", "decimation", "black_box_seconds")},
    "live_view.address": "Settings.live_view",
    "live_view.port": "Settings.live_view",
}
"""The parameters that make a setting of several parameters' values, each with the field it goes into; every other
parameter has a field of its own name, its dots made underscores."""


def run_without_ros(*arguments: str) -> subprocess.CompletedProcess:
    """This Python with `arguments`, in the repository, its ROS imports refused; to its end."""
    path = os.pathsep.join(filter(None, [str(NO_ROS), os.environ.get("PYTHONPATH")]))
    return subprocess.run(
        [sys.executable, *arguments],
        cwd=REPO,
        env={**os.environ, "PYTHONPATH": path},
        capture_output=True,
        text=True,
        timeout=RUN_TIMEOUT_S,
        check=False,
    )


def test_the_package_and_a_parameters_file_need_no_ros():
    result = run_without_ros("-c", IMPORTS_WITHOUT_ROS)
    assert result.returncode == 0, result.stderr
    joints, ros_modules = result.stdout.splitlines()
    assert joints == ",".join(f"joint_{i}" for i in range(1, 7))
    assert ros_modules == "", ros_modules


def test_these_tests_pass_with_ros_blocked():
    if ROS_BLOCKED:
        pytest.skip("this is the run with ROS blocked")
    result = run_without_ros("-m", "pytest", "-q", "-p", "no:cacheprovider", __file__)
    assert result.returncode == 0, result.stdout + result.stderr
    # Every test but this one ran there.
    assert re.search(r"\b\d+ passed, 1 skipped in ", result.stdout), result.stdout


def write(directory: Path, text: str, name: str = "params.yaml") -> str:
    path = directory / name
    path.write_text(text)
    return str(path)


def test_dotted_keys_and_nested_maps_give_the_same_names(tmp_path):
    dotted = write(
        tmp_path,
        """
akd_node:
  ros__parameters:
    link: sim:2
    limits.max_velocity: 6.0
    rt.priority: 10
    joints: [a, b]
    joints.a.limits.min_position: -1.5
    joints.b.mapping: flexible
    joints.b.mapping.rx: ["0x6040:00/16 0x60C1:01/32"]
    joints.b.mapping.tx: ["0x6041:00/16 0x6064:00/32"]
""",
        "dotted.yaml",
    )
    nested = write(
        tmp_path,
        """
akd_node:
  ros__parameters:
    link: sim:2
    limits:
      max_velocity: 6.0
    rt: {priority: 10}
    joints: [a, b]
    joints.a:
      limits: {min_position: -1.5}
    joints.b:
      mapping: flexible
      mapping.rx: ["0x6040:00/16 0x60C1:01/32"]
      mapping.tx: ["0x6041:00/16 0x6064:00/32"]
""",
        "nested.yaml",
    )
    values = params.read_parameters_file(dotted)
    assert values == params.read_parameters_file(nested)
    assert values["limits.max_velocity"] == 6.0 and values["joints.b.mapping.rx"] == ["0x6040:00/16 0x60C1:01/32"]
    settings = params.settings(values)
    a, b = settings.joints
    assert (settings.realtime.priority, a.limits.min_position, a.limits.max_velocity) == (10, -1.5, 6.0)
    assert b.slave == 1 and b.mapping == ([[0x60400010, 0x60C10120]], [[0x60410010, 0x60640020]])


def test_the_six_axis_files_give_each_joint_its_block():
    settings = params.settings(params.read_parameters_file(str(REPO / "config" / "akd_sim_6axis.yaml")))
    assert [(j.name, j.slave) for j in settings.joints] == [(f"joint_{i}", i - 1) for i in range(1, 7)]
    assert [j.units.gear_ratio for j in settings.joints] == [100.0, 100.0, 80.0, 50.0, 50.0, 50.0]
    assert settings.joints[1].limits.min_position == -2.0 and settings.joints[0].limits.min_position == -3.2
    assert settings.joints[5].latch_arm == ((1, "rising"),) and settings.joints[4].latch_arm == ()
    # The real six-axis template writes its blocks as nested maps (joints.joint_1: {...}).
    template = params.read_parameters_file(str(REPO / "config" / "akd_6axis.yaml"))
    template["link"] = "sim:6"  # its link names an interface of the target machine
    settings = params.settings(template)
    assert settings.joints[2].units.direction == -1 and settings.joints[5].latch_arm == ((1, "rising"),)


def test_only_the_nodes_own_sections_and_the_wildcards_apply_a_later_one_winning(tmp_path):
    path = write(
        tmp_path,
        """
/**:
  ros__parameters:
    cycle_time: 0.002
    status_rate: 5.0
akd_node:
  ros__parameters:
    cycle_time: 0.004
other_node:
  ros__parameters:
    cycle_time: 0.008
    not_ours: 1
/ns:
  akd_node:
    ros__parameters:
      mode: homing
/**/akd_node:
  ros__parameters:
    diagnostics_rate: 2.0
/*:
  ros__parameters:
    status_rate: 20.0
""",
    )
    assert params.read_parameters_file(path) == {"cycle_time": 0.004, "status_rate": 20.0, "diagnostics_rate": 2.0}
    assert params.read_parameters_file(path, "/ns/akd_node") == {
        "cycle_time": 0.002,
        "status_rate": 5.0,
        "mode": "homing",
        "diagnostics_rate": 2.0,
    }
    with pytest.raises(params.ParameterError, match="unknown parameter not_ours; "):
        params.read_parameters_file(path, "other_node")


def test_a_later_file_and_p_override_as_rcl_merges_them(tmp_path):
    first = write(tmp_path, "akd_node:\n  ros__parameters:\n    cycle_time: 0.002\n    mode: homing\n", "first.yaml")
    second = write(tmp_path, "/**:\n  ros__parameters:\n    cycle_time: 0.004\n", "second.yaml")
    assert params.read_arguments(["akd_node", "--ros-args", "--params-file", first, "--params-file", second]) == {
        "cycle_time": 0.004,
        "mode": "homing",
    }
    given = ["--ros-args", "--params-file", first, "-p", "mode:=profile_velocity", "-p", "dc:=off"]
    assert params.read_arguments(given) == {"cycle_time": 0.002, "mode": "profile_velocity", "dc": False}
    assert params.settings(params.read_arguments(given)).dc is False
    # -p sets the wildcard section, which here first appeared before the node's own: the node's section wins.
    assert params.read_arguments(["--ros-args", "-p", "mode:=profile_torque", "--params-file", first]) == {
        "mode": "homing",
        "cycle_time": 0.002,
    }
    # Arguments outside --ros-args are the program's own.
    assert params.read_arguments(["-p", "mode:=homing", "--ros-args", "--", "-p", "mode:=homing"]) == {}
    # No arguments at all (AkdNode(args=[]), as a program that builds the node itself gives it): nothing set.
    assert params.read_arguments([]) == {}


@pytest.mark.parametrize("case", sorted(set(BAD_FILES) - REFUSED_AT_CONFIGURE))
def test_a_bad_parameters_file_is_refused_with_the_nodes_message(case, tmp_path):
    body, expected = BAD_FILES[case]
    with pytest.raises(params.ParameterError) as refused:
        params.settings(params.read_parameters_file(str(params_file(tmp_path, body))))
    for text in expected:
        assert text in str(refused.value), f"{text!r} not in {refused.value}"


@pytest.mark.parametrize("case", sorted(REFUSED_AT_CONFIGURE))
def test_the_bad_files_the_bus_refuses_pass_the_parameters_checks(case, tmp_path):
    body, _ = BAD_FILES[case]
    params.settings(params.read_parameters_file(str(params_file(tmp_path, body))))


def test_a_yaml_syntax_error_names_the_file_line_and_column(tmp_path):
    path = write(tmp_path, "akd_node:\n  ros__parameters:\n    link: sim\n    mode: [homing\n    cycle_time: 0.001\n")
    with pytest.raises(params.ParameterError) as refused:
        params.read_parameters_file(path)
    message = str(refused.value)
    assert message == (
        f"parameters file {path}, line 5, column 15: expected ',' or ']', but got ':' (while parsing a flow sequence, "
        "line 4, column 11)"
    )
    path = write(tmp_path, "akd_node:\n  ros__parameters:\n    link: sim\n   mode: homing\n")
    with pytest.raises(params.ParameterError, match=r"params\.yaml, line 4, column 4: expected <block end>"):
        params.read_parameters_file(path)


def test_unknown_names_are_refused_as_declare_refuses_them(tmp_path):
    path = write(tmp_path, "/**:\n  ros__parameters:\n    cycle_tme: 0.001\n    link: sim\n")
    with pytest.raises(params.ParameterError) as refused:
        params.read_parameters_file(path)
    assert str(refused.value).startswith("unknown parameter cycle_tme; the parameters are: link, joints, ")
    assert "joints.<name>.<one of slave, alias, mode" in str(refused.value)
    # rclpy's own QoS overrides are no parameter of the node's but are not unknown either.
    path = write(tmp_path, "akd_node:\n  ros__parameters:\n    qos_overrides./joint_states.publisher.depth: 5\n")
    assert params.read_parameters_file(path) == {"qos_overrides./joint_states.publisher.depth": 5}
    # A section of another node is not read, so its names are not this node's to refuse.
    path = write(tmp_path, "other_node:\n  ros__parameters:\n    cycle_tme: 0.001\n")
    assert params.read_parameters_file(path) == {}


def test_a_file_that_is_no_parameters_file_is_refused_naming_it(tmp_path):
    missing = str(tmp_path / "missing.yaml")
    with pytest.raises(params.ParameterError, match=f"parameters file {missing}: No such file or directory"):
        params.read_parameters_file(missing)
    for text, where in (
        ("- link\n", "the top level"),
        ("akd_node: sim\n", "akd_node"),
        ("akd_node:\n  link: sim\n", "akd_node/link"),
    ):
        with pytest.raises(params.ParameterError) as refused:
            params.read_parameters_file(write(tmp_path, text))
        assert f": {where} must be a map of node names, each with its ros__parameters" in str(refused.value)
    assert params.read_parameters_file(write(tmp_path, "")) == {}


def test_each_parameter_is_held_in_the_settings_under_its_own_name():
    import dataclasses

    fields = {
        per_joint: {field.name for field in dataclasses.fields(params.JointSettings if per_joint else params.Settings)}
        for per_joint in (False, True)
    }
    without = {spec.name for spec in params.SCHEMA if spec.name.replace(".", "_") not in fields[spec.per_joint]}
    assert without == set(COMPOSED)
    made = params.settings({"constraints.goal_time": 2.5, "trajectory.stop_deceleration": 4.0})
    assert (made.constraints_goal_time, made.joints[0].trajectory_stop_deceleration) == (2.5, 4.0)
