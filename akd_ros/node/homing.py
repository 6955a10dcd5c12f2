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
"""

from __future__ import annotations

import time

from akd_ros.node.node_state import AXIS_ERRORS, NodeState
from akd_ros.node.transports.transport import ActionCallbacks, Transport
from akd_ros.params import JointSettings

HOME = "akd_ros/action/Home"
FEEDBACK_PERIOD_S = 0.1
# How long past its own time-out a homing may take to come back to its mode before the action gives up on it.
_END_MARGIN_S = 5.0
_FAULT = 0x0008


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
        # None where the transport serves no action; then nothing here runs.
        self._action = transport.action_server(
            HOME, "~/home", ActionCallbacks(goal=lambda goal: True, execute=self._execute, cancel=lambda h: True), group
        )

    def _execute(self, handle):
        goal_joints = list(handle.request.joints)
        node_state = self._node_state
        with node_state.lock:
            bus = node_state.bus if node_state.active else None
        joints = goal_joints or [j.name for j in node_state.joints]
        unknown = [name for name in joints if name not in {j.name for j in node_state.joints}]
        if bus is None or unknown:
            why = (
                "the node is not active (activate it first)"
                if bus is None
                else f"unknown joint {', '.join(unknown)} (joints: {', '.join(j.name for j in node_state.joints)})"
            )
            handle.abort()
            return self._action.Result(success=False, message=f"homing refused: {why}")
        settings = {j.name: j for j in node_state.joints}
        runs = {name: _Run(settings[name], bus[name]) for name in joints}
        order = [[*joints]] if node_state.settings.homing_sequence == "together" else [[name] for name in joints]
        for batch in order:
            for name in batch:
                runs[name].start()
            self._follow(handle, runs, batch)
            if node_state.settings.homing_sequence == "one_by_one" and not all(runs[n].homed for n in batch):
                break
        for run in runs.values():
            run.finish()
        failed = [f"{name}: {run.outcome}, {run.reason}" for name, run in runs.items() if not run.homed]
        success = not failed
        message = "homed: " + ", ".join(joints) if success else "not homed: " + "; ".join(failed)
        if handle.is_cancel_requested:
            handle.canceled()
        elif success:
            handle.succeed()
        else:
            handle.abort()
        # rclpy's logger takes one severity per call site.
        if success:
            self._logger.info(f"~/home: {message}")
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
        """Publishes feedback until every homing of `batch` ended; cancels them when the goal is canceled."""
        canceled = False
        while True:
            if handle.is_cancel_requested and not canceled:
                canceled = True
                for name in batch:
                    runs[name].cancel()
            ended = all(runs[name].poll() for name in batch)
            handle.publish_feedback(
                self._action.Feedback(
                    joints=list(runs),
                    state=[run.state for run in runs.values()],
                    position=[run.position for run in runs.values()],
                    homed=[run.homed for run in runs.values()],
                )
            )
            if ended:
                return
            time.sleep(FEEDBACK_PERIOD_S)


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
        if self.statusword & _FAULT or self.axis.state().statusword & _FAULT:
            try:
                self.error_code = int.from_bytes(self.axis.sdo_read(0x603F, 0), "little")
            except AXIS_ERRORS:
                self.error_code = 0
            self.reason += f"; drive in Fault, error code 0x{self.error_code:04X}"
