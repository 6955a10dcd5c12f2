"""`akd_node`: the AKD axes of one EtherCAT line in ROS 2, a lifecycle (managed) node over `akd_ros.Bus`.

One joint (no `joints` parameter: its topics and services under ~/) or a robot of several (`joints`, each with its
block joints.<name>.* and its topics and services under ~/<joint>/). Topics: /joint_states (sensor_msgs/JointState,
SI, every joint of one cycle), /diagnostics (a status per joint and one of the bus), per joint status (DriveStatus),
latch (LatchEvent) and fault (DriveFault) and the commands position_command, velocity_command and torque_command
(std_msgs/Float64, SI); ~/joint_commands (sensor_msgs/JointState by name), ~/joint_trajectory
(trajectory_msgs/JointTrajectory, interpolated by the cycle thread) and ~/trajectory_status (TrajectoryStatus).
Services: ~/enable, ~/disable, ~/reset_fault, ~/quick_stop (std_srvs/Trigger, every joint at once), and per joint the
same four, set_mode, arm_latch, sdo_read and sdo_write (the package's own).

One module per job, each a part that the node's `Core` is made of:

- `core`: `Core`, the parts over a transport and the transitions (configure opens the Bus, close closes it);
- `lifecycle`: `AkdNode`, the rclpy LifecycleNode that runs a Core on rclpy (`ros_transport`);
- `transport`: what the parts need of a middleware (`Transport`, `Qos`);
- `publishing`: /joint_states, each joint's status and its events (latch, fault);
- `diagnostics`: /diagnostics;
- `commands`: the command topics, their refusal and time-out, the automatic fault reset, the drive requests;
- `trajectories`: ~/joint_trajectory and ~/trajectory_status;
- `services`: the services over those requests;
- `recording`: the bag of everything published and received, and of every cycle of every joint (`record.*`);
- `clock`: stamps, the cycle thread's monotonic times moved onto the ROS clock;
- `session`: what the parts share (the settings, the clock; from configure to cleanup the Bus, the Recorder, the
  lock).

Threads: a MultiThreadedExecutor runs three callback groups. The periodic group (publishing timers) and the command
group (the command subscriptions, queued 100 deep so a stall of the Python side delays commands rather than drops
them) never wait on the drive; the request group (services, the supervisor that handles command time-outs and
automatic fault resets) may wait up to the axes' time-outs without stopping the periodic topics. The session's lock
guards the axes' Python-side state (position unwrapping, event queues, the last command) between them.
"""

from __future__ import annotations

import signal
import sys

import rclpy
from rclpy.executors import ExternalShutdownException, MultiThreadedExecutor
from rclpy.lifecycle import TransitionCallbackReturn
from rclpy.signals import SignalHandlerOptions

from akd_ros.node.lifecycle import NODE_NAME, AkdNode
from akd_ros.params import ParameterError

__all__ = ["NODE_NAME", "AkdNode", "main"]

_SIGNAL_CHECK_S = 0.1


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
