"""`akd_node`'s command line: its help, its parameters read as rcl reads them, and the runner its transport needs
(`akd_ros.node.ros_node` over rclpy, `akd_ros.node.zenoh_node` on Zenoh alone)."""

from __future__ import annotations

import sys

from akd_ros.node.node_state import NODE_NAME

EXAMPLES = """examples:
  akd_node --ros-args --params-file config/akd_sim.yaml
  akd_node --ros-args --params-file config/akd_sim_6axis.yaml -p link:=udp://127.0.0.1:34980
  akd_node --ros-args -p link:=enp3s0 -p mode:=cyclic_synchronous_position -r __ns:=/arm
"""


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
