"""What the node's parts share: the settings and the clock, and from a configure to its cleanup the Axis, the
Recorder, whether the node is active, and the lock that guards the Axis's Python-side state (position unwrapping,
event queues, the last command) between the callback groups."""

from __future__ import annotations

import threading

from akd_ros import _native
from akd_ros.axis import Axis, CommandError
from akd_ros.node.clock import CycleClock
from akd_ros.params import Settings
from akd_ros.recorder import Recorder

AXIS_ERRORS = (ValueError, TimeoutError, _native.EtherCatError)
"""What the Axis raises for a request it cannot carry out; the node answers with the text."""
FAULT_STATES = ("Fault", "Fault reaction active")
"""The DS402 states of a fault."""


class Session:
    """The node's settings and clock; the Axis (None until configured), the Recorder (None unless recording),
    whether the node is active, and the lock that guards the Axis between the callback groups."""

    def __init__(self, settings: Settings, clock: CycleClock) -> None:
        self.settings, self.clock = settings, clock
        self.lock = threading.Lock()
        self.axis: Axis | None = None
        self.active = False
        self.recorder: Recorder | None = None

    def state(self):
        """(axis, its state and statistics), or None when the axis is closed or the node inactive."""
        with self.lock:
            if self.axis is None or not self.active:
                return None
            return self.axis, self.axis.state(), self.axis.stats()

    def axis_for_request(self) -> Axis:
        """The Axis of an active node; CommandError otherwise."""
        axis = self.axis
        if axis is None or not self.active:
            raise CommandError("the node is not active; configure and activate it first")
        return axis
