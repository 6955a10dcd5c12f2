"""What the node's parts share: the settings and the clock, and from a configure to its cleanup the Bus with an Axis
per joint and a Device per device, the Recorder, whether the node is active, the lock that guards the axes'
Python-side state (position unwrapping, event queues, the last command) between the callback groups, and the action
goals executing (`Goals`), which a node that closes ends, each with a result, before its bus goes."""

from __future__ import annotations

import contextlib
import threading
import time
from collections.abc import Iterator

from akd_ros import _native
from akd_ros.axis import Axis, CommandError
from akd_ros.bus import Bus
from akd_ros.device import Device
from akd_ros.node.clock import CycleClock
from akd_ros.params import JointSettings, Settings
from akd_ros.recorder import Recorder

NODE_NAME = "akd_node"
"""The node's name, under which its ~/ topics and services are."""
AXIS_ERRORS = (ValueError, TimeoutError, _native.EtherCatError)
"""What the Bus and an Axis raise for a request they cannot carry out; the node answers with the text."""
FAULT_STATES = frozenset(state for state in _native.DS402_STATES if state.is_fault)
"""The DS402 states of a fault (`Ds402State.is_fault`)."""


def namespace(settings: Settings, joint: str) -> str:
    """Where `joint`'s topics and services go: ``~/<joint>/`` on a node of joints, ``~/`` on a node of one axis."""
    return f"~/{joint}/" if settings.joint_namespaces else "~/"


class Goals:
    """The action goals executing, of every action: each runs inside `running()`; `close()` asks them to end (each
    goal's loop sees `closing`, stops its motion and ends with a result) and waits until they did, so that the bus is
    closed under none."""

    def __init__(self) -> None:
        self._executing = 0
        self._changed = threading.Condition()
        self.closing = False
        """Whether the node is closing: a goal's loop that sees it stops its motion and ends, with a result."""

    @contextlib.contextmanager
    def running(self) -> Iterator[None]:
        """Counts a goal's execution for the time of the block."""
        with self._changed:
            self._executing += 1
        try:
            yield
        finally:
            with self._changed:
                self._executing -= 1
                self._changed.notify_all()

    def close(self, timeout: float) -> bool:
        """Asks every goal executing to end and waits up to `timeout` s until none runs; whether none does."""
        deadline = time.monotonic() + timeout
        with self._changed:
            self.closing = True
            while self._executing and (left := deadline - time.monotonic()) > 0:
                self._changed.wait(left)
            return self._executing == 0

    def open(self) -> None:
        """Takes goals again (a node configured anew)."""
        self.closing = False


class NodeState:
    """The node's settings and clock; the Bus (None until configured), the Recorder (None unless recording),
    whether the node is active, and the lock that guards the axes between the callback groups."""

    def __init__(self, settings: Settings, clock: CycleClock) -> None:
        self.settings, self.clock = settings, clock
        self.lock = threading.Lock()
        self.bus: Bus | None = None
        self.active = False
        self.recorder: Recorder | None = None
        self.goals = Goals()

    @property
    def joints(self) -> tuple[JointSettings, ...]:
        """Every joint's settings, in order."""
        return self.settings.joints

    def joint(self, name: str) -> JointSettings:
        """The settings of joint `name`."""
        return next(j for j in self.settings.joints if j.name == name)

    def states(self, with_stats: bool = False):
        """(bus, every axis's state by joint from one cycle, the cycle's statistics where `with_stats`, else None), or
        None when closed or inactive. /joint_states, the most frequent caller, needs no statistics."""
        with self.lock:
            if self.bus is None or not self.active:
                return None
            return self.bus, self.bus.states(), self.bus.stats() if with_stats else None

    def bus_for_request(self) -> Bus:
        """The Bus of an active node; CommandError otherwise."""
        bus = self.bus
        if bus is None or not self.active:
            raise CommandError("the node is not active; configure and activate it first")
        return bus

    def axis_for_request(self, joint: str) -> Axis:
        """The Axis of `joint` on an active node; CommandError otherwise."""
        return self.bus_for_request()[joint]

    def device_for_request(self, device: str) -> Device:
        """The Device `device` on an active node; CommandError otherwise."""
        return self.bus_for_request().device(device)
