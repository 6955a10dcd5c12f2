"""Least privilege: the tools and a Bus on a raw interface as a user that is not root and holds CAP_NET_RAW alone.

The virtual AKD is served by `akd-sim` (as root) on one end of a veth pair; the master runs on the other end as uid
65534 (nobody) through `setpriv`, without any capability, and with CAP_NET_RAW as an ambient capability (as systemd's
AmbientCapabilities= gives it). Without it the tool says in one line which capability is missing and how to grant it;
with it the tool works, and once the socket is open no thread of the process keeps a capability (but CAP_SYS_NICE,
which the cycle thread's SCHED_FIFO priority uses, where it was given). Root gets a one-line warning at start.

The tests as uid 65534 need root (for the namespaces and to start a process as another user): elsewhere they are
skipped. The root warning is checked either way: given as root, not given otherwise.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from collections.abc import Sequence
from pathlib import Path

import pytest

from akd_ros.privilege import ROOT_WARNING
from support.netns import akd_sim_in_netns, console_script, netns_argv, stop_process
from support.ros import node_command

REPO = Path(__file__).resolve().parents[1]
NOBODY = ["setpriv", "--reuid=65534", "--regid=65534", "--clear-groups"]
CAP_NET_RAW = 1 << 13
CAP_SYS_NICE = 1 << 23
CAPABILITY_SETS = ("CapInh", "CapPrm", "CapEff", "CapAmb")

AS_ROOT = os.geteuid() == 0


@pytest.fixture
def as_user() -> None:
    """Skips, saying why, where the test cannot make namespaces and start the master as uid 65534. Taken before
    `veth`, so the reason is this one."""
    if not AS_ROOT:
        pytest.skip("needs root: it makes network namespaces and starts the master as uid 65534 (setpriv)")
    if shutil.which("setpriv") is None or shutil.which("unshare") is None:
        pytest.skip("needs setpriv and unshare (Debian package util-linux)")


def ambient(*capabilities: str) -> list[str]:
    """setpriv options that give the started program `capabilities` (e.g. "net_raw") as ambient ones."""
    given = ",".join(f"+{c}" for c in capabilities)
    return [f"--inh-caps={given}", f"--ambient-caps={given}"]


def hidden_ancestor(path: Path) -> Path | None:
    """The topmost directory above `path` that other users cannot enter (e.g. /root, 0700), if any."""
    for directory in reversed(path.parents):
        if not directory.stat().st_mode & 0o001:
            return directory
    return None


def user_view(holders: Path, prepare: Sequence[str] = ()) -> str:
    """A shell script that, in a mount namespace of its own, lets uid 65534 reach this interpreter, the virtual
    environment and the tree where a user-unreadable directory holds them (pyenv under /root on a CI machine), then
    runs its arguments: each such directory is covered with an empty tmpfs into which just those paths are bound.
    Nothing outside the namespace changes."""
    needed = sorted({Path(p).resolve() for p in (sys.base_prefix, sys.prefix, REPO)})
    lines = ["set -e"]
    covered: dict[Path, list[Path]] = {}
    for path in needed:
        top = hidden_ancestor(path)
        if top is not None:
            covered.setdefault(top, []).append(path)
    for n, (top, paths) in enumerate(covered.items()):
        for m, path in enumerate(paths):
            lines.append(f"mkdir -p {holders}/{n}-{m} && mount --bind {path} {holders}/{n}-{m}")
        lines.append(f"mount -t tmpfs -o mode=0755 akd-user-view {top}")
        for m, path in enumerate(paths):
            lines.append(f"mkdir -p {path} && mount --bind {holders}/{n}-{m} {path}")
    lines += [*prepare, 'exec "$@"']
    return "\n".join(lines)


def as_nobody(
    ns: str, argv: Sequence[str], holders: Path, capabilities: Sequence[str] = (), prepare: Sequence[str] = ()
) -> list[str]:
    """The command line that runs `argv` in network namespace `ns` as uid 65534 with `capabilities` alone (`holders`:
    an empty directory of the test's, where the user's view is put together; `prepare`: shell lines run as root in
    that view first)."""
    view = ["unshare", "--mount", "--propagation", "private", "sh", "-c", user_view(holders, prepare), "user-view"]
    caps = ambient(*capabilities) if capabilities else []
    return netns_argv(ns, [*view, *NOBODY, *caps, *argv])


def run(argv: list[str], timeout: float = 60.0) -> subprocess.CompletedProcess:
    return subprocess.run(argv, capture_output=True, text=True, timeout=timeout, check=False)


def capability_sets(status: str) -> dict[str, int]:
    """The four capability sets of a /proc/<pid>/task/<tid>/status text."""
    fields = dict(line.split(":\t", 1) for line in status.splitlines() if ":\t" in line)
    return {name: int(fields[name], 16) for name in CAPABILITY_SETS}


def capabilities_of_threads(pid: int) -> dict[int, dict[str, int]]:
    """Every thread of process `pid` and its four capability sets, from /proc."""
    return {
        int(task.name): capability_sets((task / "status").read_text()) for task in Path(f"/proc/{pid}/task").iterdir()
    }


def test_scan_without_cap_net_raw_says_which_capability_and_how_to_grant_it(as_user, veth, tmp_path):
    with akd_sim_in_netns(veth.ns_sim, veth.if_sim):
        scan = run(as_nobody(veth.ns_master, [*console_script("akd-scan"), veth.if_master], tmp_path))
    assert scan.returncode == 1, scan.stdout + scan.stderr
    assert scan.stdout == ""
    [line] = scan.stderr.splitlines()
    assert line.startswith(f'akd-scan: error: opening an AF_PACKET socket on "{veth.if_master}"'), line
    interpreter = os.path.realpath(sys.executable)
    for hint in (
        "needs CAP_NET_RAW, which this process lacks",
        f"setcap cap_net_raw+ep {interpreter}",
        "AmbientCapabilities=CAP_NET_RAW",
        "setpriv --inh-caps=+net_raw --ambient-caps=+net_raw",
        "Operation not permitted",
    ):
        assert hint in line, line


def test_scan_with_cap_net_raw_alone_works_without_the_root_warning(as_user, veth, tmp_path):
    with akd_sim_in_netns(veth.ns_sim, veth.if_sim, count=2):
        scan = run(as_nobody(veth.ns_master, [*console_script("akd-scan"), veth.if_master], tmp_path, ["net_raw"]))
    assert scan.returncode == 0, scan.stderr
    assert [line.split()[0] for line in scan.stdout.splitlines()] == ["0", "1"], scan.stdout
    assert "vendor=0x0000006A product=0x00414B44" in scan.stdout
    assert scan.stderr == ""


def test_scan_with_setcap_on_the_interpreter_works(as_user, veth, tmp_path):
    # On a copy of the interpreter (`python -m venv --copies`), as docs/howto/without_root.md advises: setcap on the
    # venv's usual symlink would give every user of the shared interpreter CAP_NET_RAW.
    if shutil.which("setcap") is None:
        pytest.skip("needs setcap (Debian package libcap2-bin)")
    venv = Path(tempfile.mkdtemp(prefix="akd-setcap-"))
    try:
        venv.chmod(0o755)
        base = Path(sys.base_prefix) / "bin" / "python3"
        subprocess.run([str(base), "-m", "venv", "--copies", "--without-pip", str(venv)], check=True, timeout=60)
        python = venv / "bin" / "python3"
        made = run(["setcap", "cap_net_raw+ep", str(python.resolve())])
        if made.returncode != 0:
            pytest.skip(f"setcap is refused here (a filesystem without extended attributes?): {made.stderr.strip()}")
        # The tree and the installed packages of this venv, on the path of the copy.
        site = next(p for p in sys.path if p.endswith("site-packages"))
        argv = ["env", f"PYTHONPATH={REPO}:{site}", str(python), "-m", "akd_ros.cli.scan", veth.if_master]
        with akd_sim_in_netns(veth.ns_sim, veth.if_sim):
            scan = run(as_nobody(veth.ns_master, argv, tmp_path))
    finally:
        shutil.rmtree(venv)
    assert scan.returncode == 0, scan.stderr
    assert scan.stdout.startswith("0 vendor=0x0000006A product=0x00414B44"), scan.stdout
    assert scan.stderr == ""


# Threads of its own start before the bus opens, as a node's executor and middleware threads do: capabilities are per
# thread, so they must give theirs up too. The script reports its capabilities before the open, opens a Bus of one
# drive, waits for the test to look at /proc/<pid>, closes and tries to open a second master.
BUS_SCRIPT = r"""
import json, sys, threading, time
from pathlib import Path
from akd_ros import Bus, DriveConfig, LinkError, Master, RealTime

def capabilities():
    fields = dict(line.split(":\t", 1) for line in Path("/proc/thread-self/status").read_text().splitlines())
    return {name: int(fields[name], 16) for name in ("CapPrm", "CapEff", "CapAmb")}

iface, priority = sys.argv[1], json.loads(sys.argv[2])
stop = threading.Event()
others = [threading.Thread(target=stop.wait, name=f"other {n}") for n in range(2)]
for thread in others:
    thread.start()
before = capabilities()
bus = Bus(iface, [DriveConfig(slave=0)], realtime=RealTime(priority=priority))
first = bus.axes[0].state().cycle
time.sleep(0.2)
print(json.dumps({"before": before, "warnings": bus.warnings, "cycles": bus.axes[0].state().cycle - first}), flush=True)
sys.stdin.readline()
print(json.dumps({"close": bus.close()}), flush=True)
try:
    Master(iface).close()
    print(json.dumps({"reopen": "opened"}), flush=True)
except LinkError as error:
    print(json.dumps({"reopen": str(error)}), flush=True)
stop.set()
"""


@pytest.mark.parametrize(
    ("capabilities", "priority", "kept"),
    [(["net_raw"], None, 0), (["net_raw", "sys_nice"], 10, CAP_SYS_NICE)],
    ids=["net_raw", "net_raw+sys_nice_for_sched_fifo"],
)
def test_bus_as_user_gives_up_its_capabilities_once_the_socket_is_open(
    as_user, veth, tmp_path, capabilities, priority, kept
):
    argv = [sys.executable, "-c", BUS_SCRIPT, veth.if_master, json.dumps(priority)]
    with akd_sim_in_netns(veth.ns_sim, veth.if_sim):
        master = subprocess.Popen(
            as_nobody(veth.ns_master, argv, tmp_path, capabilities),
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        try:
            # Every exec on the way (ip netns exec, unshare, sh, setpriv, the venv's re-exec) keeps the pid.
            line = master.stdout.readline()
            assert line, master.communicate(timeout=10)[1]
            opened = json.loads(line)
            threads = capabilities_of_threads(master.pid)
            master.stdin.write("\n")
            master.stdin.flush()
            out, err = master.communicate(timeout=30)
        finally:
            stop_process(master)
    given = CAP_NET_RAW | (CAP_SYS_NICE if kept else 0)
    assert opened["before"] == {"CapPrm": given, "CapEff": given, "CapAmb": given}, opened
    assert opened["cycles"] > 50, opened
    # SCHED_FIFO was set after the drop: CAP_SYS_NICE was kept for it.
    assert opened["warnings"] == [], opened
    # Main thread, the two others, the cycle thread at least: none holds more than what the cycle may use.
    assert len(threads) >= 4, threads
    for tid, sets in threads.items():
        assert sets == {"CapInh": 0, "CapPrm": kept, "CapEff": kept, "CapAmb": 0}, (tid, sets)
    assert master.returncode == 0, err
    results = [json.loads(line) for line in out.splitlines()]
    assert results[0] == {"close": None}
    # The price, said as such: CAP_NET_RAW is gone for good, a second interface needs a new process.
    reopen = results[1]["reopen"]
    assert "this process gave up CAP_NET_RAW after it opened its raw socket on" in reopen, reopen
    assert "Traceback" not in err and "warning" not in err, err


def start_lines(stderr: str, prog: str) -> list[str]:
    """The lines a tool that ends on a bad argument writes: the warning as root, then its error."""
    lines = stderr.splitlines()
    assert lines[-1].startswith(f"{prog}: error: "), stderr
    return lines[:-1]


@pytest.mark.parametrize("tool", ["akd-scan", "akd-sim", "akd-sdo"])
def test_root_and_only_root_is_warned_at_start_in_one_line(tool):
    # A bad argument ends each tool right after the start: the warning comes before the error.
    argv = {"akd-scan": ["udp://127.0.0.1:0"], "akd-sim": ["--udp", "127.0.0.1:0"], "akd-sdo": ["sim", "read", "x"]}
    result = run([*console_script(tool), *argv[tool]])
    assert result.returncode == 1, result.stdout + result.stderr
    assert start_lines(result.stderr, tool) == ([f"{tool}: warning: {ROOT_WARNING}"] if AS_ROOT else [])


def test_root_and_only_root_is_warned_by_the_node_at_start(tmp_path):
    argv, env = node_command(tmp_path / "absent.yaml")
    node = subprocess.run(argv, env=env, capture_output=True, text=True, timeout=60, check=False)
    assert node.returncode == 1, node.stdout + node.stderr
    assert start_lines(node.stderr, "akd_node") == ([f"akd_node: warning: {ROOT_WARNING}"] if AS_ROOT else [])
    # (Run as uid 65534 with CAP_NET_RAW, the node and the tools say nothing of the kind: the tests above.)


def blocks_signal(status: str, signal: int) -> bool:
    blocked = next(line for line in status.splitlines() if line.startswith("SigBlk:"))
    return bool(int(blocked.split()[1], 16) & 1 << (signal - 1))


def test_node_as_user_with_cap_net_raw_runs_and_its_threads_give_up_what_they_can(as_user, veth, tmp_path):
    # The node's files where uid 65534 reads them and ROS writes its logs (HOME).
    home = Path(tempfile.mkdtemp(prefix="akd-privilege-"))
    try:
        os.chown(home, 65534, 65534)
        params = home / "akd.yaml"
        params.write_text(
            re.sub(r"link: \S+", f"link: {veth.if_master}", (REPO / "config" / "akd_sim.yaml").read_text())
        )
        argv, env = node_command(params)
        with akd_sim_in_netns(veth.ns_sim, veth.if_sim):
            node = subprocess.Popen(
                as_nobody(veth.ns_master, argv, tmp_path, ["net_raw"]),
                env={**env, "HOME": str(home)},
                stdout=subprocess.PIPE,
                stderr=subprocess.STDOUT,
                text=True,
            )
            try:
                log = []
                deadline = time.monotonic() + 60
                while not any("active:" in line for line in log) and time.monotonic() < deadline:
                    line = node.stdout.readline()
                    assert line, "".join(log)
                    log.append(line)
                threads = {
                    task.name: (task / "status").read_text() for task in Path(f"/proc/{node.pid}/task").iterdir()
                }
                node.send_signal(signal.SIGINT)
                rest, _ = node.communicate(timeout=30)
            finally:
                stop_process(node)
    finally:
        shutil.rmtree(home)
    log_text = "".join(log) + rest
    assert node.returncode == 0, log_text
    assert "closed: drive disabled, bus in Init" in log_text
    assert "warning: running as root" not in log_text and "Traceback" not in log_text
    # Threads that block every signal (the two that loading rclpy starts) cannot be made to drop theirs: the node
    # warns, naming them; every other thread, the cycle thread among them, holds nothing.
    kept = [line for line in log_text.splitlines() if "kept their capabilities" in line]
    holding = {tid for tid, status in threads.items() if capability_sets(status) != dict.fromkeys(CAPABILITY_SETS, 0)}
    assert len(threads) > 10, threads
    assert all(blocks_signal(threads[tid], signal.SIGRTMAX) for tid in holding), holding
    if holding:
        [warning] = kept
        assert all(f"{tid} (" in warning for tid in holding) and "block signal" in warning, warning
    else:
        assert kept == [], kept


def test_akd_eoe_as_a_user_with_cap_net_raw_and_cap_net_admin_bridges_the_drives(as_user, veth, tmp_path):
    # The TAP interface opens before the raw socket, after which the master keeps no CAP_NET_ADMIN.
    from test_eoe import DRIVES, HOST, SUMMARY, _ping_each_drive, _ready_lines

    argv = [*console_script("akd-eoe"), veth.if_master, "--host", HOST, "--tap", "akdeoe2", "--period", "0.004"]
    for ip in DRIVES:
        argv += ["--ip", f"{ip}/24"]
    # /dev/net/tun is 0600 on some containers (this CI machine's), 0666 on the distributions, where CAP_NET_ADMIN
    # guards it: as there, in the user's view only.
    tun = tmp_path / "tun"
    tun.mkdir()
    prepare = [
        f"mount -t tmpfs -o mode=0755 akd-tun {tun}",
        f"mknod -m 0666 {tun}/tun c 10 200",
        f"mount --bind {tun}/tun /dev/net/tun",
    ]
    with akd_sim_in_netns(veth.ns_sim, veth.if_sim, count=2):
        command = as_nobody(veth.ns_master, argv, tmp_path / "view", ("net_raw", "net_admin"), prepare)
        process = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        try:
            _ready_lines(process, 2, timeout=30)
            _ping_each_drive(veth.ns_master, small=2, large=1)
        finally:
            out, err = stop_process(process)
    summary = SUMMARY.search(out)
    assert summary and "Traceback" not in err, out + err
    assert int(summary["from"]) >= 6, summary[0]
