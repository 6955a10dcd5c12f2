"""`akd_node`: one AKD axis in ROS 2, a lifecycle (managed) node over `akd_ros.Axis`.

Lifecycle: configure opens the Axis (the bus to Op, the cycle thread running, the drive disabled); activate arms the
configured latches and starts publishing and accepting commands; deactivate disables the drive; cleanup and shutdown
close the Axis (drive disabled, bus back to Init). With `autostart` the node walks itself to active at start-up, and
with `enable_on_start` it then enables the power stage.

Topics: /joint_states (sensor_msgs/JointState, SI), /diagnostics, ~/status (DriveStatus), ~/latch (LatchEvent),
~/fault (DriveFault); commands on ~/position_command, ~/velocity_command and ~/torque_command (std_msgs/Float64, SI).
Services: ~/enable, ~/disable, ~/reset_fault, ~/quick_stop (std_srvs/Trigger), ~/set_mode, ~/arm_latch, ~/sdo_read,
~/sdo_write (the package's own).

Stamps: periodic messages carry the ROS time of their publication. Events (latch captures, faults) carry the time
of the cycle that saw them: its monotonic wake-up time moved onto the ROS clock by the age of the event at
publication, ``now_ros - (now_monotonic - time_ns)``, so an event is stamped as long before its publication as it
really happened.

Recording (`record.enabled`): from configure to cleanup an `akd_ros.recorder.Recorder` writes a rosbag2 bag of every
message published (at its stamp), every command received (refused ones too, at their arrival) and every cycle as
a CycleSample on ~/cycle (every `record.decimation`-th), and writes its black box (~/black_box) at each fault.

Threads: a MultiThreadedExecutor runs three callback groups. The periodic group (publishing timers) and the command
group (the command subscriptions, queued 100 deep so a stall of the Python side delays commands rather than drops
them) never wait on the drive; the request group (services, the supervisor that handles command time-outs and
automatic fault resets) may wait up to the Axis's time-outs without stopping the periodic topics. `_lock` guards
the Axis's Python-side state (position unwrapping, event queues, the last command) between them.
"""

from __future__ import annotations

import math
import re
import signal
import sys
import threading
import time

import rclpy
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rclpy.callback_groups import MutuallyExclusiveCallbackGroup
from rclpy.executors import ExternalShutdownException, MultiThreadedExecutor
from rclpy.lifecycle import LifecycleNode, LifecycleState, TransitionCallbackReturn
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rclpy.signals import SignalHandlerOptions
from rclpy.time import Time
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64
from std_srvs.srv import Trigger

from akd_ros import _native
from akd_ros.axis import MODES, Axis, CommandError
from akd_ros.msg import CycleSample, DriveFault, DriveStatus, LatchEvent
from akd_ros.params import ParameterError, Settings, declare
from akd_ros.recorder import Recorder
from akd_ros.srv import ArmLatch, SdoRead, SdoWrite, SetMode

NODE_NAME = "akd_node"
"""The node's name, under which its ~/ topics and services are."""
_EDGE_NAMES = {LatchEvent.EDGE_RISING: "rising", LatchEvent.EDGE_FALLING: "falling"}
_EDGE_CODES = {name: code for code, name in _EDGE_NAMES.items()}
_FAULT_STATES = ("Fault", "Fault reaction active")
# Events are taken from the cycle thread at this rate; its queue holds 256, far more than arrive in 20 ms.
_EVENT_POLL_S = 0.02
_SUPERVISOR_PERIOD_S = 0.02
# How often one kind of refused command is logged.
_REFUSAL_LOG_PERIOD_S = 1.0
_NUMBER = re.compile(r"[-+]?(\d+\.?\d*(e[-+]?\d+)?|nan|inf)")
_ERRORS = (ValueError, TimeoutError, _native.EtherCatError)
# Which target of a cycle record is the command, by the mode the drive shows (0x6061).
_TARGET_OF_MODE = {1: "target_position", 7: "target_position", 8: "target_position", 3: "target_velocity",
                   4: "target_torque"}
_UINT32_MAX = 2**32 - 1
_SIGNAL_CHECK_S = 0.1
# Readings of the ROS and the monotonic clock closer than this are taken as simultaneous.
_CLOCK_READ_SPREAD_NS = 50_000
_CLOCK_READ_TRIES = 5


def snake(name: str | None) -> str:
    """A state's name as the messages spell it: "Operation enabled" -> "operation_enabled", "SafeOp" -> "safe_op";
    None -> "unknown"."""
    return "unknown" if name is None else re.sub(r"(?<=[a-z])(?=[A-Z])", "_", name).replace(" ", "_").lower()


class AkdNode(LifecycleNode):
    """The lifecycle node of one AKD axis (see the module doc); parameters are checked on construction and a bad
    one raises `akd_ros.params.ParameterError`."""

    def __init__(self, args: list[str] | None = None, **kwargs) -> None:
        """`args` is the command line rclpy.init was given (None: sys.argv, as rclpy.init takes it); kwargs go to
        rclpy's Node."""
        super().__init__(NODE_NAME, **kwargs)
        arguments = [*(sys.argv if args is None else args), *(kwargs.get("cli_args") or [])]
        self.settings: Settings = declare(self, arguments, kwargs.get("parameter_overrides") or [])
        self.axis: Axis | None = None
        self.failure: str | None = None
        """Why the last transition failed, for the log and the exit message."""
        self._lock = threading.Lock()
        self._active = False
        self._last_command: tuple[str, float, float] | None = None
        self._halted = False
        self._reset_pending = False
        self._last_fault: DriveFault | None = None
        self._counters_seen: dict[str, int] = {}
        self._refusals: dict[str, tuple[float, int]] = {}
        self._recorder: Recorder | None = None
        periodic = MutuallyExclusiveCallbackGroup()
        requests = MutuallyExclusiveCallbackGroup()
        # Commands have a group of their own, so a slow timer callback (a batch of cycles to record) does not hold
        # them up, and a deep queue, so a stall of the node's Python side delays commands instead of dropping them.
        commands = MutuallyExclusiveCallbackGroup()
        command_qos = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE)
        reliable = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)
        events = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE)
        self._joint_states = self.create_lifecycle_publisher(JointState, "/joint_states", reliable)
        self._status = self.create_lifecycle_publisher(DriveStatus, "~/status", reliable)
        self._diagnostics = self.create_lifecycle_publisher(DiagnosticArray, "/diagnostics", reliable)
        self._latch = self.create_lifecycle_publisher(LatchEvent, "~/latch", events)
        self._fault = self.create_lifecycle_publisher(DriveFault, "~/fault", events)
        s = self.settings
        # The timers run in every state and do nothing unless active: cancelling a timer the executor has already
        # taken as ready makes rclpy raise in the executor.
        self.create_timer(1.0 / s.joint_states_rate, self._publish_joint_states, periodic)
        self.create_timer(1.0 / s.status_rate, self._publish_status, periodic)
        self.create_timer(1.0 / s.diagnostics_rate, self._publish_diagnostics, periodic)
        self.create_timer(_EVENT_POLL_S, self._publish_events, periodic)
        self.create_timer(_SUPERVISOR_PERIOD_S, self._supervise, requests)
        self._qos = {"reliable": reliable, "events": events, "commands": command_qos}
        self._command_topics = {}
        for kind in ("position", "velocity", "torque"):
            subscription = self.create_subscription(Float64, f"~/{kind}_command",
                                                    lambda m, k=kind: self._on_command(k, m), command_qos,
                                                    callback_group=commands)
            self._command_topics[kind] = subscription.topic_name
        for name, handler in (("enable", self._enable), ("disable", self._disable),
                              ("reset_fault", self._reset_fault), ("quick_stop", self._quick_stop)):
            self.create_service(Trigger, f"~/{name}", self._trigger(name, handler), callback_group=requests)
        self.create_service(SetMode, "~/set_mode", self._set_mode, callback_group=requests)
        self.create_service(ArmLatch, "~/arm_latch", self._arm_latch, callback_group=requests)
        self.create_service(SdoRead, "~/sdo_read", self._sdo_read, callback_group=requests)
        self.create_service(SdoWrite, "~/sdo_write", self._sdo_write, callback_group=requests)

    # --- lifecycle -------------------------------------------------------------------------------------------------

    def _fail(self, message: str) -> TransitionCallbackReturn:
        self.failure = message
        self.get_logger().error(message)
        return TransitionCallbackReturn.FAILURE

    def on_configure(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Opens the Axis: the bus to Op and the cycle thread running, the drive disabled."""
        s = self.settings
        try:
            axis = Axis(s.link, slave=s.slave, alias=s.alias, period=s.cycle_time, mode=s.mode, units=s.units, limits=s.limits,
                        mapping=s.mapping, priority=s.rt_priority, cpu=s.rt_cpu, lock_memory=s.rt_lock_memory)
        except _ERRORS as e:
            return self._fail(f"configure: the drive at slave {s.slave} on link {s.link!r} did not open: {e}")
        try:
            # The Axis writes 0x6060 as given; set_mode also checks that the mapping carries the mode's target.
            axis.set_mode(s.mode)
        except _ERRORS as e:
            axis.close()
            return self._fail(f"parameters mode/mapping: {e}")
        for warning in axis.warnings:
            self.get_logger().warning(f"real-time settings (rt.*): {warning}")
        if s.record is not None:
            try:
                self._recorder = self._open_recorder()
            except (ValueError, OSError) as e:
                axis.close()
                return self._fail(f"parameters record.*: the recorder did not start: {e}")
        with self._lock:
            self.axis = axis
        self.get_logger().info(f"configured: slave {s.slave} on {s.link} in Op, cycle {s.cycle_time * 1e3:g} ms, "
                               f"mode {s.mode}")
        return TransitionCallbackReturn.SUCCESS

    def on_activate(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Arms the configured latches, starts publishing and accepting commands; enables with enable_on_start."""
        for channel, edge in self.settings.latch_arm:
            try:
                self.axis.arm_latch(channel, edge)
            except _ERRORS as e:
                return self._fail(f"parameter latch.arm: latch {channel}/{edge} not armed: {e}")
        self._counters_seen = {}
        self._active = True
        result = super().on_activate(state)
        if self.settings.enable_on_start:
            ok, message = self._enable()
            if ok:
                self.get_logger().info(f"enable_on_start: {message}")
            else:
                self.get_logger().error(f"enable_on_start: {message}")
        self.get_logger().info(f"active: publishing /joint_states of {self.settings.joint_name}, taking commands")
        return result

    def on_deactivate(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Stops publishing and accepting commands and disables the drive."""
        self._active = False
        ok, message = self._disable()
        if not ok:
            self.get_logger().error(f"deactivate: {message}")
        return super().on_deactivate(state)

    def on_cleanup(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Closes the Axis: the drive disabled, the cycle stopped, the bus back to Init."""
        self.close()
        return TransitionCallbackReturn.SUCCESS

    def on_shutdown(self, state: LifecycleState) -> TransitionCallbackReturn:
        """As cleanup, from any state."""
        self.close()
        return TransitionCallbackReturn.SUCCESS

    def on_error(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Closes the Axis, so the node is unconfigured and can be configured again."""
        self.close()
        return TransitionCallbackReturn.SUCCESS

    def close(self) -> None:
        """Stops publishing, disables the drive and returns the bus to Init (does nothing when not configured)."""
        self._active = False
        with self._lock:
            axis, self.axis = self.axis, None
        if axis is not None:
            axis.close()
            self.get_logger().info("closed: drive disabled, bus in Init")
        recorder, self._recorder = self._recorder, None
        if recorder is not None:
            stats = recorder.close()
            self.get_logger().info(f"recorded {stats.bag or 'no bag'}: {stats.written} messages, "
                                   f"{stats.dropped} dropped, {stats.black_box_dumps} black box dumps, "
                                   f"{stats.errors} errors")

    # --- recording -------------------------------------------------------------------------------------------------

    def _open_recorder(self) -> Recorder:
        """A Recorder of every topic the node publishes, the commands it receives and its cycles."""
        s = self.settings
        recorder = Recorder(s.record["folder"], cycle_rate_hz=1.0 / s.cycle_time,
                            decimation=s.record["decimation"], black_box_seconds=s.record["black_box_seconds"],
                            on_error=lambda text: self.get_logger().error(f"recording stopped: {text}"))
        try:
            for publisher, kind, qos in ((self._joint_states, JointState, "reliable"),
                                         (self._status, DriveStatus, "reliable"),
                                         (self._diagnostics, DiagnosticArray, "reliable"),
                                         (self._latch, LatchEvent, "events"), (self._fault, DriveFault, "events")):
                recorder.add_topic(publisher.topic_name, kind, self._qos[qos])
            for topic in self._command_topics.values():
                recorder.add_topic(topic, Float64, self._qos["commands"])
            recorder.add_cycle_topic(self.resolve_topic_name("~/cycle"), CycleSample, self._qos["reliable"])
        except ValueError:
            recorder.close()
            raise
        self.get_logger().info(f"recording to {recorder.bag_path}")
        return recorder

    def _publish(self, publisher, message) -> None:
        """Publishes `message` (stamped) and records it at its stamp."""
        publisher.publish(message)
        recorder = self._recorder
        if recorder is not None:
            stamp = message.header.stamp
            recorder.write(publisher.topic_name, message, stamp.sec * 1_000_000_000 + stamp.nanosec)

    def _record_cycles(self, recorder: Recorder, columns: dict[str, list]) -> None:
        """Hands each cycle record of `columns` (`Axis.samples`) to `recorder` as a CycleSample."""
        units = self.settings.units
        # Cycle times are monotonic; the bag's are ROS times (see the module doc on stamps).
        offset = self._ros_minus_monotonic_ns()
        for i in range(len(columns["cycle"])):
            mode = columns["mode"][i]
            target = _TARGET_OF_MODE.get(mode)
            if target == "target_position":
                command = units.position_to_si(columns[target][i])
            elif target == "target_velocity":
                command = units.velocity_to_si(columns[target][i])
            elif target == "target_torque":
                command = units.torque_to_si(columns[target][i])
            else:
                command = math.nan
            time_ns = columns["time_ns"][i] + offset
            sample = CycleSample(
                stamp=Time(nanoseconds=time_ns).to_msg(), cycle=columns["cycle"][i],
                position=units.position_to_si(columns["position"][i]),
                velocity=units.velocity_to_si(columns["velocity"][i]),
                torque=units.torque_to_si(columns["torque"][i]), command=command,
                following_error=columns["following_error"][i] * units.si_per_count,
                position_counts=columns["position"][i], statusword=columns["statusword"][i], mode_of_operation=mode,
                period_ns=min(columns["period_ns"][i], _UINT32_MAX),
                exchange_ns=min(columns["exchange_ns"][i], _UINT32_MAX), wkc=columns["wkc"][i],
            )
            recorder.cycle_sample(sample, time_ns)

    # --- periodic topics -------------------------------------------------------------------------------------------

    def _stamp(self, time_ns: int | None = None):
        """ROS time now, or of the cycle whose monotonic wake-up time is `time_ns` (see the module doc)."""
        if time_ns is None:
            return self.get_clock().now().to_msg()
        return Time(nanoseconds=time_ns + self._ros_minus_monotonic_ns()).to_msg()

    def _ros_minus_monotonic_ns(self) -> int:
        """ROS time minus monotonic time, from the two clocks read as close together as a few tries allow.

        Another thread taking the GIL between the two readings would shift the result by milliseconds, and with it
        the recorded cycles (out of order in the bag) and the events' stamps (outside their black box)."""
        best_spread, offset = math.inf, 0
        for _ in range(_CLOCK_READ_TRIES):
            before = time.monotonic_ns()
            ros = self.get_clock().now().nanoseconds
            after = time.monotonic_ns()
            if after - before < best_spread:
                best_spread, offset = after - before, ros - (before + after) // 2
            if best_spread <= _CLOCK_READ_SPREAD_NS:
                break
        return offset

    def _state(self):
        """(axis, its state and statistics), or None when the axis is closed or the node inactive."""
        with self._lock:
            if self.axis is None or not self._active:
                return None
            return self.axis, self.axis.state(), self.axis.stats()

    def _publish_joint_states(self) -> None:
        taken = self._state()
        if taken is None:
            return
        _, state, _ = taken
        message = JointState(name=[self.settings.joint_name], position=[state.position])
        message.header.stamp = self._stamp()
        if state.velocity is not None:
            message.velocity = [state.velocity]
        if state.torque is not None:
            message.effort = [state.torque]
        self._publish(self._joint_states, message)

    def _publish_status(self) -> None:
        taken = self._state()
        if taken is None:
            return
        axis, state, stats = taken
        message = DriveStatus(
            joint=self.settings.joint_name, ds402_state=snake(state.state), statusword=state.statusword,
            mode=state.mode or axis.mode, mode_of_operation=MODES.get(state.mode, 0),
            following_error=math.nan if state.following_error is None else state.following_error,
            cycles=stats["cycles"], overruns=stats["overruns"], lost_frames=stats["lost_frames"],
            wkc_errors=stats["wkc_errors"], period_mean=stats["period"]["mean_ns"] * 1e-9,
            period_max=stats["period"]["max_ns"] * 1e-9, exchange_p99=stats["exchange"]["p99_ns"] * 1e-9,
        )
        message.header.stamp = self._stamp()
        self._publish(self._status, message)

    def _publish_diagnostics(self) -> None:
        taken = self._state()
        if taken is None:
            return
        axis, state, stats = taken
        counters = {k: stats[k] for k in ("overruns", "lost_frames", "wkc_errors", "events_dropped")}
        grown = [k for k, v in counters.items() if v > self._counters_seen.get(k, v)]
        self._counters_seen = counters
        if state.state in _FAULT_STATES:
            level = DiagnosticStatus.ERROR
        elif grown or not state.fresh or state.progress in ("stuck", "lost") or state.state == "Quick stop active":
            level = DiagnosticStatus.WARN
        else:
            level = DiagnosticStatus.OK
        summary = state.state or "no valid DS402 state"
        if state.reason:
            summary += f": {state.reason}"
        if grown:
            summary += f" ({', '.join(grown)} since the last report)"
        if level == DiagnosticStatus.ERROR and self._last_fault is not None:
            summary += f"; last fault {self._last_fault.text or hex(self._last_fault.code)}"
        fault = self._last_fault
        values = {
            "ds402_state": state.state or "unknown", "statusword": f"0x{state.statusword:04X}",
            "mode": state.mode or axis.mode, "request": state.request or "", "progress": state.progress,
            "position": f"{state.position:.9g}", "cycles": stats["cycles"], **counters,
            "period_mean_s": f"{stats['period']['mean_ns'] * 1e-9:.6g}",
            "period_max_s": f"{stats['period']['max_ns'] * 1e-9:.6g}",
            "exchange_p99_s": f"{stats['exchange']['p99_ns'] * 1e-9:.6g}",
            "last_fault": "none" if fault is None else f"{fault.source}: {fault.text or f'0x{fault.code:04X}'}",
            "last_fault_code": "" if fault is None else f"0x{fault.code:04X}",
            "last_fault_action": "" if fault is None else fault.action,
        }
        status = DiagnosticStatus(
            level=level, name=f"{NODE_NAME}: {self.settings.joint_name}", message=summary,
            hardware_id=f"AKD slave {self.settings.slave} on {self.settings.link}",
            values=[KeyValue(key=k, value=str(v)) for k, v in values.items()],
        )
        message = DiagnosticArray(status=[status])
        message.header.stamp = self._stamp()
        self._publish(self._diagnostics, message)

    def _publish_events(self) -> None:
        with self._lock:
            if self.axis is None or not self._active:
                return
            latches, faults = list(self.axis.latch_events()), list(self.axis.fault_events())
            # Taken with the events, so the black box holds the cycles up to a fault when it is written.
            recorder = self._recorder
            columns = self.axis.samples() if recorder is not None else None
        if columns is not None:
            self._record_cycles(recorder, columns)
        joint = self.settings.joint_name
        for e in latches:
            message = LatchEvent(joint=joint, channel=e.channel, edge=_EDGE_CODES[e.edge], position=e.position,
                                 position_counts=e.position_counts)
            message.header.stamp = self._stamp(e.time_ns)
            self._publish(self._latch, message)
        for e in faults:
            self.get_logger().error(f"fault: {e.describe()}")
            message = DriveFault(
                joint=joint, source=e.source, code=min(e.code, 0xFFFF), text=e.text or "",
                ds402_state=snake(e.ds402_state), al_state=snake(e.al_state),
                al_status_code=e.al_status_code, action=e.action,
            )
            message.header.stamp = self._stamp(e.time_ns)
            self._last_fault = message
            self._publish(self._fault, message)
            if recorder is not None:
                recorder.fault(message.header.stamp.sec * 1_000_000_000 + message.header.stamp.nanosec)
            self._reset_pending = self.settings.fault_reset == "auto_once"

    # --- commands --------------------------------------------------------------------------------------------------

    def _on_command(self, kind: str, message: Float64) -> None:
        recorder = self._recorder
        if recorder is not None:
            recorder.write(self._command_topics[kind], message, self.get_clock().now().nanoseconds)
        value = message.data
        try:
            with self._lock:
                if self.axis is None or not self._active:
                    raise CommandError(f"{kind} command refused: the node is not active (activate it first)")
                drive_state = self.axis.cycle.drive_status(self.axis.slave)["state"]
                if drive_state != "Operation enabled":
                    raise CommandError(f"{kind} command refused: the drive is in {drive_state}, not Operation "
                                       "enabled; call ~/enable first")
                getattr(self.axis, f"command_{kind}")(value)
                self._last_command = (kind, value, time.monotonic())
                if self._halted:
                    self.axis.halt(False)
                    self._halted = False
        except CommandError as e:
            self._warn_refused(str(e))

    def _warn_refused(self, message: str) -> None:
        """Logs a refusal, each kind (its text without the numbers) at most once per _REFUSAL_LOG_PERIOD_S, with the
        count of those not logged since."""
        kind = _NUMBER.sub("#", message)
        now = time.monotonic()
        last, hidden = self._refusals.get(kind, (-math.inf, 0))
        if now - last < _REFUSAL_LOG_PERIOD_S:
            self._refusals[kind] = (last, hidden + 1)
            return
        self._refusals[kind] = (now, 0)
        more = f" ({hidden} more like it since)" if hidden else ""
        self.get_logger().warning(message + more)

    def _supervise(self) -> None:
        """Resets a fault once under fault_reset auto_once; acts on a velocity or torque stream that stopped."""
        axis = self.axis
        if axis is None or not self._active:
            return
        if self._reset_pending:
            self._reset_pending = False
            if axis.cycle.drive_status(axis.slave)["state"] in _FAULT_STATES:
                ok, message = self._reset_fault()
                self.get_logger().warning(f"fault_reset auto_once: {message}")
        timeout = self.settings.command_timeout
        with self._lock:
            last = self._last_command
            if timeout <= 0 or last is None or last[0] == "position" or last[1] == 0.0:
                return
            if time.monotonic() - last[2] < timeout:
                return
            self._last_command = None
            if axis.cycle.drive_status(axis.slave)["state"] != "Operation enabled":
                return
            if self.settings.command_timeout_policy == "hold":
                axis.halt(True)
                self._halted = True
        what = f"no {last[0]} command for {timeout:g} s (command_timeout) while commanding {last[1]:g}"
        if self.settings.command_timeout_policy == "hold":
            self.get_logger().warning(f"{what}: halted, holding until the next command")
            return
        try:
            axis.quick_stop()
            self.get_logger().warning(f"{what}: quick stop; call ~/enable to go on")
        except _ERRORS as e:
            self.get_logger().error(f"{what}: quick stop failed: {e}")

    # --- services --------------------------------------------------------------------------------------------------

    def _axis_for_request(self) -> Axis:
        axis = self.axis
        if axis is None or not self._active:
            raise CommandError("the node is not active; configure and activate it first")
        return axis

    def _release_halt(self, axis: Axis) -> None:
        with self._lock:
            if self._halted:
                axis.halt(False)
                self._halted = False
            self._last_command = None

    def _enable(self) -> tuple[bool, str]:
        try:
            axis = self._axis_for_request()
            self._release_halt(axis)
            axis.enable()
        except _ERRORS as e:
            return False, f"not enabled: {e}"
        return True, "Operation enabled; the target holds the actual position until commanded"

    def _disable(self) -> tuple[bool, str]:
        axis = self.axis
        if axis is None:
            return False, "not disabled: the node is not configured"
        try:
            self._release_halt(axis)
            axis.disable()
        except _ERRORS as e:
            return False, f"not disabled: {e}"
        return True, "Switch on disabled (power stage off)"

    def _reset_fault(self) -> tuple[bool, str]:
        try:
            self._axis_for_request().reset_fault()
        except _ERRORS as e:
            return False, f"fault not reset: {e}"
        return True, "fault reset: Switch on disabled; call ~/enable to go on"

    def _quick_stop(self) -> tuple[bool, str]:
        try:
            axis = self._axis_for_request()
            self._release_halt(axis)
            axis.quick_stop()
        except _ERRORS as e:
            return False, f"quick stop failed: {e}"
        return True, "Quick stop active; call ~/enable to go on"

    def _trigger(self, name: str, handler):
        def callback(request, response):
            response.success, response.message = handler()
            # rclpy ties a severity to each logging call site: one call per severity.
            if response.success:
                self.get_logger().info(f"~/{name}: {response.message}")
            else:
                self.get_logger().warning(f"~/{name}: {response.message}")
            return response

        return callback

    def _set_mode(self, request, response):
        try:
            axis = self._axis_for_request()
            if request.mode not in MODES:
                raise CommandError(f"mode {request.mode!r} is not one of {', '.join(MODES)}")
            self._release_halt(axis)
            with self._lock:
                axis.set_mode(request.mode)
            response.success, response.message = True, f"mode {request.mode}"
        except _ERRORS as e:
            response.success, response.message = False, f"mode not changed: {e}"
        self.get_logger().info(f"~/set_mode: {response.message}")
        return response

    def _arm_latch(self, request, response):
        try:
            axis = self._axis_for_request()
            if request.edge not in _EDGE_NAMES:
                raise CommandError(f"latch edge {request.edge}: allowed {LatchEvent.EDGE_RISING} (rising) or "
                                   f"{LatchEvent.EDGE_FALLING} (falling)")
            axis.arm_latch(request.channel, _EDGE_NAMES[request.edge], request.arm)
            response.success = True
            response.message = (f"latch {request.channel} {'armed' if request.arm else 'disarmed'} on the "
                                f"{_EDGE_NAMES[request.edge]} edge")
        except _ERRORS as e:
            response.success, response.message = False, f"latch not changed: {e}"
        return response

    def _sdo_read(self, request, response):
        try:
            response.data = list(self._axis_for_request().sdo_read(request.index, request.subindex))
            response.success, response.message = True, ""
        except _ERRORS as e:
            response.success, response.message = False, f"0x{request.index:04X}:{request.subindex:02X}: {e}"
        return response

    def _sdo_write(self, request, response):
        try:
            self._axis_for_request().sdo_write(request.index, request.subindex, bytes(request.data))
            response.success, response.message = True, ""
        except _ERRORS as e:
            response.success, response.message = False, f"0x{request.index:04X}:{request.subindex:02X}: {e}"
        return response


def main(args: list[str] | None = None) -> int:
    """Entry point of `akd_node`: runs the node until SIGINT/SIGTERM, then disables the drive, returns the bus to
    Init and exits 0. A bad parameter or a failed autostart exits 1 with the reason on stderr."""
    # The signals end spin() here rather than shutting the context down at once, so the drive is disabled and the
    # bus closed while the node can still log it.
    rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
    # SIGINT too: a shell starts background jobs with it ignored, and it must still stop the node cleanly.
    for number in (signal.SIGINT, signal.SIGTERM):
        signal.signal(number, signal.default_int_handler)
    try:
        node = AkdNode(args)
    except ParameterError as e:
        print(f"{NODE_NAME}: error: {e}", file=sys.stderr)
        rclpy.try_shutdown()
        return 1
    executor = MultiThreadedExecutor(num_threads=4)
    executor.add_node(node)
    status = 0
    try:
        if node.settings.autostart:
            for step in (node.trigger_configure, node.trigger_activate):
                if step() != TransitionCallbackReturn.SUCCESS:
                    print(f"{NODE_NAME}: error: {node.failure}", file=sys.stderr)
                    status = 1
                    break
        while status == 0 and rclpy.ok():
            # Bounded waits: a signal's handler runs only when the wait returns to Python.
            executor.spin_once(timeout_sec=_SIGNAL_CHECK_S)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        node.close()
        executor.shutdown()
        node.destroy_node()
        rclpy.try_shutdown()
    return status


if __name__ == "__main__":
    sys.exit(main())
