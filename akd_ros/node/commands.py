"""Commands: ~/position_command, ~/velocity_command and ~/torque_command (std_msgs/Float64, SI), their refusal, the
command time-out and the automatic fault reset, and the drive requests that the services and the transitions make
(enable, disable, reset_fault, quick_stop).

A refused command never reaches the drive; each kind is logged as a warning at most once per
_REFUSAL_LOG_PERIOD_S, with the count of those not logged. A velocity or torque command that is not zero and not
renewed for `command_timeout` seconds is handled by `command_timeout_policy` (hold: halt until the next command;
quick_stop) in the cycle thread, which sees the stream stop to the cycle (`Axis.set_command_timeout`); the node
logs what it did. Every command received is recorded, refused ones too, at its arrival."""

from __future__ import annotations

import math
import re
import time
from collections.abc import Callable

from rclpy.qos import QoSProfile
from std_msgs.msg import Float64

from akd_ros.axis import Axis, CommandError
from akd_ros.node.session import AXIS_ERRORS, FAULT_STATES, Session

_SUPERVISOR_PERIOD_S = 0.02
# How often one kind of refused command is logged.
_REFUSAL_LOG_PERIOD_S = 1.0
_NUMBER = re.compile(r"[-+]?(\d+\.?\d*(e[-+]?\d+)?|nan|inf)")


class Commands:
    """The command subscriptions (in `group`, `qos`), the supervisor timer (in `supervisor_group`: it may wait on
    the drive) that resets a fault under auto_once, and whether such a reset is due."""

    def __init__(self, node, session: Session, group, qos: QoSProfile, supervisor_group) -> None:
        self._session, self._clock, self._settings = session, session.clock, session.settings
        self._logger = node.get_logger()
        self.qos = qos
        self._reset_pending = False
        self._refusals: dict[str, tuple[float, int]] = {}
        self.topics: dict[str, str] = {}
        """The command topics' names by kind (position, velocity, torque)."""
        for kind in ("position", "velocity", "torque"):
            subscription = node.create_subscription(
                Float64, f"~/{kind}_command", lambda m, k=kind: self._on_command(k, m), qos, callback_group=group
            )
            self.topics[kind] = subscription.topic_name
        node.create_timer(_SUPERVISOR_PERIOD_S, self._supervise, supervisor_group)

    def fault_seen(self) -> None:
        """A fault was published: under fault_reset auto_once the supervisor resets it."""
        self._reset_pending = self._settings.fault_reset == "auto_once"

    def _on_command(self, kind: str, message: Float64) -> None:
        session = self._session
        recorder = session.recorder
        if recorder is not None:
            recorder.write(self.topics[kind], message, self._clock.now_ns())
        value = message.data
        try:
            with session.lock:
                if session.axis is None or not session.active:
                    raise CommandError(f"{kind} command refused: the node is not active (activate it first)")
                drive_state = session.axis.cycle.drive_status(session.axis.slave)["state"]
                if drive_state != "Operation enabled":
                    raise CommandError(
                        f"{kind} command refused: the drive is in {drive_state}, not Operation "
                        "enabled; call ~/enable first"
                    )
                getattr(session.axis, f"command_{kind}")(value)
        except CommandError as e:
            self._warn_refused(str(e))

    def _warn_refused(self, message: str) -> None:
        """Logs a refusal, each kind (its text without the numbers) at most once per _REFUSAL_LOG_PERIOD_S, with the
        count of those not logged since."""
        kind = _NUMBER.sub("#", message)
        now = time.monotonic()
        last, hidden = self._refusals.get(kind, (-math.inf, 0))
        if now - last < _REFUSAL_LOG_PERIOD_S:
            self._refusals[kind] = (last, hidden + 1)
            return
        self._refusals[kind] = (now, 0)
        more = f" ({hidden} more like it since)" if hidden else ""
        self._logger.warning(message + more)

    def _supervise(self) -> None:
        """Resets a fault once under fault_reset auto_once."""
        axis = self._session.axis
        if axis is None or not self._session.active:
            return
        if self._reset_pending:
            self._reset_pending = False
            if axis.cycle.drive_status(axis.slave)["state"] in FAULT_STATES:
                _, message = self.reset_fault()
                self._logger.warning(f"fault_reset auto_once: {message}")

    def enable(self) -> tuple[bool, str]:
        """Enables the drive: (done, what happened)."""
        return self._request(
            Axis.enable, "not enabled", "Operation enabled; the target holds the actual position until commanded"
        )

    def disable(self) -> tuple[bool, str]:
        """Disables the drive (also when the node is configured but inactive): (done, what happened)."""
        axis = self._session.axis
        if axis is None:
            return False, "not disabled: the node is not configured"
        try:
            axis.disable()
        except AXIS_ERRORS as e:
            return False, f"not disabled: {e}"
        return True, "Switch on disabled (power stage off)"

    def reset_fault(self) -> tuple[bool, str]:
        """Resets a fault: (done, what happened)."""
        try:
            self._session.axis_for_request().reset_fault()
        except AXIS_ERRORS as e:
            return False, f"fault not reset: {e}"
        return True, "fault reset: Switch on disabled; call ~/enable to go on"

    def quick_stop(self) -> tuple[bool, str]:
        """Quick stop: (done, what happened)."""
        return self._request(Axis.quick_stop, "quick stop failed", "Quick stop active; call ~/enable to go on")

    def _request(self, request: Callable[[Axis], None], failed: str, done: str) -> tuple[bool, str]:
        """`request` of the active node's Axis: (True, done) or (False, failed and why)."""
        try:
            request(self._session.axis_for_request())
        except AXIS_ERRORS as e:
            return False, f"{failed}: {e}"
        return True, done
