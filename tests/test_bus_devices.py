"""`akd_ros.Bus` on a virtual cell, an EK1100 with an EL1004 and an EL2004 in front of two AKDs (``sim:ek1100,...``):
the terminals go to Op with the drives and are read and set by channel name (`bus.devices`), an input's edge is an
event of its cycle, the line is checked against the drives and devices given before anything goes to Op, and the
devices' outputs go off as the Bus closes.

The waits have deadlines only so that a failure does not hang; no test asserts how fast anything happens.
"""

from __future__ import annotations

import re

import pytest
from akd_ros._native import Ds402State

from akd_ros import Bus, CommandError, DriveConfig, Master
from akd_ros.device import DeviceConfig
from support.waiting import wait_for

CELL = "sim:ek1100,el1004,el2004,akd,akd?missed=lost&pace=immediate"
DRIVES = [DriveConfig(slave=3, name="j1"), DriveConfig(slave=4, name="j2")]
DEVICES = [
    DeviceConfig(slave=1, name="inputs", product="EL1004"),
    DeviceConfig(slave=2, name="outputs", product="el2004"),
]


@pytest.fixture
def cell():
    with Bus(CELL, DRIVES, devices=DEVICES) as bus:
        yield bus


def test_the_terminals_are_read_and_set_by_name_beside_the_drives(cell: Bus) -> None:
    inputs, outputs = cell.device("inputs"), cell.device("outputs")
    assert (inputs.product, outputs.product) == ("EL1004", "EL2004")
    assert inputs.input_names == [f"channel_{n}_input" for n in range(1, 5)] and inputs.output_names == []
    assert outputs.output_names == [f"channel_{n}_output" for n in range(1, 5)]
    assert cell.unnamed == [0], "the EK1100, named by neither"
    outputs.set_outputs({"channel_2_output": True, "channel_4_output": 1})
    wait_for("the outputs at the pins", lambda: cell.simulator.terminal_state(2)["outputs"] == [0, 1, 0, 1])
    assert cell.devices_io()["outputs"].outputs == {
        "channel_1_output": False,
        "channel_2_output": True,
        "channel_3_output": False,
        "channel_4_output": True,
    }
    unknown = 'device outputs: configuration: slave 2 has no output channel "valve"; its outputs: channel_1_output, '
    with pytest.raises(CommandError, match=re.escape(unknown)):
        outputs.set_outputs({"channel_1_output": True, "valve": True})
    with pytest.raises(CommandError, match=re.escape("channel channel_1_output: 2 given, allowed 0..=1")):
        outputs.set_outputs({"channel_1_output": 2})
    with pytest.raises(CommandError, match="is an input"):
        inputs.set_outputs({"channel_1_input": True})
    assert cell.simulator.terminal_state(2)["outputs"] == [0, 1, 0, 1], "nothing set by a refusal"

    list(inputs.input_events())
    cell.simulator.set_input(1, 3, True)
    change = wait_for("the input's event", lambda: next(inputs.input_events(), None))
    assert change.inputs["channel_3_input"] is True and change.inputs["channel_1_input"] is False
    assert inputs.io().inputs["channel_3_input"] is True
    # The drives run as ever beside them.
    cell.enable()
    assert [a.state().state for a in cell.axes] == [Ds402State.OPERATION_ENABLED] * 2


def test_the_outputs_go_off_as_the_bus_closes():
    with Bus(CELL, DRIVES, devices=DEVICES) as bus:
        bus.device("outputs").set_outputs({"channel_1_output": True})
        simulator, cycle = bus.simulator, bus.cycle
        wait_for("output 1 on", lambda: simulator.terminal_state(2)["outputs"] == [1, 0, 0, 0])
        assert cycle.snapshot()["outputs"][2] == b"\x01"
    # The virtual line is gone with its master: the cycle's last snapshot says what went out last, off.
    assert bus.closed and cycle.snapshot()["outputs"][2] == b"\x00"


@pytest.mark.parametrize(
    ("drives", "devices", "message"),
    [
        (
            DRIVES,
            [DeviceConfig(slave=2, name="outputs", product="EL2008")],
            "slave 2 is an EL2004; device outputs expects an EL2008",
        ),
        ([DriveConfig(slave=2, name="j1")], [], "slave 2 is an EL2004; drive j1 expects an AKD"),
        (
            DRIVES,
            [DeviceConfig(slave=7, name="far")],
            "slave 7 is not on the bus: the line has 5 slaves (0..4); device far expects a device there",
        ),
        (
            [DriveConfig(slave=5, name="j3")],
            [],
            "slave 5 is not on the bus: the line has 5 slaves (0..4); drive j3 expects an AKD there",
        ),
        (DRIVES[:1], [DeviceConfig(slave=4, name="j2b")], "slave 4 is an AKD; device j2b expects a device beside"),
        (DRIVES, [DeviceConfig(slave=3, name="twice")], "slave 3 is given to a drive and to device twice"),
    ],
)
def test_a_line_other_than_expected_is_refused_in_one_line_before_op(drives, devices, message):
    with pytest.raises(CommandError) as refused:
        Bus(CELL, drives, devices=devices)
    assert message in str(refused.value) and "\n" not in str(refused.value)


def test_the_scan_names_every_slave_with_its_channels():
    with Master(CELL) as master:
        slaves = master.scan()
    assert [(s["order"], s["akd"]) for s in slaves] == [
        ("EK1100", False),
        ("EL1004", False),
        ("EL2004", False),
        ("AKD", True),
        ("AKD", True),
    ]
    assert [c["name"] for c in slaves[2]["channels"]] == [f"channel_{n}_output" for n in range(1, 5)]
    first = slaves[1]["channels"][0]
    assert (first["index"], first["subindex"], first["bits"], first["data_type"], first["pdo"]) == (
        0x6000,
        1,
        1,
        "BOOLEAN",
        0x1A00,
    )
