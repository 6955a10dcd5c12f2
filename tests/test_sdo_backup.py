"""akd-sdo dump and restore as a user runs them, against akd-sim --udp with two virtual AKDs (whose object
dictionaries live on between the tool's runs): a configuration dumped from one drive and restored onto the other
makes their dumps equal; a refused value is reported with its abort code and the rest is written; read-only and
unknown objects are skipped with a note; --dry-run shows what would change and writes nothing."""

from __future__ import annotations

import subprocess
from pathlib import Path

import pytest
import yaml

import akd_ros
from support.netns import akd_sim_udp, console_script, free_udp_port

# A bound on one run of the tool, not a timing expectation: a dump reads some 200 entries over loopback.
RUN_TIMEOUT_S = 120.0
# What drive 0 is given before its dump, so the dump differs from drive 1's power-up configuration: a
# following error window, a profile velocity, a mode, a cycle time (0x60C2 250 us), and the second flexible RxPDO
# and TxPDO mapping something else (which a restore may only write in the AKD's order).
CHANGES = [
    ("0x6065:0", "1000"),
    ("0x6081:0", "2097152"),
    ("0x6060:0", "8"),
    ("0x60C2:1", "25"),
    ("0x60C2:2", "-5"),
    ("0x1C12:0", "0"),
    ("0x1C13:0", "0"),
    ("0x1601:0", "0"),
    ("0x1601:2", "0x60FF0020"),
    ("0x1601:0", "2"),
    ("0x1A01:0", "0"),
    ("0x1A01:2", "0x606C0020"),
    ("0x1A01:0", "2"),
    ("0x1C12:0", "4"),
    ("0x1C13:0", "4"),
]


def akd_sdo(link: str, *args: str) -> subprocess.CompletedProcess:
    """akd-sdo LINK ARGS, to its end."""
    return subprocess.run(
        [*console_script("akd-sdo"), link, *args], capture_output=True, text=True, timeout=RUN_TIMEOUT_S, check=False
    )


def ok(result: subprocess.CompletedProcess) -> str:
    assert result.returncode == 0, f"exit {result.returncode}\n{result.stdout}\n{result.stderr}"
    return result.stdout


def entries(path: Path) -> dict[tuple[int, int], dict]:
    """A dump's records by (index, subindex)."""
    return {(r["index"], r["subindex"]): r for r in yaml.safe_load(path.read_text())["objects"]}


def read(link: str, position: int, address: str) -> str:
    return ok(akd_sdo(link, "--position", str(position), "read", address)).strip()


@pytest.fixture(scope="module")
def link():
    port = free_udp_port()
    with akd_sim_udp(port, count=2):
        link = f"udp://127.0.0.1:{port}"
        for address, value in CHANGES:
            ok(akd_sdo(link, "--position", "0", "write", address, value))
        yield link


@pytest.fixture(scope="module")
def dumped(link, tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("dump") / "drive0.yaml"
    output = ok(akd_sdo(link, "--position", "0", "dump", "-o", str(path)))
    assert output.splitlines()[-1].startswith(f"dumped {len(entries(path))} entries to {path}")
    return path


def test_a_dump_holds_every_readable_entry_with_its_name_type_and_value(link, dumped):
    records = entries(dumped)
    text = dumped.read_text()
    assert "index: 0x6065" in text, "indices are written in hex"
    assert records[0x6065, 0] == {
        "index": 0x6065,
        "subindex": 0,
        "object": "Following error window",
        "name": "Following error window",
        "type": "UNSIGNED32",
        "access": ["read_preop", "read_safeop", "read_op", "write_preop", "write_safeop", "write_op"],
        "value": 1000,
    }
    assert records[0x1008, 0]["value"] == "AKD" and records[0x1008, 0]["type"] == "VISIBLE_STRING"
    assert records[0x60C2, 2]["value"] == -5 and records[0x1601, 2]["value"] == 0x60FF0020
    assert records[0x1018, 1]["value"] == 0x6A
    # Every object the drive lists is in the dump, with each of its entries.
    with akd_ros.Master(link) as master:
        master.scan()
        master.request_state("PreOp", 0)
        listed = master.sdo_object_list(0)
        subindices = {i: master.sdo_object_description(0, i)["max_subindex"] for i in listed}
    assert sorted({index for index, _ in records}) == sorted(listed)
    for index, highest in subindices.items():
        assert [s for i, s in records if i == index] == list(range(highest + 1)), f"0x{index:04X}"


def test_a_restore_onto_a_second_drive_makes_their_dumps_equal(link, dumped, tmp_path):
    before = tmp_path / "drive1_before.yaml"
    ok(akd_sdo(link, "--position", "1", "dump", "-o", str(before)))
    assert entries(before)[0x1601, 2]["value"] != entries(dumped)[0x1601, 2]["value"]

    result = akd_sdo(link, "--position", "1", "restore", str(dumped))
    output = ok(result)
    assert "refused" not in output.replace("0 refused", ""), output
    assert "note: 0x1018:04 Serial number: read-only, skipped" in output
    summary = output.splitlines()[-1]
    assert summary.startswith("restored: ") and summary.endswith(" 0 refused"), summary

    after = tmp_path / "drive1_after.yaml"
    ok(akd_sdo(link, "--position", "1", "dump", "-o", str(after)))
    source, restored = entries(dumped), entries(after)
    assert source.keys() == restored.keys()
    differing = {key for key in source if source[key]["value"] != restored[key]["value"]}
    # Only what no restore can write differs: the drive's own serial number (read-only).
    assert differing == {(0x1018, 4)}, {k: (source[k]["value"], restored[k]["value"]) for k in differing}
    assert read(link, 1, "0x1601:2") == "0x1601:02 = 1627324448 (0x60FF0020)"
    assert read(link, 1, "0x1C12:0") == "0x1C12:00 = 4 (0x04)"


def test_a_refused_value_is_reported_by_its_abort_and_the_rest_is_written(link, dumped, tmp_path):
    document = yaml.safe_load(dumped.read_text())
    for record in document["objects"]:
        if (record["index"], record["subindex"]) == (0x6060, 0):
            record["value"] = 2  # no mode of the AKD's
        if (record["index"], record["subindex"]) == (0x60C2, 1):
            record["value"] = 1  # 1 x 10^-5 s: below the AKD's 250 us
        if (record["index"], record["subindex"]) == (0x6081, 0):
            record["value"] = 3145728
        if (record["index"], record["subindex"]) == (0x6072, 0):
            record["value"] = 70000  # more than UNSIGNED16 holds
    document["objects"].append({"index": 0x2FFF, "subindex": 0, "name": "not an AKD's", "value": 1})
    bad = tmp_path / "bad.yaml"
    bad.write_text(yaml.safe_dump(document))

    result = akd_sdo(link, "--position", "1", "restore", str(bad))
    assert result.returncode == 1, f"{result.stdout}\n{result.stderr}"
    output = result.stdout
    assert "Traceback" not in result.stderr, result.stderr
    assert "refused: 0x6060:00 Modes of operation <- 2: abort 0x06090030 (value range of parameter exceeded)" in output
    assert "refused: 0x60C2:02 Interpolation time index <- -5: abort 0x06090032" in output
    assert "refused: 0x6072:00 Max torque: 70000 is out of range for UNSIGNED16 (0..65535)" in output
    assert "note: 0x2FFF:00 not an AKD's: the drive has no such object, skipped" in output
    assert output.splitlines()[-1].endswith(" 3 refused"), output
    # What was not refused was written.
    assert read(link, 1, "0x6081:0") == "0x6081:00 = 3145728 (0x00300000)"
    assert read(link, 1, "0x6060:0") == "0x6060:00 = 8 (0x08)"


def test_a_dry_run_shows_what_would_change_and_writes_nothing(link, tmp_path):
    own = tmp_path / "drive1.yaml"
    ok(akd_sdo(link, "--position", "1", "dump", "-o", str(own)))
    document = yaml.safe_load(own.read_text())
    for record in document["objects"]:
        if (record["index"], record["subindex"]) == (0x6065, 0):
            record["value"] = 4242
    changed = tmp_path / "changed.yaml"
    changed.write_text(yaml.safe_dump(document))
    before = read(link, 1, "0x6065:0")
    held = int(before.split()[2])
    assert held != 4242
    output = ok(akd_sdo(link, "--position", "1", "restore", str(changed), "--dry-run"))
    assert f"would change 0x6065:00 Following error window: {held} -> 4242" in output
    assert output.splitlines()[-1].startswith("dry run: 1 would change, ")
    assert output.splitlines()[-1].endswith("nothing written")
    assert read(link, 1, "0x6065:0") == before


def test_a_file_that_is_no_dump_is_one_line_and_status_1(link, tmp_path):
    broken = tmp_path / "broken.yaml"
    broken.write_text("objects: [\n")
    result = akd_sdo(link, "restore", str(broken))
    assert result.returncode == 1
    error = result.stderr.splitlines()[-1]
    assert error.startswith(f"akd-sdo: error: {broken}, line 2, column 1: "), result.stderr
    assert "Traceback" not in result.stderr
    other = tmp_path / "other.yaml"
    other.write_text("link: sim\n")
    result = akd_sdo(link, "restore", str(other))
    assert result.returncode == 1
    assert result.stderr.splitlines()[-1] == (
        f"akd-sdo: error: {other}: not an akd-sdo dump (a map with a list 'objects'; make one with akd-sdo LINK dump)"
    )
