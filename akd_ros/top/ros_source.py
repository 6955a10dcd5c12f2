"""akd-top attached to a running akd_node over ROS: rclpy on the ROS domain of the environment, spun in a thread of
its own (see `attached` for what is read and called)."""

from __future__ import annotations

import importlib
import threading
from collections.abc import Callable

import rclpy
from rclpy.executors import SingleThreadedExecutor
from rclpy.qos import QoSProfile, ReliabilityPolicy

from akd_ros.top.attached import AttachedSource

# Bounds on one service call: discovery of the service, then the answer (the node's requests wait at most 5 s).
DISCOVERY_TIMEOUT_S = 1.0
CALL_TIMEOUT_S = 10.0


def get_interface(ros_type: str):
    """The rclpy class of `ros_type`, e.g. sensor_msgs/msg/JointState."""
    package, kind, name = ros_type.split("/")
    return getattr(importlib.import_module(f"{package}.{kind}"), name)


class RosSource(AttachedSource):
    """akd_node `node` (its fully qualified name, /akd_node by default) over rclpy."""

    def __init__(self, node: str = "/akd_node") -> None:
        super().__init__(node)
        self._context = rclpy.Context()
        rclpy.init(context=self._context)
        self._node = rclpy.create_node("akd_top", context=self._context, start_parameter_services=False)
        self._qos = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE)
        self.start()
        self._executor = SingleThreadedExecutor(context=self._context)
        self._executor.add_node(self._node)
        self._stopping = threading.Event()
        self._spinning = threading.Thread(target=self._spin, name="akd-top ROS", daemon=True)
        self._spinning.start()

    def _spin(self) -> None:
        while not self._stopping.is_set():
            self._executor.spin_once(timeout_sec=0.05)

    def subscribe(self, topic: str, ros_type: str, callback: Callable[[object], None]) -> None:
        self._node.create_subscription(get_interface(ros_type), topic, callback, self._qos)

    def call(self, service: str, ros_type: str, fields: dict):
        kind = get_interface(ros_type)
        client = self._node.create_client(kind, service)
        try:
            if not client.wait_for_service(timeout_sec=DISCOVERY_TIMEOUT_S):
                return None
            answered = threading.Event()
            future = client.call_async(kind.Request(**fields))
            future.add_done_callback(lambda _: answered.set())
            if not answered.wait(CALL_TIMEOUT_S):
                raise RuntimeError(f"{service} did not answer within {CALL_TIMEOUT_S:g} s")
            return future.result()
        finally:
            self._node.destroy_client(client)

    def close(self) -> None:
        self._stopping.set()
        self._spinning.join()
        self._executor.shutdown()
        self._node.destroy_node()
        rclpy.shutdown(context=self._context)
