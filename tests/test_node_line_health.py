"""The line's health as a user sees it: akd_node with six joints on akd-sim's six virtual AKDs (UDP), recording,
watched through real rclpy and by akd-top attached over ROS. A clean line shows zero everywhere; a faulty cable
injected on akd-sim's stdin (`crc 3 1 ...`: frames entering slave 3's port 1, which on the virtual daisy chain come
back from slave 4, its port 0) is named on /diagnostics and in akd-top as that cable; a link taken down and up
(`link 3 1 down`, `up`) likewise; and the counters in the bag are those akd-sim's virtual ESCs counted.

The waits have deadlines only so that a failure does not hang; nothing asserts how fast anything happens (the node
reads the line four times a second and publishes /diagnostics five times a second, so it is seconds at most).
"""

from __future__ import annotations

import asyncio
import json
import signal
from pathlib import Path

import pytest
from diagnostic_msgs.msg import DiagnosticStatus
from rosbags.highlevel import AnyReader
from rosbags.typesys import Stores, get_typestore

from support.ros import Client, module_domain, node_on_sim

DOMAINS = range(91, 96)
"""ROS_DOMAIN_IDs of this module (see test_node_joints.py for the others' ranges)."""
JOINTS = [f"joint_{i}" for i in range(1, 7)]
PARAMS = """\
akd_node:
  ros__parameters:
    link: udp://127.0.0.1:{port}
    cycle_time: 0.002
    rt.priority: 30
    mode: cyclic_synchronous_position
    joint_states_rate: 20.0
    diagnostics_rate: 5.0
    record.enabled: true
    record.folder: {folder}
    record.black_box_seconds: 0.0
    joints: [{joints}]
"""
COUNTERS = ("invalid_frames", "rx_errors", "forwarded_errors", "lost_links")
RETURN_PAIR_INTO_3 = "errors on the cable into slave 3 (joint_4) port 1, from slave 4 (joint_5) port 0: "
CABLE_3_TO_4 = "the cable into slave 4 (joint_5) port 0, from slave 3 (joint_4) port 1"

ros_domain = module_domain(DOMAINS)


def line_statuses(message) -> dict[str, DiagnosticStatus]:
    """The line's statuses of a /diagnostics message, by what they are of ("line", "line slave N")."""
    return {s.name.split(": ", 1)[1]: s for s in message.status if ": line" in s.name}


def values(status) -> dict[str, str]:
    return {v.key: v.value for v in status.values}


def totals(statuses: dict) -> dict[int, dict[str, int]]:
    """Each slave's counters since the start, as its status gives them: {"portP_COUNTER": n, ...}."""
    found = {}
    for what, status in statuses.items():
        if what.startswith("line slave "):
            v = values(status)
            counted = {k: int(x) for k, x in v.items() if k.endswith(COUNTERS)}
            counted |= {k: int(v[k]) for k in ("processing_unit_errors", "pdi_errors")}
            found[int(v["slave"])] = counted
    return found


def sim_counted(sim, slave: int) -> dict[str, int]:
    """What akd-sim's ESC of `slave` counted since power-up, keyed as the node's status keys them."""
    esc = json.loads(sim.command(f"counters {slave}")[3:])
    counted = {f"port{p['port']}_{c}": p["counted"][c] for p in esc["ports"] for c in COUNTERS}
    return counted | esc["counted"]


def number(level) -> int:
    """A DiagnosticStatus level as its number (a byte in rclpy's messages)."""
    return level[0] if isinstance(level, bytes) else int(level)


def level(status) -> int:
    return number(status.level)


OK, WARN, ERROR = (number(x) for x in (DiagnosticStatus.OK, DiagnosticStatus.WARN, DiagnosticStatus.ERROR))


def latest_line(ros: Client) -> dict[str, DiagnosticStatus]:
    return line_statuses(ros.latest("/diagnostics"))


def wait_line(ros: Client, what: str, done) -> dict[str, DiagnosticStatus]:
    """The line's statuses of the first /diagnostics message for which `done(statuses)` holds."""
    found = []
    ros.spin_until(lambda: found.append(latest_line(ros)) or done(found[-1]), what)
    return found[-1]


async def akd_top_names(source, words: str) -> None:
    """akd-top attached to the node shows the line's summary with `words`, and the port the fault entered by
    highlighted."""
    from akd_ros.top.app import Top
    from test_top import until

    app = Top(source, refresh_s=0.1)
    async with app.run_test(size=(200, 60)) as pilot:
        await until(pilot, lambda: words in app.line_text, f"akd-top's line saying {words!r}")
        await until(pilot, lambda: app.line_table.row_count == 12, "a row per port of the six slaves")
        cell = app.line_table.get_cell("3:1", "invalid_frames")
        assert int(cell.plain) > 0 and "yellow" in str(cell.style), cell
        assert app.line_table.get_cell("5:0", "invalid_frames").plain == "0"
        await pilot.press("q")


def bag_line_totals(folder: Path) -> dict[int, dict[str, int]]:
    """The counters of the last /diagnostics message in the bag the node recorded into `folder`."""
    (bag,) = folder.iterdir()
    last = None
    with AnyReader([bag], default_typestore=get_typestore(Stores.ROS2_JAZZY)) as reader:
        connections = [c for c in reader.connections if c.topic == "/diagnostics"]
        for connection, _, raw in reader.messages(connections=connections):
            message = reader.deserialize(raw, connection.msgtype)
            if any(": line slave" in s.name for s in message.status):
                last = message
    assert last is not None, "no line statuses in the bag's /diagnostics"
    return totals(line_statuses(last))


def test_a_faulty_cable_and_a_link_are_named_and_the_bag_counts_what_the_escs_counted(tmp_path, ros_domain):
    pytest.importorskip("rclpy")
    from akd_ros.top.ros_source import RosSource

    bags = tmp_path / "bags"
    params = PARAMS.replace("{folder}", str(bags)).replace("{joints}", ", ".join(JOINTS))
    with node_on_sim(params, tmp_path, ros_domain, count=6) as (sim, node, ros):
        # A clean line: OK everywhere, every counter 0.
        clean = wait_line(ros, "the line read", lambda s: len(s) == 7 and "no errors on the line" in s["line"].message)
        assert all(level(s) == OK for s in clean.values()), clean
        assert all(n == 0 for counted in totals(clean).values() for n in counted.values()), totals(clean)
        assert values(clean["line slave 3"])["port1_peer"] == "slave 4 (joint_5) port 0"

        # Errors entering slave 3's port 1: the return pair of the cable from slave 4.
        sim.command("crc 3 1 40 25")
        named = wait_line(ros, "the faulty cable named", lambda s: s["line"].message.startswith(RETURN_PAIR_INTO_3))
        assert level(named["line"]) == WARN
        assert level(named["line slave 3"]) == WARN
        assert named["line slave 3"].message.startswith("port 1: "), named["line slave 3"].message
        source = RosSource("/akd_node")
        try:
            asyncio.run(akd_top_names(source, RETURN_PAIR_INTO_3))
        finally:
            source.close()
        # Once the fault has spoiled all 40, the node's totals are what each virtual ESC counted.
        spoiling = lambda: json.loads(sim.command("counters 3")[3:])["ports"][1]["spoiling"]  # noqa: E731
        ros.spin_until(lambda: spoiling() == 0, "the fault's end")
        expected = {slave: sim_counted(sim, slave) for slave in range(6)}
        assert expected[3]["port1_invalid_frames"] == 40 and expected[0]["port1_forwarded_errors"] == 40
        wait_line(ros, "the node's totals at akd-sim's", lambda s: totals(s) == expected)

        # A link taken down: the slaves behind it out of reach, the cable named; up again: its lost links.
        sim.command("link 3 1 down")
        down = wait_line(ros, "the link named", lambda s: s["line"].message.startswith(f"no link on {CABLE_3_TO_4}"))
        assert level(down["line"]) == ERROR
        assert level(down["line slave 5"]) == ERROR
        sim.command("link 3 1 up")
        wait_line(ros, "its loss named", lambda s: s["line"].message.startswith(f"link lost on {CABLE_3_TO_4}: 1 "))
        expected = {slave: sim_counted(sim, slave) for slave in range(6)}
        assert expected[3]["port1_lost_links"] == 1 and expected[4]["port0_lost_links"] == 1
        wait_line(ros, "the node's totals at akd-sim's after the link", lambda s: totals(s) == expected)
        ros.spin_for(0.5)
        node.process.send_signal(signal.SIGINT)
        ros.spin_until(lambda: node.process.poll() is not None, "akd_node's exit on SIGINT")
    assert "Traceback" not in node.output()
    assert bag_line_totals(bags) == expected
