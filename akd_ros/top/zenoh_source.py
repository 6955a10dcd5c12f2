"""akd-top attached to a running akd_node over Zenoh, as rmw_zenoh's wire carries it, with no ROS install: a session
of its own (rmw_zenoh's default, connecting to the router at tcp/localhost:7447, or `connect`), a ZenohNode on the
domain of ROS_DOMAIN_ID, subscriptions decoded with the package's types, and service calls as an rmw_zenoh client
makes them (a query with the request, its sequence number and the client's GID in the attachment). See `attached`
for what is read and called."""

from __future__ import annotations

import itertools
import os
import time
from collections.abc import Callable

from akd_ros.node.zenoh_node import domain_id
from akd_ros.top.attached import AttachedSource
from akd_ros.zenoh.entities import ZenohNode
from akd_ros.zenoh.session import open_session, session_config
from akd_ros.zenoh.types import Types
from akd_ros.zenoh.wire import Attachment, QoS, data_key_expr, dds_type_name

# A bound on one service call (the node's requests wait at most 5 s for the drive).
CALL_TIMEOUT_S = 10.0
SUBSCRIPTION_QOS = QoS(depth=100)


class ZenohSource(AttachedSource):
    """akd_node `node` (its fully qualified name, /akd_node by default) over Zenoh; `connect`: the endpoints to
    connect to instead of rmw_zenoh's default router."""

    def __init__(self, node: str = "/akd_node", connect: list[str] | None = None) -> None:
        super().__init__(node)
        self._types = Types()
        self._domain = domain_id()
        self._session = open_session(session_config(None, connect))
        self._node = ZenohNode(self._session, self._types, "akd_top", domain=self._domain)
        # The GID an rmw_zenoh client sends with each request, the node's reply carries it back.
        self._gid = os.urandom(16)
        self._numbers = itertools.count(1)
        self.start()

    def subscribe(self, topic: str, ros_type: str, callback: Callable[[object], None]) -> None:
        decode = lambda cdr: self._types.from_cdr(cdr, ros_type)  # noqa: E731
        self._node.subscription(topic, ros_type, callback, SUBSCRIPTION_QOS, deserialize=decode)

    def call(self, service: str, ros_type: str, fields: dict):
        key = data_key_expr(self._domain, service, dds_type_name(ros_type), self._types.rihs01(ros_type))
        request_type, response_type = f"{ros_type}_Request", f"{ros_type}_Response"
        request = self._types.to_cdr(self._types.message(request_type, **fields), request_type)
        attachment = Attachment(next(self._numbers), time.time_ns(), self._gid).encode()
        replies = list(self._session.get(key, payload=request, attachment=attachment, timeout=CALL_TIMEOUT_S))
        answers = [r.ok for r in replies if r.ok is not None]
        if not answers:
            return None
        return self._types.from_cdr(answers[0].payload.to_bytes(), response_type)

    def close(self) -> None:
        self._node.close()
        self._session.close()
