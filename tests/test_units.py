"""akd_ros.units: drive counts and 0.1 % torque units against SI, the 32-bit position wrap, and set-point limits.

`Units` and `unwrap_position` are the crate's (`_native`): what these tests judge is the one scale by which the node's
joint states, its recorded cycles and its commands convert too."""

from __future__ import annotations

import math
import re

import pytest
from hypothesis import given
from hypothesis import strategies as st

from akd_ros import _native
from akd_ros.units import Limits, Units, unwrap_position

INT32_MIN, INT32_MAX = -(2**31), 2**31 - 1
INT16_MIN, INT16_MAX = -(2**15), 2**15 - 1

REV = 2**20
TAU = 2 * math.pi


@st.composite
def any_units(draw: st.DrawFn) -> Units:
    """Units over the whole range of sensible mechanics, rotary and linear."""
    linear = draw(st.booleans())
    return Units(
        counts_per_revolution=draw(st.integers(1, 2**24)),
        gear_ratio=draw(st.floats(0.01, 100.0)),
        direction=draw(st.sampled_from([1, -1])),
        offset=draw(st.floats(-100.0, 100.0)),
        axis="linear" if linear else "rotary",
        lead=draw(st.floats(1e-4, 1.0)) if linear else None,
        peak_torque=draw(st.floats(0.01, 1000.0)),
    )


# Round trips: each way within one count (or one 0.1 % torque unit).


@given(any_units(), st.integers(INT32_MIN + 1, INT32_MAX - 1))
def test_position_counts_round_trip(units: Units, counts: int) -> None:
    assert abs(units.position_to_counts(units.position_to_si(counts)) - counts) <= 1


@given(any_units(), st.floats(-0.999, 0.999))
def test_position_si_round_trip(units: Units, fraction: float) -> None:
    position = units.position_to_si(round(fraction * INT32_MAX))
    position += fraction * units.si_per_count / 3  # between counts, not on one
    assert abs(units.position_to_si(units.position_to_counts(position)) - position) <= abs(units.si_per_count)


@given(any_units(), st.integers(INT32_MIN + 1, INT32_MAX - 1))
def test_velocity_counts_round_trip(units: Units, counts_per_second: int) -> None:
    assert abs(units.velocity_to_counts(units.velocity_to_si(counts_per_second)) - counts_per_second) <= 1


@given(any_units(), st.floats(-0.999, 0.999))
def test_velocity_si_round_trip(units: Units, fraction: float) -> None:
    velocity = fraction * INT32_MAX * units.si_per_count
    assert abs(units.velocity_to_si(units.velocity_to_counts(velocity)) - velocity) <= abs(units.si_per_count)


@given(any_units(), st.integers(INT16_MIN, INT16_MAX))
def test_torque_drive_round_trip(units: Units, value: int) -> None:
    assert units.torque_to_drive(units.torque_to_si(value)) == value


@given(any_units(), st.floats(-0.999, 0.999))
def test_torque_si_round_trip(units: Units, fraction: float) -> None:
    torque = fraction * INT16_MAX * units.si_per_torque_unit
    assert abs(units.torque_to_si(units.torque_to_drive(torque)) - torque) <= abs(units.si_per_torque_unit)


# Known values.


def test_one_revolution_is_2_pi_rad_and_2_pow_20_counts() -> None:
    units = Units()
    assert units.position_to_counts(TAU) == REV
    assert units.position_to_si(REV) == pytest.approx(TAU, rel=1e-15)
    assert units.velocity_to_counts(TAU) == REV
    assert units.velocity_to_si(-REV) == pytest.approx(-TAU, rel=1e-15)
    assert units.position_unit == "rad"


def test_gear_10_turns_the_motor_10_times_per_load_revolution() -> None:
    units = Units(gear_ratio=10.0, peak_torque=2.5)
    assert units.position_to_counts(TAU) == 10 * REV
    assert units.velocity_to_counts(-TAU) == -10 * REV
    assert units.torque_to_drive(25.0) == 1000  # peak motor torque gives ten times the torque at the load
    assert units.torque_to_si(500) == pytest.approx(12.5)


def test_direction_minus_1_flips_every_sign() -> None:
    units = Units(direction=-1, peak_torque=2.0)
    assert units.position_to_counts(TAU) == -REV
    assert units.position_to_si(REV) == pytest.approx(-TAU)
    assert units.velocity_to_counts(TAU) == -REV
    assert units.torque_to_drive(2.0) == -1000
    assert units.torque_to_si(-1000) == pytest.approx(2.0)


def test_offset_shifts_positions_only() -> None:
    units = Units(offset=1.5)
    assert units.position_to_counts(1.5) == 0
    assert units.position_to_si(0) == 1.5
    assert units.position_to_counts(1.5 + TAU) == REV
    assert units.velocity_to_counts(TAU) == REV


def test_linear_axis_in_metres_and_newtons() -> None:
    units = Units(axis="linear", lead=0.005, gear_ratio=2.0, peak_torque=0.5)
    assert units.position_unit == "m"
    assert units.position_to_counts(0.005) == 2 * REV  # one load revolution
    assert units.velocity_to_counts(0.01) == 4 * REV
    # peak torque 0.5 N·m x gear 2 = 1 N·m at the screw; 2π rad per 5 mm gives 1 N·m x 2π / 0.005 m
    assert units.torque_to_si(1000) == pytest.approx(TAU / 0.005)
    assert units.torque_to_drive(TAU / 0.005 / 2) == 500


def test_peak_torque_is_1000_thousandths() -> None:
    units = Units(peak_torque=3.0)
    assert units.torque_to_drive(3.0) == 1000
    assert units.torque_to_drive(-0.003) == -1
    assert units.torque_to_si(INT16_MAX) == pytest.approx(3.0 * INT16_MAX / 1000)


# The 32-bit position wrap.


def test_unwrap_across_the_int32_ends() -> None:
    assert unwrap_position(INT32_MAX, INT32_MIN) == INT32_MAX + 1
    assert unwrap_position(INT32_MIN, INT32_MAX) == INT32_MIN - 1
    assert unwrap_position(INT32_MAX + 10, INT32_MIN + 20) == INT32_MAX + 21
    assert unwrap_position(5 * 2**32 + 7, 3) == 5 * 2**32 + 3
    assert unwrap_position(-7, -7) == -7


def _raw(counts: int) -> int:
    """What the drive's int32 reads at continuous position `counts`."""
    return (counts + 2**31) % 2**32 - 2**31


@given(st.integers(INT32_MIN, INT32_MAX), st.lists(st.integers(-(2**31) + 1, 2**31 - 1), max_size=50))
def test_unwrap_follows_any_motion_of_less_than_2_pow_31_per_reading(start: int, steps: list[int]) -> None:
    true, continuous = start, start
    for step in steps:
        true += step
        continuous = unwrap_position(continuous, _raw(true))
        assert continuous == true


def test_the_python_face_is_the_crates_one_scale() -> None:
    assert Units is _native.Units and unwrap_position is _native.unwrap_position
    assert Units(gear_ratio=2.0) == Units(gear_ratio=2.0) != Units()
    assert hash(Units(offset=0.5)) == hash(Units(offset=0.5))
    assert repr(Units(axis="linear", lead=0.005)) == (
        "Units(counts_per_revolution=1048576, gear_ratio=1.0, direction=1, offset=0.0, axis='linear', lead=0.005, "
        "peak_torque=3.0)"
    )


@given(st.integers(INT32_MIN, INT32_MAX), st.lists(st.integers(-(2**31) + 1, 2**31 - 1), max_size=50))
def test_a_reader_of_positions_unwraps_by_the_same_rule(start: int, steps: list[int]) -> None:
    # An Axis and the feed each keep a PositionUnwrap: the first reading is taken as it is, each next by the rule.
    reader, true = _native.PositionUnwrap(), start
    assert reader.next(start) == start
    for step in steps:
        true += step
        assert reader.next(_raw(true)) == true == unwrap_position(true - step, _raw(true))


def test_unwrapped_position_stays_continuous_in_si() -> None:
    units = Units()
    before = unwrap_position(INT32_MAX - 1, INT32_MAX - 1)
    after = unwrap_position(before, INT32_MIN + 1)
    assert units.position_to_si(after) - units.position_to_si(before) == pytest.approx(3 * units.si_per_count)


# Refusals, each with its message.


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"counts_per_revolution": 0}, "counts_per_revolution must be a positive integer, got 0"),
        ({"counts_per_revolution": -4096}, "counts_per_revolution must be a positive integer, got -4096"),
        ({"counts_per_revolution": 1048576.0}, "counts_per_revolution must be a positive integer, got 1048576.0"),
        ({"counts_per_revolution": True}, "counts_per_revolution must be a positive integer, got True"),
        ({"gear_ratio": 0.0}, "gear_ratio must be a finite number greater than 0, got 0.0"),
        ({"gear_ratio": -2.0}, "gear_ratio must be a finite number greater than 0, got -2.0"),
        ({"gear_ratio": math.nan}, "gear_ratio must be a finite number greater than 0, got nan"),
        ({"gear_ratio": math.inf}, "gear_ratio must be a finite number greater than 0, got inf"),
        ({"direction": 0}, "direction must be +1 or -1, got 0"),
        ({"direction": 2}, "direction must be +1 or -1, got 2"),
        ({"direction": True}, "direction must be +1 or -1, got True"),
        ({"offset": math.nan}, "offset must be a finite number, got nan"),
        ({"offset": -math.inf}, "offset must be a finite number, got -inf"),
        ({"offset": "0.5"}, "offset must be a finite number, got '0.5'"),
        ({"axis": "angular"}, "axis must be 'rotary' or 'linear', got 'angular'"),
        ({"axis": "linear"}, "lead (m per load revolution) is required for a linear axis"),
        ({"axis": "linear", "lead": 0.0}, "lead must be a finite number greater than 0, got 0.0"),
        ({"lead": 0.01}, "lead applies to a linear axis only; a rotary axis needs lead None, got 0.01"),
        ({"peak_torque": 0.0}, "peak_torque must be a finite number greater than 0, got 0.0"),
        ({"peak_torque": math.nan}, "peak_torque must be a finite number greater than 0, got nan"),
    ],
)
def test_units_refuse_bad_configuration(kwargs: dict, message: str) -> None:
    with pytest.raises(ValueError, match=re.escape(message)):
        Units(**kwargs)


@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf])
@pytest.mark.parametrize("kind", ["position", "velocity", "torque"])
def test_conversions_refuse_non_finite_values(kind: str, bad: float) -> None:
    units = Units()
    convert = {
        "position": units.position_to_counts,
        "velocity": units.velocity_to_counts,
        "torque": units.torque_to_drive,
    }
    with pytest.raises(ValueError, match=re.escape(f"{kind} must be a finite number, got {bad}")):
        convert[kind](bad)


def test_position_outside_int32_is_refused_with_the_range() -> None:
    units = Units()
    largest = units.position_to_si(INT32_MAX)
    assert units.position_to_counts(largest) == INT32_MAX
    message = (
        f"position 13000.0 rad maps to drive value {round(13000.0 / TAU * REV)}, outside [-2147483648, 2147483647]; "
        f"the allowed position range is [{-TAU * 2**11:.6g}, {largest:.6g}] rad"
    )
    with pytest.raises(ValueError, match=re.escape(message)):
        units.position_to_counts(13000.0)


def test_range_in_the_message_follows_direction_and_offset() -> None:
    units = Units(direction=-1, offset=100.0, axis="linear", lead=0.001)
    with pytest.raises(ValueError, match=r"the allowed position range is \[97\.95\d*, 102\.04\d*\] m$"):
        units.position_to_counts(-5.0)


def test_velocity_outside_int32_is_refused() -> None:
    with pytest.raises(ValueError, match=re.escape("velocity 20000.0 rad/s maps to drive value 3337721072, outside")):
        Units().velocity_to_counts(20000.0)


def test_torque_beyond_int16_of_0_1_percent_is_refused() -> None:
    units = Units(peak_torque=1.0)
    assert units.torque_to_drive(32.767) == INT16_MAX
    assert units.torque_to_drive(-32.768) == INT16_MIN
    message = (
        "torque 32.768 N·m maps to drive value 32768, outside [-32768, 32767]; "
        "the allowed torque range is [-32.768, 32.767] N·m"
    )
    with pytest.raises(ValueError, match=re.escape(message)):
        units.torque_to_drive(32.768)


def test_unwrap_refuses_a_raw_position_outside_int32() -> None:
    message = "raw position must be an int32, in [-2147483648, 2147483647], got "
    with pytest.raises(ValueError, match=re.escape(message + "2147483648")):
        unwrap_position(0, INT32_MAX + 1)
    with pytest.raises(ValueError, match=re.escape(message + "1.0")):
        unwrap_position(0, 1.0)  # type: ignore[arg-type]


# Limits.


def test_limits_pass_values_within() -> None:
    limits = Limits(min_position=-1.0, max_position=2.0, max_velocity=3.0, max_torque=4.0)
    assert limits.check("position", -1.0) == -1.0
    assert limits.check("position", 2.0) == 2.0
    assert limits.check("velocity", -3.0) == -3.0
    assert limits.check("torque", 0.5) == 0.5


def test_open_limits_pass_any_finite_value() -> None:
    for kind in ("position", "velocity", "torque"):
        assert Limits().check(kind, -1e300) == -1e300


@pytest.mark.parametrize(
    ("kind", "value", "message"),
    [
        ("position", -1.5, "position -1.5 is beyond the limit min_position; the allowed position range is [-1.0, 2.0]"),
        ("position", 2.5, "position 2.5 is beyond the limit max_position; the allowed position range is [-1.0, 2.0]"),
        ("velocity", -3.5, "velocity -3.5 is beyond the limit max_velocity; the allowed velocity range is [-3.0, 3.0]"),
        ("torque", 4.5, "torque 4.5 is beyond the limit max_torque; the allowed torque range is [-4.0, 4.0]"),
    ],
)
def test_refuse_policy_names_the_limit(kind: str, value: float, message: str) -> None:
    limits = Limits(min_position=-1.0, max_position=2.0, max_velocity=3.0, max_torque=4.0, policy="refuse")
    with pytest.raises(ValueError, match=re.escape(message)):
        limits.check(kind, value)


def test_refuse_names_an_open_end_as_infinite() -> None:
    with pytest.raises(ValueError, match=re.escape("the allowed position range is [-inf, 2.0]")):
        Limits(max_position=2.0).check("position", 3.0)


@pytest.mark.parametrize(
    ("kind", "value", "sent"),
    [("position", -1.5, -1.0), ("position", 2.5, 2.0), ("velocity", -3.5, -3.0), ("torque", 4.5, 4.0)],
)
def test_clamp_policy_sends_the_limit(kind: str, value: float, sent: float) -> None:
    limits = Limits(min_position=-1, max_position=2, max_velocity=3, max_torque=4, policy="clamp")
    assert limits.check(kind, value) == sent
    assert type(limits.check(kind, value)) is float


@pytest.mark.parametrize("policy", ["clamp", "refuse"])
@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf])
@pytest.mark.parametrize("kind", ["position", "velocity", "torque"])
def test_non_finite_set_points_are_refused_under_either_policy(policy: str, bad: float, kind: str) -> None:
    limits = Limits(min_position=-1.0, max_position=2.0, max_velocity=3.0, max_torque=4.0, policy=policy)
    with pytest.raises(ValueError, match=re.escape(f"{kind} must be a finite number, got {bad}")):
        limits.check(kind, bad)


def test_check_refuses_an_unknown_kind() -> None:
    with pytest.raises(ValueError, match=re.escape("kind must be 'position', 'velocity' or 'torque', got 'force'")):
        Limits().check("force", math.nan)  # type: ignore[arg-type]


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"min_position": 1.0, "max_position": 0.0}, "min_position 1.0 must not exceed max_position 0.0"),
        ({"min_position": math.nan}, "min_position must be a finite number, got nan"),
        ({"max_position": math.inf}, "max_position must be a finite number, got inf"),
        ({"max_velocity": 0.0}, "max_velocity must be a finite number greater than 0, got 0.0"),
        ({"max_velocity": -1.0}, "max_velocity must be a finite number greater than 0, got -1.0"),
        ({"max_torque": math.inf}, "max_torque must be a finite number greater than 0, got inf"),
        ({"max_torque": None, "max_velocity": True}, "max_velocity must be a finite number greater than 0, got True"),
        ({"policy": "wrap"}, "policy must be 'clamp' or 'refuse', got 'wrap'"),
    ],
)
def test_limits_refuse_bad_configuration(kwargs: dict, message: str) -> None:
    with pytest.raises(ValueError, match=re.escape(message)):
        Limits(**kwargs)


def test_units_and_limits_are_frozen() -> None:
    with pytest.raises(AttributeError):
        Units().gear_ratio = 2.0  # type: ignore[misc]
    with pytest.raises(AttributeError):
        Limits().policy = "clamp"  # type: ignore[misc]
