"""Recording of the drive's topics into rosbag2 bags, with a black box of the last seconds.

A :class:`Recorder` writes one rosbag2 bag directory (metadata.yaml version 9 and MCAP files with
the ``ros2`` profile) as ``ros2 bag record -s mcap`` would, without needing rosbag2 itself. The
MCAP files are written by a thread of the crate (``akd_ros._native.BagWriter``), which does all
their I/O and holds no lock and no GIL that anyone handing it a message waits for; a thread of the
recorder's own writes metadata.yaml when the files change.

- Messages arrive serialised (:meth:`Recorder.write_serialized`: the bytes a middleware
  publishes or delivers) or are serialised by the caller (:meth:`Recorder.write`), by rclpy's
  ``serialize_message`` (rclpy message classes) or by rosbags' ``serialize_cdr`` (rosbags
  message classes with their typestore); the schemas are the complete ``ros2msg`` definitions,
  made of the packages' .msg files as rosbag2 makes them, and the type hashes their RIHS01
  hashes, computed by rosbags' typestore from those definitions, so every reader decodes the bag
  without this package.
- The per-cycle channel (:meth:`Recorder.cycle_records`, already serialised, e.g. by
  ``akd_ros._native.cycle_sample_records``; :meth:`Recorder.cycle_sample`, one message; or
  :meth:`Recorder.take_cycles_from`, a running cycle's records taken by the writer thread
  itself) is recorded every ``decimation``-th cycle, or not at all with ``decimation=0``; the
  last ``black_box_seconds`` of every cycle are kept in memory regardless, and
  :meth:`Recorder.fault` writes them to the black box topic (by default ``black_box`` beside
  the cycle topic, e.g. ``/akd_node/black_box``) with their own times, so the cycles before a
  fault are in the bag even when the cycle topic is not recorded. The chunk is closed and synced
  at a fault, at most once per ``black_box_sync_interval``: the faults of a host that loses a
  frame every few seconds (each a fault of every drive) share one.
- Chunks are closed (and so safe from a crash of the process) every ``chunk_size`` bytes or
  ``flush_interval`` seconds, and metadata.yaml is rewritten after them, at most once per
  ``flush_interval``, to describe exactly what the closed chunks hold. A bag whose process was
  killed has MCAP files without a summary: :func:`reindex` rebuilds their summaries and
  metadata.yaml, as ``ros2 bag reindex`` does.
- Files are split by size or by duration into ``<bag>_0.mcap``, ``<bag>_1.mcap``, ..., each a
  complete MCAP file with all schemas and channels.
- Handing over never blocks and never raises for I/O: a full queue drops the message and
  counts it; a failed disk (unwritable folder, disk full) is reported once, through
  ``on_error`` or else the ``akd_ros.recorder`` logger, and counted in :attr:`Recorder.stats`;
  recording stops there, and the bag stays readable up to the last closed chunk.
"""

from __future__ import annotations

import atexit
import collections
import datetime
import functools
import importlib
import logging
import math
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
    number: int = 0
    """Its number with the crate's writer (the order added)."""

    @functools.cached_property
    def topic_metadata(self) -> dict:
        """Its topic_metadata in metadata.yaml, made once."""
        return {
            "name": self.name,
            "type": self.msg_type.name,
            "serialization_format": _SERIALIZATION,
            "offered_qos_profiles": yaml.safe_load(self.qos_yaml),
            "type_description_hash": self.msg_type.type_hash,
        }


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


def _bag_metadata(topics: list[tuple[_Topic, int]], files: list[_File]) -> dict:
    """metadata.yaml's content, as rosbag2 (Jazzy) writes it, for the given topics (each with its message count) and
    files."""
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
                {"topic_metadata": t.topic_metadata, "message_count": count} for t, count in topics
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


@dataclass
class RecorderStats:
    """Counters of a Recorder, all since it was made.

    ``written`` messages are in the bag's closed chunks or pending in the open one; ``dropped``
    were refused because the queue was full or recording had stopped on an error; ``errors``
    counts I/O failures (only the first is reported); ``black_box_dumps`` counts faults whose
    black box was written, ``black_box_syncs`` the closes and syncs of the chunk they made
    (coalesced); ``files`` are the bag's MCAP files so far.
    """

    bag: Path | None = None
    written: int = 0
    dropped: int = 0
    errors: int = 0
    black_box_dumps: int = 0
    black_box_syncs: int = 0
    files: list[Path] = field(default_factory=list)


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
    - ``black_box_sync_interval`` (seconds): the least time between two closes and syncs of the
      chunk for faults; the faults in between are written at once and synced together after it.
    - ``queue_size``: items waiting for the writer thread (a message, or one call's cycle
      records) beyond which the next is dropped.
    - ``on_error``: called once, from the recorder's thread, with the text of the first I/O error
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
        black_box_sync_interval: float = 5.0,
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
        _check_positive("black_box_sync_interval", black_box_sync_interval)
        if split_size is not None:
            _check_positive("split_size", split_size, integer=True)
        if split_duration is not None:
            _check_positive("split_duration", split_duration)
        if not isinstance(decimation, int) or isinstance(decimation, bool) or decimation < 0:
            raise ValueError(f"decimation must be an integer >= 0 (0: cycle topic off), not {decimation!r}")
        if not isinstance(black_box_seconds, (int, float)) or not 0 <= black_box_seconds < math.inf:
            raise ValueError(f"black_box_seconds must be a finite number >= 0, not {black_box_seconds!r}")

        self._folder = Path(folder)
        self._flush_interval = flush_interval
        self._decimation = decimation
        self._on_error = on_error
        stamp = datetime.datetime.now().strftime("%Y_%m_%d-%H_%M_%S")
        self._name = f"{prefix}_{stamp}" if prefix else stamp
        self._topics: dict[str, _Topic] = {}
        self._cycle_topic: str | None = None
        self._cycle_class: type | None = None
        self._cycle_type: MessageType | None = None
        self._black_box_on = black_box_seconds > 0
        self._lock = threading.Lock()
        self._closed = False
        self._report: dict = {"bag": None, "files": []}
        self._metadata_errors = 0
        ring_size = max(1, math.ceil((black_box_seconds + _BLACK_BOX_MARGIN_S) * cycle_rate_hz) * samples_per_cycle)
        self._writer = _native.BagWriter(
            self._folder,
            self._name,
            compression=compression,
            profile="ros2",
            library=_LIBRARY,
            chunk_size=chunk_size,
            flush_interval=flush_interval,
            split_size=split_size,
            split_duration=split_duration,
            queue_size=queue_size,
            decimation=decimation,
            samples_per_cycle=samples_per_cycle,
            black_box_seconds=black_box_seconds,
            ring_size=ring_size,
            sync_interval=black_box_sync_interval,
        )
        self._keeper = threading.Thread(target=self._keep, name="akd_recorder", daemon=True)
        self._keeper.start()
        # A recorder left open still gets its summaries when the interpreter exits normally.
        atexit.register(self.close)

    @property
    def bag_path(self) -> Path:
        """The bag directory, made by the writer thread (so it may not exist yet, or have failed).

        ``_2``, ``_3``, ... is appended to its name if another recorder took it that second."""
        bag = self._report["bag"]
        return Path(bag) if bag is not None else self._folder / self._name

    @property
    def stats(self) -> RecorderStats:
        """The counters now (see :class:`RecorderStats`)."""
        counters = self._writer.counters()
        return RecorderStats(
            bag=self._report["bag"] and Path(self._report["bag"]),
            written=counters["written"],
            dropped=counters["dropped"],
            errors=counters["errors"] + self._metadata_errors,
            black_box_dumps=counters["black_box_dumps"],
            black_box_syncs=counters["black_box_syncs"],
            files=[Path(f["path"]) for f in self._report["files"]],
        )

    def add_topic(self, topic: str, msg_class: type, qos: Any = None, *, typestore: Any = None) -> None:
        """Adds a topic of msg_class (see :func:`message_type`) with the QoS its publisher offers.

        Raises ValueError for a topic name that is not absolute, one added before, or a class
        that is no message class.
        """
        if not (isinstance(topic, str) and topic.startswith("/") and not topic.endswith("/") and " " not in topic):
            raise ValueError(f"topic must be an absolute ROS topic name such as '/akd_node/cycle', not {topic!r}")
        self._add_topic(topic, message_type(msg_class, typestore), msg_class, qos)

    def _add_topic(self, topic: str, msg_type: MessageType, msg_class: type, qos: Any) -> _Topic:
        with self._lock:
            if topic in self._topics:
                raise ValueError(f"topic {topic} was added before (topics: {sorted(self._topics)})")
            entry = _Topic(topic, msg_type, _dump_yaml([_qos_profile(qos)]), msg_class, len(self._topics))
            self._topics[topic] = entry
            metadata = {"offered_qos_profiles": entry.qos_yaml, "topic_type_hash": msg_type.type_hash}
            self._writer.add_topic(topic, msg_type.name, msg_type.definition.encode(), metadata)
        return entry

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
        cycle = self._add_topic(topic, msg_type, msg_class, qos).number if self._decimation else None
        box = self._add_topic(black_box_topic, msg_type, msg_class, qos).number if self._black_box_on else None
        self._writer.set_cycle_topics(cycle, box)
        self._cycle_topic = topic
        self._cycle_class, self._cycle_type = msg_class, msg_type

    def _topic(self, topic: str) -> _Topic:
        entry = self._topics.get(topic)
        if entry is None:
            raise ValueError(f"topic {topic} was not added (topics: {sorted(self._topics)})")
        return entry

    def write(self, topic: str, msg: Any, time_ns: int) -> None:
        """Serialises msg (here, in the caller) and queues it for topic at time_ns (nanoseconds
        since the epoch); never blocks.

        Raises ValueError for a topic not added or a message of another type than the topic's;
        a full queue or a failed recorder drops and counts the message instead.
        """
        entry = self._topic(topic)
        if type(msg) is not entry.msg_class:
            raise ValueError(f"topic {topic} takes {entry.msg_type.name}, not {type(msg).__qualname__}")
        self._writer.write(entry.number, time_ns, entry.msg_type.serialize(msg))

    def write_serialized(self, topic: str, data: bytes, time_ns: int) -> None:
        """Queues `data`, a message of topic serialised as the bag holds it (CDR, as a middleware
        publishes it), at time_ns; as :meth:`write`, without serialising."""
        self._writer.write(self._topic(topic).number, time_ns, data)

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
        if records:
            self._writer.records(records)

    def take_cycles_from(self, feed: Any) -> None:
        """From now on the writer thread takes every cycle's records of `feed` (an
        ``akd_ros._native.Feed``) itself, as :meth:`cycle_records` takes them, without Python."""
        if self._cycle_topic is None:
            raise ValueError("no cycle topic: call add_cycle_topic first")
        feed.record_cycles(self._writer)

    def take_stream_from(self, feed: Any, stream: int, topic: str) -> None:
        """Every message `feed` makes on its stream `stream` is also recorded on `topic`, at its stamp, by the crate."""
        feed.record(stream, self._writer, self._topic(topic).number)

    def fault(self, time_ns: int) -> None:
        """Writes the black box: the samples of the ``black_box_seconds`` up to time_ns (the
        fault's time; samples after it may have been taken already) not written by an earlier fault.

        They go to the black box topic with their own times, at once, and the chunk is closed and
        synced, at once for the first fault and at most every ``black_box_sync_interval`` after
        it, so that the moments before the fault survive whatever follows. Does nothing without
        a cycle topic or with ``black_box_seconds=0``.
        """
        if self._cycle_topic is None or not self._black_box_on:
            return
        self._writer.fault(time_ns)

    def hold(self, held: bool) -> None:
        """Holds the writer thread where it is (True) until released (False): a disk that stalls, on demand, to see
        what a stall costs (the queue fills and drops; the cycles' records are lost and counted where they wait)."""
        self._writer.hold(held)

    def close(self, timeout: float = 30.0) -> RecorderStats:
        """Writes what is queued, finishes the MCAP summaries and metadata.yaml, stops the thread.

        Waits at most timeout seconds for the writer thread; returns the final stats."""
        if not self._closed:
            self._closed = True
            self._writer.hold(False)
            self._writer.close()
            atexit.unregister(self.close)
        self._keeper.join(timeout)
        self._writer.join(max(0.0, timeout))
        return self.stats

    def __enter__(self) -> Recorder:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # --- the recorder's thread: metadata.yaml and the files' metadata records ------------------------------

    def _keep(self) -> None:
        """Writes metadata.yaml when the writer's files change (a chunk closed, a file split off), at most once per
        flush_interval (its YAML is the recorder's one Python cost per chunk: every cycle recorded closes a chunk
        several times a second), and gives the files it parked their metadata record, until the writer's end;
        reports the first failure."""
        seen, reported, written = 0, False, -math.inf
        while True:
            report = self._writer.report(seen, 60.0)
            if report["version"] == seen:
                continue
            wait = written + self._flush_interval - time.monotonic()
            if wait > 0 and not (report["closing"] or report["done"] or report["failure"] or report["parked"]):
                # What changes meanwhile is in the report taken after the wait.
                time.sleep(wait)
                report = self._writer.report(report["version"], 0.0)
            seen, self._report, written = report["version"], report, time.monotonic()
            failure = report["failure"]
            if failure is not None and not reported:
                reported = True
                self._report_error(failure)
            elif failure is None and report["bag"] is not None:
                metadata = self._metadata(report)
                if report["parked"]:
                    information = metadata["rosbag2_bagfile_information"]
                    self._writer.finish(_dump_yaml(information))
                try:
                    _write_metadata(Path(report["bag"]), metadata)
                except OSError as err:
                    self._metadata_errors += 1
                    if not reported:
                        reported = True
                        self._report_error(f"recording into {report['bag']}: metadata.yaml not written: {err}")
            if report["done"]:
                return

    def _report_error(self, text: str) -> None:
        # One report: a caller with on_error logs it its own way (the node through its ROS logger).
        if self._on_error is not None:
            self._on_error(text)
        else:
            LOG.error("%s", text)

    def _metadata(self, report: dict) -> dict:
        topics = list(self._topics.values())
        files = []
        for f in report["files"]:
            start, end = f["span"] if f["span"] is not None else (None, None)
            files.append(_File(Path(f["path"]), start, end, f["messages"]))
        return _bag_metadata(list(zip(topics, report["topic_messages"], strict=False)), files)


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
    counts: collections.Counter = collections.Counter()
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
                counts[channels[record.channel_id].topic] += 1
        files.append(info)
        if not (complete and _has_summary(path)):
            _rewrite(path, records, schemas, channels)

    metadata = _bag_metadata([(t, counts[name]) for name, t in topics.items()], files)
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
