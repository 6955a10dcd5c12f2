"""The drive's own I/O from Python, without ROS: `Axis.io`, `Axis.set_outputs` and `Axis.input_events` against the
in-process virtual AKD with akd_ros's `io` mapping, what a mapping carries (`_native.mapping_io`, `io_mappings`) and
the node's parameters that name inputs and outputs, checked before the bus is touched.

The waits have deadlines only so that a failure does not hang; nothing here asserts how fast anything happens. The
virtual AKDs judge missed frames by the frames the line lost (`?missed=lost`), so a cycle this shared host runs late
does not fault them.
"""

from __future__ import annotations

import math
import re

import pytest
import yaml
from akd_ros._native import Ds402State

from akd_ros import Axis, CommandError, _native, params
from akd_ros.axis import ANALOG_VOLTS_PER_COUNT, MODES
from support.docs_pages import blocks_of
from support.waiting import wait_for

CSP = "cyclic_synchronous_position"


@pytest.fixture
def axis():
    """An Axis in cyclic synchronous position with the io mapping, its drive enabled."""
    with Axis("sim?missed=lost", mode=CSP, mapping=_native.IO_MAPPING) as axis:
        axis.enable()
        yield axis


def later(axis: Axis, cycles: int) -> None:
    start = axis.io().cycle
    wait_for(f"{cycles} cycles", lambda: axis.io().cycle >= start + cycles)


def test_inputs_switches_and_the_analog_input_read_as_the_drive_shows_them(axis):
    sim = axis.simulator
    later(axis, 5)
    assert not any(axis.io().inputs) and not any(axis.io().switches.values())
    sim.set_input(0, 3, True)
    sim.set_switch(0, "home_switch", True)
    sim.set_analog_input(0, -2.5)
    io = wait_for("the inputs", lambda: (io := axis.io()).inputs[2] and io)
    assert io.inputs == (False, False, True, False, False, False, False)
    assert io.switches == {"negative_limit": False, "positive_limit": False, "home_switch": True, "interlock": False}
    assert io.digital_inputs == (1 << 2) | (1 << 18)
    assert abs(io.analog_input + 2.5) <= ANALOG_VOLTS_PER_COUNT
    assert io.hardware_enable == "high"
    # Each change is one event of the cycle whose inputs showed it, handed out once.
    changes = list(axis.input_events())
    assert changes and changes[-1].inputs[2] and changes[-1].switches["home_switch"], changes
    assert all(c.cycle <= io.cycle for c in changes)
    assert list(axis.input_events()) == []


def test_outputs_go_out_by_the_process_image_and_read_back_from_the_drive(axis):
    sim = axis.simulator
    axis.set_outputs({2: True}, analog_output=-3.3)
    drive = wait_for("the outputs", lambda: (d := sim.drive_state(0))["digital_outputs"][1] and d)
    assert drive["digital_outputs"] == [False, True]
    assert abs(drive["analog_output"] + 3.3) <= ANALOG_VOLTS_PER_COUNT
    axis.set_outputs({1: True})
    wait_for("output 1 too", lambda: sim.drive_state(0)["digital_outputs"] == [True, True])
    io = axis.io()
    assert io.outputs == (True, True) and abs(io.analog_output + 3.3) <= ANALOG_VOLTS_PER_COUNT
    # A held axis stays held: outputs are no command.
    assert axis.state().state == Ds402State.OPERATION_ENABLED and axis.command is None


def test_bad_outputs_are_refused_and_change_nothing(axis):
    axis.set_outputs({1: True}, analog_output=1.0)
    later(axis, 3)
    before = bytes(axis.cycle.outputs(axis.slave))
    for levels, analog, refusal in (
        ({3: True}, None, "outputs refused: output 3: the AKD has digital outputs 1 to 2"),
        ({0: False}, None, "output 0: the AKD has digital outputs 1 to 2"),
        ({2: True}, math.nan, "analog output refused: nan V; allowed a finite voltage within ±10 V"),
        ({2: True}, 10.5, "analog output refused: 10.5 V; allowed a finite voltage within ±10 V"),
        (None, -math.inf, "analog output refused: -inf V"),
    ):
        with pytest.raises(CommandError, match=refusal.replace("(", r"\(").replace(")", r"\)")):
            axis.set_outputs(levels, analog)
    assert bytes(axis.cycle.outputs(axis.slave)) == before


def test_a_mapping_without_outputs_refuses_them_naming_mappings_that_carry_them():
    with Axis("sim?missed=lost", mode=CSP) as axis:
        with pytest.raises(CommandError) as refused:
            axis.set_outputs({1: True})
        assert str(refused.value) == (
            "outputs refused: the mapping of slave_0 carries no digital outputs (0x60FE:01); mappings that do with "
            f"mode {CSP}: io, 0x1725/0x1B20"
        )
        with pytest.raises(CommandError, match=r"no analog output \(0x3470:03\); .*: io, 0x1725/0x1B20"):
            axis.set_outputs(analog_output=1.0)
        io = axis.io()
        assert (io.outputs, io.digital_outputs, io.analog_output, io.analog_input) == ((), None, None, None)


def test_a_limit_switch_holds_a_move_toward_it_and_lets_one_away_go(axis):
    sim = axis.simulator
    start = axis.state().position
    sim.set_switch(0, "positive_limit", True)
    wait_for("the switch", lambda: axis.io().switches["positive_limit"])
    step = 0.002
    for i in range(1, 200):
        axis.command_position(start + step * i)
        later(axis, 1)
    held = axis.state()
    assert held.position < start + 0.05, (start, held.position)
    assert held.statusword & (1 << 11), "internal limit active"
    assert held.state == Ds402State.OPERATION_ENABLED
    for i in range(1, 200):
        axis.command_position(held.position - step * i)
        later(axis, 1)
    away = wait_for("the move away", lambda: (s := axis.state()).position < held.position - 0.3 and s)
    assert not away.statusword & (1 << 11)


def test_what_each_mapping_carries_and_which_carry_a_modes_command_with_the_io():
    carried = _native.mapping_io(*_native.IO_MAPPING)
    assert all(carried.values()), carried
    assert _native.mapping_io(*_native.DEFAULT_MAPPING) == {
        "digital_inputs": True,
        "analog_input": False,
        "digital_outputs": False,
        "analog_output": False,
    }
    assert _native.mapping_io(0x1725, 0x1B26) == dict.fromkeys(carried, True)
    everything = ["digital_inputs", "analog_input", "digital_outputs", "analog_output"]
    # Interpolated position's 0x60C1:01 is in no mapping with all of the I/O but a flexible one of the user's.
    expected = {
        "profile_position": ["io", "0x1725/0x1B20"],
        "profile_velocity": ["io"],
        "profile_torque": ["io"],
        "homing": ["io", "0x1725/0x1B20"],
        "interpolated_position": [],
        CSP: ["io", "0x1725/0x1B20"],
    }
    assert {mode: [name for name, _ in _native.io_mappings(mode, everything)] for mode in MODES} == expected
    with pytest.raises(ValueError, match="no mode"):
        _native.io_mappings("jog", [])
    with pytest.raises(ValueError, match='"outputs" is none of digital_inputs'):
        _native.io_mappings(CSP, ["outputs"])


def test_parameters_name_inputs_and_outputs_and_are_checked_against_the_mapping():
    given = {"mapping": "io", "mode": CSP, "io.inputs.part_present": 3, "io.outputs.lamp": 2, "io_rate": 50.0}
    params.check_names(given)
    joint = params.settings(given).joints[0]
    assert (joint.io_inputs, joint.io_outputs, joint.describe_io()) == (
        {"part_present": 3},
        {"lamp": 2},
        "digital inputs, analog input, digital outputs, analog output",
    )
    two = {
        "link": "sim:2",
        "joints": ["a", "b"],
        "mode": CSP,
        "io.inputs.door": 1,
        "joints.a.mapping": "io",
        "joints.a.io.outputs.valve": 1,
        "joints.b.io.inputs.door": 4,
    }
    params.check_names(two)
    a, b = params.settings(two).joints
    assert (a.io_inputs, a.io_outputs, b.io_inputs) == ({"door": 1}, {"valve": 1}, {"door": 4})
    assert b.describe_io() == "digital inputs"
    for bad, refusal in (
        (
            {"io.outputs.lamp": 1},
            "parameters io.outputs.* of joint akd_axis: its mapping 'default' carries no digital outputs (0x60FE:01); "
            "mappings that do with mode interpolated_position: 0x1720/0x1B20, 0x1722/0x1B20, 0x1723/0x1B20",
        ),
        ({"io.inputs.part_present": 8}, "parameter io.inputs.part_present must be an integer in [1, 7], got 8"),
        ({"io.outputs.lamp": 3, "mapping": "io"}, "parameter io.outputs.lamp must be an integer in [1, 2], got 3"),
        ({"io.inputs.Bad-Name": 1}, "unknown parameter io.inputs.Bad-Name"),
        ({"joints": ["a"], "joints.c.io.inputs.x": 1}, "unknown parameter joints.c.io.inputs.x"),
        (
            {"mapping": "0x1720/0x1B01", "io.inputs.x": 1},
            "parameters io.inputs.* of joint akd_axis: its mapping '0x1720/0x1B01' carries no digital inputs (0x60FD)",
        ),
    ):
        with pytest.raises(params.ParameterError, match=re.escape(refusal)):
            params.check_names(bad)
            params.settings(bad)


def test_the_flexible_mapping_docs_io_gives_for_interpolated_position_carries_all_of_the_io():
    block = next(b for b in blocks_of("docs/io.md") if b.language == "yaml").code
    given = yaml.safe_load("p:\n" + block)["p"]
    joint = params.settings(given).joints[0]
    assert joint.mode == "interpolated_position" and all(joint.io_carried.values()), joint.io_carried
