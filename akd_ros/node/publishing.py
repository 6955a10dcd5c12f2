"""Publishing: /joint_states (sensor_msgs/JointState, SI: every joint, all of one cycle), and per joint its status
(DriveStatus), latch (LatchEvent) and fault (DriveFault) topics, each message recorded at its stamp when recording,
and the cycle records taken with the events.

The timers run in every state and do nothing unless the node is active: cancelling a timer the executor has already
taken as ready makes rclpy raise in the executor."""

from __future__ import annotations

import math
import re
from collections.abc import Callable

from akd_ros.axis import MODES
from akd_ros.node.clock import nanoseconds
from akd_ros.node.homing import joint_homed
from akd_ros.node.recording import record_cycles
from akd_ros.node.session import Session, namespace
from akd_ros.node.transport import Qos, Transport

EDGE_RISING, EDGE_FALLING = 1, 2
"""LatchEvent's edge codes (its EDGE_RISING and EDGE_FALLING constants)."""
EDGE_NAMES = {EDGE_RISING: "rising", EDGE_FALLING: "falling"}
"""Latch edges by their LatchEvent code."""
_EDGE_CODES = {name: code for code, name in EDGE_NAMES.items()}
# Events are taken from the cycle thread at this rate; its queue holds 256, far more than arrive in 20 ms.
_EVENT_POLL_S = 0.02


def snake(name: str | None) -> str:
    """A state's name as the messages spell it: "Operation enabled" -> "operation_enabled", "SafeOp" -> "safe_op";
    None -> "unknown"."""
    return "unknown" if name is None else re.sub(r"(?<=[a-z])(?=[A-Z])", "_", name).replace(" ", "_").lower()


class RecordedPublisher:
    """A publisher of `type_name` on `topic` whose messages are also recorded, at their stamp, while the session
    records."""

    def __init__(self, transport: Transport, type_name: str, topic: str, qos: Qos, session: Session) -> None:
        self._publisher = transport.publisher(type_name, topic, qos)
        self.msg_type, self.qos, self.topic_name = (
            self._publisher.msg_type,
            self._publisher.qos,
            self._publisher.topic_name,
        )
        self._session = session

    def publish(self, message) -> None:
        """Publishes `message` (stamped) and records it at its stamp."""
        self._publisher.publish(message)
        recorder = self._session.recorder
        if recorder is not None:
            recorder.write(self.topic_name, message, nanoseconds(message.header.stamp))


class JointPublishers:
    """One joint's status, latch and fault publishers."""

    def __init__(self, transport: Transport, session: Session, joint: str, reliable: Qos, events: Qos) -> None:
        ns = namespace(session.settings, joint)
        self.status = RecordedPublisher(transport, "akd_ros/msg/DriveStatus", f"{ns}status", reliable, session)
        self.latch = RecordedPublisher(transport, "akd_ros/msg/LatchEvent", f"{ns}latch", events, session)
        self.fault = RecordedPublisher(transport, "akd_ros/msg/DriveFault", f"{ns}fault", events, session)


class Publishing:
    """The periodic joint_states and statuses, and the events (latches, faults, command time-outs) with the cycle
    records; `on_fault(joint)` is called for each fault published."""

    def __init__(
        self,
        transport: Transport,
        session: Session,
        group,
        reliable: Qos,
        events: Qos,
        on_fault: Callable[[str], None],
    ) -> None:
        self._session, self._clock, self._settings, self._on_fault = session, session.clock, session.settings, on_fault
        self._logger = transport.logger
        self._header = transport.message_class("std_msgs/msg/Header")
        self._joint_state = transport.message_class("sensor_msgs/msg/JointState")
        self._drive_status = transport.message_class("akd_ros/msg/DriveStatus")
        self._latch_event = transport.message_class("akd_ros/msg/LatchEvent")
        self._drive_fault = transport.message_class("akd_ros/msg/DriveFault")
        self.joint_states = RecordedPublisher(
            transport, "sensor_msgs/msg/JointState", "/joint_states", reliable, session
        )
        self.joints = {j.name: JointPublishers(transport, session, j.name, reliable, events) for j in session.joints}
        """Each joint's publishers by its name."""
        self.last_fault: dict[str, object] = {}
        """The last fault published of each joint, for /diagnostics."""
        transport.timer(1.0 / session.settings.joint_states_rate, self._publish_joint_states, group)
        transport.timer(1.0 / session.settings.status_rate, self._publish_status, group)
        transport.timer(_EVENT_POLL_S, self._publish_events, group)

    def publishers(self) -> list[RecordedPublisher]:
        """Every publisher of this part, for the recorder."""
        return [self.joint_states] + [p for j in self.joints.values() for p in (j.status, j.latch, j.fault)]

    def _publish_joint_states(self) -> None:
        taken = self._session.states()
        if taken is None:
            return
        _, states, _ = taken
        values = list(states.values())
        # JointState leaves velocity or effort empty when they are not all known.
        message = self._joint_state(
            header=self._header(stamp=self._clock.stamp()),
            name=list(states),
            position=[s.position for s in values],
            velocity=[s.velocity for s in values] if all(s.velocity is not None for s in values) else [],
            effort=[s.torque for s in values] if all(s.torque is not None for s in values) else [],
        )
        self.joint_states.publish(message)

    def _publish_status(self) -> None:
        taken = self._session.states(with_stats=True)
        if taken is None:
            return
        bus, states, stats = taken
        stamp = self._clock.stamp()
        for joint, state in states.items():
            message = self._drive_status(
                header=self._header(stamp=stamp),
                joint=joint,
                ds402_state=snake(state.state),
                statusword=state.statusword,
                mode=state.mode or bus[joint].mode,
                mode_of_operation=MODES.get(state.mode, 0),
                following_error=math.nan if state.following_error is None else state.following_error,
                homed=joint_homed(self._session.joint(joint), bus[joint]),
                cycles=stats["cycles"],
                overruns=stats["overruns"],
                lost_frames=stats["lost_frames"],
                wkc_errors=stats["wkc_errors"],
                period_mean=stats["period"]["mean_ns"] * 1e-9,
                period_max=stats["period"]["max_ns"] * 1e-9,
                exchange_p99=stats["exchange"]["p99_ns"] * 1e-9,
            )
            self.joints[joint].status.publish(message)

    def _publish_events(self) -> None:
        session = self._session
        with session.lock:
            if session.bus is None or not session.active:
                return
            taken = [
                (a, list(a.latch_events()), list(a.fault_events()), list(a.command_timeout_events()))
                for a in session.bus.axes
            ]
            # Taken with the events, so the black box holds the cycles up to a fault when it is written.
            recorder = session.recorder
            columns = [(a, a.samples()) for a in session.bus.axes] if recorder is not None else None
        if columns is not None:
            record_cycles(recorder, columns, self._clock.ros_minus_monotonic_ns())
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
        for axis, latches, faults, timeouts in taken:
            joint = axis.name
            for e in timeouts:
                self._logger.warning(f"{joint}: {e.describe(how_to_enable)}")
            for e in latches:
                message = self._latch_event(
                    header=self._header(stamp=self._clock.stamp(e.time_ns)),
                    joint=joint,
                    channel=e.channel,
                    edge=_EDGE_CODES[e.edge],
                    position=e.position,
                    position_counts=e.position_counts,
                )
                self.joints[joint].latch.publish(message)
            for e in faults:
                message = self._drive_fault(
                    header=self._header(stamp=self._clock.stamp(e.time_ns)),
                    joint=joint,
                    source=e.source,
                    code=min(e.code, 0xFFFF),
                    text=e.text or "",
                    ds402_state=snake(e.ds402_state),
                    al_state=snake(e.al_state),
                    al_status_code=e.al_status_code,
                    action=e.action,
                )
                self.last_fault[joint] = message
                self.joints[joint].fault.publish(message)
                if recorder is not None:
                    recorder.fault(nanoseconds(message.header.stamp))
                self._on_fault(joint)
