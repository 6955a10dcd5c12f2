"""akd_node against a virtual AKD, seen from another process through real rclpy.

The drive is an `akd-sim --udp` process whose stdin injects faults and input toggles; the node is `.venv/bin/akd_node
--ros-args --params-file FILE` with link udp://127.0.0.1:PORT; this process is the ROS client (subscriptions and
service calls over rmw_fastrtps_cpp, a ROS_DOMAIN_ID of its own, discovery on localhost). Every wait is bounded and
both processes are always ended in teardown. The tests share one node and set up the drive state each needs.
"""

from __future__ import annotations

import math
import signal
import time

import pytest
from diagnostic_msgs.msg import DiagnosticStatus
from std_srvs.srv import Trigger

from akd_ros import Axis
from akd_ros.msg import LatchEvent
from akd_ros.node.diagnostics import dc_values, fbus_param02_unknown
from akd_ros.srv import SdoRead, SdoWrite, SetMode
from support.ros import (
    COUNTS_PER_RAD,
    NODE,
    WAIT_S,
    Client,
    NodeProcess,
    Sim,
    latch_across,
    move_to,
    node_on_sim,
    ready,
    ros_environment,
    stop,
)

# ROS_DOMAIN_IDs of this module; the second node's are SECOND_DOMAIN_OFFSET above. Other modules take other ranges.
DOMAINS = range(201, 211)
JOINT = "test_axis"
JOINT_STATES_RATE = 50.0
MAX_POSITION = 1e4


PARAMS = """\
akd_node:
  ros__parameters:
    link: udp://127.0.0.1:{port}
    cycle_time: 0.002
    doors: [observe, operate, configure]
    # As an integrator runs it: the cycle thread under SCHED_FIFO where permitted (else a warning).
    rt.priority: 30
    mode: interpolated_position
    joint_name: {joint}
    limits.min_position: -{max_position}
    limits.max_position: {max_position}
    limits.max_velocity: 20.0
    limits.max_torque: 2.0
    joint_states_rate: {rate}
    status_rate: 10.0
    diagnostics_rate: 5.0
    # Longer than the node's rare Python stalls on this shared machine (the cycle thread times
    # the stream at the drive, so a stall that holds the commands back counts as a stop).
    command_timeout: 1.0
    command_timeout_policy: hold
"""


@pytest.fixture(scope="module")
def ros_domain():
    """A ROS_DOMAIN_ID of this module's own, discovery on localhost, Fast DDS; set for the module."""
    with ros_environment(DOMAINS) as domain:
        yield domain


@pytest.fixture(scope="module")
def sim():
    """The virtual AKD, served over UDP by akd-sim."""
    from support.netns import free_udp_port

    simulator = Sim(free_udp_port())
    yield simulator
    simulator.stop()


@pytest.fixture(scope="module")
def node(ros_domain, sim, tmp_path_factory):
    """The node on the simulator's port."""
    params = tmp_path_factory.mktemp("node") / "akd_test.yaml"
    params.write_text(PARAMS.format(port=sim.port, joint=JOINT, max_position=MAX_POSITION, rate=JOINT_STATES_RATE))
    process = NodeProcess(params)
    yield process
    stop(process.process)
    print(f"akd_node output:\n{process.output()}")


@pytest.fixture(scope="module")
def ros(node, ros_domain):
    """The client, once the node publishes."""
    client = Client(ros_domain)
    client.spin_until(lambda: client.received["/joint_states"] or node.process.poll() is not None, "joint_states")
    assert node.process.poll() is None, f"akd_node exited:\n{node.output()}"
    yield client
    client.close()


def test_joint_states_arrive_at_the_configured_rate_with_the_drive_values(ros, sim):
    ros.trigger("disable")
    start = len(ros.received["/joint_states"])
    ros.spin_for(2.0)
    count = len(ros.received["/joint_states"]) - start
    # About 100 at 50 Hz; the range only tells a publishing rate from a wrong one.
    assert 50 <= count <= 150, count
    message = ros.received["/joint_states"][-1]
    assert message.name == [JOINT]
    assert len(message.position) == len(message.velocity) == len(message.effort) == 1
    drive = sim.state()
    assert abs(ros.position() * COUNTS_PER_RAD - drive["position"]) <= 1.0, (ros.position(), drive)
    assert message.header.stamp.sec > 0


def test_a_position_command_moves_the_axis(ros, sim):
    ready(ros, sim, "interpolated_position")
    target = ros.position() + 1.0
    move_to(ros, target)
    assert abs(sim.state()["position"] - target * COUNTS_PER_RAD) < 1e-3 * COUNTS_PER_RAD


def test_a_velocity_command_turns_the_axis_and_a_stopped_stream_halts_it(ros, sim, node):
    ready(ros, sim, "profile_velocity")
    ros.stream("velocity", [2.0] * 50)
    velocity = ros.latest("/joint_states").velocity[0]
    assert velocity == pytest.approx(2.0, rel=0.05)
    assert sim.state()["velocity"] == pytest.approx(2.0 * COUNTS_PER_RAD, rel=0.05)
    # No more commands: after command_timeout the node halts the axis (policy hold) and it stays enabled.
    ros.spin_until(lambda: abs(ros.latest("/joint_states").velocity[0]) < 0.01, "axis halted")
    drive = sim.state()
    assert drive["state"] == "Operation enabled", (drive, node.output())
    assert "command_timeout" in node.output()


def test_a_torque_command_drives_the_axis_in_torque_mode(ros, sim):
    ready(ros, sim, "profile_torque")
    ros.stream("torque", [0.3] * 10)
    state = ros.latest("/joint_states")
    assert state.effort[0] == pytest.approx(0.3, rel=0.05)
    assert state.velocity[0] > 0.1
    ros.stream("torque", [-0.3] * 10 + [0.0] * 5)
    ros.trigger("disable")


def test_an_injected_fault_shows_on_fault_and_diagnostics_and_reset_clears_it(ros, sim):
    ready(ros, sim, "interpolated_position")
    sim.command("fault 0 F439")
    # Lost frames on a busy machine come as faults too; the one injected is F439 (CiA code 0x8611).
    following = [f for f in ros.received[NODE + "fault"] if f.code == 0x8611]
    ros.spin_until(
        lambda: following or following.extend(f for f in ros.received[NODE + "fault"] if f.code == 0x8611),
        "DriveFault 0x8611",
    )
    fault = following[-1]
    assert "F439" in fault.text, fault
    assert fault.joint == JOINT and fault.source in ("drive_fault", "emergency")
    assert fault.al_state == "op" and fault.ds402_state in ("fault", "fault_reaction_active"), fault
    assert fault.header.stamp.sec > 0

    def status() -> DiagnosticStatus:
        return ros.latest("/diagnostics").status[0]

    ros.spin_until(lambda: status().level == DiagnosticStatus.ERROR, "ERROR on /diagnostics")
    values = {v.key: v.value for v in status().values}
    assert "F439" in values["last_fault"] and values["ds402_state"] == "Fault", values
    # Enable does not reset a fault: it fails, saying where the drive is stuck and why.
    refused = ros.call(Trigger, "enable")
    assert not refused.success and "Fault" in refused.message and "reset_fault" in refused.message, refused

    ros.trigger("reset_fault")
    assert sim.state()["fault"] is None
    ros.spin_until(lambda: status().level == DiagnosticStatus.OK, "OK on /diagnostics after the reset")


def test_a_latch_event_arrives_after_the_input_edge(ros, sim):
    ready(ros, sim, "interpolated_position")
    edge_counts = latch_across(ros, sim, 0.5)
    latch = ros.received[NODE + "latch"][-1]
    assert (latch.joint, latch.channel, latch.edge) == (JOINT, 1, LatchEvent.EDGE_RISING)
    assert abs(latch.position_counts - edge_counts) <= 1, (latch.position_counts, edge_counts)
    assert latch.position == pytest.approx(latch.position_counts / COUNTS_PER_RAD, abs=1e-9)
    sim.command("toggles 0 1")


def test_drive_status_and_the_services_round_trip_with_the_node(ros, sim):
    ready(ros, sim, "interpolated_position")
    status = ros.latest(NODE + "status")
    assert (status.joint, status.ds402_state, status.mode) == (JOINT, "operation_enabled", "interpolated_position")
    assert status.mode_of_operation == 7 and status.statusword & 0x6F == 0x27
    assert status.cycles > 0 and 0 < status.period_mean < 0.01 and status.period_max >= status.period_mean
    response = ros.call(SdoRead, "sdo_read", SdoRead.Request(index=0x6061, subindex=0))
    assert response.success and list(response.data) == [7], response
    response = ros.call(SetMode, "set_mode", SetMode.Request(mode="cyclic_synchronous_velocity"))
    assert not response.success and "interpolated_position" in response.message
    response = ros.call(SdoWrite, "sdo_write", SdoWrite.Request(index=0x5FFF, subindex=0, data=[1, 2]))
    assert not response.success and response.message.startswith("0x5FFF:00: "), response


def test_bad_commands_are_refused_and_the_axis_stays_still(ros, sim, node):
    ready(ros, sim, "interpolated_position")
    before = sim.state()["position"]
    ros.stream("position", [math.nan, MAX_POSITION * 2, -MAX_POSITION * 2] * 5)
    ros.stream("velocity", [1.0] * 5)
    ros.stream("torque", [0.5] * 5)
    ros.spin_for(0.5)
    assert abs(sim.state()["position"] - before) <= 2, "the axis moved"
    log = node.output()
    for what in (
        "position command refused: position must be a finite number",
        "beyond the limit max_position",
        "beyond the limit min_position",
        "velocity command refused",
        "torque command refused",
    ):
        assert what in log, f"no warning with {what!r} in:\n{log}"


def test_sigterm_disables_the_drive_and_exits_0(ros, sim, node):
    ready(ros, sim, "interpolated_position")
    node.process.send_signal(signal.SIGTERM)
    assert node.process.wait(timeout=WAIT_S) == 0, node.output()
    # The simulator answers queries only while a master sends frames: a fresh master looks at what the node left.
    from akd_ros import Master

    master = Master(f"udp://127.0.0.1:{sim.port}")
    try:
        assert master.scan()[0]["found_al_state"] == "Init"
        master.request_state("preop")
        statusword = int.from_bytes(master.sdo_read(0, 0x6041, 0), "little")
    finally:
        master.close()
    # Switch on disabled; a drive left enabled would show Fault (F125 after eight missed frames).
    assert statusword & 0x6F == 0x40, hex(statusword)


SECOND_PARAMS = """\
akd_node:
  ros__parameters:
    link: udp://127.0.0.1:{{port}}
    cycle_time: 0.002
    # As an integrator runs it: the cycle thread under SCHED_FIFO where permitted (else a warning).
    rt.priority: 30
    mode: profile_velocity
    joint_name: {joint}
    joint_states_rate: 50.0
    fault_reset: auto_once
    command_timeout: 1.0
    command_timeout_policy: quick_stop
    enable_on_start: true
    record.enabled: true
    record.folder: {bags}
    record.decimation: 10
"""
SECOND_DOMAIN_OFFSET = 10


@pytest.fixture
def second(tmp_path, ros_domain):
    """Another simulator and node (auto_once fault reset, quick stop on a stopped command stream, enabled at
    start-up), with a client of its own, on a domain of its own so the module's node is not seen."""
    params = SECOND_PARAMS.format(joint=JOINT, bags=tmp_path / "bags")
    with node_on_sim(params, tmp_path, ros_domain + SECOND_DOMAIN_OFFSET) as (simulator, process, client):
        yield simulator, process, client, tmp_path / "bags"


def test_quick_stop_on_a_stopped_stream_and_a_fault_reset_once_by_itself_all_recorded(second):
    sim, node, ros, bags = second
    ros.spin_until(lambda: "enable_on_start: Operation enabled" in node.output(), "enable at start-up")
    ros.stream("velocity", [3.0] * 25)
    assert ros.latest("/joint_states").velocity[0] == pytest.approx(3.0, rel=0.05)
    # The stream stops: after command_timeout the node quick-stops the axis.
    ros.spin_until(lambda: "quick stop; call ~/enable to go on" in node.output(), "quick stop on the time-out")
    assert sim.state()["state"] == "Quick stop active"
    ros.trigger("enable")
    sim.command("fault 0 F235")
    ros.spin_until(lambda: any("F235" in f.text for f in ros.received[NODE + "fault"]), "DriveFault F235")
    # auto_once resets the fault and leaves the drive disabled.
    ros.spin_until(lambda: "fault_reset auto_once: fault reset" in node.output(), "the fault reset by the node")
    assert sim.state()["fault"] is None and sim.state()["state"] == "Switch on disabled"

    stop(node.process)
    assert node.process.returncode == 0, node.output()
    (bag,) = bags.iterdir()
    from rosbags.highlevel import AnyReader

    with AnyReader([bag]) as reader:
        counts = {c.topic: c.msgcount for c in reader.connections}
        faults = [reader.deserialize(raw, c.msgtype) for c, _, raw in reader.messages() if c.topic == NODE + "fault"]
    assert set(counts) == {
        "/joint_states",
        "/diagnostics",
        NODE + "status",
        NODE + "latch",
        NODE + "fault",
        NODE + "position_command",
        NODE + "velocity_command",
        NODE + "torque_command",
        NODE + "joint_commands",
        NODE + "joint_trajectory",
        NODE + "trajectory_status",
        NODE + "io",
        NODE + "cycle",
        NODE + "black_box",
    }, counts
    assert counts["/joint_states"] > 10 and counts[NODE + "cycle"] > 10 and counts[NODE + "black_box"] > 10
    assert counts[NODE + "velocity_command"] == 25, counts
    assert any("F235" in f.text for f in faults)


FIXED_CSP_PARAMS = """\
akd_node:
  ros__parameters:
    link: udp://127.0.0.1:{port}
    cycle_time: 0.002
    # As an integrator runs it: the cycle thread under SCHED_FIFO where permitted (else a warning).
    rt.priority: 30
    mode: cyclic_synchronous_position
    mapping: 0x1724/0x1B26
    joint_name: test_axis
    joint_states_rate: 50.0
    enable_on_start: true
"""


def test_a_fixed_mapping_without_velocity_or_torque_targets_runs_with_the_time_out_unwatched(tmp_path, ros_domain):
    """The fixed CSP mapping carries no 0x60FF/0x6071, so the cycle thread cannot watch a velocity or torque stream:
    the node says so once and runs; position commands need no time-out."""
    with node_on_sim(FIXED_CSP_PARAMS, tmp_path, ros_domain + SECOND_DOMAIN_OFFSET) as (_sim, node, ros):
        ros.spin_until(lambda: "enable_on_start: Operation enabled" in node.output(), "enable at start-up")
        assert "parameter command_timeout: not watched" in node.output()
        assert "0x60FF" in node.output()
        move_to(ros, ros.position() + 0.5)


# The first node's parameters (its {port} left for node_on_sim) with distributed clocks on, `on` unquoted.
DC_PARAMS = (
    PARAMS.format(port="{port}", joint=JOINT, max_position=MAX_POSITION, rate=JOINT_STATES_RATE)
    + "    dc: on\n    dc_shift: -0.0002\n"
)


def test_stopping_after_the_drives_vanished_says_so_in_one_line_and_exits_0(tmp_path, ros_domain):
    from support.netns import free_udp_port

    sim = Sim(free_udp_port())
    path = tmp_path / "akd_node.yaml"
    path.write_text(PARAMS.format(port=sim.port, joint=JOINT, max_position=MAX_POSITION, rate=JOINT_STATES_RATE))
    node = NodeProcess(path, ros_domain + SECOND_DOMAIN_OFFSET)
    try:
        deadline = time.monotonic() + WAIT_S
        while "active: publishing" not in node.output():
            assert node.process.poll() is None and time.monotonic() < deadline, node.output()
            time.sleep(0.05)
    finally:
        sim.stop()  # the drive's power and cable gone at once
    time.sleep(0.5)
    stop(node.process)
    output = node.output()
    assert node.process.returncode == 0, output
    assert "Traceback" not in output and "the line did not go back to Init" in output, output


def test_dc_on_over_udp_runs_sync0_at_the_cycle_time_and_diagnostics_show_it(tmp_path, ros_domain):
    """`dc: on` (unquoted, which YAML reads as a bool) switches distributed clocks on over UDP, where 'auto' would
    not: the virtual AKD runs SYNC0 at the cycle time, moved by dc_shift, with FBUS.PARAM02 = 1 and its PLL locked."""
    with node_on_sim(DC_PARAMS, tmp_path, ros_domain + SECOND_DOMAIN_OFFSET) as (sim, _node, ros):
        dc = sim.state()["dc"]
        assert dc["sync0_active"] and dc["pll_locked"] and dc["source"] == "sync0", dc
        assert (dc["sync0_cycle_ns"], dc["cycle_ns"], dc["fbus_param02"]) == (2_000_000, 2_000_000, 1), dc
        assert dc["sync0_start_ns"] % 2_000_000 == 1_800_000, dc
        values = {v.key: v.value for v in ros.latest("/diagnostics").status[0].values}
        assert (values["dc"], values["dc_cycle_s"], values["dc_shift_s"]) == ("on (SYNC0)", "0.002", "-0.0002")
        assert (values["fbus_param02"], values["dc_reference_slave"]) == ("1", "0"), values
        # Read in the cyclic frame from the first cycles on; the only drive is the reference clock itself.
        assert abs(int(values["system_time_difference_ns"])) < 1_000_000, values


def test_an_unknown_fbus_param02_warns_to_set_it_on_the_drive() -> None:
    """The master writes FBUS.PARAM02 only where the drive's SDO information names the object so, and leaves it
    unknown (None) elsewhere (native/tests/distributed_clocks.rs: a drive without the object, one naming it
    otherwise); /diagnostics then warns and says what to do on the drive."""
    with Axis("sim:2?missed=lost", dc=True) as axis:
        dc = axis.cycle.dc_status()
    assert not fbus_param02_unknown(dc, 0) and dc_values(dc, 0)["fbus_param02"] == 1
    unknown = {**dc, "drives": [{**dc["drives"][0], "fbus_param02": None}, dc["drives"][1]]}
    assert fbus_param02_unknown(unknown, 0) and not fbus_param02_unknown(unknown, 1)
    advice = dc_values(unknown, 0)["fbus_param02"]
    assert "not confirm" in advice and "set FBUS.PARAM02 = 1 on the drive (WorkBench)" in advice, advice
    assert not fbus_param02_unknown({"active": False}, 0)
