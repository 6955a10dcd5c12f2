"""The command-line tools as a user runs them: akd-scan, akd-sdo, akd-sim (UDP and raw)."""

from __future__ import annotations

import re
import shutil
import signal
import subprocess
import sys
from pathlib import Path

import pytest

import akd_ros
from support.netns import akd_sim_in_netns, akd_sim_udp, console_script, run_in_netns, udp_port_bound
from support.waiting import wait_for

# One line of akd-scan for a virtual AKD: the real drive's identity from its SII.
AKD_LINE = re.compile(
    r"^(?P<position>\d+) vendor=0x0000006A product=0x00414B44 revision=0x00000002 "
    r"name='AKD EtherCAT Drive \(CoE\)' state=(?P<state>\w+)"
)


def run_tool(name: str, *args: str, timeout: float = 60.0) -> subprocess.CompletedProcess:
    """Runs one console script to completion and returns its status and output."""
    return subprocess.run([*console_script(name), *args], capture_output=True, text=True, timeout=timeout, check=False)


def scanned_positions(stdout: str) -> list[int]:
    """Positions of the AKD lines akd-scan printed; fails on any other line."""
    positions = []
    for line in stdout.splitlines():
        match = AKD_LINE.match(line)
        assert match, f"unexpected akd-scan line: {line!r}"
        positions.append(int(match["position"]))
    return positions


def test_scan_sim_prints_one_line_per_virtual_akd():
    result = run_tool("akd-scan", "sim")
    assert result.returncode == 0, result.stderr
    assert scanned_positions(result.stdout) == [0]
    assert "model=AKD-" in result.stdout


def test_scan_sim_count_two():
    result = run_tool("akd-scan", "sim:2")
    assert result.returncode == 0, result.stderr
    assert scanned_positions(result.stdout) == [0, 1]


def test_sdo_read_identity_matches_scan():
    result = run_tool("akd-sdo", "sim", "read", "0x1018:1")
    assert result.returncode == 0, result.stderr
    assert result.stdout.strip() == "0x1018:01 = 106 (0x0000006A)"


def test_sdo_read_string_object():
    result = run_tool("akd-sdo", "sim", "read", "0x1008:0")
    assert result.returncode == 0, result.stderr
    master = akd_ros.Master("sim")
    master.scan()
    master.request_state("PreOp")
    expected = master.sdo_read(0, 0x1008, 0).rstrip(b"\0").decode("latin-1")
    master.close()
    assert result.stdout.strip() == f"0x1008:00 = {expected!r}"


def expected_abort_name(index: int, subindex: int, write: bytes | None = None) -> tuple[int, str]:
    """The abort the library itself reports for this access, to compare the tool's line with."""
    master = akd_ros.Master("sim")
    master.scan()
    master.request_state("PreOp")
    try:
        if write is None:
            master.sdo_read(0, index, subindex)
        else:
            master.sdo_write(0, index, subindex, write)
    except akd_ros.SdoAbortError as abort:
        return abort.code, abort.code_name
    finally:
        master.close()
    pytest.fail(f"0x{index:04X}:{subindex:02X} did not abort")


def test_sdo_read_missing_object_names_the_abort():
    code, name = expected_abort_name(0x1234, 0)
    assert code == 0x06020000
    result = run_tool("akd-sdo", "sim", "read", "0x1234:0")
    assert result.returncode == 1
    assert "0x06020000" in result.stderr and name in result.stderr
    assert "Traceback" not in result.stderr
    assert result.stdout == ""


def test_sdo_write_read_only_object_names_the_abort():
    result = run_tool("akd-sdo", "sim", "write", "0x6041:0", "0")
    assert result.returncode == 1
    code, name = expected_abort_name(0x6041, 0, b"\0\0")
    assert code == 0x06010002
    assert "0x06010002" in result.stderr and name in result.stderr
    assert "Traceback" not in result.stderr


@pytest.mark.parametrize("value", ["128", "-129", "0x1FF", "eight"])
def test_sdo_write_value_that_does_not_fit_is_refused_before_sending(value):
    result = run_tool("akd-sdo", "sim", "write", "0x6060:0", value)
    assert result.returncode == 1
    errors = [line for line in result.stderr.splitlines() if "warning: running as root" not in line]
    assert len(errors) == 1 and errors[0].startswith("akd-sdo: error: "), result.stderr
    assert "INTEGER8" in result.stderr or "number" in result.stderr
    assert "Traceback" not in result.stderr


@pytest.mark.parametrize("address", ["0x10000:0", "0x6060:256", "6060", "x:y"])
def test_sdo_bad_address_is_a_clear_error(address):
    result = run_tool("akd-sdo", "sim", "read", address)
    assert result.returncode == 1
    assert "INDEX:SUB" in result.stderr or "0..0xFFFF" in result.stderr


def test_sim_over_udp_serves_scan_and_sdo_round_trip(udp_port):
    link = f"udp://127.0.0.1:{udp_port}"
    with akd_sim_udp(udp_port) as sim:
        scan = run_tool("akd-scan", link)
        assert scan.returncode == 0, scan.stderr
        assert scanned_positions(scan.stdout) == [0]
        # The simulator keeps its object dictionary between masters, so a value written by one
        # akd-sdo process is read back by the next, whatever its size and sign.
        for address, value, shown in (
            ("0x6060:0", "3", "3 (0x03)"),
            ("0x6071:0", "-100", "-100 (0xFF9C)"),
            ("0x607A:0", "-123456", "-123456 (0xFFFE1DC0)"),
            ("0x607A:0", "0x7FFFFFFF", "2147483647 (0x7FFFFFFF)"),
        ):
            written = run_tool("akd-sdo", link, "write", address, value)
            assert written.returncode == 0, written.stderr
            read = run_tool("akd-sdo", link, "read", address)
            assert read.returncode == 0, read.stderr
            assert read.stdout.strip().endswith(f"= {shown}")
    assert sim.returncode == 0
    assert sim.output_text.strip().splitlines()[-1] == "akd-sim: stopped"


def test_sim_over_udp_count_two(udp_port):
    with akd_sim_udp(udp_port, count=2):
        scan = run_tool("akd-scan", f"udp://127.0.0.1:{udp_port}")
    assert scan.returncode == 0, scan.stderr
    assert scanned_positions(scan.stdout) == [0, 1]


def test_sdo_position_selects_the_drive(udp_port):
    link = f"udp://127.0.0.1:{udp_port}"
    with akd_sim_udp(udp_port, count=2):
        for position, value in ((0, "1"), (1, "7")):
            written = run_tool("akd-sdo", link, "--position", str(position), "write", "0x6060:0", value)
            assert written.returncode == 0, written.stderr
        shown = [run_tool("akd-sdo", link, "--position", str(p), "read", "0x6060:0").stdout.strip() for p in (0, 1)]
        beyond = run_tool("akd-sdo", link, "--position", "2", "read", "0x6060:0")
    assert shown == ["0x6060:00 = 1 (0x01)", "0x6060:00 = 7 (0x07)"]
    assert beyond.returncode == 1 and "position 2" in beyond.stderr


@pytest.mark.skipif(shutil.which("tshark") is None, reason="tshark not installed (scripts/setup.sh installs it)")
def test_scan_pcap_option_writes_a_capture_tshark_decodes(tmp_path):
    capture = tmp_path / "scan.pcapng"
    result = run_tool("akd-scan", "--pcap", str(capture), "sim")
    assert result.returncode == 0, result.stderr
    decoded = subprocess.run(
        ["tshark", "-r", str(capture), "-Y", "ecat"], capture_output=True, text=True, timeout=60, check=False
    )
    assert decoded.returncode == 0, decoded.stderr
    frames = decoded.stdout.splitlines()
    assert frames and all("Malformed" not in line for line in frames)
    # The scan reads the SII through its interface at 0x0502: those requests and replies are there.
    assert sum("Ado 0x502" in line for line in frames) > 100


def test_sim_stops_cleanly_on_sigint(udp_port):
    with akd_sim_udp(udp_port) as sim:
        sim.send_signal(signal.SIGINT)
        out, _ = sim.communicate(timeout=10)
    assert sim.returncode == 0
    assert out.strip().splitlines()[-1] == "akd-sim: stopped"


def test_sim_stops_on_sigint_even_when_started_with_it_ignored(udp_port):
    # As a shell's background job or a CI runner starts it: SIGINT ignored, which Python would keep.
    argv = [*console_script("akd-sim"), "--udp", f"127.0.0.1:{udp_port}"]
    sim = subprocess.Popen(
        argv,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_IGN),
    )
    try:
        wait_for("akd-sim's port", lambda: udp_port_bound(udp_port), 10.0)
        sim.send_signal(signal.SIGINT)
        out, _ = sim.communicate(timeout=10)
    finally:
        if sim.poll() is None:
            sim.kill()
            sim.wait()
    assert sim.returncode == 0 and out.strip().splitlines()[-1] == "akd-sim: stopped", out


def test_sim_refuses_bad_arguments():
    assert run_tool("akd-sim", "--udp", "127.0.0.1:1", "--count", "0").returncode == 2
    bad_port = run_tool("akd-sim", "--udp", "127.0.0.1:99999")
    assert bad_port.returncode == 1
    assert "1..65535" in bad_port.stderr


def test_scan_names_a_missing_interface():
    result = run_tool("akd-scan", "akd-no-such-if")
    assert result.returncode == 1
    assert "akd-no-such-if" in result.stderr
    assert "Traceback" not in result.stderr


def test_scan_over_raw_ethernet_in_netns(veth):
    with akd_sim_in_netns(veth.ns_sim, veth.if_sim, count=2):
        scan = run_in_netns(veth.ns_master, [*console_script("akd-scan"), veth.if_master])
    assert scan.returncode == 0, scan.stderr
    assert scanned_positions(scan.stdout) == [0, 1]


HELPED_TOOLS = ("akd-sim", "akd-scan", "akd-sdo", "akd-plot", "akd_node", "akd-top", "akd-zenohd", "akd-access")


@pytest.mark.parametrize("tool", HELPED_TOOLS)
def test_every_tools_help_shows_an_example(tool):
    result = subprocess.run(
        [shutil.which(tool, path=str(Path(sys.executable).parent)), "--help"],
        capture_output=True,
        text=True,
        timeout=60,
        check=False,
    )
    assert result.returncode == 0, result.stderr
    assert "examples:" in result.stdout, result.stdout
    examples = result.stdout.split("examples:", 1)[1].splitlines()
    # Each example is a command line of the tool itself.
    assert [line.split()[0] for line in examples if line.strip()] == [tool] * sum(1 for x in examples if x.strip())


def akd_zenohd_error(*arguments: str) -> str:
    """The one line of akd-zenohd `arguments`, which must fail."""
    result = subprocess.run(
        [str(Path(sys.executable).with_name("akd-zenohd")), *arguments],
        capture_output=True,
        text=True,
        timeout=60,
        check=False,
    )
    assert result.returncode == 1, result.stdout + result.stderr
    (line,) = result.stderr.splitlines()
    return line


def test_akd_zenohd_on_a_port_in_use_says_so_in_one_line():
    from support.zenoh import zenoh_router

    with zenoh_router() as endpoint:
        line = akd_zenohd_error("--listen", endpoint)
    assert line.startswith(f"akd-zenohd: error: cannot listen on {endpoint}: "), line


@pytest.mark.parametrize(
    "config, words",
    [
        (None, "is not a file"),
        ("{mode: 1", "is not a Zenoh configuration: --> 1:8"),
        (
            '{mode: "router", listen: {endpoints: ["tls/127.0.0.1:1"]}, transport: {link: {tls: '
            '{listen_certificate: "/nonexistent.pem", listen_private_key: "/nonexistent.key"}}}}',
            "cannot listen on",
        ),
    ],
)
def test_akd_zenohd_with_a_config_it_cannot_use_says_so_in_one_line(tmp_path, config, words):
    path = tmp_path / "router.json5"
    if config is not None:
        path.write_text(config)
    line = akd_zenohd_error("--config", str(path))
    assert line.startswith("akd-zenohd: error: ") and words in line, line


def test_a_yaml_syntax_error_in_a_parameters_file_is_the_nodes_one_line(tmp_path):
    path = tmp_path / "params.yaml"
    path.write_text("akd_node:\n  ros__parameters:\n    link: [sim\n    mode: homing\n")
    result = subprocess.run(
        [str(Path(sys.executable).parent / "akd_node"), "--ros-args", "--params-file", str(path)],
        capture_output=True,
        text=True,
        timeout=60,
        check=False,
    )
    assert result.returncode == 1
    lines = [line for line in result.stderr.splitlines() if "running as root is not needed" not in line]
    assert lines == [
        f"akd_node: error: parameters file {path}, line 4, column 9: expected ',' or ']', but got ':' "
        "(while parsing a flow sequence, line 3, column 11)"
    ], result.stderr
    assert "Traceback" not in result.stdout + result.stderr


# Starts akd-sim's command thread once for each line the start runs (in start_commands and what it calls), with
# SIGTERM sent at that line by a trace function (the handler runs as the trace function returns), under akd-sim's own
# handlers; prints, a line each, what the start raised. Then waits for every command thread to read to the end of its
# pipe: one waiting for a lock that the interrupted start left taken never ends.
SIGNAL_AT_EACH_LINE = """
import os, signal, sys, threading
from akd_ros.cli.common import stop_on_signals
from akd_ros.cli.sim import start_commands

def start(signal_at):
    lines, fired = 0, False

    def trace(frame, event, arg):
        nonlocal lines, fired
        if event == "line":
            if lines == signal_at:
                fired = True
                os.kill(os.getpid(), signal.SIGTERM)
            lines += 1
        return trace

    read_end, write_end = os.pipe()
    outcome = "none"
    sys.settrace(trace)
    try:
        start_commands(None, read_end)
    except BaseException as e:
        outcome = f"{type(e).__name__}: {e}"
    finally:
        sys.settrace(None)
        os.close(write_end)
    return fired, outcome, lines

stop_on_signals()
_, outcome, lines = start(None)
print(f"without a signal: {outcome}", flush=True)
for at in range(lines):
    fired, outcome, _ = start(at)
    if fired:
        print(f"line {at}: {outcome}", flush=True)
for thread in threading.enumerate():
    if thread is not threading.current_thread() and thread.is_alive():
        thread.join()
print("every command thread ended", flush=True)
"""


def test_a_signal_while_akd_sim_starts_its_command_thread_stops_it_quietly():
    # It once ended in "RuntimeError: release unlocked lock" (threading's own Condition interrupted), or left
    # threading's lock of starting threads taken, so that no thread could start or end after it.
    sweep = subprocess.Popen([sys.executable, "-c", SIGNAL_AT_EACH_LINE], stdout=subprocess.PIPE, text=True)
    try:
        out, _ = sweep.communicate(timeout=60)
    except subprocess.TimeoutExpired:
        sweep.kill()
        out, _ = sweep.communicate()
    lines = out.splitlines()
    assert lines[:1] == ["without a signal: none"], out
    assert lines[-1:] == ["every command thread ended"], out
    signalled = lines[1:-1]
    assert len(signalled) > 10, out
    assert all(line.endswith(": KeyboardInterrupt: signal 15") for line in signalled), out
