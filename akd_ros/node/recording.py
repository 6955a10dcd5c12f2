"""Recording (`record.enabled`): from configure to cleanup an `akd_ros.recorder.Recorder` writes a rosbag2 bag of
every message published (at its stamp), every command received (refused ones too, at their arrival) and every cycle
of every joint as a CycleSample on ~/cycle (every `record.decimation`-th cycle), and writes its black box
(~/black_box) at each fault. The cycles and the messages the crate makes (/joint_states, the statuses) reach the bag
without Python (`akd_ros.node.publishing`); the recorder's writer thread is the crate's, and a disk that cannot keep
up costs records, dropped and counted, never a delay to a command."""

from __future__ import annotations

from akd_ros.params import Settings
from akd_ros.recorder import Recorder


def open_recorder(transport, settings: Settings, topics: list[tuple[str, type, object]], cycle_qos: object) -> Recorder:
    """A Recorder of `topics` (name, message class, QoS: what the node publishes and the commands it receives) and
    of the node's cycles on ~/cycle (one CycleSample per joint and cycle); raises ValueError or OSError when it
    cannot start."""
    record = settings.record
    recorder = Recorder(
        record["folder"],
        cycle_rate_hz=1.0 / settings.cycle_time,
        samples_per_cycle=len(settings.joints),
        decimation=record["decimation"],
        black_box_seconds=record["black_box_seconds"],
        on_error=lambda text: transport.logger.error(f"recording stopped: {text}"),
    )
    # rosbags' classes (a Zenoh transport's) are described by their typestore; rclpy's by their .msg files.
    typestore = transport.typestore
    try:
        for topic, kind, qos in topics:
            recorder.add_topic(topic, kind, qos, typestore=typestore)
        recorder.add_cycle_topic(
            transport.resolve("~/cycle"),
            transport.recorded_class("akd_ros/msg/CycleSample"),
            cycle_qos,
            typestore=typestore,
        )
    except ValueError:
        recorder.close()
        raise
    transport.logger.info(f"recording to {recorder.bag_path}")
    return recorder
