"""akd-top: a live terminal view of a bus's joints (DS402 state, mode, position, velocity, torque, following error, last
fault), its cycle statistics and distributed clocks, and its line (each slave's ports: link, the other end, error
counters, highlighted when they rose, and the worst place said in the cable's words), with keys that enable, disable,
quick-stop, reset or arm a latch of the selected joint, each after a confirmation.

It runs a link itself (LINK: the drives are opened with akd_ros.Bus and its cycle thread, no ROS), or attaches to a
running akd_node (--attach ros over rclpy, --attach zenoh over rmw_zenoh's wire without ROS: its /joint_states,
/diagnostics, status and fault topics and its services, on the ROS domain of the environment). Keys: e enable, d
disable, s quick stop, r reset fault, l arm a latch, q quit; up and down choose the joint. Exit status 0, 1 when the bus
or the node cannot be opened."""

from __future__ import annotations

import sys

from akd_ros.cli.common import LINK_HELP, run, tool_parser

EXAMPLES = """examples:
  akd-top sim:6                       six virtual AKDs run in this process
  akd-top udp://127.0.0.1:34980       the virtual AKDs of akd-sim --udp 127.0.0.1:34980 --count 2
  akd-top enp3s0                      the drives on an interface (needs CAP_NET_RAW)
  akd-top --attach ros                the akd_node running on this ROS domain
  akd-top --attach ros --node /arm/akd_node
  akd-top --attach zenoh --connect tcp/192.168.1.10:7447
"""


def main(argv: list[str] | None = None) -> int:
    """Entry point of akd-top."""
    parser = tool_parser(
        "akd-top",
        "A live terminal view of a bus's joints, with keys to enable, disable, quick-stop and reset them.",
        EXAMPLES,
    )
    parser.add_argument("link", metavar="LINK", nargs="?", help=LINK_HELP + "; not with --attach")
    parser.add_argument(
        "--attach", choices=("ros", "zenoh"), help="attach to a running akd_node over ROS or Zenoh instead of a LINK"
    )
    parser.add_argument("--node", default="/akd_node", help="the node to attach to (default /akd_node)")
    parser.add_argument(
        "--connect",
        action="append",
        metavar="ENDPOINT",
        help="with --attach zenoh: a Zenoh endpoint to connect to (default rmw_zenoh's router, tcp/localhost:7447)",
    )
    parser.add_argument(
        "--period", type=float, default=0.004, metavar="SECONDS", help="cycle time with a LINK (default 0.004 s)"
    )
    parser.add_argument(
        "--priority", type=int, metavar="N", help="with a LINK: the cycle thread under SCHED_FIFO N (where permitted)"
    )
    args = parser.parse_args(argv)
    if (args.link is None) == (args.attach is None):
        parser.error("give either a LINK or --attach ros|zenoh")

    def body() -> int:
        from akd_ros.top.app import Top

        if args.attach == "ros":
            from akd_ros.top.ros_source import RosSource

            source = RosSource(args.node)
        elif args.attach == "zenoh":
            from akd_ros.top.zenoh_source import ZenohSource

            source = ZenohSource(args.node, args.connect)
        else:
            from akd_ros.top.direct import DirectSource

            source = DirectSource(args.link, period=args.period, priority=args.priority)
        try:
            Top(source).run()
        finally:
            source.close()
        return 0

    return run("akd-top", body, opens_a_link=args.link is not None)


if __name__ == "__main__":
    sys.exit(main())
