"""A ROS node's publishers, subscriptions, services and service clients over one Zenoh session, as rmw_zenoh puts
them on the wire.

Each entity declares its liveliness token (so graph tools on an rmw_zenoh system list it) and uses its data key
expression; every sample, query and reply carries rmw_zenoh's attachment. What arrives without a valid
attachment, or with a payload its type rejects, is dropped as rmw_zenoh drops it; here it is also counted per
reason and logged once per entity, so that a misbehaving peer is visible without flooding the log.

QoS maps as rmw_zenoh maps it: reliability to Zenoh's, congestion control `block` only for reliable keep-all
(`drop` otherwise, so a slow subscriber never stalls the publisher), and transient-local topics through
zenoh-ext's advanced publisher (a cache of the history depth, publisher detection, and for reliable ones
sporadic heartbeats for miss detection) and advanced subscriber (late-publisher detection querying that history,
heartbeat recovery when reliable).

The payloads are plain bytes (CDR with its encapsulation header); `akd_ros.zenoh.types` makes and reads them.
One `ZenohNode` per session: rmw_zenoh numbers the nodes and entities of a session from one counter, which the
node owns here.
"""

from __future__ import annotations

import itertools
import threading
import time
from collections import Counter
from collections.abc import Callable

import zenoh
import zenoh.ext

from akd_ros.zenoh.types import Types
from akd_ros.zenoh.wire import (
    ADMIN_SPACE,
    SERVICES_QOS,
    Attachment,
    Durability,
    Entity,
    EntityKind,
    History,
    NodeInfo,
    QoS,
    Reliability,
    TopicInfo,
    dds_type_name,
    fully_qualified_name,
    gid_of,
    node_entity,
)

Log = Callable[[str], None]
# The period rmw_zenoh gives a reliable transient-local publisher's sporadic heartbeat (500 ms).
HEARTBEAT_PERIOD = 0.5
SENDER_QUERY_S = 1.0
"""How long `ZenohNode.sender_of` waits for the graph's liveliness tokens."""
SENDERS_KEPT = 256
"""How many senders `ZenohNode.sender_of` keeps named before it asks the graph afresh."""
# How many queries a keep-all service holds while its handler is busy (the client then waits, as Zenoh blocks).
KEEP_ALL_QUERIES = 1024


def publisher_options(qos: QoS) -> dict[str, object]:
    """Zenoh's publisher options for a ROS QoS profile, as rmw_zenoh chooses them."""
    reliable = qos.reliability is Reliability.RELIABLE
    return {
        "reliability": zenoh.Reliability.RELIABLE if reliable else zenoh.Reliability.BEST_EFFORT,
        "congestion_control": (
            zenoh.CongestionControl.BLOCK
            if reliable and qos.history is History.KEEP_ALL
            else zenoh.CongestionControl.DROP
        ),
    }


class Dropped:
    """What an entity dropped, by reason, logging only the first drop."""

    def __init__(self, what: str, log: Log) -> None:
        self.counts: Counter[str] = Counter()
        self._what = what
        self._log = log

    @property
    def total(self) -> int:
        """All drops so far."""
        return sum(self.counts.values())

    def __call__(self, reason: str, detail: str) -> None:
        first = reason not in self.counts
        self.counts[reason] += 1
        if first:
            self._log(f"{self._what}: dropped {detail}; later drops like it are counted, not logged")


def _accepted(
    carrier: zenoh.Sample | zenoh.Query, deserialize: Callable[[bytes], object], dropped: Dropped, what: str
) -> tuple[Attachment, object] | None:
    """A sample's or query's attachment and deserialized payload, or None when it is dropped (and counted)."""
    raw = carrier.attachment
    if raw is None:
        dropped("no_attachment", f"a {what} without an attachment")
        return None
    try:
        attachment = Attachment.decode(raw.to_bytes())
    except ValueError as error:
        dropped("bad_attachment", f"a {what} with a malformed attachment ({error})")
        return None
    payload = carrier.payload
    try:
        return attachment, deserialize(b"" if payload is None else payload.to_bytes())
    except ValueError as error:
        dropped("bad_payload", f"a {what} whose payload is not valid ({error})")
        return None


class _Receiver:
    """A subscription's or a service's entity, what it dropped, and what it calls: `_callback(message, gid)`."""

    def __init__(
        self, entity: Entity, kind: str, callback: Callable, deserialize: Callable, log: Log, with_gid: bool
    ) -> None:
        assert entity.topic is not None
        self.entity = entity
        self.key_expr = entity.data_key_expr()
        self.dropped = Dropped(f"{kind} {entity.topic.name}", log)
        self._deserialize = deserialize
        self._callback = callback if with_gid else lambda message, gid: callback(message)


class Publisher:
    """A topic's publisher: `publish` puts CDR bytes with the attachment (sequence numbers from 1, the system
    clock's time, the publisher's GID)."""

    def __init__(self, session: zenoh.Session, entity: Entity) -> None:
        assert entity.topic is not None
        self.entity = entity
        self.key_expr = entity.data_key_expr()
        self.gid = entity.gid
        qos = entity.topic.qos
        options = publisher_options(qos)
        if qos.durability is Durability.TRANSIENT_LOCAL:
            reliable = qos.reliability is Reliability.RELIABLE
            self._publisher = zenoh.ext.declare_advanced_publisher(
                session,
                self.key_expr,
                cache=zenoh.ext.CacheConfig(max_samples=qos.depth),
                publisher_detection=True,
                sample_miss_detection=(
                    zenoh.ext.MissDetectionConfig(heartbeat=None, sporadic_heartbeat=HEARTBEAT_PERIOD)
                    if reliable
                    else None
                ),
                **options,
            )
        else:
            self._publisher = session.declare_publisher(self.key_expr, **options)
        self._token = session.liveliness().declare_token(entity.liveliness_key())
        self._lock = threading.Lock()
        self._sequence_number = 0

    def publish(self, cdr: bytes) -> int:
        """Puts one sample; returns its sequence number."""
        with self._lock:
            self._sequence_number += 1
            attachment = Attachment(self._sequence_number, time.time_ns(), self.gid)
            self._publisher.put(bytes(cdr), attachment=attachment.encode())
            return self._sequence_number

    def close(self) -> None:
        """Withdraws the token and the publisher."""
        self._token.undeclare()
        self._publisher.undeclare()


class Subscription(_Receiver):
    """A topic's subscription: callback(message) for each sample with a valid attachment whose payload
    `deserialize` accepts (raising ValueError otherwise); message is what deserialize returns, by default the
    CDR bytes themselves. `with_gid`: callback(message, gid), gid the sender's GID its attachment gives."""

    def __init__(
        self,
        session: zenoh.Session,
        entity: Entity,
        callback: Callable[[object], None],
        deserialize: Callable[[bytes], object],
        log: Log,
        with_gid: bool = False,
    ) -> None:
        super().__init__(entity, "subscription", callback, deserialize, log, with_gid)
        self.received = 0
        qos = entity.topic.qos
        if qos.durability is Durability.TRANSIENT_LOCAL:
            reliable = qos.reliability is Reliability.RELIABLE
            self._subscriber = zenoh.ext.declare_advanced_subscriber(
                session,
                self.key_expr,
                self._on_sample,
                history=zenoh.ext.HistoryConfig(detect_late_publishers=True, max_samples=qos.depth),
                recovery=zenoh.ext.RecoveryConfig(periodic_queries=None, heartbeat=True) if reliable else None,
                subscriber_detection=True,
            )
        else:
            self._subscriber = session.declare_subscriber(self.key_expr, self._on_sample)
        self._token = session.liveliness().declare_token(entity.liveliness_key())

    def _on_sample(self, sample: zenoh.Sample) -> None:
        if accepted := _accepted(sample, self._deserialize, self.dropped, "sample"):
            self.received += 1
            self._callback(accepted[1], accepted[0].gid)

    def close(self) -> None:
        """Withdraws the token and the subscriber."""
        self._token.undeclare()
        self._subscriber.undeclare()


class Service(_Receiver):
    """A service server: a complete queryable whose queries, each with a client's attachment, are answered by
    handler(request) -> reply CDR bytes on a thread of the service's own (a handler may wait for the drive
    without holding up Zenoh's threads). The reply carries the request's sequence number and the client's GID,
    which is how an rmw_zenoh client matches it to its request. request is what deserialize_request returns, by
    default the CDR bytes; `with_gid`: handler(request, gid), gid the client's GID. Queries beyond the history
    depth waiting for the handler drop the oldest, as rmw_zenoh does."""

    def __init__(
        self,
        session: zenoh.Session,
        entity: Entity,
        handler: Callable[[object], bytes],
        deserialize_request: Callable[[bytes], object],
        log: Log,
        with_gid: bool = False,
    ) -> None:
        super().__init__(entity, "service", handler, deserialize_request, log, with_gid)
        self.answered = 0
        qos = entity.topic.qos
        # Keep-all queues without dropping (to a bound, where rmw_zenoh has none); keep-last drops the oldest.
        keep_all = qos.history is History.KEEP_ALL
        channel = zenoh.handlers.FifoChannel(KEEP_ALL_QUERIES) if keep_all else zenoh.handlers.RingChannel(qos.depth)
        self._queryable = session.declare_queryable(self.key_expr, channel, complete=True)
        self._token = session.liveliness().declare_token(entity.liveliness_key())
        self._thread = threading.Thread(target=self._serve, name=f"zenoh service {entity.topic.name}", daemon=True)
        self._thread.start()

    def _serve(self) -> None:
        # The channel ends (the iteration stops) when the queryable is undeclared. Leaving a query's context
        # sends its final message at once, which a client's get waits for after the reply.
        for query in self._queryable:
            with query:
                self._answer(query)

    def _answer(self, query: zenoh.Query) -> None:
        accepted = _accepted(query, self._deserialize, self.dropped, "request")
        if accepted is None:
            return
        attachment, request = accepted
        try:
            reply = self._callback(request, attachment.gid)
        except Exception as error:  # noqa: BLE001  (a failing handler must not end the service's thread)
            self.dropped("handler_failed", f"a request its handler failed on ({type(error).__name__}: {error})")
            return
        reply_attachment = Attachment(attachment.sequence_number, time.time_ns(), attachment.gid)
        query.reply(self.key_expr, bytes(reply), attachment=reply_attachment.encode())
        self.answered += 1

    def close(self) -> None:
        """Withdraws the token and the queryable, and waits for the service's thread."""
        self._token.undeclare()
        self._queryable.undeclare()
        self._thread.join(timeout=5)


class Client:
    """A service client: `call` sends the request's CDR bytes as a query with the attachment an rmw_zenoh client
    sends (sequence numbers from 1, the system clock's time, the client's GID, which the server's reply carries
    back) and gives the reply's CDR bytes, or None where no server answered within the time-out."""

    def __init__(self, session: zenoh.Session, entity: Entity) -> None:
        self.entity = entity
        self.key_expr = entity.data_key_expr()
        self.gid = entity.gid
        self._session = session
        self._token = session.liveliness().declare_token(entity.liveliness_key())
        self._lock = threading.Lock()
        self._sequence_number = 0

    def call(self, request: bytes, timeout: float) -> bytes | None:
        """The reply to one request, waiting at most `timeout` seconds; None where none came."""
        with self._lock:
            self._sequence_number += 1
            attachment = Attachment(self._sequence_number, time.time_ns(), self.gid)
        replies = self._session.get(
            self.key_expr, payload=bytes(request), attachment=attachment.encode(), timeout=timeout
        )
        answers = [reply.ok for reply in replies if reply.ok is not None]
        return answers[0].payload.to_bytes() if answers else None

    def close(self) -> None:
        """Withdraws the token."""
        self._token.undeclare()


class ZenohNode:
    """A ROS node on one Zenoh session: its liveliness token and the entities it declares, named and typed as
    an rmw_zenoh node would name them (relative names under the namespace, `~` for the node's own)."""

    def __init__(
        self,
        session: zenoh.Session,
        types: Types,
        name: str,
        namespace: str = "/",
        domain: int = 0,
        enclave: str = "/",
        log: Log = print,
    ) -> None:
        self.session = session
        self.types = types
        self.info = NodeInfo(name=name, namespace=namespace, domain=domain, enclave=enclave)
        self.zid = str(session.zid())
        self._log = log
        self._ids = itertools.count()
        self.node_id = next(self._ids)
        self.entity = node_entity(self.zid, self.node_id, self.info)
        self._token = session.liveliness().declare_token(self.entity.liveliness_key())
        self._entities: list[Publisher | Subscription | Service | Client] = []
        self._senders: dict[bytes, str] = {}
        self._watchers: list[zenoh.Subscriber] = []

    def _entity(self, kind: EntityKind, name: str, ros_type: str, qos: QoS) -> Entity:
        topic = TopicInfo(
            name=fully_qualified_name(name, self.info.namespace, self.info.name),
            dds_type=dds_type_name(ros_type),
            type_hash=self.types.rihs01(ros_type),
            qos=qos.adapted(),
        )
        return Entity(self.zid, self.node_id, next(self._ids), kind, self.info, topic)

    def publisher(self, topic: str, ros_type: str, qos: QoS | None = None) -> Publisher:
        """A publisher of `ros_type` (e.g. sensor_msgs/msg/JointState) on topic."""
        publisher = Publisher(self.session, self._entity(EntityKind.PUBLISHER, topic, ros_type, qos or QoS()))
        self._entities.append(publisher)
        return publisher

    def subscription(
        self,
        topic: str,
        ros_type: str,
        callback: Callable[[object], None],
        qos: QoS | None = None,
        deserialize: Callable[[bytes], object] = bytes,
        with_gid: bool = False,
    ) -> Subscription:
        """A subscription to topic calling callback(deserialize(cdr)) for each valid sample (with_gid: and the
        sender's GID)."""
        subscription = Subscription(
            self.session,
            self._entity(EntityKind.SUBSCRIPTION, topic, ros_type, qos or QoS()),
            callback,
            deserialize,
            self._log,
            with_gid,
        )
        self._entities.append(subscription)
        return subscription

    def service(
        self,
        name: str,
        ros_type: str,
        handler: Callable[[object], bytes],
        qos: QoS | None = None,
        deserialize_request: Callable[[bytes], object] = bytes,
        with_gid: bool = False,
    ) -> Service:
        """A server of the service `ros_type` (e.g. std_srvs/srv/Trigger) answering with handler's CDR bytes
        (with_gid: handler(request, gid), gid the client's)."""
        service = Service(
            self.session,
            self._entity(EntityKind.SERVICE, name, ros_type, qos or SERVICES_QOS),
            handler,
            deserialize_request,
            self._log,
            with_gid,
        )
        self._entities.append(service)
        return service

    def client(self, name: str, ros_type: str, qos: QoS | None = None) -> Client:
        """A client of the service `ros_type` (e.g. std_srvs/srv/Trigger) named `name`."""
        client = Client(self.session, self._entity(EntityKind.CLIENT, name, ros_type, qos or SERVICES_QOS))
        self._entities.append(client)
        return client

    def sender_of(self, gid: bytes) -> str:
        """Who sent a sample or request whose attachment gives `gid`, as far as Zenoh can tell: the node and
        session of the entity whose liveliness token hashes to it, and the certificate name of the link to that
        session where it is a TLS link of this session's own (a client of a router is behind the router's link)."""
        if gid not in self._senders:
            replies = self.session.liveliness().get(f"{ADMIN_SPACE}/{self.info.domain}/**", timeout=SENDER_QUERY_S)
            keys = [str(reply.ok.key_expr) for reply in replies if reply.ok is not None]
            entity = next((Entity.parse(key) for key in keys if gid_of(key) == gid), None)
            if entity is None:
                # Not remembered: a client's token may reach this session after its first request (through a
                # router they take different ways).
                return f"gid {gid.hex()} (no entity of the graph has it)"
            if len(self._senders) >= SENDERS_KEPT:
                # Clients come and go (and a careless one may send any GID): forget them all rather than grow.
                self._senders.clear()
            self._senders[gid] = self.who(entity)
        return self._senders[gid]

    def certificates(self, zid: str) -> list[str]:
        """The names the certificates of this session's TLS links to the session `zid` give (none for a session
        that is not linked to this one directly, e.g. one behind a router, or linked without TLS)."""
        names = {link.auth_identifier for link in self.session.info.links() if str(link.zid) == zid}
        return sorted(name for name in names if name)

    def who(self, entity: Entity) -> str:
        """The node and session of `entity`, and the certificate name of this session's link to that session."""
        node = f"{entity.node.namespace.rstrip('/')}/{entity.node.name}"
        names = self.certificates(entity.zid)
        certificate = f", certificate {', '.join(names)}" if names else ""
        return f"node {node} of session {entity.zid}{certificate}"

    def watch(self, callback: Callable[[Entity, bytes], None]) -> None:
        """Calls `callback(entity, gid)` on Zenoh's thread for each entity of the graph's other sessions, those there
        now and each declared later (its liveliness token and the GID it hashes to); tokens that are not rmw_zenoh's
        are passed over."""

        def on_token(sample: zenoh.Sample) -> None:
            if sample.kind != zenoh.SampleKind.PUT:
                return
            key = str(sample.key_expr)
            try:
                entity = Entity.parse(key)
            except ValueError:
                return
            if entity.zid != self.zid:
                callback(entity, gid_of(key))

        self._watchers.append(
            self.session.liveliness().declare_subscriber(f"{ADMIN_SPACE}/{self.info.domain}/**", on_token, history=True)
        )

    def dropped(self) -> int:
        """Samples and requests its subscriptions and services dropped so far (no or a malformed attachment, a
        payload its type rejects, a failed handler)."""
        return sum(e.dropped.total for e in self._entities if isinstance(e, Subscription | Service))

    def close(self) -> None:
        """Withdraws every entity and the node's token (the session stays open: its owner closes it)."""
        for watcher in self._watchers:
            watcher.undeclare()
        self._watchers.clear()
        for entity in reversed(self._entities):
            entity.close()
        self._entities.clear()
        self._token.undeclare()
