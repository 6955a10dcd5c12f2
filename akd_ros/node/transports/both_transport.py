"""The node's parts over rclpy and Zenoh at once (`transport: both`): `BothTransport`.

rclpy's messages, timers and executor, as `RosTransport`; every publisher, subscription and service is also
declared on Zenoh in rmw_zenoh's wire format (`akd_ros.zenoh`). A message published goes out on both, as CDR on
Zenoh (the recorder's serialiser: rclpy's, trimmed to the CDR written); one arriving on Zenoh is read into rclpy's
class and handed to the same callback, on a worker thread of its callback group (`ZenohTransport`'s groups), so
callbacks of one group never overlap among those that came by Zenoh.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from akd_ros.node.transports.ros_transport import RosGroup, RosMessages, RosTransport
from akd_ros.node.transports.transport import ActionCallbacks, Qos
from akd_ros.node.transports.zenoh_transport import ZenohTransport
from akd_ros.recorder import message_type


class _Publisher:
    def __init__(self, both: BothTransport, type_name: str, topic: str, qos: Qos) -> None:
        self._ros = both.ros.publisher(type_name, topic, qos)
        self.topic_name, self.msg_type, self.qos = self._ros.topic_name, self._ros.msg_type, self._ros.qos
        self._serialize = message_type(self.msg_type).serialize
        self._zenoh = both.zenoh.publisher(type_name, topic, qos)

    def publish(self, message: Any) -> None:
        self._ros.publish(message)
        self._zenoh.publish_serialized(self._serialize(message))

    def publish_serialized(self, data: bytes) -> None:
        self._ros.publish_serialized(data)
        self._zenoh.publish_serialized(data)


class BothTransport:
    """`ros` (on the node's LifecycleNode) with `zenoh` beside it (see the module doc)."""

    name = "both"
    typestore = None

    def __init__(self, ros: RosTransport, zenoh: ZenohTransport) -> None:
        self.ros, self.zenoh = ros, zenoh
        self.logger = ros.logger
        self._messages = RosMessages()

    def start(self) -> None:
        self.ros.start()

    def close(self) -> None:
        self.ros.close()

    def message_class(self, type_name: str) -> type:
        return self.ros.message_class(type_name)

    def publisher(self, type_name: str, topic: str, qos: Qos) -> _Publisher:
        return _Publisher(self, type_name, topic, qos)

    def subscription(
        self, type_name: str, topic: str, callback: Callable[[Any], None], qos: Qos, group: RosGroup
    ) -> str:
        self.zenoh.subscription(type_name, topic, callback, qos, group.worker, self._messages)
        return self.ros.subscription(type_name, topic, callback, qos, group)

    def service(self, type_name: str, name: str, handler: Callable[[Any, Any], Any], group: RosGroup) -> None:
        self.zenoh.service(type_name, name, handler, group.worker, self._messages)
        self.ros.service(type_name, name, handler, group)

    def action_server(self, type_name: str, name: str, callbacks: ActionCallbacks, group: RosGroup) -> type:
        # Served over rclpy only: rmw_zenoh's clients reach it through a router bridging DDS, not this Zenoh session.
        return self.ros.action_server(type_name, name, callbacks, group)

    def sender(self) -> bytes | None:
        return self.zenoh.sender()

    def caller(self, door: str, sender: bytes | None) -> str | None:
        return self.zenoh.caller(door, sender) if sender is not None else self.ros.caller(door, None)

    def watch_clients(self, callback: Callable[[str, str, bytes, str, list[str]], None]) -> None:
        self.zenoh.watch_clients(callback)

    def timer(self, period: float, callback: Callable[[], None], group: RosGroup) -> None:
        self.ros.timer(period, callback, group)

    def group(self, name: str) -> RosGroup:
        return self.ros.group(name)

    def now_ns(self) -> int:
        return self.ros.now_ns()

    def resolve(self, name: str) -> str:
        return self.ros.resolve(name)

    def counters(self) -> dict[str, int]:
        return self.zenoh.counters()

    def recorded_class(self, type_name: str) -> type:
        return self.ros.recorded_class(type_name)

    def recorded_qos(self, qos: Qos) -> Any:
        return self.ros.recorded_qos(qos)
