"""`Device`: one of a line's other slaves from Python, beside the drives of an `akd_ros.Bus` (`bus.devices`).

A device is a slave the master configures from what it says of itself (its SII): an EK1100 coupler, an EL1004's
digital inputs, an EL2004's digital outputs, an EL3102's analog inputs. Its channels are its PDO entries, named in
snake case after the names its SII gives them (an EL1004's "Channel 1"/"Input" is ``channel_1_input``; the crate's
rule, `_native.Cycle.channels`). `io` reads them all from one cycle, `set_outputs` sets outputs by name in the next
cycle's process image (every one or none: an unknown output or a value the channel cannot take is a `CommandError`
that sets nothing), and `input_events` hands out each change of its inputs of one bit, stamped with the cycle whose
inputs showed it. Its outputs go off (`outputs_off`) when the Bus closes, and the cycle thread switches them off itself
when the device is lost or back in Op and when the line's fault reaction quick-stops the drives: they stay off until
set again. Its losses and returns are `fault_events`, as a drive's.
"""

from __future__ import annotations

import collections
import math
from collections.abc import Iterator, Mapping
from dataclasses import dataclass

from akd_ros import _native
from akd_ros.axis import FaultEvent
from akd_ros.bus import Bus, CommandError

INPUT_EVENTS_KEPT = 4096
"""Changes of a device's inputs kept until `input_events` takes them; older ones are dropped."""


def device_name(slave: dict) -> str:
    """The name akd-scan's parameters file and akd-top give the slave `slave` (as `Master.scan` found it) as a device:
    its order number in snake case and its position (``el2004_2``)."""
    return f"{_native.snake_case(slave.get('order') or 'slave')}_{slave['position']}"


@dataclass(frozen=True)
class DeviceConfig:
    """One device of a `Bus`: its position on the line (`slave`), its name (``"slave_<position>"`` unless given) and,
    where given, the product it must be (its order number as its SII gives it, e.g. ``"EL2004"``, compared without
    regard to case), checked before the line goes to Op."""

    slave: int
    name: str | None = None
    product: str | None = None

    def attach(self, bus: Bus, slave: int) -> Device:
        """The Device at position `slave` of `bus`; the Bus calls it once the line is in Op."""
        return Device(bus, slave, self.name or f"slave_{slave}")


@dataclass(frozen=True)
class DeviceIo:
    """A device's channels in one cycle: inputs as read, outputs as sent, each by name; a bit is a bool."""

    cycle: int
    time_ns: int
    fresh: bool
    """Whether that cycle's exchange succeeded (else the inputs are the last good ones)."""
    inputs: dict[str, bool | int | float]
    outputs: dict[str, bool | int | float]
    levels: int | None = None
    """Of a change (`Device.input_events`): its inputs of one bit as the cycle thread reported them, the first in bit
    0."""


class Device:
    """One device on a `Bus` (see the module)."""

    def __init__(self, bus: Bus, slave: int, name: str) -> None:
        self._bus = bus
        self.slave = slave
        """Its position on the bus."""
        self.name = name
        """Its name on the bus."""
        found = bus.slaves[slave]
        self.product: str = found.get("order") or f"0x{found['product_code']:08X}"
        """Its order number as its SII gives it (e.g. "EL2004"), else its product code."""
        self.description: str = found.get("name") or ""
        """Its name as its SII gives it (e.g. "EL2004 4K. Dig. Ausgang 24V, 0.5A")."""
        self.channels: list[dict] = bus.cycle.channels(slave)
        """Its channels (`_native.Cycle.channels`): name, direction, index, subindex, bits, data_type, pdo."""
        self.input_names = [c["name"] for c in self.channels if c["direction"] == "input"]
        """Its input channels' names, in wire order."""
        self.output_names = [c["name"] for c in self.channels if c["direction"] == "output"]
        """Its output channels' names, in wire order."""
        self._bit_inputs = [c["name"] for c in self.channels if c["direction"] == "input" and c["bits"] == 1]
        self._input_events: collections.deque[DeviceIo] = collections.deque(maxlen=INPUT_EVENTS_KEPT)
        self._faults: collections.deque[FaultEvent] = collections.deque()

    def io(self, of: dict | None = None) -> DeviceIo:
        """Its channels in the last cycle (or in `of`, one of `_native.Cycle.devices_io`'s)."""
        now = of if of is not None else self._bus.cycle.devices_io([self.slave])[0]
        return DeviceIo(now["cycle"], now["time_ns"], now["fresh"], dict(now["inputs"]), dict(now["outputs"]))

    def set_outputs(self, values: Mapping[str, bool | int | float]) -> None:
        """Sets output channels by name from the next cycle on, every one or none; the others keep theirs. A bit takes
        a bool (or 0, 1). CommandError, setting nothing, for an unknown output, an input, or a value the channel
        cannot take."""
        if not values:
            raise CommandError(f"device {self.name}: nothing to set; its outputs: {', '.join(self.output_names)}")
        for name, value in values.items():
            if isinstance(value, float) and not math.isfinite(value):
                raise CommandError(f"device {self.name}: output {name} given {value}, not a finite number")
        try:
            self._bus.cycle.set_channels(self.slave, dict(values))
        except (_native.ConfigError, TypeError) as e:
            raise CommandError(f"device {self.name}: {e}") from None

    def outputs_off(self) -> None:
        """Switches every output off from the next cycle on."""
        self._bus.cycle.switch_outputs_off(self.slave)

    def input_events(self) -> Iterator[DeviceIo]:
        """Each change of its inputs of one bit since the last call, oldest first, each once: the channels of the cycle
        whose inputs showed it (its other values those of the snapshot when it was taken). The last INPUT_EVENTS_KEPT
        are kept between calls."""
        self._poll()
        while self._input_events:
            yield self._input_events.popleft()

    def fault_events(self) -> Iterator[FaultEvent]:
        """Its losses and returns since the last call (sources "unreachable", "al_state", "recovered"), each once."""
        self._poll()
        while self._faults:
            yield self._faults.popleft()

    def recovery(self) -> dict:
        """Where its recovery stands (`_native.Cycle.recovery_status`)."""
        return self._bus.cycle.recovery_status(self.slave)

    def _poll(self) -> None:
        if self._bus.closed:
            return
        events = list(self._bus.events_of(self.slave))
        changes = [e for e in events if e["kind"] == "device_inputs"]
        if changes:
            now = self._bus.cycle.devices_io([self.slave])[0]
            for e in changes:
                levels = {name: bool(e["levels"] >> n & 1) for n, name in enumerate(self._bit_inputs)}
                inputs = {**now["inputs"], **levels}
                outputs = dict(now["outputs"])
                self._input_events.append(DeviceIo(e["cycle"], e["time_ns"], True, inputs, outputs, e["levels"]))
        for e in events:
            if e["kind"] == "fault":
                self._faults.append(e["fault"])
