"""The node's parts over rclpy and Zenoh at once (`transport: both`): `BothTransport`.

rclpy's messages, timers and executor: a `RosTransport`; every publisher, subscription and service is also
declared on Zenoh in rmw_zenoh's wire format (`akd_ros.zenoh`). A message published goes out on both, as CDR on
Zenoh (the recorder's serialiser: rclpy's, trimmed to the CDR written); one arriving on Zenoh is read into rclpy's
class and handed to the same callback, on a worker thread of its callback group (`ZenohTransport`'s groups), so
callbacks of one group never overlap among those that came by Zenoh.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from akd_ros.node.transports.ros_transport import RosGroup, RosMessages, RosTransport
from akd_ros.node.transports.transport import Qos
from akd_ros.node.transports.zenoh_transport import ZenohTransport
from akd_ros.recorder import message_type


class _Publisher:
    def __init__(self, ros, zenoh) -> None:
        self._ros, self._zenoh = ros, zenoh
        self.topic_name, self.msg_type, self.qos = ros.topic_name, ros.msg_type, ros.qos
        self._serialize = message_type(self.msg_type).serialize

    def publish(self, message: Any) -> None:
        self._ros.publish(message)
        self._zenoh.publish_serialized(self._serialize(message))

    def publish_serialized(self, data: bytes) -> None:
        self._ros.publish_serialized(data)
        self._zenoh.publish_serialized(data)


class BothTransport(RosTransport):
    """The rclpy transport of the LifecycleNode `node` with `zenoh` beside it (see the module doc). Actions are served
    over rclpy only: rmw_zenoh's clients reach them through a router bridging DDS, not this Zenoh session."""

    name = "both"

    def __init__(self, node, zenoh: ZenohTransport) -> None:
        super().__init__(node)
        self.zenoh = zenoh
        self._messages = RosMessages()

    def publisher(self, type_name: str, topic: str, qos: Qos) -> _Publisher:
        return _Publisher(super().publisher(type_name, topic, qos), self.zenoh.publisher(type_name, topic, qos))

    def subscription(
        self, type_name: str, topic: str, callback: Callable[[Any], None], qos: Qos, group: RosGroup
    ) -> str:
        self.zenoh.subscription(type_name, topic, callback, qos, group.worker, self._messages)
        return super().subscription(type_name, topic, callback, qos, group)

    def service(self, type_name: str, name: str, handler: Callable[[Any, Any], Any], group: RosGroup) -> None:
        self.zenoh.service(type_name, name, handler, group.worker, self._messages)
        super().service(type_name, name, handler, group)

    def sender(self) -> bytes | None:
        return self.zenoh.sender()

    def caller(self, door: str, sender: bytes | None) -> str | None:
        return self.zenoh.caller(door, sender) if sender is not None else super().caller(door, None)

    def watch_clients(self, callback: Callable[[str, str, bytes, str, list[str]], None]) -> None:
        self.zenoh.watch_clients(callback)

    def counters(self) -> dict[str, int]:
        return self.zenoh.counters()
