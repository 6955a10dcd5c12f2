"""KickCAT (PyPI `kickcat`), a third-party master, against the virtual AKD over a veth pair.

Like test_soem: akd-sim on one veth end in its namespace, the kickcat script in the other, the
script's observations as JSON. kickcat's Python API (2.5) reads the SII inside `Bus.init` but does
not expose what it read, so the identity is checked through CoE 0x1018, and the SII content
kickcat uses is checked by what depends on it: the mailbox sync managers it sets from the SII
(the virtual AKD refuses PreOp with 0x0017 unless SM0/SM1 are at 0x1800/0x1C00 in mailbox mode,
no longer than the SII's 1024 bytes)
and the process-data sync manager start addresses it takes from the SII SM category (SafeOp is
refused when SM2/SM3 are not at 0x1100/0x1140).
"""

from __future__ import annotations

import pytest

from support.kickcat_script import KICKCAT_HELPERS
from support.netns import master_script_report

kickcat = pytest.importorskip("kickcat", reason="kickcat is installed by scripts/setup.sh")

KICKCAT_SCRIPT = (
    KICKCAT_HELPERS
    + r"""
iface, mapping = sys.argv[1], sys.argv[2]
link, bus, slaves, report = start(iface)


def read(slave, index, subindex, size=4):
    return bus.read_sdo(slave, index, subindex, kickcat.Access.PARTIAL, size, 1.0)


first = slaves[0]
report["sdo_identity"] = [int.from_bytes(read(first, 0x1018, sub), "little") for sub in (1, 2, 3, 4)]
report["device_name"] = read(first, 0x1008, 0, 64).rstrip(b"\0").decode("latin-1")
report["descriptions"] = {hex(index): list(bus.read_object_description(first, index))
                          for index in (0x1018, 0x6040, 0x6041)}
report["entry_6041"] = list(bus.read_entry_description(first, 0x6041, 0))

if mapping == "fixed":
    select_fixed_mappings(bus, slaves)
bus.create_mapping()
report["sizes"] = [[s.output_size, s.input_size] for s in slaves]

bus.request_state(State.SAFE_OP)
try:
    bus.wait_for_state(State.SAFE_OP, 2.0)
except Exception as error:
    report["safeop_error"] = f"{type(error).__name__}: {error}"
    print(json.dumps(report))
    sys.exit(0)
for slave in slaves:
    slave.set_output_bytes(struct.pack("<iH", 0, 0x0006))
bus.process_data()
bus.request_state(State.OPERATIONAL)
bus.wait_for_state(State.OPERATIONAL, 2.0, bus.process_data)
report["state_in_op"] = [str(bus.get_state(s)) for s in slaves]



def set_outputs(cycle):
    for position, slave in enumerate(slaves):
        slave.set_output_bytes(struct.pack("<iH", 1000 * cycle + position, 0x0006))


report["cycles"] = 100
report["cycle_errors"], report["first_error"] = run_cycles(bus, set_outputs, report["cycles"])
report["inputs"] = [s.input_data.hex() for s in slaves]
bus.request_state(State.INIT)
print(json.dumps(report))
"""
)


def run_kickcat(net, count: int, mapping: str) -> dict:
    """Serves `count` virtual AKDs and runs the script against them; returns its report."""
    report = master_script_report(net, KICKCAT_SCRIPT, [mapping], count=count)
    print(f"kickcat Bus.init attempts: {report['init_attempts']}, errors: {report['init_errors']}")
    return report


@pytest.mark.parametrize("count", [1, 2])
def test_kickcat_reaches_op_and_exchanges_process_data(veth, count):
    report = run_kickcat(veth, count, "fixed")
    assert report["found"] == count
    assert report["state_after_init"] == ["State.PREOP"] * count
    assert report["sdo_identity"][:3] == [0x6A, 0x00414B44, 2]
    assert report["device_name"] == "AKD"
    names = {index: description[0] for index, description in report["descriptions"].items()}
    assert names == {"0x1018": "Identity object", "0x6040": "Controlword", "0x6041": "Statusword"}
    assert "RECORD" in report["descriptions"]["0x1018"][1]
    assert report["entry_6041"][0] == "Statusword"
    assert "bit length:    16" in report["entry_6041"][1]
    assert report["sizes"] == [[6, 6]] * count
    assert report["state_in_op"] == ["State.OPERATIONAL"] * count
    assert report["cycle_errors"] == 0, report["first_error"]


def test_kickcat_power_up_mapping_is_refused_like_the_real_drive(veth):
    # The real drive's power-up mapping (17 bytes each way) is refused at PreOp->SafeOp with AL
    # status code 0x001D, as the capture of SOEM with a real AKD shows; kickcat must see it too.
    report = run_kickcat(veth, 1, "powerup")
    assert report["sizes"] == [[17, 17]]
    assert "safeop_error" in report
    assert report["safeop_error"].startswith("ErrorAL")


# Runs in the master's namespace: argv = interface. The cell ek1100, el1004, el2004, akd: the AKD's fixed mappings,
# Op, and 100 cycles in which kickcat checks every datagram's working counter against its own expectation.
KICKCAT_CELL_SCRIPT = (
    KICKCAT_HELPERS
    + r"""
link, bus, slaves, report = start(sys.argv[1])
select_fixed_mappings(bus, [slaves[3]])
bus.create_mapping()
report["sizes"] = [[s.output_size, s.input_size] for s in slaves]


def outputs(cycle=0):
    slaves[2].set_output_bytes(bytes([0b0101]))
    slaves[3].set_output_bytes(struct.pack("<iH", cycle, 0x0006))


bus.request_state(State.SAFE_OP)
bus.wait_for_state(State.SAFE_OP, 2.0)
outputs()
bus.process_data()
bus.request_state(State.OPERATIONAL)
bus.wait_for_state(State.OPERATIONAL, 2.0, bus.process_data)
report["state_in_op"] = [str(bus.get_state(s)) for s in slaves]
report["cycle_errors"], report["first_error"] = run_cycles(bus, outputs)
bus.request_state(State.INIT)
print(json.dumps(report))
"""
)


def test_kickcat_reaches_op_on_a_cell_of_terminals_and_an_akd(veth):
    report = master_script_report(veth, KICKCAT_CELL_SCRIPT, [], line="ek1100,el1004,el2004,akd")
    assert report["found"] == 4
    assert report["state_after_init"] == ["State.PREOP"] * 4
    # kickcat maps by whole bytes: the terminals' 4 bits take a byte each way.
    assert report["sizes"] == [[0, 0], [0, 1], [1, 0], [6, 6]]
    assert report["state_in_op"] == ["State.OPERATIONAL"] * 4
    assert report["cycle_errors"] == 0, report["first_error"]
