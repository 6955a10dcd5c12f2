"""~/follow_joint_trajectory (control_msgs/action/FollowJointTrajectory), the action MoveIt's simple controller manager
and motion scripts speak: the second door to the cycle thread's trajectories (the first is ~/joint_trajectory,
`akd_ros.node.trajectories`), played by the same interpolation, judged there every cycle.

A goal is checked whole before anything moves; a bad one ends ABORTED with control_msgs' error_code (INVALID_JOINTS for
an unknown joint, OLD_HEADER_TIMESTAMP for a trajectory over before it arrived, INVALID_GOAL for the rest: no points,
times that are negative or do not increase, NaN, a point or the path between points past a joint's limits (position,
limits.max_velocity, limits.max_acceleration, judged by the crate on the interpolated path), a joint not enabled in a
position mode, being homed, or not homed where homing.required, a bad tolerance) and an error_string saying why.
Tolerances per joint: a goal's value above 0 is used, 0 takes the joint's constraints.* parameter, -1 means not judged
(as control_msgs says); NaN and other negative values are refused; accelerations are not judged (the drive reports
none). The cycle thread ends the trajectory: done (SUCCEEDED), past a path tolerance (PATH_TOLERANCE_VIOLATED, after
braking the joints to a standstill), outside the goal tolerance after the goal time (GOAL_TOLERANCE_VIOLATED), a drive
leaving Operation enabled, also before the trajectory's start (ABORTED, PATH_TOLERANCE_VIOLATED: the path cannot be
followed, naming the joint), replaced by a newer goal or trajectory (ABORTED, INVALID_GOAL, as
joint_trajectory_controller answers a preempted goal; the newer one took over from the set-point in force without a
step), refused when it was to start because from the set-points then in force a joint would go past its limits, or a
joint of the trajectory in force that it does not drive was still moving (ABORTED, INVALID_GOAL, nothing moved). A
cancel brakes every joint from its set-point at its trajectory.stop_deceleration, then CANCELED; a goal still waiting
for its start ends CANCELED at once. A node that closes brakes every goal's joints and ends it ABORTED before its bus
goes. Feedback (desired, actual, error of each joint, the desired being the set-point the actual values follow) at
follow_joint_trajectory.feedback_rate.
"""

from __future__ import annotations

import math
import time

from akd_ros.axis import CommandError
from akd_ros.node.clock import nanoseconds
from akd_ros.node.homing import unhomed_refusal
from akd_ros.node.node_state import AXIS_ERRORS, NodeState
from akd_ros.node.trajectories import Trajectories, ended_before
from akd_ros.node.transports.transport import ActionCallbacks, Transport

FOLLOW_JOINT_TRAJECTORY = "control_msgs/action/FollowJointTrajectory"
# How long past its end plus goal time a trajectory may take to be reported over before the goal gives up on it.
_END_MARGIN_S = 5.0
# control_msgs' INVALID_GOAL, for the tolerances checked before the action's class is at hand.
_INVALID_GOAL = -1


class _RefusedError(Exception):
    """A goal refused before anything moved: control_msgs' error_code and why."""

    def __init__(self, code: int, text: str):
        super().__init__(text)
        self.code = code


def _tolerance(given: float, default: float, what: str) -> float:
    """A goal's tolerance `what` (> 0: it; 0: `default`, itself not judged where 0; -1: not judged, as control_msgs
    says) as the cycle thread takes it (inf: not judged); _RefusedError for NaN or another negative value."""
    if math.isnan(given) or (given < 0 and given != -1):
        raise _RefusedError(_INVALID_GOAL, f"{what} {given}; allowed > 0, 0 (the joint's default) or -1 (not judged)")
    value = default if given == 0 else given
    return math.inf if value <= 0 or not math.isfinite(value) else value


class FollowJointTrajectory:
    """The ~/follow_joint_trajectory action server; each goal's execution polls the cycle thread in `group`."""

    def __init__(self, transport: Transport, node_state: NodeState, group) -> None:
        self._node_state, self._logger = node_state, transport.logger
        self._point = transport.message_class("trajectory_msgs/msg/JointTrajectoryPoint")
        self._header = transport.message_class("std_msgs/msg/Header")
        # None where the transport serves no action; then nothing here runs.
        self._action = transport.action_server(
            FOLLOW_JOINT_TRAJECTORY,
            "~/follow_joint_trajectory",
            ActionCallbacks(goal=lambda goal: True, execute=self._execute, cancel=lambda handle: True),
            group,
        )

    def _execute(self, handle):
        with self._node_state.goals.running():
            try:
                identifier, joints, axes, end_s = self._start(handle.request)
            except _RefusedError as e:
                self._logger.warning(f"~/follow_joint_trajectory: goal refused, nothing moved: {e}")
                handle.abort()
                return self._action.Result(error_code=e.code, error_string=f"goal refused, nothing moved: {e}")
            self._logger.info(f"~/follow_joint_trajectory: trajectory {identifier} of {', '.join(joints)}")
            try:
                return self._follow(handle, identifier, joints, axes, end_s)
            except (CommandError, *AXIS_ERRORS) as e:
                # The bus went away under the goal (a cleanup): its trajectory went with it.
                text = f"aborted: the trajectory could no longer be followed: {e}"
                self._logger.error(f"~/follow_joint_trajectory: trajectory {identifier}: {text}")
                handle.abort()
                return self._action.Result(error_code=self._action.Result.PATH_TOLERANCE_VIOLATED, error_string=text)

    def _start(self, goal):
        """Checks `goal` whole and hands its trajectory to the cycle thread: (id, joints, axes, the monotonic time in s
        by which it must have ended); _RefusedError where it cannot be followed."""
        codes, node_state = self._action.Result, self._node_state
        trajectory = goal.trajectory
        joints = list(trajectory.joint_names)
        if goal.multi_dof_trajectory.joint_names:
            raise _RefusedError(codes.INVALID_JOINTS, "multi_dof_trajectory names joints; akd_node drives none")
        by_name = {j.name: j for j in node_state.joints}
        unknown = [name for name in joints if name not in by_name]
        if unknown or not joints:
            what = f"unknown joint {', '.join(unknown)}" if unknown else "trajectory.joint_names is empty"
            raise _RefusedError(codes.INVALID_JOINTS, f"{what} (joints: {', '.join(by_name)})")
        for field in ("path_tolerance", "goal_tolerance"):
            stray = [t.name for t in getattr(goal, field) if t.name not in joints]
            if stray:
                text = f"{field} names {', '.join(stray)}, not a joint of the trajectory ({', '.join(joints)})"
                raise _RefusedError(codes.INVALID_JOINTS, text)
        try:
            times, points = Trajectories._points(trajectory, joints)
        except CommandError as e:
            raise _RefusedError(codes.INVALID_GOAL, str(e)) from None
        tolerances = self._tolerances(goal, [by_name[name] for name in joints])
        given_goal_time = goal.goal_time_tolerance.sec + goal.goal_time_tolerance.nanosec * 1e-9
        if given_goal_time < 0:
            raise _RefusedError(
                codes.INVALID_GOAL,
                f"goal_time_tolerance {given_goal_time:g} s; allowed >= 0 s (0: constraints.goal_time)",
            )
        goal_time = given_goal_time or node_state.settings.constraints_goal_time
        clock = node_state.clock
        stamp_ns = nanoseconds(trajectory.header.stamp)
        start_ns = None if stamp_ns == 0 else stamp_ns - clock.ros_minus_monotonic_ns()
        if (late := ended_before(start_ns, times[-1])) is not None:
            raise _RefusedError(
                codes.OLD_HEADER_TIMESTAMP,
                f"the trajectory ends {late:.3f} s before it arrived (header.stamp {stamp_ns} ns plus its last "
                "time_from_start); stamp 0 means on arrival",
            )
        now_ns = time.monotonic_ns()
        end_s = (max(start_ns or now_ns, now_ns) * 1e-9) + times[-1] + goal_time + _END_MARGIN_S
        try:
            with node_state.lock:
                bus = node_state.bus_for_request()
                if node_state.goals.closing:
                    raise CommandError("the node is shutting down")
                if why := unhomed_refusal(node_state, joints):
                    raise CommandError(why)
                identifier = bus.play_trajectory(joints, times, points, start_ns, tolerances, goal_time)
                axes = [bus[name] for name in joints]
        except (CommandError, *AXIS_ERRORS) as e:
            text = str(e).removeprefix("trajectory refused, nothing moved: ").removeprefix("trajectory refused: ")
            raise _RefusedError(codes.INVALID_GOAL, text) from None
        return identifier, joints, axes, end_s

    @staticmethod
    def _tolerances(goal, joints) -> list[tuple[float, float, float, float, float]]:
        """Per joint (path position, path velocity, goal position, goal velocity, stop deceleration) in SI."""
        path = {t.name: t for t in goal.path_tolerance}
        at_goal = {t.name: t for t in goal.goal_tolerance}
        result = []
        for joint in joints:
            p, g = path.get(joint.name), at_goal.get(joint.name)
            name = joint.name
            result.append(
                (
                    _tolerance(
                        p.position if p else 0.0, joint.constraints_trajectory, f"path_tolerance of {name}: position"
                    ),
                    _tolerance(p.velocity if p else 0.0, 0.0, f"path_tolerance of {name}: velocity"),
                    _tolerance(g.position if g else 0.0, joint.constraints_goal, f"goal_tolerance of {name}: position"),
                    _tolerance(
                        g.velocity if g else 0.0,
                        joint.constraints_stopped_velocity_tolerance,
                        f"goal_tolerance of {name}: velocity",
                    ),
                    joint.trajectory_stop_deceleration,
                )
            )
        return result

    def _follow(self, handle, identifier: int, joints: list[str], axes, end_s: float):
        """Publishes feedback until the cycle thread ends trajectory `identifier`; stops it on a cancel."""
        node_state = self._node_state
        period = 1.0 / node_state.settings.follow_joint_trajectory_feedback_rate
        stopping = False
        while True:
            if (handle.is_cancel_requested or node_state.goals.closing) and not stopping:
                stopping = True
                axes[0].bus.cycle.stop_trajectory(identifier)
            with node_state.lock:
                cycle = axes[0].bus.cycle
                status = cycle.trajectory_status(identifier)
                followed = [cycle.trajectory_followed(axis.slave) for axis in axes]
            if status["state"] not in ("pending", "running"):
                break
            if all(f is not None for f in followed):
                handle.publish_feedback(self._feedback(joints, axes, followed))
            if time.monotonic() > end_s and not stopping:
                stopping = True
                axes[0].bus.cycle.stop_trajectory(identifier)
            time.sleep(period)
        return self._result(handle, status, joints, axes, stopping)

    def _feedback(self, joints, axes, followed):
        desired, actual, error = self._point(), self._point(), self._point()
        for axis, (p, v, ap, av) in zip(axes, followed, strict=True):
            to_position, to_velocity = axis.units.position_to_si, axis.units.velocity_to_si
            sample = (to_position(p), to_velocity(v), to_position(ap), to_velocity(av))
            desired.positions.append(sample[0])
            desired.velocities.append(sample[1])
            actual.positions.append(sample[2])
            actual.velocities.append(sample[3])
            error.positions.append(sample[0] - sample[2])
            error.velocities.append(sample[1] - sample[3])
        header = self._header(stamp=self._node_state.clock.stamp())
        return self._action.Feedback(header=header, joint_names=joints, desired=desired, actual=actual, error=error)

    def _result(self, handle, status: dict, joints, axes, stopping: bool):
        """Ends the goal as the cycle thread ended its trajectory."""
        codes, state = self._action.Result, status["state"]
        by_slave = {axis.slave: axis for axis in axes}
        axis = by_slave.get(status.get("slave"))
        name = axis.name if axis is not None else f"slave {status.get('slave')}"
        code, text = codes.SUCCESSFUL, ""
        if state == "done":
            handle.succeed()
        elif state == "stopped" and handle.is_cancel_requested:
            text = "canceled: the joints were brought to a standstill"
            handle.canceled()
        else:
            if state == "stopped" and self._node_state.goals.closing:
                code = codes.PATH_TOLERANCE_VIOLATED
                text = "aborted: the node is shutting down; the joints were brought to a standstill"
            elif state == "stopped":
                code = codes.GOAL_TOLERANCE_VIOLATED
                text = "the trajectory did not end in time; the joints were stopped"
            elif state in ("path_tolerance_violated", "goal_tolerance_violated"):
                kind, unit = ("velocity", axis.units.position_unit + "/s") if status["velocity"] else ("position", "")
                unit = unit or axis.units.position_unit
                error = abs(status["error"] * axis.units.si_per_count)
                if state == "path_tolerance_violated":
                    code = codes.PATH_TOLERANCE_VIOLATED
                    text = (
                        f"{name}'s {kind} strayed {error:.6g} {unit} from its set-point, past its path tolerance; the "
                        "joints were brought to a standstill"
                    )
                else:
                    code = codes.GOAL_TOLERANCE_VIOLATED
                    text = (
                        f"{name}'s {kind} was {error:.6g} {unit} from the goal at the end of the goal time tolerance, "
                        "past its goal tolerance"
                    )
            elif state == "aborted":
                code = codes.PATH_TOLERANCE_VIOLATED
                text = f"aborted: the drive of {name} left Operation enabled ({status['ds402_state']}); the others hold"
            elif state == "replaced":
                # As joint_trajectory_controller answers a goal a newer one preempted.
                code = codes.INVALID_GOAL
                text = f"preempted: trajectory {status['replaced_by']} took over from the set-point in force"
            elif state == "refused":
                code = codes.INVALID_GOAL
                text = f"refused when it was to start, nothing moved: {status['reason']}"
            else:
                code = codes.INVALID_GOAL
                text = f"the trajectory ended {state}"
            handle.abort()
        if code == codes.SUCCESSFUL:
            self._logger.info(f"~/follow_joint_trajectory: trajectory {status['id']} {state}. {text}".rstrip(". "))
        else:
            self._logger.error(f"~/follow_joint_trajectory: trajectory {status['id']}: {text}")
        return self._action.Result(error_code=code, error_string=text)
