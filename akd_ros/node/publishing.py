"""Publishing: /joint_states (sensor_msgs/JointState, SI: every joint, all of one cycle), and per joint its status
(DriveStatus), latch (LatchEvent) and fault (DriveFault) topics, each message recorded at its stamp when recording.

How the node publishes, and where a new publication goes
--------------------------------------------------------

/joint_states and each joint's status are made by the crate (`akd_ros._native.Feed`, see `native/src/ros/feed.rs`):
from configure to cleanup a thread of the crate reads the cycle's snapshot at each stream's rate, makes the message
bodies (CDR, serialised by `cdr-encoding` from the .msg fields) and hands them out. One Python thread of this part
(`akd-publish`) waits for them with the GIL released and hands each to its publisher as bytes
(`Publisher.publish_serialized`); while recording, the crate queues the same bytes in the bag itself
(`Recorder.take_stream_from`), and the bag's writer thread takes every cycle's records from the cycle without Python
(`Recorder.take_cycles_from`). So Python wakes at the publication rates, never per cycle, and a message costs it one
publish call, whatever the message holds.

The events (latches, faults, command time-outs) stay Python's: they are rare and carry texts. The feed says when
the cycle has events waiting; this thread then takes them, publishes them, logs the faults and has the recorder write
their black box.

Each joint's ~/io (akd_ros/DriveIO, `akd_ros.node.io`) is made the same way, at io_rate, and once more at each change
of the drive's inputs: this thread hands the cycle's event of it to the feed (`Feed.input_change`), which makes that
message, stamped with the cycle that showed the change, and hands it out and records it as the periodic ones, so an
edge is neither late by a period nor lost between two; so is each device's ~/<device>/io (akd_ros/DeviceIO, at each
change of its inputs of one bit: `Feed.device_input_change`), whose losses and returns this thread logs. Another
periodic publication
is added so: its message struct and its making
from the snapshot in the crate (a `Kind` of `native/src/ros/feed.rs`; on change: compared there with what it last
made, at its stream's check rate), a `Feed.add_...` stream here in `_start_feed` with its period, and its publisher in
`self._streams` by the stream's id (recorded with `take_stream_from` when the topic is in the bag). Nothing of it runs
in Python but the publish call. A publication that must go through an rclpy API taking message objects (an action's
feedback) takes the same snapshot-derived values from the crate at its own rate and builds its message there, at that
rate, never per cycle. Any publisher made through the transport is in the live view too (`akd_ros.node.live_view`).
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable

from akd_ros import _native
from akd_ros.node.clock import nanoseconds
from akd_ros.node.node_state import NodeState, namespace
from akd_ros.node.threads import name_this_thread
from akd_ros.node.transports.transport import Qos, Transport
from akd_ros.params import JointSettings

EDGE_RISING, EDGE_FALLING = 1, 2
"""LatchEvent's edge codes (its EDGE_RISING and EDGE_FALLING constants)."""
EDGE_NAMES = {EDGE_RISING: "rising", EDGE_FALLING: "falling"}
"""Latch edges by their LatchEvent code."""
_EDGE_CODES = {name: code for code, name in EDGE_NAMES.items()}
# How long the publishing thread waits for the feed at most: how soon it sees the node closed.
_TAKE_TIMEOUT_S = 0.5
# How often the ROS minus monotonic time that stamps the crate's messages and the recorded cycles is read again.
_OFFSET_PERIOD_S = 1.0


def _feed_joint(axis, joint: JointSettings) -> dict:
    """`axis`, the drive of `joint`, as the crate's feed takes it: what its messages say beside the drive's values."""
    return {
        "slave": axis.slave,
        "name": axis.name,
        "units": axis.units,
        "homes": joint.homing_method != "none",
        "inputs": list((joint.io_inputs or {}).items()),
        "outputs": list((joint.io_outputs or {}).items()),
        "volts_per_count": axis.analog_scale,
    }


class RecordedPublisher:
    """A publisher of `type_name` on `topic` whose messages are also recorded, at their stamp, while the node state
    records."""

    def __init__(self, transport: Transport, type_name: str, topic: str, qos: Qos, node_state: NodeState) -> None:
        self._publisher = transport.publisher(type_name, topic, qos)
        self.msg_type, self.qos, self.topic_name = (
            self._publisher.msg_type,
            self._publisher.qos,
            self._publisher.topic_name,
        )
        self._node_state = node_state

    def publish(self, message) -> None:
        """Publishes `message` (stamped) and records it at its stamp."""
        self._publisher.publish(message)
        recorder = self._node_state.recorder
        if recorder is not None:
            recorder.write(self.topic_name, message, nanoseconds(message.header.stamp))

    def publish_serialized(self, data: bytes, stamp_ns: int) -> None:
        """Publishes a message given serialised, stamped `stamp_ns`, and records it at that stamp."""
        self._publisher.publish_serialized(data)
        recorder = self._node_state.recorder
        if recorder is not None:
            recorder.write_serialized(self.topic_name, data, stamp_ns)

    def publish_made(self, data: bytes) -> None:
        """Publishes a message the crate made (and records itself)."""
        self._publisher.publish_serialized(data)


class JointPublishers:
    """One joint's status, latch and fault publishers."""

    def __init__(self, transport: Transport, node_state: NodeState, joint: str, reliable: Qos, events: Qos) -> None:
        ns = namespace(node_state.settings, joint)
        self.status = RecordedPublisher(transport, "akd_ros/msg/DriveStatus", f"{ns}status", reliable, node_state)
        self.latch = RecordedPublisher(transport, "akd_ros/msg/LatchEvent", f"{ns}latch", events, node_state)
        self.fault = RecordedPublisher(transport, "akd_ros/msg/DriveFault", f"{ns}fault", events, node_state)


class Publishing:
    """/joint_states and the statuses made by the crate, and the events (latches, faults, command time-outs) with the
    recorder's black box; `on_fault(joint)` is called for each fault published. `start()` at configure, `stop()` at
    cleanup, `set_active` at activate and deactivate."""

    def __init__(
        self,
        transport: Transport,
        node_state: NodeState,
        reliable: Qos,
        events: Qos,
        on_fault: Callable[[str], None],
    ) -> None:
        self._node_state, self._clock, self._settings, self._on_fault = (
            node_state,
            node_state.clock,
            node_state.settings,
            on_fault,
        )
        self._logger = transport.logger
        self._header = transport.message_class("std_msgs/msg/Header")
        self._latch_event = transport.message_class("akd_ros/msg/LatchEvent")
        self._drive_fault = transport.message_class("akd_ros/msg/DriveFault")
        self.joint_states = RecordedPublisher(
            transport, "sensor_msgs/msg/JointState", "/joint_states", reliable, node_state
        )
        self.joints = {
            j.name: JointPublishers(transport, node_state, j.name, reliable, events) for j in node_state.joints
        }
        """Each joint's publishers by its name."""
        self.last_fault: dict[str, object] = {}
        """The last fault published of each joint, for /diagnostics."""
        self.last_device_fault: dict[str, object] = {}
        """The last loss or return of each device (an `akd_ros.axis.FaultEvent`), for /diagnostics."""
        self.offset_ns = 0
        """ROS minus monotonic time as last read: it stamps the crate's messages, the recorded cycles and the events,
        so that a fault's black box ends at the fault's own cycle."""
        self._feed: _native.Feed | None = None
        self._streams: dict[int, RecordedPublisher] = {}
        self._drive_io: tuple[dict[str, RecordedPublisher], float] | None = None
        self._drive_io_streams: dict[str, int] = {}
        self._device_io: tuple[dict[str, RecordedPublisher], float] | None = None
        self._device_io_streams: dict[str, int] = {}
        self._thread: threading.Thread | None = None

    def publishers(self) -> list[RecordedPublisher]:
        """Every publisher of this part, for the recorder."""
        return [self.joint_states] + [p for j in self.joints.values() for p in (j.status, j.latch, j.fault)]

    def publish_drive_io(self, publishers: dict[str, RecordedPublisher], period: float) -> None:
        """Has the feed make each joint's akd_ros/DriveIO every `period` seconds from `start()` on, for its publisher
        in `publishers` (by joint name)."""
        self._drive_io = (publishers, period)

    def publish_device_io(self, publishers: dict[str, RecordedPublisher], period: float) -> None:
        """Has the feed make each device's akd_ros/DeviceIO every `period` seconds from `start()` on, for its publisher
        in `publishers` (by device name)."""
        self._device_io = (publishers, period)

    def start(self) -> None:
        """Starts the crate's feed of the node state's Bus and the thread that publishes what it makes (at configure,
        once the Bus and the recorder are there)."""
        bus, settings = self._node_state.bus, self._settings
        joints = {joint.name: joint for joint in self._node_state.joints}
        devices = [{"slave": d.slave, "name": d.name, "product": d.product} for d in bus.devices]
        feed = _native.Feed(bus.cycle, [_feed_joint(axis, joints[axis.name]) for axis in bus.axes], devices)
        self._streams = {feed.add_joint_states(1.0 / settings.joint_states_rate): self.joint_states}
        for k, axis in enumerate(bus.axes):
            self._streams[feed.add_drive_status(k, 1.0 / settings.status_rate)] = self.joints[axis.name].status
        if self._drive_io is not None:
            publishers, period = self._drive_io
            for k, axis in enumerate(bus.axes):
                self._drive_io_streams[axis.name] = stream = feed.add_drive_io(k, period)
                self._streams[stream] = publishers[axis.name]
        if self._device_io is not None:
            publishers, period = self._device_io
            for k, device in enumerate(bus.devices):
                self._device_io_streams[device.name] = stream = feed.add_device_io(k, period)
                self._streams[stream] = publishers[device.name]
        self._read_offset(feed)
        recorder = self._node_state.recorder
        if recorder is not None:
            recorder.take_cycles_from(feed)
            for stream, publisher in self._streams.items():
                recorder.take_stream_from(feed, stream, publisher.topic_name)
        feed.start()
        self._feed = feed
        self._thread = threading.Thread(target=self._run, args=(feed,), name="akd-publish", daemon=True)
        self._thread.start()

    def set_active(self, active: bool) -> None:
        """Starts (or stops) making and publishing messages."""
        if self._feed is not None:
            if active:
                self._read_offset(self._feed)
            self._feed.set_active(active)

    def stop(self) -> None:
        """Stops the feed and the publishing thread (before the Bus closes)."""
        feed, self._feed = self._feed, None
        if feed is not None:
            feed.stop()
        if self._thread is not None:
            self._thread.join(timeout=5.0)
            self._thread = None

    def feed_dropped(self) -> int:
        """Messages the crate made that this part did not take in time (0 when not started)."""
        return 0 if self._feed is None else self._feed.dropped

    def _read_offset(self, feed) -> None:
        self.offset_ns = self._clock.ros_minus_monotonic_ns()
        feed.set_offset(self.offset_ns)

    def _run(self, feed) -> None:
        name_this_thread("akd-publish")
        streams, next_offset = self._streams, time.monotonic() + _OFFSET_PERIOD_S
        while self._feed is feed:
            messages, events = feed.take(_TAKE_TIMEOUT_S)
            try:
                for stream, data in messages:
                    streams[stream].publish_made(data)
                bus = self._node_state.bus
                # Another part taking its events may have filed these drives' under them meanwhile.
                if events or (bus is not None and bus.events_waiting()):
                    self._publish_events()
                if time.monotonic() >= next_offset:
                    next_offset += _OFFSET_PERIOD_S
                    self._read_offset(feed)
            except Exception as e:  # noqa: BLE001  (logged; publishing goes on)
                self._logger.error(f"publishing failed: {type(e).__name__}: {e}")

    def _publish_events(self) -> None:
        node_state = self._node_state
        with node_state.lock:
            if node_state.bus is None or not node_state.active:
                return
            taken = [
                (a, list(a.latch_events()), list(a.fault_events()), list(a.command_timeout_events()))
                for a in node_state.bus.axes
            ]
            changes = [(a.name, list(a.input_events())) for a in node_state.bus.axes]
            devices = [(d, list(d.input_events()), list(d.fault_events())) for d in node_state.bus.devices]
            recorder = node_state.recorder
        feed = self._feed
        for joint, ios in changes:
            stream = self._drive_io_streams.get(joint)
            for io in ios if feed is not None and stream is not None else ():
                feed.input_change(stream, io.cycle, io.time_ns, io.digital_inputs or 0, io.statusword or 0)
        for device, edges, faults in devices:
            stream = self._device_io_streams.get(device.name)
            for io in edges if feed is not None and stream is not None else ():
                feed.device_input_change(stream, io.cycle, io.time_ns, io.levels)
            for e in faults:
                line = f"device {device.name} (slave {device.slave}, {device.product}): {e.describe()}"
                if e.source == "recovered":
                    self._logger.warning(line)
                else:
                    self._logger.error(line)
                self.last_device_fault[device.name] = e
        how_to_enable = "call ~/enable to go on"
        # A fault of the link (a lost frame, a working counter) is every drive's in the same cycle: one line for all.
        logged: dict[tuple, list[str]] = {}
        for axis, _, faults, _ in taken:
            for e in faults:
                logged.setdefault((e.cycle, e.source, e.code, e.describe()), []).append(axis.name)
        for (_, source, _, text), joints in logged.items():
            if source == "recovered":
                self._logger.warning(f"{', '.join(joints)}: {text}; {how_to_enable}")
            else:
                self._logger.error(f"fault of {', '.join(joints)}: {text}")
        offset = self.offset_ns
        for axis, latches, faults, timeouts in taken:
            joint = axis.name
            for e in timeouts:
                self._logger.warning(f"{joint}: {e.describe(how_to_enable)}")
            for e in latches:
                message = self._latch_event(
                    header=self._header(stamp=self._clock.time(e.time_ns + offset)),
                    joint=joint,
                    channel=e.channel,
                    edge=_EDGE_CODES[e.edge],
                    position=e.position,
                    position_counts=e.position_counts,
                )
                self.joints[joint].latch.publish(message)
            for e in faults:
                message = self._drive_fault(
                    header=self._header(stamp=self._clock.time(e.time_ns + offset)),
                    joint=joint,
                    source=e.source,
                    code=min(e.code, 0xFFFF),
                    text=e.text or "",
                    ds402_state=_native.Ds402State.message_name(e.ds402_state),
                    al_state=_native.snake_case(e.al_state or "unknown"),
                    al_status_code=e.al_status_code,
                    action=e.action,
                )
                self.last_fault[joint] = message
                self.joints[joint].fault.publish(message)
                if recorder is not None:
                    # The same offset as the recorded cycles': the black box ends at the fault's own cycle.
                    recorder.fault(e.time_ns + offset)
                self._on_fault(joint)
