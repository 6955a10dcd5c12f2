"""akd-top attached to a running akd_node over Zenoh, as rmw_zenoh's wire carries it, with no ROS install: a session
of its own (rmw_zenoh's default, connecting to the router at tcp/localhost:7447, or `connect`), a ZenohNode on the
domain of ROS_DOMAIN_ID, subscriptions decoded with the package's types, and service calls through the node's clients,
as an rmw_zenoh client makes them. While the session reaches no router, the bus line says so (nothing arrives without
one). See `attached` for what is read and called."""

from __future__ import annotations

from collections.abc import Callable

from akd_ros.node.zenoh_node import domain_id
from akd_ros.top.attached import AttachedSource
from akd_ros.top.source import BusRow
from akd_ros.zenoh.entities import Client, ZenohNode
from akd_ros.zenoh.session import connect_endpoints, open_session, session_config
from akd_ros.zenoh.types import Types
from akd_ros.zenoh.wire import QoS

# A bound on one service call (the node's requests wait at most 5 s for the drive).
CALL_TIMEOUT_S = 10.0
SUBSCRIPTION_QOS = QoS(depth=100)


class ZenohSource(AttachedSource):
    """akd_node `node` (its fully qualified name, /akd_node by default) over Zenoh; `connect`: the endpoints to
    connect to instead of rmw_zenoh's default router."""

    def __init__(self, node: str = "/akd_node", connect: list[str] | None = None) -> None:
        super().__init__(node)
        self._types = Types()
        config = session_config(None, connect)
        self._endpoints = ", ".join(connect_endpoints(config))
        self._session = open_session(config)
        self._node = ZenohNode(self._session, self._types, "akd_top", domain=domain_id())
        self._clients: dict[str, Client] = {}
        self.start()

    def subscribe(self, topic: str, ros_type: str, callback: Callable[[object], None]) -> None:
        decode = lambda cdr: self._types.from_cdr(cdr, ros_type)  # noqa: E731
        self._node.subscription(topic, ros_type, callback, SUBSCRIPTION_QOS, deserialize=decode)

    def call(self, service: str, ros_type: str, fields: dict):
        if service not in self._clients:
            self._clients[service] = self._node.client(service, ros_type)
        request_type, response_type = f"{ros_type}_Request", f"{ros_type}_Response"
        request = self._types.to_cdr(self._types.message(request_type, **fields), request_type)
        reply = self._clients[service].call(request, CALL_TIMEOUT_S)
        return None if reply is None else self._types.from_cdr(reply, response_type)

    def bus_row(self) -> BusRow:
        if not self._session.info.routers_zid():
            hint = (
                f"{self.node_name} (no Zenoh router reached at {self._endpoints}: start one, e.g. "
                ".venv/bin/akd-zenohd, or give --connect ENDPOINT)"
            )
            return BusRow(hint)
        return super().bus_row()

    def close(self) -> None:
        self._node.close()
        self._session.close()
