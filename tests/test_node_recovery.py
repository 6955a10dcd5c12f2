"""akd_node through the field's failures, as a user sees them: akd-sim killed under the running node and started
again (the drive power-cycled, its line gone and back), and a drive power-cycled in Op. The node reports the loss on
~/fault, in /diagnostics and in its log, brings the drive back to Op by itself with its power stage off, and the drive
moves again only after a fresh enable and a fresh command. The times measured go to the recovery table.
"""

from __future__ import annotations

import signal
import time

from diagnostic_msgs.msg import DiagnosticStatus

from support import recovery_table
from support.netns import udp_port_bound
from support.ros import NODE, WAIT_S, Sim, module_domain, move_to, node_on_sim

DOMAINS = range(10, 20)
JOINT = "axis"
PARAMS = """\
akd_node:
  ros__parameters:
    link: udp://127.0.0.1:{port}
    cycle_time: 0.002
    rt.priority: 30
    mode: interpolated_position
    joint_name: axis
    joint_states_rate: 50.0
    diagnostics_rate: 10.0
    enable_on_start: true
"""


ros_domain = module_domain(DOMAINS)


def faults(ros) -> list:
    return ros.received[NODE + "fault"]


def wait_fault(ros, source: str, after: int, *others: str) -> object:
    """The first ~/fault message of `source` (or one of `others`) among those received after the first `after`, and
    when the test had it (wall clock ns; the client spins every 20 ms). Its stamp is the cycle it is about."""
    found = []
    sources = (source, *others)
    ros.spin_until(lambda: found.extend(m for m in faults(ros)[after:] if m.source in sources) or found, f"{source}")
    return found[0], time.time_ns()


def joint_diagnostics(ros) -> DiagnosticStatus:
    return next(s for s in ros.latest("/diagnostics").status if s.name.endswith(f": {JOINT}"))


def test_akd_sim_killed_and_started_again_is_reported_and_recovered_powerless(tmp_path, ros_domain):
    with node_on_sim(PARAMS, tmp_path, ros_domain) as (sim, node, ros):
        ros.spin_until(lambda: "enable_on_start: Operation enabled" in node.output(), "enable at start-up")
        before = len(faults(ros))
        t0 = time.time_ns()
        sim.process.send_signal(signal.SIGKILL)
        sim.process.wait(timeout=WAIT_S)
        lost, lost_seen = wait_fault(ros, "lost_frames", before)
        assert "drive disabled" in lost.action, lost
        # While the drive is gone, /diagnostics says so, and the log has said it once.
        ros.spin_until(lambda: "unreachable" in joint_diagnostics(ros).message, "diagnostics saying unreachable")
        status = joint_diagnostics(ros)
        assert status.level == DiagnosticStatus.ERROR, status
        assert "fault of axis: lost_frames" in node.output(), node.output()
        time.sleep(0.3)
        restarted = time.time_ns()
        sim = Sim(sim.port)
        try:
            deadline = time.monotonic() + WAIT_S
            while not udp_port_bound(sim.port):
                assert time.monotonic() < deadline
                time.sleep(0.01)
            back, back_seen = wait_fault(ros, "recovered", before)
            assert "power stage off" in back.action, back
            ros.spin_until(lambda: "unreachable" not in joint_diagnostics(ros).message, "diagnostics after recovery")
            assert "axis: recovered: back after" in node.output(), node.output()
            # Back in Op with the power stage off: nothing moves until enabled again.
            assert sim.state()["state"] in ("Switch on disabled", "Not ready to switch on"), sim.state()
            here = ros.position()
            ros.spin_for(0.3)
            assert ros.position() == here
            ros.trigger("enable")
            move_to(ros, here + 0.5)
        finally:
            sim.stop()
    assert "Traceback" not in node.output()
    recovery_table.record(
        "akd-sim killed under the running node, started again 0.3 s later",
        "~/fault `lost_frames` (disabled), /diagnostics ERROR `unreachable, being brought back`, log `fault of axis: "
        "lost_frames ...`; then ~/fault `recovered`, log `axis: recovered: back after N ms ...; call ~/enable`",
        lost_seen - t0,
        back_seen - restarted,
    )


def test_a_drive_power_cycled_under_the_node_comes_back_powerless(tmp_path, ros_domain):
    with node_on_sim(PARAMS, tmp_path, ros_domain) as (sim, node, ros):
        ros.spin_until(lambda: "enable_on_start: Operation enabled" in node.output(), "enable at start-up")
        before = len(faults(ros))
        t0 = time.time_ns()
        sim.command("power_cycle 0")
        # The only drive on the line: no answer from it is a wrong working counter of the whole frame.
        lost, lost_seen = wait_fault(ros, "working_counter", before, "unreachable")
        assert "drive disabled" in lost.action, lost
        back, back_seen = wait_fault(ros, "recovered", before)
        assert "power stage off" in back.action, back
        assert sim.state()["state"] == "Switch on disabled", sim.state()
        ros.trigger("enable")
        move_to(ros, ros.position() + 0.5)
    assert "Traceback" not in node.output()
    recovery_table.record(
        "drive power-cycled under the node",
        "~/fault `working_counter` (its only drive silent; disabled), then `recovered`; ~/enable and a command move "
        "it again",
        lost_seen - t0,
        back_seen - t0,
    )
