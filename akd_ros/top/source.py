"""What akd-top shows and asks, whatever it comes from: one `JointRow` per joint, one `BusRow`, and the requests a
person makes of a joint. The view (`akd_ros.top.app`) is written once over this interface."""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass, field

ACTIONS = ("enable", "disable", "quick_stop", "reset_fault")
"""The requests of one joint, as the node's services and `Axis` name them."""


@dataclass(frozen=True)
class JointRow:
    """One joint as last seen: CiA 402 state, mode, position, velocity, torque (SI units: rad, rad/s, N·m; m, m/s,
    N on a linear axis), following error, and the last fault with its text."""

    name: str
    state: str | None = None
    mode: str | None = None
    position: float | None = None
    velocity: float | None = None
    torque: float | None = None
    following_error: float | None = None
    fault: str | None = None


@dataclass(frozen=True)
class BusRow:
    """The bus: where it is, the cycle thread's statistics and distributed clocks, each as `label: text`."""

    link: str
    stats: dict[str, str] = field(default_factory=dict)
    dc: str = "unknown"


class Source(ABC):
    """A bus akd-top shows. `rows` and `bus_row` are cheap and called from the view's timer; `request` and `arm_latch`
    may wait for the drive (up to a few seconds) and are called from a worker thread."""

    @abstractmethod
    def rows(self) -> list[JointRow]:
        """Every joint's row, in the bus's order."""

    @abstractmethod
    def bus_row(self) -> BusRow:
        """The bus's row."""

    @abstractmethod
    def request(self, joint: str, action: str) -> str:
        """Asks `joint` for `action` (one of ACTIONS); gives what happened as one sentence, raises RuntimeError
        saying why when it was refused."""

    @abstractmethod
    def arm_latch(self, joint: str, channel: int, edge: str) -> str:
        """Arms latch `channel` (1 or 2) of `joint` on `edge` ("rising" or "falling"); as `request`."""

    @abstractmethod
    def close(self) -> None:
        """Lets go of the bus (for a direct link: disables the drives and stops the cycle)."""


def check_action(action: str) -> None:
    """Raises ValueError naming the allowed actions for an unknown one."""
    if action not in ACTIONS:
        raise ValueError(f"unknown action {action!r}; one of {', '.join(ACTIONS)}")
