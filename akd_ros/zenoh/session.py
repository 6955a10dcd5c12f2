"""The Zenoh session of a node on rmw_zenoh's network: configured as rmw_zenoh configures its own by default,
opened, and checked for a router.

rmw_zenoh's nodes are peers that find each other through a router (`rmw_zenohd`, tcp/localhost:7447 by default)
with multicast scouting off, listen on loopback only, and timestamp their samples (which the advanced
publisher's cache for transient-local topics needs). A node that starts before its router warns and keeps
running: Zenoh keeps trying to connect and the node joins the graph once the router is up.
"""

from __future__ import annotations

import json
import time
from collections.abc import Sequence
from pathlib import Path

import zenoh

DEFAULT_ROUTER = "tcp/localhost:7447"
# rmw_zenoh's DEFAULT_RMW_ZENOH_SESSION_CONFIG.json5, the settings it changes from Zenoh's own defaults.
DEFAULT_SETTINGS = {
    "mode": "peer",
    "connect/endpoints": [DEFAULT_ROUTER],
    "listen/endpoints": ["tcp/localhost:0"],
    "scouting/multicast/enabled": False,
    "scouting/gossip/target": {"router": ["router", "peer"], "peer": ["router"]},
    "timestamping/enabled": {"router": True, "peer": True, "client": True},
    "queries_default_timeout": 60000,
}
# How long a new session may take to report its router before the check warns.
ROUTER_CHECK_TIMEOUT = 2.0


class SessionConfigError(ValueError):
    """A session configuration that cannot be used: a missing or unreadable file, a bad endpoint."""


def session_config(config_file: str | Path | None = None, connect: Sequence[str] | None = None) -> zenoh.Config:
    """The session's configuration: rmw_zenoh's default, or the given Zenoh JSON5 file instead (as rmw_zenoh's
    ZENOH_SESSION_CONFIG_URI replaces it), with connect, when given, as the endpoints to connect to."""
    if config_file:
        path = Path(config_file)
        if not path.is_file():
            raise SessionConfigError(f"zenoh.config {str(path)!r} is not a file")
        try:
            config = zenoh.Config.from_file(path)
        except zenoh.ZError as error:
            raise SessionConfigError(f"zenoh.config {str(path)!r} is not a Zenoh configuration: {error}") from None
    else:
        config = zenoh.Config()
        for key, value in DEFAULT_SETTINGS.items():
            config.insert_json5(key, json.dumps(value))
    if connect:
        endpoints = list(connect)
        if bad := [endpoint for endpoint in endpoints if not isinstance(endpoint, str) or "/" not in endpoint]:
            raise SessionConfigError(
                f"zenoh.connect endpoint {bad[0]!r} is not of the form <protocol>/<address>, e.g. {DEFAULT_ROUTER}"
            )
        try:
            config.insert_json5("connect/endpoints", json.dumps(endpoints))
        except zenoh.ZError as error:
            raise SessionConfigError(f"zenoh.connect {endpoints!r} is not a list of Zenoh endpoints: {error}") from None
    return config


def connect_endpoints(config: zenoh.Config) -> list[str]:
    """The endpoints the configuration connects to (a per-mode mapping flattened)."""
    endpoints = json.loads(config.get_json("connect/endpoints"))
    if isinstance(endpoints, dict):
        return [endpoint for listed in endpoints.values() for endpoint in listed]
    return list(endpoints or [])


def open_session(config: zenoh.Config) -> zenoh.Session:
    """Opens the session; it does not wait for a router (Zenoh keeps connecting in the background). A session that
    does not open (an endpoint to listen on that is taken, a certificate that does not load) is a
    SessionConfigError saying why in Zenoh's words, without the places in Zenoh's source they name."""
    try:
        return zenoh.open(config)
    except zenoh.ZError as error:
        words = str(error).split(" at /", 1)[0]
        raise SessionConfigError(f"the Zenoh session does not open: {words}") from None


def router_warning(session: zenoh.Session, config: zenoh.Config, timeout: float = ROUTER_CHECK_TIMEOUT) -> str | None:
    """None once a router is connected to the session (waiting up to timeout), else the warning to log, naming
    the addresses tried."""
    deadline = time.monotonic() + timeout
    while not session.info.routers_zid():
        if time.monotonic() >= deadline:
            endpoints = ", ".join(connect_endpoints(config)) or "no endpoint (zenoh.connect is empty)"
            return (
                f"no Zenoh router reachable at {endpoints}; start one (e.g. `ros2 run rmw_zenoh_cpp rmw_zenohd`) "
                "or set zenoh.connect. The node keeps running and joins the ROS graph once a router is up."
            )
        time.sleep(0.05)
    return None
