"""The node without its middleware: `Core`, the parts a node of AKD joints is made of over a transport, and its
transitions (configure opens the Bus, activate starts publishing and taking commands, deactivate disables the drives,
close closes the Bus). `akd_ros.node.lifecycle` runs it as an rclpy lifecycle node, `akd_ros.node.zenoh_node` on
Zenoh alone.
"""

from __future__ import annotations

from akd_ros.axis import CommandError
from akd_ros.bus import Bus
from akd_ros.eoe_bridge import EoeBridge
from akd_ros.node.clock import CycleClock
from akd_ros.node.commands import Commands
from akd_ros.node.diagnostics import Diagnostics
from akd_ros.node.doors import Doors
from akd_ros.node.follow_joint_trajectory import FollowJointTrajectory
from akd_ros.node.homing import Homing
from akd_ros.node.io import Io
from akd_ros.node.node_state import AXIS_ERRORS, NODE_NAME, NodeState
from akd_ros.node.publishing import Publishing
from akd_ros.node.recording import open_recorder
from akd_ros.node.services import Services
from akd_ros.node.trajectories import JOINT_TRAJECTORY, Trajectories
from akd_ros.node.transports.transport import Qos, Transport
from akd_ros.params import Settings
from akd_ros.recorder import Recorder
from akd_ros.tap import Tap

# How long a closing node waits for its action goals to end (a trajectory braking, a homing halting).
_GOALS_END_S = 10.0


class Core:
    """A bus of AKD joints as a node, over `transport` (see `akd_ros.node`): its parts and its transitions, each of
    which gives whether it succeeded (`failure` says why not)."""

    def __init__(self, transport: Transport, settings: Settings) -> None:
        self.settings = settings
        self.failure: str | None = None
        """Why the last transition failed, for the log and the exit message."""
        self._live_view = None
        if settings.live_view is not None:
            # Imported only when on: with the live view off the node imports no foxglove.
            from akd_ros.node.live_view import LiveView

            self._live_view = LiveView(settings.live_view, transport)
            transport = self._live_view.transport
        # Every part declares its doors here: those of a closed role never exist; each request is recorded.
        doors = Doors(transport, settings.doors)
        transport = doors
        self._transport = transport
        self._logger = transport.logger
        self._eoe_bridge: EoeBridge | None = None
        self._node_state = NodeState(
            self.settings, CycleClock(transport.now_ns, transport.message_class("builtin_interfaces/msg/Time"))
        )
        periodic, requests = transport.group("periodic"), transport.group("requests")
        # Commands have a group of their own, so a slow timer callback (a batch of cycles to record) does not hold
        # them up, and a deep queue, so a stall of the node's Python side delays commands instead of dropping them.
        commands = transport.group("commands")
        command_qos = Qos(depth=100)
        self._reliable = Qos(depth=10)
        events = Qos(depth=100)
        self._commands = Commands(transport, self._node_state, commands, command_qos, requests)
        self._publishing = Publishing(transport, self._node_state, self._reliable, events, self._commands.fault_seen)
        self._trajectories = Trajectories(transport, self._node_state, commands, periodic, command_qos, events)
        self._io = Io(transport, self._node_state, requests, events, self._publishing)
        self._diagnostics = Diagnostics(
            transport, self._node_state, periodic, self._reliable, NODE_NAME, self._publishing
        )
        Services(transport, self._node_state, self._commands, requests)
        # Homing goals have a group of their own: one runs for as long as its joints home.
        Homing(transport, self._node_state, transport.group("homing"))
        # So do FollowJointTrajectory goals: one runs until its trajectory ends, a newer one beside it to preempt it.
        FollowJointTrajectory(transport, self._node_state, transport.group("follow"))
        doors.watch_clients()
        self._logger.info(doors.summary())

    @property
    def bus(self) -> Bus | None:
        """The Bus while configured, else None."""
        return self._node_state.bus

    @property
    def recorder(self) -> Recorder | None:
        """The Recorder while configured with record.enabled, else None (e.g. to hold its writer, as a stalled disk
        would, and see what that costs)."""
        return self._node_state.recorder

    def _fail(self, message: str) -> bool:
        self.failure = message
        self._logger.error(message)
        return False

    def _where(self) -> str:
        """The joints and where they are, and the devices, for the log."""
        s = self.settings
        if not s.joint_namespaces:
            j = s.joints[0]
            where = f"slave {j.slave}" if j.alias is None else f"alias {j.alias}"
        else:
            where = ", ".join(
                f"{j.name} (slave {j.slave})" if j.alias is None else f"{j.name} (alias {j.alias})" for j in s.joints
            )
        devices = ", ".join(f"{d.name} (slave {d.slave}{f', {d.product}' if d.product else ''})" for d in s.devices)
        return f"{where}; devices {devices}" if devices else where

    def configure(self) -> bool:
        """Opens the Bus: the line to Op and the cycle thread running, every drive disabled; with eoe.tap, the EoE
        bridge; with live_view.port, first the live view."""
        self._node_state.goals.open()
        if self._live_view is not None:
            try:
                self._live_view.open()
            except OSError as e:
                return self._fail(f"parameters live_view.*: {e}")
        tap = self._open_tap()
        try:
            configured = self._configure(tap)
        finally:
            if self._eoe_bridge is None and tap is not None:
                tap.close()
        if not configured and self._live_view is not None:
            self._live_view.close()
        return configured

    def _open_tap(self) -> Tap | None:
        """With eoe.tap, the TAP interface, opened before the link (whose raw socket gives up CAP_NET_ADMIN); a
        warning, and none, where it cannot open (without CAP_NET_ADMIN): the drives run as well without it."""
        s = self.settings
        if s.eoe_tap is None:
            return None
        try:
            return Tap(s.eoe_tap, s.eoe_host)
        except OSError as e:
            self._logger.warning(f"parameter eoe.tap: no EoE bridge: {e}")
            return None

    def _configure(self, tap: Tap | None) -> bool:
        s = self.settings
        # What each mapping carries of the drive's I/O, known from the parameters before the bus is touched.
        self._logger.info("I/O the mappings carry: " + "; ".join(f"{j.name}: {j.describe_io()}" for j in s.joints))
        try:
            bus = Bus(s.link, [j.drive() for j in s.joints], devices=[d.device() for d in s.devices], **s.bus_options())
        except AXIS_ERRORS as e:
            return self._fail(f"configure: the drives ({self._where()}) on link {s.link!r} did not open: {e}")
        for joint, axis in zip(s.joints, bus.axes, strict=True):
            prefix = "" if not s.joint_namespaces else f"joints.{joint.name}."
            try:
                # The Bus sets the mode as given; set_mode also checks that the mapping carries the mode's target.
                axis.set_mode(joint.mode)
            except AXIS_ERRORS as e:
                bus.close()
                return self._fail(f"parameters {prefix}mode/{prefix}mapping: {e}")
            try:
                axis.set_command_timeout(joint.command_timeout, joint.command_timeout_policy)
            except CommandError as e:
                # Velocity and torque commands then go by SDO, which the cycle thread does not watch.
                self._logger.warning(f"parameter {prefix}command_timeout: not watched: {e}")
        for warning in bus.warnings:
            self._logger.warning(f"configure: not permitted: {warning}")
        if bus.unnamed:
            found = ", ".join(f"{p} ({bus.slaves[p].get('order') or bus.slaves[p]['name']})" for p in bus.unnamed)
            self._logger.warning(
                f"configure: slaves in Op that the parameters name neither as a joint nor as a device, their outputs "
                f"off: {found}; name them under devices to see and set them"
            )
        if s.record is not None:
            topics = [(p.topic_name, p.msg_type, p.qos) for p in self._publishing.publishers()]
            topics += [(p.topic_name, p.msg_type, p.qos) for p in self._io.publishers.values()]
            topics += [(p.topic_name, p.msg_type, p.qos) for p in self._io.device_publishers.values()]
            topics += [
                (p.topic_name, p.msg_type, p.qos) for p in (self._diagnostics.publisher, self._trajectories.status)
            ]
            commanded = [*self._commands.recorded_topics(), (self._trajectories.topic, JOINT_TRAJECTORY)]
            topics += [
                (topic, self._transport.recorded_class(kind), self._transport.recorded_qos(self._commands.qos))
                for topic, kind in commanded
            ]
            try:
                self._node_state.recorder = open_recorder(
                    self._transport, s, topics, self._transport.recorded_qos(self._reliable)
                )
            except (ValueError, OSError) as e:
                bus.close()
                return self._fail(f"parameters record.*: the recorder did not start: {e}")
        if tap is not None:
            self._eoe_bridge = EoeBridge(bus.cycle, bus.eoe_drives, tap)
            drives = ", ".join(f"{j.name} at {j.eoe_ip.split('/')[0]}" for j in s.joints if j.eoe_ip is not None)
            self._logger.info(f"EoE bridge: {drives} through {tap.name}")
        with self._node_state.lock:
            self._node_state.bus = bus
        self._publishing.start()
        modes = ", ".join(sorted({j.mode for j in s.joints}))
        self._logger.info(
            f"configured: {self._where()} on {s.link} in Op, cycle {s.cycle_time * 1e3:g} ms, mode {modes}"
        )
        return True

    def activate(self) -> bool:
        """Arms the configured latches, starts publishing and accepting commands; enables with enable_on_start."""
        bus = self._node_state.bus
        for joint, axis in zip(self.settings.joints, bus.axes, strict=True):
            for channel, edge in joint.latch_arm:
                try:
                    axis.arm_latch(channel, edge)
                except AXIS_ERRORS as e:
                    return self._fail(f"parameter latch.arm of {joint.name}: latch {channel}/{edge} not armed: {e}")
        self._diagnostics.restart_counters()
        self._node_state.active = True
        self._publishing.set_active(True)
        if self.settings.enable_on_start:
            ok, message = self._commands.request_all("enable")
            if ok:
                self._logger.info(f"enable_on_start: {message}")
            else:
                self._logger.error(f"enable_on_start: {message}")
        self._logger.info(f"active: publishing /joint_states of {', '.join(bus.names)}, taking commands")
        return True

    def deactivate(self) -> None:
        """Stops publishing and accepting commands, disables the drives and switches the devices' outputs off."""
        self._node_state.active = False
        self._publishing.set_active(False)
        ok, message = self._commands.request_all("disable")
        if not ok:
            self._logger.error(f"deactivate: {message}")
        bus = self._node_state.bus
        for device in bus.devices if bus is not None else ():
            try:
                device.outputs_off()
            except AXIS_ERRORS as e:
                self._logger.error(f"deactivate: the outputs of device {device.name} were not switched off: {e}")

    def end_goals(self) -> None:
        """Ends every action goal executing, each with its result: their motions stopped (trajectories braked to a
        standstill, homings halted), before the bus they run on closes; waits for them, up to _GOALS_END_S."""
        if not self._node_state.goals.close(_GOALS_END_S):
            self._logger.warning(f"closing: some action goals had not ended after {_GOALS_END_S:g} s")

    def close(self) -> None:
        """Ends the action goals executing, stops publishing, disables the drives and returns the line to Init, and
        closes the live view (does nothing when not configured)."""
        node_state = self._node_state
        self.end_goals()
        node_state.active = False
        self._publishing.stop()
        with node_state.lock:
            bus, node_state.bus = node_state.bus, None
        recorder, node_state.recorder = node_state.recorder, None
        bridge, self._eoe_bridge = self._eoe_bridge, None
        if bridge is not None:
            bridge.close()
            stats, dropped = bus.stats(), bus.cycle.eoe_dropped()
            # What the bridge carried, beside what the process data lost meanwhile.
            self._logger.info(
                f"EoE bridge closed: {bridge.to_drives} frames to the drives, {bridge.from_drives} from them, "
                f"dropped {dropped[0]} and {dropped[1]}; the cycle: {stats['cycles']} cycles, "
                f"{stats['lost_frames']} lost frames, {stats['wkc_errors']} WKC errors"
                + (f"; {bridge.refused} frames too long for EoE" if bridge.refused else "")
                + (f"; it had stopped: {bridge.failure}" if bridge.failure else "")
            )
        if bus is not None:
            # Records the ring or the bus dropped before the node took them are cycles the bag lacks.
            lost = bus.stats()["samples_dropped"] if recorder is not None else 0
            problem = bus.close()
            if problem is not None:
                self._logger.warning(f"closed: the cycle stopped, but {problem}")
            else:
                closed = "closed: drives disabled, bus in Init"
                self._logger.info(closed if self.settings.joint_namespaces else "closed: drive disabled, bus in Init")
            if lost:
                self._logger.warning(f"recording: {lost} per-cycle records were not taken in time, not in the bag")
        if self._live_view is not None:
            self._live_view.close()
        if recorder is not None:
            stats = recorder.close()
            self._logger.info(
                f"recorded {stats.bag or 'no bag'}: {stats.written} messages, "
                f"{stats.dropped} dropped, {stats.black_box_dumps} black box dumps, "
                f"{stats.errors} errors"
            )
