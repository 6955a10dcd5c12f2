"""Commands: each joint's position_command, velocity_command and torque_command (std_msgs/Float64, SI), the set-points
of several joints by name on ~/joint_commands (sensor_msgs/JointState), their refusal, the command time-out and the
automatic fault reset, and the drive requests that the services and the transitions make (enable, disable,
reset_fault, quick_stop, of one joint or of every joint).

A refused command never reaches the drive; each kind is logged as a warning at most once per
_REFUSAL_LOG_PERIOD_S, with the count of those not logged. A JointState on ~/joint_commands is checked whole before
any of it is sent: an unknown joint, a missing value, NaN or a value past a limit refuses all of it. Each named joint
takes the value its mode commands (position, velocity, or effort for torque). A velocity or torque command that is not
zero and not renewed for the joint's `command_timeout` seconds is handled by its `command_timeout_policy` (hold: halt
until the next command; quick_stop) in the cycle thread, which sees the stream stop to the cycle
(`Axis.set_command_timeout`); the node logs what it did. Every command received is recorded, refused ones too, at
its arrival."""

from __future__ import annotations

import math
import re
import time

from akd_ros import _native
from akd_ros.axis import Axis, CommandError
from akd_ros.bus import BusRequestError
from akd_ros.node.homing import unhomed_refusal
from akd_ros.node.node_state import AXIS_ERRORS, FAULT_STATES, NodeState, namespace
from akd_ros.node.transports.transport import Qos, Transport

FLOAT64 = "std_msgs/msg/Float64"
JOINT_STATE = "sensor_msgs/msg/JointState"

_SUPERVISOR_PERIOD_S = 0.02
# How often one kind of refused command is logged.
_REFUSAL_LOG_PERIOD_S = 1.0
_NUMBER = re.compile(r"[-+]?(\d+\.?\d*(e[-+]?\d+)?|nan|inf)")
COMMAND_KINDS = ("position", "velocity", "torque")
"""The kinds of command, each with its topic per joint."""
_JOINT_STATE_FIELD = {"position": "position", "velocity": "velocity", "torque": "effort"}
_REQUEST_WORDS = {
    "enable": ("not enabled", "Operation enabled; the target holds the actual position until commanded"),
    "disable": ("not disabled", "Switch on disabled (power stage off)"),
    "reset_fault": ("fault not reset", "fault reset: Switch on disabled; call ~/enable to go on"),
    "quick_stop": ("quick stop failed", "Quick stop active; call ~/enable to go on"),
}


class Commands:
    """The command subscriptions (in `group`, `qos`), the supervisor timer (in `supervisor_group`: it may wait on
    the drive) that resets a fault under auto_once, and which joints such a reset is due for."""

    def __init__(self, transport: Transport, node_state: NodeState, group, qos: Qos, supervisor_group) -> None:
        self._node_state, self._clock, self._settings = node_state, node_state.clock, node_state.settings
        self._logger = transport.logger
        self.qos = qos
        self._reset_pending: set[str] = set()
        self._handshakes: dict[str, int] = {}
        self._refusals: dict[str, tuple[float, int]] = {}
        self.topics: dict[tuple[str, str], str] = {}
        """The command topics' names by (joint, kind)."""
        for joint in node_state.joints:
            ns = namespace(node_state.settings, joint.name)
            for kind in COMMAND_KINDS:
                self.topics[joint.name, kind] = transport.subscription(
                    FLOAT64,
                    f"{ns}{kind}_command",
                    lambda m, j=joint.name, k=kind: self._on_command(j, k, m),
                    qos,
                    group,
                )
        self.joint_commands_topic: str = transport.subscription(
            JOINT_STATE, "~/joint_commands", self._on_joint_commands, qos, group
        )
        transport.timer(_SUPERVISOR_PERIOD_S, self._supervise, supervisor_group)

    def recorded_topics(self) -> list[tuple[str, str]]:
        """Every command topic with its message type's name, for the recorder."""
        return [(topic, FLOAT64) for topic in self.topics.values()] + [(self.joint_commands_topic, JOINT_STATE)]

    def fault_seen(self, joint: str) -> None:
        """A fault of `joint` was published: under its fault_reset auto_once the supervisor resets it."""
        if next(j for j in self._node_state.joints if j.name == joint).fault_reset == "auto_once":
            self._reset_pending.add(joint)

    def _enabled_axis(self, joint: str, what: str) -> Axis:
        """The Axis of `joint` if the node is active and its drive in Operation enabled; CommandError otherwise.
        Called with the node state's lock held."""
        node_state = self._node_state
        if node_state.bus is None or not node_state.active:
            raise CommandError(f"{what} refused: the node is not active (activate it first)")
        axis = node_state.bus[joint]
        drive_state = axis.cycle.drive_status(axis.slave).state
        if drive_state != _native.Ds402State.OPERATION_ENABLED:
            raise CommandError(
                f"{what} refused: the drive of {joint} is in {drive_state}, not Operation enabled; call ~/enable first"
            )
        return axis

    def _on_command(self, joint: str, kind: str, message) -> None:
        arrival_ns = self._clock.now_ns()
        node_state = self._node_state
        try:
            with node_state.lock:
                axis = self._enabled_axis(joint, f"{kind} command")
                if kind == "position" and (why := unhomed_refusal(node_state, [joint])):
                    raise CommandError(f"position command refused, nothing sent: {why}")
                self._sent(node_state.bus.command([(axis, kind, message.data)]), [axis])
        except CommandError as e:
            self._warn_refused(f"{joint}: {e}")
        self._record(self.topics[joint, kind], message, arrival_ns)

    def _on_joint_commands(self, message) -> None:
        arrival_ns = self._clock.now_ns()
        node_state = self._node_state
        try:
            with node_state.lock:
                commands = self._joint_commands(message)
                positioned = [axis.name for axis, kind, _ in commands if kind == "position"]
                if why := unhomed_refusal(node_state, positioned):
                    raise CommandError(why)
                try:
                    self._sent(node_state.bus.command(commands), [axis for axis, _, _ in commands])
                except CommandError as e:
                    raise CommandError(f"joint {e.joint}: {e}" if e.joint else str(e)) from None
        except CommandError as e:
            self._warn_refused(f"~/joint_commands refused, nothing sent: {e}")
        self._record(self.joint_commands_topic, message, arrival_ns)

    def _record(self, topic: str, message, arrival_ns: int) -> None:
        """Records a command at its arrival, once it is on its way to the drive (or refused): its serialisation
        never delays it."""
        recorder = self._node_state.recorder
        if recorder is not None:
            recorder.write(topic, message, arrival_ns)

    def _sent(self, handshakes: list[int | None], axes: list[Axis]) -> None:
        """Notes the set-point handshakes the commands to `axes` started, which the supervisor follows: a callback
        never waits for one."""
        for axis, handshake in zip(axes, handshakes, strict=True):
            if handshake is not None:
                self._handshakes[axis.name] = handshake

    def _joint_commands(self, message) -> list[tuple[Axis, str, float]]:
        """Each named joint's command of `message` (axis, kind, value); CommandError naming the first problem."""
        names = list(message.name)
        known = [j.name for j in self._node_state.joints]
        unknown = [n for n in names if n not in known]
        if unknown:
            raise CommandError(f"unknown joint {', '.join(unknown)} (joints: {', '.join(known)})")
        if len(set(names)) != len(names):
            raise CommandError(f"a joint is named twice in {', '.join(names)}")
        if not names:
            raise CommandError("no joint named (name is empty)")
        commands = []
        for i, joint in enumerate(names):
            axis = self._enabled_axis(joint, f"the command of {joint}")
            kind = axis.command_kind
            if kind is None:
                raise CommandError(f"joint {joint} is in mode {axis.mode}, which takes no command")
            field = _JOINT_STATE_FIELD[kind]
            values = getattr(message, field)
            if len(values) != len(names):
                raise CommandError(
                    f"joint {joint} in mode {axis.mode} takes its {kind} from {field}, which "
                    f"has {len(values)} values for {len(names)} names"
                )
            commands.append((axis, kind, float(values[i])))
        return commands

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
        """Resets a fault once under fault_reset auto_once, and warns of a profile-position set-point the drive did not
        take (its handshake stuck in the cycle thread)."""
        bus = self._node_state.bus
        if bus is None or not self._node_state.active:
            return
        for joint, handshake in list(self._handshakes.items()):
            axis = bus[joint]
            status = axis.cycle.setpoint_status(axis.slave)
            ours = status["request"] == handshake
            if ours and status["progress"] == "in_progress":
                continue
            if self._handshakes.get(joint) == handshake:
                self._handshakes.pop(joint, None)
            if ours and status["progress"] == "stuck":
                self._warn_refused(f"{joint}: the position set-point was not taken: {status['reason']}")
        while self._reset_pending:
            joint = self._reset_pending.pop()
            axis = bus[joint]
            if axis.cycle.drive_status(axis.slave).state in FAULT_STATES:
                _, message = self.request(joint, "reset_fault")
                self._logger.warning(f"fault_reset auto_once: {message} (joint {joint})")

    def request(self, joint: str, request: str) -> tuple[bool, str]:
        """`request` ("enable", "disable", "reset_fault", "quick_stop") of `joint`'s drive and waits: (done, what
        happened). Disable also works on a node configured but inactive."""
        failed, done = _REQUEST_WORDS[request]
        try:
            if request == "disable" and self._node_state.bus is not None:
                axis = self._node_state.bus[joint]
            else:
                axis = self._node_state.axis_for_request(joint)
            if getattr(axis, request)() is False:
                return True, f"no fault to reset: the drive of {joint} is in {axis.state().state}; left as it was"
        except AXIS_ERRORS as e:
            return False, f"{failed}: {e}"
        return True, done

    def request_all(self, request: str) -> tuple[bool, str]:
        """`request` of every joint's drive at once and waits for all: (done, what happened, naming each joint that
        refused and why)."""
        failed, done = _REQUEST_WORDS[request]
        bus = self._node_state.bus
        try:
            if bus is None or (request != "disable" and not self._node_state.active):
                bus = self._node_state.bus_for_request()
            reset = getattr(bus, request)()
        except BusRequestError as e:
            why = "; ".join(f"joint {joint}: {reason}" for joint, reason in e.failed.items())
            return False, f"{failed}: {why}; done: {', '.join(e.done) or 'none'}"
        except AXIS_ERRORS as e:
            return False, f"{failed}: {e}"
        joints = bus.names if request != "reset_fault" else reset
        if not joints:
            return True, "no fault to reset: no drive is in Fault; every drive left as it was"
        others = [name for name in bus.names if name not in joints]
        untouched = f"; no fault on {', '.join(others)}, left as they were" if others else ""
        return True, (f"{', '.join(joints)}: {done}" if self._settings.joint_namespaces else done) + untouched
