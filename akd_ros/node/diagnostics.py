"""Diagnostics: /diagnostics (diagnostic_msgs/DiagnosticArray) at `diagnostics_rate`, one status of the axis.

ERROR in a fault state; WARN when a fault counter grew since the last report, the state is not fresh, a request is
stuck or lost, in Quick stop active, or with distributed clocks on a drive whose FBUS.PARAM02 is unknown (the
master writes it only where the drive's SDO information confirms the object, see `Master.configure_dc`); OK
otherwise. The values carry the state, the cycle statistics, the distributed clocks and the last fault."""

from __future__ import annotations

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rclpy.qos import QoSProfile

from akd_ros.node.publishing import Publishing, RecordedPublisher
from akd_ros.node.session import FAULT_STATES, Session

FBUS_PARAM02_UNKNOWN = (
    "FBUS.PARAM02 unknown: the drive's SDO information does not confirm the object, so nothing was written; "
    "set FBUS.PARAM02 = 1 on the drive (WorkBench) for its PLL to follow SYNC0"
)
"""What /diagnostics says of a drive with distributed clocks whose FBUS.PARAM02 the master left alone."""


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
    """The /diagnostics publisher and its timer; `name` names the status, `publishing` has the last fault."""

    def __init__(
        self,
        node,
        session: Session,
        group,
        qos: QoSProfile,
        name: str,
        publishing: Publishing,
    ) -> None:
        self._session, self._clock, self._settings = session, session.clock, session.settings
        self._name, self._publishing = name, publishing
        self.publisher = RecordedPublisher(node, DiagnosticArray, "/diagnostics", qos, session)
        self._counters_seen: dict[str, int] = {}
        node.create_timer(1.0 / session.settings.diagnostics_rate, self._publish, group)

    def restart_counters(self) -> None:
        """Counts the fault counters' growth from the next report on (at activate)."""
        self._counters_seen = {}

    def _publish(self) -> None:
        taken = self._session.state()
        if taken is None:
            return
        axis, state, stats = taken
        counters = {k: stats[k] for k in ("overruns", "lost_frames", "wkc_errors", "events_dropped")}
        grown = [k for k, v in counters.items() if v > self._counters_seen.get(k, v)]
        self._counters_seen = counters
        fault = self._publishing.last_fault
        dc_status = axis.cycle.dc_status()
        dc = dc_values(dc_status, axis.slave)
        param02_unknown = fbus_param02_unknown(dc_status, axis.slave)
        if state.state in FAULT_STATES:
            level = DiagnosticStatus.ERROR
        elif (
            grown
            or not state.fresh
            or state.progress in ("stuck", "lost")
            or state.state == "Quick stop active"
            or param02_unknown
        ):
            level = DiagnosticStatus.WARN
        else:
            level = DiagnosticStatus.OK
        summary = state.state or "no valid DS402 state"
        if state.reason:
            summary += f": {state.reason}"
        if grown:
            summary += f" ({', '.join(grown)} since the last report)"
        if param02_unknown:
            summary += f"; {FBUS_PARAM02_UNKNOWN}"
        if level == DiagnosticStatus.ERROR and fault is not None:
            summary += f"; last fault {fault.text or hex(fault.code)}"
        values = {
            "ds402_state": state.state or "unknown",
            "statusword": f"0x{state.statusword:04X}",
            "mode": state.mode or axis.mode,
            "request": state.request or "",
            "progress": state.progress,
            "position": f"{state.position:.9g}",
            "cycles": stats["cycles"],
            **counters,
            "period_mean_s": f"{stats['period']['mean_ns'] * 1e-9:.6g}",
            "period_max_s": f"{stats['period']['max_ns'] * 1e-9:.6g}",
            "exchange_p99_s": f"{stats['exchange']['p99_ns'] * 1e-9:.6g}",
            **dc,
            "last_fault": "none" if fault is None else f"{fault.source}: {fault.text or f'0x{fault.code:04X}'}",
            "last_fault_code": "" if fault is None else f"0x{fault.code:04X}",
            "last_fault_action": "" if fault is None else fault.action,
        }
        status = DiagnosticStatus(
            level=level,
            name=self._name,
            message=summary,
            hardware_id=f"AKD slave {self._settings.slave} on {self._settings.link}",
            values=[KeyValue(key=k, value=str(v)) for k, v in values.items()],
        )
        message = DiagnosticArray(status=[status])
        message.header.stamp = self._clock.stamp()
        self.publisher.publish(message)
