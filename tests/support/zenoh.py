"""A Zenoh router for the tests, in a process of its own as rmw_zenohd would be, on a loopback TCP port the test
picks, multicast scouting off so that nothing outside the test joins; and sessions connected to it.

The router is akd-zenohd (eclipse-zenoh in router mode, rmw_zenohd's settings), ended by its owner's teardown with
SIGINT; every wait is bounded.
"""

from __future__ import annotations

import signal
import socket
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import zenoh

from akd_ros.zenoh.session import open_session, session_config

# A bound on every wait, not a timing expectation.
WAIT_S = 20.0
AKD_ZENOHD = Path(sys.executable).with_name("akd-zenohd")


def free_tcp_port() -> int:
    """A TCP port on 127.0.0.1 that was free a moment ago."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


def _listening(port: int) -> bool:
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as probe:
        return probe.connect_ex(("127.0.0.1", port)) == 0


@contextmanager
def zenoh_router(port: int | None = None, config: Path | None = None) -> Iterator[str]:
    """A running router; yields its endpoint (tcp/127.0.0.1:<port>). With `config` (a configuration file listening
    with TLS on `port` of 127.0.0.1), the router runs with it: tls/127.0.0.1:<port>."""
    port = port or free_tcp_port()
    endpoint = f"{'tcp' if config is None else 'tls'}/127.0.0.1:{port}"
    arguments = ["--listen", endpoint] if config is None else ["--config", str(config)]
    # The router's log goes to a file, which a chatty router cannot fill up as it could a pipe.
    with tempfile.TemporaryFile(mode="w+") as log:
        process = subprocess.Popen([str(AKD_ZENOHD), *arguments], stdout=log, stderr=log, text=True)
        try:
            deadline = time.monotonic() + WAIT_S
            while not _listening(port):
                if process.poll() is not None:
                    log.seek(0)
                    raise AssertionError(f"the Zenoh router exited with {process.returncode}: {log.read()}")
                assert time.monotonic() < deadline, f"the Zenoh router did not listen on {endpoint} in {WAIT_S} s"
                time.sleep(0.05)
            yield endpoint
        finally:
            process.send_signal(signal.SIGINT)
            try:
                process.wait(timeout=5)
            except subprocess.TimeoutExpired:
                process.kill()
                process.wait(timeout=5)


@contextmanager
def zenoh_session(endpoint: str) -> Iterator[zenoh.Session]:
    """A session configured as rmw_zenoh's default but connecting to endpoint, connected to its router."""
    session = open_session(session_config(connect=[endpoint]))
    try:
        deadline = time.monotonic() + WAIT_S
        while not session.info.routers_zid():
            assert time.monotonic() < deadline, f"no router connected to the session at {endpoint} in {WAIT_S} s"
            time.sleep(0.02)
        yield session
    finally:
        session.close()


def liveliness_keys(session: zenoh.Session, domain: int = 0) -> list[str]:
    """Every liveliness token of the domain the router knows, as rmw_zenoh's graph cache reads them at start."""
    return sorted(str(reply.ok.key_expr) for reply in session.liveliness().get(f"@ros2_lv/{domain}/**", timeout=5))
