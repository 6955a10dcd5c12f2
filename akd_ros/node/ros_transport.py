"""The node's parts over rclpy (DDS through rmw_fastrtps_cpp): `RosTransport`, on the node's LifecycleNode.

Publishers are lifecycle publishers, so nothing goes out before activate; messages are the rosidl-generated classes.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable
from typing import Any

from rclpy.callback_groups import MutuallyExclusiveCallbackGroup
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

from akd_ros.node.transport import Qos


def message_class(type_name: str) -> type:
    """The rosidl-generated class of `type_name` ("pkg/msg/Name" or "pkg/srv/Name")."""
    package, kind, name = type_name.split("/")
    return getattr(importlib.import_module(f"{package}.{kind}"), name)


def qos_profile(qos: Qos) -> QoSProfile:
    """rclpy's QoSProfile of `qos`."""
    return QoSProfile(
        depth=qos.depth,
        reliability=ReliabilityPolicy.RELIABLE if qos.reliable else ReliabilityPolicy.BEST_EFFORT,
        durability=DurabilityPolicy.TRANSIENT_LOCAL if qos.transient_local else DurabilityPolicy.VOLATILE,
    )


class _Publisher:
    def __init__(self, node, msg_type: type, topic: str, qos: QoSProfile) -> None:
        self.msg_type, self.qos = msg_type, qos
        self._publisher = node.create_lifecycle_publisher(msg_type, topic, qos)
        self.topic_name: str = self._publisher.topic_name

    def publish(self, message: Any) -> None:
        self._publisher.publish(message)


class RosTransport:
    """The transport of a LifecycleNode `node` (see `akd_ros.node.transport.Transport`)."""

    name = "rclpy"
    typestore = None

    def __init__(self, node) -> None:
        self._node = node
        self.logger = node.get_logger()

    def message_class(self, type_name: str) -> type:
        return message_class(type_name)

    def publisher(self, type_name: str, topic: str, qos: Qos) -> _Publisher:
        return _Publisher(self._node, message_class(type_name), topic, qos_profile(qos))

    def subscription(self, type_name: str, topic: str, callback: Callable[[Any], None], qos: Qos, group: Any) -> str:
        subscription = self._node.create_subscription(
            message_class(type_name), topic, callback, qos_profile(qos), callback_group=group
        )
        return subscription.topic_name

    def service(self, type_name: str, name: str, handler: Callable[[Any, Any], Any], group: Any) -> None:
        self._node.create_service(message_class(type_name), name, handler, callback_group=group)

    def timer(self, period: float, callback: Callable[[], None], group: Any) -> None:
        self._node.create_timer(period, callback, group)

    def group(self) -> MutuallyExclusiveCallbackGroup:
        return MutuallyExclusiveCallbackGroup()

    def now_ns(self) -> int:
        return self._node.get_clock().now().nanoseconds

    def resolve(self, name: str) -> str:
        return self._node.resolve_topic_name(name)

    def counters(self) -> dict[str, int]:
        return {}

    def recorded_class(self, type_name: str) -> type:
        return message_class(type_name)

    def recorded_qos(self, qos: Qos) -> QoSProfile:
        return qos_profile(qos)
