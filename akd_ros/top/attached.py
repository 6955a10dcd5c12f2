"""akd-top's sources for a running akd_node, whatever the middleware: its joints from /joint_states, their state,
mode and last fault from /diagnostics, position, velocity and effort from /joint_states, following error from each
joint's `status`, faults from its `fault`, its drive's own I/O from its `io`, the bus's statistics and DC from the
`<node>: bus` diagnostic status, the devices beside the drives from their statuses (`<node>: <device>`, with their
channels), the line's slaves from its `<node>: line` and `<node>: line slave N` statuses; requests
through the joint's Trigger services and `arm_latch`. The middleware
(`ros_source`: rclpy; `zenoh_source`: rmw_zenoh's wire without ROS) subscribes and calls.

A joint's topics and services are `<node>/<joint>/...` with `joints`, `<node>/...` for a node of one joint without:
DriveStatus and DriveFault carry the joint's name, so both are subscribed, and a request goes to the joint's own
service, or to the node's for the one joint of a node without `joints`.
"""

from __future__ import annotations

import threading
from abc import abstractmethod
from collections.abc import Callable

from akd_ros.top.direct import STATS_LABELS
from akd_ros.top.source import (
    SWITCH_WORDS,
    BusRow,
    DeviceRow,
    JointRow,
    LineView,
    Source,
    check_action,
    devices_view,
    io_text,
    line_view,
)

JOINT_STATE = "sensor_msgs/msg/JointState"
DIAGNOSTICS = "diagnostic_msgs/msg/DiagnosticArray"
DRIVE_STATUS = "akd_ros/msg/DriveStatus"
DRIVE_FAULT = "akd_ros/msg/DriveFault"
DRIVE_IO = "akd_ros/msg/DriveIO"
# DriveIO's hardware_enable codes (its HARDWARE_ENABLE_* constants, msg/DriveIO.msg).
HARDWARE_ENABLE = {0: "unknown", 1: "high", 2: "low"}
TRIGGER = "std_srvs/srv/Trigger"
ARM_LATCH = "akd_ros/srv/ArmLatch"
# LatchEvent's EDGE_RISING and EDGE_FALLING, the codes ArmLatch's edge takes (msg/LatchEvent.msg).
EDGES = {"rising": 1, "falling": 2}


class AttachedSource(Source):
    """akd_node `node` (its fully qualified name) seen through a middleware's subscriptions and service calls."""

    def __init__(self, node: str) -> None:
        self.node_name = "/" + node.strip("/")
        self._lock = threading.Lock()
        self._joints: list[str] = []
        self._joint_states: dict[str, tuple] = {}
        self._diagnostics: dict[str, dict[str, str]] = {}
        self._line: dict[str, tuple] = {}
        self._devices: dict[str, tuple] = {}
        self._following: dict[str, float] = {}
        self._faults: dict[str, str] = {}
        self._io: dict[str, str | None] = {}

    def start(self) -> None:
        """Subscribes to what every node has; each joint's own topics follow once /joint_states names it."""
        self.subscribe("/joint_states", JOINT_STATE, self._on_joint_states)
        self.subscribe("/diagnostics", DIAGNOSTICS, self._on_diagnostics)
        self._subscribe_joint(None)

    @abstractmethod
    def subscribe(self, topic: str, ros_type: str, callback: Callable[[object], None]) -> None:
        """Calls callback(message) for each message of `ros_type` on `topic`, on a thread of the middleware's."""

    @abstractmethod
    def call(self, service: str, ros_type: str, fields: dict):
        """Calls `service` of `ros_type` with a request of `fields`; its response, None where no such service
        answers. Raises RuntimeError when it does not answer in time."""

    def _prefix(self, joint: str | None) -> str:
        return f"{self.node_name}/" if joint is None else f"{self.node_name}/{joint}/"

    def _subscribe_joint(self, joint: str | None) -> None:
        prefix = self._prefix(joint)
        self.subscribe(prefix + "status", DRIVE_STATUS, self._on_status)
        self.subscribe(prefix + "fault", DRIVE_FAULT, self._on_fault)
        self.subscribe(prefix + "io", DRIVE_IO, self._on_io)

    # --- what arrives --------------------------------------------------------------------------------------------

    def _on_joint_states(self, message) -> None:
        new = []
        with self._lock:
            for i, name in enumerate(message.name):
                if name not in self._joints:
                    self._joints.append(name)
                    new.append(name)
                self._joint_states[name] = tuple(
                    float(values[i]) if i < len(values) else None
                    for values in (message.position, message.velocity, message.effort)
                )
        for name in new:
            self._subscribe_joint(name)

    def _on_diagnostics(self, message) -> None:
        prefix = f"{self.node_name.lstrip('/')}: "
        with self._lock:
            for status in message.status:
                if status.name.startswith(prefix):
                    what = status.name[len(prefix) :]
                    values = {v.key: v.value for v in status.values}
                    self._diagnostics[what] = values
                    level = status.level[0] if isinstance(status.level, bytes) else int(status.level)
                    if what == "line" or what.startswith("line slave "):
                        self._line[what] = (level, what, status.message, status.hardware_id, values)
                    elif "device" in values:
                        self._devices[what] = (level, what, status.message, status.hardware_id, values)

    def _on_status(self, message) -> None:
        with self._lock:
            self._following[message.joint] = float(message.following_error)

    def _on_fault(self, message) -> None:
        with self._lock:
            self._faults[message.joint] = f"{message.source}: {message.text or f'0x{message.code:04X}'}"

    def _on_io(self, m) -> None:
        switches = {name: bool(getattr(m, name)) for name in SWITCH_WORDS}
        hardware_enable = HARDWARE_ENABLE.get(int(m.hardware_enable), "unknown")
        text = io_text(m.inputs, switches, hardware_enable, m.analog_input, m.outputs, m.analog_output)
        with self._lock:
            self._io[m.joint] = text

    # --- Source --------------------------------------------------------------------------------------------------

    def rows(self) -> list[JointRow]:
        with self._lock:
            rows = []
            for joint in self._joints:
                values = self._diagnostics.get(joint, {})
                position, velocity, effort = self._joint_states.get(joint, (None, None, None))
                last = values.get("last_fault")
                fault = self._faults.get(joint) or (last if last not in (None, "none") else None)
                state, mode, following = values.get("ds402_state"), values.get("mode"), self._following.get(joint)
                io = self._io.get(joint)
                rows.append(JointRow(joint, state, mode, position, velocity, effort, following, fault, io))
            return rows

    def bus_row(self) -> BusRow:
        with self._lock:
            values = self._diagnostics.get("bus", {})
        dc = values.get("dc", "unknown")
        if "dc_cycle_s" in values:
            dc += (
                f", cycle {values['dc_cycle_s']} s, shift {values['dc_shift_s']} s, "
                f"reference slave {values['dc_reference_slave']}, difference misses {values['dc_difference_misses']}"
            )
        stats = {k: values[k] for k in STATS_LABELS if k in values}
        return BusRow(values.get("link", f"{self.node_name} (no /diagnostics yet)"), stats, dc)

    def devices(self) -> list[DeviceRow]:
        with self._lock:
            statuses = list(self._devices.values())
        return devices_view(statuses)

    def line(self) -> LineView:
        with self._lock:
            statuses = list(self._line.values())
        return line_view(statuses) if statuses else LineView(summary="no line statuses on /diagnostics yet")

    def _joint_call(self, joint: str, name: str, ros_type: str, fields: dict):
        """Calls the joint's service `name`, or the node's for the one joint of a node without joints."""
        with self._lock:
            alone = self._joints == [joint]
        for prefix in [self._prefix(joint)] + ([self._prefix(None)] if alone else []):
            response = self.call(prefix + name, ros_type, fields)
            if response is not None:
                return response
        raise RuntimeError(f"no service {self._prefix(joint)}{name} (is {self.node_name} running and active?)")

    def request(self, joint: str, action: str) -> str:
        check_action(action)
        response = self._joint_call(joint, action, TRIGGER, {})
        if not response.success:
            raise RuntimeError(f"{joint}: {action} refused: {response.message}")
        return f"{joint}: {action} done" + (f" ({response.message})" if response.message else "")

    def arm_latch(self, joint: str, channel: int, edge: str) -> str:
        response = self._joint_call(
            joint, "arm_latch", ARM_LATCH, {"channel": channel, "edge": EDGES[edge], "arm": True}
        )
        if not response.success:
            raise RuntimeError(f"{joint}: arming latch {channel} refused: {response.message}")
        return f"{joint}: latch {channel} armed on the {edge} edge"
