"""Recording of the drive's topics into rosbag2 bags, with a black box of the last seconds.

A :class:`Recorder` writes one rosbag2 bag directory (metadata.yaml version 9 and MCAP files with
the ``ros2`` profile) as ``ros2 bag record -s mcap`` would, without needing rosbag2 itself: the
node hands it messages, a writer thread of its own serialises them and does all the disk I/O.

- Messages are serialised once (in the writer thread, but the per-cycle records, which come
  serialised), by rclpy's ``serialize_message`` (rclpy message classes) or by
  rosbags' ``serialize_cdr`` (rosbags message classes with their typestore); the schemas are the
  complete ``ros2msg`` definitions, made of the packages' .msg files as rosbag2 makes them, and the
  type hashes their RIHS01 hashes, computed by rosbags' typestore from those definitions, so every
  reader decodes the bag without this package.
- The per-cycle channel (:meth:`Recorder.cycle_records`, already serialised, e.g. by
  ``akd_ros._native.cycle_sample_records``; or :meth:`Recorder.cycle_sample`, one message) is
  recorded every ``decimation``-th cycle, or not at all with ``decimation=0``; the last
  ``black_box_seconds`` of every cycle are kept in memory regardless, and
  :meth:`Recorder.fault` writes them to the black box topic (by default ``black_box`` beside
  the cycle topic, e.g. ``/akd_node/black_box``) with their own times, so the cycles before a
  fault are in the bag even when the cycle topic is not recorded.
- Chunks are closed (and so safe from a crash of the process) every ``chunk_size`` bytes or
  ``flush_interval`` seconds, and metadata.yaml is rewritten each time to describe exactly what
  the closed chunks hold. A bag whose process was killed has MCAP files without a summary:
  :func:`reindex` rebuilds their summaries and metadata.yaml, as ``ros2 bag reindex`` does.
- Files are split by size or by duration into ``<bag>_0.mcap``, ``<bag>_1.mcap``, ..., each a
  complete MCAP file with all schemas and channels.
- :meth:`Recorder.write` never blocks and never raises for I/O: a full queue drops the message
  and counts it; a failed disk (unwritable folder, disk full) is reported once, through
  ``on_error`` or else the ``akd_ros.recorder`` logger, and counted in :attr:`Recorder.stats`;
  recording stops there, and the bag stays readable up to the last closed chunk.
"""

from __future__ import annotations

import atexit
import bisect
import collections
import datetime
import functools
import importlib
import logging
import math
import operator
import os
import struct
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml
from mcap.exceptions import McapError
from mcap.reader import make_reader
from mcap.records import Channel, Message, Schema
from mcap.stream_reader import StreamReader
from mcap.writer import CompressionType, Writer

from akd_ros import _native

__all__ = [
    "BAG_VERSION",
    "COMPRESSIONS",
    "MessageType",
    "Recorder",
    "RecorderStats",
    "message_type",
    "reindex",
]

LOG = logging.getLogger("akd_ros.recorder")

#: rosbag2 metadata version written (Jazzy's).
BAG_VERSION = 9
#: Chunk compressions, by the name used in the constructor and the ROS parameters.
COMPRESSIONS = ("zstd", "lz4", "none")
_DEFINITION_DELIMITER = "=" * 80 + "\n"
# The black box ring holds this much more than black_box_seconds: samples reach the recorder in
# batches after the cycle that faulted, and the window before the fault must still be whole then.
_BLACK_BOX_MARGIN_S = 1.0
_STORAGE_ID = "mcap"
_SERIALIZATION = "cdr"
_LIBRARY = "akd_ros recorder"
# The profile an rmw publisher offers by default (rmw_qos_profile_default), in rosbag2's v9 form.
_DEFAULT_QOS = {
    "history": "keep_last",
    "depth": 10,
    "reliability": "reliable",
    "durability": "volatile",
    "deadline": {"sec": 0, "nsec": 0},
    "lifespan": {"sec": 0, "nsec": 0},
    "liveliness": "system_default",
    "liveliness_lease_duration": {"sec": 0, "nsec": 0},
    "avoid_ros_namespace_conventions": False,
}


@dataclass(frozen=True)
class MessageType:
    """What a bag needs of one message type.

    ``name`` is the full ROS name (``pkg/msg/Type``), ``definition`` the complete ``ros2msg``
    schema (the type's .msg text, then each nested type's after a delimiter), ``type_hash`` the
    RIHS01 type description hash and ``serialize`` turns a message into CDR bytes.
    """

    name: str
    definition: str
    type_hash: str
    serialize: Callable[[Any], bytes] = field(compare=False)


def _rclpy_name(msg_class: type) -> str:
    return f"{msg_class.__module__.split('.')[0]}/msg/{msg_class.__name__}"


def _nested_classes(msg_class: type) -> list[type]:
    """The message classes of msg_class's fields, sorted by name, as rosbag2 orders dependencies."""
    found = {}
    for slot_type in msg_class.SLOT_TYPES:
        slot_type = getattr(slot_type, "value_type", slot_type)
        namespaces = getattr(slot_type, "namespaces", None)
        if namespaces:
            module = importlib.import_module(".".join(namespaces))
            nested = getattr(module, slot_type.name)
            found[_rclpy_name(nested)] = nested
    return [found[name] for name in sorted(found)]


def _msg_file(name: str) -> Path:
    """The .msg file that defines name (``pkg/msg/Type``), as its package installs it.

    rosbag2 reads the same file from the package's share directory. An installed package (a ROS
    install, a colcon install, PyPI's ROS wheels, a wheel of akd_ros) has its Python modules in
    ``<prefix>/lib/pythonX.Y/site-packages/<pkg>`` and its definitions in
    ``<prefix>/share/<pkg>/msg``; an editable one (``pip install -e``, ``colcon build
    --symlink-install``) imports its modules from its source tree, where ``msg/`` is beside them.
    """
    package, _, type_name = name.split("/")
    module_dir = Path(importlib.import_module(package).__file__).resolve().parent
    folders = [module_dir.parents[3] / "share" / package] if len(module_dir.parents) > 3 else []
    folders.append(module_dir.parent)
    for folder in folders:
        path = folder / "msg" / f"{type_name}.msg"
        if path.is_file():
            return path
    raise ValueError(
        f"{name}: no {type_name}.msg in {', '.join(str(f / 'msg') for f in folders)}, so the bag could not describe it"
    )


def _rclpy_message_type(msg_class: type) -> MessageType:
    from rclpy.serialization import serialize_message
    from rclpy.type_support import check_for_type_support
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    check_for_type_support(msg_class)
    name = _rclpy_name(msg_class)
    seen: set[str] = set()

    # rosbag2's LocalMessageDefinitionSource: each type's .msg text, then, depth first, every
    # nested type not written yet after the two-line delimiter.
    def definition(cls: type) -> str:
        text = _msg_file(_rclpy_name(cls)).read_text(encoding="utf-8").rstrip("\n") + "\n"
        for nested in _nested_classes(cls):
            nested_name = _rclpy_name(nested)
            if nested_name not in seen:
                seen.add(nested_name)
                text += f"\n{_DEFINITION_DELIMITER}MSG: {nested_name}\n" + definition(nested)
        return text

    full_definition = definition(msg_class)
    # The RIHS01 hash of exactly the definition the bag carries: rosbags computes it as rosidl's
    # generators do (the type support of the same .msg files reports the same hash).
    store = get_typestore(Stores.EMPTY)
    store.register(get_types_from_msg(full_definition, name))
    msgdef = store.get_msgdef(name)

    def serialize(msg: Any) -> bytes:
        # rmw_fastrtps's rmw_serialize (behind serialize_message) returns the buffer at its size
        # estimate, which aligns even empty sequences (e.g. an empty float64[]) and so can be
        # longer than the CDR written; rosbags refuses more than 3 bytes after a message. The CDR's
        # length follows from the message's sequence and string lengths alone: rosbags' size
        # function reads those from the rclpy message by field name, without a second decode.
        data = serialize_message(msg)
        return data[: 4 + msgdef.getsize_cdr(0, msg, store)]

    return MessageType(
        name=name,
        definition=full_definition,
        type_hash=store.hash_rihs01(name),
        serialize=serialize,
    )


def _rosbags_message_type(msg_class: type, typestore: Any) -> MessageType:
    name = msg_class.__msgtype__
    if typestore.types.get(name) is not msg_class:
        raise ValueError(f"{name} is not a message class of the given typestore")
    definition, _ = typestore.generate_msgdef(name, ros_version=2)
    return MessageType(
        name=name,
        definition=definition,
        type_hash=typestore.hash_rihs01(name),
        serialize=lambda msg: bytes(typestore.serialize_cdr(msg, name)),
    )


def message_type(msg_class: type, typestore: Any = None) -> MessageType:
    """Describes msg_class for a bag.

    msg_class is an rclpy message class (e.g. ``sensor_msgs.msg.JointState``), or, with the
    rosbags ``typestore`` it belongs to, a rosbags message class (e.g.
    ``typestore.types['sensor_msgs/msg/JointState']``). Raises ValueError for anything else.
    """
    if typestore is not None:
        if not hasattr(msg_class, "__msgtype__"):
            raise ValueError(f"{msg_class!r} is not a rosbags message class (no __msgtype__)")
        return _rosbags_message_type(msg_class, typestore)
    if not (isinstance(msg_class, type) and hasattr(msg_class, "SLOT_TYPES")):
        raise ValueError(
            f"{msg_class!r} is not an rclpy message class; pass a class such as "
            "sensor_msgs.msg.JointState, or a rosbags message class with typestore="
        )
    return _rclpy_message_type(msg_class)


def _duration_yaml(duration: Any) -> dict:
    nanoseconds = duration.nanoseconds
    return {"sec": nanoseconds // 1_000_000_000, "nsec": nanoseconds % 1_000_000_000}


def _qos_profile(qos: Any) -> dict:
    """rosbag2's v9 dictionary of an rclpy QoSProfile (None: the rmw default profile; a dict: those of its keys over
    the default profile's)."""
    if qos is None:
        return dict(_DEFAULT_QOS)
    if isinstance(qos, dict):
        unknown = sorted(set(qos) - set(_DEFAULT_QOS))
        if unknown:
            raise ValueError(f"qos keys {', '.join(unknown)} are not rosbag2's; allowed: {', '.join(_DEFAULT_QOS)}")
        return {**_DEFAULT_QOS, **qos}
    try:
        return {
            "history": qos.history.name.lower(),
            "depth": int(qos.depth),
            "reliability": qos.reliability.name.lower(),
            "durability": qos.durability.name.lower(),
            "deadline": _duration_yaml(qos.deadline),
            "lifespan": _duration_yaml(qos.lifespan),
            "liveliness": qos.liveliness.name.lower(),
            "liveliness_lease_duration": _duration_yaml(qos.liveliness_lease_duration),
            "avoid_ros_namespace_conventions": bool(qos.avoid_ros_namespace_conventions),
        }
    except AttributeError as err:
        raise ValueError(f"qos must be an rclpy.qos.QoSProfile or None, not {qos!r}") from err


# libyaml's emitter where PyYAML has it: metadata.yaml is rewritten at every closed chunk.
_YAML_DUMPER = getattr(yaml, "CSafeDumper", yaml.SafeDumper)


def _dump_yaml(data: Any) -> str:
    return yaml.dump(data, Dumper=_YAML_DUMPER, default_flow_style=False, sort_keys=False)


@dataclass
class _Topic:
    name: str
    msg_type: MessageType
    qos_yaml: str
    msg_class: type | None = None
    message_count: int = 0

    @functools.cached_property
    def qos_profiles(self) -> Any:
        """The offered QoS profiles as metadata.yaml lists them, read once."""
        return yaml.safe_load(self.qos_yaml)


@dataclass
class _File:
    path: Path
    start_ns: int | None = None
    end_ns: int | None = None
    message_count: int = 0

    def add(self, first_ns: int, last_ns: int | None = None, count: int = 1) -> None:
        """Counts `count` messages from `first_ns` to `last_ns` (the same by default)."""
        last_ns = first_ns if last_ns is None else last_ns
        self.start_ns = first_ns if self.start_ns is None else min(self.start_ns, first_ns)
        self.end_ns = last_ns if self.end_ns is None else max(self.end_ns, last_ns)
        self.message_count += count


def _bag_metadata(topics: list[_Topic], files: list[_File]) -> dict:
    """metadata.yaml's content, as rosbag2 (Jazzy) writes it, for the given topics and files."""
    starts = [f.start_ns for f in files if f.start_ns is not None]
    ends = [f.end_ns for f in files if f.end_ns is not None]
    start = min(starts, default=0)
    return {
        "rosbag2_bagfile_information": {
            "version": BAG_VERSION,
            "storage_identifier": _STORAGE_ID,
            "duration": {"nanoseconds": max(ends, default=start) - start},
            "starting_time": {"nanoseconds_since_epoch": start},
            "message_count": sum(f.message_count for f in files),
            "topics_with_message_count": [
                {
                    "topic_metadata": {
                        "name": t.name,
                        "type": t.msg_type.name,
                        "serialization_format": _SERIALIZATION,
                        "offered_qos_profiles": t.qos_profiles,
                        "type_description_hash": t.msg_type.type_hash,
                    },
                    "message_count": t.message_count,
                }
                for t in topics
            ],
            # Compression is MCAP's own, per chunk: rosbag2 lists no bag-level compression then.
            "compression_format": "",
            "compression_mode": "",
            "relative_file_paths": [f.path.name for f in files],
            "files": [
                {
                    "path": f.path.name,
                    "starting_time": {"nanoseconds_since_epoch": f.start_ns or 0},
                    "duration": {"nanoseconds": (f.end_ns or 0) - (f.start_ns or 0)},
                    "message_count": f.message_count,
                }
                for f in files
            ],
            "custom_data": None,
            "ros_distro": os.environ.get("ROS_DISTRO", "jazzy"),
        }
    }


def _write_metadata(bag: Path, metadata: dict) -> None:
    # Written beside and renamed, so a crash never leaves a half-written metadata.yaml.
    tmp = bag / "metadata.yaml.tmp"
    tmp.write_text(_dump_yaml(metadata), encoding="utf-8")
    os.replace(tmp, bag / "metadata.yaml")


class _McapFile:
    """One open MCAP file of the bag, with every topic's schema and channel, written by the crate's `BagFile`."""

    def __init__(self, path: Path, topics: list[_Topic], compression: str):
        self.info = _File(path)
        # Chunks are closed by flush() from the recorder, so that each closed chunk reaches the OS at once.
        self.file = _native.BagFile(path, compression, "ros2", _LIBRARY)
        self.schema_ids: dict[str, int] = {}
        self.channel_ids: dict[str, int] = {}
        for topic in topics:
            self.add_topic(topic)

    def add_topic(self, topic: _Topic) -> None:
        msg_type = topic.msg_type
        if msg_type.name not in self.schema_ids:
            definition = msg_type.definition.encode()
            self.schema_ids[msg_type.name] = self.file.add_schema(msg_type.name, "ros2msg", definition)
        self.channel_ids[topic.name] = self.file.add_channel(
            self.schema_ids[msg_type.name],
            topic.name,
            _SERIALIZATION,
            {"offered_qos_profiles": topic.qos_yaml, "topic_type_hash": msg_type.type_hash},
        )

    def add_messages(self, topic: str, records: list[tuple[int, bytes]]) -> int:
        """Adds `records` (time ns, data) of `topic`, in time order; their bytes in all."""
        size = self.file.add_messages(self.channel_ids[topic], records)
        self.info.add(records[0][0], records[-1][0], len(records))
        return size

    def flush(self, sync: bool = False) -> None:
        self.file.flush()
        if sync:
            self.file.sync()

    def size(self) -> int:
        return self.file.size()

    def close(self, metadata: dict) -> None:
        self.file.finish(
            "rosbag2",
            {
                "serialized_metadata": _dump_yaml(metadata["rosbag2_bagfile_information"]),
                "ROS_DISTRO": metadata["rosbag2_bagfile_information"]["ros_distro"],
            },
        )


@dataclass
class RecorderStats:
    """Counters of a Recorder, all since it was made.

    ``written`` messages are in the bag's closed chunks or pending in the open one; ``dropped``
    were refused because the queue was full or recording had stopped on an error; ``errors``
    counts I/O failures (only the first is reported); ``black_box_dumps`` counts faults whose
    black box was written; ``files`` are the bag's MCAP files so far.
    """

    bag: Path | None = None
    written: int = 0
    dropped: int = 0
    errors: int = 0
    black_box_dumps: int = 0
    files: list[Path] = field(default_factory=list)


_CLOSE = object()


class Recorder:
    """Records topics into a new rosbag2 bag (MCAP) inside ``folder``; see the module doc.

    The bag directory is named ``<prefix>_<YYYY_MM_DD-HH_MM_SS>`` (no prefix: the time alone)
    after the local time it was opened at. A recorder not closed is closed at interpreter exit.
    Arguments:

    - ``cycle_rate_hz``: the rate of cycles, which sizes the black box ring.
    - ``samples_per_cycle``: records per cycle (one per drive of a bus, in turn), which also
      size the ring; decimation keeps or drops a cycle's records together.
    - ``split_size`` (bytes) / ``split_duration`` (seconds): start a new MCAP file when the
      current one has reached this size, or spans this long; None never splits.
    - ``chunk_size`` (bytes) / ``flush_interval`` (seconds): a chunk is closed, compressed and
      written when it holds this much, or is this old; a killed process loses at most that.
    - ``compression``: ``'zstd'``, ``'lz4'`` or ``'none'`` for the chunks.
    - ``decimation``: record every n-th cycle's samples on the cycle topic; 0 records none (the
      black box still keeps them all).
    - ``black_box_seconds``: how much of the past :meth:`fault` writes to the black box topic.
    - ``queue_size``: items waiting for the writer thread (a message, or one call's cycle
      records) beyond which the next is dropped.
    - ``on_error``: called once, from the writer thread, with the text of the first I/O error
      (without it, the error goes to the ``akd_ros.recorder`` logger).

    Bad arguments raise ValueError naming the allowed values; I/O never raises into the caller.
    """

    def __init__(
        self,
        folder: os.PathLike | str,
        *,
        cycle_rate_hz: float,
        split_size: int | None = None,
        split_duration: float | None = None,
        chunk_size: int = 1 << 20,
        flush_interval: float = 1.0,
        compression: str = "zstd",
        decimation: int = 1,
        black_box_seconds: float = 5.0,
        samples_per_cycle: int = 1,
        queue_size: int = 100_000,
        prefix: str = "akd",
        on_error: Callable[[str], None] | None = None,
    ):
        if compression not in COMPRESSIONS:
            raise ValueError(f"compression {compression!r} is not one of {sorted(COMPRESSIONS)}")
        _check_positive("cycle_rate_hz", cycle_rate_hz)
        _check_positive("chunk_size", chunk_size, integer=True)
        _check_positive("flush_interval", flush_interval)
        _check_positive("queue_size", queue_size, integer=True)
        _check_positive("samples_per_cycle", samples_per_cycle, integer=True)
        if split_size is not None:
            _check_positive("split_size", split_size, integer=True)
        if split_duration is not None:
            _check_positive("split_duration", split_duration)
        if not isinstance(decimation, int) or isinstance(decimation, bool) or decimation < 0:
            raise ValueError(f"decimation must be an integer >= 0 (0: cycle topic off), not {decimation!r}")
        if not isinstance(black_box_seconds, (int, float)) or not 0 <= black_box_seconds < math.inf:
            raise ValueError(f"black_box_seconds must be a finite number >= 0, not {black_box_seconds!r}")

        self._folder = Path(folder)
        self._compression = compression
        self._split_size = split_size
        self._split_duration_ns = None if split_duration is None else int(split_duration * 1e9)
        self._chunk_size = chunk_size
        self._flush_interval = flush_interval
        self._decimation = decimation
        self._queue_size = queue_size
        self._on_error = on_error
        stamp = datetime.datetime.now().strftime("%Y_%m_%d-%H_%M_%S")
        self._name = f"{prefix}_{stamp}" if prefix else stamp

        self._topics: dict[str, _Topic] = {}
        self._cycle_topic: str | None = None
        self._black_box_topic: str | None = None
        self._cycle_class: type | None = None
        self._cycle_type: MessageType | None = None
        self._samples_per_cycle = samples_per_cycle
        ring_size = max(1, math.ceil((black_box_seconds + _BLACK_BOX_MARGIN_S) * cycle_rate_hz) * samples_per_cycle)
        self._ring: collections.deque = collections.deque(maxlen=ring_size)
        self._black_box_on = black_box_seconds > 0
        self._black_box_ns = int(black_box_seconds * 1e9)
        # The records a fault wrote already, as runs of serial numbers [first, end), in order (writer thread only).
        self._dumped: list[tuple[int, int]] = []
        self._cycle_count = 0
        self._lock = threading.Lock()
        self._stats_lock = threading.Lock()

        # A deque, not a queue.Queue: append and popleft take no lock the caller could wait on
        # (the wake-up event's lock is only taken when the writer thread is asleep).
        self._queue: collections.deque = collections.deque()
        self._wake = threading.Event()
        self._closed = False
        self._failed = False
        self.stats = RecorderStats()
        # The topics the writer thread has registered, in order; _topics may be ahead of it.
        self._registered: list[_Topic] = []
        self._files: list[_File] = []
        self._file: _McapFile | None = None
        self._pending_bytes = 0
        self._last_flush = time.monotonic()
        self._thread = threading.Thread(target=self._run, name="akd_recorder", daemon=True)
        self._thread.start()
        # A recorder left open still gets its summaries when the interpreter exits normally.
        atexit.register(self.close)

    @property
    def bag_path(self) -> Path:
        """The bag directory, made by the writer thread (so it may not exist yet, or have failed).

        ``_2``, ``_3``, ... is appended to its name if another recorder took it that second."""
        return self._folder / self._name

    def add_topic(self, topic: str, msg_class: type, qos: Any = None, *, typestore: Any = None) -> None:
        """Adds a topic of msg_class (see :func:`message_type`) with the QoS its publisher offers.

        Raises ValueError for a topic name that is not absolute, one added before, or a class
        that is no message class.
        """
        if not (isinstance(topic, str) and topic.startswith("/") and not topic.endswith("/") and " " not in topic):
            raise ValueError(f"topic must be an absolute ROS topic name such as '/akd_node/cycle', not {topic!r}")
        self._add_topic(topic, message_type(msg_class, typestore), msg_class, qos)

    def _add_topic(self, topic: str, msg_type: MessageType, msg_class: type, qos: Any) -> None:
        with self._lock:
            if topic in self._topics:
                raise ValueError(f"topic {topic} was added before (topics: {sorted(self._topics)})")
            entry = _Topic(topic, msg_type, _dump_yaml([_qos_profile(qos)]), msg_class)
            self._topics[topic] = entry
        self._enqueue(("topic", entry), control=True)

    def add_cycle_topic(
        self,
        topic: str,
        msg_class: type,
        qos: Any = None,
        *,
        black_box_topic: str | None = None,
        typestore: Any = None,
    ) -> None:
        """Adds the per-cycle topic that :meth:`cycle_records` feeds, and its black box topic.

        The black box topic (default: ``black_box`` in the cycle topic's namespace) has the same
        type; it is only in the bag when the black box is on (``black_box_seconds > 0``), and
        the cycle topic only when ``decimation > 0``.
        """
        if self._cycle_topic is not None:
            raise ValueError(f"the cycle topic is {self._cycle_topic} already; there is one per recorder")
        if black_box_topic is None:
            black_box_topic = topic.rsplit("/", 1)[0] + "/black_box"
        if black_box_topic == topic:
            raise ValueError(f"black_box_topic must differ from the cycle topic {topic}")
        msg_type = message_type(msg_class, typestore)
        if self._decimation:
            self._add_topic(topic, msg_type, msg_class, qos)
        if self._black_box_on:
            self._add_topic(black_box_topic, msg_type, msg_class, qos)
        self._cycle_topic, self._black_box_topic = topic, black_box_topic
        self._cycle_class, self._cycle_type = msg_class, msg_type

    def write(self, topic: str, msg: Any, time_ns: int) -> None:
        """Queues msg for topic at time_ns (nanoseconds since the epoch); never blocks.

        The message must not be changed afterwards: it is serialised by the writer thread.
        Raises ValueError for a topic not added or a message of another type than the topic's;
        a full queue or a failed recorder drops and counts the message instead.
        """
        entry = self._topics.get(topic)
        if entry is None:
            raise ValueError(f"topic {topic} was not added (topics: {sorted(self._topics)})")
        if type(msg) is not entry.msg_class:
            raise ValueError(f"topic {topic} takes {entry.msg_type.name}, not {type(msg).__qualname__}")
        self._enqueue((topic, msg, time_ns))

    def cycle_sample(self, msg: Any, time_ns: int) -> None:
        """Takes one sample, a message of the cycle topic's class, serialised here and then taken
        as :meth:`cycle_records` takes records. Raises ValueError before add_cycle_topic or for a
        message of another type."""
        if type(msg) is not self._cycle_class:
            if self._cycle_topic is None:
                raise ValueError("no cycle topic: call add_cycle_topic first")
            expected, got = self._cycle_class.__qualname__, type(msg).__qualname__
            raise ValueError(f"the cycle topic takes {expected}, not {got}")
        self.cycle_records([(time_ns, self._cycle_type.serialize(msg))])

    def cycle_records(self, records: list[tuple[int, bytes]]) -> None:
        """Takes records of consecutive cycles, each (time ns, the cycle topic's message
        serialised as a bag holds it, e.g. by ``akd_ros._native.cycle_sample_records``),
        ``samples_per_cycle`` a cycle: all into the black box ring, every decimation-th cycle's
        to the cycle topic. Never blocks; raises ValueError before add_cycle_topic."""
        if self._cycle_topic is None:
            raise ValueError("no cycle topic: call add_cycle_topic first")
        first = self._cycle_count
        self._cycle_count += len(records)
        self._ring.extend((first + i, time_ns, data) for i, (time_ns, data) in enumerate(records))
        if self._decimation:
            per_cycle, decimation = self._samples_per_cycle, self._decimation
            kept = [r for i, r in enumerate(records, first) if (i // per_cycle) % decimation == 0]
            if kept:
                self._enqueue(("cycle", kept))

    def fault(self, time_ns: int) -> None:
        """Writes the black box: the samples of the ``black_box_seconds`` up to time_ns (the
        fault's time; samples after it may have been taken already) not written by an earlier fault.

        They go to the black box topic with their own times, and the chunk is closed and synced
        at once so that the moments before the fault survive whatever follows. Does nothing
        without a cycle topic or with ``black_box_seconds=0``.
        """
        if self._cycle_topic is None or not self._black_box_on:
            return
        # Only the copy here (one C call); the writer thread picks the samples.
        self._enqueue(("black_box", list(self._ring), time_ns), control=True)

    def close(self, timeout: float = 30.0) -> RecorderStats:
        """Writes what is queued, finishes the MCAP summaries and metadata.yaml, stops the thread.

        Waits at most timeout seconds for the writer thread; returns the final stats."""
        if not self._closed:
            self._closed = True
            self._enqueue(_CLOSE, control=True)
            atexit.unregister(self.close)
        self._thread.join(timeout)
        return self.stats

    def __enter__(self) -> Recorder:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def _enqueue(self, item: Any, control: bool = False) -> None:
        full = not control and len(self._queue) >= self._queue_size
        refused = self._failed or self._closed or full
        if refused and item is not _CLOSE:
            with self._stats_lock:
                self.stats.dropped += _messages_in(item)
            return
        self._queue.append(item)
        if not self._wake.is_set():
            self._wake.set()

    # --- writer thread ---------------------------------------------------------------------

    def _run(self) -> None:
        try:
            self._folder.mkdir(parents=True, exist_ok=True)
            name, number = self._name, 1
            while True:
                try:
                    self.bag_path.mkdir()
                    break
                except FileExistsError:
                    number += 1
                    self._name = f"{name}_{number}"
            self.stats.bag = self.bag_path
            self._open_file()
            self._save_metadata()
        except Exception as err:  # noqa: BLE001 - every I/O failure is reported, none raised
            self._fail(f"cannot open bag {self.bag_path}: {err}")
        while True:
            self._wake.wait(self._flush_interval)
            self._wake.clear()
            while self._queue:
                item = self._queue.popleft()
                if item is _CLOSE:
                    self._finish()
                    return
                if not self._failed:
                    self._guarded(self._handle, item)
            if not self._failed and self._pending_bytes and self._flush_due():
                self._guarded(self._flush)

    def _flush_due(self) -> bool:
        return time.monotonic() - self._last_flush >= self._flush_interval

    def _guarded(self, action: Callable, *args: Any) -> None:
        try:
            action(*args)
        except Exception as err:  # noqa: BLE001 - every I/O failure is reported, none raised
            self._fail(f"recording into {self.bag_path} stopped: {err}")

    def _fail(self, text: str) -> None:
        self.stats.errors += 1
        if self._failed:
            return
        self._failed = True
        # One report: a caller with on_error logs it its own way (the node through its ROS logger).
        if self._on_error is not None:
            self._on_error(text)
        else:
            LOG.error("%s", text)
        # What waits is lost with the failed disk: count it as dropped.
        with self._stats_lock:
            self.stats.dropped += sum(_messages_in(item) for item in self._queue)

    def _handle(self, item: tuple) -> None:
        if item[0] == "topic":
            self._registered.append(item[1])
            self._file.add_topic(item[1])
            self._save_metadata()
        elif item[0] == "black_box":
            _, ring, fault_ns = item
            self._add_records(self._black_box_topic, self._black_box(ring, fault_ns))
            self.stats.black_box_dumps += 1
            self._flush(sync=True)
        elif item[0] == "cycle":
            self._add_records(self._cycle_topic, item[1])
        else:
            topic, msg, time_ns = item
            self._add_records(topic, [(time_ns, self._topics[topic].msg_type.serialize(msg))])

    def _black_box(self, ring: list[tuple[int, int, bytes]], fault_ns: int) -> list[tuple[int, bytes]]:
        """The records (time ns, data) of `ring` within black_box_seconds up to fault_ns that no fault wrote before.

        Faults may come out of time order (an emergency before the Fault state seen in an earlier cycle): each writes
        its whole window but no record written before. The ring holds consecutive serial numbers in cycle order, so
        its window and what was written are runs found by bisection, and a fault costs the records it writes, not the
        ring: on a host that loses a frame now and then, every such gap is a fault."""
        if not ring:
            return []
        first = ring[0][0]
        self._dumped = [(start, end) for start, end in self._dumped if end > first]
        time_of = operator.itemgetter(1)
        window = (
            bisect.bisect_right(ring, fault_ns - self._black_box_ns, key=time_of) + first,
            bisect.bisect_right(ring, fault_ns, key=time_of) + first,
        )
        taken, at = [], window[0]
        for start, end in [*self._dumped, (window[1], window[1])]:
            if end <= at:
                continue
            taken.extend(ring[at - first : min(start, window[1]) - first])
            at = max(at, end)
            if at >= window[1]:
                break
        self._dumped = _merged([*self._dumped, window])
        return [(time_ns, data) for _, time_ns, data in taken]

    def _add_records(self, topic: str, records: list[tuple[int, bytes]]) -> None:
        """Writes `records` (time ns, data) of `topic`, in time order, into a new file where they reach the split
        duration."""
        entry = self._topics[topic]
        start = 0
        while start < len(records):
            end = len(records)
            if self._split_duration_ns is not None:
                first_ns = self._file.info.start_ns
                limit = (records[start][0] if first_ns is None else first_ns) + self._split_duration_ns
                end = bisect.bisect_left(records, limit, lo=start, key=operator.itemgetter(0))
                if end == start:
                    self._split()
                    continue
            batch = records[start:end]
            self._pending_bytes += self._file.add_messages(topic, batch)
            entry.message_count += len(batch)
            self.stats.written += len(batch)
            start = end
            if self._pending_bytes >= self._chunk_size or self._flush_due():
                self._flush()

    def _flush(self, sync: bool = False) -> None:
        self._file.flush(sync)
        self._pending_bytes = 0
        self._last_flush = time.monotonic()
        self._save_metadata()
        if self._split_size is not None and self._file.size() >= self._split_size:
            self._split()

    def _split(self) -> None:
        self._file.flush()
        self._file.close(self._metadata())
        self._open_file()
        self._pending_bytes = 0
        self._save_metadata()

    def _open_file(self) -> None:
        path = self.bag_path / f"{self._name}_{len(self._files)}.mcap"
        self._file = _McapFile(path, self._registered, self._compression)
        self._files.append(self._file.info)
        self.stats.files.append(path)

    def _metadata(self) -> dict:
        return _bag_metadata(self._registered, self._files)

    def _save_metadata(self) -> None:
        _write_metadata(self.bag_path, self._metadata())

    def _finish(self) -> None:
        if self._failed or self._file is None:
            return
        self._guarded(self._file.close, self._metadata())
        if not self._failed:
            self._guarded(self._save_metadata)


def _merged(runs: list[tuple[int, int]]) -> list[tuple[int, int]]:
    """Runs [first, end) of serial numbers, sorted, overlapping and touching ones joined."""
    merged: list[tuple[int, int]] = []
    for start, end in sorted(run for run in runs if run[0] < run[1]):
        if merged and start <= merged[-1][1]:
            merged[-1] = (merged[-1][0], max(merged[-1][1], end))
        else:
            merged.append((start, end))
    return merged


def _messages_in(item: Any) -> int:
    """How many messages a queue item carries (topic additions and the close carry none)."""
    if item is _CLOSE or item[0] == "topic":
        return 0
    return len(item[1]) if item[0] in ("black_box", "cycle") else 1  # a black box: its ring's records


def _check_positive(name: str, value: Any, integer: bool = False) -> None:
    kinds = (int,) if integer else (int, float)
    if not isinstance(value, kinds) or isinstance(value, bool) or not 0 < value < math.inf:
        kind = "an integer" if integer else "a number"
        raise ValueError(f"{name} must be {kind} > 0, not {value!r}")


# --- reindex ---------------------------------------------------------------------------------


def _read_records(path: Path) -> tuple[list, bool]:
    """The schema, channel and message records of an MCAP file, read to the last whole record.

    Returns them and whether the file was complete (had its footer).
    """
    records = []
    complete = False
    with open(path, "rb") as stream:
        try:
            for record in StreamReader(stream, skip_magic=False).records:
                if isinstance(record, (Schema, Channel, Message)):
                    records.append(record)
            complete = True
        # A file cut anywhere (struct.error: inside a record's length field) holds what precedes the cut.
        except (McapError, EOFError, ValueError, OSError, struct.error) as err:
            LOG.info("%s ends early (%s); recovering what precedes", path.name, err)
    return records, complete


def _has_summary(path: Path) -> bool:
    try:
        with open(path, "rb") as stream:
            return make_reader(stream).get_summary() is not None
    except Exception:  # noqa: BLE001 - any failure means the summary must be rebuilt
        return False


def reindex(bag: os.PathLike | str) -> Path:
    """Rebuilds a bag after a crash, as ``ros2 bag reindex`` does, and returns metadata.yaml's path.

    Each ``.mcap`` file of the directory without a summary (its writer was killed) is rewritten
    with every whole record it holds (all messages of its closed chunks) and a complete summary;
    metadata.yaml is then written anew from the files. Raises FileNotFoundError for a path that
    is no directory or holds no .mcap file.
    """
    bag = Path(bag)
    if not bag.is_dir():
        raise FileNotFoundError(f"{bag} is not a bag directory")

    def index(path: Path) -> tuple[int, str]:
        suffix = path.stem.rsplit("_", 1)[-1]
        return (int(suffix), path.name) if suffix.isdigit() else (-1, path.name)

    paths = sorted(bag.glob("*.mcap"), key=index)
    if not paths:
        raise FileNotFoundError(f"{bag} holds no .mcap file")

    topics: dict[str, _Topic] = {}
    files: list[_File] = []
    for path in paths:
        records, complete = _read_records(path)
        schemas = {r.id: r for r in records if isinstance(r, Schema)}
        channels = {r.id: r for r in records if isinstance(r, Channel)}
        for channel in channels.values():
            if channel.topic not in topics:
                schema = schemas[channel.schema_id]
                msg_type = MessageType(
                    name=schema.name,
                    definition=schema.data.decode(),
                    type_hash=channel.metadata.get("topic_type_hash", ""),
                    serialize=bytes,
                )
                qos_yaml = channel.metadata.get("offered_qos_profiles", "")
                topics[channel.topic] = _Topic(channel.topic, msg_type, qos_yaml)
        info = _File(path)
        for record in records:
            if isinstance(record, Message):
                info.add(record.log_time)
                topics[channels[record.channel_id].topic].message_count += 1
        files.append(info)
        if not (complete and _has_summary(path)):
            _rewrite(path, records, schemas, channels)

    metadata = _bag_metadata(list(topics.values()), files)
    _write_metadata(bag, metadata)
    return bag / "metadata.yaml"


def _rewrite(path: Path, records: list, schemas: dict, channels: dict) -> None:
    tmp = path.with_name(path.name + ".reindex")
    with open(tmp, "wb") as stream:
        writer = Writer(stream, compression=CompressionType.ZSTD)
        writer.start(profile="ros2", library=_LIBRARY)
        schema_ids = {sid: writer.register_schema(s.name, s.encoding, s.data) for sid, s in schemas.items()}
        channel_ids = {
            cid: writer.register_channel(c.topic, c.message_encoding, schema_ids[c.schema_id], c.metadata)
            for cid, c in channels.items()
        }
        for record in records:
            if isinstance(record, Message):
                writer.add_message(
                    channel_ids[record.channel_id],
                    record.log_time,
                    record.data,
                    record.publish_time,
                    record.sequence,
                )
        writer.finish()
        stream.flush()
        os.fsync(stream.fileno())
    os.replace(tmp, path)
