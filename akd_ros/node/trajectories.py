"""Trajectories: ~/joint_trajectory (trajectory_msgs/JointTrajectory, as joint_trajectory_controller takes it) played
by the cycle thread, and ~/trajectory_status (TrajectoryStatus) on its progress and outcome.

The cycle thread interpolates the points at the cycle rate (`Bus.play_trajectory`): quintic where accelerations are
given, cubic where velocities are, linear otherwise, from `header.stamp` (zero: on arrival) plus each point's
`time_from_start`. A new trajectory takes over from the set-point in force without a step. An unknown joint, a point
past a joint's position or velocity limit, times that do not increase, NaN, or a joint that is not enabled in
interpolated or cyclic synchronous position refuse the whole trajectory before anything moves: `refused` on
~/trajectory_status, with why, and a warning. Its start and its end (done, replaced, aborted by a fault or a drive
leaving Operation enabled) are published as the cycle thread reports them, its progress at `status_rate` while it
runs."""

from __future__ import annotations

import time

from akd_ros.axis import CommandError
from akd_ros.node.clock import nanoseconds
from akd_ros.node.homing import unhomed_refusal
from akd_ros.node.node_state import NodeState
from akd_ros.node.publishing import RecordedPublisher
from akd_ros.node.transports.transport import Qos, Transport

JOINT_TRAJECTORY = "trajectory_msgs/msg/JointTrajectory"

_ENDED = ("done", "replaced", "aborted", "refused", "stopped")


def _seconds(duration) -> float:
    return duration.sec + duration.nanosec * 1e-9


def ended_before(start_ns: int | None, duration_s: float) -> float | None:
    """How long before now (s) a trajectory of `duration_s` from `start_ns` (monotonic; None: now) ended, or None
    while it has not: such a one is refused whatever the door, as joint_trajectory_controller refuses it."""
    now_ns = time.monotonic_ns()
    if start_ns is None or start_ns + round(duration_s * 1e9) >= now_ns:
        return None
    return (now_ns - start_ns) * 1e-9 - duration_s


class Trajectories:
    """The ~/joint_trajectory subscription (in `command_group`) and the ~/trajectory_status publisher, with the timer
    (in `periodic_group`) that publishes the cycle thread's trajectory events and the progress of the one running."""

    def __init__(
        self, transport: Transport, node_state: NodeState, command_group, periodic_group, qos: Qos, events: Qos
    ):
        self._node_state, self._clock = node_state, node_state.clock
        self._logger = transport.logger
        self._header = transport.message_class("std_msgs/msg/Header")
        self._trajectory_status = transport.message_class("akd_ros/msg/TrajectoryStatus")
        self.topic: str = transport.subscription(
            JOINT_TRAJECTORY, "~/joint_trajectory", self._on_trajectory, qos, command_group
        )
        """The trajectory topic's name, for the recorder."""
        self.status = RecordedPublisher(
            transport, "akd_ros/msg/TrajectoryStatus", "~/trajectory_status", events, node_state
        )
        self._joints: dict[int, list[str]] = {}
        self._running: int | None = None
        transport.timer(0.02, self._publish_events, periodic_group)
        transport.timer(1.0 / node_state.settings.status_rate, self._publish_progress, periodic_group)

    def _on_trajectory(self, message) -> None:
        node_state = self._node_state
        recorder = node_state.recorder
        if recorder is not None:
            recorder.write(self.topic, message, self._clock.now_ns())
        joints = list(message.joint_names)
        try:
            times, points = self._points(message, joints)
            stamp_ns = nanoseconds(message.header.stamp)
            # The stamp is ROS time; the cycle thread's clock is monotonic.
            start_ns = None if stamp_ns == 0 else stamp_ns - self._clock.ros_minus_monotonic_ns()
            if start_ns is not None and start_ns < 0:
                raise CommandError(f"header.stamp {stamp_ns} ns is before this machine started; zero means now")
            if (late := ended_before(start_ns, times[-1])) is not None:
                raise CommandError(
                    f"it ends {late:.3f} s before it arrived (header.stamp {stamp_ns} ns plus its last "
                    "time_from_start); stamp 0 means on arrival"
                )
            with node_state.lock:
                bus = node_state.bus_for_request()
                if why := unhomed_refusal(node_state, joints):
                    raise CommandError(why)
                identifier = bus.play_trajectory(joints, times, points, start_ns)
                self._joints[identifier] = joints
        except CommandError as e:
            text = str(e) if str(e).startswith("trajectory refused") else f"trajectory refused: {e}"
            self._logger.warning(f"~/joint_trajectory: {text}")
            self._publish(state="refused", joints=joints, points=len(message.points), message=text)
            return
        self._logger.info(
            f"~/joint_trajectory: trajectory {identifier} of {', '.join(joints)}, {len(points)} points over "
            f"{times[-1]:.3f} s"
        )

    @staticmethod
    def _points(message, joints: list[str]):
        """(times in s, points of (position, velocity, acceleration) per joint); CommandError for a malformed one."""
        if not joints:
            raise CommandError("joint_names is empty")
        if not message.points:
            raise CommandError("it has no points")
        times, points = [], []
        for k, point in enumerate(message.points):
            if len(point.positions) != len(joints):
                raise CommandError(
                    f"point {k} has {len(point.positions)} positions for {len(joints)} joint_names; every point needs "
                    "one position per joint"
                )
            for field in ("velocities", "accelerations"):
                count = len(getattr(point, field))
                if count not in (0, len(joints)):
                    raise CommandError(
                        f"point {k} has {count} {field} for {len(joints)} joint_names; give none or one per joint"
                    )
            if len(point.accelerations) and not len(point.velocities):
                raise CommandError(f"point {k} has accelerations without velocities; a quintic needs both")
            velocities = list(point.velocities) or [None] * len(joints)
            accelerations = list(point.accelerations) or [None] * len(joints)
            time_from_start = _seconds(point.time_from_start)
            if time_from_start < 0:
                raise CommandError(
                    f"point {k}'s time_from_start is {time_from_start:g} s; times from the start increase from above "
                    "0 s"
                )
            times.append(time_from_start)
            points.append(
                [
                    (float(p), None if v is None else float(v), None if a is None else float(a))
                    for p, v, a in zip(point.positions, velocities, accelerations, strict=True)
                ]
            )
        return times, points

    def _publish(self, **fields) -> None:
        self.status.publish(self._trajectory_status(header=self._header(stamp=self._clock.stamp()), **fields))

    def _status_fields(self, status: dict, bus) -> dict:
        identifier = status["id"]
        text = ""
        if status["state"] == "aborted":
            joint = next((a.name for a in bus.axes if a.slave == status["slave"]), f"slave {status['slave']}")
            text = f"aborted: the drive of {joint} left Operation enabled ({status['ds402_state']})"
        elif status["state"] == "replaced":
            text = f"replaced by trajectory {status['replaced_by']}"
        elif status["state"] == "refused":
            text = f"refused when it was to start, nothing moved: {status['reason']}"
        return {
            "id": identifier,
            "state": status["state"],
            "joints": self._joints.get(identifier, []),
            "point": status["point"],
            "points": status["points"],
            "elapsed": status["elapsed_ns"] * 1e-9,
            "duration": status["duration_ns"] * 1e-9,
            "replaced_by": status["replaced_by"] or 0,
            "message": text,
        }

    def _publish_events(self) -> None:
        node_state = self._node_state
        with node_state.lock:
            bus = node_state.bus
            if bus is None or not node_state.active:
                return
            statuses = []
            for event in bus.trajectory_events():
                status = bus.cycle.trajectory_status(event["id"])
                # The event's own state: the status may already be a later one.
                statuses.append({**status, **{k: event[k] for k in ("state", "replaced_by", "slave", "ds402_state")}})
        for status in statuses:
            fields = self._status_fields(status, bus)
            if status["state"] == "running":
                self._running = status["id"]
            elif status["state"] in _ENDED:
                if self._running == status["id"]:
                    self._running = None
                self._joints.pop(status["id"], None)
                if status["state"] in ("aborted", "refused"):
                    self._logger.error(f"trajectory {status['id']} {fields['message']}")
            self._publish(**fields)

    def _publish_progress(self) -> None:
        node_state = self._node_state
        with node_state.lock:
            bus = node_state.bus
            if bus is None or not node_state.active or self._running is None:
                return
            status = bus.cycle.trajectory_status(self._running)
        if status["state"] == "running":
            self._publish(**self._status_fields(status, bus))
