"""Stamps: the cycle thread's monotonic times moved onto the ROS clock.

Periodic messages carry the ROS time of their publication. Events (latch captures, faults) and recorded cycles carry
the time of the cycle that saw them: its monotonic wake-up time moved onto the ROS clock by the age of the event at
publication, ``now_ros - (now_monotonic - time_ns)``, so an event is stamped as long before its publication as it
really happened.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from typing import Any

# Readings of the ROS and the monotonic clock closer than this are taken as simultaneous.
_CLOCK_READ_SPREAD_NS = 50_000
_CLOCK_READ_TRIES = 5
_NS_PER_S = 1_000_000_000


def nanoseconds(stamp) -> int:
    """A builtin_interfaces/Time in nanoseconds."""
    return stamp.sec * _NS_PER_S + stamp.nanosec


class CycleClock:
    """The node's ROS clock (`now_ns`), and the cycle thread's monotonic times on it, as builtin_interfaces/Time
    messages of `time_class`."""

    def __init__(self, now_ns: Callable[[], int], time_class: Callable[..., Any]) -> None:
        self.now_ns = now_ns
        """ROS time now, in nanoseconds."""
        self._time = time_class

    def time(self, ns: int):
        """The builtin_interfaces/Time of `ns` nanoseconds."""
        return self._time(sec=ns // _NS_PER_S, nanosec=ns % _NS_PER_S)

    def stamp(self, time_ns: int | None = None):
        """ROS time now, or of the cycle whose monotonic wake-up time is `time_ns` (see the module doc)."""
        if time_ns is None:
            return self.time(self.now_ns())
        return self.time(time_ns + self.ros_minus_monotonic_ns())

    def ros_minus_monotonic_ns(self) -> int:
        """ROS time minus monotonic time, from the two clocks read as close together as a few tries allow.

        Another thread taking the GIL between the two readings would shift the result by milliseconds, and with it
        the recorded cycles (out of order in the bag) and the events' stamps (outside their black box)."""
        best_spread, offset = math.inf, 0
        for _ in range(_CLOCK_READ_TRIES):
            before = time.monotonic_ns()
            ros = self.now_ns()
            after = time.monotonic_ns()
            if after - before < best_spread:
                best_spread, offset = after - before, ros - (before + after) // 2
            if best_spread <= _CLOCK_READ_SPREAD_NS:
                break
        return offset
