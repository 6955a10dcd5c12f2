"""akd-top driven through Textual's own pilot (`App.run_test`, headless) against the virtual AKDs: once over a link it
runs itself (`sim:2`, no ROS) and attached to akd_node on akd-sim --udp with two joints, over ROS (ROS domains 0-8)
and over Zenoh (a router of the test's own, no ROS import). What is checked is what the view's table shows: a fault
injected in a virtual AKD appears in its joint's row, and enable with its confirmation brings the selected joint (and
only it) to Operation enabled."""

from __future__ import annotations

import asyncio
import os
import random
import subprocess
import sys
import time
from pathlib import Path

import pytest

from akd_ros.top.app import COLUMNS, ChooseLatch, Confirm, Top
from akd_ros.top.direct import DirectSource
from support.netns import console_script

# A bound on each wait, not a timing expectation: requests, discovery and diagnostics take seconds on a loaded machine.
WAIT_S = 30.0
DOMAINS = range(9)


async def until(pilot, done, what: str) -> None:
    """Lets the app run until done() is true; fails naming what did not happen."""
    deadline = time.monotonic() + WAIT_S
    while not done():
        if time.monotonic() > deadline:
            table = pilot.app.table
            rows = [[table.get_cell(r, c) for c, _ in COLUMNS] for r in table.rows]
            pytest.fail(f"no {what} within {WAIT_S} s; outcome: {pilot.app.last_outcome!r}; rows: {rows}")
        await pilot.pause(0.05)


def shown(app: Top, joint: str, column: str) -> str:
    """What the view's table shows in `joint`'s row under `column`."""
    return app.table.get_cell(joint, column)


async def enable_with_confirmation(pilot, app: Top, joint: str) -> None:
    """e, then the confirmation's y, on the selected `joint`; waits for its row to show Operation enabled."""
    assert app.selected() == joint
    await pilot.press("e")
    assert isinstance(app.screen, Confirm) and app.screen.question == f"Enable {joint}?"
    await pilot.press("y")
    await until(pilot, lambda: shown(app, joint, "state") == "Operation enabled", f"{joint} Operation enabled")


async def fault_then_reset(pilot, app: Top, joint: str, inject_f439) -> None:
    """inject_f439() faults `joint`'s drive with F439; waits for its row to show the fault with its text and the
    Fault state, then resets it with r and the confirmation's y, to Switch on disabled."""
    inject_f439()
    await until(pilot, lambda: "F439" in shown(app, joint, "fault"), f"F439 in {joint}'s row")
    # The drive's 0x603F and its emergency both report it; the row shows the later of the two.
    assert shown(app, joint, "fault") in ("drive_fault: F439 Following error", "emergency: F439 Following error")
    await until(pilot, lambda: shown(app, joint, "state") == "Fault", f"{joint} in Fault")
    await pilot.press("r")
    assert isinstance(app.screen, Confirm) and app.screen.question == f"Reset the fault of {joint}?"
    await pilot.press("y")
    await until(pilot, lambda: shown(app, joint, "state") == "Switch on disabled", f"{joint} reset")


async def direct_scenario(source: DirectSource, inject_fault) -> None:
    app = Top(source, refresh_s=0.05)
    async with app.run_test(size=(200, 30)) as pilot:
        await until(pilot, lambda: app.table.row_count == 2, "two rows")
        assert [shown(app, j, "state") for j in ("slave_0", "slave_1")] == ["Switch on disabled"] * 2
        assert shown(app, "slave_0", "mode") == "interpolated_position"
        assert "cycles" in app.bus_text and "DC: " in app.bus_text

        # Answering no asks nothing.
        await pilot.press("e")
        assert isinstance(app.screen, Confirm)
        await pilot.press("n")
        assert app.last_outcome == "slave_0: enable not asked"
        await pilot.pause(0.3)
        assert shown(app, "slave_0", "state") == "Switch on disabled"

        # The second joint, selected with the cursor, enabled with confirmation; the first stays disabled.
        await pilot.press("down")
        await enable_with_confirmation(pilot, app, "slave_1")
        assert shown(app, "slave_0", "state") == "Switch on disabled"
        assert shown(app, "slave_1", "fault") == "-"

        # A latch armed through its screen and the confirmation.
        await pilot.press("l")
        assert isinstance(app.screen, ChooseLatch)
        await pilot.press("3")
        assert isinstance(app.screen, Confirm) and "latch 2 of slave_1 on the rising edge" in app.screen.question
        await pilot.press("y")
        await until(pilot, lambda: "latch 2 armed" in app.last_outcome, "latch armed")

        # A fault injected in the virtual AKD appears in its joint's row, with its text; reset, then enable again.
        await fault_then_reset(pilot, app, "slave_1", lambda: inject_fault(1, "F439"))
        await enable_with_confirmation(pilot, app, "slave_1")
        await pilot.press("s")
        await pilot.press("y")
        await until(pilot, lambda: shown(app, "slave_1", "state") == "Quick stop active", "slave_1 quick-stopped")
        await pilot.press("q")


def test_direct_link_shows_faults_and_enables_with_confirmation():
    # The virtual AKDs judge missed frames by frames lost (`?missed=lost`): the view is the subject, not how late this
    # shared host runs the cycle thread, which would fault them with F125 as it would real ones.
    source = DirectSource("sim:2?missed=lost", period=0.004)
    try:
        asyncio.run(direct_scenario(source, source.bus.simulator.inject_fault))
    finally:
        source.close()


async def line_scenario(source: DirectSource) -> None:
    app = Top(source, refresh_s=0.05)
    async with app.run_test(size=(200, 60)) as pilot:
        await until(pilot, lambda: app.line_table.row_count == 12, "a row per port of the six slaves")
        await until(pilot, lambda: "no errors on the line" in app.line_text, "a clean line")
        assert app.line_table.get_cell("2:1", "peer").plain == "slave 3 (slave_3) port 0"
        # The cable from slave 1 into slave 2: frames entering slave 2's port 0 spoiled.
        source.bus.simulator.crc_errors(2, 0, 20, 10)
        words = "errors on the cable into slave 2 (slave_2) port 0, from slave 1 (slave_1) port 1: "
        await until(pilot, lambda: words in app.line_text, "the cable named")
        await until(pilot, lambda: app.line_table.get_cell("2:0", "invalid_frames").plain == "20", "all 20 counted")
        assert "yellow" in str(app.line_table.get_cell("2:0", "invalid_frames").style)
        # After it, forwarded; in front of it, nothing.
        assert app.line_table.get_cell("3:0", "forwarded_errors").plain == "20"
        assert app.line_table.get_cell("1:0", "invalid_frames").plain == "0"
        await pilot.press("q")


def test_direct_link_shows_the_line_and_names_a_faulty_cable():
    source = DirectSource("sim:6?missed=lost", period=0.004)
    try:
        asyncio.run(line_scenario(source))
    finally:
        source.close()


async def cell_scenario(source: DirectSource) -> None:
    app = Top(source, refresh_s=0.05)
    async with app.run_test(size=(200, 60)) as pilot:
        await until(pilot, lambda: app.device_table.row_count == 3, "a row per device")
        assert app.table.row_count == 1 and shown(app, "slave_3", "state") == "Switch on disabled"
        cells = {c: app.device_table.get_cell("el1004_1", c).plain for c in ("slave", "product", "inputs", "outputs")}
        assert cells == {"slave": "1", "product": "EL1004", "inputs": "0000", "outputs": "-"}, cells
        assert app.device_table.get_cell("ek1100_0", "inputs").plain == "-"
        source.bus.simulator.set_input(1, 2, True)
        await until(pilot, lambda: app.device_table.get_cell("el1004_1", "inputs").plain == "0100", "input 2 high")
        source.bus.device("el2004_2").set_outputs({"channel_4_output": True})
        await until(pilot, lambda: app.device_table.get_cell("el2004_2", "outputs").plain == "0001", "output 4 on")
        assert app.device_table.get_cell("el2004_2", "message").plain == "EL2004 in Op"
        await pilot.press("q")


def test_direct_link_on_a_cell_shows_its_devices_channels():
    # Before akd-top took the other slaves as devices, a line with terminals was refused (slave 0 is an EK1100).
    source = DirectSource("sim:ek1100,el1004,el2004,akd?missed=lost", period=0.004)
    try:
        asyncio.run(cell_scenario(source))
    finally:
        source.close()


def test_help_and_a_bad_link_are_one_line():
    result = subprocess.run(
        [*console_script("akd-top"), "--help"], capture_output=True, text=True, timeout=60, check=False
    )
    assert result.returncode == 0 and "examples:" in result.stdout and "akd-top sim:6" in result.stdout
    result = subprocess.run(
        [*console_script("akd-top"), "udp://127.0.0.1"], capture_output=True, text=True, timeout=60, check=False
    )
    assert result.returncode == 1
    # The one line, after root's warning where the tests run as root.
    lines = [line for line in result.stderr.splitlines() if "running as root is not needed" not in line]
    assert lines == [
        'akd-top: error: configuration: link "udp://127.0.0.1" is no udp://HOST:PORT with a port in 1..65535'
    ]
    result = subprocess.run(
        [*console_script("akd-top"), "sim", "--attach", "ros"], capture_output=True, text=True, timeout=60, check=False
    )
    assert result.returncode == 2 and "give either a LINK or --attach ros|zenoh" in result.stderr


NODE_PARAMS = """\
akd_node:
  ros__parameters:
    link: udp://127.0.0.1:{port}
    cycle_time: 0.002
    # As test_node.py runs it, as an integrator would: the cycle thread under SCHED_FIFO where permitted.
    rt.priority: 30
    mode: interpolated_position
    joints: [arm, wrist]
    joint_states_rate: 20.0
    status_rate: 10.0
    diagnostics_rate: 5.0
"""


async def attached_scenario(source, sim) -> None:
    app = Top(source, refresh_s=0.1)
    async with app.run_test(size=(200, 30)) as pilot:
        await until(pilot, lambda: app.table.row_count == 2, "both joints' rows")
        await until(pilot, lambda: shown(app, "wrist", "state") == "Switch on disabled", "wrist's state")
        await until(pilot, lambda: "cycles" in app.bus_text, "the bus's statistics")
        assert "udp://127.0.0.1" in app.bus_text
        await pilot.press("down")
        await enable_with_confirmation(pilot, app, "wrist")
        assert shown(app, "arm", "state") == "Switch on disabled"
        await fault_then_reset(pilot, app, "wrist", lambda: sim.command("fault 1 F439"))
        await pilot.press("q")


def attached_to_a_node(tmp_path, template: str, source_of, label: str = "", without_ros: bool = False) -> None:
    """`attached_scenario` with the source `source_of()` gives, on akd_node run with parameters `template` (its
    {port} akd-sim's, two drives; `without_ros`: from .venv-noros), all ended afterwards, the node's output printed
    after `label`."""
    from support.netns import free_udp_port
    from support.ros import NodeProcess, Sim, stop

    sim = Sim(free_udp_port(), count=2)
    params = tmp_path / "akd_node.yaml"
    params.write_text(template.format(port=sim.port))
    node = NodeProcess(params, without_ros=without_ros)
    source = None
    try:
        source = source_of()
        asyncio.run(attached_scenario(source, sim))
    finally:
        if source is not None:
            source.close()
        stop(node.process)
        sim.stop()
        print(f"{label}akd_node output:\n{node.output()}")


def test_attached_over_ros_shows_faults_and_enables_with_confirmation(tmp_path):
    pytest.importorskip("rclpy", reason="the ROS attach needs rclpy (.venv has it)")
    from akd_ros.top.ros_source import RosSource
    from support.ros import ros_environment

    with ros_environment(DOMAINS) as domain:
        attached_to_a_node(tmp_path, NODE_PARAMS, lambda: RosSource("/akd_node"), f"ROS domain {domain}; ")


# akd-top on a link, in an interpreter whose every ROS import is refused (tests/support/no_ros): the view comes up and
# shows the drive; it prints the ROS modules that were loaded (none may be).
WITHOUT_ROS = """
import asyncio, sys
from akd_ros.top.app import Top
from akd_ros.top.direct import DirectSource

async def main(source):
    app = Top(source, refresh_s=0.05)
    async with app.run_test(size=(200, 30)) as pilot:
        while not app.table.row_count:
            await pilot.pause(0.05)
        print(app.table.get_cell("slave_0", "joint"))
        await pilot.press("q")

source = DirectSource("sim")
try:
    asyncio.run(main(source))
finally:
    source.close()
print(",".join(sorted(m for m in sys.modules if __import__("sitecustomize").is_ros(m))))
"""


def test_the_view_of_a_link_needs_no_ros():
    repo = Path(__file__).resolve().parents[1]
    python = repo / ".venv-noros" / "bin" / "python"
    result = subprocess.run(
        [str(python if python.exists() else sys.executable), "-c", WITHOUT_ROS],
        env={**os.environ, "PYTHONPATH": str(repo / "tests" / "support" / "no_ros")},
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )
    assert result.returncode == 0, result.stderr
    assert result.stdout.splitlines()[-2:] == ["slave_0", ""], result.stdout


ZENOH_NODE_PARAMS = NODE_PARAMS.replace(
    "  ros__parameters:\n", '  ros__parameters:\n    transport: zenoh\n    zenoh.connect: ["{endpoint}"]\n'
)


def test_attached_over_zenoh_shows_faults_and_enables_with_confirmation(tmp_path, monkeypatch):
    from akd_ros.top.zenoh_source import ZenohSource
    from support.zenoh import zenoh_router

    monkeypatch.setenv("ROS_DOMAIN_ID", str(random.choice(DOMAINS)))
    with zenoh_router() as endpoint:
        attached_to_a_node(
            tmp_path,
            ZENOH_NODE_PARAMS.replace("{endpoint}", endpoint),
            lambda: ZenohSource("/akd_node", [endpoint]),
            without_ros=True,
        )


def test_attached_over_zenoh_with_no_router_says_so_in_one_line():
    from akd_ros.top.zenoh_source import ZenohSource
    from support.zenoh import free_tcp_port

    endpoint = f"tcp/127.0.0.1:{free_tcp_port()}"

    async def scenario(source: ZenohSource) -> None:
        app = Top(source, refresh_s=0.05)
        async with app.run_test(size=(200, 30)) as pilot:
            await until(pilot, lambda: "no Zenoh router" in app.bus_text, "the hint in the bus line")
            assert app.bus_text.splitlines()[0] == (
                f"bus /akd_node (no Zenoh router reached at {endpoint}: start one, e.g. .venv/bin/akd-zenohd, or "
                "give --connect ENDPOINT): "
            )
            assert app.table.row_count == 0
            await pilot.press("q")

    source = ZenohSource("/akd_node", [endpoint])
    try:
        asyncio.run(scenario(source))
    finally:
        source.close()
