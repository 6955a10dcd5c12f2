"""The node's parts over rclpy (DDS through rmw_fastrtps_cpp): `RosTransport`, on the node's LifecycleNode.

Publishers are lifecycle publishers, so nothing goes out before activate; messages are the rosidl-generated classes.

The executor's thread takes what arrives (`akd_ros.node.ros_node` runs a SingleThreadedExecutor) and runs the
subscriptions' callbacks itself: a command goes from its arrival to the cycle's set-point slot on that thread, behind
nothing but the executor's own wait. Whatever may wait or take long runs elsewhere: a service's handler on the
`Worker` thread of its group and an action's goal on a thread of its own for as long as it runs (the executor awaits
their answers, so it takes the next command meanwhile), timers on those threads too (see
`akd_ros.node.transports.worker` for why), which `start()` starts and `close()` stops, and /joint_states and the
statuses on the publishing thread (`akd_ros.node.publishing`). Publishers and subscriptions install no
default QoS event handlers: each is a waitable that every wake-up of the executor, every command, walks in Python
(about 4 µs each, two per publisher or subscription: 0.3 ms of each command with six joints, 1.5 ms with 64). The
other end of a topic whose QoS is incompatible still says so: rclpy's and rclcpp's publishers and subscriptions log
it by default.
"""

from __future__ import annotations

import functools
import importlib
from collections.abc import Callable
from typing import Any

from rclpy.callback_groups import MutuallyExclusiveCallbackGroup
from rclpy.event_handler import PublisherEventCallbacks, SubscriptionEventCallbacks
from rclpy.qos import (
    DurabilityPolicy,
    QoSProfile,
    ReliabilityPolicy,
    qos_profile_parameters,
    qos_profile_services_default,
)
from rclpy.serialization import deserialize_message, serialize_message
from rclpy.task import Future

from akd_ros.node.transports.transport import ActionCallbacks, Qos
from akd_ros.node.transports.worker import Worker, WorkerGroups, in_thread


@functools.cache
def message_class(type_name: str) -> type:
    """The rosidl-generated class of `type_name` ("pkg/msg/Name", "pkg/srv/Name" or "pkg/srv/Name_Request")."""
    package, kind, name = type_name.split("/")
    return getattr(importlib.import_module(f"{package}.{kind}"), name)


class RosMessages:
    """rclpy's messages made, serialised and read by type name as a Zenoh transport takes them (the methods of
    `akd_ros.zenoh.types.Types` it uses), so that what arrives by Zenoh with transport both reaches the callbacks as
    rclpy's classes, as what arrives by rclpy does."""

    def message(self, type_name: str) -> Any:
        return message_class(type_name)()

    def to_cdr(self, message: Any, type_name: str) -> bytes:
        return serialize_message(message)

    def from_cdr(self, data: bytes, type_name: str) -> Any:
        return deserialize_message(bytes(data), message_class(type_name))


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
        self._publisher = node.create_lifecycle_publisher(
            msg_type, topic, qos, event_callbacks=PublisherEventCallbacks(use_default_callbacks=False)
        )
        self.topic_name: str = self._publisher.topic_name

    def publish(self, message: Any) -> None:
        self._publisher.publish(message)

    def publish_serialized(self, data: bytes) -> None:
        # rclpy publishes bytes as a serialized message (rmw_publish_serialized_message).
        self._publisher.publish(data)


def _settle(answered: Future, done) -> None:
    """`answered` as the concurrent.futures.Future `done` ended."""
    error = done.exception()
    if error is None:
        answered.set_result(done.result())
    else:
        answered.set_exception(error)


def _awaitable(node, done) -> Future:
    """A future of `node`'s executor that ends as `done` (a concurrent.futures.Future ended elsewhere) does."""
    answered = Future(executor=node.executor)
    # A done callback is a task of the executor's: its creation wakes the executor to resume the task awaiting it.
    answered.add_done_callback(lambda _: None)
    done.add_done_callback(lambda ended: _settle(answered, ended))
    return answered


_SERVICE_QOS = QoSProfile(
    depth=qos_profile_parameters.depth,
    reliability=qos_profile_services_default.reliability,
    durability=qos_profile_services_default.durability,
)
"""Services' QoS: the default's, as deep as the parameter services'."""


def _failed(response, error: Exception):
    """`response` (a service's response or an action's result) saying that its handler failed with `error`, where it
    has the fields to say so."""
    text = f"failed: {type(error).__name__}: {error}"
    for field, value in (("success", False), ("message", text), ("error_string", text)):
        if hasattr(response, field):
            setattr(response, field, value)
    if hasattr(response, "error_code"):
        response.error_code = getattr(response, "INVALID_GOAL", -1)
    return response


class RosGroup:
    """A callback group of the rclpy transport: the executor's for subscriptions and services, a worker thread for
    timers (and, with transport both, for what arrives by Zenoh)."""

    def __init__(self, callbacks: MutuallyExclusiveCallbackGroup, worker: Worker) -> None:
        self.callbacks, self.worker = callbacks, worker


class RosTransport(WorkerGroups):
    """The transport of a LifecycleNode `node` (see `akd_ros.node.transports.transport.Transport`); its groups' timer
    threads are `WorkerGroups`'."""

    name = "rclpy"
    typestore = None

    def __init__(self, node) -> None:
        super().__init__(node.get_logger())
        self._node = node

    def message_class(self, type_name: str) -> type:
        return message_class(type_name)

    def publisher(self, type_name: str, topic: str, qos: Qos) -> _Publisher:
        return _Publisher(self._node, message_class(type_name), topic, qos_profile(qos))

    def subscription(
        self, type_name: str, topic: str, callback: Callable[[Any], None], qos: Qos, group: RosGroup
    ) -> str:
        subscription = self._node.create_subscription(
            message_class(type_name),
            topic,
            callback,
            qos_profile(qos),
            callback_group=group.callbacks,
            event_callbacks=SubscriptionEventCallbacks(use_default_callbacks=False),
        )
        return subscription.topic_name

    def service(self, type_name: str, name: str, handler: Callable[[Any, Any], Any], group: RosGroup) -> None:
        node = self._node

        async def serve(request, response):
            # The handler runs on the group's thread; the executor's takes the next message while it waits.
            try:
                return await _awaitable(node, group.worker.submit(handler, request, response))
            except Exception as e:  # noqa: BLE001  (a defect: the worker logged it; the caller still gets an answer)
                return _failed(response, e)

        # The group takes one request at a time, the others waiting in the service's queue meanwhile: as deep as ROS's
        # own parameter services have theirs, "so that requests do not get lost". A burst of calls overflowed the
        # default depth of 10, and a call dropped there is never answered.
        node.create_service(
            message_class(type_name), name, serve, qos_profile=_SERVICE_QOS, callback_group=group.callbacks
        )

    def action_server(self, type_name: str, name: str, callbacks: ActionCallbacks, group: RosGroup) -> type:
        from rclpy.action import ActionServer, CancelResponse, GoalResponse

        action = message_class(type_name)
        node, goal_thread = self._node, f"{group.worker.name}-goal"

        async def execute(handle):
            # A goal runs as long as its motion: on a thread of its own, so the executor's, which takes the commands,
            # never waits for it, and a newer goal's runs beside it to preempt it.
            try:
                return await _awaitable(node, in_thread(goal_thread, callbacks.execute, handle))
            except Exception as e:  # noqa: BLE001  (a defect: the goal still ends, with a result saying so)
                self.logger.error(f"{name}: goal failed: {type(e).__name__}: {e}")
                if handle.is_active:
                    handle.abort()
                return _failed(action.Result(), e)

        ActionServer(
            node,
            action,
            name,
            execute_callback=execute,
            goal_callback=lambda goal: GoalResponse.ACCEPT if callbacks.goal(goal) else GoalResponse.REJECT,
            cancel_callback=lambda handle: CancelResponse.ACCEPT if callbacks.cancel(handle) else CancelResponse.REJECT,
            callback_group=group.callbacks,
        )
        return action

    def watch_clients(self, callback: Callable[[str, str, bytes, str, list[str]], None]) -> None:
        """rclpy tells nothing of the graph's clients as they are made (and DDS here has no authentication)."""

    def timer(self, period: float, callback: Callable[[], None], group: RosGroup) -> None:
        group.worker.add_timer(period, callback)

    def group(self, name: str) -> RosGroup:
        return RosGroup(MutuallyExclusiveCallbackGroup(), super().group(name))

    def now_ns(self) -> int:
        return self._node.get_clock().now().nanoseconds

    def resolve(self, name: str) -> str:
        return self._node.resolve_topic_name(name)

    def sender(self) -> None:
        return None

    def caller(self, door: str, sender: bytes | None) -> str:
        """rclpy hands a callback no sender: its executor takes a request's header (the client's writer GUID) and
        passes it to send_response only, and a sample's to no one. So who it may be, from the graph, each writer
        with its GID: for a topic, the other publishers of it; for a service, its clients, the writers of the DDS
        topic a service's requests go on (rq/<name>Request, as ROS 2 maps a service onto DDS)."""
        own = (self._node.get_name(), self._node.get_namespace())
        for what, infos in (
            ("a publisher of the topic", lambda: self._node.get_publishers_info_by_topic(door)),
            (
                "a client of the service",
                lambda: self._node.get_publishers_info_by_topic(f"rq{door}Request", no_mangle=True),
            ),
        ):
            writers = sorted(
                {
                    f"{info.node_namespace.rstrip('/')}/{info.node_name} (gid {bytes(info.endpoint_gid).hex()})"
                    for info in infos()
                    if (info.node_name, info.node_namespace) != own
                }
            )
            if writers:
                return f"dds: {what}: {', '.join(writers)}"
        return "dds: unknown (rclpy gives a callback no sender, and the graph has no other writer of it)"

    def counters(self) -> dict[str, int]:
        return {}

    def recorded_class(self, type_name: str) -> type:
        return message_class(type_name)

    def recorded_qos(self, qos: Qos) -> QoSProfile:
        return qos_profile(qos)
