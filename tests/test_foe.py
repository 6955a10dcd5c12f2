"""File access over EtherCAT as a user runs it: files written to the virtual AKD read back identical, a missing name
refused with FoE's "not found" (0x8001) by name, through the extension and through akd-foe over UDP."""

from __future__ import annotations

import os
import subprocess

import pytest

import akd_ros
from support.netns import akd_sim_udp, console_script, free_udp_port


def run_tool(name: str, *args: str, timeout: float = 60.0) -> subprocess.CompletedProcess:
    return subprocess.run([*console_script(name), *args], capture_output=True, timeout=timeout, check=False)


def test_files_written_read_back_identical_and_progress_is_reported():
    master = akd_ros.Master("sim:2")
    try:
        master.scan()
        master.request_state("preop")
        # 1012 bytes a packet in the AKD's 1 KiB mailbox: whole packets (and an empty last one), and not.
        for position, size in ((0, 4 * 1012), (1, 100_000), (0, 0)):
            data = os.urandom(size)
            sent: list[tuple[int, int]] = []
            master.foe_write(position, f"file{size}.bin", data, progress=lambda s, t, sent=sent: sent.append((s, t)))
            assert sent[-1] == (size, size)
            received: list[int] = []
            assert master.foe_read(position, f"file{size}.bin", progress=received.append) == data
            assert received[-1] == size
        # Each drive has files of its own.
        with pytest.raises(akd_ros.FoeError):
            master.foe_read(1, "file4048.bin")
    finally:
        master.close()


def test_a_missing_file_is_refused_by_name():
    master = akd_ros.Master("sim")
    try:
        master.scan()
        master.request_state("preop")
        with pytest.raises(akd_ros.FoeError) as refused:
            master.foe_read(0, "missing.bin")
        assert (refused.value.name, refused.value.code, refused.value.code_name) == ("missing.bin", 0x8001, "not found")
        assert 'refused file "missing.bin": FoE error 0x8001 (not found)' in str(refused.value)
        # A slave position that is not there, and FoE refused in Init (no mailbox), are errors too.
        with pytest.raises(akd_ros.ConfigError):
            master.foe_read(3, "x")
    finally:
        master.close()


def test_akd_foe_writes_and_reads_back_and_names_a_missing_file(tmp_path):
    port = free_udp_port()
    link = f"udp://127.0.0.1:{port}"
    source, copy = tmp_path / "firmware.bin", tmp_path / "copy.bin"
    source.write_bytes(os.urandom(30_000))
    with akd_sim_udp(port):
        written = run_tool("akd-foe", link, "write", "fw.bin", str(source))
        assert written.returncode == 0, written.stderr
        assert b"wrote 30000 bytes as 'fw.bin'" in written.stderr
        read = run_tool("akd-foe", link, "read", "fw.bin", str(copy))
        assert read.returncode == 0, read.stderr
        assert copy.read_bytes() == source.read_bytes()
        missing = run_tool("akd-foe", link, "read", "nothing.bin", str(tmp_path / "n"))
    assert missing.returncode == 1
    lines = missing.stderr.decode().strip().splitlines()
    assert lines[-1] == ('akd-foe: error: FoE: slave 0 refused file "nothing.bin": FoE error 0x8001 (not found)'), (
        missing.stderr
    )
    assert b"Traceback" not in missing.stderr
    assert not (tmp_path / "n").exists()
