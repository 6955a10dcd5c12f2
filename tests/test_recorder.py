"""akd_ros.recorder: bags written by the Recorder, read back by rosbags, mcap and rclpy.

Every test records real rclpy messages through the recorder's writer thread into a bag on disk
and reads it with third-party readers only (rosbags' AnyReader, which decodes with the bag's own
schemas, mcap's reader, rclpy's deserialize_message), so what is checked is what a user of
``ros2 bag`` or Foxglove would see.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest
import sensor_msgs
import yaml
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from mcap.exceptions import EndOfFile, McapError
from mcap.reader import NonSeekingReader, make_reader
from rclpy.qos import qos_profile_sensor_data
from rclpy.serialization import deserialize_message
from rosbags.highlevel import AnyReader, AnyReaderError
from rosbags.typesys import Stores, get_typestore
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64

from akd_ros.recorder import Recorder, message_type, reindex

T0 = 1_700_000_000_000_000_000
RATE_HZ = 1000
PERIOD_NS = 1_000_000_000 // RATE_HZ
CYCLE, BLACK_BOX = "/akd_node/cycle", "/akd_node/black_box"
LATCH, FAULT = "/akd_node/latch", "/akd_node/fault"


def sample(i: int) -> JointState:
    """The synthetic cycle sample number i: position, velocity and torque that follow from i."""
    msg = JointState()
    msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(T0 + i * PERIOD_NS, 1_000_000_000)
    msg.name = ["axis"]
    msg.position = [i * 1e-3]
    msg.velocity = [1.0]
    msg.effort = [0.01 * (i % 50)]
    return msg


def fault_message(code: str) -> DiagnosticArray:
    """A drive fault as diagnostics, the way a fault topic of standard messages would carry it."""
    msg = DiagnosticArray()
    msg.status = [DiagnosticStatus(level=DiagnosticStatus.ERROR, name="akd", message=f"{code} lag too large")]
    return msg


def record_run(folder: Path, cycles=3000, fault_at=2500, latch_at=1200, **options):
    """Records a synthetic run: cycles, a latch, a fault; returns the bag and what went in."""
    options.setdefault("black_box_seconds", 1.0)
    options.setdefault("decimation", 2)
    with Recorder(folder, cycle_rate_hz=RATE_HZ, **options) as recorder:
        recorder.add_cycle_topic(CYCLE, JointState, qos_profile_sensor_data)
        recorder.add_topic(LATCH, Float64)
        recorder.add_topic(FAULT, DiagnosticArray)
        for i in range(cycles):
            recorder.cycle_sample(sample(i), T0 + i * PERIOD_NS)
            if i == latch_at:
                recorder.write(LATCH, Float64(data=sample(i).position[0]), T0 + i * PERIOD_NS)
            if i == fault_at:
                recorder.write(FAULT, fault_message("F439"), T0 + i * PERIOD_NS)
                recorder.fault(T0 + i * PERIOD_NS)
    assert recorder.stats.errors == 0 and recorder.stats.dropped == 0
    return recorder.bag_path, recorder.stats


def read_metadata(bag: Path) -> dict:
    """metadata.yaml's rosbag2_bagfile_information."""
    return yaml.safe_load((bag / "metadata.yaml").read_text())["rosbag2_bagfile_information"]


def topic_metadata(info: dict) -> dict:
    """Each topic's topic_metadata in metadata.yaml, by topic name."""
    return {t["topic_metadata"]["name"]: t["topic_metadata"] for t in info["topics_with_message_count"]}


def topic_counts(info: dict) -> dict:
    """Each topic's message_count in metadata.yaml, by topic name."""
    return {t["topic_metadata"]["name"]: t["message_count"] for t in info["topics_with_message_count"]}


def cycle_index(time_ns: int) -> int:
    """The synthetic run's cycle number at time_ns."""
    return round((time_ns - T0) / PERIOD_NS)


def test_bag_reads_back_with_rosbags_mcap_and_rclpy(tmp_path):
    bag, stats = record_run(tmp_path)
    assert bag.parent == tmp_path and bag.name.startswith("akd_20")
    assert len(bag.name) == len("akd_2026_11_28-20_51_03")
    info = read_metadata(bag)
    assert info["version"] == 9 and info["storage_identifier"] == "mcap"
    assert info["relative_file_paths"] == [f"{bag.name}_0.mcap"]
    assert [f["path"] for f in info["files"]] == [f"{bag.name}_0.mcap"]
    counts = topic_counts(info)
    # Decimation 2 keeps every other cycle; the black box holds the second before the fault.
    assert counts == {CYCLE: 1500, BLACK_BOX: 1000, LATCH: 1, FAULT: 1}
    assert info["message_count"] == sum(counts.values()) == stats.written
    assert info["starting_time"]["nanoseconds_since_epoch"] == T0
    assert info["duration"]["nanoseconds"] == 2998 * PERIOD_NS  # the last decimated sample

    # rosbags: topics, types, counts, hashes and values.
    with AnyReader([bag], default_typestore=get_typestore(Stores.ROS2_JAZZY)) as reader:
        assert {c.topic: c.msgcount for c in reader.connections} == counts
        types = {c.topic: c.msgtype for c in reader.connections}
        assert types == {
            CYCLE: "sensor_msgs/msg/JointState",
            BLACK_BOX: "sensor_msgs/msg/JointState",
            LATCH: "std_msgs/msg/Float64",
            FAULT: "diagnostic_msgs/msg/DiagnosticArray",
        }
        meta_hashes = {n: t["type_description_hash"] for n, t in topic_metadata(info).items()}
        assert {c.topic: c.digest for c in reader.connections} == meta_hashes
        jazzy = get_typestore(Stores.ROS2_JAZZY)
        assert all(meta_hashes[t] == jazzy.hash_rihs01(types[t]) for t in types)
        by_topic: dict[str, list] = {}
        for connection, timestamp, raw in reader.messages():
            msg = reader.deserialize(raw, connection.msgtype)
            by_topic.setdefault(connection.topic, []).append((timestamp, msg))
    cycle_indices = [cycle_index(t) for t, _ in by_topic[CYCLE]]
    assert cycle_indices == list(range(0, 3000, 2))
    for (timestamp, msg), i in zip(by_topic[CYCLE], cycle_indices, strict=True):
        assert msg.position[0] == sample(i).position[0] and msg.effort[0] == sample(i).effort[0]
        assert msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec == timestamp
    assert [cycle_index(t) for t, _ in by_topic[BLACK_BOX]] == list(range(1501, 2501))
    assert [m.data for _, m in by_topic[LATCH]] == [1.2]
    assert by_topic[FAULT][0][1].status[0].message == "F439 lag too large"

    # mcap: profile, schemas, channel metadata as in metadata.yaml, statistics, compressed chunks.
    with open(bag / f"{bag.name}_0.mcap", "rb") as stream:
        reader = make_reader(stream)
        assert reader.get_header().profile == "ros2"
        summary = reader.get_summary()
        assert summary.statistics.message_count == info["message_count"]
        assert summary.chunk_indexes and {c.compression for c in summary.chunk_indexes} == {"zstd"}
        topics = topic_metadata(info)
        for channel in summary.channels.values():
            schema = summary.schemas[channel.schema_id]
            meta = topics[channel.topic]
            assert (schema.name, schema.encoding) == (meta["type"], "ros2msg")
            assert channel.message_encoding == meta["serialization_format"] == "cdr"
            qos = yaml.safe_load(channel.metadata["offered_qos_profiles"])
            assert qos == meta["offered_qos_profiles"]
            assert channel.metadata["topic_type_hash"] == meta["type_description_hash"]
            assert summary.statistics.channel_message_counts[channel.id] == counts[channel.topic]
        events = [(c.topic, m) for _, c, m in reader.iter_messages(topics=[LATCH, FAULT])]
        assert [(t, cycle_index(m.log_time)) for t, m in events] == [(LATCH, 1200), (FAULT, 2500)]
        assert deserialize_message(events[0][1].data, Float64).data == 1.2
        fault = deserialize_message(events[1][1].data, DiagnosticArray)
        assert fault.status[0].message == "F439 lag too large"
        raw = next(m for _, c, m in reader.iter_messages(topics=[CYCLE]))
        assert deserialize_message(raw.data, JointState).position[0] == 0.0

    qos = topics[CYCLE]["offered_qos_profiles"]
    assert qos == [
        {
            "history": "keep_last",
            "depth": 5,
            "reliability": "best_effort",
            "durability": "volatile",
            "deadline": {"sec": 0, "nsec": 0},
            "lifespan": {"sec": 0, "nsec": 0},
            "liveliness": "system_default",
            "liveliness_lease_duration": {"sec": 0, "nsec": 0},
            "avoid_ros_namespace_conventions": False,
        }
    ]


def test_schema_is_the_msg_text_with_its_dependencies_and_the_type_support_hash():
    joint_state = message_type(JointState)
    # <prefix>/lib/pythonX.Y/site-packages/sensor_msgs/__init__.py -> <prefix>/share
    share = Path(sensor_msgs.__file__).parents[4] / "share"
    sections = joint_state.definition.split("\n" + "=" * 80 + "\n")
    assert sections[0] == (share / "sensor_msgs/msg/JointState.msg").read_text()
    for section, name in zip(sections[1:], ["std_msgs/msg/Header", "builtin_interfaces/msg/Time"], strict=True):
        assert section == f"MSG: {name}\n" + (share / f"{name}.msg").read_text()
    assert len(sections) == 3
    generated = json.loads((share / "sensor_msgs/msg/JointState.json").read_text())
    assert joint_state.type_hash == generated["type_hashes"][0]["hash_string"]
    assert message_type(Float64).definition == (share / "std_msgs/msg/Float64.msg").read_text()


def test_the_package_messages_hashes_agree_with_rosbags_hash_of_their_definitions():
    from rosbags.typesys import get_types_from_msg

    from akd_ros.msg import CycleSample, DriveFault, LatchEvent

    for msg_class in (CycleSample, LatchEvent, DriveFault):
        described = message_type(msg_class)
        store = get_typestore(Stores.ROS2_JAZZY)
        store.register(get_types_from_msg(described.definition, described.name))
        assert described.type_hash == store.hash_rihs01(described.name)
        own_text = described.definition.split("\n" + "=" * 80 + "\n")[0]
        msg_file = Path(__file__).parents[1] / "msg" / f"{msg_class.__name__}.msg"
        # Fields and constants as in the .msg file (the type support escapes non-ASCII comments).
        assert fields_of(own_text) == fields_of(msg_file.read_text())


def fields_of(msg_text: str) -> list[str]:
    """The field and constant lines of .msg text, without comments."""
    lines = (line.split("#")[0].strip() for line in msg_text.splitlines())
    return [line for line in lines if line]


def test_rosbags_message_classes_go_through_the_rosbags_serializer(tmp_path):
    store = get_typestore(Stores.ROS2_JAZZY)
    float64 = store.types["std_msgs/msg/Float64"]
    with Recorder(tmp_path, cycle_rate_hz=RATE_HZ) as recorder:
        recorder.add_topic("/value", float64, typestore=store)
        for i in range(10):
            recorder.write("/value", float64(data=i / 4), T0 + i)
    with AnyReader([recorder.bag_path]) as reader:
        values = [reader.deserialize(raw, c.msgtype).data for c, _, raw in reader.messages()]
        assert reader.connections[0].digest == message_type(Float64).type_hash
    assert values == [i / 4 for i in range(10)]


def test_decimation_zero_keeps_only_the_black_box(tmp_path):
    bag, _ = record_run(tmp_path, decimation=0, black_box_seconds=0.5)
    counts = topic_counts(read_metadata(bag))
    assert counts == {BLACK_BOX: 500, LATCH: 1, FAULT: 1}


@pytest.mark.parametrize("faults", [(1500, 1700), (1700, 1500), (1200, 1700, 1500, 1700)])
def test_a_second_fault_writes_only_the_samples_no_fault_wrote(tmp_path, faults):
    # In time order, or not (an emergency seen after the Fault state of an earlier cycle), or the same fault again.
    with Recorder(tmp_path, cycle_rate_hz=RATE_HZ, decimation=0, black_box_seconds=1.0) as recorder:
        recorder.add_cycle_topic(CYCLE, JointState, black_box_topic="/akd/box")
        for i in range(2000):
            recorder.cycle_sample(sample(i), T0 + i * PERIOD_NS)
        for fault in faults:
            recorder.fault(T0 + fault * PERIOD_NS)
    assert recorder.stats.black_box_dumps == len(faults)
    # Faults within black_box_sync_interval (5 s) of the first share its close and sync of the chunk.
    assert recorder.stats.black_box_syncs == 1
    with AnyReader([recorder.bag_path]) as reader:
        indices = [cycle_index(t) for _, t, _ in reader.messages()]
        assert [c.topic for c in reader.connections] == ["/akd/box"]
    assert sorted(indices) == list(range(min(faults) - 999, max(faults) + 1))


def test_records_of_several_joints_a_cycle_are_decimated_and_kept_in_the_black_box_together(tmp_path):
    # Two joints a cycle, both stamped with their cycle's time, handed over in batches as the node does.
    serialize = message_type(JointState).serialize
    joints = ("a", "b")
    records = []
    for i in range(1000):
        for joint in joints:
            msg = sample(i)
            msg.name = [joint]
            records.append((T0 + i * PERIOD_NS, serialize(msg)))
    with Recorder(
        tmp_path, cycle_rate_hz=RATE_HZ, samples_per_cycle=2, decimation=3, black_box_seconds=0.2
    ) as recorder:
        recorder.add_cycle_topic(CYCLE, JointState)
        for start in range(0, len(records), 250):
            recorder.cycle_records(records[start : start + 250])
        recorder.fault(T0 + 900 * PERIOD_NS)
    with AnyReader([recorder.bag_path]) as reader:
        seen = {CYCLE: [], BLACK_BOX: []}
        for c, t, raw in reader.messages():
            seen[c.topic].append((cycle_index(t), reader.deserialize(raw, c.msgtype).name[0]))
    assert seen[CYCLE] == [(i, joint) for i in range(0, 1000, 3) for joint in joints]
    assert seen[BLACK_BOX] == [(i, joint) for i in range(701, 901) for joint in joints]


@pytest.mark.parametrize("split", [{"split_size": 40_000}, {"split_duration": 0.7}])
def test_split_files_are_each_complete_and_all_listed(tmp_path, split):
    bag, stats = record_run(tmp_path, chunk_size=8_000, compression="lz4", **split)
    info = read_metadata(bag)
    names = [f"{bag.name}_{i}.mcap" for i in range(len(stats.files))]
    assert len(names) >= 3
    assert info["relative_file_paths"] == names == sorted(p.name for p in bag.glob("*.mcap"))
    total = 0
    for entry in info["files"]:
        with open(bag / entry["path"], "rb") as stream:
            summary = make_reader(stream).get_summary()
        assert {c.topic for c in summary.channels.values()} == {CYCLE, BLACK_BOX, LATCH, FAULT}
        assert {c.compression for c in summary.chunk_indexes} <= {"lz4"}
        assert summary.statistics.message_count == entry["message_count"]
        if entry["message_count"]:
            start, end = summary.statistics.message_start_time, summary.statistics.message_end_time
            assert entry["starting_time"]["nanoseconds_since_epoch"] == start
            assert entry["duration"]["nanoseconds"] == end - start
        black_box_id = next(c.id for c in summary.channels.values() if c.topic == BLACK_BOX)
        has_black_box = summary.statistics.channel_message_counts.get(black_box_id)
        if "split_duration" in split and not has_black_box:
            # The black box reaches back before its file's start; every other file spans less.
            assert entry["duration"]["nanoseconds"] < 700_000_000
        total += entry["message_count"]
    assert total == info["message_count"] == stats.written
    with AnyReader([bag]) as reader:
        assert sum(1 for _ in reader.messages()) == total


def test_unwritable_folder_is_reported_once_and_writes_are_counted_as_dropped(tmp_path):
    blocker = tmp_path / "not_a_folder"
    blocker.write_text("a file where the recording folder should be")
    reports = []
    recorder = Recorder(blocker / "bags", cycle_rate_hz=RATE_HZ, on_error=reports.append)
    recorder.add_cycle_topic(CYCLE, JointState)
    recorder.add_topic(LATCH, Float64)
    for i in range(2000):
        recorder.cycle_sample(sample(i), T0 + i * PERIOD_NS)
        recorder.write(LATCH, Float64(data=1.0), T0 + i * PERIOD_NS)
    recorder.fault(T0 + 2000 * PERIOD_NS)
    stats = recorder.close()
    assert len(reports) == 1 and str(blocker / "bags") in reports[0]
    assert stats.errors == 1 and stats.written == 0
    # Every cycle and latch message, and the black box's 2000 samples (its ring holds 5 s).
    assert stats.dropped == 2000 * 2 + 2000
    assert not (blocker / "bags").exists()


def test_full_queue_drops_and_counts(tmp_path):
    with Recorder(tmp_path, cycle_rate_hz=RATE_HZ, queue_size=5) as recorder:
        recorder.add_topic(LATCH, Float64)
        # A disk that stalls: the writer thread held while the messages come.
        recorder.hold(True)
        for i in range(20_000):
            recorder.write(LATCH, Float64(data=float(i)), T0 + i)
        recorder.hold(False)
    assert recorder.stats.dropped >= 20_000 - 2 * 5
    assert recorder.stats.written + recorder.stats.dropped == 20_000
    assert read_metadata(recorder.bag_path)["message_count"] == recorder.stats.written


def test_disk_full_is_reported_once_and_the_bag_is_readable_after_reindex(tmp_path):
    # A file size limit makes the kernel refuse writes past it, as a full disk does (EFBIG).
    script = textwrap.dedent(
        f"""
        import resource, signal, sys
        sys.path.insert(0, {str(Path(__file__).parent)!r})
        from test_recorder import sample, T0, PERIOD_NS, CYCLE
        from sensor_msgs.msg import JointState
        from akd_ros.recorder import Recorder
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
        resource.setrlimit(resource.RLIMIT_FSIZE, (60_000, 60_000))
        reports = []
        recorder = Recorder(
            {str(tmp_path)!r}, cycle_rate_hz=1000, chunk_size=4_000, on_error=reports.append
        )
        recorder.add_cycle_topic(CYCLE, JointState)
        for i in range(20_000):
            recorder.cycle_sample(sample(i), T0 + i * PERIOD_NS)
        stats = recorder.close()
        print(len(reports), stats.errors >= 1, stats.written > 0, stats.dropped > 0,
              stats.written + stats.dropped >= 20_000)
        print(reports[0])
        """
    )
    result = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, result.stderr
    lines = result.stdout.splitlines()
    assert lines[0] == "1 True True True True", result.stdout
    assert "File too large" in lines[1]
    (bag,) = tmp_path.iterdir()
    reindex(bag)
    with AnyReader([bag]) as reader:
        indices = [cycle_index(t) for _, t, _ in reader.messages()]
    assert indices and indices == list(range(len(indices)))


KILLED_RECORDER = """
import sys, time
sys.path.insert(0, sys.argv[2])
from test_recorder import sample, T0, PERIOD_NS, CYCLE
from sensor_msgs.msg import JointState
from akd_ros.recorder import Recorder
recorder = Recorder(sys.argv[1], cycle_rate_hz=1000, chunk_size=2_000, flush_interval=0.05)
recorder.add_cycle_topic(CYCLE, JointState)
print(recorder.bag_path, flush=True)
i = 0
while True:
    recorder.cycle_sample(sample(i), T0 + i * PERIOD_NS)
    i += 1
    time.sleep(0.0002)
"""


def test_sigkilled_recording_is_readable_up_to_the_last_closed_chunk(tmp_path):
    process = subprocess.Popen(
        [sys.executable, "-c", KILLED_RECORDER, str(tmp_path), str(Path(__file__).parent)],
        stdout=subprocess.PIPE,
        text=True,
    )
    try:
        bag = Path(process.stdout.readline().strip())
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline:
            meta = bag / "metadata.yaml"
            if meta.exists() and read_metadata(bag)["message_count"] > 500:
                break
            time.sleep(0.05)
        process.send_signal(signal.SIGKILL)
    finally:
        process.kill()
        process.wait()
    counted = read_metadata(bag)["message_count"]
    assert counted > 500
    (mcap_file,) = bag.glob("*.mcap")

    # mcap reads a file without summary from the start, up to the last whole chunk.
    with open(mcap_file, "rb") as stream:
        with pytest.raises(McapError):
            make_reader(stream).get_summary()
        stream.seek(0)
        indices = []
        try:
            for _, _, message in NonSeekingReader(stream).iter_messages(log_time_order=False):
                indices.append(cycle_index(message.log_time))
        except EndOfFile:  # the chunk being written when the process was killed
            pass
    assert len(indices) >= counted and indices == list(range(len(indices)))

    # rosbags needs the summary: it refuses the file until reindex rebuilds it.
    with pytest.raises(AnyReaderError), AnyReader([bag]) as reader:
        list(reader.messages())
    reindex(bag)
    info = read_metadata(bag)
    with AnyReader([bag]) as reader:
        recovered = [cycle_index(t) for _, t, _ in reader.messages()]
        assert reader.connections[0].msgcount == info["message_count"]
    assert recovered == indices
    assert info["files"][0]["message_count"] == len(indices)
    assert info["duration"]["nanoseconds"] == (len(indices) - 1) * PERIOD_NS


@pytest.mark.parametrize(
    "options, text",
    [
        ({"compression": "gzip"}, "compression 'gzip' is not one of ['lz4', 'none', 'zstd']"),
        ({"decimation": -1}, "decimation must be an integer >= 0"),
        ({"split_size": 0}, "split_size must be an integer > 0"),
        ({"split_duration": -2.0}, "split_duration must be a number > 0"),
        ({"black_box_seconds": float("inf")}, "black_box_seconds must be a finite number >= 0"),
        ({"cycle_rate_hz": 0}, "cycle_rate_hz must be a number > 0"),
    ],
)
def test_bad_options_are_named_with_the_allowed_values(tmp_path, options, text):
    options = {"cycle_rate_hz": RATE_HZ, **options}
    with pytest.raises(ValueError, match="^" + text.replace("[", r"\[").replace("]", r"\]")):
        Recorder(tmp_path, **options)


def test_bad_topics_and_classes_are_named(tmp_path):
    with Recorder(tmp_path, cycle_rate_hz=RATE_HZ) as recorder:
        with pytest.raises(ValueError, match="absolute ROS topic name"):
            recorder.add_topic("cycle", JointState)
        with pytest.raises(ValueError, match="is not an rclpy message class"):
            recorder.add_topic("/x", dict)
        with pytest.raises(ValueError, match=r"qos must be an rclpy.qos.QoSProfile or None"):
            recorder.add_topic("/x", Float64, qos="reliable")
        recorder.add_topic("/x", Float64)
        with pytest.raises(ValueError, match=r"topic /x was added before \(topics: \['/x'\]\)"):
            recorder.add_topic("/x", Float64)
        with pytest.raises(ValueError, match=r"topic /y was not added \(topics: \['/x'\]\)"):
            recorder.write("/y", Float64(), T0)
        with pytest.raises(ValueError, match="topic /x takes std_msgs/msg/Float64, not JointState"):
            recorder.write("/x", JointState(), T0)
        with pytest.raises(ValueError, match="no cycle topic: call add_cycle_topic first"):
            recorder.cycle_sample(sample(0), T0)
        recorder.add_cycle_topic(CYCLE, JointState)
        with pytest.raises(ValueError, match="the cycle topic takes JointState, not Float64"):
            recorder.cycle_sample(Float64(), T0)


def test_reindex_of_a_folder_without_mcap_files_says_so(tmp_path):
    with pytest.raises(FileNotFoundError, match=r"holds no .mcap file"):
        reindex(tmp_path)
    with pytest.raises(FileNotFoundError, match="is not a bag directory"):
        reindex(tmp_path / "missing")


def test_reindex_of_a_finished_bag_rebuilds_the_same_metadata(tmp_path):
    bag, _ = record_run(tmp_path, split_size=40_000, chunk_size=8_000)
    before = read_metadata(bag)
    sizes = {p: p.stat().st_size for p in bag.glob("*.mcap")}
    os.remove(bag / "metadata.yaml")
    reindex(bag)
    assert read_metadata(bag) == before
    assert {p: p.stat().st_size for p in bag.glob("*.mcap")} == sizes


def test_two_recorders_in_the_same_second_get_two_bags(tmp_path):
    recorders = [Recorder(tmp_path, cycle_rate_hz=RATE_HZ) for _ in range(3)]
    for recorder in recorders:
        recorder.add_topic(LATCH, Float64)
        recorder.write(LATCH, Float64(data=1.0), T0)
        recorder.close()
    bags = {recorder.bag_path for recorder in recorders}
    assert len(bags) == 3 and bags == set(tmp_path.iterdir())
    assert all(read_metadata(bag)["message_count"] == 1 for bag in bags)


def test_a_recorder_left_open_is_closed_at_exit(tmp_path):
    script = textwrap.dedent(
        f"""
        from std_msgs.msg import Float64
        from akd_ros.recorder import Recorder
        recorder = Recorder({str(tmp_path)!r}, cycle_rate_hz=1000, prefix="")
        recorder.add_topic("/value", Float64)
        for i in range(100):
            recorder.write("/value", Float64(data=float(i)), {T0} + i)
        """
    )
    subprocess.run([sys.executable, "-c", script], check=True, timeout=120)
    (bag,) = tmp_path.iterdir()
    assert bag.name.startswith("20") and len(bag.name) == len("2026_11_28-20_51_03")
    with AnyReader([bag]) as reader:
        assert [reader.deserialize(raw, c.msgtype).data for c, _, raw in reader.messages()] == [
            float(i) for i in range(100)
        ]
