"""What akd-top shows and asks, whatever it comes from: one `JointRow` per joint, one `BusRow`, one `DeviceRow` per
device beside the drives (a terminal's channels), the line's slaves with their ports' links and error counters
(`LineView`, read from the line's /diagnostics statuses by `line_view` whichever source gave them), and the requests a
person makes of a joint. The view (`akd_ros.top.app`) is written once over this interface."""

from __future__ import annotations

import math
import re
from abc import ABC, abstractmethod
from collections.abc import Iterable
from dataclasses import dataclass, field

ACTIONS = ("enable", "disable", "quick_stop", "reset_fault")
"""The requests of one joint, as the node's services and `Axis` name them."""


@dataclass(frozen=True)
class JointRow:
    """One joint as last seen: CiA 402 state, mode, position, velocity, torque (SI units: rad, rad/s, N·m; m, m/s,
    N on a linear axis), following error, the last fault with its text, and its drive's own I/O (`io_text`)."""

    name: str
    state: str | None = None
    mode: str | None = None
    position: float | None = None
    velocity: float | None = None
    torque: float | None = None
    following_error: float | None = None
    fault: str | None = None
    io: str | None = None


@dataclass(frozen=True)
class BusRow:
    """The bus: where it is, the cycle thread's statistics and distributed clocks, each as `label: text`."""

    link: str
    stats: dict[str, str] = field(default_factory=dict)
    dc: str = "unknown"


@dataclass(frozen=True)
class PortCell:
    """One port of a slave of the line: its link, what is at its other end, its counters since the start (as text), and
    what they counted over the last seconds (`window`, in words); `rising` when that is anything."""

    port: int
    link: str
    peer: str
    invalid_frames: str
    rx_errors: str
    forwarded_errors: str
    lost_links: str
    window: str
    rising: bool


@dataclass(frozen=True)
class LineRow:
    """One slave of the line: its position and name, its status's level (0 OK, 1 WARN, 2 ERROR) and message, its
    ports."""

    slave: int
    name: str
    level: int
    message: str
    ports: list[PortCell]


@dataclass(frozen=True)
class LineView:
    """The line: its status's level and summary (the worst place, in the cable's words), and its slaves."""

    level: int = 0
    summary: str = "not read"
    rows: list[LineRow] = field(default_factory=list)


@dataclass(frozen=True)
class DeviceRow:
    """One device beside the drives (a terminal): its name, position and product, its status's level (0 OK, 1 WARN,
    2 ERROR) and message, and its input and output channels, each direction in one cell (`channels_text`)."""

    name: str
    slave: str
    product: str
    level: int
    message: str
    inputs: str
    outputs: str


def channels_text(channels: dict) -> str:
    """A device's channels of one direction in one cell: its bits as 0/1 digits in wire order (the first channel
    first), then its other channels as name=value; '-' for none. A bit is a bool, or "high"/"low" as /diagnostics
    says it."""
    bits = {"high": "1", "low": "0", True: "1", False: "0"}
    digits = "".join(bits[v] for v in channels.values() if isinstance(v, bool) or v in ("high", "low"))
    others = [f"{k}={v}" for k, v in channels.items() if not (isinstance(v, bool) or v in ("high", "low"))]
    return " ".join(([digits] if digits else []) + others) or "-"


def devices_view(statuses: Iterable[tuple]) -> list[DeviceRow]:
    """The devices as akd_node's /diagnostics statuses give them (each (level, what, message, hardware_id, values),
    values with the device's name under "device" and its channels under "input NAME"/"output NAME"); the other
    statuses are passed over."""
    rows = []
    for level, _, message, _, values in statuses:
        values = dict(values)
        if "device" not in values:
            continue
        channels = {
            kind: {k.split(" ", 1)[1]: v for k, v in values.items() if k.startswith(kind + " ")}
            for kind in ("input", "output")
        }
        rows.append(
            DeviceRow(
                values["device"],
                values.get("slave", ""),
                values.get("product", ""),
                int(level),
                message,
                channels_text(channels["input"]),
                channels_text(channels["output"]),
            )
        )
    return rows


_PORT = re.compile(r"port(\d+)")


def line_view(statuses: Iterable[tuple]) -> LineView:
    """The line as its /diagnostics statuses give it (`Bus.line_diagnostics`' tuples, or those received, each
    (level, what, message, hardware_id, values) with `what` "line" or "line slave N" and values (key, value) pairs or
    a dict); the other statuses are passed over."""
    view = LineView()
    rows = []
    for level, what, message, _, values in statuses:
        values = dict(values)
        if what == "line":
            view = LineView(int(level), message)
        elif what.startswith("line slave "):
            ports = []
            for key in values:
                if (match := _PORT.fullmatch(key)) is None:
                    continue
                p = f"port{match[1]}"
                window = values.get(p + "_window", "")
                ports.append(
                    PortCell(
                        int(match[1]),
                        values[key],
                        values.get(p + "_peer", ""),
                        *(values.get(f"{p}_{c}", "") for c in COUNTERS),
                        window,
                        bool(window) and not window.startswith("no errors"),
                    )
                )
            rows.append(
                LineRow(
                    int(values.get("slave", what.rsplit(" ", 1)[-1])),
                    values.get("name", ""),
                    int(level),
                    message,
                    ports,
                )
            )
    return LineView(view.level, view.summary, sorted(rows, key=lambda r: r.slave))


COUNTERS = ("invalid_frames", "rx_errors", "forwarded_errors", "lost_links")
"""A port's error counters, as the line's statuses name them."""


class Source(ABC):
    """A bus akd-top shows. `rows` and `bus_row` are cheap and called from the view's timer; `request` and `arm_latch`
    may wait for the drive (up to a few seconds) and are called from a worker thread."""

    @abstractmethod
    def rows(self) -> list[JointRow]:
        """Every joint's row, in the bus's order."""

    @abstractmethod
    def bus_row(self) -> BusRow:
        """The bus's row."""

    def line(self) -> LineView:
        """The line's slaves with their ports' links and error counters; a source without them says so."""
        return LineView(summary="not shown by this source")

    def devices(self) -> list[DeviceRow]:
        """The devices beside the drives, each with its channels; none for a source without them."""
        return []

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


SWITCH_WORDS = {"negative_limit": "-limit", "positive_limit": "+limit", "home_switch": "home", "interlock": "interlock"}
"""The switches of 0x60FD as the I/O column names them while active."""


def io_text(
    inputs, switches: dict[str, bool], hardware_enable: str, analog_input, outputs, analog_output
) -> str | None:
    """A drive's I/O in one cell: digital inputs 1..7 as 0/1 digits (input 1 first), the switches that are active,
    the hardware enable where not high, the analog input, digital outputs 1..2 and the analog output (V); what the
    mapping lacks is left out (None for nothing at all)."""
    parts = [f"DI {''.join('1' if x else '0' for x in inputs)}"] if len(inputs) else []
    parts += [SWITCH_WORDS[name] for name, active in switches.items() if active]
    if hardware_enable != "high":
        parts.append(f"enable {hardware_enable}")
    if analog_input is not None and math.isfinite(analog_input):
        parts.append(f"AI {analog_input:.2f} V")
    if len(outputs):
        parts.append(f"DO {''.join('1' if x else '0' for x in outputs)}")
    if analog_output is not None and math.isfinite(analog_output):
        parts.append(f"AO {analog_output:.2f} V")
    return " ".join(parts) or None


def check_action(action: str) -> None:
    """Raises ValueError naming the allowed actions for an unknown one."""
    if action not in ACTIONS:
        raise ValueError(f"unknown action {action!r}; one of {', '.join(ACTIONS)}")
