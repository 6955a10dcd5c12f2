"""What a node offers, as its parts declare it: every topic it publishes or takes, every service and every action it
serves, with its type and QoS (`declared`).

The parts are built over `Noting`, a transport that takes note of each publisher, subscription, service and action
server instead
of opening it, and that runs nothing (no timer, no callback, no bus): the same constructors the running node calls,
so the list is the code's own. The documentation's reference of topics and services is generated from it, and
`tests/test_docs_reference.py` compares it with a running node's graph. No ROS is needed: messages are rosbags'
(`akd_ros.zenoh.types`), as on the Zenoh transport.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from akd_ros.node.node_state import NODE_NAME
from akd_ros.node.transports.transport import Qos
from akd_ros.params import Settings
from akd_ros.zenoh.types import Types

PUBLISHER, SUBSCRIPTION, SERVICE, ACTION = "publisher", "subscription", "service", "action"
"""The kinds of `Endpoint`."""


@dataclass(frozen=True)
class Endpoint:
    """One door of the node: a topic it publishes or subscribes to, or a service or an action it serves."""

    kind: str
    """PUBLISHER, SUBSCRIPTION, SERVICE or ACTION."""
    name: str
    """Its absolute name, e.g. /akd_node/joint_1/status."""
    type_name: str
    """Its ROS type, e.g. akd_ros/msg/DriveStatus, std_srvs/srv/Trigger or akd_ros/action/Home."""
    qos: Qos | None = None
    """A topic's QoS as the node gives it; None for a service or an action."""


class _Publisher:
    def __init__(self, transport: Noting, type_name: str, topic: str) -> None:
        self.topic_name = transport.resolve(topic)
        self.msg_type = transport.recorded_class(type_name)
        self.qos = None

    def publish(self, message: Any) -> None:
        raise RuntimeError(f"{self.topic_name}: a noted publisher publishes nothing")


class _Silent:
    """A logger that keeps nothing: building the parts logs nothing worth keeping."""

    def info(self, text: str) -> None:
        pass

    warning = error = info


class Noting:
    """A transport (`akd_ros.node.transports.transport.Transport`) that notes what the parts declare in `endpoints`
    and runs nothing; `node_name` resolves ~/ names as the node's own."""

    name = "no transport (noted)"
    typestore = None

    def __init__(self, types: Types, node_name: str = NODE_NAME) -> None:
        self.types = types
        self.node_name = node_name
        self.logger = _Silent()
        self.endpoints: list[Endpoint] = []

    def start(self) -> None:
        raise RuntimeError("a Noting transport runs nothing")

    def close(self) -> None:
        pass

    def message_class(self, type_name: str) -> Callable[..., Any]:
        return self.types.message_class(type_name)

    def publisher(self, type_name: str, topic: str, qos: Qos) -> _Publisher:
        publisher = _Publisher(self, type_name, topic)
        self.endpoints.append(Endpoint(PUBLISHER, publisher.topic_name, type_name, qos))
        return publisher

    def subscription(self, type_name: str, topic: str, callback: Callable[[Any], None], qos: Qos, group: Any) -> str:
        name = self.resolve(topic)
        self.endpoints.append(Endpoint(SUBSCRIPTION, name, type_name, qos))
        return name

    def service(self, type_name: str, name: str, handler: Callable[[Any, Any], Any], group: Any) -> None:
        self.endpoints.append(Endpoint(SERVICE, self.resolve(name), type_name))

    def action_server(self, type_name: str, name: str, callbacks: Any, group: Any) -> None:
        self.endpoints.append(Endpoint(ACTION, self.resolve(name), type_name))

    def timer(self, period: float, callback: Callable[[], None], group: Any) -> None:
        pass

    def sender(self) -> None:
        return None

    def caller(self, door: str, sender: bytes | None) -> str:
        return ""

    def watch_clients(self, callback: Callable[..., None]) -> None:
        pass

    def group(self, name: str) -> None:
        return None

    def now_ns(self) -> int:
        return 0

    def resolve(self, name: str) -> str:
        if name.startswith("~/"):
            return f"/{self.node_name}/{name[2:]}"
        return name if name.startswith("/") else f"/{name}"

    def counters(self) -> dict[str, int]:
        return {}

    def recorded_class(self, type_name: str) -> type:
        return self.types.store.types[type_name]

    def recorded_qos(self, qos: Qos) -> Qos:
        return qos


def declared(settings: Settings, types: Types | None = None, node_name: str = NODE_NAME) -> list[Endpoint]:
    """Every topic, service and action of a node with `settings` named `node_name`, in the order its parts declare them;
    `types` (a `Types`, which takes a second or so to build) may be shared between calls."""
    from akd_ros.node.core import Core

    transport = Noting(types or Types(), node_name)
    Core(transport, settings)
    return transport.endpoints
