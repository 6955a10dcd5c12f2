"""Publishing: /joint_states (sensor_msgs/JointState, SI), ~/status (DriveStatus), ~/latch (LatchEvent) and ~/fault
(DriveFault), each message recorded at its stamp when recording, and the cycle records taken with the events.

The timers run in every state and do nothing unless the node is active: cancelling a timer the executor has already
taken as ready makes rclpy raise in the executor."""

from __future__ import annotations

import math
import re
from collections.abc import Callable

from rclpy.qos import QoSProfile
from sensor_msgs.msg import JointState

from akd_ros.axis import MODES
from akd_ros.msg import DriveFault, DriveStatus, LatchEvent
from akd_ros.node.clock import nanoseconds
from akd_ros.node.recording import record_cycles
from akd_ros.node.session import Session

EDGE_NAMES = {LatchEvent.EDGE_RISING: "rising", LatchEvent.EDGE_FALLING: "falling"}
"""Latch edges by their LatchEvent code."""
_EDGE_CODES = {name: code for code, name in EDGE_NAMES.items()}
# Events are taken from the cycle thread at this rate; its queue holds 256, far more than arrive in 20 ms.
_EVENT_POLL_S = 0.02


def snake(name: str | None) -> str:
    """A state's name as the messages spell it: "Operation enabled" -> "operation_enabled", "SafeOp" -> "safe_op";
    None -> "unknown"."""
    return "unknown" if name is None else re.sub(r"(?<=[a-z])(?=[A-Z])", "_", name).replace(" ", "_").lower()


class RecordedPublisher:
    """A lifecycle publisher of `msg_type` on `topic` whose messages are also recorded, at their stamp, while the
    session records."""

    def __init__(self, node, msg_type: type, topic: str, qos: QoSProfile, session: Session) -> None:
        self.msg_type, self.qos = msg_type, qos
        self._publisher = node.create_lifecycle_publisher(msg_type, topic, qos)
        self.topic_name: str = self._publisher.topic_name
        self._session = session

    def publish(self, message) -> None:
        """Publishes `message` (stamped) and records it at its stamp."""
        self._publisher.publish(message)
        recorder = self._session.recorder
        if recorder is not None:
            recorder.write(self.topic_name, message, nanoseconds(message.header.stamp))


class Publishing:
    """The periodic joint_states and status, and the events (latches, faults) with the cycle records; `on_fault` is
    called for each fault published."""

    def __init__(
        self,
        node,
        session: Session,
        group,
        reliable: QoSProfile,
        events: QoSProfile,
        on_fault: Callable[[], None],
    ) -> None:
        self._session, self._clock, self._settings, self._on_fault = session, session.clock, session.settings, on_fault
        self._logger = node.get_logger()
        self.joint_states = RecordedPublisher(node, JointState, "/joint_states", reliable, session)
        self.status = RecordedPublisher(node, DriveStatus, "~/status", reliable, session)
        self.latch = RecordedPublisher(node, LatchEvent, "~/latch", events, session)
        self.fault = RecordedPublisher(node, DriveFault, "~/fault", events, session)
        self.last_fault: DriveFault | None = None
        """The last fault published, for /diagnostics."""
        node.create_timer(1.0 / session.settings.joint_states_rate, self._publish_joint_states, group)
        node.create_timer(1.0 / session.settings.status_rate, self._publish_status, group)
        node.create_timer(_EVENT_POLL_S, self._publish_events, group)

    def _publish_joint_states(self) -> None:
        taken = self._session.state()
        if taken is None:
            return
        _, state, _ = taken
        message = JointState(name=[self._settings.joint_name], position=[state.position])
        message.header.stamp = self._clock.stamp()
        if state.velocity is not None:
            message.velocity = [state.velocity]
        if state.torque is not None:
            message.effort = [state.torque]
        self.joint_states.publish(message)

    def _publish_status(self) -> None:
        taken = self._session.state()
        if taken is None:
            return
        axis, state, stats = taken
        message = DriveStatus(
            joint=self._settings.joint_name,
            ds402_state=snake(state.state),
            statusword=state.statusword,
            mode=state.mode or axis.mode,
            mode_of_operation=MODES.get(state.mode, 0),
            following_error=math.nan if state.following_error is None else state.following_error,
            cycles=stats["cycles"],
            overruns=stats["overruns"],
            lost_frames=stats["lost_frames"],
            wkc_errors=stats["wkc_errors"],
            period_mean=stats["period"]["mean_ns"] * 1e-9,
            period_max=stats["period"]["max_ns"] * 1e-9,
            exchange_p99=stats["exchange"]["p99_ns"] * 1e-9,
        )
        message.header.stamp = self._clock.stamp()
        self.status.publish(message)

    def _publish_events(self) -> None:
        session = self._session
        with session.lock:
            if session.axis is None or not session.active:
                return
            latches, faults = list(session.axis.latch_events()), list(session.axis.fault_events())
            timeouts = list(session.axis.command_timeout_events())
            # Taken with the events, so the black box holds the cycles up to a fault when it is written.
            recorder = session.recorder
            columns = session.axis.samples() if recorder is not None else None
        if columns is not None:
            record_cycles(recorder, columns, self._settings.units, self._clock.ros_minus_monotonic_ns())
        for e in timeouts:
            self._logger.warning(e.describe("call ~/enable to go on"))
        joint = self._settings.joint_name
        for e in latches:
            message = LatchEvent(
                joint=joint,
                channel=e.channel,
                edge=_EDGE_CODES[e.edge],
                position=e.position,
                position_counts=e.position_counts,
            )
            message.header.stamp = self._clock.stamp(e.time_ns)
            self.latch.publish(message)
        for e in faults:
            self._logger.error(f"fault: {e.describe()}")
            message = DriveFault(
                joint=joint,
                source=e.source,
                code=min(e.code, 0xFFFF),
                text=e.text or "",
                ds402_state=snake(e.ds402_state),
                al_state=snake(e.al_state),
                al_status_code=e.al_status_code,
                action=e.action,
            )
            message.header.stamp = self._clock.stamp(e.time_ns)
            self.last_fault = message
            self.fault.publish(message)
            if recorder is not None:
                recorder.fault(nanoseconds(message.header.stamp))
            self._on_fault()
