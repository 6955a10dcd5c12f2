"""akd_node's bags (record.*), made by the running node against a virtual AKD and read by third-party readers.

One recorded run with a latch and a fault, stopped by SIGINT, is read back with rosbags' AnyReader and with mcap's
reader (messages decoded by rclpy's deserialize_message), and compared with what this process received from and sent
to the node over ROS; akd-plot draws it. A second run is killed with SIGKILL while recording, and a third records into
a folder that cannot be made. The node is `.venv/bin/akd_node` on an `akd-sim --udp` process (tests/support/ros.py);
every wait is bounded and both processes are ended in teardown.
"""

from __future__ import annotations

import importlib
import itertools
import json
import os
import signal
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

import pytest
import yaml
from mcap.exceptions import EndOfFile
from mcap.reader import NonSeekingReader, make_reader
from rclpy.serialization import deserialize_message
from rosbags.highlevel import AnyReader, AnyReaderError
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

from akd_ros.units import Units
from support.netns import free_udp_port
from support.ros import (
    BIN,
    COUNTS_PER_RAD,
    NODE,
    NODE_TOPICS,
    WAIT_S,
    Sim,
    akd_plot,
    latch_across,
    move_to,
    node_on_sim,
    ready,
    ros_environment,
)

REPO = Path(__file__).resolve().parents[1]
# ROS_DOMAIN_IDs of this module, apart from test_messages' (100-200), test_node's (201-220) and test_node_params'
# (221-230); each run below takes its own domain, RUN_DOMAIN_STEP apart.
DOMAINS = range(60, 70)
RUN_DOMAIN_STEP = 10
CYCLE_TIME = 0.002
BLACK_BOX_SECONDS = 1.0
CYCLE, BLACK_BOX = NODE + "cycle", NODE + "black_box"
COMMAND_TOPICS = {kind: f"{NODE}{kind}_command" for kind in ("position", "velocity", "torque")}
# The commands by joint name and the trajectories are recorded too, although this run sends none.
RECORDED_TOPICS = {
    *NODE_TOPICS,
    *COMMAND_TOPICS.values(),
    NODE + "joint_commands",
    NODE + "joint_trajectory",
    CYCLE,
    BLACK_BOX,
}
F439_CODE = 0x8611

PARAMS = """\
akd_node:
  ros__parameters:
    link: udp://127.0.0.1:{{port}}
    cycle_time: {cycle_time}
    # As an integrator runs it: the cycle thread under SCHED_FIFO where permitted (else a warning).
    rt.priority: 30
    mode: interpolated_position
    joint_name: recorded_axis
    joint_states_rate: 50.0
    status_rate: 10.0
    diagnostics_rate: 5.0
    record.enabled: true
    record.folder: {folder}
    record.decimation: 1
    record.black_box_seconds: {black_box_seconds}
"""


def params(folder: Path) -> str:
    """The node's parameters file (a node_on_sim template) recording every cycle into `folder`."""
    return PARAMS.format(cycle_time=CYCLE_TIME, folder=folder, black_box_seconds=BLACK_BOX_SECONDS)


@pytest.fixture(scope="module")
def ros_domain():
    """A ROS_DOMAIN_ID of this module's own, discovery on localhost, Fast DDS; set for the module."""
    with ros_environment(DOMAINS) as domain:
        yield domain


def stamp_ns(stamp) -> int:
    """A builtin_interfaces/Time (rclpy's or rosbags') in nanoseconds."""
    return stamp.sec * 1_000_000_000 + stamp.nanosec


@dataclass
class FaultRun:
    """A recorded run and what the client saw of it."""

    bag: Path
    received: dict
    sent: dict
    type_hashes: dict
    """The RIHS01 hash each topic's live endpoint on the node offered (its publisher or its subscription)."""
    edge_counts: int
    """Where the simulated input of latch 1 rose."""
    output: str


@pytest.fixture(scope="module")
def fault_run(ros_domain, tmp_path_factory) -> FaultRun:
    """The node recording every cycle: enabled, moved across an input toggle so latch 1 fires, refused velocity
    and torque commands, F439 injected, then SIGINT."""
    folder = tmp_path_factory.mktemp("fault_run")
    with node_on_sim(params(folder / "bags"), folder, ros_domain) as (sim, node, ros):
        # Every topic matched before anything happens, so the client sees every event the node records.
        hashes = {}
        for topic in NODE_TOPICS:
            ros.spin_until(
                lambda topic=topic: ros.node.get_publishers_info_by_topic(topic), f"the node's publisher of {topic}"
            )
            hashes[topic] = str(ros.node.get_publishers_info_by_topic(topic)[0].topic_type_hash)
        for topic in COMMAND_TOPICS.values():
            ros.spin_until(
                lambda topic=topic: ros.node.get_subscriptions_info_by_topic(topic),
                f"the node's subscription of {topic}",
            )
            hashes[topic] = str(ros.node.get_subscriptions_info_by_topic(topic)[0].topic_type_hash)

        ready(ros, sim, "interpolated_position")
        # Between two of move_to's steps, where the axis passes rather than settles.
        edge_counts = latch_across(ros, sim, 0.51)
        # Refused (interpolated_position is active) yet recorded: the bag keeps every command received.
        ros.stream("velocity", [0.5] * 3)
        ros.stream("torque", [0.1] * 2)
        sim.command("fault 0 F439")
        ros.spin_until(lambda: any(f.code == F439_CODE for f in ros.received[NODE + "fault"]), "DriveFault F439")
        # Whatever else the fault brings (the emergency beside the Fault state) arrives too.
        ros.spin_for(1.0)
        node.process.send_signal(signal.SIGINT)
        ros.spin_until(lambda: node.process.poll() is not None, "akd_node's exit on SIGINT")
        assert node.process.returncode == 0, node.output()
        ros.spin_for(0.5)
        (bag,) = (folder / "bags").iterdir()
        return FaultRun(
            bag,
            {topic: list(messages) for topic, messages in ros.received.items()},
            dict(ros.sent),
            hashes,
            edge_counts,
            node.output(),
        )


def rosbags_messages(bag: Path) -> tuple[dict, dict]:
    """(topic: message count, topic: [(time_ns, message)]) of a bag through rosbags' AnyReader, which decodes with
    the bag's own schemas."""
    with AnyReader([bag], default_typestore=get_typestore(Stores.ROS2_JAZZY)) as reader:
        counts = {c.topic: c.msgcount for c in reader.connections}
        messages: dict = {topic: [] for topic in counts}
        for connection, time_ns, raw in reader.messages():
            messages[connection.topic].append((time_ns, reader.deserialize(raw, connection.msgtype)))
    return counts, messages


def rclpy_class(type_name: str) -> type:
    """The rclpy message class of a bag's type name, e.g. 'akd_ros/msg/LatchEvent'."""
    package, kind, name = type_name.split("/")
    return getattr(importlib.import_module(f"{package}.{kind}"), name)


def mcap_messages(bag: Path) -> tuple[dict, dict]:
    """(topic: channel metadata, topic: [(log_time, rclpy message)]) of a bag's MCAP files through mcap's reader,
    each message decoded by rclpy's deserialize_message into the class its schema names."""
    channels: dict = {}
    messages: dict = {}
    for path in sorted(bag.glob("*.mcap")):
        with open(path, "rb") as stream:
            reader = make_reader(stream)
            assert reader.get_header().profile == "ros2"
            for schema, channel, message in reader.iter_messages(log_time_order=False):
                assert (schema.encoding, channel.message_encoding) == ("ros2msg", "cdr"), (schema, channel)
                channels[channel.topic] = dict(channel.metadata)
                decoded = deserialize_message(message.data, rclpy_class(schema.name))
                messages.setdefault(channel.topic, []).append((message.log_time, decoded))
    return channels, messages


def metadata(bag: Path) -> dict:
    """metadata.yaml's rosbag2_bagfile_information."""
    return yaml.safe_load((bag / "metadata.yaml").read_text())["rosbag2_bagfile_information"]


def test_rosbags_reads_every_topic_with_the_counts_sent_and_received_live(fault_run):
    counts, messages = rosbags_messages(fault_run.bag)
    assert set(counts) == RECORDED_TOPICS, sorted(counts)
    for kind, topic in COMMAND_TOPICS.items():
        assert counts[topic] == fault_run.sent[kind], (topic, counts[topic], fault_run.sent)
    assert [m.data for _, m in messages[COMMAND_TOPICS["velocity"]]] == [0.5] * 3
    for topic in (NODE + "latch", NODE + "fault"):
        assert counts[topic] == len(fault_run.received[topic]), (topic, counts[topic], fault_run.received[topic])
    # Periodic topics: the bag has every message the client got (it may have more, from before the client matched).
    for topic in ("/joint_states", "/diagnostics", NODE + "status"):
        recorded = {time_ns for time_ns, _ in messages[topic]}
        live = {stamp_ns(m.header.stamp) for m in fault_run.received[topic]}
        assert live and live <= recorded, (topic, len(live - recorded))
    # The axis may cross the edge more than once while it settles: every capture is an event.
    latches = fault_run.received[NODE + "latch"]
    assert latches and len(messages[NODE + "latch"]) == len(latches)
    for latch, (time_ns, recorded) in zip(latches, messages[NODE + "latch"], strict=True):
        assert time_ns == stamp_ns(latch.header.stamp) == stamp_ns(recorded.header.stamp)
        assert (recorded.position, recorded.position_counts, recorded.channel, recorded.edge) == (
            latch.position,
            latch.position_counts,
            latch.channel,
            latch.edge,
        )
        assert abs(recorded.position_counts - fault_run.edge_counts) <= 1, (recorded, fault_run.edge_counts)
    faults = [m for _, m in messages[NODE + "fault"] if m.code == F439_CODE]
    assert faults and all("F439" in f.text for f in faults), faults
    info = metadata(fault_run.bag)
    assert {t["topic_metadata"]["name"]: t["message_count"] for t in info["topics_with_message_count"]} == counts
    assert info["message_count"] == sum(counts.values())
    # The node's own account at the close: everything handed to the recorder is in the bag.
    assert (
        f"recorded {fault_run.bag}: {sum(counts.values())} messages, 0 dropped, {counts[NODE + 'fault']} black "
        "box dumps, 0 errors"
    ) in fault_run.output


def test_every_cycle_is_recorded_with_consecutive_cycle_numbers(fault_run):
    _, messages = rosbags_messages(fault_run.bag)
    cycles = [m.cycle for _, m in messages[CYCLE]]
    assert len(cycles) > 1000, len(cycles)
    assert cycles == list(range(cycles[0], cycles[0] + len(cycles))), "a cycle is missing or repeated"
    times = [time_ns for time_ns, _ in messages[CYCLE]]
    assert all(a < b for a, b in itertools.pairwise(times))
    assert all(time_ns == stamp_ns(m.stamp) for time_ns, m in messages[CYCLE])
    # The recorded cycles are the drive's: Operation enabled (0x27 in the low bits) while moving, in mode 7.
    assert any(m.statusword & 0x6F == 0x27 and m.mode_of_operation == 7 for _, m in messages[CYCLE])


def test_the_black_box_ends_at_the_fault_and_holds_black_box_seconds_of_cycles(fault_run):
    _, messages = rosbags_messages(fault_run.bag)
    fault_ns = min(time_ns for time_ns, m in messages[NODE + "fault"] if m.code == F439_CODE)
    # The cycles of the BLACK_BOX_SECONDS up to the fault, whether this fault or an earlier one (a lost frame is a
    # fault too) wrote them: exactly those the cycle topic (every cycle) has in that window, the same samples.
    window = (fault_ns - round(BLACK_BOX_SECONDS * 1e9), fault_ns)
    dump = [(time_ns, m) for time_ns, m in messages[BLACK_BOX] if window[0] < time_ns <= window[1]]
    cycles = [(time_ns, m) for time_ns, m in messages[CYCLE] if window[0] < time_ns <= window[1]]
    assert len(dump) > 100, len(dump)
    assert [m.cycle for _, m in dump] == [m.cycle for _, m in cycles], "the black box differs from the cycles"
    assert dump == cycles
    # The window was full: the cycle topic has cycles before it, and the next cycle after the black box's last is
    # after the fault, so the black box ends at the fault's cycle or the one before.
    assert messages[CYCLE][0][0] <= window[0]
    following = [time_ns for time_ns, m in messages[CYCLE] if m.cycle == dump[-1][1].cycle + 1]
    assert following and following[0] > fault_ns - 1_000_000, (following, fault_ns)
    assert len({m.cycle for _, m in messages[BLACK_BOX]}) == len(messages[BLACK_BOX]), "a sample written twice"
    # The black box shows the drive in Operation enabled before the fault.
    assert dump[0][1].statusword & 0x6F == 0x27, hex(dump[0][1].statusword)


def test_mcap_reads_the_same_messages_which_rclpy_decodes_equal_to_those_received(fault_run):
    channels, messages = mcap_messages(fault_run.bag)
    counts, _ = rosbags_messages(fault_run.bag)
    # Read message by message, mcap sees the channels that have messages: all but those this run sent nothing on.
    assert set(channels) == RECORDED_TOPICS - {
        NODE + "joint_commands",
        NODE + "joint_trajectory",
        NODE + "trajectory_status",
    }
    assert {topic: len(m) for topic, m in messages.items()} == {topic: n for topic, n in counts.items() if n}
    for topic in (NODE + "latch", NODE + "fault"):
        assert [m for _, m in messages[topic]] == fault_run.received[topic], topic
    recorded = dict(messages["/joint_states"])
    for message in fault_run.received["/joint_states"]:
        assert recorded[stamp_ns(message.header.stamp)] == message


def test_type_hashes_agree_between_metadata_mcap_the_live_node_and_the_message_definitions(fault_run):
    info = metadata(fault_run.bag)
    channels, _ = mcap_messages(fault_run.bag)
    store = get_typestore(Stores.ROS2_JAZZY)
    for path in sorted((REPO / "msg").glob("*.msg")):
        store.register(get_types_from_msg(path.read_text(), f"akd_ros/msg/{path.stem}"))
    for entry in info["topics_with_message_count"]:
        topic = entry["topic_metadata"]
        name, type_hash = topic["name"], topic["type_description_hash"]
        if name in channels:
            assert channels[name]["topic_type_hash"] == type_hash, name
            assert yaml.safe_load(channels[name]["offered_qos_profiles"]) == topic["offered_qos_profiles"], name
        else:  # mcap_messages sees a channel through its messages
            assert entry["message_count"] == 0, entry
        # RIHS01 computed by rosbags from the .msg definitions, independently of the type support's own.
        assert store.hash_rihs01(topic["type"]) == type_hash, name
        if name in fault_run.type_hashes:
            assert fault_run.type_hashes[name] == type_hash, name


def test_akd_plot_draws_the_fault_run(fault_run, tmp_path):
    picture = tmp_path / "fault.png"
    done = akd_plot(str(fault_run.bag), "-o", str(picture))
    assert done.returncode == 0, done.stderr
    assert picture.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert picture.stat().st_size > 20_000


def test_a_bag_of_a_sigkilled_node_is_readable_up_to_its_last_chunk_and_reindexed(ros_domain, tmp_path):
    with node_on_sim(params(tmp_path / "bags"), tmp_path, ros_domain + RUN_DOMAIN_STEP) as (sim, node, ros):
        ready(ros, sim, "interpolated_position")
        # Over a second of motion, so chunks have been closed (record flush interval: 1 s).
        move_to(ros, ros.position() + 2.0, seconds=3.0)
        node.process.kill()
        node.process.wait(timeout=WAIT_S)
    (bag,) = (tmp_path / "bags").iterdir()
    (path,) = bag.glob("*.mcap")
    counted = metadata(bag)["message_count"]

    cycles, read = [], 0
    with open(path, "rb") as stream:
        try:
            for schema, channel, message in NonSeekingReader(stream).iter_messages(log_time_order=False):
                read += 1
                if channel.topic == CYCLE:
                    cycles.append(deserialize_message(message.data, rclpy_class(schema.name)).cycle)
        except EndOfFile:  # the chunk being written at the kill
            pass
    assert len(cycles) > 500, len(cycles)
    assert cycles == list(range(cycles[0], cycles[0] + len(cycles)))
    # metadata.yaml, rewritten at each closed chunk, claims nothing the file does not hold.
    assert 0 < counted <= read, (counted, read)

    with pytest.raises(AnyReaderError), AnyReader([bag]) as reader:
        list(reader.messages())
    # The documented way (docs/howto/recording.md), then the picture of what was saved.
    subprocess.run(
        [sys.executable, "-c", f"from akd_ros.recorder import reindex; reindex({str(bag)!r})"], check=True, timeout=120
    )
    counts, messages = rosbags_messages(bag)
    assert [m.cycle for _, m in messages[CYCLE]] == cycles
    assert metadata(bag)["message_count"] == sum(counts.values()) == read
    picture = tmp_path / "killed.png"
    subprocess.run([str(BIN / "akd-plot"), str(bag), "-o", str(picture)], check=True, timeout=120)
    assert picture.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_an_unwritable_folder_is_reported_once_and_the_node_runs_on(ros_domain, tmp_path):
    blocker = tmp_path / "a_file"
    blocker.write_text("not a folder")
    folder = blocker / "bags"
    with node_on_sim(params(folder), tmp_path, ros_domain + 2 * RUN_DOMAIN_STEP) as (sim, node, ros):
        ready(ros, sim, "interpolated_position")
        target = ros.position() + 1.0
        move_to(ros, target)
        assert abs(sim.state()["position"] - target * COUNTS_PER_RAD) < 1e-3 * COUNTS_PER_RAD
        count = len(ros.received["/joint_states"])
        ros.spin_for(1.0)
        # 50 Hz: the range only tells publishing from not publishing.
        assert len(ros.received["/joint_states"]) - count >= 25
        assert node.process.poll() is None
        output = node.output()
    assert output.count("Not a directory") == 1 and "recording stopped: cannot open bag" in output, output
    assert not folder.exists()


STALLED_RECORDER = """
import json, sys, threading, time
import rclpy
from rclpy.executors import SingleThreadedExecutor
from rclpy.parameter import Parameter
from std_msgs.msg import Float64
from akd_ros.node.lifecycle import AkdNode
from akd_ros.node.threads import hold_gil_briefly

port, folder, hold_s, commands = int(sys.argv[1]), sys.argv[2], float(sys.argv[3]), int(sys.argv[4])
rclpy.init()
hold_gil_briefly()
node = AkdNode(args=[], parameter_overrides=[
    Parameter("link", value=f"udp://127.0.0.1:{port}"),
    Parameter("cycle_time", value=0.0005),
    Parameter("mode", value="cyclic_synchronous_position"),
    Parameter("enable_on_start", value=True),
    Parameter("record.enabled", value=True),
    Parameter("record.folder", value=folder),
    Parameter("record.decimation", value=1),
])
executor = SingleThreadedExecutor()
executor.add_node(node)
threading.Thread(target=executor.spin, daemon=True).start()
from rclpy.lifecycle import TransitionCallbackReturn
for step in (node.trigger_configure, node.trigger_activate):
    assert step() == TransitionCallbackReturn.SUCCESS, node.failure
client = rclpy.create_node("stall_client")
commands_topic = client.create_publisher(Float64, "/akd_node/position_command", 100)
deadline = time.monotonic() + 10
while commands_topic.get_subscription_count() == 0 and time.monotonic() < deadline:
    time.sleep(0.05)
axis = node.bus.axes[0]
here = axis.state().position
# The disk stalls: the recorder's writer is held for hold_s, longer than the cycle keeps its records.
node.recorder.hold(True)
time.sleep(1.0)
sent = []
for k in range(commands):
    value = here + (k + 1) * 1e-4
    sent.append((time.time_ns(), value))
    commands_topic.publish(Float64(data=value))
    time.sleep((hold_s - 1.0) / commands)
dropped_while_held = node.bus.stats()["samples_dropped"]
node.recorder.hold(False)
time.sleep(0.5)
node.trigger_deactivate()
recorder = node.recorder
node.trigger_shutdown()
stats = recorder.stats
print(json.dumps({
    "sent": sent, "units_offset": axis.units.offset, "si_per_count": axis.units.si_per_count,
    "samples_dropped": dropped_while_held, "recorder_dropped": stats.dropped, "written": stats.written,
    "errors": stats.errors, "bag": str(recorder.bag_path),
}))
executor.shutdown()
client.destroy_node()
node.destroy_node()
rclpy.shutdown()
"""

COMMAND_BOUND_S = 0.05
"""How long a command may take to reach the wire while the recorder is stalled: generous against the cycle (0.5 ms)
and DDS (about 1 ms), far below the stall (6 s) it must not wait for."""


def test_a_stalled_recorder_costs_counted_records_and_never_delays_a_command(ros_domain, tmp_path):

    trace = tmp_path / "setpoints.jsonl"
    sim = Sim(free_udp_port(), setpoint_trace=trace)
    try:
        done = subprocess.run(
            [sys.executable, "-c", STALLED_RECORDER, str(sim.port), str(tmp_path / "bags"), "6.0", "40"],
            capture_output=True,
            text=True,
            timeout=120,
            env={**os.environ, "ROS_DOMAIN_ID": str(ros_domain + 3 * RUN_DOMAIN_STEP)},
        )
    finally:
        sim.stop()
    assert done.returncode == 0, done.stdout + done.stderr
    run = json.loads(done.stdout.strip().splitlines()[-1])
    units = Units(offset=run["units_offset"])
    assert units.si_per_count == run["si_per_count"]
    # When akd-sim received the first frame carrying each command's value as the drive's target position.
    lines = [json.loads(line) for line in trace.read_text().splitlines()]
    arrived = {
        line["target_position"]: line["realtime_ns"]
        for line in reversed(lines[:-1])
        if "target_position" in line.get("changed", [])
    }
    late = [
        (value, (arrived[units.position_to_counts(value)] - sent_ns) * 1e-9)
        if units.position_to_counts(value) in arrived
        else (value, None)
        for sent_ns, value in run["sent"]
    ]
    assert all(seconds is not None and seconds < COMMAND_BOUND_S for _, seconds in late), late
    # The stall shows as records lost and counted: the cycle keeps 8192 records a drive (4 s at 2 kHz), the writer
    # took none for 6 s.
    assert run["samples_dropped"] > 0, run
    assert run["errors"] == 0
    # What was taken is in the bag, every message of it readable.
    counts, _ = rosbags_messages(Path(run["bag"]))
    assert sum(counts.values()) == metadata(Path(run["bag"]))["message_count"] == run["written"]
