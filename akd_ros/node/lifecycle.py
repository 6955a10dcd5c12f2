"""The lifecycle (managed) node over rclpy: `AkdNode`, a LifecycleNode that runs a `Core` on a `RosTransport`.

configure opens the Bus (the line to Op, the one cycle thread running, every joint's drive disabled); activate arms
the configured latches and starts publishing and accepting commands; deactivate disables the drives; cleanup and
shutdown close the Bus (drives disabled, line back to Init). With `autostart` the node walks itself to active at
start-up (see `akd_ros.node.ros_node`), and with `enable_on_start` it then enables every joint's power stage.
"""

from __future__ import annotations

import sys
import threading
import time

from rclpy.lifecycle import LifecycleNode, LifecycleState, TransitionCallbackReturn

from akd_ros.bus import Bus
from akd_ros.node.core import NODE_NAME, Core
from akd_ros.node.ros_parameters import declare
from akd_ros.node.transports.ros_transport import RosTransport
from akd_ros.params import Settings
from akd_ros.recorder import Recorder

__all__ = ["NODE_NAME", "AkdNode"]

# How long the executor spins, once the goals ended, for their results to go out.
_RESULTS_SENT_S = 0.3


def _outcome(done: bool) -> TransitionCallbackReturn:
    return TransitionCallbackReturn.SUCCESS if done else TransitionCallbackReturn.FAILURE


class AkdNode(LifecycleNode):
    """The lifecycle node of a bus of AKD joints (see `akd_ros.node`); parameters are checked on construction and a
    bad one raises `akd_ros.params.ParameterError`."""

    def __init__(self, args: list[str] | None = None, **kwargs) -> None:
        """`args` is the command line rclpy.init was given (None: sys.argv, as rclpy.init takes it); kwargs go to
        rclpy's Node."""
        super().__init__(NODE_NAME, **kwargs)
        arguments = [*(sys.argv if args is None else args), *(kwargs.get("cli_args") or [])]
        self.settings: Settings = declare(self, arguments, kwargs.get("parameter_overrides") or [])
        self._zenoh = None
        if self.settings.transport == "both":
            from akd_ros.node.transports.both_transport import BothTransport
            from akd_ros.node.transports.zenoh_transport import ZenohTransport
            from akd_ros.node.zenoh_node import open_zenoh

            self._zenoh = open_zenoh(self.settings, self.get_logger())
            transport = BothTransport(self, ZenohTransport(self._zenoh[1], self.get_logger()))
        else:
            transport = RosTransport(self)
        self._core = Core(transport, self.settings)
        transport.start()
        self._transport = transport

    @property
    def failure(self) -> str | None:
        """Why the last transition failed, for the log and the exit message."""
        return self._core.failure

    @property
    def bus(self) -> Bus | None:
        """The Bus while configured, else None."""
        return self._core.bus

    @property
    def recorder(self) -> Recorder | None:
        """The Recorder while configured with record.enabled, else None."""
        return self._core.recorder

    def on_configure(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Opens the Bus: the line to Op and the cycle thread running, every drive disabled."""
        return _outcome(self._core.configure())

    def on_activate(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Arms the configured latches, starts publishing and accepting commands; enables with enable_on_start."""
        if not self._core.activate():
            return TransitionCallbackReturn.FAILURE
        return super().on_activate(state)

    def on_deactivate(self, state: LifecycleState) -> TransitionCallbackReturn:
        """Stops publishing and accepting commands and disables the drives."""
        self._core.deactivate()
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
        """Ends the action goals executing, stops publishing, disables the drives and returns the line to Init (does
        nothing when not configured)."""
        self._core.close()

    def end_goals(self, executor) -> None:
        """Ends every action goal executing with its result (`Core.end_goals`) while `executor`, the node's, spins to
        send the results out: for a node that stops, before it closes its bus."""
        ended = threading.Event()
        threading.Thread(target=lambda: (self._core.end_goals(), ended.set()), name="akd-end-goals").start()
        while not ended.is_set():
            executor.spin_once(timeout_sec=0.02)
        # The results go out from tasks the goals' ends made: give them their turns.
        deadline = time.monotonic() + _RESULTS_SENT_S
        while time.monotonic() < deadline:
            executor.spin_once(timeout_sec=0.02)

    def destroy_node(self) -> None:
        """Also stops the timer threads and withdraws the node from Zenoh (transport both)."""
        self._transport.close()
        if self._zenoh is not None:
            session, zenoh_node = self._zenoh
            self._zenoh = None
            zenoh_node.close()
            session.close()
        super().destroy_node()
