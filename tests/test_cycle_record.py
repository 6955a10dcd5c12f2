"""`_native.cycle_sample_records`: the crate builds and serialises the recorder's per-cycle CycleSample messages.

Its bytes must be those of the same message built field by field in Python with the joint's `Units` and serialised by
rclpy (the recorder's serialisation), so the records of three drives of `sim:3` in three modes, moving, are compared
with that; and rosbags reads them back.
"""

from __future__ import annotations

import math

import pytest
from builtin_interfaces.msg import Time
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

from akd_ros import Bus, DriveConfig, Units, _native
from akd_ros.msg import CycleSample
from akd_ros.recorder import message_type
from support.waiting import wait_for

DRIVES = [
    DriveConfig(slave=0, name="csp", mode="cyclic_synchronous_position", units=Units(gear_ratio=3.0, offset=-1.25)),
    DriveConfig(slave=1, name="velocity", mode="profile_velocity", units=Units(direction=-1)),
    DriveConfig(slave=2, name="torque", mode="profile_torque", units=Units(axis="linear", lead=0.01, peak_torque=6.0)),
]
# ROS minus monotonic time, as the node passes it: negative too, to cross the epoch's second boundaries.
OFFSET_NS = 1_733_000_000_123_456_789

NAME = "akd_ros/msg/CycleSample"
_COMMAND_OF_MODE = {mode.code: mode.command for mode in _native.MODES_OF_OPERATION if mode.command}


def reference(joint: str, units: Units, columns: dict[str, list], i: int, offset_ns: int) -> CycleSample:
    """Row `i` of `columns` as a CycleSample built field by field, as its .msg file describes it."""
    command = _COMMAND_OF_MODE.get(columns["mode"][i])
    to_si = {"position": units.position_to_si, "velocity": units.velocity_to_si, "torque": units.torque_to_si}
    ns = columns["time_ns"][i] + offset_ns
    return CycleSample(
        stamp=Time(sec=ns // 10**9, nanosec=ns % 10**9),
        cycle=columns["cycle"][i],
        joint=joint,
        position=units.position_to_si(columns["position"][i]),
        velocity=units.velocity_to_si(columns["velocity"][i]),
        torque=units.torque_to_si(columns["torque"][i]),
        command=to_si[command](columns[f"target_{command}"][i]) if command else math.nan,
        following_error=columns["following_error"][i] * units.si_per_count,
        position_counts=columns["position"][i],
        statusword=columns["statusword"][i],
        mode_of_operation=columns["mode"][i],
        period_ns=columns["period_ns"][i],
        exchange_ns=columns["exchange_ns"][i],
        wkc=columns["wkc"][i],
    )


@pytest.fixture(scope="module")
def taken():
    """Each drive's records of a few hundred cycles, the three enabled and commanded."""
    with Bus("sim:3?missed=lost", DRIVES) as bus:
        bus.enable()
        csp, velocity, torque = bus.axes
        csp.command_position(csp.state().position + 0.2)
        velocity.command_velocity(2.0)
        torque.command_torque(-30.0)
        end = csp.state().cycle + 300
        wait_for("300 cycles", lambda: csp.state().cycle >= end)
        yield [(axis, axis.samples()) for axis in bus.axes]


@pytest.mark.parametrize("offset_ns", [OFFSET_NS, -OFFSET_NS])
def test_records_are_the_bytes_rclpy_gives_the_same_message_in_cycle_then_joint_order(taken, offset_ns) -> None:
    serialize = message_type(CycleSample).serialize
    store = cycle_sample_typestore()
    records = _native.cycle_sample_records([(a.name, a.units, columns) for a, columns in taken], offset_ns)
    expected = sorted(
        (columns["cycle"][i], k, reference(axis.name, axis.units, columns, i, offset_ns))
        for k, (axis, columns) in enumerate(taken)
        for i in range(len(columns["cycle"]))
    )
    assert len(records) == len(expected) >= 900
    assert [t for t, _ in records] == [m.stamp.sec * 10**9 + m.stamp.nanosec for _, _, m in expected]
    # Fast CDR leaves the alignment padding unwritten: its bytes are compared as rosbags writes them (zeros), after
    # rosbags has read them, and their lengths as they are.
    assert [len(data) for _, data in records] == [len(serialize(m)) for _, _, m in expected]
    rclpy_bytes = [serialize(m) for _, _, m in expected]
    assert [data for _, data in records] == [
        bytes(store.serialize_cdr(store.deserialize_cdr(b, NAME), NAME)) for b in rclpy_bytes
    ]
    # Moving as commanded, so the comparison covers values other than zeros.
    modes = {m.joint: m.mode_of_operation for _, _, m in expected}
    assert modes == {"csp": 8, "velocity": 3, "torque": 4}
    assert {m.joint for _, _, m in expected if m.command != 0.0} == {"csp", "velocity", "torque"}


def cycle_sample_typestore():
    """A rosbags typestore of CycleSample from the definition a bag carries."""
    store = get_typestore(Stores.EMPTY)
    store.register(get_types_from_msg(message_type(CycleSample).definition, NAME))
    return store


def one_row(**values: int) -> dict[str, list]:
    """Columns of one record as `Cycle.samples` gives them: zeros but for `values`."""
    return {name: [values.get(name, 0)] for name in _native.SAMPLE_COLUMNS}


def test_rosbags_reads_a_record_back_with_its_stamp_and_nan_for_a_mode_without_command() -> None:
    row = one_row(cycle=5, time_ns=2_000_000_007, mode=6, position=100, statusword=0x1637, wkc=3)
    [(time_ns, data)] = _native.cycle_sample_records([("j", Units(), row)], -1_000_000_000)
    message = cycle_sample_typestore().deserialize_cdr(data, NAME)
    assert time_ns == 1_000_000_007
    assert (message.stamp.sec, message.stamp.nanosec, message.cycle, message.joint) == (1, 7, 5, "j")
    assert (message.position_counts, message.statusword, message.wkc, message.mode_of_operation) == (100, 0x1637, 3, 6)
    assert math.isnan(message.command)  # homing has no command


def test_records_without_a_column_or_with_columns_of_unequal_length_are_refused_by_name() -> None:
    with pytest.raises(ValueError, match='without their "wkc" column'):
        _native.cycle_sample_records([("j", Units(), {k: v for k, v in one_row().items() if k != "wkc"})], 0)
    uneven = one_row()
    uneven["torque"] = [0, 0]
    with pytest.raises(ValueError, match="differ in length"):
        _native.cycle_sample_records([("j", Units(), uneven)], 0)
    assert _native.cycle_sample_records([("j", Units(), {})], 0) == []
