"""SOEM (through pysoem) against a virtual line of Beckhoff terminals and AKDs served by `akd-sim --line` over a veth
pair, as tests/test_soem.py runs it against AKDs alone.

The real terminals' reference is SOEM's slaveinfo of a real EK1100 with two EL2004s
(`../shared/real-ethercat/soem-sdinfo-2-el2004.txt`): each slave's process-data sizes in bits, its sync manager, its
FMMU with the bit offsets SOEM packed the outputs at, its DC and its open ports. The virtual line must show SOEM the
same. The cell test then drives a coupler, an input terminal, an output terminal and an AKD to Op and checks, through
akd-sim's own commands, that the output terminal's pins follow SOEM's process data and drop when the watchdog runs
out, and that an input set on akd-sim's stdin reaches SOEM.
"""

from __future__ import annotations

import json
import re
import subprocess
import sys
import time

import pytest

from support.netns import akd_sim_in_netns, master_script_report, netns_argv
from support.soem_script import SOEM_HELPERS
from support.waiting import Lines

pysoem = pytest.importorskip("pysoem", reason="pysoem is installed by scripts/setup.sh")

SLAVEINFO = "soem-sdinfo-2-el2004.txt"

# Runs in the master's namespace: argv = interface. What SOEM made of each slave, read back from the slaves' ESCs.
SLAVEINFO_SCRIPT = (
    SOEM_HELPERS
    + r"""
def slaveinfo(master, report):
    report["iomap_size"] = master.config_map()
    report["dc"] = master.config_dc()
    report["safeop"] = reach_safeop(master)
    report["op"] = report["safeop"] and reach_op(master)
    report["slaves"] = [{
        "name": s.name, "man": s.man, "id": s.id, "rev": s.rev, "state": s.state,
        "sizes": [len(s.output), len(s.input)],
        "sm0": s._fprd(0x0800, 8).hex(), "fmmu0": s._fprd(0x0600, 16).hex(),
        "dl_status": int.from_bytes(s._fprd(0x0110, 2), "little"),
        "receive_time": int.from_bytes(s._fprd(0x0900, 4), "little"),
    } for s in master.slaves]


session(sys.argv[1], slaveinfo)
"""
)


def real_slaveinfo(path) -> list[dict]:
    """Each slave of SOEM's slaveinfo text: its name, identity, sizes in bits, SM0, FMMU0, DC and active ports."""
    slaves = []
    for block in path.read_text().split("\nSlave:")[1:]:

        def field(pattern: str, block: str = block) -> re.Match | None:
            return re.search(pattern, block)

        slave = {
            "name": field(r"Name:(\S+)")[1],
            "man": int(field(r"Man: (\w+)")[1], 16),
            "id": int(field(r"ID: (\w+)")[1], 16),
            "rev": int(field(r"Rev: (\w+)")[1], 16),
            "bits": [int(field(r"Output size: (\d+)bits")[1]), int(field(r"Input size: (\d+)bits")[1])],
            "has_dc": field(r"Has DC: (\d)")[1] == "1",
            "active_ports": field(r"Activeports:([\d.]+)")[1],
        }
        sm = field(r"SM0 A:(\w+) L:\s*(\d+) F:(\w+)")
        slave["sm0"] = sm and (int(sm[1], 16), int(sm[2]), int(sm[3], 16))
        fmmu = field(r"FMMU0 Ls:(\w+) Ll:\s*(\d+) Lsb:(\d) Leb:(\d) Ps:(\w+) Psb:(\d) Ty:(\w+) Act:(\w+)")
        slave["fmmu0"] = fmmu and (
            int(fmmu[1], 16),
            int(fmmu[2]),
            int(fmmu[3]),
            int(fmmu[4]),
            int(fmmu[5], 16),
            int(fmmu[6]),
            int(fmmu[7], 16),
            int(fmmu[8], 16),
        )
        slaves.append(slave)
    return slaves


def active_ports(dl_status: int) -> str:
    """SOEM's active ports of a slave from its DL status: a port counts where it has communication and its loop is
    open."""
    return ".".join("1" if dl_status >> (8 + 2 * port) & 0x3 == 0x2 else "0" for port in range(4))


def virtual_slaveinfo(slave: dict) -> dict:
    """The same fields as `real_slaveinfo` gives, from the registers SOEM set in a virtual slave."""
    sm0, fmmu0 = bytes.fromhex(slave["sm0"]), bytes.fromhex(slave["fmmu0"])
    enabled = fmmu0[12] & 1
    bits = [0, 0]
    if enabled:
        length, first, last = int.from_bytes(fmmu0[4:6], "little"), fmmu0[6], fmmu0[7]
        bits[0 if fmmu0[11] == 2 else 1] = (length - 1) * 8 + last - first + 1
    return {
        "name": slave["name"],
        "man": slave["man"],
        "id": slave["id"],
        "rev": slave["rev"],
        "bits": bits,
        "has_dc": slave["receive_time"] != 0,
        "active_ports": active_ports(slave["dl_status"]),
        # SOEM's SM flags: control byte, then the enable byte it wrote to the activate register.
        "sm0": sm0[6] & 1
        and (int.from_bytes(sm0[0:2], "little"), int.from_bytes(sm0[2:4], "little"), sm0[4] | sm0[6] << 16),
        "fmmu0": enabled
        and (
            int.from_bytes(fmmu0[0:4], "little"),
            int.from_bytes(fmmu0[4:6], "little"),
            fmmu0[6],
            fmmu0[7],
            int.from_bytes(fmmu0[8:10], "little"),
            fmmu0[10],
            fmmu0[11],
            fmmu0[12],
        ),
    }


def test_soem_sees_the_virtual_terminals_as_it_saw_the_real_ones(veth, real_ethercat_dir):
    real = real_slaveinfo(real_ethercat_dir / SLAVEINFO)
    assert [s["name"] for s in real] == ["EK1100", "EL2004", "EL2004"]
    report = master_script_report(veth, SLAVEINFO_SCRIPT, [], line="ek1100,el2004,el2004")
    assert report["found"] == 3 and report["preop"] and report["op"], report
    ours = [virtual_slaveinfo(s) for s in report["slaves"]]
    assert ours == [{k: r[k] if r[k] is not None else 0 for k in r} for r in real]
    # One logical byte of outputs, the two EL2004s' four bits each; no inputs.
    assert report["iomap_size"] == 1 and report["dc"]


# Runs in the master's namespace: argv = interface. The cell ek1100, el1004, el2004, akd to Op; the EL2004's outputs 1
# and 3 on every cycle until the EL1004's input 2 is seen high, then no frame until a line on stdin, then Init.
CELL_SCRIPT = (
    SOEM_HELPERS
    + r"""
def cell(master, report):
    slaves = master.slaves
    report["names"] = [s.name for s in slaves]
    slaves[3].config_func = lambda position: select_fixed_mappings(master, position)
    report["iomap_size"] = master.config_map()
    report["sizes"] = [[len(s.output), len(s.input)] for s in slaves]
    report["safeop"] = reach_safeop(master)
    report["expected_wkc"] = master.expected_wkc
    report["op"] = report["safeop"] and reach_op(master)
    print("op", flush=True)
    wkcs, deadline = [], time.monotonic() + 60
    while time.monotonic() < deadline:
        slaves[2].output = bytes([0b0101])
        slaves[3].output = struct.pack("<iH", 0, 0x0006)
        master.send_processdata()
        wkcs.append(master.receive_processdata(20000))
        if slaves[1].input[0] & 0b0010:
            report["input_seen"] = slaves[1].input[0]
            break
        time.sleep(0.002)
    report["wkcs"] = sorted(set(wkcs))
    print("input seen", flush=True)
    sys.stdin.readline()
    master.read_state()
    report["states_before_init"] = [s.state for s in slaves]


session(sys.argv[1], cell)
"""
)

LINE = "ek1100,el1004,el2004,akd"


def test_soem_runs_a_cell_whose_terminals_follow_the_process_data(veth):
    with akd_sim_in_netns(veth.ns_sim, veth.if_sim, line=LINE, stdin=True, options=("--missed", "lost")) as sim:
        sim_lines = Lines(sim.stdout)
        assert sim_lines.next() == f"akd-sim: starting line {LINE} on interface {veth.if_sim}"

        def command(line: str) -> str:
            sim.stdin.write(line + "\n")
            sim.stdin.flush()
            return sim_lines.next()

        def terminal(position: int) -> dict:
            reply = command(f"state {position}")
            assert reply.startswith("ok {"), reply
            return json.loads(reply[3:])

        def wait_for(what: str, done, timeout: float = 30.0) -> dict:
            deadline = time.monotonic() + timeout
            while not done(state := terminal(2)):
                assert time.monotonic() < deadline, f"{what}: {state}"
                time.sleep(0.05)
            return state

        argv = netns_argv(veth.ns_master, [sys.executable, "-c", CELL_SCRIPT, veth.if_master])
        script = subprocess.Popen(
            argv, stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
        )
        try:
            script_lines = Lines(script.stdout)
            assert script_lines.next(timeout=60) == "op"
            # SOEM's outputs 1 and 3 of the EL2004 are on its pins.
            state = wait_for("the EL2004's pins follow", lambda s: s["outputs"] == [True, False, True, False])
            assert (state["al_state"], state["watchdog_expired"]) == ("Op", False)
            assert terminal(1)["inputs"] == [False] * 4
            # An input set on akd-sim's stdin reaches SOEM (after the terminal's 3 ms filter).
            assert command("input 1 2 high") == "ok input 1 2 high"
            assert script_lines.next(timeout=60) == "input seen"
            # SOEM sends nothing now: the sync-manager watchdog (100 ms) drops the pins, in Op.
            state = wait_for("the watchdog drops the EL2004's pins", lambda s: s["watchdog_expired"])
            assert (state["outputs"], state["al_state"]) == ([False] * 4, "Op")
            script.stdin.write("done\n")
            script.stdin.close()
            assert script.wait(timeout=60) == 0, script.stderr.read()
            report = json.loads(script_lines.next())
        finally:
            if script.poll() is None:
                script.kill()
                script.wait()
    assert report["found"] == 4 and report["names"] == ["EK1100", "EL1004", "EL2004", "AKD"]
    # The coupler has no process data; 1 byte of outputs and inputs for the terminals' 4 bits; 0x1701/0x1B01.
    assert report["sizes"] == [[0, 0], [0, 1], [1, 0], [6, 6]]
    # One LRW: each ESC adds 2 where it is written (EL2004, AKD) and 1 where it is read (EL1004, AKD). The ESCs' count,
    # not this SOEM's own expectation (report["expected_wkc"]), which counts a slave's outputs only where they move the
    # logical address on, as 4 bits packed into a byte do not: it expects 3 here, and 2 of an EK1100 with two EL2004s,
    # where the older SOEM of the slaveinfo reference calculated 4 for the real ones.
    assert report["wkcs"] == [6], report["wkcs"]
    assert report["input_seen"] == 0b0010
    assert report["states_before_init"] == [pysoem.OP_STATE] * 4
