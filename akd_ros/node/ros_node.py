"""akd_node over rclpy (`transport: rclpy` or `both`): the lifecycle node `AkdNode` under a SingleThreadedExecutor,
whose thread takes the commands and runs nothing that waits (see `akd_ros.node.transports.ros_transport`).

SIGINT and SIGTERM are taken by a thread of their own (sigwait), which wakes the executor through a guard condition:
the executor's thread wakes for what arrives and for nothing else (a wait bounded for Python's signal handlers to run
cost it ten wake-ups a second, each walking the node's hundred-odd entities)."""

from __future__ import annotations

import signal
import sys
import threading

import rclpy
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.lifecycle import TransitionCallbackReturn
from rclpy.signals import SignalHandlerOptions

from akd_ros.node.lifecycle import NODE_NAME, AkdNode
from akd_ros.node.threads import hold_gil_briefly
from akd_ros.params import ParameterError

_STOP_SIGNALS = {signal.SIGINT, signal.SIGTERM}


def run(args: list[str] | None = None) -> int:
    """Runs the node on rclpy until SIGINT/SIGTERM, then disables the drives, returns the bus to Init and exits 0. A
    bad parameter or a failed autostart exits 1 with the reason on stderr."""
    # The signals end the spin here rather than shutting the context down at once, so the drive is disabled and the
    # bus closed while the node can still log it. SIGINT too: a shell starts background jobs with it ignored, and it
    # must still stop the node cleanly. Blocked before any thread starts, so that every thread (rclpy's, the crate's)
    # leaves them to the one that waits for them.
    for number in _STOP_SIGNALS:
        signal.signal(number, signal.SIG_DFL)
    signal.pthread_sigmask(signal.SIG_BLOCK, _STOP_SIGNALS)
    rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
    hold_gil_briefly()
    try:
        node = AkdNode(args)
    except ParameterError as e:
        print(f"{NODE_NAME}: error: {e}", file=sys.stderr)
        rclpy.try_shutdown()
        return 1
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    stopped = threading.Event()
    wake = node.create_guard_condition(lambda: None)

    def take_signal() -> None:
        signal.sigwait(_STOP_SIGNALS)
        stopped.set()
        wake.trigger()

    threading.Thread(target=take_signal, name="akd-signals", daemon=True).start()
    status = 0
    try:
        if node.settings.autostart:
            for step in (node.trigger_configure, node.trigger_activate):
                if stopped.is_set():
                    break
                if step() != TransitionCallbackReturn.SUCCESS:
                    print(f"{NODE_NAME}: error: {node.failure}", file=sys.stderr)
                    status = 1
                    break
        while status == 0 and not stopped.is_set() and rclpy.ok():
            executor.spin_once()
    except ExternalShutdownException:
        pass
    finally:
        # Every goal executing gets its result while the executor still runs, before the bus goes to Init.
        if rclpy.ok():
            node.end_goals(executor)
        node.close()
        executor.shutdown()
        node.destroy_node()
        rclpy.try_shutdown()
    return status
