"""`_native.Feed` and `_native.diagnostic_array`: the message bodies the crate makes for the node, and the records it
hands a recorder without Python.

The bytes are what rclpy would publish for the same message: rclpy deserialises them into its own classes with the
values the drives show (`Bus.states`, `Cycle.drive_status`, `Cycle.stats`), and rosbags, which writes CDR's padding as
zeros where Fast CDR leaves it unwritten, writes them back byte for byte. A feed recording into a `Recorder` gives a
bag that rosbags reads whole: every cycle of every joint, and every /joint_states message the feed made.
"""

from __future__ import annotations

import math
import time

import pytest
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rclpy.serialization import deserialize_message
from rosbags.highlevel import AnyReader
from rosbags.typesys import Stores, get_types_from_msg, get_typestore
from sensor_msgs.msg import JointState

from akd_ros import Bus, DriveConfig, Units, _native
from akd_ros.msg import DriveStatus
from akd_ros.recorder import Recorder, message_type
from support.waiting import wait_for

DRIVES = [
    DriveConfig(slave=0, name="shoulder", mode="cyclic_synchronous_position", units=Units(gear_ratio=3.0, offset=-0.5)),
    DriveConfig(slave=1, name="wrist", mode="profile_velocity", units=Units(direction=-1)),
]
NS = 1_000_000_000


def rosbags_bytes(data: bytes, type_name: str, cls) -> bytes:
    """`data` as rosbags writes the message it reads from it (CDR's padding as zeros)."""
    store = get_typestore(Stores.ROS2_JAZZY)
    store.register(get_types_from_msg(message_type(cls).definition, type_name))
    return bytes(store.serialize_cdr(store.deserialize_cdr(data, type_name), type_name))


def stamp_ns(message) -> int:
    return message.header.stamp.sec * NS + message.header.stamp.nanosec


@pytest.fixture(scope="module")
def bus():
    with Bus("sim:2?missed=lost", DRIVES) as b:
        b.enable()
        shoulder, wrist = b.axes
        shoulder.command_position(shoulder.state().position + 0.3)
        wrist.command_velocity(1.5)
        yield b


def feed_of(bus: Bus) -> _native.Feed:
    """A feed of `bus`'s joints, the first homed by its drive (never, here), the others not homed at all."""
    return _native.Feed(bus.cycle, [(a.slave, a.name, a.units, k == 0) for k, a in enumerate(bus.axes)])


def take_until(feed: _native.Feed, streams: set[int], timeout: float = 10.0) -> dict[int, list[bytes]]:
    """What `feed` makes until every stream of `streams` has given a message."""
    got: dict[int, list[bytes]] = {}
    deadline = time.monotonic() + timeout
    while not streams <= got.keys():
        assert time.monotonic() < deadline, f"no message of streams {streams - got.keys()}"
        for stream, data in feed.take(0.2)[0]:
            got.setdefault(stream, []).append(data)
    return got


def test_joint_states_and_statuses_are_what_rclpy_reads_with_the_drives_values(bus: Bus) -> None:
    feed = feed_of(bus)
    states = feed.add_joint_states(0.01)
    statuses = [feed.add_drive_status(k, 0.02) for k in range(2)]
    with pytest.raises(ValueError, match="period must be a finite number of seconds > 0, not 0"):
        feed.add_joint_states(0.0)
    with pytest.raises(ValueError, match="no joint 2: the feed has 2"):
        feed.add_drive_status(2, 0.1)
    offset = 1_733_000_000 * NS
    feed.set_offset(offset)
    feed.start()
    with pytest.raises(ValueError, match=r"add its streams before start\(\)"):
        feed.add_joint_states(0.01)
    try:
        assert feed.take(0.1) == ([], False), "an inactive feed makes nothing"
        feed.set_active(True)
        got = take_until(feed, {states, *statuses})
        before = time.monotonic_ns() + offset
    finally:
        feed.stop()
    data = got[states][-1]
    message = deserialize_message(data, JointState)
    assert rosbags_bytes(data, "sensor_msgs/msg/JointState", JointState) == data
    assert list(message.name) == ["shoulder", "wrist"]
    assert len(message.position) == len(message.velocity) == len(message.effort) == 2
    assert before - 5 * NS < stamp_ns(message) <= before
    now = bus.states()
    assert message.position[0] == pytest.approx(now["shoulder"].position, abs=1e-3)
    assert message.velocity[1] == pytest.approx(1.5, rel=0.05)
    for k, joint in enumerate(("shoulder", "wrist")):
        data = got[statuses[k]][-1]
        status = deserialize_message(data, DriveStatus)
        assert rosbags_bytes(data, "akd_ros/msg/DriveStatus", DriveStatus) == data
        drive = bus.cycle.drive_status(k)
        assert (status.joint, status.ds402_state, status.statusword) == (
            joint,
            "operation_enabled",
            drive["statusword"],
        )
        assert (status.mode, status.mode_of_operation) == (bus[joint].mode, 8 if k == 0 else 3)
        assert 0 < status.cycles <= bus.stats()["cycles"] and status.lost_frames == 0
        assert status.period_mean == pytest.approx(bus.cycle.period, rel=0.2)
        assert math.isfinite(status.following_error)
        assert status.homed == (k == 1), "a joint its drive homes is homed once homing is attained; the others are"
    assert feed.dropped == 0
    # Stopped, it hands out nothing and does not wait.
    assert feed.take(5.0) == ([], False)


def test_the_feed_says_when_the_cycle_has_events_waiting_while_active() -> None:
    with Bus("sim:1?missed=lost", DRIVES[:1]) as bus:
        bus.enable()
        feed = feed_of(bus)
        feed.start()
        try:
            bus.simulator.inject_fault(0, "F439")
            wait_for("the fault's event", lambda: bus.cycle.events_pending)
            assert feed.take(0.1) == ([], False), "an inactive feed says nothing"
            feed.set_active(True)
            assert feed.take(5.0) == ([], True)
            # Said once until taken: Python takes the events when told, not at every look of the feed's.
            assert feed.take(0.05) == ([], False)
            assert any(e["kind"] == "fault" for e in bus.cycle.events())
            assert not bus.cycle.events_pending
        finally:
            feed.stop()


def test_diagnostic_array_is_what_rclpy_reads() -> None:
    statuses = [
        (2, "akd_node: a", "fault on a; ünïcode", "AKD slave 0", [("joint", "a"), ("statusword", "0x0218")]),
        (0, "akd_node: bus", "cycle running", "EtherCAT line sim", []),
    ]
    data = _native.diagnostic_array(-1, statuses)
    message = deserialize_message(data, DiagnosticArray)
    assert rosbags_bytes(data, "diagnostic_msgs/msg/DiagnosticArray", DiagnosticArray) == data
    assert (message.header.stamp.sec, message.header.stamp.nanosec) == (-1, NS - 1)
    expected = [
        DiagnosticStatus(
            level=bytes([level]),
            name=name,
            message=text,
            hardware_id=hardware,
            values=[KeyValue(key=k, value=v) for k, v in values],
        )
        for level, name, text, hardware, values in statuses
    ]
    assert list(message.status) == expected


def test_a_recording_feed_puts_every_cycle_and_every_message_in_the_bag(bus: Bus, tmp_path) -> None:
    feed = feed_of(bus)
    states = feed.add_joint_states(0.01)
    with Recorder(tmp_path, cycle_rate_hz=1 / bus.cycle.period, samples_per_cycle=2) as recorder:
        from akd_ros.msg import CycleSample

        recorder.add_topic("/joint_states", JointState)
        recorder.add_cycle_topic("/akd_node/cycle", CycleSample)
        recorder.take_cycles_from(feed)
        recorder.take_stream_from(feed, states, "/joint_states")
        feed.start()
        feed.set_active(True)
        published = 0
        end = time.monotonic() + 1.0
        while time.monotonic() < end:
            published += len(feed.take(0.1)[0])
        feed.stop()
    stats = recorder.stats
    assert stats.errors == 0 and stats.dropped == 0
    cycles: dict[str, list[int]] = {"shoulder": [], "wrist": []}
    joint_states = 0
    with AnyReader([recorder.bag_path]) as reader:
        for connection, _, raw in reader.messages():
            message = reader.deserialize(raw, connection.msgtype)
            if connection.topic == "/joint_states":
                joint_states += 1
            else:
                cycles[message.joint].append(message.cycle)
    assert joint_states == published >= 50
    # Every cycle of both joints since the records were first taken, each once.
    first = cycles["shoulder"][0]
    assert cycles["shoulder"] == cycles["wrist"] == list(range(first, first + len(cycles["wrist"])))
    assert len(cycles["wrist"]) > 0.5 / bus.cycle.period
