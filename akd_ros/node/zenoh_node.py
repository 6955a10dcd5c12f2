"""akd_node with `transport: zenoh`: the node's Core on a Zenoh session in rmw_zenoh's wire format, with no ROS
install at all (no rclpy, no ROS wheels).

The parameters come from the same command line (`--ros-args --params-file FILE -p NAME:=VALUE`), read with PyYAML as
rcl reads them (`akd_ros.params.read_arguments`). The session is rmw_zenoh's default (peer mode, a router at
tcp/localhost:7447, multicast scouting off) unless `zenoh.config` or `zenoh.connect` say otherwise; without a router
the node warns, naming the address, and runs on. The node always walks itself to active (there is no lifecycle
service without rclpy); SIGINT or SIGTERM disables the drives, returns the bus to Init and exits 0.
"""

from __future__ import annotations

import datetime
import os
import signal
import sys
import threading
import time

from akd_ros.node.core import NODE_NAME, Core
from akd_ros.node.threads import hold_gil_briefly
from akd_ros.params import ParameterError, Settings

_LEVELS = {"info": "INFO", "warning": "WARN", "error": "ERROR"}


class Logger:
    """Log lines as rclpy's console logger writes them (`[LEVEL] [seconds] [akd_node]: text`), on stderr."""

    def __init__(self, name: str) -> None:
        self._name = name
        self._lock = threading.Lock()

    def _log(self, level: str, text: str) -> None:
        with self._lock:
            print(f"[{_LEVELS[level]}] [{time.time():.9f}] [{self._name}]: {text}", file=sys.stderr, flush=True)

    def info(self, text: str) -> None:
        self._log("info", text)

    def warning(self, text: str) -> None:
        self._log("warning", text)

    def error(self, text: str) -> None:
        self._log("error", text)


def domain_id() -> int:
    """ROS_DOMAIN_ID as rmw_zenoh reads it (0 when unset); ValueError naming it otherwise."""
    text = os.environ.get("ROS_DOMAIN_ID", "") or "0"
    if not text.isdigit() or not 0 <= int(text) <= 232:
        raise ValueError(f"ROS_DOMAIN_ID {text!r} is not a domain id (0..232)")
    return int(text)


def open_zenoh(settings: Settings, logger):
    """The session (`zenoh.config`, `zenoh.connect` or rmw_zenoh's default) and the node's ZenohNode on it, the
    router's absence warned about through `logger`; the caller closes both. ParameterError where the session does
    not open."""
    from akd_ros.zenoh.entities import ZenohNode
    from akd_ros.zenoh.session import SessionConfigError, open_session, router_warning, session_config
    from akd_ros.zenoh.types import Types

    try:
        config = session_config(settings.zenoh_config, settings.zenoh_connect)
        session = open_session(config)
    except SessionConfigError as error:
        raise ParameterError(f"parameters zenoh.config/zenoh.connect: {error}") from None
    try:
        warning = router_warning(session, config)
        if warning:
            logger.warning(warning)
        zenoh_node = ZenohNode(session, Types(), NODE_NAME, domain=domain_id(), log=logger.warning)
    except BaseException:
        session.close()
        raise
    logger.info(f"on Zenoh as session {zenoh_node.zid}, domain {zenoh_node.info.domain}")
    return session, zenoh_node


def run(settings: Settings) -> int:
    """Runs the node on Zenoh until SIGINT/SIGTERM; its exit status (1 when configure or activate failed)."""
    from akd_ros.node.transports.zenoh_transport import ZenohTransport

    hold_gil_briefly()
    logger = Logger(NODE_NAME)
    stop = threading.Event()
    for number in (signal.SIGINT, signal.SIGTERM):
        signal.signal(number, lambda *_: stop.set())
    try:
        session, zenoh_node = open_zenoh(settings, logger)
    except ParameterError as error:
        print(f"{NODE_NAME}: error: {error}", file=sys.stderr)
        return 1
    status = 0
    try:
        transport = ZenohTransport(zenoh_node, logger)
        core = Core(transport, settings)
        transport.start()
        try:
            if not (core.configure() and core.activate()):
                print(f"{NODE_NAME}: error: {core.failure}", file=sys.stderr)
                status = 1
            while status == 0 and not stop.wait(0.1):
                pass
        finally:
            core.close()
            transport.close()
            zenoh_node.close()
    finally:
        session.close()
    logger.info(f"stopped at {datetime.datetime.now().isoformat(timespec='seconds')}")
    return status
