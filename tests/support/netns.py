"""Network namespaces and veth pairs for tests that put EtherCAT frames on a real (virtual) wire.

Every test that uses AF_PACKET gets its own pair of network namespaces joined by a veth pair, so
its frames never reach a host interface and tests can run in parallel. Everything made here is
deleted on exit, also when the test fails. Where the machine does not allow it (not root, no
CAP_SYS_ADMIN, no `ip`), the test is skipped with the reason.

Typical use::

    with veth_pair() as net, akd_sim_in_netns(net.ns_sim, net.if_sim):
        result = run_python_in_netns(net.ns_master, SCRIPT, args=[net.if_master])

or, to open a raw socket of the current process inside the master's namespace::

    with veth_pair() as net, akd_sim_in_netns(net.ns_sim, net.if_sim):
        with entered_netns(net.ns_master):
            master = akd_ros.Master(net.if_master)
"""

from __future__ import annotations

import contextlib
import ctypes
import itertools
import json
import os
import shutil
import signal
import socket
import subprocess
import sys
import time
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

import pytest

ETHERTYPE_ECAT = 0x88A4
_CLONE_NEWNET = 0x40000000
_counter = itertools.count()


@dataclass(frozen=True)
class VethPair:
    """Two namespaces and the two ends of the veth pair between them."""

    ns_master: str
    if_master: str
    ns_sim: str
    if_sim: str


def _ip(*args: str, check: bool = True) -> subprocess.CompletedProcess:
    return subprocess.run(["ip", *args], capture_output=True, text=True, timeout=10, check=check)


def netns_unavailable_reason() -> str | None:
    """Why network namespaces cannot be made here, or None when they can."""
    if shutil.which("ip") is None:
        return "the `ip` command (Debian package iproute2) is not installed"
    probe = f"akd-probe-{os.getpid()}-{next(_counter)}"
    made = _ip("netns", "add", probe, check=False)
    if made.returncode != 0:
        return f"`ip netns add` is not permitted here: {made.stderr.strip()}"
    _ip("netns", "del", probe, check=False)
    return None


def _kill_pids_in(ns: str) -> None:
    """Stops processes the test left in its own namespace, so deleting it frees the veth."""
    listed = _ip("netns", "pids", ns, check=False)
    for pid in listed.stdout.split():
        with contextlib.suppress(ProcessLookupError):
            os.kill(int(pid), signal.SIGKILL)


@contextmanager
def veth_pair(mtu: int = 1500) -> Iterator[VethPair]:
    """Makes two uniquely named namespaces with a veth pair between them, links up, IPv6 off.

    IPv6 is switched off on both ends so that no router solicitations share the wire with the
    EtherCAT frames (they would be filtered by EtherType anyway, but a quiet wire keeps captures
    readable). Skips the calling test when namespaces are not permitted.
    """
    reason = netns_unavailable_reason()
    if reason is not None:
        pytest.skip(reason)
    tag = f"{os.getpid() % 100000}x{next(_counter)}"
    net = VethPair(f"akd-m-{tag}", f"akm{tag}", f"akd-s-{tag}", f"aks{tag}")
    made: list[str] = []
    try:
        for ns in (net.ns_master, net.ns_sim):
            _ip("netns", "add", ns)
            made.append(ns)
            _ip("-n", ns, "link", "set", "lo", "up")
        _ip(
            "link",
            "add",
            net.if_master,
            "netns",
            net.ns_master,
            "mtu",
            str(mtu),
            "type",
            "veth",
            "peer",
            "name",
            net.if_sim,
            "netns",
            net.ns_sim,
            "mtu",
            str(mtu),
        )
        for ns, ifname in ((net.ns_master, net.if_master), (net.ns_sim, net.if_sim)):
            subprocess.run(
                ["ip", "netns", "exec", ns, "sysctl", "-qw", f"net.ipv6.conf.{ifname}.disable_ipv6=1"],
                capture_output=True,
                timeout=10,
                check=False,
            )
            _ip("-n", ns, "link", "set", ifname, "up")
        yield net
    except subprocess.CalledProcessError as error:
        raise RuntimeError(f"could not set up veth pair {net}: {error.stderr.strip()}") from error
    finally:
        for ns in made:
            _kill_pids_in(ns)
            _ip("netns", "del", ns, check=False)


def netns_argv(ns: str, argv: Sequence[str]) -> list[str]:
    """The command line that runs `argv` inside namespace `ns` (same pid: `ip` execs it)."""
    return ["ip", "netns", "exec", ns, *argv]


def run_in_netns(
    ns: str, argv: Sequence[str], timeout: float = 30.0, env: dict | None = None
) -> subprocess.CompletedProcess:
    """Runs a command in `ns` to completion (bounded by `timeout`), capturing text output."""
    return subprocess.run(netns_argv(ns, argv), capture_output=True, text=True, timeout=timeout, env=env, check=False)


def run_python_in_netns(
    ns: str, script: str, args: Sequence[str] = (), timeout: float = 30.0, env: dict | None = None
) -> subprocess.CompletedProcess:
    """Runs a Python script (source text) with this interpreter in `ns`, bounded by `timeout`."""
    return run_in_netns(ns, [sys.executable, "-c", script, *args], timeout=timeout, env=env)


def console_script(name: str) -> list[str]:
    """The argv that starts one of the package's console scripts with this interpreter's install.

    Prefers the installed script next to the interpreter (what a user runs); falls back to the
    module so tests also work from a tree where the scripts were installed elsewhere (colcon puts
    them in lib/akd_ros).
    """
    installed = Path(sys.executable).with_name(name)
    if installed.exists():
        return [str(installed)]
    module = {"akd-sim": "sim", "akd-scan": "scan", "akd-sdo": "sdo", "akd-eoe": "eoe", "akd-foe": "foe"}[name]
    return [sys.executable, "-m", f"akd_ros.cli.{module}"]


def _packet_socket_open(ns: str, ifname: str) -> bool:
    """True when a packet socket for EtherType 0x88A4 is bound to `ifname` in `ns`."""
    listing = run_in_netns(ns, ["cat", "/proc/net/packet"], timeout=5)
    index = run_in_netns(ns, ["cat", f"/sys/class/net/{ifname}/ifindex"], timeout=5).stdout.strip()
    for line in listing.stdout.splitlines()[1:]:
        fields = line.split()
        # sk RefCnt Type Proto Iface R Rmem User Inode
        if len(fields) >= 5 and int(fields[3], 16) == ETHERTYPE_ECAT and fields[4] == index:
            return True
    return False


def udp_port_bound(port: int) -> bool:
    """True when some socket of this namespace is bound to UDP `port` (IPv4)."""
    with open("/proc/net/udp") as table:
        for line in table.readlines()[1:]:
            local = line.split()[1]
            if int(local.split(":")[1], 16) == port:
                return True
    return False


def stop_process(process: subprocess.Popen, timeout: float = 5.0) -> tuple[str, str]:
    """Sends SIGTERM, waits `timeout`, then SIGKILL; returns (stdout, stderr)."""
    if process.poll() is None:
        process.send_signal(signal.SIGTERM)
    try:
        out, err = process.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        process.kill()
        out, err = process.communicate(timeout=timeout)
    return out or "", err or ""


def _wait_until(ready, process: subprocess.Popen, what: str, timeout: float) -> None:
    deadline = time.monotonic() + timeout
    while not ready():
        if process.poll() is not None:
            out, err = process.communicate()
            raise RuntimeError(
                f"{what} exited with status {process.returncode} before it was ready: {err.strip() or out.strip()}"
            )
        if time.monotonic() > deadline:
            stop_process(process)
            raise RuntimeError(f"{what} was not ready within {timeout} s")
        time.sleep(0.05)


SIM_PRIORITY = 40
"""SCHED_FIFO priority of akd-sim's threads where the system permits it. A real AKD has a processor of its own; on a
loaded test host a virtual one descheduled for more than seven cycles would fault with F125 (synchronization lost)
as the real one does when its master falls silent, which is not what the tests are about."""


def realtime(priority: int | None, cpu: int | None = None) -> None:
    """In a child before it executes: SCHED_FIFO at `priority` (unless None) for it and every thread it starts, and
    bound to `cpu` when one is given, each if permitted."""
    if priority is not None:
        with contextlib.suppress(PermissionError, OSError):
            os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(priority))
    if cpu is not None:
        with contextlib.suppress(PermissionError, OSError):
            os.sched_setaffinity(0, {cpu})


@contextmanager
def _serving(
    argv: list[str],
    ready,
    what: str,
    ready_timeout: float,
    cpu: int | None = None,
    priority: int | None = SIM_PRIORITY,
    stdin: bool = False,
) -> Iterator[subprocess.Popen]:
    """Starts a simulator process (under SCHED_FIFO `priority` unless None, and on `cpu` when given, where permitted;
    with its stdin a pipe for commands when `stdin`), yields it once `ready()` holds, stops it with SIGTERM on exit and
    checks it stopped cleanly (status 0). Its output is then in `process.output_text`."""
    process = subprocess.Popen(
        argv,
        stdin=subprocess.PIPE if stdin else None,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        preexec_fn=lambda: realtime(priority, cpu),
    )
    _wait_until(ready, process, what, ready_timeout)
    try:
        yield process
    finally:
        out, err = stop_process(process)
        process.output_text = out
    if process.returncode != 0:
        raise RuntimeError(
            f"{what} did not stop cleanly on SIGTERM (status {process.returncode}): {err.strip() or out.strip()}"
        )


def akd_sim_in_netns(
    ns: str,
    ifname: str,
    count: int = 1,
    ready_timeout: float = 10.0,
    cpu: int | None = None,
    busy_poll: bool = False,
    options: Sequence[str] = (),
    line: str | None = None,
    stdin: bool = False,
):
    """Runs `akd-sim --iface IFNAME --count N` (`--line LINE` where a line is given) in `ns` (context manager yielding
    the process once its packet socket is bound; stopped with SIGTERM on exit), bound to `cpu` when one is given;
    with `busy_poll`, `--busy-poll` under the normal scheduler (which it needs), else SCHED_FIFO; with further akd-sim
    `options`, e.g. ("--missed", "warn"); its stdin a pipe for commands when `stdin`."""
    slaves = ("--line", line) if line else ("--count", str(count))
    argv = netns_argv(
        ns,
        [
            *console_script("akd-sim"),
            *("--iface", ifname, *slaves),
            *(["--busy-poll"] * busy_poll),
            *options,
        ],
    )
    what = f"akd-sim on {ifname} in {ns}"
    priority = None if busy_poll else SIM_PRIORITY
    return _serving(argv, lambda: _packet_socket_open(ns, ifname), what, ready_timeout, cpu, priority, stdin)


def akd_sim_udp(port: int, count: int = 1, host: str = "127.0.0.1", ready_timeout: float = 10.0):
    """Runs `akd-sim --udp HOST:PORT --count N` in this namespace (context manager yielding the
    process once the port is bound; stopped with SIGTERM on exit)."""
    argv = [*console_script("akd-sim"), "--udp", f"{host}:{port}", "--count", str(count)]
    return _serving(argv, lambda: udp_port_bound(port), f"akd-sim on udp {host}:{port}", ready_timeout)


def master_script_report(
    net: VethPair,
    script: str,
    args: Sequence[str],
    count: int = 1,
    timeout: float = 120.0,
    options: Sequence[str] = (),
    line: str | None = None,
) -> dict:
    """Serves `count` virtual AKDs (the slaves `line` names, where given) on the sim end of `net` (with akd-sim
    `options`), runs a third-party master's script (source text) in the master namespace with (interface, *args), and
    returns the JSON report the script printed as its last line; fails the test with the script's output otherwise."""
    with akd_sim_in_netns(net.ns_sim, net.if_sim, count=count, options=options, line=line):
        result = run_python_in_netns(net.ns_master, script, args=[net.if_master, *args], timeout=timeout)
    if result.returncode != 0:
        pytest.fail(f"master script failed (status {result.returncode}):\n{result.stderr}\n{result.stdout}")
    return json.loads(result.stdout.strip().splitlines()[-1])


@contextmanager
def entered_netns(ns: str) -> Iterator[None]:
    """Moves the calling thread into namespace `ns` for the block, then back.

    Sockets opened inside the block stay in `ns` after it ends, so an in-process master can open
    its raw socket on the master's veth end while the test itself keeps running here. Only the
    calling thread moves (setns(2) is per thread).
    """
    libc = ctypes.CDLL(None, use_errno=True)
    with open("/proc/thread-self/ns/net") as home, open(f"/run/netns/{ns}") as target:
        if libc.setns(target.fileno(), _CLONE_NEWNET) != 0:
            errno = ctypes.get_errno()
            pytest.skip(f"setns into {ns} not permitted: {os.strerror(errno)}")
        try:
            yield
        finally:
            if libc.setns(home.fileno(), _CLONE_NEWNET) != 0:
                errno = ctypes.get_errno()
                raise RuntimeError(f"could not return from netns {ns}: {os.strerror(errno)}")


def free_udp_port() -> int:
    """A UDP port on 127.0.0.1 free right now (the kernel picks it)."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]
