"""akd-access: who may use which door of akd_node over Zenoh.

`akd-access init DIR --endpoint tls/HOST:PORT` makes a small certificate authority in DIR, a key and certificate for
the node and for a client of each role (observer, operator, configurer), and the Zenoh configuration of each:
DIR/node.json5 (the node listening on the endpoint with mutual TLS and access control by role; give it to akd_node as
its zenoh.config parameter) and DIR/observer.json5, DIR/operator.json5, DIR/configurer.json5 (clients connecting to
it; an rmw_zenoh node takes one as ZENOH_SESSION_CONFIG_URI). A client without a certificate of this authority
cannot connect. The rules name the node's doors as it declares them (`--params`: the node's parameters file, for the
doors of its joints and devices); the configuration files name the keys and certificates by their absolute paths.
`--router tls/HOST:PORT` puts a router between machines in front of the node: DIR/router.json5 (run it with
`akd-zenohd --config DIR/router.json5`) listens there with the same TLS and rules for the clients, whose
configurations then connect to it.
"""

from __future__ import annotations

import sys
from pathlib import Path

from akd_ros.cli.common import EXIT_FAILURE, run, tool_parser

EXAMPLES = """examples:
  akd-access init access --endpoint tls/127.0.0.1:7448
  akd-access init /etc/akd/access --endpoint tls/192.168.1.10:7448 --params config/akd_6axis.yaml
  akd-access init access --endpoint tls/127.0.0.1:7448 --router tls/192.168.1.10:7450
"""


def main(argv: list[str] | None = None) -> int:
    """Entry point of akd-access."""
    parser = tool_parser("akd-access", __doc__.splitlines()[0], EXAMPLES)
    commands = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    init = commands.add_parser("init", help="make the authority, the certificates and the Zenoh configurations")
    init.add_argument("directory", metavar="DIR", type=Path, help="where to write them (made if missing)")
    init.add_argument("--endpoint", required=True, help="where the node listens: tls/HOST:PORT")
    init.add_argument(
        "--router",
        metavar="ENDPOINT",
        help="where a router in front of the node listens for the clients: tls/HOST:PORT (writes router.json5)",
    )
    init.add_argument("--params", metavar="FILE", help="akd_node's parameters file (default: one joint)")
    init.add_argument("--node-name", default="akd_node", help="the node's name (default akd_node)")
    init.add_argument("--days", type=int, default=None, help="how long the certificates are valid")
    init.add_argument("--force", action="store_true", help="replace an authority already in DIR")
    args = parser.parse_args(argv)

    def body() -> int:
        from akd_ros import access
        from akd_ros.node.interface import declared
        from akd_ros.params import DOOR_ROLES, ParameterError, read_parameters_file, settings

        host = access.endpoint_host(args.endpoint)
        router_host = None if args.router is None else access.endpoint_host(args.router, "--router")
        days = access.VALIDITY_DAYS if args.days is None else args.days
        if days < 1:
            raise ValueError(f"--days must be at least 1, got {days}")
        directory = args.directory.resolve()
        if (directory / "ca.key").exists() and not args.force:
            print(
                f"akd-access: error: {directory} already holds an authority (ca.key); --force replaces it, and every "
                "certificate it signed stops being accepted",
                file=sys.stderr,
            )
            return EXIT_FAILURE
        try:
            values = read_parameters_file(args.params, args.node_name) if args.params else {}
            # Every role's doors, whichever the file opens: a role's rules are there for the day it opens them.
            doors = declared(settings({**values, "doors": list(DOOR_ROLES)}), node_name=args.node_name)
        except ParameterError as error:
            print(f"akd-access: error: {error}", file=sys.stderr)
            return EXIT_FAILURE
        directory.mkdir(parents=True, exist_ok=True)
        access.write_authority(directory, host, days, router_host)
        written = access.write_configs(directory, args.endpoint, doors, args.node_name, args.router)
        for path in written:
            print(f"akd-access: wrote {path}")
        clients = [p.name for p in written if p.stem in access.CLIENTS.values()]
        router = f"; run the router with 'akd-zenohd --config {directory / 'router.json5'}'" if args.router else ""
        print(
            f"akd-access: give akd_node 'transport: zenoh' and 'zenoh.config: {written[0]}'{router}; a client takes "
            f"its role's file ({', '.join(clients)}) as its Zenoh configuration"
        )
        return 0

    return run("akd-access", body, opens_a_link=False)


if __name__ == "__main__":
    sys.exit(main())
