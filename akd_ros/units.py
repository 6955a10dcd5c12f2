"""Conversion between the AKD's drive units and SI units of the load (REP 103), and set-point limits.

The drive speaks in counts of the motor's feedback and in thousandths of the drive's peak torque; the Python surface
speaks in rad, rad/s and N·m for a rotary axis, or m, m/s and N for a linear one. `Units` holds the mechanics that
relate the two; `Limits` checks set-points before they are converted and sent.

Drive units, as the virtual AKD uses them:

- position (0x6064, 0x607A): int32 counts of the motor, `counts_per_revolution` per motor revolution. The drive's
  counter wraps at 32 bits; `unwrap_position` turns successive raw readings into one continuous count.
- velocity (0x606C, 0x60FF): int32 counts per second. This is an assumption the virtual AKD makes; the real AKD's
  DS402 velocity unit is configurable, so a real drive must be set up to match it.
- torque (0x6071, 0x6077): int16 in 0.1 % of the drive's peak torque (thousandths: 1000 means 100 %). The AKD
  manual says so for mode 4 ("torque in % of drive peak torque"), unlike CiA 402's per mille of rated torque.

`gear_ratio` is motor revolutions per load revolution, `direction` flips the load's sense against the motor's, and
`offset` is the load position (SI) at motor count 0. A linear axis moves `lead` metres per load revolution.
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Callable
from dataclasses import dataclass
from typing import Literal

INT32_MIN, INT32_MAX = -(2**31), 2**31 - 1
INT16_MIN, INT16_MAX = -(2**15), 2**15 - 1
TORQUE_UNITS_PER_PEAK = 1000
"""Drive torque units per peak torque: 0x6071/0x6077 count in 0.1 %."""

AxisKind = Literal["rotary", "linear"]
LimitKind = Literal["position", "velocity", "torque"]
Policy = Literal["clamp", "refuse"]


def _finite(name: str, value: float, *, positive: bool = False) -> float:
    """`value` as a float, or a ValueError naming `name` when it is no real number, NaN, infinite or (if `positive`)
    not greater than zero."""
    if (
        isinstance(value, bool)
        or not isinstance(value, numbers.Real)
        or not math.isfinite(value)
        or (positive and value <= 0)
    ):
        allowed = "a finite number greater than 0" if positive else "a finite number"
        raise ValueError(f"{name} must be {allowed}, got {value!r}")
    return float(value)


def _drive_value(
    name: str, si: float, value: int, drive_range: tuple[int, int], to_si: Callable[[int], float], unit: str
) -> int:
    """The drive `value` for `si`, or a ValueError saying it falls outside `drive_range` and which SI values fit."""
    low, high = drive_range
    if not low <= value <= high:
        ends = sorted((to_si(low), to_si(high)))
        raise ValueError(
            f"{name} {si} {unit} maps to drive value {value}, outside [{low}, {high}]; "
            f"the allowed {name} range is [{ends[0]:.9g}, {ends[1]:.9g}] {unit}"
        )
    return value


def unwrap_position(previous: int, raw: int) -> int:
    """The continuous count nearest `previous` that reads as the int32 `raw` on the drive.

    The drive's position wraps from 2**31 - 1 to -2**31; feeding each raw reading with the last result keeps the
    count continuous as long as the axis moves less than 2**31 counts between readings. Start with `previous = raw`.
    """
    if isinstance(raw, bool) or not isinstance(raw, int) or not INT32_MIN <= raw <= INT32_MAX:
        raise ValueError(f"raw position must be an int32, in [{INT32_MIN}, {INT32_MAX}], got {raw!r}")
    step = (raw - previous + 2**31) % 2**32 - 2**31
    return previous + step


@dataclass(frozen=True)
class Units:
    """How drive counts and thousandths of peak torque map to SI units of the load (see the module doc)."""

    counts_per_revolution: int = 2**20
    """Feedback counts per motor revolution; the virtual AKD uses 2**20."""
    gear_ratio: float = 1.0
    """Motor revolutions per load revolution."""
    direction: int = 1
    """+1 when the load turns with the motor's positive sense, -1 when against it."""
    offset: float = 0.0
    """Load position at motor count 0: rad for a rotary axis, m for a linear one."""
    axis: AxisKind = "rotary"
    """"rotary" (rad, rad/s, N·m) or "linear" (m, m/s, N)."""
    lead: float | None = None
    """Metres the load travels per load revolution; required for, and only for, a linear axis."""
    peak_torque: float = 3.0
    """The drive's peak torque at the motor in N·m (peak current times motor torque constant), which drive torque value
    1000 (100 %) means; the virtual AKD's is 3 N·m."""

    def __post_init__(self) -> None:
        cpr = self.counts_per_revolution
        if isinstance(cpr, bool) or not isinstance(cpr, int) or cpr <= 0:
            raise ValueError(f"counts_per_revolution must be a positive integer, got {cpr!r}")
        _finite("gear_ratio", self.gear_ratio, positive=True)
        if self.direction not in (1, -1) or isinstance(self.direction, bool):
            raise ValueError(f"direction must be +1 or -1, got {self.direction!r}")
        _finite("offset", self.offset)
        if self.axis == "rotary":
            if self.lead is not None:
                raise ValueError(f"lead applies to a linear axis only; a rotary axis needs lead None, got {self.lead}")
        elif self.axis == "linear":
            if self.lead is None:
                raise ValueError("lead (m per load revolution) is required for a linear axis")
            _finite("lead", self.lead, positive=True)
        else:
            raise ValueError(f"axis must be 'rotary' or 'linear', got {self.axis!r}")
        _finite("peak_torque", self.peak_torque, positive=True)

    @property
    def position_unit(self) -> str:
        """The SI unit of positions: "rad" or "m"."""
        return "rad" if self.axis == "rotary" else "m"

    @property
    def si_per_count(self) -> float:
        """Load travel (rad or m, signed by `direction`) per motor count."""
        travel = 2 * math.pi if self.lead is None else self.lead
        return self.direction * travel / (self.counts_per_revolution * self.gear_ratio)

    @property
    def si_per_torque_unit(self) -> float:
        """Load torque (N·m) or force (N), signed by `direction`, per drive torque unit (0.1 % of peak)."""
        load_torque = self.peak_torque * self.gear_ratio / TORQUE_UNITS_PER_PEAK
        per_unit = load_torque if self.lead is None else load_torque * 2 * math.pi / self.lead
        return self.direction * per_unit

    def position_to_si(self, counts: int) -> float:
        """The load position (rad or m) at motor position `counts` (raw int32 or an unwrapped count)."""
        return counts * self.si_per_count + self.offset

    def position_to_counts(self, position: float) -> int:
        """The int32 target position (0x607A) for the load position `position` (rad or m)."""
        counts = round((_finite("position", position) - self.offset) / self.si_per_count)
        unit = self.position_unit
        return _drive_value("position", position, counts, (INT32_MIN, INT32_MAX), self.position_to_si, unit)

    def velocity_to_si(self, counts_per_second: int) -> float:
        """The load velocity (rad/s or m/s) at motor velocity `counts_per_second` (0x606C)."""
        return counts_per_second * self.si_per_count

    def velocity_to_counts(self, velocity: float) -> int:
        """The int32 target velocity (0x60FF, counts per second) for the load velocity `velocity` (rad/s or m/s)."""
        counts = round(_finite("velocity", velocity) / self.si_per_count)
        unit = self.position_unit + "/s"
        return _drive_value("velocity", velocity, counts, (INT32_MIN, INT32_MAX), self.velocity_to_si, unit)

    def acceleration_to_counts(self, acceleration: float) -> float:
        """Motor counts/s² for the load acceleration `acceleration` (rad/s² or m/s²)."""
        return _finite("acceleration", acceleration) / self.si_per_count

    def torque_to_si(self, value: int) -> float:
        """The load torque (N·m) or force (N) for the drive torque `value` (0x6077, 0.1 % of peak)."""
        return value * self.si_per_torque_unit

    def torque_to_drive(self, torque: float) -> int:
        """The int16 target torque (0x6071, 0.1 % of peak) for the load torque (N·m) or force (N) `torque`."""
        value = round(_finite("torque", torque) / self.si_per_torque_unit)
        unit = "N·m" if self.lead is None else "N"
        return _drive_value("torque", torque, value, (INT16_MIN, INT16_MAX), self.torque_to_si, unit)


def scale_mismatch(counts_per_revolution: int, scaling: dict | None, mapped: set[tuple[int, int]]) -> str | None:
    """Where the drive counts the position objects its mapping carries (`mapped`, (index, subindex)) in another scale
    than `counts_per_revolution`, one sentence saying which, by how much, from which of its objects, and what to
    change; None where they agree or the drive does not tell (`scaling` is `_native.Master.position_scaling`'s, None
    for a drive without the DS402 scaling objects).

    The objects give positions only: the AKD's velocity and torque units are its own parameters, so a joint's units
    are configured, not derived from them, and this check is what keeps a drive set up in another scale from moving
    to the wrong places."""
    if scaling is None:
        return None
    differing = {
        (index, sub): counts
        for (index, sub), counts in scaling["counts_per_revolution"].items()
        if (index, sub) in mapped and counts is not None and counts != counts_per_revolution
    }
    if not differing:
        return None
    objects = ", ".join(f"0x{i:04X}" + (f":{s:02X}" if s else "") for i, s in differing)
    counts = sorted(set(differing.values()))
    told = []
    if any(i in (0x6063, 0x60C1) for i, _ in differing):
        told.append(
            "0x608F = {}/{} (encoder increments per motor revolutions, FB1.PSCALE)".format(
                *scaling["encoder_resolution"]
            )
        )
    if any(i in (0x6064, 0x607A) for i, _ in differing):
        told.append(
            "FBUS.PARAM05 bit 4 set: feed constant 0x6092 = {}/{} over gear ratio 0x6091 = {}/{}".format(
                *scaling["feed_constant"], *scaling["gear_ratio"]
            )
        )
    return (
        f"counts_per_revolution is {counts_per_revolution}, but the drive counts "
        f"{' and '.join(f'{c:.10g}' for c in counts)} per motor revolution in {objects} ({'; '.join(told)}): "
        f"its positions would be read and commanded {counts[0] / counts_per_revolution:.6g} times off; set "
        f"counts_per_revolution to the drive's scale, or the drive's scaling to {counts_per_revolution} per revolution"
    )


@dataclass(frozen=True)
class Limits:
    """Set-point limits in SI units of the load; `None` leaves a limit open.

    Velocity and torque limits are symmetric magnitudes. With policy "clamp" a value beyond a limit is brought to
    the limit, with "refuse" it raises; NaN and infinite values are refused under either policy.
    """

    min_position: float | None = None
    """Lowest position (rad or m)."""
    max_position: float | None = None
    """Highest position (rad or m)."""
    max_velocity: float | None = None
    """Largest velocity magnitude (rad/s or m/s)."""
    max_torque: float | None = None
    """Largest torque (N·m) or, on a linear axis, force (N) magnitude."""
    policy: Policy = "refuse"
    """"clamp" or "refuse"."""
    max_acceleration: float | None = None
    """Largest acceleration magnitude (rad/s² or m/s²) of a trajectory or a cyclic position set-point's step, which
    the cycle judges (`Axis` hands it down); no command is clamped to it."""

    def __post_init__(self) -> None:
        for name in ("min_position", "max_position"):
            if getattr(self, name) is not None:
                _finite(name, getattr(self, name))
        for name in ("max_velocity", "max_torque", "max_acceleration"):
            if getattr(self, name) is not None:
                _finite(name, getattr(self, name), positive=True)
        if self.min_position is not None and self.max_position is not None and self.min_position > self.max_position:
            raise ValueError(f"min_position {self.min_position} must not exceed max_position {self.max_position}")
        if self.policy not in ("clamp", "refuse"):
            raise ValueError(f"policy must be 'clamp' or 'refuse', got {self.policy!r}")

    def check(self, kind: LimitKind, value: float) -> float:
        """The `kind` set-point to send for `value`: clamped or refused (ValueError naming the limit) by policy."""
        if kind == "position":
            low, high = self.min_position, self.max_position
            low_name, high_name = "min_position", "max_position"
        elif kind in ("velocity", "torque"):
            limit = self.max_velocity if kind == "velocity" else self.max_torque
            low, high = (None, None) if limit is None else (-limit, limit)
            low_name = high_name = "max_" + kind
        else:
            raise ValueError(f"kind must be 'position', 'velocity' or 'torque', got {kind!r}")
        value = _finite(kind, value)
        if low is not None and value < low:
            name, bound = low_name, low
        elif high is not None and value > high:
            name, bound = high_name, high
        else:
            return value
        if self.policy == "clamp":
            return float(bound)
        allowed = f"[{-math.inf if low is None else low}, {math.inf if high is None else high}]"
        raise ValueError(f"{kind} {value} is beyond the limit {name}; the allowed {kind} range is {allowed}")
