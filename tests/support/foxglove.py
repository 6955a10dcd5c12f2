"""A client of Foxglove's WebSocket protocol, as the Foxglove app speaks it to a live view: the protocol published as
foxglove.websocket.v1, which the foxglove-sdk's servers accept under the subprotocol name foxglove.sdk.v1 only (the
same messages; a client offering only the old name gets HTTP 400). What it speaks: the server's serverInfo, advertise
and status messages (JSON text), subscriptions, and binary message data frames (opcode 1: subscription id u32,
receive time ns u64, then the message), all little-endian. Messages are decoded with rosbags against the schema the
server advertised for their channel (ros2msg text, CDR).

Made on the `websockets` package's synchronous client; every wait is bounded by WAIT_S.
"""

from __future__ import annotations

import json
import socket
import struct
import time
from contextlib import ExitStack
from dataclasses import dataclass

from rosbags.typesys import Stores, get_types_from_msg, get_typestore
from websockets.exceptions import ConnectionClosed
from websockets.sync.client import connect

from support.ros import WAIT_S

SUBPROTOCOL = "foxglove.sdk.v1"
MESSAGE_DATA = 0x01
"""The opcode of a binary message data frame (server to client) and of a client's message data (client to server)."""
_DATA_HEADER = struct.Struct("<BIQ")


@dataclass(frozen=True)
class Channel:
    """A channel the server advertised."""

    id: int
    topic: str
    encoding: str
    schema_name: str
    schema: str
    schema_encoding: str


class FoxgloveClient:
    """One connection to the live view at `url`; `receive_buffer` bytes of socket receive buffer where given (a small
    one makes a client that stops reading stuck sooner)."""

    def __init__(self, url: str, receive_buffer: int | None = None) -> None:
        sock = None
        if receive_buffer is not None:
            host, port = url.removeprefix("ws://").rsplit(":", 1)
            sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, receive_buffer)
            sock.settimeout(WAIT_S)
            sock.connect((host, int(port)))
        self._closing = ExitStack()
        self.connection = self._closing.enter_context(
            connect(url, subprotocols=[SUBPROTOCOL], sock=sock, open_timeout=WAIT_S, max_size=None)
        )
        assert self.connection.subprotocol == SUBPROTOCOL, self.connection.subprotocol
        self.server_info: dict | None = None
        self.channels: dict[int, Channel] = {}
        self.texts: list[dict] = []
        """Every JSON message the server sent, in order."""
        self._subscriptions: dict[int, int] = {}
        self._decoders: dict[int, tuple] = {}

    @property
    def local_port(self) -> int:
        return self.connection.socket.getsockname()[1]

    def close(self) -> None:
        self._closing.close()

    def __enter__(self) -> FoxgloveClient:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def _take(self, frame) -> tuple[int, int, bytes] | None:
        """Files a text frame; a message data frame as (subscription, receive time ns, message)."""
        if isinstance(frame, str):
            message = json.loads(frame)
            self.texts.append(message)
            op = message["op"]
            if op == "serverInfo":
                self.server_info = message
            elif op == "advertise":
                for c in message["channels"]:
                    self.channels[c["id"]] = Channel(
                        c["id"], c["topic"], c["encoding"], c["schemaName"], c["schema"], c["schemaEncoding"]
                    )
            elif op == "unadvertise":
                for channel_id in message["channelIds"]:
                    self.channels.pop(channel_id, None)
            return None
        opcode, subscription, received_ns = _DATA_HEADER.unpack_from(frame)
        assert opcode == MESSAGE_DATA, f"unexpected binary opcode {opcode}"
        return subscription, received_ns, bytes(frame[_DATA_HEADER.size :])

    def pump(self, until, what: str, timeout: float = WAIT_S):
        """Reads frames until `until(data)` (data: a message data frame or None; None first, before any is read) gives
        something; that."""
        deadline = time.monotonic() + timeout
        result = until(None)
        while not result:
            left = deadline - time.monotonic()
            assert left > 0, f"no {what} within {timeout} s"
            try:
                frame = self.connection.recv(timeout=left)
            except TimeoutError:
                continue
            except ConnectionClosed as e:
                raise AssertionError(f"the live view closed the connection before {what}: {e}") from None
            result = until(self._take(frame))
        return result

    def topics(self, wanted: set[str]) -> dict[str, Channel]:
        """The advertised channels by topic, once every one of `wanted` is advertised."""

        def advertised(_):
            found = {c.topic: c for c in self.channels.values()}
            return found if self.server_info is not None and wanted <= set(found) else None

        return self.pump(advertised, f"advertisement of {sorted(wanted)}")

    def subscribe(self, channel: Channel) -> int:
        """Subscribes to `channel`; the subscription's id."""
        subscription = len(self._subscriptions) + 1
        self._subscriptions[subscription] = channel.id
        self.send({"op": "subscribe", "subscriptions": [{"id": subscription, "channelId": channel.id}]})
        return subscription

    def send(self, message: dict) -> None:
        self.connection.send(json.dumps(message))

    def decode(self, channel: Channel, data: bytes):
        """`data`, a message of `channel`, decoded with rosbags from the channel's advertised schema alone."""
        assert (channel.encoding, channel.schema_encoding) == ("cdr", "ros2msg"), channel
        if channel.id not in self._decoders:
            store = get_typestore(Stores.EMPTY)
            store.register(get_types_from_msg(channel.schema, channel.schema_name))
            self._decoders[channel.id] = (store, channel.schema_name)
        store, name = self._decoders[channel.id]
        return store.deserialize_cdr(data, name)

    def next_message(self, channel: Channel, subscription: int, timeout: float = WAIT_S):
        """The next message of `subscription` (of `channel`), decoded."""

        def of_subscription(data):
            return data if data is not None and data[0] == subscription else None

        _, _, data = self.pump(of_subscription, f"message on {channel.topic}", timeout)
        return self.decode(channel, data)

    def reply(self, op: str, containing: str, timeout: float = WAIT_S) -> dict:
        """The first message `op` (since the connection) whose text (`message`) contains `containing`."""

        def found(_):
            return next((t for t in self.texts if t["op"] == op and containing in t.get("message", "")), None)

        return self.pump(found, f"{op} message containing {containing!r}", timeout)

    def send_binary(self, opcode: int, *fields: int, data: bytes = b"") -> None:
        """A binary client message: `opcode`, then each of `fields` as u32, then `data`."""
        self.connection.send(struct.pack(f"<B{len(fields)}I", opcode, *fields) + data)
