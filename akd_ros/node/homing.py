"""Homing: the ~/home action (akd_ros/action/Home) and each joint's homed state, which ~/status, /diagnostics and the
bag carry and which, under homing.required, holds back position commands and trajectories.

A joint with homing.method 'drive' is homed by the drive's own homing (on the AKD the method, speeds and offset of
its HOME.* parameters), run by the cycle thread (`Cycle.start_homing`: into mode 6, bit 4, homing attained with the
motion stopped, back to the joint's mode with the target at the actual position); it stays homed until its drive is
power-cycled or lost, which the cycle thread sees. A joint with homing.method 'none' (an absolute encoder) is homed
from the start. Joints of one goal home together or one after the other (homing.sequence); the feedback gives each
joint's homing state from its statusword (bits 13, 12, 10) and position at 10 Hz, the result each joint's outcome and,
for a failure, its statusword, its drive's error code and why. A cancel halts the homings under way; the drives stay
enabled, still.

A goal succeeds only when it homed every joint it names: a joint it could not start (not in Operation enabled, driven
by a trajectory, homed by another goal's homing), a canceled or failed one makes it fail, whatever the joint's homed
state was before. A goal naming a joint twice, or a joint another goal homes, is refused before anything moves. A node
that closes cancels the homings under way and ends each goal with its result before the bus goes.
"""

from __future__ import annotations

import threading
import time

from akd_ros import _native
from akd_ros.node.node_state import AXIS_ERRORS, NodeState
from akd_ros.node.transports.transport import ActionCallbacks, Transport
from akd_ros.params import JointSettings

HOME = "akd_ros/action/Home"
FEEDBACK_PERIOD_S = 0.1
# How long past its own time-out a homing may take to come back to its mode before the action gives up on it.
_END_MARGIN_S = 5.0


def joint_homed(joint: JointSettings, axis) -> bool:
    """Whether `joint` (its `axis` on a running Bus) is homed: always with homing.method 'none'."""
    return joint.homing_method == "none" or axis.bus.cycle.homing_status(axis.slave)["homed"]


def unhomed_refusal(node_state: NodeState, joints: list[str]) -> str | None:
    """Why a motion of `joints` is refused under homing.required (a sentence naming them), or None; call with the
    node_state's bus running."""
    by_name = {j.name: j for j in node_state.joints}
    bus = node_state.bus
    unhomed = [
        name
        for name in joints
        if name in by_name and by_name[name].homing_required and not joint_homed(by_name[name], bus[name])
    ]
    if not unhomed:
        return None
    return (
        f"{', '.join(unhomed)} {'is' if len(unhomed) == 1 else 'are'} not homed and homing.required is set: home "
        f"{'it' if len(unhomed) == 1 else 'them'} first with the ~/home action"
    )


class Homing:
    """The ~/home action server, its goals run in `group` (which it holds while a goal runs)."""

    def __init__(self, transport: Transport, node_state: NodeState, group) -> None:
        self._node_state, self._logger = node_state, transport.logger
        # The joints the goals executing home: a joint is homed by one goal at a time.
        self._homing: set[str] = set()
        self._homing_lock = threading.Lock()
        # None where the transport serves no action; then nothing here runs.
        self._action = transport.action_server(
            HOME, "~/home", ActionCallbacks(goal=lambda goal: True, execute=self._execute, cancel=lambda h: True), group
        )

    def _execute(self, handle):
        with self._node_state.goals.running():
            try:
                joints = self._claim(list(handle.request.joints))
            except _RefusedError as e:
                handle.abort()
                self._logger.warning(f"~/home: homing refused, nothing moved: {e}")
                return self._action.Result(success=False, message=f"homing refused, nothing moved: {e}")
            try:
                return self._home(handle, joints)
            finally:
                with self._homing_lock:
                    self._homing.difference_update(joints)

    def _claim(self, goal_joints: list[str]) -> list[str]:
        """The joints `goal_joints` names (every joint when none), now this goal's; _RefusedError for a node that is not
        active or closing, an unknown joint, a joint named twice or homed by another goal."""
        node_state = self._node_state
        joints = goal_joints or [j.name for j in node_state.joints]
        known = [j.name for j in node_state.joints]
        unknown = [name for name in joints if name not in known]
        twice = sorted({name for name in joints if joints.count(name) > 1})
        with node_state.lock:
            active = node_state.bus is not None and node_state.active and not node_state.goals.closing
        if not active:
            raise _RefusedError("the node is not active (activate it first)")
        if unknown:
            raise _RefusedError(f"unknown joint {', '.join(unknown)} (joints: {', '.join(known)})")
        if twice:
            raise _RefusedError(f"{', '.join(twice)} named twice; name each joint once")
        with self._homing_lock:
            taken = [name for name in joints if name in self._homing]
            if taken:
                raise _RefusedError(
                    f"{', '.join(taken)} already homed by another goal; cancel it or wait for its result"
                )
            self._homing.update(joints)
        return joints

    def _home(self, handle, joints: list[str]):
        node_state = self._node_state
        bus = node_state.bus
        settings = {j.name: j for j in node_state.joints}
        runs = {name: _Run(settings[name], bus[name]) for name in joints}
        order = [[*joints]] if node_state.settings.homing_sequence == "together" else [[name] for name in joints]
        for batch in order:
            for name in batch:
                runs[name].start()
            self._follow(handle, runs, batch)
            if node_state.settings.homing_sequence == "one_by_one" and not all(runs[n].attained for n in batch):
                break
        for run in runs.values():
            run.finish()
        # Success means every joint named homed by this goal: a joint refused, canceled or failed is not, whatever
        # it was before.
        failed = [f"{name}: {run.outcome}, {run.reason}" for name, run in runs.items() if not run.attained]
        success = not failed
        message = "homed: " + ", ".join(joints) if success else "not homed: " + "; ".join(failed)
        if node_state.goals.closing:
            message = f"the node is shutting down; {message}"
        # Asked before the goal ends: a goal ended canceled no longer reports the request.
        canceled = handle.is_cancel_requested
        if canceled:
            handle.canceled()
        elif success:
            handle.succeed()
        else:
            handle.abort()
        # rclpy's logger takes one severity per call site; a cancel is what the client asked for, no error.
        if success:
            self._logger.info(f"~/home: {message}")
        elif canceled:
            self._logger.info(f"~/home: canceled; {message}")
        else:
            self._logger.error(f"~/home: {message}")
        return self._action.Result(
            success=success,
            message=message,
            joints=joints,
            homed=[runs[n].homed for n in joints],
            outcome=[runs[n].outcome for n in joints],
            statusword=[runs[n].statusword for n in joints],
            error_code=[runs[n].error_code for n in joints],
            reason=[runs[n].reason for n in joints],
        )

    def _follow(self, handle, runs: dict, batch: list[str]) -> None:
        """Publishes feedback until every homing of `batch` ended; cancels them when the goal is canceled or the node
        closes."""
        canceled = False
        while True:
            if (handle.is_cancel_requested or self._node_state.goals.closing) and not canceled:
                canceled = True
                for name in batch:
                    runs[name].cancel()
            # Every joint's status, each polled: the feedback shows each as it is.
            ended = [runs[name].poll() for name in runs]
            handle.publish_feedback(
                self._action.Feedback(
                    joints=list(runs),
                    state=[run.state for run in runs.values()],
                    position=[run.position for run in runs.values()],
                    homed=[run.homed for run in runs.values()],
                )
            )
            if all(done for name, done in zip(runs, ended, strict=True) if name in batch):
                return
            time.sleep(FEEDBACK_PERIOD_S)


class _RefusedError(Exception):
    """A homing goal refused before anything moved."""


class _Run:
    """One joint's homing within a goal."""

    def __init__(self, joint: JointSettings, axis) -> None:
        self.joint, self.axis = joint, axis
        self.state, self.outcome, self.reason = "waiting", "not_run", "an earlier joint's homing failed"
        self.homed = joint_homed(joint, axis)
        self.statusword = self.error_code = 0
        self.position = axis.state().position
        self._request: int | None = None
        self._deadline = 0.0

    @property
    def attained(self) -> bool:
        """Whether this goal homed the joint (homing attained, or homing.method 'none')."""
        return self.outcome == "attained"

    def start(self) -> None:
        if self.joint.homing_method == "none":
            self.outcome, self.reason, self.homed, self.state = "attained", "", True, "attained"
            return
        try:
            self._request = self.axis.bus.cycle.start_homing(self.axis.slave, self.joint.homing_timeout)
        except AXIS_ERRORS as e:
            self.outcome, self.reason = "refused", str(e)
            return
        self._deadline = time.monotonic() + self.joint.homing_timeout + _END_MARGIN_S
        self.outcome, self.reason = "in_progress", ""

    def cancel(self) -> None:
        if self._request is not None:
            self.axis.bus.cycle.cancel_homing(self.axis.slave)

    def poll(self) -> bool:
        """Takes the cycle thread's status; whether this joint's homing is over (or never ran)."""
        self.position = self.axis.state().position
        if self._request is None:
            return True
        status = self.axis.bus.cycle.homing_status(self.axis.slave)
        self.state, self.statusword, self.homed = status["homing_state"], status["statusword"], status["homed"]
        if status["phase"] == "done":
            self.outcome, self.reason = status["outcome"], status["reason"] or ""
            self._request = None
            return True
        if time.monotonic() > self._deadline:
            self.outcome = "timed_out"
            self.reason = f"the cycle thread did not end the homing ({status['phase']}) within its time-out"
            self._request = None
            return True
        return False

    def finish(self) -> None:
        """Reads the drive's error code where it is in Fault, for the result."""
        if any(
            (state := _native.Ds402State.from_statusword(statusword)) is not None and state.is_fault
            for statusword in (self.statusword, self.axis.state().statusword)
        ):
            try:
                self.error_code = self.axis.cycle.drive_error_code(self.axis.slave)
            except AXIS_ERRORS:
                self.error_code = 0
            self.reason += f"; drive in Fault, error code 0x{self.error_code:04X}"
