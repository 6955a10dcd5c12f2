"""Recording (`record.enabled`): from configure to cleanup an `akd_ros.recorder.Recorder` writes a rosbag2 bag of
every message published (at its stamp), every command received (refused ones too, at their arrival) and every cycle
of every joint as a CycleSample on ~/cycle (every `record.decimation`-th cycle), and writes its black box
(~/black_box) at each fault."""

from __future__ import annotations

import math

from akd_ros import _native
from akd_ros.axis import Axis
from akd_ros.node.clock import CycleClock
from akd_ros.params import Settings
from akd_ros.recorder import Recorder
from akd_ros.units import Units

# Which target of a cycle record is the command, by the mode the drive shows (0x6061): the one of the mode's command.
_TARGET_OF_MODE = {mode.code: f"target_{mode.command}" for mode in _native.MODES_OF_OPERATION if mode.command}
_UINT32_MAX = 2**32 - 1


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


def record_cycles(
    recorder: Recorder, sample_class, clock: CycleClock, taken: list[tuple[Axis, dict[str, list]]], offset_ns: int
) -> None:
    """Hands each cycle record of each axis's `columns` (`Axis.samples`, taken for every axis at once) to `recorder`
    as a CycleSample, cycle by cycle and in each cycle joint by joint; cycle times are monotonic, and `offset_ns`
    (ROS minus monotonic time) moves them onto the bag's ROS times."""
    rows = sorted(
        (cycle, k, i) for k, (_, columns) in enumerate(taken) for i, cycle in enumerate(columns.get("cycle", ()))
    )
    for _, k, i in rows:
        axis, columns = taken[k]
        _record_sample(recorder, sample_class, clock, axis.name, axis.units, columns, i, offset_ns)


def _record_sample(
    recorder: Recorder,
    sample_class,
    clock: CycleClock,
    joint: str,
    units: Units,
    columns: dict[str, list],
    i: int,
    offset_ns: int,
) -> None:
    """Row `i` of `columns` (of `joint`, in `units`) to `recorder` as a CycleSample."""
    mode = columns["mode"][i]
    target = _TARGET_OF_MODE.get(mode)
    if target == "target_position":
        command = units.position_to_si(columns[target][i])
    elif target == "target_velocity":
        command = units.velocity_to_si(columns[target][i])
    elif target == "target_torque":
        command = units.torque_to_si(columns[target][i])
    else:
        command = math.nan
    time_ns = columns["time_ns"][i] + offset_ns
    sample = sample_class(
        stamp=clock.time(time_ns),
        cycle=columns["cycle"][i],
        joint=joint,
        position=units.position_to_si(columns["position"][i]),
        velocity=units.velocity_to_si(columns["velocity"][i]),
        torque=units.torque_to_si(columns["torque"][i]),
        command=command,
        following_error=columns["following_error"][i] * units.si_per_count,
        position_counts=columns["position"][i],
        statusword=columns["statusword"][i],
        mode_of_operation=mode,
        period_ns=min(columns["period_ns"][i], _UINT32_MAX),
        exchange_ns=min(columns["exchange_ns"][i], _UINT32_MAX),
        wkc=columns["wkc"][i],
    )
    recorder.cycle_sample(sample, time_ns)
