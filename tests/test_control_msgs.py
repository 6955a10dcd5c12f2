"""control_msgs as this package builds it where control_msgs is not installed (rosidl_build.py, from
interfaces/control_msgs): the same types, fields and RIHS01 type hashes as ros-jazzy-control-msgs, so that MoveIt on a
full ROS install talks to ~/follow_joint_trajectory.

The expected hashes were computed by rosidl (rosidl_adapter and rosidl_generator_type_description, the wheels in
constraints.txt) from the upstream Jazzy definitions (github.com/ros-controls/control_msgs, branch jazzy at
f901df2662f22a39a06aa04a85a34602c47e3cc0, release 5.8.0: msg/JointTolerance.msg, msg/JointComponentTolerance.msg,
action/FollowJointTrajectory.action), with `upstream_hashes` below run on a checkout of those three files. Here the same
function runs on interfaces/control_msgs and must give the same hashes, and the built Python types must carry the same
fields and constants.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
rosidl_build = pytest.importorskip("rosidl_build")
pytest.importorskip("rosidl_adapter")

UPSTREAM_JAZZY = {
    "control_msgs/msg/JointTolerance": "RIHS01_c254f9cece0f3b733017b6990fd46d1326e25242d6b8844398c97d9a88e7d648",
    "control_msgs/msg/JointComponentTolerance": "RIHS01_"
    "739ea7566931944d33830fa10f1bf5e7a7fbdc3172bce7a7eaac642bd6e3ffa4",
    "control_msgs/action/FollowJointTrajectory": "RIHS01_"
    "738ebcb7a2d7cfa42f9f1001cc99ce3a4383d1cfe508015d9be8485e4b1c66f6",
    "control_msgs/action/FollowJointTrajectory_SendGoal": "RIHS01_"
    "b13789dddc325a7a962825c45e28c77d37237ec129dd0c34dc5994562938c57f",
    "control_msgs/action/FollowJointTrajectory_GetResult": "RIHS01_"
    "e3ceb38e3e1867c8dc0f46014df26e90eb93422f27e9e97f936e07f94be4bc8b",
    "control_msgs/action/FollowJointTrajectory_FeedbackMessage": "RIHS01_"
    "80398fcb9674a79081a9906e2ccf0c804dd7cb15e22e362e606ee87186beab71",
}
"""RIHS01 hashes rosidl gives the upstream Jazzy definitions (see the module doc)."""


def upstream_hashes(source_dir: Path, build_dir: Path) -> dict[str, str]:
    """The RIHS01 hash of every type rosidl derives from the control_msgs definitions in `source_dir` (absolute; msg/,
    action/), by type name, as rosidl_generator_type_description writes them for a package build."""
    package = rosidl_build.InterfacePackage(
        rosidl_build.CONTROL_MSGS, source_dir, build_dir / "python", rosidl_build.CONTROL_MSGS_DEPENDENCIES
    )
    generators = rosidl_build.import_generators()
    prefixes = rosidl_build.ros_prefixes(generators)
    shares = [f"{d}:{rosidl_build.package_prefix(d, prefixes) / 'share' / d}" for d in package.dependencies]
    idl_dir, tuples = build_dir / "idl", []
    files = rosidl_build.interface_files(source_dir)
    for relative in files:
        generators["rosidl_adapter"].convert_to_idl(source_dir, package.name, relative, idl_dir)
        tuples.append(f"{idl_dir}:{relative.with_suffix('.idl')}")
    arguments = build_dir / "arguments.json"
    arguments.write_text(
        json.dumps(
            {
                "package_name": package.name,
                "output_dir": str(build_dir / "hashes"),
                "idl_tuples": tuples,
                "include_paths": shares,
            }
        )
    )
    generators["rosidl_generator_type_description"].generate_type_hash(str(arguments))
    hashes = {}
    for relative in files:
        description = json.loads((build_dir / "hashes" / relative.with_suffix(".json")).read_text())
        hashes |= {entry["type_name"]: entry["hash_string"] for entry in description["type_hashes"]}
    return hashes


def test_the_built_definitions_hash_as_the_upstream_jazzy_ones(tmp_path):
    ours = upstream_hashes((ROOT / "interfaces" / "control_msgs").resolve(), tmp_path)
    assert {name: ours.get(name) for name in UPSTREAM_JAZZY} == UPSTREAM_JAZZY


def test_the_python_types_carry_the_upstream_fields_and_constants():
    action = pytest.importorskip("control_msgs.action")
    fjt = action.FollowJointTrajectory
    goal = fjt.Goal()
    assert list(goal.get_fields_and_field_types()) == [
        "trajectory",
        "multi_dof_trajectory",
        "path_tolerance",
        "component_path_tolerance",
        "goal_tolerance",
        "component_goal_tolerance",
        "goal_time_tolerance",
    ]
    codes = {
        name: getattr(fjt.Result, name)
        for name in (
            "SUCCESSFUL",
            "INVALID_GOAL",
            "INVALID_JOINTS",
            "OLD_HEADER_TIMESTAMP",
            "PATH_TOLERANCE_VIOLATED",
            "GOAL_TOLERANCE_VIOLATED",
        )
    }
    assert list(codes.values()) == [0, -1, -2, -3, -4, -5]
    assert list(fjt.Feedback().get_fields_and_field_types())[:5] == [
        "header",
        "joint_names",
        "desired",
        "actual",
        "error",
    ]
