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
- `lifecycle`: `AkdNode`, the rclpy LifecycleNode that runs a Core on rclpy (`transports.ros_transport`);
- `transports`: what the parts need of a middleware (`transport`: `Transport`, `Qos`) and the middlewares: rclpy
  (`ros_transport`), Zenoh (`zenoh_transport`), both (`both_transport`);
- `publishing`: /joint_states, each joint's status (made by the crate) and its events (latch, fault);
- `diagnostics`: /diagnostics;
- `commands`: the command topics, their refusal and time-out, the automatic fault reset, the drive requests;
- `trajectories`: ~/joint_trajectory and ~/trajectory_status;
- `services`: the services over those requests;
- `recording`: the bag of everything published and received, and of every cycle of every joint (`record.*`);
- `live_view`: everything published, served to Foxglove over its WebSocket protocol, view only (`live_view.*`);
  `foxglove_layout` the Foxglove layout of a node's joints, for it and for the bags;
- `clock`: stamps, the cycle thread's monotonic times moved onto the ROS clock;
- `threads`: the node's Python threads named in the operating system as the crate's are;
- `node_state`: what the parts share (the settings, the clock; from configure to cleanup the Bus, the Recorder, the
  lock).

Threads. The cycle thread and, beside it, the crate's feed (/joint_states and the statuses made from the cycle's
snapshot) and the bag's writer (every cycle's records and what is published, written to the bag) never need Python.
In Python: the publishing thread (`publishing`) hands the feed's messages to the middleware and takes the cycle's
events when the feed says there are some; three callback groups: the periodic group (/diagnostics, the trajectories'
status), the command group (the command subscriptions, queued 100 deep so a stall of the Python side delays commands
rather than drops them) and the request group (services, the supervisor that handles automatic fault resets), which
may wait up to the axes' time-outs. Over rclpy a SingleThreadedExecutor takes every message and runs the command
callbacks itself, while services run on the request group's thread (`transports.worker`) and timers on their group's,
so nothing that waits or takes long is ever in front of a command; over Zenoh each group is such a thread. Every
Python thread gives the GIL up within GIL_SWITCH_INTERVAL_S when another wants it. The node state's lock guards the
axes' Python-side state (position unwrapping, event queues, the last command) between them.
"""

from __future__ import annotations

import sys

__all__ = ["NODE_NAME", "AkdNode", "main"]

NODE_NAME = "akd_node"
"""The node's name, under which its ~/ topics and services are."""
EXAMPLES = """examples:
  akd_node --ros-args --params-file config/akd_sim.yaml
  akd_node --ros-args --params-file config/akd_sim_6axis.yaml -p link:=udp://127.0.0.1:34980
  akd_node --ros-args -p link:=enp3s0 -p mode:=cyclic_synchronous_position -r __ns:=/arm
"""


GIL_SWITCH_INTERVAL_S = 0.0005
"""How long a Python thread of the node runs at most while another waits for the GIL (Python's default is 5 ms): the
thread that takes a command waits no longer than this behind the node's other Python work."""


def hold_gil_briefly() -> None:
    """Sets the interpreter's switch interval to GIL_SWITCH_INTERVAL_S, for the node's process (both runners)."""
    sys.setswitchinterval(GIL_SWITCH_INTERVAL_S)


def __getattr__(name: str):
    # AkdNode is rclpy's; a node on Zenoh alone never imports it.
    if name == "AkdNode":
        from akd_ros.node.lifecycle import AkdNode

        return AkdNode
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def _asked_for_help(arguments: list[str]) -> bool:
    """Prints the node's help when its own arguments (those before --ros-args) ask for it: what it is, the parameters
    file and -p arguments it takes (docs/reference/parameters.md), examples."""
    import argparse

    parser = argparse.ArgumentParser(
        prog=NODE_NAME,
        usage=f"{NODE_NAME} [-h] --ros-args [--params-file FILE] [-p NAME:=VALUE ...] [-r __ns:=NAMESPACE]",
        description="The AKD drives of one EtherCAT line as a ROS 2 lifecycle node. Its parameters come from a\n"
        "parameters file and -p arguments after --ros-args (docs/reference/parameters.md). A bad parameter or a\n"
        "failed start exits 1 with one line on stderr.",
        epilog=EXAMPLES,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    own = arguments[1:]
    own = own[: own.index("--ros-args")] if "--ros-args" in own else own
    if not {"-h", "--help"} & set(own):
        return False
    parser.print_help()
    return True


def main(args: list[str] | None = None) -> int:
    """Entry point of `akd_node`: runs the node on the transport its parameters name (rclpy where it imports, else
    Zenoh) until SIGINT/SIGTERM, then disables the drives, returns the bus to Init and exits 0. A bad parameter or a
    failed start exits 1 with the reason on stderr, one line."""
    from akd_ros import params
    from akd_ros.privilege import warn_if_root

    arguments = sys.argv if args is None else args
    if _asked_for_help(arguments):
        return 0
    warn_if_root(NODE_NAME)
    try:
        given = params.read_arguments(arguments, NODE_NAME)
        transport = params.transport_of(given)
        if transport == "zenoh":
            settings = params.settings({**given, "transport": "zenoh"})
    except params.ParameterError as e:
        print(f"{NODE_NAME}: error: {e}", file=sys.stderr)
        return 1
    if transport == "zenoh":
        from akd_ros.node.zenoh_node import run

        return run(settings)
    try:
        from akd_ros.node.ros_node import run
    except ImportError as e:
        print(
            f"{NODE_NAME}: error: parameter transport {transport!r} needs rclpy, which does not import here ({e}); "
            "use transport zenoh on a machine without ROS",
            file=sys.stderr,
        )
        return 1
    return run(args)


if __name__ == "__main__":
    sys.exit(main())
