"""What the node's parts need of a middleware, so the same parts run over rclpy (DDS), over Zenoh in rmw_zenoh's wire
format without any ROS install, or over both.

A transport builds messages of a ROS type by name (`message_class`), makes publishers, subscriptions, services and
timers, logs, and tells the ROS time. The parts never import a middleware: they ask their transport. Messages are
built whole, every field given to the constructor (a Zenoh transport's message classes convert sequences there).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Protocol


@dataclass(frozen=True)
class Qos:
    """The QoS of a topic as the node uses it: keep-last `depth`, reliable or best effort, volatile or transient
    local."""

    depth: int
    reliable: bool = True
    transient_local: bool = False


@dataclass(frozen=True)
class ActionCallbacks:
    """What an action server calls, as rclpy's ActionServer does: `goal(goal) -> bool` accepts or rejects a goal,
    `execute(handle) -> result` runs an accepted one (handle.request, publish_feedback, is_cancel_requested,
    succeed/abort/canceled), `cancel(handle) -> bool` accepts or rejects a cancel request."""

    goal: Callable[[Any], bool]
    execute: Callable[[Any], Any]
    cancel: Callable[[Any], bool]


class Publisher(Protocol):
    """A publisher of one topic."""

    topic_name: str
    """The topic's absolute name."""
    msg_type: type
    """The class of its messages."""
    qos: Any
    """Its QoS as the recorder takes it (`Transport.recorded_qos`)."""

    def publish(self, message: Any) -> None:
        """Sends `message`."""

    def publish_serialized(self, data: bytes) -> None:
        """Sends a message given serialised as rmw publishes it (CDR behind its encapsulation header), e.g. made by
        the crate (`akd_ros._native.Feed`): nothing is built or serialised in Python."""


class Transport(Protocol):
    """A middleware the node's parts run on (see the module doc)."""

    logger: Any
    """With info, warning and error(text)."""
    typestore: Any
    """The rosbags typestore its messages are of, for the recorder; None for rosidl-generated ones."""

    def start(self) -> None:
        """Starts what runs the callbacks (the groups' threads), once the parts are made."""

    def close(self) -> None:
        """Stops it."""

    def message_class(self, type_name: str) -> Callable[..., Any]:
        """The class (or factory) of ROS type `type_name`, e.g. "sensor_msgs/msg/JointState"; called with fields as
        keyword arguments, the others take their defaults."""

    def publisher(self, type_name: str, topic: str, qos: Qos) -> Publisher:
        """A publisher of `type_name` on `topic` (absolute, or ~/ for the node's own)."""

    def subscription(self, type_name: str, topic: str, callback: Callable[[Any], None], qos: Qos, group: Any) -> str:
        """Calls `callback(message)` for each message on `topic`; gives the topic's absolute name."""

    def service(self, type_name: str, name: str, handler: Callable[[Any, Any], Any], group: Any) -> None:
        """Serves `name` of service type `type_name` ("pkg/srv/Name"): `handler(request, response)` fills and returns
        the response."""

    def action_server(self, type_name: str, name: str, callbacks: ActionCallbacks, group: Any) -> Any | None:
        """Serves action `name` of type `type_name` ("pkg/action/Name") with `callbacks`; gives the action's class
        (its Goal, Feedback and Result), or None where this transport serves no action (it says so in the log)."""

    def sender(self) -> bytes | None:
        """What tells apart the sender of the sample or request the running callback handles, at no cost (over Zenoh
        its GID); None where the middleware tells nothing."""

    def caller(self, door: str, sender: bytes | None) -> str | None:
        """Who `sender` (`sender()` of a callback of `door`) is, as far as the middleware tells; it may ask the
        graph, so it is called only for what is recorded."""

    def watch_clients(self, callback: Callable[[str, str, bytes, str, list[str]], None]) -> None:
        """Calls `callback(name, kind, sender, caller, certificates)`, on a thread of the middleware's, for each
        client the middleware sees made before it sends anything: a publisher of topic `name` or a client of service
        `name` (`kind` "publisher" or "client"), `sender` telling it apart as `sender()` does, `caller` who it is,
        `certificates` the names the certificates of its authenticated links to the node give. Over Zenoh from the
        graph's liveliness tokens; rclpy tells nothing of it and never calls."""

    def timer(self, period: float, callback: Callable[[], None], group: Any) -> None:
        """Calls `callback` every `period` seconds."""

    def group(self, name: str) -> Any:
        """A callback group named `name` (its thread's name: akd-`name`): callbacks of one group never run at the same
        time; of different groups they may."""

    def now_ns(self) -> int:
        """ROS time now, in nanoseconds."""

    def resolve(self, name: str) -> str:
        """The absolute name of topic `name`."""

    def counters(self) -> dict[str, int]:
        """The middleware's own counters for /diagnostics (e.g. samples dropped), by name."""

    def recorded_class(self, type_name: str) -> type:
        """The class of `type_name`'s messages (what `message_class` makes), as the recorder checks them."""

    def recorded_qos(self, qos: Qos) -> Any:
        """`qos` as `akd_ros.recorder.Recorder.add_topic` takes it."""
