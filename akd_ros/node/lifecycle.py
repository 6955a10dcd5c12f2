"""The lifecycle (managed) node: `AkdNode`, made of the node's parts, and its transitions.

configure opens the Bus (the line to Op, the one cycle thread running, every joint's drive disabled); activate arms
the configured latches and starts publishing and accepting commands; deactivate disables the drives; cleanup and
shutdown close the Bus (drives disabled, line back to Init). With `autostart` the node walks itself to active at
start-up (see `akd_ros.node.main`), and with `enable_on_start` it then enables every joint's power stage.
"""

from __future__ import annotations

import sys

from rclpy.callback_groups import MutuallyExclusiveCallbackGroup
from rclpy.lifecycle import LifecycleNode, LifecycleState, TransitionCallbackReturn
from rclpy.qos import QoSProfile, ReliabilityPolicy
from trajectory_msgs.msg import JointTrajectory

from akd_ros.axis import CommandError
from akd_ros.bus import Bus
from akd_ros.node.clock import CycleClock
from akd_ros.node.commands import Commands
from akd_ros.node.diagnostics import Diagnostics
from akd_ros.node.publishing import Publishing
from akd_ros.node.recording import open_recorder
from akd_ros.node.ros_parameters import declare
from akd_ros.node.services import Services
from akd_ros.node.session import AXIS_ERRORS, Session
from akd_ros.node.trajectories import Trajectories
from akd_ros.params import Settings

NODE_NAME = "akd_node"
"""The node's name, under which its ~/ topics and services are."""


class AkdNode(LifecycleNode):
    """The lifecycle node of a bus of AKD joints (see `akd_ros.node`); parameters are checked on construction and a
    bad one raises `akd_ros.params.ParameterError`."""

    def __init__(self, args: list[str] | None = None, **kwargs) -> None:
        """`args` is the command line rclpy.init was given (None: sys.argv, as rclpy.init takes it); kwargs go to
        rclpy's Node."""
        super().__init__(NODE_NAME, **kwargs)
        arguments = [*(sys.argv if args is None else args), *(kwargs.get("cli_args") or [])]
        self.settings: Settings = declare(self, arguments, kwargs.get("parameter_overrides") or [])
        self.failure: str | None = None
        """Why the last transition failed, for the log and the exit message."""
        self._session = Session(self.settings, CycleClock(self.get_clock()))
        periodic = MutuallyExclusiveCallbackGroup()
        requests = MutuallyExclusiveCallbackGroup()
        # Commands have a group of their own, so a slow timer callback (a batch of cycles to record) does not hold
        # them up, and a deep queue, so a stall of the node's Python side delays commands instead of dropping them.
        commands = MutuallyExclusiveCallbackGroup()
        command_qos = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE)
        self._reliable = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)
        events = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE)
        self._commands = Commands(self, self._session, commands, command_qos, requests)
        self._publishing = Publishing(self, self._session, periodic, self._reliable, events, self._commands.fault_seen)
        self._trajectories = Trajectories(self, self._session, commands, periodic, command_qos, events)
        self._diagnostics = Diagnostics(self, self._session, periodic, self._reliable, NODE_NAME, self._publishing)
        Services(self, self._session, self._commands, requests)

    @property
    def bus(self) -> Bus | None:
        """The Bus while configured, else None."""
        return self._session.bus

    def _fail(self, message: str) -> TransitionCallbackReturn:
        self.failure = message
        self.get_logger().error(message)
        return TransitionCallbackReturn.FAILURE

    def _where(self) -> str:
        """The joints and where they are, for the log."""
        s = self.settings
        if not s.joint_namespaces:
            j = s.joints[0]
            return f"slave {j.slave}" if j.alias is None else f"alias {j.alias}"
        return ", ".join(
            f"{j.name} (slave {j.slave})" if j.alias is None else f"{j.name} (alias {j.alias})" for j in s.joints
        )

    def on_configure(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Opens the Bus: the line to Op and the cycle thread running, every drive disabled."""
        s = self.settings
        try:
            bus = Bus(
                s.link,
                [j.drive() for j in s.joints],
                period=s.cycle_time,
                priority=s.rt_priority,
                cpu=s.rt_cpu,
                lock_memory=s.rt_lock_memory,
                fault_reaction=s.fault_reaction,
                dc=s.dc,
                dc_shift=s.dc_shift,
            )
        except AXIS_ERRORS as e:
            return self._fail(f"configure: the drives ({self._where()}) on link {s.link!r} did not open: {e}")
        for joint, axis in zip(s.joints, bus.axes, strict=True):
            prefix = "" if not s.joint_namespaces else f"joints.{joint.name}."
            try:
                # The Bus writes 0x6060 as given; set_mode also checks that the mapping carries the mode's target.
                axis.set_mode(joint.mode)
            except AXIS_ERRORS as e:
                bus.close()
                return self._fail(f"parameters {prefix}mode/{prefix}mapping: {e}")
            try:
                axis.set_command_timeout(joint.command_timeout, joint.command_timeout_policy)
            except CommandError as e:
                # Velocity and torque commands then go by SDO, which the cycle thread does not watch.
                self.get_logger().warning(f"parameter {prefix}command_timeout: not watched: {e}")
        for warning in bus.warnings:
            self.get_logger().warning(f"real-time settings (rt.*): {warning}")
        if s.record is not None:
            topics = [(p.topic_name, p.msg_type, p.qos) for p in self._publishing.publishers()]
            topics += [
                (p.topic_name, p.msg_type, p.qos) for p in (self._diagnostics.publisher, self._trajectories.status)
            ]
            topics += [(topic, kind, self._commands.qos) for topic, kind in self._commands.recorded_topics()]
            topics.append((self._trajectories.topic, JointTrajectory, self._commands.qos))
            try:
                self._session.recorder = open_recorder(self, s, topics, self._reliable)
            except (ValueError, OSError) as e:
                bus.close()
                return self._fail(f"parameters record.*: the recorder did not start: {e}")
        with self._session.lock:
            self._session.bus = bus
        modes = ", ".join(sorted({j.mode for j in s.joints}))
        self.get_logger().info(
            f"configured: {self._where()} on {s.link} in Op, cycle {s.cycle_time * 1e3:g} ms, mode {modes}"
        )
        return TransitionCallbackReturn.SUCCESS

    def on_activate(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Arms the configured latches, starts publishing and accepting commands; enables with enable_on_start."""
        bus = self._session.bus
        for joint, axis in zip(self.settings.joints, bus.axes, strict=True):
            for channel, edge in joint.latch_arm:
                try:
                    axis.arm_latch(channel, edge)
                except AXIS_ERRORS as e:
                    return self._fail(f"parameter latch.arm of {joint.name}: latch {channel}/{edge} not armed: {e}")
        self._diagnostics.restart_counters()
        self._session.active = True
        result = super().on_activate(state)
        if self.settings.enable_on_start:
            ok, message = self._commands.request_all("enable")
            if ok:
                self.get_logger().info(f"enable_on_start: {message}")
            else:
                self.get_logger().error(f"enable_on_start: {message}")
        self.get_logger().info(f"active: publishing /joint_states of {', '.join(bus.names)}, taking commands")
        return result

    def on_deactivate(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Stops publishing and accepting commands and disables the drives."""
        self._session.active = False
        ok, message = self._commands.request_all("disable")
        if not ok:
            self.get_logger().error(f"deactivate: {message}")
        return super().on_deactivate(state)

    def on_cleanup(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Closes the Bus: the drives disabled, the cycle stopped, the line back to Init."""
        self.close()
        return TransitionCallbackReturn.SUCCESS

    def on_shutdown(self, state: LifecycleState) -> TransitionCallbackReturn:
        """As cleanup, from any state."""
        self.close()
        return TransitionCallbackReturn.SUCCESS

    def on_error(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Closes the Bus, so the node is unconfigured and can be configured again."""
        self.close()
        return TransitionCallbackReturn.SUCCESS

    def close(self) -> None:
        """Stops publishing, disables the drives and returns the line to Init (does nothing when not configured)."""
        session = self._session
        session.active = False
        with session.lock:
            bus, session.bus = session.bus, None
        if bus is not None:
            bus.close()
            self.get_logger().info(
                "closed: drives disabled, bus in Init"
                if self.settings.joint_namespaces
                else "closed: drive disabled, bus in Init"
            )
        recorder, session.recorder = session.recorder, None
        if recorder is not None:
            stats = recorder.close()
            self.get_logger().info(
                f"recorded {stats.bag or 'no bag'}: {stats.written} messages, "
                f"{stats.dropped} dropped, {stats.black_box_dumps} black box dumps, "
                f"{stats.errors} errors"
            )
