"""akd-zenohd: a Zenoh router, as rmw_zenohd runs one, for akd_node over Zenoh on a machine without ROS.

rmw_zenoh's nodes (and akd_node with transport zenoh, and akd-top --attach zenoh) are peers that find each other
through a router, tcp/localhost:7447 by default. ROS installs bring rmw_zenohd for it; this is the same router made
with eclipse-zenoh (the package akd_ros already uses), with rmw_zenohd's settings: router mode, listening on port
7447 of every address, multicast scouting off, timestamps on (which transient-local topics need); or with a Zenoh
configuration file of its own (`--config`, e.g. the router.json5 `akd-access init --router` writes). It serves until
SIGINT or SIGTERM.
"""

from __future__ import annotations

import json
import sys
import threading
from pathlib import Path

from akd_ros.cli.common import EXIT_FAILURE, run, tool_parser

# rmw_zenoh's DEFAULT_RMW_ZENOH_ROUTER_CONFIG.json5, the settings it changes from Zenoh's own defaults.
DEFAULT_LISTEN = "tcp/[::]:7447"
ROUTER_SETTINGS = {
    "mode": "router",
    "scouting/multicast/enabled": False,
    "timestamping/enabled": {"router": True, "peer": True, "client": True},
}

EXAMPLES = """examples:
  akd-zenohd                              rmw_zenohd's default: port 7447 of every address
  akd-zenohd --listen tcp/127.0.0.1:7447  this machine only
  akd-zenohd --config access/router.json5 a router between machines, with TLS and access control (akd-access)
"""


def router_config(listen: list[str] | None, config_file: Path | None = None):
    """rmw_zenohd's router configuration, or the one in `config_file`, listening on `listen` where given."""
    import zenoh

    if config_file is not None:
        try:
            config = zenoh.Config.from_file(config_file)
        except zenoh.ZError as error:
            # The JSON5 parser's message spans lines (a caret under the place): one line here.
            words = " ".join(str(error).split(" at /", 1)[0].split())
            raise ValueError(f"--config {str(config_file)!r} is not a Zenoh configuration: {words}") from None
    else:
        config = zenoh.Config()
        for key, value in ROUTER_SETTINGS.items():
            config.insert_json5(key, json.dumps(value))
        listen = listen or [DEFAULT_LISTEN]
    if listen:
        try:
            config.insert_json5("listen/endpoints", json.dumps(listen))
        except zenoh.ZError as error:
            raise ValueError(f"--listen {listen!r}: not a list of Zenoh endpoints ({error})") from None
    return config


def main(argv: list[str] | None = None) -> int:
    """Entry point of akd-zenohd."""
    parser = tool_parser("akd-zenohd", __doc__.splitlines()[0], EXAMPLES)
    parser.add_argument(
        "--listen",
        action="append",
        metavar="ENDPOINT",
        help=f"a Zenoh endpoint to listen on, repeatable (default {DEFAULT_LISTEN}, as rmw_zenohd, or the config's)",
    )
    parser.add_argument(
        "--config",
        metavar="FILE",
        type=Path,
        help="a Zenoh configuration file (JSON5) to run with instead of rmw_zenohd's settings",
    )
    args = parser.parse_args(argv)

    def body() -> int:
        import zenoh

        if args.config is not None and not args.config.is_file():
            print(f"akd-zenohd: error: --config {str(args.config)!r} is not a file", file=sys.stderr)
            return EXIT_FAILURE
        config = router_config(args.listen, args.config)
        listen = json.loads(config.get_json("listen/endpoints"))
        if isinstance(listen, dict):
            listen = listen.get("router") or []
        try:
            session = zenoh.open(config)
        except zenoh.ZError as error:
            words = str(error).split(" at /", 1)[0]
            print(f"akd-zenohd: error: cannot listen on {', '.join(listen)}: {words}", file=sys.stderr)
            return EXIT_FAILURE
        print(f"akd-zenohd: Zenoh router {session.info.zid()} listening on {', '.join(listen)}", flush=True)
        try:
            threading.Event().wait()
        except KeyboardInterrupt:
            pass
        finally:
            session.close()
        print("akd-zenohd: stopped", flush=True)
        return 0

    return run("akd-zenohd", body, opens_a_link=False)


if __name__ == "__main__":
    sys.exit(main())
