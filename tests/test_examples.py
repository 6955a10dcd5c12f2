"""Every program in examples/ runs to exit status 0 against the virtual AKD: those without ROS as they are, those of
the node against an `akd_node` this test starts (two joints on `sim:2?missed=lost`, recording), and read_bag.py on
the bag that node wrote. Each is on the documentation's examples page."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from support.params_files import params_file
from support.ros import WAIT_S, NodeProcess, ros_environment, stop

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = ROOT / "examples"
DOMAINS = range(50, 55)
WITHOUT_ROS = ("axis_profile_position.py", "bus_of_drives.py")
OF_THE_NODE = ("node_client.py", "joint_trajectory.py")
OF_A_BAG = ("read_bag.py",)
HELPERS = ("ros_helpers.py",)
"""Imported by the examples, not run."""


def run(name: str, *args: str, cwd: Path = ROOT) -> str:
    """Runs examples/`name`; its output, once it exited 0."""
    done = subprocess.run(
        [sys.executable, str(EXAMPLES / name), *args],
        cwd=cwd,
        capture_output=True,
        text=True,
        timeout=WAIT_S * 4,
        check=False,
    )
    assert done.returncode == 0, f"{name} exited {done.returncode}:\n{done.stdout}{done.stderr}"
    return done.stdout


def test_every_example_is_run_here_and_shown_on_the_examples_page():
    page = (ROOT / "docs" / "examples.md").read_text(encoding="utf-8")
    programs = sorted(path.name for path in EXAMPLES.glob("*.py"))
    assert programs == sorted(WITHOUT_ROS + OF_THE_NODE + OF_A_BAG + HELPERS)
    for name in programs:
        assert f"```{{literalinclude}} ../examples/{name}" in page, name


@pytest.mark.parametrize("name", WITHOUT_ROS)
def test_an_example_without_ros_runs(name):
    assert run(name)


def test_the_node_s_examples_run_against_a_node_and_its_bag_is_read(tmp_path):
    bags = tmp_path / "bags"
    body = f"link: sim:2?missed=lost\njoints: [shoulder, elbow]\nrecord.enabled: true\nrecord.folder: {bags}"
    with ros_environment(DOMAINS) as domain:
        node = NodeProcess(params_file(tmp_path, body), domain)
        try:
            # The example itself waits for the node (its /joint_states, its services), as a user runs it.
            assert "shoulder: +" in run(OF_THE_NODE[0])
            assert ": done" in run(OF_THE_NODE[1])
        finally:
            stop(node.process)
        assert node.process.returncode == 0, node.output()
    (bag,) = bags.iterdir()
    shown = run(OF_A_BAG[0], str(bag))
    assert "/akd_node/joint_trajectory: 1 messages" in shown
    assert "shoulder:" in shown and "elbow:" in shown
