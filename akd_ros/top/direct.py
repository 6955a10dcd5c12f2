"""akd-top's source for a link it runs itself (`sim:6`, `udp://...`, an interface): an `akd_ros.Bus` with an Axis per
AKD found and a Device per other slave (a coupler, I/O terminals), and its cycle thread; no ROS."""

from __future__ import annotations

from akd_ros import _native
from akd_ros.axis import DriveConfig
from akd_ros.bus import Bus
from akd_ros.device import DeviceConfig, device_name
from akd_ros.top.source import (
    BusRow,
    DeviceRow,
    JointRow,
    LineView,
    Source,
    channels_text,
    check_action,
    io_text,
    line_view,
)

STATS_LABELS = ("cycles", "overruns", "lost_frames", "wkc_errors", "period_mean_s", "period_max_s", "exchange_p99_s")
"""The cycle statistics shown, named as akd_node's /diagnostics names them (so both sources show the same)."""


def stats_texts(stats: dict) -> dict[str, str]:
    """`Bus.stats()` as the shown labels and texts."""
    return {
        "cycles": str(stats["cycles"]),
        "overruns": str(stats["overruns"]),
        "lost_frames": str(stats["lost_frames"]),
        "wkc_errors": str(stats["wkc_errors"]),
        "period_mean_s": f"{stats['period']['mean_ns'] * 1e-9:.6g}",
        "period_max_s": f"{stats['period']['max_ns'] * 1e-9:.6g}",
        "exchange_p99_s": f"{stats['exchange']['p99_ns'] * 1e-9:.6g}",
    }


def dc_text(dc: dict) -> str:
    """`Cycle.dc_status()` in one line."""
    if not dc["active"]:
        return "off (the drives follow SM2)"
    return (
        f"on (SYNC0), cycle {dc['cycle_ns'] * 1e-9:.6g} s, shift {dc['shift_ns'] * 1e-9:.6g} s, "
        f"reference slave {dc['reference_position']}, difference misses {dc['difference_misses']}"
    )


def fault_text(event) -> str:
    """A `FaultEvent` as the row shows it: its source and the AKD's text (or the code)."""
    return f"{event.source}: {event.text or f'0x{event.code:04X}'}"


class DirectSource(Source):
    """Every AKD on `link` as an Axis of one Bus (named slave_<position>, in interpolated position mode) and every other
    slave as a Device (named as akd-scan's parameters file names it, el2004_2), at `period` seconds per cycle, the
    cycle thread under SCHED_FIFO `priority` where given (`Bus`'s)."""

    def __init__(self, link: str, period: float = 0.004, priority: int | None = None) -> None:
        master = _native.Master(link)
        try:
            slaves = master.scan()
        finally:
            master.close()
        drives = [DriveConfig(slave=s["position"]) for s in slaves if s["akd"]]
        if not drives:
            raise ValueError(f"no drive answers on {link}")
        self.link = link
        self.bus = Bus(
            link,
            drives,
            devices=[DeviceConfig(slave=s["position"], name=device_name(s)) for s in slaves if not s["akd"]],
            period=period,
            realtime=_native.RealTime(priority=priority),
        )
        self._faults: dict[str, str] = {}

    def rows(self) -> list[JointRow]:
        states, ios = self.bus.states(), self.bus.io()
        rows = []
        for axis in self.bus.axes:
            for event in axis.fault_events():
                self._faults[axis.name] = fault_text(event)
            s, io = states[axis.name], ios[axis.name]
            rows.append(
                JointRow(
                    axis.name,
                    None if s.state is None else str(s.state),
                    s.mode,
                    s.position,
                    s.velocity,
                    s.torque,
                    s.following_error,
                    self._faults.get(axis.name),
                    io_text(io.inputs, io.switches, io.hardware_enable, io.analog_input, io.outputs, io.analog_output),
                )
            )
        return rows

    def bus_row(self) -> BusRow:
        return BusRow(self.link, stats_texts(self.bus.stats()), dc_text(self.bus.cycle.dc_status()))

    def line(self) -> LineView:
        return line_view(self.bus.line_diagnostics())

    def devices(self) -> list[DeviceRow]:
        ios = self.bus.devices_io()
        rows = []
        for device in self.bus.devices:
            io = ios[device.name]
            if device.recovery()["recovering"]:
                level, message = 2, "unreachable, being brought back, its outputs off"
            elif not io.fresh:
                level, message = 1, "the last frame did not come back"
            else:
                level, message = 0, f"{device.product} in Op"
            rows.append(
                DeviceRow(
                    device.name,
                    str(device.slave),
                    device.product,
                    level,
                    message,
                    channels_text(io.inputs),
                    channels_text(io.outputs),
                )
            )
        return rows

    def request(self, joint: str, action: str) -> str:
        check_action(action)
        axis = self.bus[joint]
        try:
            getattr(axis, action)()
        except (TimeoutError, ValueError, _native.EtherCatError) as e:
            raise RuntimeError(str(e)) from None
        return f"{joint}: {action} done, now {axis.state().state}"

    def arm_latch(self, joint: str, channel: int, edge: str) -> str:
        try:
            self.bus[joint].arm_latch(channel, edge)
        except (ValueError, _native.EtherCatError) as e:
            raise RuntimeError(str(e)) from None
        return f"{joint}: latch {channel} armed on the {edge} edge"

    def close(self) -> None:
        self.bus.close()
