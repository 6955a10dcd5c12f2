"""akd_node over rclpy (`transport: rclpy` or `both`): the lifecycle node `AkdNode` under a SingleThreadedExecutor,
whose thread takes the commands and runs nothing that waits (see `akd_ros.node.ros_transport`)."""

from __future__ import annotations

import signal
import sys

import rclpy
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.lifecycle import TransitionCallbackReturn
from rclpy.signals import SignalHandlerOptions

from akd_ros.node import hold_gil_briefly
from akd_ros.node.lifecycle import NODE_NAME, AkdNode
from akd_ros.params import ParameterError

_SIGNAL_CHECK_S = 0.1


def run(args: list[str] | None = None) -> int:
    """Runs the node on rclpy until SIGINT/SIGTERM, then disables the drives, returns the bus to Init and exits 0. A
    bad parameter or a failed autostart exits 1 with the reason on stderr."""
    # The signals end spin() here rather than shutting the context down at once, so the drive is disabled and the
    # bus closed while the node can still log it.
    rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
    hold_gil_briefly()
    # SIGINT too: a shell starts background jobs with it ignored, and it must still stop the node cleanly.
    for number in (signal.SIGINT, signal.SIGTERM):
        signal.signal(number, signal.default_int_handler)
    try:
        node = AkdNode(args)
    except ParameterError as e:
        print(f"{NODE_NAME}: error: {e}", file=sys.stderr)
        rclpy.try_shutdown()
        return 1
    executor = SingleThreadedExecutor()
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
