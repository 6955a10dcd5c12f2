"""The live view (`live_view.port`): everything the node publishes, served to Foxglove over its WebSocket protocol
(foxglove.websocket.v1) by the foxglove-sdk, for watching only.

Every topic is in it by construction: `LiveView.transport` wraps the node's transport, and each publisher a part makes
through it is also a channel of the view, of the topic's ROS type: schema encoding ros2msg, the type's complete
definition with its dependencies as rosbag2 stores it (`akd_ros.recorder.message_type`, the recorder's own), message
encoding cdr. A message the crate made (/joint_states, the statuses, ~/io, /diagnostics: `publish_serialized`) goes to
the view as the very bytes the middleware gets; a message object (latches, faults, trajectory status) is serialised
by the recorder's serialiser, and only while a client is subscribed to its channel. A publication a part adds later
(the line's counters, say) is in the view with nothing more to do.

Never in the node's way. Logging to a channel hands the bytes to the SDK's queue of each subscribed client and
returns: the queue is bounded (BACKLOG messages a client, its oldest dropped when full), and the sockets are written by
the SDK's own threads (a tokio runtime in Rust, without the GIL). No Python callback is given to the server, so no
Python runs on those threads but the forwarding of the SDK's warnings to the node's log. A slow or stuck client loses
its oldest messages; it never holds up the publishing thread, a timer or a command, which take no part in serving.

View only. The server is started with no capability: no client publishing, no services, no parameters, no connection
graph. The SDK answers a client's advertise, service call or parameter request with an error status and keeps nothing
it sends, so a live view is no way to move the arm. It listens on `live_view.address`, this machine only by default.

The server opens at configure, before anything else (a port in use or an address not of this machine fails the
configure with one line, nothing else opened), and closes at cleanup. With the live view off (port 0) the node imports
neither this module nor foxglove, and starts no thread for it.
"""

from __future__ import annotations

import logging
from typing import Any

import foxglove

from akd_ros.node.node_state import NODE_NAME
from akd_ros.node.transports.transport import Qos, Transport
from akd_ros.recorder import MessageType, message_type

BACKLOG = 1024
"""Messages queued for one client at most before its oldest are dropped: about five seconds of a six-joint node at
its default rates (/joint_states at 100 Hz, each joint's status and ~/io at 10 Hz), some 0.5 MB."""
SCHEMA_ENCODING, MESSAGE_ENCODING = "ros2msg", "cdr"
"""How the channels describe their messages: ROS 2 .msg definitions, CDR as the middleware carries it."""


class LiveViewError(OSError):
    """The live view could not open; the message says where and why."""


class _ViewedPublisher:
    """A publisher of the node's transport whose messages also go to the live view's `channel`."""

    def __init__(self, publisher, channel: foxglove.Channel, described: MessageType) -> None:
        self._publisher, self._channel, self._serialize = publisher, channel, described.serialize
        self.topic_name, self.msg_type, self.qos = publisher.topic_name, publisher.msg_type, publisher.qos

    def publish(self, message: Any) -> None:
        self._publisher.publish(message)
        if self._channel.has_sinks():
            self._channel.log(self._serialize(message))

    def publish_serialized(self, data: bytes) -> None:
        self._publisher.publish_serialized(data)
        self._channel.log(data)


class _ViewedTransport:
    """The node's transport, each of its publishers also a channel of the live view (see the module doc); everything
    else is the transport's own."""

    def __init__(self, transport: Transport, view: LiveView) -> None:
        self._transport, self._view = transport, view

    def __getattr__(self, name: str) -> Any:
        return getattr(self._transport, name)

    def publisher(self, type_name: str, topic: str, qos: Qos):
        return self._view.channel_of(self._transport.publisher(type_name, topic, qos))


class _ToNodeLog(logging.Handler):
    """The SDK's warnings and errors (it logs through Python's logging) as warnings of the node's log: what goes
    wrong there is a client's (a failed handshake, a client dropped), never the drives'."""

    def __init__(self, logger) -> None:
        super().__init__(logging.WARNING)
        self._logger = logger

    def emit(self, record: logging.LogRecord) -> None:
        self._logger.warning(f"live view: {record.getMessage()}")


class LiveView:
    """The live view of a node whose parts run on `transport` (they are given `self.transport` instead), listening on
    `where` (address, port) once `open()`ed; see the module doc."""

    def __init__(self, where: tuple[str, int], transport: Transport) -> None:
        self.address, self.port = where
        self._logger = transport.logger
        self._typestore = transport.typestore
        self._context = foxglove.Context()
        self._described: dict[type, MessageType] = {}
        self._server = None
        self.transport = _ViewedTransport(transport, self)
        """The transport the node's parts are built on."""
        sdk_log = logging.getLogger("foxglove")
        sdk_log.setLevel(logging.WARNING)
        sdk_log.propagate = False
        sdk_log.handlers = [_ToNodeLog(self._logger)]

    @property
    def url(self) -> str:
        """Where a client connects, e.g. ws://127.0.0.1:8765."""
        host = f"[{self.address}]" if ":" in self.address else self.address
        return f"ws://{host}:{self.port}"

    def channel_of(self, publisher) -> _ViewedPublisher:
        """`publisher` (of the node's transport) with a channel of the view beside it."""
        kind = publisher.msg_type
        described = self._described.get(kind)
        if described is None:
            described = self._described[kind] = message_type(kind, self._typestore)
        schema = foxglove.Schema(name=described.name, encoding=SCHEMA_ENCODING, data=described.definition.encode())
        channel = foxglove.Channel(
            publisher.topic_name, schema=schema, message_encoding=MESSAGE_ENCODING, context=self._context
        )
        return _ViewedPublisher(publisher, channel, described)

    def open(self) -> None:
        """Starts serving; LiveViewError when it cannot listen (the port in use, an address not of this machine)."""
        if self._server is not None:
            return
        try:
            self._server = foxglove.start_server(
                name=NODE_NAME,
                host=self.address,
                port=self.port,
                capabilities=[],
                context=self._context,
                message_backlog_size=BACKLOG,
            )
        except RuntimeError as e:
            raise LiveViewError(
                f"the live view did not open on {self.url}: {e}; give live_view.port a free port (0 for no live view) "
                "and live_view.address an address of this machine"
            ) from None
        self._logger.info(f"live view: Foxglove WebSocket on {self.url}, view only")

    def close(self) -> None:
        """Stops serving (its clients are disconnected); `open()` serves again."""
        server, self._server = self._server, None
        if server is not None:
            server.stop()
