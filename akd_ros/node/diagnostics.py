"""Diagnostics: /diagnostics (diagnostic_msgs/DiagnosticArray) at `diagnostics_rate`, a status per joint and one of
the bus, in one message.

A joint's status (`akd_node: <joint>`, hardware id naming its drive's position and serial number) is ERROR in a fault
state or while its drive is unreachable and being brought back (with the attempts and why the last failed); WARN when
its state is not fresh, a request is stuck or lost, in Quick stop active, or with distributed clocks on a drive whose
FBUS.PARAM02 is unknown (the master writes it only where the drive's SDO information confirms the object, see
`Master.configure_dc`); OK otherwise. Its values carry the state, its distributed clock, its recovery and its last
fault. A joint whose I/O holds its drive back (hardware enable low, a limit switch active: `akd_ros.node.io.reasons`)
is WARN at least, and says so in the drive's words. The bus's status (`akd_node: bus`) is ERROR while a joint is in
Fault or unreachable, WARN when a fault counter grew since the last report or the last frame did not come back; its
values carry the link, the cycle statistics and the distributed clocks. One counter, f125_stalls (the cycle stalled
8.5 periods or more with a drive enabled), is also logged as a warning when it grows: a real AKD raises F125 there,
virtual AKDs with `missed=warn` go on (docs/virtual_akd.md).

Each device beside the drives (`devices`) has a status too (`akd_node: <device>`, hardware id naming what it is and
where): ERROR while it is unreachable and being brought back, WARN when its inputs are not fresh, OK otherwise; its
values carry every channel, inputs as read and outputs as sent (a bit "high" or "low"), its recovery and its last loss.
The bus is ERROR while a device is lost, as while a joint is.

The line's links and error counters, as the reads beside the cycle found them, follow in statuses the crate makes
(`Bus.line_diagnostics`, docs/reference/diagnostics.md): `akd_node: line`, naming the worst place (ERROR while a link
is down, WARN while errors or lost links were counted in the last 10 s), and `akd_node: line slave N` for each slave,
its ports' links and counters."""

from __future__ import annotations

from akd_ros import _native
from akd_ros.node.homing import joint_homed
from akd_ros.node.io import named_levels, reasons
from akd_ros.node.node_state import FAULT_STATES, NodeState
from akd_ros.node.publishing import Publishing, RecordedPublisher
from akd_ros.node.transports.transport import Qos, Transport

FBUS_PARAM02_UNKNOWN = (
    "FBUS.PARAM02 unknown: the drive's SDO information does not confirm the object, so nothing was written; "
    "set FBUS.PARAM02 = 1 on the drive (WorkBench) for its PLL to follow SYNC0"
)
"""What /diagnostics says of a drive with distributed clocks whose FBUS.PARAM02 the master left alone."""


def _number(level: bytes | int) -> int:
    """A DiagnosticStatus level as its number."""
    return level[0] if isinstance(level, bytes) else int(level)


def f125_warning(stats: dict, new: int) -> str:
    """What the node says when the cycle stalled, a drive enabled, long enough for a real AKD to raise F125."""
    return (
        f"a real AKD would raise F125 here: {new} cycle stall{'s' if new > 1 else ''} of 8.5 periods or more while a "
        f"drive was enabled since the last report ({stats['f125_stalls']} in all; longest period "
        f"{stats['period']['max_ns'] * 1e-6:.1f} ms); virtual AKDs with missed=warn go on, a real line faults. "
        "Give the cycle thread real-time priority (rt.priority) on a host that stalls it"
    )


def fbus_param02_unknown(dc: dict, slave: int) -> bool:
    """Whether, with distributed clocks on, the drive at `slave` has an unknown FBUS.PARAM02 in `Cycle.dc_status()`
    (not written, because its SDO information did not name the object FBUS.PARAM02)."""
    return any(d["position"] == slave and d["fbus_param02"] is None for d in dc.get("drives", ()))


def dc_values(dc: dict, slave: int) -> dict[str, object]:
    """The key/values of `Cycle.dc_status()` for the drive at `slave`: whether SYNC0 runs, its cycle and shift, the
    reference clock, the drive's FBUS.PARAM02 and its last system-time difference."""
    if not dc["active"]:
        return {"dc": "off (the drive follows SM2)"}
    drive = next((d for d in dc["drives"] if d["position"] == slave), {})
    difference = drive.get("system_time_difference_ns")
    return {
        "dc": "on (SYNC0)",
        "dc_cycle_s": f"{dc['cycle_ns'] * 1e-9:.6g}",
        "dc_shift_s": f"{dc['shift_ns'] * 1e-9:.6g}",
        "dc_reference_slave": dc["reference_position"],
        "fbus_param02": FBUS_PARAM02_UNKNOWN if fbus_param02_unknown(dc, slave) else drive.get("fbus_param02"),
        "system_time_difference_ns": "not read yet" if difference is None else difference,
        "dc_difference_misses": dc["difference_misses"],
    }


class Diagnostics:
    """The /diagnostics publisher and its timer: one status per joint (`akd_node: <joint>`) and one of the bus
    (`akd_node: bus`); `publishing` has each joint's last fault."""

    def __init__(
        self, transport: Transport, node_state: NodeState, group, qos: Qos, node_name: str, publishing: Publishing
    ) -> None:
        self._node_state, self._clock, self._settings = node_state, node_state.clock, node_state.settings
        self._joints = {j.name: j for j in node_state.joints}
        self._node_name, self._publishing = node_name, publishing
        self._transport = transport
        status = transport.message_class("diagnostic_msgs/msg/DiagnosticStatus")
        # The levels' numbers, from the transport's message class (a byte in rclpy's, an int in rosbags').
        self._ok, self._warn, self._error = (_number(level) for level in (status.OK, status.WARN, status.ERROR))
        self.publisher = RecordedPublisher(
            transport, "diagnostic_msgs/msg/DiagnosticArray", "/diagnostics", qos, node_state
        )
        self._counters_seen: dict[str, int] = {}
        transport.timer(1.0 / node_state.settings.diagnostics_rate, self._publish, group)

    def restart_counters(self) -> None:
        """Counts the fault counters' growth from the next report on (at activate)."""
        self._counters_seen = {}

    def _publish(self) -> None:
        taken = self._node_state.states(with_stats=True)
        if taken is None:
            return
        bus, states, stats = taken
        counted = ["overruns", "f125_stalls", "lost_frames", "wkc_errors", "events_dropped"]
        # Cycle records are taken only while recording; then each one lost is a cycle missing from the bag.
        recorder = self._node_state.recorder
        if recorder is not None:
            counted.append("samples_dropped")
        counters = {k: stats[k] for k in counted}
        # What the crate made and nobody published in time, and, recording, what the bag's writer could not take
        # (its queue full, its disk failed): counted, never waited for.
        counters["messages_dropped"] = self._publishing.feed_dropped()
        if recorder is not None:
            counters["records_dropped"] = recorder.stats.dropped
        # The middleware's drops (a Zenoh sample without rmw_zenoh's attachment) grow the bus's WARN as the cycle's do.
        counters |= self._transport.counters()
        grown = [k for k, v in counters.items() if v > self._counters_seen.get(k, v)]
        if "f125_stalls" in grown:
            self._transport.logger.warning(
                f125_warning(stats, stats["f125_stalls"] - self._counters_seen["f125_stalls"])
            )
        self._counters_seen = counters
        dc_status = bus.cycle.dc_status()
        recovery = {joint: bus[joint].recovery() for joint in states}
        ios = bus.io()
        statuses = [self._joint_status(bus[j], state, dc_status, recovery[j], ios[j]) for j, state in states.items()]
        lost = [joint for joint, r in recovery.items() if r["recovering"]]
        device_ios = bus.devices_io()
        for device in bus.devices:
            device_recovery = device.recovery()
            statuses.append(self._device_status(device, device_ios[device.name], device_recovery))
            if device_recovery["recovering"]:
                lost.append(device.name)
        statuses.append(self._bus_status(bus, states, stats, counters, grown, dc_status, lost))
        statuses += [(level, f"{self._node_name}: {what}", *rest) for level, what, *rest in bus.line_diagnostics()]
        # The message's body is the crate's to make: no message object per key and value.
        stamp_ns = self._clock.now_ns()
        self.publisher.publish_serialized(_native.diagnostic_array(stamp_ns, statuses), stamp_ns)

    def _joint_status(self, axis, state, dc_status: dict, recovery: dict, io) -> tuple:
        """The status of one joint: its drive's state, mode, position, DC, recovery and last fault, what of its I/O
        (`io`, its `AxisIo`) holds it back, and its named inputs and outputs."""
        held = reasons(io, state.statusword)
        fault = self._publishing.last_fault.get(axis.name)
        param02_unknown = fbus_param02_unknown(dc_status, axis.slave)
        if recovery["recovering"] or state.state in FAULT_STATES:
            level = self._error
        elif (
            not state.fresh
            or state.progress in (_native.RequestProgress.STUCK, _native.RequestProgress.LOST)
            or state.state == _native.Ds402State.QUICK_STOP_ACTIVE
            or (param02_unknown)
            or held
        ):
            level = self._warn
        else:
            level = self._ok
        summary = str(state.state or "no valid DS402 state")
        if state.reason:
            summary += f": {state.reason}"
        if recovery["recovering"]:
            summary = f"unreachable, being brought back (attempt {recovery['attempts']}"
            summary += f": {recovery['last_error']})" if recovery["last_error"] else ")"
        if param02_unknown:
            summary += f"; {FBUS_PARAM02_UNKNOWN}"
        for reason in held:
            summary += f"; {reason}"
        if level == self._error and fault is not None:
            summary += f"; last fault {fault.text or hex(fault.code)}"
        values = {
            "joint": axis.name,
            "slave": axis.slave,
            "serial_number": axis.serial_number,
            "ds402_state": str(state.state or "unknown"),
            "statusword": f"0x{state.statusword:04X}",
            "mode": state.mode or axis.mode,
            "request": str(state.request or ""),
            "progress": str(state.progress),
            "position": f"{state.position:.9g}",
            "homed": joint_homed(self._node_state.joint(axis.name), axis),
            **dc_values(dc_status, axis.slave),
            "last_fault": "none" if fault is None else f"{fault.source}: {fault.text or f'0x{fault.code:04X}'}",
            "last_fault_code": "" if fault is None else f"0x{fault.code:04X}",
            "last_fault_action": "" if fault is None else fault.action,
            "recovering": recovery["recovering"],
            "recoveries": recovery["recoveries"],
            "io": "; ".join(held) or "nothing holds the drive back",
            **named_levels(self._joints[axis.name], io),
        }
        hardware_id = f"AKD slave {axis.slave} serial {axis.serial_number} on {self._settings.link}"
        return self._status_message(level, axis.name, summary, hardware_id, values)

    def _device_status(self, device, io, recovery: dict) -> tuple:
        """The status of one device: its channels, its recovery and its last loss or return."""
        fault = self._publishing.last_device_fault.get(device.name)
        if recovery["recovering"]:
            level = self._error
            why = f": {recovery['last_error']}" if recovery["last_error"] else ""
            summary = f"unreachable, being brought back (attempt {recovery['attempts']}{why}), its outputs off"
        elif not io.fresh:
            level, summary = self._warn, "the last frame did not come back: its inputs are the last good ones"
        else:
            level, summary = self._ok, f"{device.product} in Op"

        def shown(value) -> str:
            return ("high" if value else "low") if isinstance(value, bool) else str(value)

        values = {
            "device": device.name,
            "slave": device.slave,
            "product": device.product,
            **{f"input {name}": shown(value) for name, value in io.inputs.items()},
            **{f"output {name}": shown(value) for name, value in io.outputs.items()},
            "recovering": recovery["recovering"],
            "recoveries": recovery["recoveries"],
            "last_event": "none" if fault is None else fault.describe(),
        }
        hardware_id = f"{device.product} ({device.description}) slave {device.slave} on {self._settings.link}"
        return self._status_message(level, device.name, summary, hardware_id, values)

    def _bus_status(self, bus, states, stats: dict, counters: dict, grown: list, dc_status: dict, lost: list) -> tuple:
        """The status of the bus: the link, the cycle's counters and timing, distributed clocks, the joints' worst."""
        faulted = [j for j, s in states.items() if s.state in FAULT_STATES]
        stale = not all(s.fresh for s in states.values())
        if lost:
            level, summary = self._error, f"unreachable: {', '.join(lost)} (being brought back)"
        elif faulted:
            level, summary = self._error, f"fault on {', '.join(faulted)}"
        elif grown or stale:
            level = self._warn
            summary = "the last frame did not come back" if stale else "cycle running"
        else:
            level, summary = self._ok, "cycle running"
        if grown:
            summary += f" ({', '.join(grown)} since the last report)"
        # What exchange_p99_s times: the round trip waited for, or the sending and the taking of a return.
        frames = "pipelined, each taken at the next wake-up" if self._settings.realtime.pipelined else "waited for"
        values = {
            "link": self._settings.link,
            "joints": ", ".join(bus.names),
            **({"devices": ", ".join(d.name for d in bus.devices)} if bus.devices else {}),
            "fault_reaction": bus.fault_reaction,
            "cycle_time_s": f"{self._settings.cycle_time:.6g}",
            "frames": frames,
            "cycles": stats["cycles"],
            **counters,
            "period_mean_s": f"{stats['period']['mean_ns'] * 1e-9:.6g}",
            "period_max_s": f"{stats['period']['max_ns'] * 1e-9:.6g}",
            "exchange_p99_s": f"{stats['exchange']['p99_ns'] * 1e-9:.6g}",
            "relayed_frames": stats["relayed_frames"],
            "relayed_lost": stats["relayed_lost"],
            # Of the frames counted lost, those that came back after their time-out: a slow line or slave, not a cable.
            "late_returns": stats["late_returns"],
            "dc": "on (SYNC0)" if dc_status["active"] else "off (the drives follow SM2)",
        }
        if dc_status["active"]:
            values |= {
                "dc_cycle_s": f"{dc_status['cycle_ns'] * 1e-9:.6g}",
                "dc_shift_s": f"{dc_status['shift_ns'] * 1e-9:.6g}",
                "dc_reference_slave": dc_status["reference_position"],
                "dc_difference_misses": dc_status["difference_misses"],
            }
        return self._status_message(level, "bus", summary, f"EtherCAT line {self._settings.link}", values)

    def _status_message(self, level: int, what: str, summary: str, hardware_id: str, values: dict) -> tuple:
        """A DiagnosticStatus `<node>: <what>` of `values` (each shown as text), as `_native.diagnostic_array` takes
        it."""
        return (level, f"{self._node_name}: {what}", summary, hardware_id, [(k, str(v)) for k, v in values.items()])
