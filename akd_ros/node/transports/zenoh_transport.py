"""The node's parts over Zenoh in rmw_zenoh's wire format, without rclpy: `ZenohTransport`, on an
`akd_ros.zenoh.ZenohNode`.

Messages are rosbags' classes of `akd_ros.zenoh.types.Types` (ROS 2 Jazzy's and the package's own), serialised to CDR
by rosbags. Zenoh calls back on its own threads; here each callback group is a `Worker` thread that runs its timers
and the callbacks handed to it one at a time, as rclpy's mutually exclusive callback groups do, so the parts see
the same concurrency on either transport. A service's handler runs on its group's thread while Zenoh's thread
waits for the reply.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from typing import Any, Protocol

from akd_ros.node.transports.transport import ActionCallbacks, Qos
from akd_ros.node.transports.worker import Worker, WorkerGroups
from akd_ros.zenoh.wire import Durability, Entity, EntityKind, QoS, Reliability


def zenoh_qos(qos: Qos) -> QoS:
    """rmw_zenoh's QoS profile of `qos`."""
    return QoS(
        reliability=Reliability.RELIABLE if qos.reliable else Reliability.BEST_EFFORT,
        durability=Durability.TRANSIENT_LOCAL if qos.transient_local else Durability.VOLATILE,
        depth=qos.depth,
    )


class Messages(Protocol):
    """How a Zenoh transport makes a message of a type by name and moves it to and from CDR: `akd_ros.zenoh.types.Types`
    (rosbags' classes) by default, rclpy's with transport both (`ros_transport.RosMessages`)."""

    def message(self, type_name: str) -> Any: ...

    def to_cdr(self, message: Any, type_name: str) -> bytes: ...

    def from_cdr(self, data: bytes, type_name: str) -> Any: ...


class _Publisher:
    def __init__(self, transport: ZenohTransport, type_name: str, topic: str, qos: Qos, publisher) -> None:
        self._transport, self._type_name = transport, type_name
        self.topic_name = transport.resolve(topic)
        self.msg_type = transport.types.store.types[type_name]
        self.qos = transport.recorded_qos(qos)
        self._publisher = publisher

    def publish(self, message: Any) -> None:
        self._publisher.publish(self._transport.types.to_cdr(message, self._type_name))

    def publish_serialized(self, data: bytes) -> None:
        self._publisher.publish(data)


class ZenohTransport(WorkerGroups):
    """The transport of `zenoh_node` (an `akd_ros.zenoh.ZenohNode` named `name`), logging to `logger` (see
    `akd_ros.node.transports.transport.Transport`); its groups are `WorkerGroups`'."""

    name = "zenoh"

    def __init__(self, zenoh_node, logger) -> None:
        super().__init__(logger)
        self._zenoh_node = zenoh_node
        self.types = zenoh_node.types
        self.typestore = self.types.store
        self._delivering = threading.local()
        """On a group's thread: the GID of the sender whose sample or request its callback handles."""

    def message_class(self, type_name: str) -> Callable[..., Any]:
        return self.types.message_class(type_name)

    def publisher(self, type_name: str, topic: str, qos: Qos) -> _Publisher:
        return _Publisher(self, type_name, topic, qos, self._zenoh_node.publisher(topic, type_name, zenoh_qos(qos)))

    def subscription(
        self,
        type_name: str,
        topic: str,
        callback: Callable[[Any], None],
        qos: Qos,
        group: Worker,
        messages: Messages | None = None,
    ) -> str:
        """As `Transport.subscription`; `messages` (default: this transport's rosbags types) reads each sample."""
        messages = messages or self.types
        # rosbags compiles a type's (de)serialiser at its first use: here, not in front of the first commands (or of
        # the recording of the first, which would hold up the second by milliseconds).
        messages.from_cdr(messages.to_cdr(messages.message(type_name), type_name), type_name)
        self._zenoh_node.subscription(
            topic,
            type_name,
            lambda message, gid: group.submit(self.delivering, gid, callback, message),
            zenoh_qos(qos),
            deserialize=lambda data: messages.from_cdr(data, type_name),
            with_gid=True,
        )
        return self.resolve(topic)

    def service(
        self,
        type_name: str,
        name: str,
        handler: Callable[[Any, Any], Any],
        group: Worker,
        messages: Messages | None = None,
    ) -> None:
        """As `Transport.service`; `messages` (default: this transport's rosbags types) reads each request and makes
        and writes its response."""
        messages = messages or self.types
        response_type = f"{type_name}_Response"

        def answer(request, gid: bytes) -> bytes:
            def run():
                response = self.delivering(gid, handler, request, messages.message(response_type))
                return messages.to_cdr(response, response_type)

            return group.submit(run).result()

        self._zenoh_node.service(
            name,
            type_name,
            answer,
            deserialize_request=lambda data: messages.from_cdr(data, f"{type_name}_Request"),
            with_gid=True,
        )

    def delivering(self, gid: bytes, callback: Callable[..., Any], *args: Any) -> Any:
        """Runs `callback(*args)` for a sample or request of the sender `gid`, which `caller` names meanwhile."""
        self._delivering.gid = gid
        try:
            return callback(*args)
        finally:
            self._delivering.gid = None

    def sender(self) -> bytes | None:
        """The GID of what the running callback handles; None outside a callback of this transport."""
        return getattr(self._delivering, "gid", None)

    def caller(self, door: str, sender: bytes | None) -> str | None:
        """Who `sender` is, as far as Zenoh tells (`ZenohNode.sender_of`)."""
        return None if sender is None else f"zenoh: {self._zenoh_node.sender_of(sender)}"

    def watch_clients(self, callback: Callable[[str, str, bytes, str, list[str]], None]) -> None:
        """As `Transport.watch_clients`: each publisher and service client of the graph's other sessions
        (`ZenohNode.watch`), its sender the GID its samples and requests carry."""
        kinds = {EntityKind.PUBLISHER: "publisher", EntityKind.CLIENT: "client"}

        def on_entity(entity: Entity, gid: bytes) -> None:
            if entity.kind in kinds and entity.topic is not None:
                certificates = self._zenoh_node.certificates(entity.zid)
                who = f"zenoh: {self._zenoh_node.who(entity)}"
                callback(entity.topic.name, kinds[entity.kind], gid, who, certificates)

        self._zenoh_node.watch(on_entity)

    def action_server(self, type_name: str, name: str, callbacks: ActionCallbacks, group: Worker) -> None:
        # rmw_zenoh carries an action as three services and two topics of types rosidl derives from the .action;
        # this transport does not build those types, so it serves no action rather than a wrong one.
        self.logger.warning(
            f"{self.resolve(name)} ({type_name}) is not served over Zenoh alone: actions need transport rclpy or both"
        )

    def timer(self, period: float, callback: Callable[[], None], group: Worker) -> None:
        group.add_timer(period, callback)

    def now_ns(self) -> int:
        return time.time_ns()

    def resolve(self, name: str) -> str:
        if name.startswith("~/"):
            return f"/{self._zenoh_node.info.name}/{name[2:]}"
        return name if name.startswith("/") else f"/{name}"

    def counters(self) -> dict[str, int]:
        return {"zenoh_dropped": self._zenoh_node.dropped()}

    def recorded_class(self, type_name: str) -> type:
        return self.types.store.types[type_name]

    def recorded_qos(self, qos: Qos) -> dict:
        return {
            "history": "keep_last",
            "depth": qos.depth,
            "reliability": "reliable" if qos.reliable else "best_effort",
            "durability": "transient_local" if qos.transient_local else "volatile",
        }
