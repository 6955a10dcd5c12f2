"""rmw_zenoh's wire format (Jazzy, rmw_zenoh_cpp 0.2.x), as pure functions and values with no I/O.

A ROS node on rmw_zenoh is seen by others only through what it puts on Zenoh: the key expression of each topic
or service, the 33-byte attachment on every sample, query and reply, and a liveliness token per node, publisher,
subscription, service and client, from which graph tools (`ros2 node list`, `ros2 topic info -v`) build the ROS
graph. This module writes and reads those exactly as rmw_zenoh_cpp does (its liveliness_utils.cpp,
attachment_helpers.cpp and qos.cpp), so that akd_node can speak to ROS nodes on rmw_zenoh without any ROS
installed. Type hashes (RIHS01) come from `akd_ros.zenoh.types`; this module only carries them.
"""

from __future__ import annotations

import enum
import struct
from dataclasses import dataclass, field

import xxhash

ADMIN_SPACE = "@ros2_lv"
# rmw_zenoh writes every '/' inside a token's field as '%', because '/' separates the fields.
SLASH_REPLACEMENT = "%"
# The length rmw_gid_t's storage has in Jazzy (RMW_GID_STORAGE_SIZE).
GID_SIZE = 16
# int64 sequence number, int64 source timestamp, then the GID as zenoh-ext serialises a byte array: its length as
# a LEB128 varint (16 fits one byte) followed by the bytes.
_ATTACHMENT = struct.Struct("<qqB16s")
ATTACHMENT_SIZE = _ATTACHMENT.size


class EntityKind(enum.Enum):
    """What a liveliness token announces, in rmw_zenoh's two-letter code."""

    NODE = "NN"
    PUBLISHER = "MP"
    SUBSCRIPTION = "MS"
    SERVICE = "SS"
    CLIENT = "SC"


class Reliability(enum.IntEnum):
    """rmw_qos_reliability_policy_e: the numbers rmw_zenoh writes into a token's QoS field."""

    SYSTEM_DEFAULT = 0
    RELIABLE = 1
    BEST_EFFORT = 2
    UNKNOWN = 3
    BEST_AVAILABLE = 4


class Durability(enum.IntEnum):
    """rmw_qos_durability_policy_e."""

    SYSTEM_DEFAULT = 0
    TRANSIENT_LOCAL = 1
    VOLATILE = 2
    UNKNOWN = 3
    BEST_AVAILABLE = 4


class History(enum.IntEnum):
    """rmw_qos_history_policy_e."""

    SYSTEM_DEFAULT = 0
    KEEP_LAST = 1
    KEEP_ALL = 2
    UNKNOWN = 3


class Liveliness(enum.IntEnum):
    """rmw_qos_liveliness_policy_e (2, manual by node, is deprecated and absent from rmw_zenoh's table)."""

    SYSTEM_DEFAULT = 0
    AUTOMATIC = 1
    MANUAL_BY_TOPIC = 3
    UNKNOWN = 4
    BEST_AVAILABLE = 5


# RMW_DURATION_INFINITE as (seconds, nanoseconds): what rmw_zenoh puts for an unset deadline, lifespan or lease.
DURATION_INFINITE = (9223372036, 854775807)


@dataclass(frozen=True)
class QoS:
    """A QoS profile as rmw_zenoh holds it after adapting the user's (`best_available_qos`): no system defaults.

    The defaults are rclpy's usual profile (reliable, volatile, keep last 10); durations are (s, ns).
    """

    reliability: Reliability = Reliability.RELIABLE
    durability: Durability = Durability.VOLATILE
    history: History = History.KEEP_LAST
    depth: int = 10
    deadline: tuple[int, int] = DURATION_INFINITE
    lifespan: tuple[int, int] = DURATION_INFINITE
    liveliness: Liveliness = Liveliness.AUTOMATIC
    liveliness_lease: tuple[int, int] = DURATION_INFINITE

    def adapted(self) -> QoS:
        """The profile as rmw_zenoh adapts it before use (`best_available_qos`): system defaults become rmw_zenoh's
        defaults, depth 0 its default depth, unspecified (0, 0) durations infinite; unknown policies are refused."""
        default = RMW_ZENOH_DEFAULT_QOS

        def duration(value: tuple[int, int], default_value: tuple[int, int]) -> tuple[int, int]:
            return default_value if tuple(value) == (0, 0) else tuple(value)

        def policy(value: enum.IntEnum, default_value: enum.IntEnum) -> enum.IntEnum:
            if value.name == "UNKNOWN":
                raise ValueError(f"QoS {type(value).__name__.lower()} unknown is not supported (rmw_zenoh refuses it)")
            return default_value if value.name == "SYSTEM_DEFAULT" else value

        return QoS(
            reliability=policy(self.reliability, default.reliability),
            durability=policy(self.durability, default.durability),
            history=policy(self.history, default.history),
            depth=self.depth or default.depth,
            deadline=duration(self.deadline, default.deadline),
            lifespan=duration(self.lifespan, default.lifespan),
            liveliness=policy(self.liveliness, default.liveliness),
            liveliness_lease=duration(self.liveliness_lease, default.liveliness_lease),
        )

    def to_keyexpr(self) -> str:
        """The compact form of a token's QoS field, each part left empty where it equals rmw_zenoh's default.

        `reliability:durability:history,depth:deadline_s,deadline_ns:lifespan_s,lifespan_ns:liveliness,lease_s,
        lease_ns`; rmw_zenoh compares against its own defaults (`RMW_ZENOH_DEFAULT_QOS`, depth 42), not rclpy's.
        """
        default = RMW_ZENOH_DEFAULT_QOS

        def part(value: int, default_value: int) -> str:
            return "" if value == default_value else str(int(value))

        return ":".join(
            [
                part(self.reliability, default.reliability),
                part(self.durability, default.durability),
                f"{part(self.history, default.history)},{part(self.depth, default.depth)}",
                f"{part(self.deadline[0], default.deadline[0])},{part(self.deadline[1], default.deadline[1])}",
                f"{part(self.lifespan[0], default.lifespan[0])},{part(self.lifespan[1], default.lifespan[1])}",
                ",".join(
                    [
                        part(self.liveliness, default.liveliness),
                        part(self.liveliness_lease[0], default.liveliness_lease[0]),
                        part(self.liveliness_lease[1], default.liveliness_lease[1]),
                    ]
                ),
            ]
        )

    @classmethod
    def from_keyexpr(cls, text: str) -> QoS:
        """Reads the compact form back; an empty part is rmw_zenoh's default. ValueError names a bad part."""
        default = RMW_ZENOH_DEFAULT_QOS
        parts = text.split(":")
        if len(parts) != 6:
            raise ValueError(f"QoS field {text!r} has {len(parts)} ':'-separated parts, expected 6")
        history, deadline, lifespan, liveliness = (
            _components(text, parts[2], 2, "history,depth"),
            _components(text, parts[3], 2, "deadline"),
            _components(text, parts[4], 2, "lifespan"),
            _components(text, parts[5], 3, "liveliness,lease"),
        )

        def number(value: str, default_value: int, what: str) -> int:
            if not value:
                return int(default_value)
            if not value.isdigit():
                raise ValueError(f"QoS field {text!r}: {what} {value!r} is not a non-negative integer")
            return int(value)

        def policy(kind: type[enum.IntEnum], value: str, default_value: enum.IntEnum, what: str) -> enum.IntEnum:
            number_ = number(value, default_value, what)
            try:
                return kind(number_)
            except ValueError:
                allowed = ", ".join(f"{member.value} ({member.name.lower()})" for member in kind)
                raise ValueError(f"QoS field {text!r}: {what} {number_} is not one of {allowed}") from None

        return cls(
            reliability=policy(Reliability, parts[0], default.reliability, "reliability"),
            durability=policy(Durability, parts[1], default.durability, "durability"),
            history=policy(History, history[0], default.history, "history"),
            depth=number(history[1], default.depth, "depth"),
            deadline=(
                number(deadline[0], default.deadline[0], "deadline s"),
                number(deadline[1], default.deadline[1], "deadline ns"),
            ),
            lifespan=(
                number(lifespan[0], default.lifespan[0], "lifespan s"),
                number(lifespan[1], default.lifespan[1], "lifespan ns"),
            ),
            liveliness=policy(Liveliness, liveliness[0], default.liveliness, "liveliness"),
            liveliness_lease=(
                number(liveliness[1], default.liveliness_lease[0], "lease s"),
                number(liveliness[2], default.liveliness_lease[1], "lease ns"),
            ),
        )


def _components(text: str, part: str, count: int, what: str) -> list[str]:
    components = part.split(",")
    if len(components) != count:
        raise ValueError(f"QoS field {text!r}: {what} part {part!r} has {len(components)} ','-parts, expected {count}")
    return components


# rmw_zenoh's own defaults (qos.cpp), against which a token's QoS field is written compactly.
RMW_ZENOH_DEFAULT_QOS = QoS(depth=42)
# rmw_qos_profile_services_default, the profile rclpy's services and clients use.
SERVICES_QOS = QoS()


def mangle(name: str) -> str:
    """A name as one token field: each '/' written '%'."""
    return name.replace("/", SLASH_REPLACEMENT)


def demangle(field_: str) -> str:
    """A token field back to its name."""
    return field_.replace(SLASH_REPLACEMENT, "/")


def dds_type_name(ros_type: str) -> str:
    """The type name rmw_zenoh's type support reports: `pkg/msg/Name` is `pkg::msg::dds_::Name_` (srv alike)."""
    parts = ros_type.split("/")
    if len(parts) != 3 or parts[1] not in ("msg", "srv") or not all(parts):
        raise ValueError(f"type name {ros_type!r} is not of the form <package>/msg/<Name> or <package>/srv/<Name>")
    package, kind, name = parts
    return f"{package}::{kind}::dds_::{name}_"


def ros_type_name(dds_type: str) -> str:
    """`pkg::msg::dds_::Name_` back to `pkg/msg/Name`, as graph tools show it."""
    parts = dds_type.split("::")
    if len(parts) != 4 or parts[2] != "dds_" or not parts[3].endswith("_"):
        raise ValueError(f"type name {dds_type!r} is not of the form <package>::msg::dds_::<Name>_")
    return f"{parts[0]}/{parts[1]}/{parts[3][:-1]}"


def fully_qualified_name(name: str, namespace: str, node_name: str) -> str:
    """A topic or service name as rcl expands it: `~` is the node's own name, relative names go under the
    namespace. The result starts with '/' and has no trailing '/'."""
    if not name:
        raise ValueError("topic or service name is empty")
    base = namespace.rstrip("/")
    if name == "~" or name.startswith("~/"):
        name = f"{base}/{node_name}{name[1:]}"
    elif not name.startswith("/"):
        name = f"{base}/{name}"
    name = name.rstrip("/")
    if "//" in name or not name:
        raise ValueError(f"topic or service name {name!r} has an empty part")
    return name


def data_key_expr(domain: int, topic: str, dds_type: str, type_hash: str) -> str:
    """The key expression of a topic's samples or a service's queries:
    `<domain>/<topic without leading or trailing '/'>/<dds type>/<RIHS01 hash>`."""
    return f"{domain}/{topic.strip('/')}/{dds_type}/{type_hash}"


def gid_of(liveliness_key: str) -> bytes:
    """An entity's GID: the XXH3-128 hash of its liveliness key expression.

    rmw_zenoh copies the hash's low 64 bits, then its high 64 bits, each in the host's (little-endian) order, so
    the GID is the 128-bit value in little-endian order (the reverse of xxhash's canonical big-endian digest).
    """
    return xxhash.xxh3_128_intdigest(liveliness_key.encode()).to_bytes(GID_SIZE, "little")


@dataclass(frozen=True)
class Attachment:
    """The attachment rmw_zenoh puts on every sample, query and reply."""

    sequence_number: int
    source_timestamp: int  # ns since the epoch, system clock
    gid: bytes

    def encode(self) -> bytes:
        """The 33 bytes: sequence number and timestamp as int64 little-endian, 0x10, then the 16-byte GID."""
        if len(self.gid) != GID_SIZE:
            raise ValueError(f"GID has {len(self.gid)} bytes, expected {GID_SIZE}")
        return _ATTACHMENT.pack(self.sequence_number, self.source_timestamp, GID_SIZE, self.gid)

    @classmethod
    def decode(cls, data: bytes) -> Attachment:
        """Reads an attachment strictly; a ValueError names what is wrong with it."""
        data = bytes(data)
        if len(data) != ATTACHMENT_SIZE:
            raise ValueError(f"attachment has {len(data)} bytes, expected {ATTACHMENT_SIZE}")
        sequence_number, source_timestamp, gid_length, gid = _ATTACHMENT.unpack(data)
        if gid_length != GID_SIZE:
            raise ValueError(f"attachment's GID length byte is {gid_length:#04x}, expected {GID_SIZE:#04x}")
        if sequence_number < 0:
            raise ValueError(f"attachment's sequence number {sequence_number} is negative")
        if source_timestamp < 0:
            raise ValueError(f"attachment's source timestamp {source_timestamp} is negative")
        return cls(sequence_number, source_timestamp, gid)


@dataclass(frozen=True)
class NodeInfo:
    """The node an entity belongs to. rcl's default namespace and enclave are both '/'."""

    name: str
    namespace: str = "/"
    domain: int = 0
    enclave: str = "/"


@dataclass(frozen=True)
class TopicInfo:
    """The topic or service of an entity other than a node: fully qualified name, rmw_zenoh's type name (for a
    service without the Request_/Response_ suffix), RIHS01 hash and adapted QoS."""

    name: str
    dds_type: str
    type_hash: str
    qos: QoS = field(default_factory=QoS)


@dataclass(frozen=True)
class Entity:
    """One liveliness token's worth: who (session, node id, entity id, kind, node) and, but for a node, what topic.

    Ids come from one counter per session; a node's entity id is its node id.
    """

    zid: str
    node_id: int
    entity_id: int
    kind: EntityKind
    node: NodeInfo
    topic: TopicInfo | None = None

    def __post_init__(self) -> None:
        if (self.kind is EntityKind.NODE) != (self.topic is None):
            raise ValueError(f"a {self.kind.name.lower()} entity {'has no' if self.topic is None else 'has a'} topic")

    def liveliness_key(self) -> str:
        """`@ros2_lv/<domain>/<zid>/<node id>/<entity id>/<kind>/<enclave>/<namespace>/<node name>` and, but for a
        node, `/<topic>/<type>/<hash>/<qos>`, each '/' inside a field written '%'."""
        fields = [
            ADMIN_SPACE,
            str(self.node.domain),
            self.zid,
            str(self.node_id),
            str(self.entity_id),
            self.kind.value,
            mangle(self.node.enclave),
            mangle(self.node.namespace),
            mangle(self.node.name),
        ]
        if self.topic is not None:
            fields += [
                mangle(self.topic.name),
                mangle(self.topic.dds_type),
                mangle(self.topic.type_hash),
                self.topic.qos.to_keyexpr(),
            ]
        # rmw_zenoh would cut the token short at an empty field, which no reader could parse: refuse it instead.
        if empty := [index for index, value in enumerate(fields) if not value]:
            raise ValueError(f"liveliness token field {empty[0]} is empty: {'/'.join(fields)!r}")
        return "/".join(fields)

    @property
    def gid(self) -> bytes:
        """The entity's GID, the hash of its liveliness key expression."""
        return gid_of(self.liveliness_key())

    def data_key_expr(self) -> str:
        """The key expression of the entity's samples or queries."""
        if self.topic is None:
            raise ValueError("a node has no data key expression")
        return data_key_expr(self.node.domain, self.topic.name, self.topic.dds_type, self.topic.type_hash)

    @classmethod
    def parse(cls, key: str) -> Entity:
        """Reads a liveliness token back into its fields; a ValueError names what is wrong with it."""
        parts = str(key).split("/")
        if len(parts) not in (9, 13):
            raise ValueError(f"liveliness token {key!r} has {len(parts)} '/'-separated fields, expected 9 or 13")
        if empty := [index for index, value in enumerate(parts) if not value]:
            raise ValueError(f"liveliness token {key!r} has an empty field {empty[0]}")
        if parts[0] != ADMIN_SPACE:
            raise ValueError(f"liveliness token {key!r} is not under {ADMIN_SPACE}")
        try:
            kind = EntityKind(parts[5])
        except ValueError:
            allowed = ", ".join(kind.value for kind in EntityKind)
            raise ValueError(f"liveliness token {key!r}: entity kind {parts[5]!r} is not one of {allowed}") from None
        for index, what in ((1, "domain"), (3, "node id"), (4, "entity id")):
            if not parts[index].isdigit():
                raise ValueError(f"liveliness token {key!r}: {what} {parts[index]!r} is not a non-negative integer")
        if (kind is EntityKind.NODE) != (len(parts) == 9):
            raise ValueError(f"liveliness token {key!r}: a {kind.name.lower()} token has {len(parts)} fields")
        node = NodeInfo(
            name=demangle(parts[8]), namespace=demangle(parts[7]), domain=int(parts[1]), enclave=demangle(parts[6])
        )
        topic = None
        if kind is not EntityKind.NODE:
            topic = TopicInfo(demangle(parts[9]), demangle(parts[10]), demangle(parts[11]), QoS.from_keyexpr(parts[12]))
        return cls(parts[2], int(parts[3]), int(parts[4]), kind, node, topic)


def node_entity(zid: str, node_id: int, node: NodeInfo) -> Entity:
    """The entity of a node itself."""
    return Entity(zid, node_id, node_id, EntityKind.NODE, node)
