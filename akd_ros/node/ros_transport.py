"""The node's parts over rclpy (DDS through rmw_fastrtps_cpp): `RosTransport`, on the node's LifecycleNode.

Publishers are lifecycle publishers, so nothing goes out before activate; messages are the rosidl-generated classes.
Subscriptions and services run in the executor, in their rclpy callback group; timers run on a `Worker` thread of
the group (see `akd_ros.node.worker` for why), which `start()` starts and `close()` stops.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable
from typing import Any

from rclpy.callback_groups import MutuallyExclusiveCallbackGroup
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

from akd_ros.node.transport import ActionCallbacks, Qos
from akd_ros.node.worker import Worker


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


class RosGroup:
    """A callback group of the rclpy transport: the executor's for subscriptions and services, a worker thread for
    timers (and, with transport both, for what arrives by Zenoh)."""

    def __init__(self, callbacks: MutuallyExclusiveCallbackGroup, worker: Worker) -> None:
        self.callbacks, self.worker = callbacks, worker


class RosTransport:
    """The transport of a LifecycleNode `node` (see `akd_ros.node.transport.Transport`)."""

    name = "rclpy"
    typestore = None

    def __init__(self, node) -> None:
        self._node = node
        self.logger = node.get_logger()
        self._workers: list[Worker] = []

    def start(self) -> None:
        """Starts the groups' timer threads (once the parts are made)."""
        for worker in self._workers:
            worker.start()

    def close(self) -> None:
        """Stops them."""
        for worker in self._workers:
            worker.stop()

    def message_class(self, type_name: str) -> type:
        return message_class(type_name)

    def publisher(self, type_name: str, topic: str, qos: Qos) -> _Publisher:
        return _Publisher(self._node, message_class(type_name), topic, qos_profile(qos))

    def subscription(
        self, type_name: str, topic: str, callback: Callable[[Any], None], qos: Qos, group: RosGroup
    ) -> str:
        subscription = self._node.create_subscription(
            message_class(type_name), topic, callback, qos_profile(qos), callback_group=group.callbacks
        )
        return subscription.topic_name

    def service(self, type_name: str, name: str, handler: Callable[[Any, Any], Any], group: RosGroup) -> None:
        self._node.create_service(message_class(type_name), name, handler, callback_group=group.callbacks)

    def action_server(self, type_name: str, name: str, callbacks: ActionCallbacks, group: RosGroup) -> type:
        from rclpy.action import ActionServer, CancelResponse, GoalResponse

        action = message_class(type_name)
        ActionServer(
            self._node,
            action,
            name,
            execute_callback=callbacks.execute,
            goal_callback=lambda goal: GoalResponse.ACCEPT if callbacks.goal(goal) else GoalResponse.REJECT,
            cancel_callback=lambda handle: CancelResponse.ACCEPT if callbacks.cancel(handle) else CancelResponse.REJECT,
            callback_group=group.callbacks,
        )
        return action

    def timer(self, period: float, callback: Callable[[], None], group: RosGroup) -> None:
        group.worker.add_timer(period, callback)

    def group(self) -> RosGroup:
        worker = Worker(f"akd-node-{len(self._workers)}", self.logger)
        self._workers.append(worker)
        return RosGroup(MutuallyExclusiveCallbackGroup(), worker)

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
