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
from akd_ros.msg import DriveIO, DriveStatus
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


def joint(axis, homes: bool = False, inputs=(), outputs=()) -> dict:
    """A joint of a feed: `axis`, homed by its drive or not, its named `inputs` and `outputs` ((name, number) each)."""
    return {
        "slave": axis.slave,
        "name": axis.name,
        "units": axis.units,
        "homes": homes,
        "inputs": list(inputs),
        "outputs": list(outputs),
        "volts_per_count": axis.analog_scale,
    }


def feed_of(bus: Bus) -> _native.Feed:
    """A feed of `bus`'s joints, the first homed by its drive (never, here), the others not homed at all."""
    return _native.Feed(bus.cycle, [joint(a, homes=k == 0) for k, a in enumerate(bus.axes)])


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
            drive.statusword,
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


def test_drive_io_reads_as_the_drive_shows_its_io_with_the_joints_names() -> None:
    drives = [
        DriveConfig(slave=0, name="gripper", mode="cyclic_synchronous_position", mapping=_native.IO_MAPPING),
        DriveConfig(slave=1, name="wrist", mode="profile_velocity"),
    ]
    with Bus("sim:2?missed=lost", drives) as bus:
        gripper, wrist = bus.axes
        with pytest.raises(ValueError, match=r"joint gripper: input x is number 9: the AKD has digital inputs 1\.\.7"):
            _native.Feed(bus.cycle, [joint(gripper, inputs=[("x", 9)])])
        bus.simulator.set_input(0, 3, True)
        bus.simulator.set_switch(0, "home_switch", True)
        bus.simulator.set_analog_input(0, -2.5)
        gripper.set_outputs({2: True}, analog_output=1.5)
        io = wait_for("the inputs and outputs", lambda: (io := gripper.io()).inputs[2] and io.outputs[1] and io)
        feed = _native.Feed(
            bus.cycle,
            [
                joint(gripper, inputs=[("part_present", 3), ("start", 1)], outputs=[("clamp", 2)]),
                joint(wrist, inputs=[("start", 1)], outputs=[("lamp", 1)]),
            ],
        )
        streams = [feed.add_drive_io(k, 0.01) for k in range(2)]
        with pytest.raises(ValueError, match="no joint 2: the feed has 2"):
            feed.add_drive_io(2, 0.1)
        feed.start()
        feed.set_active(True)
        try:
            got = take_until(feed, set(streams))
        finally:
            feed.stop()
    data = got[streams[0]][-1]
    assert rosbags_bytes(data, "akd_ros/msg/DriveIO", DriveIO) == data
    message = deserialize_message(data, DriveIO)
    assert (message.joint, message.digital_inputs_mapped, message.digital_inputs) == (
        "gripper",
        True,
        io.digital_inputs,
    )
    assert (message.home_switch, message.negative_limit, message.positive_limit, message.interlock) == (
        True,
        False,
        False,
        False,
    )
    assert list(message.inputs) == list(io.inputs)
    assert (list(message.input_names), list(message.input_numbers), list(message.named_inputs)) == (
        ["part_present", "start"],
        [3, 1],
        [True, False],
    )
    assert message.hardware_enable == DriveIO.HARDWARE_ENABLE_HIGH
    assert message.analog_input == pytest.approx(-2.5, abs=2 * gripper.analog_scale)
    assert (message.digital_outputs_mapped, list(message.outputs), list(message.named_outputs)) == (
        True,
        [False, True],
        [True],
    )
    assert message.analog_output == pytest.approx(1.5, abs=gripper.analog_scale)
    assert message.cycle >= io.cycle
    # The default mapping carries the digital inputs only: no outputs read, no output named, the analog values NaN.
    wrist_io = deserialize_message(got[streams[1]][-1], DriveIO)
    assert (wrist_io.digital_inputs_mapped, len(wrist_io.inputs), list(wrist_io.input_names)) == (True, 7, ["start"])
    assert (wrist_io.digital_outputs_mapped, list(wrist_io.outputs), list(wrist_io.output_names)) == (False, [], [])
    assert math.isnan(wrist_io.analog_input) and math.isnan(wrist_io.analog_output)


def test_an_input_change_is_handed_out_at_once_as_the_cycle_showed_it() -> None:
    drives = [DriveConfig(slave=0, name="gripper", mode="cyclic_synchronous_position", mapping=_native.IO_MAPPING)]
    with Bus("sim:1?missed=lost", drives) as bus:
        (gripper,) = bus.axes
        feed = _native.Feed(bus.cycle, [joint(gripper, inputs=[("part_present", 3)])])
        # A period far beyond the test: every DriveIO taken below is the change's own.
        io_stream, states_stream = feed.add_drive_io(0, 3600.0), feed.add_joint_states(3600.0)
        feed.start()
        try:
            # The cycle compares each cycle's inputs with the last: flipped after its first ones, the input is a change.
            start = gripper.io().cycle
            wait_for("a few cycles", lambda: gripper.io().cycle >= start + 5)
            bus.simulator.set_input(0, 3, True)
            change = wait_for("the input's change", lambda: next(iter(gripper.input_events()), None))
            edge = (io_stream, change.cycle, change.time_ns, change.digital_inputs, change.statusword)
            assert not feed.input_change(*edge), "made while inactive"
            feed.set_active(True)
            assert not feed.input_change(states_stream, *edge[1:]), "made on a stream of another kind"
            assert feed.input_change(*edge)
            (got,) = take_until(feed, {io_stream})[io_stream]
        finally:
            feed.stop()
    message = deserialize_message(got, DriveIO)
    assert (message.joint, message.cycle, stamp_ns(message)) == ("gripper", change.cycle, change.time_ns)
    assert (list(message.input_names), list(message.named_inputs)) == (["part_present"], [True])
    assert message.inputs[2] and message.digital_inputs == change.digital_inputs
    assert message.hardware_enable == DriveIO.HARDWARE_ENABLE_HIGH


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
