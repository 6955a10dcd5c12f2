"""Which of the node's doors exist, and the audit of every request at a door that moves or configures a drive.

Every door has a role: a topic the node publishes is *observe*; a service that changes a drive's configuration
(CONFIGURING_SERVICES) is *configure*; every other door (the command topics, enable, disable, reset, quick stop, mode,
latches, outputs, trajectories, homing) is *operate*. The `doors` parameter names the roles whose doors exist;
configuring doors are closed unless it names them. A closed door is never declared: it is not advertised and nothing
answers it, on any transport. `Doors` is the transport the node's parts declare their doors on: it declares those of
the open roles and records each request at an operating or configuring door, accepted or refused, on ~/access (an
akd_ros/AccessRequest: the door, what was asked, the outcome and who asked, as far as the transport can tell), which
the bag records as it records everything published; it logs the first of each burst from one sender.

A client the middleware refuses before the node sees its requests is recorded too, as far as the middleware shows
it: over Zenoh with the access control `akd_ros.access` writes, a publisher of a command topic or a client of a
service made by a session whose certificate (the name of a role's client, CLIENTS) does not grant the door's role is
recorded refused when the graph announces it. Zenoh still drops what it sends; the node never sees what it asks.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from typing import Any

from akd_ros.node.transports.transport import ActionCallbacks, Qos, Transport
from akd_ros.params import DOOR_ROLES

OBSERVE, OPERATE, CONFIGURE = DOOR_ROLES
CLIENTS = {OBSERVE: "observer", OPERATE: "operator", CONFIGURE: "configurer"}
"""The certificate common name of each role's client: a client may use the doors of its role and of the roles before
it."""
CONFIGURING_SERVICES = ("sdo_write",)
"""The services that change a drive's configuration rather than move it."""
PUBLISHER, SUBSCRIPTION, SERVICE, ACTION = "publisher", "subscription", "service", "action"
"""The kinds of door."""
ACCESS_TOPIC = "~/access"
ACCESS_TYPE = "akd_ros/msg/AccessRequest"
BURST_GAP_S = 1.0
"""A sender's messages on one topic closer together than this are one burst, logged once."""
BURSTS_KEPT = 1024
"""How many (door, sender) bursts are remembered before the ended ones are forgotten."""
REQUEST_TEXT_MAX = 200
"""How much of a request its record keeps, in characters."""


def door_name(name: str) -> str:
    """The last part of a door's name (enable, position_command): a joint's door and the node's of the same name are
    the same door."""
    return name.rsplit("/", 1)[-1]


def role_of(kind: str, name: str) -> str:
    """The role of the door of `kind` named `name` (its last part decides: a joint's door and the node's of the same
    name are the same door)."""
    if kind == PUBLISHER:
        return OBSERVE
    if kind == SERVICE and door_name(name) in CONFIGURING_SERVICES:
        return CONFIGURE
    return OPERATE


def describe(message: Any) -> str:
    """What a request asked, in one line: its fields and their values, cut to REQUEST_TEXT_MAX characters."""
    if isinstance(message, str):
        return message
    fields = getattr(message, "__slots__", None) or getattr(message, "__dataclass_fields__", None) or ()
    text = ", ".join(f"{f.lstrip('_')}={getattr(message, f)!r}" for f in fields if not f.startswith("__"))
    return text if len(text) <= REQUEST_TEXT_MAX else text[: REQUEST_TEXT_MAX - 1] + "…"


class Doors:
    """The node's `transport` with the doors of the roles `open_roles` only, each request at an operating or
    configuring one recorded on ~/access (see the module doc). Everything else is the transport's own."""

    def __init__(self, transport: Transport, open_roles: tuple[str, ...]) -> None:
        self._transport, self.open_roles = transport, open_roles
        self.closed: list[str] = []
        """The doors not declared, by name."""
        self._record = transport.publisher(ACCESS_TYPE, ACCESS_TOPIC, Qos(depth=100))
        self._message = transport.message_class(ACCESS_TYPE)
        self._stamp = transport.message_class("builtin_interfaces/msg/Time")
        self._bursts: dict[tuple[str, bytes | None, bool], float] = {}
        self._lock = threading.Lock()
        self._operating: dict[tuple[str, str], str] = {}
        """The role of each open operating or configuring door, by its name and the kind of client that uses it."""

    def __getattr__(self, name: str) -> Any:
        return getattr(self._transport, name)

    def summary(self) -> str:
        """The open roles and the closed doors, in one line, for the log at start."""
        closed = sorted({door_name(name) for name in self.closed})
        shut = f"; closed: {', '.join(closed)} (doors: {', '.join(self.open_roles)})" if closed else ""
        return f"doors open on {self._transport.name}: {', '.join(self.open_roles)}{shut}"

    def _open(self, kind: str, name: str) -> str | None:
        """The door's role when it is open, else None (and the door noted closed)."""
        role = role_of(kind, name)
        if role in self.open_roles:
            return role
        self.closed.append(self._transport.resolve(name))
        return None

    def publisher(self, type_name: str, topic: str, qos: Qos):
        return self._transport.publisher(type_name, topic, qos)

    def subscription(self, type_name: str, topic: str, callback: Callable[[Any], None], qos: Qos, group: Any):
        role = self._open(SUBSCRIPTION, topic)
        if role is None:
            return self._transport.resolve(topic)
        door = self._transport.resolve(topic)
        self._operating[door, "publisher"] = role

        def audited(message) -> None:
            callback(message)
            # A topic's commands are many and the bag records each as received: a record, the first of a burst.
            self.record(door, role, message, True, "taken", every=False)

        return self._transport.subscription(type_name, topic, audited, qos, group)

    def service(self, type_name: str, name: str, handler: Callable[[Any, Any], Any], group: Any) -> None:
        role = self._open(SERVICE, name)
        if role is None:
            return
        door = self._transport.resolve(name)
        self._operating[door, "client"] = role

        def audited(request, response):
            response = handler(request, response)
            accepted = bool(getattr(response, "success", True))
            outcome = getattr(response, "message", "") or ("done" if accepted else "refused")
            self.record(door, role, request, accepted, outcome)
            return response

        self._transport.service(type_name, name, audited, group)

    def action_server(self, type_name: str, name: str, callbacks: ActionCallbacks, group: Any):
        role = self._open(ACTION, name)
        if role is None:
            return None
        door = self._transport.resolve(name)

        def goal(request) -> bool:
            accepted = callbacks.goal(request)
            outcome = "goal accepted" if accepted else "goal refused"
            self.record(door, role, request, accepted, outcome)
            return accepted

        audited = ActionCallbacks(goal=goal, execute=callbacks.execute, cancel=callbacks.cancel)
        return self._transport.action_server(type_name, name, audited, group)

    def watch_clients(self) -> None:
        """Records, from now on, each client the transport's access control refuses at an open door (see the module
        doc); called once every part has declared its doors."""
        self._transport.watch_clients(self._client_made)

    def _client_made(self, name: str, kind: str, sender: bytes, caller: str, certificates: list[str]) -> None:
        role = self._operating.get((name, kind))
        roles = [r for r in DOOR_ROLES if CLIENTS[r] in certificates]
        # A certificate of no role's name is not this authority's scheme, and a client behind a router shows none:
        # neither is judged here.
        if role is None or not roles or max(map(DOOR_ROLES.index, roles)) >= DOOR_ROLES.index(role):
            return
        dropped = "drops its samples" if kind == "publisher" else "keeps its requests from the node"
        self.record(
            name,
            role,
            f"made a {kind} of {name}",
            False,
            f"certificate {', '.join(certificates)} may not {role}: Zenoh's access control {dropped}",
            sender=sender,
            caller=caller,
        )

    def record(
        self,
        door: str,
        role: str,
        request: Any,
        accepted: bool,
        outcome: str,
        every: bool = True,
        sender: bytes | None = None,
        caller: str | None = None,
    ) -> None:
        """Records one request at `door` on ~/access (`every`: each one, else the first of each sender's burst),
        and logs the first of each burst. Called on the thread of the callback that handled it, after it, which
        tells the sender and the caller; or given them (`sender`, `caller`)."""
        # A burst is told by the sender's cheap mark; who it is may take a graph query: only for what is recorded,
        # never for each of a stream of commands.
        sender, now = sender or self._transport.sender(), time.monotonic()
        with self._lock:
            if len(self._bursts) >= BURSTS_KEPT:
                # Only a burst still going matters; a careless client may make a new sender for each request.
                self._bursts = {k: t for k, t in self._bursts.items() if now - t <= BURST_GAP_S}
            last, self._bursts[door, sender, accepted] = self._bursts.get((door, sender, accepted)), now
        first = last is None or now - last > BURST_GAP_S
        if not (every or first):
            return
        caller = caller or self._transport.caller(door, sender) or "unknown"
        stamp = self._transport.now_ns()
        self._record.publish(
            self._message(
                stamp=self._stamp(sec=stamp // 1_000_000_000, nanosec=stamp % 1_000_000_000),
                door=door,
                role=role,
                request=describe(request),
                accepted=accepted,
                outcome=outcome,
                caller=caller,
            )
        )
        if first:
            words = f"{door} ({role}) from {caller}: {'accepted' if accepted else 'refused'}, {outcome}"
            # rclpy ties a severity to each logging call site: one call per severity.
            if accepted:
                self._transport.logger.info(f"access: {words}")
            else:
                self._transport.logger.warning(f"access: {words}")
