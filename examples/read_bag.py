"""Reads a bag akd_node recorded (record.enabled): how many messages each topic has, then each joint's cycles from
the CycleSample records: how many, the largest following error and the period's spread. rosbags reads it without
ROS; `ros2 bag info`, Foxglove and the mcap tools read it too.

    .venv/bin/akd_node --ros-args --params-file config/akd_sim.yaml -p record.enabled:=true   # Ctrl-C after a while
    .venv/bin/python examples/read_bag.py                  # the newest bag in bags/, or name one: read_bag.py BAG
"""

import math
import sys
from collections import defaultdict
from pathlib import Path

from rosbags.highlevel import AnyReader
from rosbags.typesys import Stores, get_typestore

bag = Path(sys.argv[1]) if len(sys.argv) > 1 else max(Path("bags").glob("akd_*"), default=None)
if bag is None:
    sys.exit("read_bag: no bag in bags/; record one with akd_node's record.enabled, or name one")

# AnyReader decodes with the bag's own schemas (akd_ros/msg/CycleSample ...): no akd_ros import needed.
with AnyReader([bag], default_typestore=get_typestore(Stores.ROS2_JAZZY)) as reader:
    counts = {c.topic: c.msgcount for c in reader.connections}
    cycles = defaultdict(list)
    recorded = [c for c in reader.connections if c.topic.endswith("/cycle")]
    for connection, _, data in reader.messages(connections=recorded):
        sample = reader.deserialize(data, connection.msgtype)
        cycles[sample.joint].append(sample)

print(f"{bag}:")
for topic, count in sorted(counts.items()):
    if count == 0:
        continue
    print(f"  {topic}: {count} messages")
for joint, samples in cycles.items():
    periods = sorted(s.period_ns for s in samples[1:]) or [0]
    # NaN where the joint's mapping does not carry the following error.
    worst = max((abs(s.following_error) for s in samples if not math.isnan(s.following_error)), default=0.0)
    print(
        f"  {joint}: {len(samples)} cycles, following error up to {worst:.2e} rad, "
        f"period p50 {periods[len(periods) // 2] / 1e6:.3f} ms, max {periods[-1] / 1e6:.3f} ms"
    )
