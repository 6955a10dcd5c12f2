"""A joint's units and set-point limits: `Units`, the crate's scale of a joint (`_native.Units`, re-exported here), and
`Limits`, which checks set-points in SI units of the load before they are converted and sent.

`Units` relates the drive's counts and thousandths of peak torque to rad, rad/s and N·m (m, m/s and N on a linear
axis); its one implementation is the crate's (`native/src/drive/scaling.rs`), by which the node's joint states, its
recorded cycles and its commands convert too. `unwrap_position` reads a raw int32 position across the 32-bit wrap by
the crate's one rule (an `Axis` and the node's feed each keep a `_native.PositionUnwrap`).
"""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass
from typing import Literal

from akd_ros._native import Units, unwrap_position

INT32_MIN, INT32_MAX = -(2**31), 2**31 - 1
INT16_MIN, INT16_MAX = -(2**15), 2**15 - 1

LimitKind = Literal["position", "velocity", "torque"]
Policy = Literal["clamp", "refuse"]

__all__ = ["Limits", "Units", "unwrap_position"]


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
