"""akd-top's source for a running akd_node over ROS (rclpy): its joints from /joint_states, their state, mode,
position and last fault from /diagnostics, velocity and effort from /joint_states, following error from each joint's
`status`, faults from its `fault`, the bus's statistics and DC from the `<node>: bus` diagnostic status; requests
through the joint's Trigger services and `arm_latch`.

A joint's topics and services are `<node>/<joint>/...` with `joints`, `<node>/...` for a node of one joint without:
DriveStatus and DriveFault carry the joint's name, so both are subscribed, and a request goes to the joint's own
service, or to the node's for the one joint of a node without `joints`.
"""

from __future__ import annotations

import threading

import rclpy
from diagnostic_msgs.msg import DiagnosticArray
from rclpy.executors import SingleThreadedExecutor
from rclpy.qos import QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import JointState
from std_srvs.srv import Trigger

from akd_ros.msg import DriveFault, DriveStatus, LatchEvent
from akd_ros.srv import ArmLatch
from akd_ros.top.direct import STATS_LABELS
from akd_ros.top.source import BusRow, JointRow, Source, check_action

# A bound on one service call: the node's own requests wait at most 5 s for the drive.
CALL_TIMEOUT_S = 10.0
EDGES = {"rising": LatchEvent.EDGE_RISING, "falling": LatchEvent.EDGE_FALLING}


def _number(text: str | None) -> float | None:
    try:
        return float(text)
    except (TypeError, ValueError):
        return None


class RosSource(Source):
    """akd_node `node` (its fully qualified name, /akd_node by default) on the ROS domain of the environment."""

    def __init__(self, node: str = "/akd_node") -> None:
        self.node_name = "/" + node.strip("/")
        self._lock = threading.Lock()
        self._joints: list[str] = []
        self._joint_states: dict[str, tuple] = {}
        self._diagnostics: dict[str, dict[str, str]] = {}
        self._following: dict[str, float] = {}
        self._faults: dict[str, str] = {}
        self._context = rclpy.Context()
        rclpy.init(context=self._context)
        self._node = rclpy.create_node("akd_top", context=self._context, start_parameter_services=False)
        self._qos = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE)
        self._node.create_subscription(JointState, "/joint_states", self._on_joint_states, self._qos)
        self._node.create_subscription(DiagnosticArray, "/diagnostics", self._on_diagnostics, self._qos)
        self._subscribe_joint(None)
        self._executor = SingleThreadedExecutor(context=self._context)
        self._executor.add_node(self._node)
        self._stopping = threading.Event()
        self._spinning = threading.Thread(target=self._spin, name="akd-top ROS", daemon=True)
        self._spinning.start()

    def _spin(self) -> None:
        while not self._stopping.is_set():
            self._executor.spin_once(timeout_sec=0.05)

    def _prefix(self, joint: str | None) -> str:
        return f"{self.node_name}/" if joint is None else f"{self.node_name}/{joint}/"

    def _subscribe_joint(self, joint: str | None) -> None:
        prefix = self._prefix(joint)
        self._node.create_subscription(DriveStatus, prefix + "status", self._on_status, self._qos)
        self._node.create_subscription(DriveFault, prefix + "fault", self._on_fault, self._qos)

    # --- what arrives (in the spinning thread) ----------------------------------------------------------------

    def _on_joint_states(self, message) -> None:
        new = []
        with self._lock:
            for i, name in enumerate(message.name):
                if name not in self._joints:
                    self._joints.append(name)
                    new.append(name)
                self._joint_states[name] = tuple(
                    values[i] if i < len(values) else None
                    for values in (message.position, message.velocity, message.effort)
                )
        for name in new:
            self._subscribe_joint(name)

    def _on_diagnostics(self, message) -> None:
        prefix = f"{self.node_name.lstrip('/')}: "
        with self._lock:
            for status in message.status:
                if status.name.startswith(prefix):
                    values = {v.key: v.value for v in status.values}
                    values["_message"] = status.message
                    self._diagnostics[status.name[len(prefix) :]] = values

    def _on_status(self, message) -> None:
        with self._lock:
            self._following[message.joint] = message.following_error

    def _on_fault(self, message) -> None:
        with self._lock:
            self._faults[message.joint] = f"{message.source}: {message.text or f'0x{message.code:04X}'}"

    # --- Source -----------------------------------------------------------------------------------------------

    def rows(self) -> list[JointRow]:
        with self._lock:
            rows = []
            for joint in self._joints:
                values = self._diagnostics.get(joint, {})
                position, velocity, effort = self._joint_states.get(joint, (None, None, None))
                last = values.get("last_fault")
                fault = self._faults.get(joint) or (last if last not in (None, "none") else None)
                rows.append(
                    JointRow(
                        joint,
                        values.get("ds402_state"),
                        values.get("mode"),
                        position,
                        velocity,
                        effort,
                        self._following.get(joint),
                        fault,
                    )
                )
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

    def _call(self, joint: str, name: str, kind, request):
        """Calls the joint's service `name`, or the node's for the one joint of a node without joints."""
        with self._lock:
            alone = self._joints == [joint]
        for prefix in [self._prefix(joint)] + ([self._prefix(None)] if alone else []):
            client = self._node.create_client(kind, prefix + name)
            try:
                if not client.wait_for_service(timeout_sec=1.0):
                    continue
                answered = threading.Event()
                future = client.call_async(request)
                future.add_done_callback(lambda _, answered=answered: answered.set())
                if not answered.wait(CALL_TIMEOUT_S):
                    raise RuntimeError(f"{prefix}{name} did not answer within {CALL_TIMEOUT_S:g} s")
                return future.result()
            finally:
                self._node.destroy_client(client)
        raise RuntimeError(f"no service {self._prefix(joint)}{name} (is {self.node_name} running and active?)")

    def request(self, joint: str, action: str) -> str:
        check_action(action)
        response = self._call(joint, action, Trigger, Trigger.Request())
        if not response.success:
            raise RuntimeError(f"{joint}: {action} refused: {response.message}")
        return f"{joint}: {action} done" + (f" ({response.message})" if response.message else "")

    def arm_latch(self, joint: str, channel: int, edge: str) -> str:
        request = ArmLatch.Request(channel=channel, edge=EDGES[edge], arm=True)
        response = self._call(joint, "arm_latch", ArmLatch, request)
        if not response.success:
            raise RuntimeError(f"{joint}: arming latch {channel} refused: {response.message}")
        return f"{joint}: latch {channel} armed on the {edge} edge"

    def close(self) -> None:
        self._stopping.set()
        self._spinning.join()
        self._executor.shutdown()
        self._node.destroy_node()
        rclpy.shutdown(context=self._context)
